"""The implicit solver: linear algebra, dynamics, pins, damping, contact, convergence, output."""

import csv

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from clothtool.errors import InputError, NumericalError
from clothtool.io.ply import read_ply, write_ply
from clothtool.sim.api import simulate
from clothtool.sim.linalg.blocks import BlockMatrix, ConstraintFilter, block_multiply
from clothtool.sim.linalg.pcg import BlockJacobi, filtered_pcg, make_preconditioner
from clothtool.sim.model.config import load_config
from clothtool.sim.model.methods import make_integrator
from clothtool.sim.model.builder import build_model
from clothtool.sim.solvers.implicit import ImplicitEuler


def config(**sections):
    base = {"mesh": {"grid": {"nx": 8, "ny": 8}}, "time": {"fps": 30, "frames": 10}}
    for name, values in sections.items():
        base[name] = {**base.get(name, {}), **values}
    return base


def frames(out_dir):
    return [read_ply(p) for p in sorted(out_dir.glob("frame_*.ply"))]


def stats(out_dir):
    with open(out_dir / "stats.csv") as fh:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]


def run(tmp_path, cfg, name="out"):
    return simulate(cfg, output_dir=tmp_path / name, progress=False)


def assembled_system(model, integrator, x):
    """The Newton matrix M/h² + K at x as a scipy matrix."""
    matrix = BlockMatrix(model.pattern)
    integrator.elastic.assemble(x, np.zeros_like(x), matrix.values)
    matrix.add_diagonal(model.mass / integrator.h**2)
    return matrix, matrix.to_scipy()


def test_block_product_and_filtered_pcg_match_scipy():
    cfg = load_config(config(scene={"pins": ["top_edge"]}))
    model = build_model(cfg)
    integ = ImplicitEuler(model, cfg.solver, cfg.step)
    rng = np.random.default_rng(0)
    x = model.mesh.positions + 0.05 * rng.normal(size=model.mesh.positions.shape)
    blocks, matrix = assembled_system(model, integ, x)
    p = model.pattern
    v = rng.normal(size=x.shape)
    y = np.empty_like(v)
    block_multiply(p.row_ptr, p.col, blocks.values, v, y)
    np.testing.assert_allclose(y.ravel(), matrix @ v.ravel(), rtol=1e-12)
    np.testing.assert_allclose(matrix.toarray(), matrix.toarray().T, atol=1e-9)

    b = rng.normal(size=x.shape)
    sol = np.zeros_like(b)
    its, res = filtered_pcg(blocks, b, sol, ConstraintFilter(model.kind), 1e-10,
                            5000, BlockJacobi(model.n_vertices))
    assert res <= 1e-10 and its > 0
    free = np.repeat(model.free, 3)
    expected = spla.spsolve(matrix[free][:, free].tocsc(), b.ravel()[free])
    np.testing.assert_allclose(sol.ravel()[free], expected, rtol=1e-7, atol=1e-12)
    assert not sol[model.pinned].any()  # the filter keeps pinned components at their start value
    # the reported residual is the true one
    r = (b.ravel() - matrix @ sol.ravel())[free]
    assert np.linalg.norm(r) / np.linalg.norm(b.ravel()[free]) == pytest.approx(res, rel=1e-6)


def test_free_fall_is_exactly_implicit_euler(tmp_path):
    g = np.array([0.0, -9.81, 0.3])
    cfg = config(scene={"gravity": g.tolist()}, solver={"tolerance": 1e-12, "integrator": "euler"},
                 material={"damping": 0.05})
    run(tmp_path, cfg)
    h = 1 / 30
    x = frames(tmp_path / "out")
    v = np.zeros(3)
    expected = x[0].vertices.copy()
    for k in range(1, len(x)):
        v = v + h * g
        expected = expected + h * v
        np.testing.assert_allclose(x[k].vertices, expected, rtol=0, atol=1e-10)
    rows = stats(tmp_path / "out")
    assert rows[-1]["kinetic"] == pytest.approx(0.5 * 0.2 * 1.0 * (v @ v), rel=1e-9)


