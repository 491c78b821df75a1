"""``vbd`` (Vertex Block Descent): the per-vertex systems against the assembled ones, the
colouring, free fall, the static equilibrium of the implicit method, determinism."""

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from clothtool.cli import main
from clothtool.sim.linalg.blocks import BlockMatrix
from clothtool.sim.model.config import load_config
from clothtool.sim.energies.membrane import membrane_element, membrane_vertex
from clothtool.sim.energies.energy import FemElastic
from clothtool.sim.model.methods import make_integrator
from clothtool.sim.model.builder import build_model
from clothtool.sim.solvers.vbd import colour_groups, vertex_system
from clothtool.sim.model.state import State


def setup(nx=5, ny=4, solver=None, **material):
    mat = {"stretch": [300.0, 900.0], "rest_stretch": [1.05, 0.95], "shear": 40.0, "bend": 1e-2,
           "damping": 0.05, **material}
    cfg = load_config({"mesh": {"grid": {"nx": nx, "ny": ny, "plane": "xz"}}, "material": mat,
                       "scene": {"pins": ["top_corners"]},
                       "solver": {"method": "vbd", **(solver or {})}})
    model = build_model(cfg)
    return model, make_integrator(model, cfg.solver, cfg.step), cfg.step


@pytest.mark.parametrize("material", [{}, {"bend_model": "dihedral"}, {"bend_model": "quadratic"},
                                      {"damping": 0.0}, {"bend": 0.0}],
                         ids=["hessian", "dihedral", "quadratic", "undamped", "no-bending"])
def test_vertex_systems_are_the_blocks_of_the_assembled_potential(material):
    """g_i and H_ii of every vertex equal row i of ∇E = M(x − y)/h² + ∇W(x) + D(x − x_n) and
    the diagonal block of M/h² + K(x) + D, D = (β/h) K(x_n), assembled as the implicit
    method assembles them."""
    model, vbd, h = setup(**material)
    rng = np.random.default_rng(0)
    x_n = model.mesh.positions + 0.02 * rng.normal(size=model.mesh.positions.shape)
    x = x_n + 0.03 * rng.normal(size=x_n.shape)
    state = State(x_n, rng.normal(size=x_n.shape))
    y = vbd._inertial_target(state)
    vbd.prepare(x_n)
    elastic = FemElastic(model)
    k_n, k_x = BlockMatrix(model.pattern), BlockMatrix(model.pattern)
    grad = np.zeros_like(x)
    elastic.assemble(x_n, np.zeros_like(x), k_n.values)
    elastic.assemble(x, grad, k_x.values)
    damping = model.damping / h * k_n.to_scipy().toarray()
    mass = np.repeat(model.mass, 3)
    big_g = mass * (x - y).ravel() / h**2 + grad.ravel() + damping @ (x - x_n).ravel()
    big_h = np.diag(mass / h**2) + k_x.to_scipy().toarray() + damping
    g, hm = np.empty(3), np.empty((3, 3))
    work = (np.empty(12),)
    for i in range(model.n_vertices):
        vertex_system(i, *vbd._args(x, x_n, y), g, hm, *work)
        np.testing.assert_allclose(g, big_g[3 * i:3 * i + 3], rtol=0, atol=1e-12 * np.abs(big_g).max())
        np.testing.assert_allclose(hm, big_h[3 * i:3 * i + 3, 3 * i:3 * i + 3], rtol=0,
                                   atol=1e-12 * np.abs(big_h).max())
        assert np.linalg.eigvalsh(hm).min() > 0.0


def test_membrane_vertex_is_the_diagonal_block_of_the_element_kernel():
    """membrane_vertex's gradient and 3×3 block equal corner a's rows of membrane_element's
    (FD-checked) gradient and projected Hessian, over stretched and compressed triangles,
    positive and negative shear, with and without each stiffness."""
    rng = np.random.default_rng(3)
    g9, h9, work = np.empty(9), np.empty((9, 9)), np.empty((6, 6))
    signs = set()
    for trial in range(300):
        x = rng.normal(size=(3, 3))
        dr_inv = rng.normal(size=(2, 2))
        stretch = np.array([rng.uniform(0, 5), rng.uniform(0, 5), rng.uniform(0.5, 1.5),
                            rng.uniform(0.5, 1.5)])
        stretch[trial % 3] = 0.0 if trial % 3 < 2 else stretch[2]
        k_shear = rng.uniform(0, 3) if trial % 4 else 0.0
        membrane_element(x[0], x[1], x[2], dr_inv, 0.7, stretch, k_shear, True, g9, h9, work)
        f = x[1:].T - x[0][:, None] @ np.ones((1, 2))
        signs.add(np.sign(np.dot(*(f @ dr_inv).T)))
        scale = np.abs(h9).max() + np.abs(g9).max()
        for a in range(3):
            g, h = np.zeros(3), np.zeros((3, 3))
            membrane_vertex(tuple(x[0]), tuple(x[1]), tuple(x[2]), dr_inv, 0.7, stretch, k_shear,
                            a, g, h)
            np.testing.assert_allclose(g, g9[3 * a:3 * a + 3], rtol=0, atol=1e-13 * scale)
            np.testing.assert_allclose(h, h9[3 * a:3 * a + 3, 3 * a:3 * a + 3], rtol=0,
                                       atol=1e-13 * scale)
    assert signs >= {-1.0, 1.0}


