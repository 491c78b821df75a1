"""Solver alternatives (issue 5): convergence toward converged references, pins, defaults.

Scene: an 8×8 sheet, 1 m, starting horizontal and falling from its two top
corners, undamped, for 0.3 s; errors are RMS vertex distances at t = 0.1, 0.2,
0.3 s (the largest). References are Newton-converged implicit Euler at
h = 1/480 and 1/960 s, Richardson-extrapolated: for the finite-element
material (``implicit``, ``explicit``) and for the spring network
(``mass-spring``, ``pbd``, ``xpbd``, ``projective``). The assertions are on
monotone decrease and measured orders, never on speed.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.errors import InputError
from clothtool.sim.model.config import load_config
from clothtool.sim.model.builder import build_model
from clothtool.sim.model.methods import make_integrator
from clothtool.sim.solvers.compare import Run, position_error, run_in_memory
from clothtool.sim.energies.springs import spring_assemble

CK = (3, 6, 9)
CONVERGED = dict(newton_iterations=30, newton_tolerance=1e-9, tolerance=1e-10, max_iterations=2000)


def scene(method, substeps=1, nx=8, frames=9, **solver):
    """Backward Euler for the Newton methods (the references are extrapolated for order 1)."""
    return {"mesh": {"grid": {"nx": nx, "ny": nx, "plane": "xz"}},
            "material": {"damping": 0.0, "bend": 1e-3},
            "scene": {"pins": ["top_corners"]}, "time": {"frames": frames},
            "solver": {"method": method, "substeps": substeps, "integrator": "euler", **solver}}


def richardson(method, substeps=16):
    a = run_in_memory(scene(method, substeps, **CONVERGED), CK, warmup=False)
    b = run_in_memory(scene(method, 2 * substeps, **CONVERGED), CK, warmup=False)
    ref = Run("reference", b.h)
    ref.positions = {f: 2.0 * b.positions[f] - a.positions[f] for f in CK}
    return ref


@pytest.fixture(scope="module")
def fem_reference():
    return richardson("implicit")


@pytest.fixture(scope="module")
def spring_reference():
    return richardson("mass-spring")


def errors(method, substeps, reference, **solver):
    return [position_error(run_in_memory(scene(method, s, **solver), CK), reference)
            for s in substeps]


def orders(errs):
    """Measured convergence orders log2(e(h)/e(h/2)) between successive halvings."""
    return [math.log2(a / b) for a, b in zip(errs, errs[1:])]


def assert_decreasing(errs):
    assert all(b < a for a, b in zip(errs, errs[1:])), errs


def test_spring_network_matches_the_membrane_closely(fem_reference, spring_reference):
    # the two materials differ (model error), but far less than the motion (≈ 0.4 m)
    assert position_error(spring_reference, fem_reference) < 0.02


@pytest.mark.parametrize("method", ["implicit", "mass-spring"])
def test_backward_euler_converges_first_order_in_the_step(method, fem_reference, spring_reference):
    ref = fem_reference if method == "implicit" else spring_reference
    errs = errors(method, (1, 2, 4, 8), ref)
    assert_decreasing(errs)
    # implicit Euler is first order: the last halving should show it
    assert 0.6 < orders(errs)[-1] < 1.8, (errs, orders(errs))


def test_explicit_converges_in_the_step(fem_reference):
    errs = errors("explicit", (40, 80, 160), fem_reference, cfl=0.0)
    assert_decreasing(errs)
    assert errs[0] < 0.01  # symplectic Euler at h ≈ 1/1200 s is already close


@pytest.mark.parametrize("method, solver", [
    ("pbd", {"iterations": 5}),
    ("pbd", {"iterations": 5, "pbd_variant": "jacobi"}),
    ("xpbd", {"iterations": 5}),
    ("projective", {"iterations": 5}),
])
def test_iterative_methods_converge_as_the_step_shrinks(method, solver, spring_reference):
    assert_decreasing(errors(method, (1, 2, 4, 8), spring_reference, **solver))


@pytest.fixture(scope="module")
def newton_at_quarter_step():
    """Newton-converged mass-spring implicit Euler at 4 steps per frame: the fixed point
    that XPBD's and PD's iterations approach at the same step."""
    return run_in_memory(scene("mass-spring", 4, **CONVERGED), CK)


@pytest.mark.parametrize("method", ["xpbd", "projective"])
def test_iterations_converge_to_the_implicit_step(method, newton_at_quarter_step):
    errs = [position_error(run_in_memory(scene(method, 4, iterations=i), CK), newton_at_quarter_step)
            for i in (2, 8, 32, 128)]
    assert_decreasing(errs)
    assert errs[-1] < errs[0] / 4


def test_pbd_iterations_reduce_stretch():
    stretch = [run_in_memory(scene("pbd", 2, iterations=i), ()).max_stretch for i in (1, 4, 16)]
    assert all(b < a for a, b in zip(stretch, stretch[1:])), stretch


def _edge_ratio_after(iterations, strain_limit):
    cfg = load_config(scene("pbd", 1, iterations=iterations, pbd_stiffness=0.2,
                            strain_limit=strain_limit))
    model = build_model(cfg)
    integ = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    for _ in range(9):
        integ.step(state)
    sp = integ.springs
    ratio = np.linalg.norm(state.x[sp.i] - state.x[sp.j], axis=1) / sp.rest
    return ratio[:len(sp) - sp.n_bend].max()


def test_strain_limiting_bounds_the_edges():
    """Soft PBD (s = 0.2) stretches the same whatever the iteration count (the per-iteration
    stiffness correction); with a 5 % strain limit the longest edge approaches 1.05 as the
    iterations grow (each sweep ends with one Gauss–Seidel limiting pass)."""
    soft = [_edge_ratio_after(i, 0.0) for i in (2, 10, 40)]
    limited = [_edge_ratio_after(i, 0.05) for i in (2, 10, 40)]
    assert max(soft) - min(soft) < 0.05 * min(soft) and min(soft) > 1.5
    assert all(b < a for a, b in zip(limited, limited[1:])), limited
    assert limited[-1] - 1.05 < (limited[0] - 1.05) / 4


METHODS = [("implicit", {}), ("implicit", {"preconditioner": "amg"}),
           ("implicit", {"preconditioner": "hybrid"}), ("implicit", {"preconditioner": "auto"}),
           ("mass-spring", {}), ("pbd", {}),
           ("pbd", {"pbd_variant": "jacobi"}),
           ("pbd", {"strain_limit": 0.1}), ("xpbd", {}), ("projective", {}), ("explicit", {})]


@pytest.mark.parametrize("method, solver", METHODS)
def test_pins_stay_fixed(method, solver):
    cfg = load_config({"mesh": {"grid": {"nx": 6, "ny": 6, "plane": "xz"}},
                       "material": {"damping": 0.01},
                       "scene": {"pins": ["top_corners", 3]},
                       "time": {"frames": 3}, "solver": {"method": method, **solver}})
    model = build_model(cfg)
    integ = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    pinned = state.x[model.pinned].copy()
    for _ in range(3):
        integ.step(state)
    assert np.array_equal(state.x[model.pinned], pinned)
    assert np.all(state.v[model.pinned] == 0.0)
    assert np.min(state.x[model.free][:, 1]) < 0.0  # the rest fell (PD slowest: ~4 mm)


@pytest.mark.parametrize("method, solver", METHODS)
def test_defaults_do_not_blow_up(method, solver):
    """The default material and solver settings (damping 0.01 s, one step per frame)
    on the hanging sheet: finite, bounded, and not torn apart."""
    nx = 6 if method == "explicit" else 12  # explicit with damping needs ~10⁴ steps per frame
    frames = 3 if method == "explicit" else 15
    run = run_in_memory({"mesh": {"grid": {"nx": nx, "ny": nx, "plane": "xz"}},
                         "scene": {"pins": ["top_corners"]}, "time": {"frames": frames},
                         "solver": {"method": method, **solver}}, (), warmup=False)
    assert run.ok, run.blew_up
    # PBD and XPBD at one step per frame and 10 sweeps are finite but stretchy (λ 3–7 on
    # this 12×12 sheet: docs/solvers.md recommends substeps); the others stay near 1
    assert run.max_stretch < (10.0 if method in ("pbd", "xpbd") else 1.5)


def test_spring_hessian_is_psd_and_matches_the_gradient():
    cfg = load_config(scene("mass-spring", nx=4))
    model = build_model(cfg)
    sp = model.springs
    rng = np.random.default_rng(1)
    x = model.mesh.positions + rng.normal(0, 0.1, model.mesh.positions.shape)
    from clothtool.sim.linalg.blocks import BlockMatrix, BlockPattern
    pattern = BlockPattern(model.n_vertices, sp.pairs)
    slots = pattern.slots(sp.pairs)
    grad = np.zeros_like(x)
    values = pattern.zeros()
    spring_assemble(x, sp.i, sp.j, sp.rest, sp.k, slots, grad, values)
    dense = BlockMatrix(pattern, values).to_scipy().toarray()
    assert np.allclose(dense, dense.T)
    assert np.linalg.eigvalsh(dense).min() > -1e-9 * np.abs(dense).max()
    # gradient by central differences
    from clothtool.sim.energies.springs import spring_energy
    eps = 1e-6
    fd = np.zeros_like(x)
    for v in range(model.n_vertices):
        for p in range(3):
            xp, xm = x.copy(), x.copy()
            xp[v, p] += eps
            xm[v, p] -= eps
            fd[v, p] = (spring_energy(xp, sp.i, sp.j, sp.rest, sp.k)
                        - spring_energy(xm, sp.i, sp.j, sp.rest, sp.k)) / (2 * eps)
    assert np.allclose(grad, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_spring_stiffness_reproduces_the_membrane_on_a_grid():
    model = build_model(load_config(scene("mass-spring", nx=5)))
    sp = model.springs
    axis = sp.structural[:len(sp) - sp.n_bend]
    k = sp.k[:len(sp) - sp.n_bend]
    assert np.isclose(k[axis].max(), model.stretch[0])  # interior structural springs
    assert np.isclose(k[~axis].max(), 2 * model.k_shear)  # diagonals


def test_config_validates_the_solver_keys():
    with pytest.raises(InputError, match="solver.method"):
        load_config({"mesh": {"grid": {}}, "solver": {"method": "pdb"}})
    with pytest.raises(InputError, match="did you mean 'pbd'"):
        load_config({"mesh": {"grid": {}}, "solver": {"method": "pdb"}})
    with pytest.raises(InputError, match="solver.pbd_variant"):
        load_config({"mesh": {"grid": {}}, "solver": {"pbd_variant": "gauss"}})
    with pytest.raises(InputError, match="solver.pbd_stiffness"):
        load_config({"mesh": {"grid": {}}, "solver": {"pbd_stiffness": 0}})
    with pytest.raises(InputError, match="solver.iterations"):
        load_config({"mesh": {"grid": {}}, "solver": {"iterations": 0}})


def test_simulate_writes_frames_with_every_method(tmp_path):
    from clothtool.sim.api import simulate

    for method in ("mass-spring", "pbd", "xpbd", "projective"):
        result = simulate({"mesh": {"grid": {"nx": 5, "ny": 5}}, "scene": {"pins": ["top_corners"]},
                           "time": {"frames": 2}, "solver": {"method": method}},
                          output_dir=tmp_path / method, progress=False)
        assert result.frames_written == 3
        assert (tmp_path / method / "frame_00002.ply").exists()


def test_a_method_refuses_a_feature_it_does_not_support():
    cfg = {"mesh": {"grid": {"nx": 4, "ny": 4}},
           "scene": {"colliders": [{"plane": {}}, {"sphere": {"friction": 0.3}}]},
           "solver": {"method": "pbd"}}
    with pytest.raises(InputError, match=r"^config: solver.method: 'pbd' does not support "
                                         r"scene.colliders\[1\].sphere.friction"):
        load_config(cfg)
    load_config({**cfg, "solver": {"method": "implicit"}})
    load_config({**cfg, "scene": {"colliders": [{"sphere": {}}]}})  # frictionless: projection
    with pytest.raises(InputError, match=r"^config: solver.method: 'vbd' does not support "
                                         r"solver.stiffness_continuation"):
        load_config({**cfg, "scene": {}, "solver": {"method": "vbd", "stiffness_continuation": 2}})


@pytest.mark.parametrize("method, solver", METHODS)
def test_a_saved_state_resumes_the_run_exactly(method, solver):
    """Everything a step reads from the past is in the State (contact memory included): a
    copy taken mid-run, stepped by a fresh integrator, ends bit for bit where the run does."""
    cfg = load_config({"mesh": {"grid": {"nx": 7, "ny": 7, "plane": "xz"}},
                       "material": {"damping": 0.0 if method == "explicit" else 0.01},
                       "scene": {"pins": [], "colliders": [
                           {"sphere": {"center": [0, -0.3, 0], "radius": 0.25,
                                       "friction": 0.3 if method == "implicit" else 0.0}}]},
                       "time": {"frames": 12}, "solver": {"method": method, **solver}})
    model = build_model(cfg)
    state = model.initial_state()
    integ = make_integrator(model, cfg.solver, cfg.step)
    for _ in range(6):
        integ.step(state)
    saved = state.copy()
    for _ in range(6):
        integ.step(state)
    resumed = make_integrator(model, cfg.solver, cfg.step)
    for _ in range(6):
        resumed.step(saved)
    assert np.array_equal(saved.x, state.x) and np.array_equal(saved.v, state.v)
    assert saved.time == state.time


# ---------------------------------------------------------------- hierarchical PBD


@settings(max_examples=25, deadline=None)
@given(st.integers(3, 24), st.integers(3, 24), st.sampled_from(["xy", "xz"]))
def test_pbd_hierarchy_levels_shrink_and_every_left_out_particle_follows_two_parents(nx, ny,
                                                                                   plane):
    from clothtool.sim.solvers.hierarchy import K_PARENTS, SHRINK, build_levels, coarse_masses

    model = build_model(load_config({"mesh": {"grid": {"nx": nx, "ny": ny, "plane": plane}}}))
    sp = model.springs
    edges = len(sp) - sp.n_bend
    rest = model.mesh.rest3d
    pinned = [0, model.n_vertices - 1]
    levels = build_levels(rest, sp.i[:edges], sp.j[:edges], keep=pinned)
    finer = np.arange(model.n_vertices)
    for lev in levels:
        assert len(lev.particles) <= SHRINK * len(finer)
        assert set(pinned) <= set(lev.particles)  # every level feels the pins
        assert set(lev.particles) | set(lev.fine) == set(finer)  # a partition of the finer level
        assert not set(lev.particles) & set(lev.fine)
        counts = np.diff(lev.parent_ptr)
        assert np.all(counts >= K_PARENTS)
        assert np.all(np.isin(lev.parent, lev.particles))
        np.testing.assert_allclose(np.add.reduceat(lev.weight, lev.parent_ptr[:-1]), 1.0)
        np.testing.assert_allclose(lev.rest, np.linalg.norm(rest[lev.i] - rest[lev.j], axis=1))
        finer = lev.particles
    for lev, mass in zip(levels, coarse_masses(model.mass, levels)):  # mass moves up, whole
        assert mass[lev.particles].sum() == pytest.approx(model.mass.sum(), rel=1e-12)


def test_pbd_hierarchy_prolongation_carries_a_rigid_motion_exactly():
    from clothtool.sim.solvers.hierarchy import build_levels, prolong

    model = build_model(load_config({"mesh": {"grid": {"nx": 9, "ny": 7}}}))
    sp = model.springs
    lev = build_levels(model.mesh.rest3d, sp.i, sp.j)[0]
    start = model.mesh.rest3d.copy()
    free = np.ones(model.n_vertices)
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    moved = start @ rot.T + [0.3, -0.2, 0.5]
    x = start.copy()
    x[lev.particles] = moved[lev.particles]
    prolong(x, start, lev.fine, lev.parent_ptr, lev.parent, lev.weight, free)
    # a translation is carried exactly; a rotation to first order (the fine particles are the
    # weighted mean of their parents' motions)
    x2 = start.copy()
    x2[lev.particles] = start[lev.particles] + [0.3, -0.2, 0.5]
    prolong(x2, start, lev.fine, lev.parent_ptr, lev.parent, lev.weight, free)
    np.testing.assert_allclose(x2, start + [0.3, -0.2, 0.5], atol=1e-14)
    assert np.abs(x - moved).max() < 0.2


def test_hierarchical_pbd_stretches_a_fine_sheet_far_less_at_the_same_sweeps():
    """A 32×32 sheet hanging from two corners, one step per frame, 10 sweeps: plain PBD lets it
    stretch to 39 times its length (a correction travels one edge per sweep), hierarchical PBD
    to 1.7; the pinned corners stay put."""
    stretch = {}
    for variant in ("gauss-seidel", "hierarchical"):
        cfg = load_config({"mesh": {"grid": {"nx": 32, "ny": 32, "plane": "xz"}},
                           "scene": {"pins": ["top_corners"]}, "time": {"fps": 30, "frames": 30},
                           "solver": {"method": "pbd", "pbd_variant": variant, "iterations": 10}})
        run = run_in_memory(cfg, (0, 30), warmup=False)
        assert run.ok
        model = build_model(cfg)
        np.testing.assert_array_equal(run.positions[30][model.pinned],
                                      run.positions[0][model.pinned])
        stretch[variant] = run.max_stretch
    assert stretch["hierarchical"] < 2.0 < 30.0 < stretch["gauss-seidel"]