@pytest.mark.parametrize("method", ["implicit", "mass-spring"])
def test_bdf2_integrates_free_fall_exactly(method):
    """A quadratic trajectory is BDF2's exact solution: from an exact history (x, v at
    t = −h in the State), every step lands on x0 + v0 t + g t²/2, damping or not (a rigid
    translation stretches nothing)."""
    g = np.array([0.3, -9.81, 0.5])
    cfg = load_config(config(scene={"gravity": g.tolist()}, material={"damping": 0.05},
                             solver={"method": method, "tolerance": 1e-12,
                                     "newton_tolerance": 1e-9}))
    model = build_model(cfg)
    integ = make_integrator(model, cfg.solver, cfg.step)
    h = cfg.step
    v0 = np.array([0.2, 1.0, -0.4])
    state = model.initial_state()
    x0 = state.x.copy()
    state.v[:] = v0
    state.x_prev, state.v_prev = x0 - h * v0 + 0.5 * h * h * g, np.tile(v0 - h * g, (len(x0), 1))
    for k in range(1, 11):
        integ.step(state)
        t = k * h
        np.testing.assert_allclose(state.x, x0 + v0 * t + 0.5 * g * t * t, rtol=0, atol=1e-11)
        np.testing.assert_allclose(state.v, np.tile(v0 + g * t, (len(x0), 1)), rtol=0, atol=1e-9)


@pytest.mark.parametrize("method", ["implicit", "mass-spring"])
@pytest.mark.parametrize("fps, substeps", [(30, 1), (24, 3)])
def test_bdf2_free_fall_is_exact_at_every_frame_from_the_start(tmp_path, method, fps, substeps):
    """A sheet dropped from rest lands on x0 + g t²/2 at every frame to 1e-9 m: the first
    step gets its history from a Taylor step back (a backward-Euler first step fell h²g in
    it, twice g h²/2, and stayed ¾h²g = 8 mm behind at 30 fps)."""
    g = np.array([0.3, -9.81, 0.5])
    cfg = config(scene={"gravity": g.tolist()}, material={"damping": 0.05},
                 solver={"method": method, "substeps": substeps},
                 time={"fps": fps, "frames": 12})
    run(tmp_path, cfg)
    x = frames(tmp_path / "out")
    for k, frame in enumerate(x):
        t = k / fps
        np.testing.assert_allclose(frame.vertices, x[0].vertices + 0.5 * g * t * t, rtol=0,
                                   atol=1e-9)


def test_pinned_vertices_never_move(tmp_path):
    cfg = config(scene={"pins": ["left_edge", 63]}, material={"stretch": 2000.0},
                 mesh={"grid": {"nx": 8, "ny": 8, "plane": "xz"}})
    run(tmp_path, cfg)
    x = frames(tmp_path / "out")
    pinned = [0, 8, 16, 24, 32, 40, 48, 56, 63]
    for f in x[1:]:
        assert np.array_equal(f.vertices[pinned], x[0].vertices[pinned])
    assert np.abs(x[-1].vertices - x[0].vertices).max() > 0.1  # the rest swings down


def stretched_start(tmp_path, factor=1.3):
    """A PLY whose positions are its uv pattern stretched and lifted: elastic energy, no gravity."""
    n = 6
    u, v = np.meshgrid(np.linspace(0, 0.5, n), np.linspace(0, 0.5, n))
    uv = np.stack([u.ravel(), v.ravel()], 1)
    pos = np.zeros((n * n, 3))
    pos[:, :2] = factor * uv
    pos[:, 2] = 0.05 * np.sin(7 * uv[:, 0]) * np.cos(5 * uv[:, 1])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    a = (j * n + i).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    write_ply(tmp_path / "start.ply", pos, faces, vertex_properties={"s": uv[:, 0], "t": uv[:, 1]})
    return tmp_path / "start.ply"


def total_energy(rows):
    return np.array([r["kinetic"] + r["elastic"] + r["gravity"] for r in rows])