def test_colouring_is_valid_and_deterministic():
    model, vbd, _ = setup(nx=9, ny=7)
    ptr, vertices = vbd.colour_ptr, vbd.vertices
    assert sorted(vertices) == list(np.flatnonzero(model.free))  # every free vertex once
    colour = np.full(model.n_vertices, -1)
    for c in range(len(ptr) - 1):
        group = vertices[ptr[c]:ptr[c + 1]]
        assert len(group) and np.all(np.diff(group) > 0)
        colour[group] = c
    for elements in vbd.coupled:  # triangles, hinges and the plate's vertex pairs
        for e in elements:
            cs = colour[e][colour[e] >= 0]
            assert len(set(cs)) == len(cs), e  # no colour twice in one element
    again = colour_groups(model.n_vertices, vbd.coupled, model.free)
    assert np.array_equal(again[0], ptr) and np.array_equal(again[1], vertices)
    assert len(ptr) - 1 <= 12  # a grid with hinges needs few colours


def test_free_fall_is_exactly_implicit_euler():
    model, vbd, h = setup(nx=6, ny=6, rest_stretch=1.0)
    model.pinned = model.pinned[:0]
    model.free[:] = True
    vbd = type(vbd)(model, vbd.solver, h)
    state = model.initial_state()
    expected, v = state.x.copy(), np.zeros(3)
    for _ in range(10):
        vbd.step(state)
        v = v + h * model.gravity
        expected = expected + h * v
        np.testing.assert_allclose(state.x, expected, rtol=0, atol=1e-10)


def settle(method, frames, **solver):
    """A 1 m × 0.5 m sheet hanging from its top edge, starting upright (xy)."""
    cfg = load_config({"mesh": {"grid": {"nx": 9, "ny": 5, "height": 0.5, "plane": "xy"}},
                       "material": {"density": 0.2, "stretch": 500.0, "shear": 20.0,
                                    "bend": 1e-5, "damping": 0.01},
                       "scene": {"pins": ["top_edge"]}, "solver": {"method": method, **solver}})
    model = build_model(cfg)
    integrator = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    for _ in range(frames * cfg.solver.substeps):
        integrator.step(state)
    return state.x, integrator.energies(state)[0]


def test_vbd_reaches_the_static_equilibrium_of_the_implicit_method():
    x_implicit, kinetic = settle("implicit", 60, newton_iterations=10, newton_tolerance=1e-10,
                                 tolerance=1e-10)
    assert kinetic < 1e-12
    x_vbd, kinetic = settle("vbd", 120, iterations=20)
    assert kinetic < 1e-10
    assert np.abs(x_vbd[:, 1] - x_implicit[:, 1]).max() > 0.0
    assert np.linalg.norm(x_vbd - x_implicit, axis=1).max() < 1e-3  # within 1 mm


def test_converged_vbd_follows_backward_euler_to_the_implicit_equilibrium():
    """Sweeping each step until ‖∇E‖ ≤ 10⁻⁶ ‖M g‖, VBD minimises the same incremental
    potential as Newton-converged ``implicit``: on a damped 5×5 sheet falling from horizontal
    on two corners the two trajectories agree to 10 µm at every step, and both come to rest
    (the swing damped by backward Euler) at the same static equilibrium, within 1 mm."""
    def sheet(method, **solver):
        cfg = load_config({"mesh": {"grid": {"nx": 5, "ny": 5, "plane": "xz"}},
                           "material": {"density": 0.2, "stretch": 5000.0, "shear": 50.0,
                                        "bend": 1e-5, "damping": 0.01,
                                        "damping_model": "frozen"},  # VBD's damping
                           "scene": {"pins": ["top_corners"]},
                           "solver": {"method": method, **solver}})
        model = build_model(cfg)
        return make_integrator(model, cfg.solver, cfg.step), model.initial_state()

    implicit, a = sheet("implicit", integrator="euler", newton_iterations=30, newton_tolerance=1e-12,
                        tolerance=1e-12)
    vbd, b = sheet("vbd", iterations=100000, vbd_tolerance=1e-6, chebyshev_rho=0.99)
    swing, frames = 0.0, 0
    while implicit.energies(a)[0] > 1e-10 or frames < 30:
        implicit.step(a)
        report = vbd.step(b)
        assert report.residual <= 1e-6 and 1 < report.sweeps < 100000
        swing = max(swing, np.abs(a.x - a.x[0]).max())
        assert np.linalg.norm(a.x - b.x, axis=1).max() < 1e-5, frames
        frames += 1
        assert frames < 2000
    assert swing > 0.3  # it did fall and swing
    assert vbd.energies(b)[0] < 1e-9
    assert np.linalg.norm(a.x - b.x, axis=1).max() < 1e-3