def test_energy_decreases_under_damping(tmp_path):
    ply = stretched_start(tmp_path)
    base = {"mesh": {"ply": str(ply)}, "scene": {"gravity": [0, 0, 0]},
            "material": {"stretch": 200.0, "shear": 20.0, "bend": 1e-4},
            "time": {"frames": 20}, "solver": {"newton_iterations": 4, "tolerance": 1e-9}}
    damped = {**base, "material": {**base["material"], "damping": 0.05}}
    undamped = {**base, "material": {**base["material"], "damping": 0.0}}
    run(tmp_path, damped, "damped")
    run(tmp_path, undamped, "undamped")
    e_damped = total_energy(stats(tmp_path / "damped"))
    e_undamped = total_energy(stats(tmp_path / "undamped"))
    assert e_damped[0] > 1.0
    assert np.all(np.diff(e_damped) <= 0.0)
    # BDF2's first step (SDIRK2) adds no numerical damping of its own: the undamped sheet
    # keeps its energy through it (a Taylor step back lost 94 % of it there); damping
    # leaves less energy in the end
    assert e_undamped[1] > 0.9 * e_undamped[0]
    assert e_damped[-1] < 0.8 * e_undamped[-1]


def test_no_penetration_of_a_sphere_or_plane(tmp_path):
    """A sheet dropped on a sphere with friction 0.3 over a plane. Where it comes to rest on
    the sphere, and so how hard it presses at the top, depends on the path its friction took
    it: the resting gap is measured with ``damping_model: frozen`` (1.98 mm; with the default
    strain damping the sheet slides further down the sides and rests at 1.88 mm, undamped at
    1.93 mm: all inside the barrier's wall)."""
    cfg = config(mesh={"grid": {"nx": 13, "ny": 13, "plane": "xz"}},
                 material={"damping_model": "frozen"},
                 scene={"colliders": [{"sphere": {"center": [0, -0.4, 0], "radius": 0.3,
                                                  "friction": 0.3}},
                                      {"plane": {"point": [0, -0.8, 0], "normal": [0, 1, 0]}}]},
                 time={"frames": 25})
    run(tmp_path, cfg)
    x = frames(tmp_path / "out")
    faces = x[0].faces
    for f in x:  # no triangle reaches into the sphere (exact triangle–sphere distance)
        gap = [triangle_point_distance(f.vertices[t], np.array([0, -0.4, 0])) for t in faces]
        assert min(gap) >= 0.3 + 1e-3  # the barrier's wall: half the 2 mm margin
        assert f.vertices[:, 1].min() >= -0.8 + 1e-3
    # the sheet came to rest on the sphere: within 5 % inside the margin, the edges hang lower
    assert min(gap) == pytest.approx(0.3 + 2e-3, abs=0.1e-3)
    assert x[-1].vertices[:, 1].min() < -0.2


def triangle_point_distance(tri, p, samples=60):
    """Distance from p to a triangle by dense barycentric sampling refined by the vertices'
    and edges' exact projections (a brute-force check, independent of the contact kernels)."""
    a, b, c = tri
    best = np.inf
    s = np.linspace(0.0, 1.0, samples)
    u, v = np.meshgrid(s, s)
    keep = u + v <= 1.0
    pts = a + u[keep, None] * (b - a) + v[keep, None] * (c - a)
    best = np.linalg.norm(pts - p, axis=1).min()
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    q = p - np.dot(p - a, n) * n  # the plane's foot point, when inside the triangle
    w = np.linalg.lstsq(np.stack([b - a, c - a], 1), q - a, rcond=None)[0]
    if w.min() >= 0 and w.sum() <= 1:
        best = min(best, abs(np.dot(p - a, n)))
    return best


def sag(tmp_path, n):
    """Static sag of the bottom-edge centre of a vertical sheet hung from its top edge."""
    cfg = {"mesh": {"grid": {"nx": n, "ny": n, "plane": "xy"}},
           "material": {"stretch": 100.0, "shear": 100.0, "bend": 0.0, "damping": 0.0},
           "scene": {"pins": ["top_edge"]},
           "solver": {"newton_iterations": 8, "tolerance": 1e-8, "max_iterations": 5000},
           "time": {"fps": 1, "frames": 6}}
    run(tmp_path, cfg, f"sag{n}")
    x = frames(tmp_path / f"sag{n}")
    bottom_centre = (n - 1) // 2  # row 0, middle column
    return x[0].vertices[bottom_centre, 1] - x[-1].vertices[bottom_centre, 1]


def test_same_sag_at_two_resolutions(tmp_path):
    coarse, fine = sag(tmp_path, 9), sag(tmp_path, 17)
    assert coarse > 0.005  # a visible sag, not a numerical zero
    assert fine == pytest.approx(coarse, rel=0.05)


def constrained_system(nx=12):
    """A stretched 12×12 system with its two top corners and three more vertices pinned."""
    cfg = load_config(config(mesh={"grid": {"nx": nx, "ny": nx}}, scene={"pins": ["top_corners"]}))
    model = build_model(cfg)
    integ = ImplicitEuler(model, cfg.solver, cfg.step)
    rng = np.random.default_rng(2)
    x = model.mesh.positions * 1.05 + 0.01 * rng.normal(size=model.mesh.positions.shape)
    blocks, matrix = assembled_system(model, integ, x)
    kind = model.kind.copy()
    kind[[5, 30, 77]] = 1
    return model, blocks, matrix, kind


def filter_matrix(kind):
    return np.diag(np.repeat(kind != 1, 3).astype(float))


@pytest.mark.parametrize("preconditioner", ["multigrid", "amg"])
def test_multigrid_preconditioner_is_symmetric_positive_definite_on_the_free_space(preconditioner):
    model, blocks, matrix, kind = constrained_system()
    hierarchy = make_preconditioner(preconditioner, model.pattern, model.faces)
    assert hierarchy.node_off.size >= 3  # at least two levels below the mesh
    hierarchy.update(model.mesh.positions, ConstraintFilter(kind))
    hierarchy.setup(blocks, ConstraintFilter(kind))
    n = 3 * model.n_vertices
    s = filter_matrix(kind)
    b = np.empty((n, n))
    out = np.empty((model.n_vertices, 3))
    for a in range(n):
        e = np.zeros(n)
        e[a] = 1.0
        hierarchy.apply((s @ e).reshape(-1, 3), out)
        b[:, a] = s @ out.ravel()
    np.testing.assert_allclose(b, b.T, atol=1e-12 * np.abs(b).max())
    u, sing, _ = np.linalg.svd(s)
    free_space = u[:, sing > 0.5]
    assert np.linalg.eigvalsh(free_space.T @ b @ free_space).min() > 0


@pytest.mark.parametrize("preconditioner", ["jacobi", "multigrid", "amg", "hybrid"])
def test_filtered_pcg_with_each_preconditioner_matches_a_direct_solve(preconditioner):
    model, blocks, matrix, kind = constrained_system()
    constraints = ConstraintFilter(kind)
    mg = make_preconditioner(preconditioner, model.pattern, model.faces)
    mg.update(model.mesh.positions, constraints)
    rng = np.random.default_rng(5)
    b = rng.normal(size=(model.n_vertices, 3))
    sol = np.zeros_like(b)
    its, res = filtered_pcg(blocks, b, sol, constraints, 1e-10, 5000, mg)
    assert res <= 1e-10
    s = filter_matrix(kind)
    a = matrix.toarray()
    # S A S y = S b on range(S), (I − S) y = 0
    expected = np.linalg.lstsq(s @ a @ s + (np.eye(len(s)) - s), s @ b.ravel(), rcond=None)[0]
    np.testing.assert_allclose(sol.ravel(), expected, rtol=1e-6, atol=1e-10 * np.abs(expected).max())
    if preconditioner != "jacobi":
        jacobi_its, _ = filtered_pcg(blocks, b, np.zeros_like(b), constraints, 1e-10, 5000,
                                     BlockJacobi(model.n_vertices))
        assert its < jacobi_its