def test_tolerance_stops_the_sweeps_at_a_small_true_gradient():
    """With a tolerance the sweeps stop once the sweep's residual is below it, and the true
    relative gradient ‖∇E(x)‖/‖M g‖ there (``residual``) is of the same size; without one,
    ``iterations`` sweeps run."""
    model, vbd, _ = setup(nx=6, ny=6)
    state = model.initial_state()
    state.v[:] = np.random.default_rng(2).normal(scale=0.2, size=state.v.shape)
    y, x = vbd._inertial_target(state), vbd._initial_guess(state)
    vbd.prepare(state.x)
    start = vbd.residual(x, state.x, y)
    done, r = vbd.solve(x, state.x, y, 100000, 0.9, 1e-8)
    assert start > 1e-2 and 1 < done < 100000 and r <= 1e-8
    assert vbd.residual(x, state.x, y) < 1e-7
    assert vbd.solve(vbd._initial_guess(state), state.x, y, 7)[0] == 7


@pytest.mark.parametrize("rho", [0.0, 0.8])
def test_same_config_gives_byte_identical_frames(tmp_path, rho):
    cfg = {"mesh": {"grid": {"nx": 12, "ny": 12, "plane": "xz"}},
           "scene": {"pins": ["top_corners"],
                     "colliders": [{"sphere": {"center": [0, -0.5, 0], "radius": 0.3}}]},
           "solver": {"method": "vbd", "iterations": 5, "chebyshev_rho": rho},
           "time": {"frames": 6}}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    for out in ("a", "b"):
        result = CliRunner().invoke(main, ["simulate", str(tmp_path / "c.yaml"), "-o",
                                           str(tmp_path / out), "-q"])
        assert result.exit_code == 0, result.output
    frames = sorted(p.name for p in (tmp_path / "a").glob("*.ply"))
    assert len(frames) == 7
    for name in frames:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_chebyshev_acceleration_is_the_semi_iterative_mix():
    """With ρ > 0 and at least 5 sweeps, sweep k's result x̄⁽ᵏ⁾ becomes ω_k(x̄⁽ᵏ⁾ − x⁽ᵏ⁻²⁾) + x⁽ᵏ⁻²⁾ (ω_1 = 1,
    ω_2 = 2/(2 − ρ²), ω_k = 4/(4 − ρ²ω_{k−1})), x⁽⁻¹⁾ = x⁽⁰⁾ the initial guess; checked
    against plain sweeps mixed by hand."""
    rho, sweeps = 0.7, 6
    model, vbd, _ = setup(nx=6, ny=6, solver={"iterations": sweeps, "chebyshev_rho": rho})
    start = model.initial_state()
    start.v[:] = np.random.default_rng(1).normal(scale=0.1, size=start.v.shape)
    state = start.copy()
    vbd.step(state)

    _, plain, _ = setup(nx=6, ny=6, solver={"iterations": 1})
    x_n = start.x
    y = plain._inertial_target(start)
    x = plain._initial_guess(start)
    plain.prepare(x_n)
    history = [x.copy(), x.copy()]  # x⁽ᵏ⁻²⁾, x⁽ᵏ⁻¹⁾
    omega = 1.0
    for k in range(sweeps):
        plain.sweep(x, x_n, y)
        omega = 1.0 if k == 0 else 2 / (2 - rho**2) if k == 1 else 4 / (4 - rho**2 * omega)
        x = omega * (x - history[0]) + history[0]
        history = [history[1], x.copy()]
    np.testing.assert_allclose(state.x, x, rtol=0, atol=1e-14)
    assert np.abs(x - history[0]).max() > 1e-6  # the sweeps did move it

    # below 5 sweeps per step the mix is off: ρ changes nothing
    few = [setup(nx=6, ny=6, solver={"iterations": 4, "chebyshev_rho": r})[1] for r in (0.0, rho)]
    states = [start.copy(), start.copy()]
    for integrator, s in zip(few, states):
        integrator.step(s)
    assert np.array_equal(states[0].x, states[1].x)