def test_hybrid_solves_tight_with_amg_and_loose_with_multigrid():
    """``hybrid`` is, solve by solve, ``amg`` at a tolerance of 1e-4 or finer and ``multigrid``
    above it, bit for bit; its prolongators come from the positions its Newton minimisation
    started at, even when they are built later, at the first tight solve."""
    model, blocks, _, kind = constrained_system()
    constraints = ConstraintFilter(kind)
    rng = np.random.default_rng(7)
    b = rng.normal(size=(model.n_vertices, 3))
    start = model.mesh.positions * 1.02
    hybrid = make_preconditioner("hybrid", model.pattern, model.faces)
    x = start.copy()
    hybrid.update(x, constraints)
    x += 0.01  # Newton moves on before the first tight solve
    for tol, alone in [(1e-2, "multigrid"), (1e-4, "amg"), (1e-6, "amg"), (1e-3, "multigrid")]:
        other = make_preconditioner(alone, model.pattern, model.faces)
        other.update(start, constraints)
        ours, theirs = np.zeros_like(b), np.zeros_like(b)
        got = filtered_pcg(blocks, b, ours, constraints, tol, 5000, hybrid)
        expected = filtered_pcg(blocks, b, theirs, constraints, tol, 5000, other)
        assert got == expected
        np.testing.assert_array_equal(ours, theirs)


@pytest.mark.parametrize("stretch", [1.0e3, 5.0e4])
def test_auto_is_amg_on_stiff_models_and_multigrid_on_soft_ones(stretch):
    """``auto``: ``amg`` for every solve when the stiffest membrane k over the free vertices'
    mean mass m gives k h²/m ≥ ``AUTO_RATIO`` at the solver step h, ``multigrid`` below: a
    function of the model and the step, the same for every step of a run."""
    from clothtool.sim.linalg.multilevel import ModeMultigrid
    from clothtool.sim.linalg.pcg import AUTO_RATIO, Hierarchy

    cfg = load_config(config(mesh={"grid": {"nx": 24, "ny": 24}},
                             material={"stretch": stretch, "shear": 100.0},
                             solver={"preconditioner": "auto"}))
    model = build_model(cfg)
    integ = make_integrator(model, cfg.solver, cfg.step)
    mass = float(np.mean(model.mass[model.free]))
    ratio = stretch * integ.h ** 2 / mass
    assert (ratio >= AUTO_RATIO) == (stretch > 1.0e4)  # the two sides of the threshold
    expected = ModeMultigrid if ratio >= AUTO_RATIO else Hierarchy
    assert type(integ.preconditioner) is expected
    for stiffness, kind in [(AUTO_RATIO, ModeMultigrid), (np.nextafter(AUTO_RATIO, 0), Hierarchy)]:
        pre = make_preconditioner("auto", model.pattern, model.faces, stiffness)
        assert type(pre) is kind


def test_pinned_components_keep_their_prescribed_motion():
    """The filter S: a moving pin's prescribed step stays as given, the rest solves the system."""
    cfg = load_config(config())
    model = build_model(cfg)
    integ = ImplicitEuler(model, cfg.solver, cfg.step)
    blocks, matrix = assembled_system(model, integ, model.mesh.positions)
    rng = np.random.default_rng(1)
    n = model.n_vertices
    kind = model.kind.copy()
    held = [3, 10, 20]
    kind[held] = 1
    b = rng.normal(size=(n, 3))
    sol = np.zeros((n, 3))
    sol[held] = 0.01 * rng.normal(size=(3, 3))  # prescribed motion
    given = sol[held].copy()
    its, res = filtered_pcg(blocks, b, sol, ConstraintFilter(kind), 1e-10, 5000,
                            BlockJacobi(model.n_vertices))
    assert res <= 1e-10
    np.testing.assert_array_equal(sol[held], given)
    r = (b.ravel() - matrix @ sol.ravel()).reshape(n, 3)
    r[held] = 0.0
    assert np.linalg.norm(r) <= 1e-9 * np.linalg.norm(b)


def test_determinism(tmp_path):
    cfg = config(scene={"pins": ["top_corners"]}, mesh={"grid": {"nx": 8, "ny": 8, "plane": "xz"}})
    run(tmp_path, cfg, "a")
    run(tmp_path, cfg, "b")
    a = sorted((tmp_path / "a").glob("frame_*.ply"))
    b = sorted((tmp_path / "b").glob("frame_*.ply"))
    assert len(a) == 11 and [p.name for p in a] == [p.name for p in b]
    for pa, pb in zip(a, b):
        assert pa.read_bytes() == pb.read_bytes()


def test_stiff_cloth_is_stable_at_one_step_per_frame(tmp_path):
    cfg = config(mesh={"grid": {"nx": 12, "ny": 12, "plane": "xz"}},
                 material={"stretch": 1e5, "shear": 1e3},
                 scene={"pins": ["top_corners"]}, time={"fps": 30, "frames": 30})
    result = run(tmp_path, cfg)
    assert result.frames_written == 31
    rows = stats(tmp_path / "out")
    assert all(np.isfinite(r["kinetic"]) for r in rows)
    assert max(r["max_stretch"] for r in rows) < 1.2
    last = frames(tmp_path / "out")[-1].vertices
    assert np.isfinite(last).all() and last[:, 1].min() > -1.6  # hangs, does not fly off


@pytest.mark.parametrize("solver, stretch", [
    ({"integrator": "euler", "newton_iterations": 1}, 1.01),  # the linearised step
    ({}, 1.06),  # the default: Newton stops at 0.04 m/s, i.e. 4 cm at h = 1 s
])
def test_very_stiff_cloth_at_huge_steps_still_moves(tmp_path, solver, stretch):
    """The first Newton step from a flat sheet overshoots (no out-of-plane stiffness at
    rest); the line search must shrink it until the energy drops, not give up."""
    cfg = config(mesh={"grid": {"nx": 12, "ny": 12, "plane": "xz"}},
                 material={"stretch": 1e7}, scene={"pins": ["top_corners"]},
                 time={"fps": 1, "frames": 2}, solver=solver)
    run(tmp_path, cfg)
    rows = stats(tmp_path / "out")
    assert rows[-1]["gravity"] < rows[0]["gravity"] - 1e-4  # it fell a little
    assert rows[-1]["max_stretch"] < stretch


def stepped(cfg, steps):
    """(model, integrator, state, reports) after ``steps`` steps of a config dict in memory."""
    cfg = load_config(cfg)
    model = build_model(cfg)
    integrator = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    return model, integrator, state, [integrator.step(state) for _ in range(steps)]


def hanging_sheet(stretch, levels, steps, fps=1, **solver):
    return config(mesh={"grid": {"nx": 12, "ny": 12, "plane": "xz"}},
                  material={"stretch": stretch, "shear": stretch / 10},
                  scene={"pins": ["top_corners"], "colliders": []},
                  time={"fps": fps, "frames": steps},
                  solver={"stiffness_continuation": levels, **solver})


def test_a_newton_solve_stopped_by_its_cap_is_counted():
    *_, reports = stepped(hanging_sheet(1e3, 0, 2, fps=30, newton_iterations=1,
                                        integrator="euler"), 2)
    assert [r.capped for r in reports] == [1, 1]
    *_, reports = stepped(hanging_sheet(1e3, 0, 2, fps=30), 2)
    assert [r.capped for r in reports] == [0, 0]


def test_stiffness_continuation_converges_stiff_cloth_at_one_step_per_second():
    """1e6 N/m at h = 1 s: the swing from flat of near-inextensible cloth, on which Newton
    alone crawls to its cap; from membranes 10⁴, …, 10× softer every solve converges, and the
    membrane is itself again after each step."""
    model, integrator, state, reports = stepped(hanging_sheet(1e6, 4, 4, continuation_after=0),
                                                4)
    assert [r.capped for r in reports] == [0, 0, 0, 0]
    assert integrator.max_stretch(state) <= 1.05
    assert state.x[:, 1].min() < -0.9  # it swung down (it hangs 1 m below its corners)
    fresh = build_model(load_config(hanging_sheet(1e6, 4, 4)))
    for name in ("stretch", "shear"):
        np.testing.assert_array_equal(getattr(model.terms[0], name),
                                      getattr(fresh.terms[0], name))


@pytest.mark.parametrize("material", [{}, {"damping_model": "frozen"}, {"damping": 0.0}])
def test_stiffness_continuation_finds_the_minimum_plain_newton_finds(material):
    """Where Newton converges alone (a soft sheet at 30 fps), the continuation ends at the same
    step: both solved tightly (1e-5 m/s: 0.3 µm a step), within 10 µm after five steps
    (measured 0.7–1.0 µm; another minimum would be millimetres away)."""
    tight = {"newton_tolerance": 1e-5, "tolerance": 1e-10, "newton_iterations": 60}
    ends = []
    for levels in (0, 2):
        cfg = hanging_sheet(2e3, levels, 5, fps=30, continuation_after=0, **tight)
        cfg["material"].update(material)
        ends.append(stepped(cfg, 5)[2].x.copy())
    assert np.max(np.abs(ends[0] - ends[1])) < 1e-5


def test_continuation_after_a_stall_converges_stiff_cloth_at_one_step_per_second():
    """1e6 N/m at h = 1 s with the continuation only for stalled solves: Newton alone stalls
    (unconverged after 20 steps, 13–19 of them with velocity corrections within the tolerance
    and a decrement above it), and every solve is solved again through the softer membranes
    to convergence; the membrane is itself again after each step."""
    model, integrator, state, reports = stepped(hanging_sheet(1e6, 4, 4, continuation_after=20),
                                                4)
    assert [r.capped for r in reports] == [0, 0, 0, 0]
    assert all(r.newton_iterations > 20 for r in reports)  # each stalled first
    assert integrator.max_stretch(state) <= 1.05
    assert state.x[:, 1].min() < -0.9
    fresh = build_model(load_config(hanging_sheet(1e6, 4, 4)))
    for name in ("stretch", "shear"):
        np.testing.assert_array_equal(getattr(model.terms[0], name),
                                      getattr(fresh.terms[0], name))


def test_automatic_continuation_levels_follow_the_stiffness_to_inertia_ratio():
    """``auto``: the fewest n with k·ĥ²/(m·10ⁿ) ≤ 1e4, m the free vertices' mean mass (the
    12×12 sheet: 0.2 kg/m² on 1 m², pinned corners left out: 1.4026 g): at 1e6 N/m and
    ĥ = 2/3 s k·ĥ²/m = 3.17e8, 5 levels; SDIRK2's first stage (ĥ = 0.293 s) 6.12e7, 4; 1e7 N/m
    3.17e9, 6; 2000 N/m at 30 fps (ĥ = 1/45 s) 704: none."""
    levels = []
    for stretch, fps, h_eff in ((1e6, 1, 2 / 3), (1e6, 1, 1 - np.sqrt(0.5)), (1e7, 1, 2 / 3),
                                (2e3, 30, 1 / 45)):
        cfg = load_config(hanging_sheet(stretch, "auto", 1, fps=fps))
        integrator = make_integrator(build_model(cfg), cfg.solver, cfg.step)
        levels.append(integrator.continuation_levels(h_eff))
    assert levels == [5, 4, 6, 0]
    with pytest.raises(InputError, match=r"solver.stiffness_continuation must be an integer or "
                                         r"'auto', got 'always'"):
        load_config(hanging_sheet(1e6, "always", 1))


@pytest.mark.parametrize("stretch", [1e6, 1e7])
def test_automatic_continuation_after_a_stall_converges_stiff_cloth(stretch):
    """1e6 and 1e7 N/m at h = 1 s, the level count from the stiffness-to-inertia ratio: every
    stalled solve is solved again through 4–6 softer membranes, every solve converges (four
    fixed levels left two of the 1e7 N/m sheet's solves at the cap)."""
    _, integrator, state, reports = stepped(hanging_sheet(stretch, "auto", 4,
                                                          continuation_after=20), 4)
    assert [r.capped for r in reports] == [0, 0, 0, 0]
    assert integrator.max_stretch(state) <= 1.05
    assert state.x[:, 1].min() < -0.9


@pytest.mark.parametrize("levels", [4, "auto"])
@pytest.mark.parametrize("material", [{}, {"damping_model": "frozen"}])
def test_continuation_after_leaves_a_solve_that_converges_alone_as_it_is(material, levels):
    """A soft sheet at 30 fps converges within 20 Newton steps: with the continuation only
    after 20 unconverged steps every step is the one plain Newton takes, bit for bit."""
    ends, counts = [], []
    for solver in ({}, {"continuation_after": 20}):
        cfg = hanging_sheet(2e3, levels if solver else 0, 5, fps=30, **solver)
        cfg["material"].update(material)
        _, _, state, reports = stepped(cfg, 5)
        ends.append(state.x.copy())
        counts.append([r.newton_iterations for r in reports])
    np.testing.assert_array_equal(ends[0], ends[1])
    assert counts[0] == counts[1]


def test_continuation_after_beyond_the_newton_cap_leaves_the_linearised_step_as_it_is():
    """``newton_iterations: 1`` (Baraff–Witkin's linearised step) on stiff cloth with the
    continuation after 20 steps: the solve stops at its own cap of one step, as without it."""
    ends = []
    for solver in ({"stiffness_continuation": 0}, {"stiffness_continuation": "auto",
                                                   "continuation_after": 20}):
        cfg = hanging_sheet(1e7, 0, 2, integrator="euler", newton_iterations=1)
        cfg["solver"].update(solver)
        _, _, state, reports = stepped(cfg, 2)
        assert [r.newton_iterations for r in reports] == [1, 1]
        ends.append(state.x.copy())
    np.testing.assert_array_equal(ends[0], ends[1])


def test_continuation_after_goes_on_alone_where_the_steps_were_not_stiffness_bound():
    """A solve unconverged after k steps, fewer than half of them with velocity corrections
    within the tolerance and a decrement above it, has not stalled on the stiffness: Newton
    goes on alone to its cap (3 steps, then the rest from there) and never softens."""
    tight = {"newton_tolerance": 1e-9, "newton_iterations": 6, "integrator": "euler"}
    plain = stepped(hanging_sheet(2e3, 0, 1, fps=30, **tight), 1)[3][0]
    split = stepped(hanging_sheet(2e3, 4, 1, fps=30, continuation_after=3, **tight), 1)[3][0]
    assert plain.capped == split.capped == 1
    assert plain.newton_iterations == split.newton_iterations == 6


def test_blow_up_names_the_frame_and_keeps_earlier_frames(tmp_path):
    cfg = config(solver={"max_speed": 0.5}, time={"frames": 10})  # free fall passes 0.5 m/s at frame 2
    with pytest.raises(NumericalError, match=r"blew up at frame 2: velocities exploded"):
        run(tmp_path, cfg)
    written = frames(tmp_path / "out")
    assert len(written) == 2
    assert len(stats(tmp_path / "out")) == 2


def test_output_layout(tmp_path):
    cfg = config(time={"frames": 4}, output={"every": 2})
    result = run(tmp_path, cfg)
    out = tmp_path / "out"
    assert sorted(p.name for p in out.glob("*.ply")) == ["frame_00000.ply", "frame_00002.ply",
                                                         "frame_00004.ply"]
    assert result.frames_written == 3
    first = read_ply(out / "frame_00000.ply")
    assert first.header.format == "binary_little_endian"
    model = build_model(load_config(cfg))
    np.testing.assert_array_equal(first.uv, model.mesh.uv)
    np.testing.assert_array_equal(first.faces, model.faces)
    with open(out / "stats.csv") as fh:
        header = fh.readline().strip().split(",")
    assert header[:10] == ["frame", "time", "kinetic", "elastic", "gravity", "newton_iterations",
                           "cg_iterations", "residual", "max_stretch", "wall_s"]
    assert [r["frame"] for r in stats(out)] == [0, 2, 4]
    # a second run into the same folder replaces the first one's frames
    run(tmp_path, {**cfg, "output": {"every": 4}})
    assert sorted(p.name for p in out.glob("*.ply")) == ["frame_00000.ply", "frame_00004.ply"]
