"""The linear algebra of the Newton step: SPD block inverses, the preconditioners on
ill-conditioned contact blocks, and the two scenes that crashed the multigrid setup (issue 17).
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.contact.shapes import capsule
from clothtool.io.ply import write_ply
from clothtool.sim.api import simulate
from clothtool.sim.linalg.blocks import BlockMatrix, ConstraintFilter
from clothtool.sim.linalg.pcg import BlockJacobi, filtered_pcg, make_preconditioner
from clothtool.sim.model.config import GridSpec, load_config
from clothtool.sim.model.mesh import grid_mesh
from clothtool.sim.model.builder import build_model
from clothtool.sim.solvers.implicit import ImplicitEuler
from clothtool.vec3 import spd_inverse3


def barrier_block(k, n, m):
    """k n nᵀ + m I: a contact barrier's Gauss–Newton block over the inertia m/h²."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    nn = np.outer(n, n)
    return k * nn + m * np.eye(3), (np.eye(3) - nn) / m + nn / (k + m)


@settings(max_examples=200, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(0.0, 26.0),
       st.floats(-2.0, 4.0))
def test_spd_inverse_of_barrier_blocks_matches_the_closed_form(nx, ny, nz, log_k, log_m):
    """(k nnᵀ + mI)⁻¹ = (I − nnᵀ)/m + nnᵀ/(k + m) for k/m up to 1e26, to the precision the
    stored block keeps (its entries carry rounding ε·k, so m is known to ε·k/m; above
    k/m ≈ 1e14 it is lost, and the floor m restores it)."""
    if nx * nx + ny * ny + nz * nz < 1e-2:
        return
    m, ratio = 10.0**log_m, 10.0**log_k
    a, exact = barrier_block(ratio * m, [nx, ny, nz], m)
    out = np.empty((3, 3))
    spd_inverse3(a, m, out)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, out.T, rtol=0, atol=1e-14 / m)
    within = min(0.05, max(1e-7, 8 * np.finfo(float).eps * ratio))  # cofactors: ~ε/HADAMARD
    assert np.abs(out - exact).max() <= within * np.abs(exact).max()


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=9, max_size=9), st.floats(1e-3, 1e3))
def test_spd_inverse_of_well_conditioned_blocks_is_the_inverse(entries, shift):
    b = np.array(entries).reshape(3, 3)
    a = b @ b.T + shift * np.eye(3)
    out = np.empty((3, 3))
    spd_inverse3(a, 0.0, out)
    np.testing.assert_allclose(out @ a, np.eye(3), atol=1e-9)


def test_spd_inverse_where_the_cofactor_determinant_is_zero():
    """k/2 + 1 rounds to k/2 at k = 2e20: the stored block [[K, K, 0], [K, K, 0], [0, 0, 1]] has
    determinant exactly 0 (the cofactor inverse divided by it: ZeroDivisionError)."""
    a, exact = barrier_block(2e20, [1.0, 1.0, 0.0], 1.0)
    cofactor_det = (a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
                    - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
                    + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))
    assert cofactor_det == 0.0
    out = np.empty((3, 3))
    spd_inverse3(a, 1.0, out)
    np.testing.assert_allclose(out, exact, atol=1e-12)
    spd_inverse3(a, 0.0, out)  # no floor known: finite and positive semi-definite
    assert np.all(np.isfinite(out)) and np.linalg.eigvalsh(out).min() > -1e-12 * np.abs(out).max()
    spd_inverse3(np.full((3, 3), np.nan), 1.0, out)
    assert np.all(np.isnan(out))


def contact_system(k):
    """The Newton matrix of a pinned 12×12 sheet with barrier blocks k nnᵀ (k up to 1e22·m/h²)
    on a few vertices, as its diagonal blocks and the coupling between neighbours."""
    cfg = load_config({"mesh": {"grid": {"nx": 12, "ny": 12}}, "scene": {"pins": ["top_edge"]}})
    model = build_model(cfg)
    integ = ImplicitEuler(model, cfg.solver, cfg.step)
    rng = np.random.default_rng(3)
    x = model.mesh.positions + 0.01 * rng.normal(size=model.mesh.positions.shape)
    matrix = BlockMatrix(model.pattern)
    integ.elastic.assemble(x, np.zeros_like(x), matrix.values)
    inertia = model.mass / cfg.step**2
    matrix.add_diagonal(inertia)
    hit = [5, 17, 40, 41, 77]
    for v, n in zip(hit, [[1, 1, 0], [0, 0, 1], [1, 2, 3], [1, 2, 3], [1, 1, 0]]):
        matrix.values[model.pattern.diag[v]] += barrier_block(k * inertia[v], n, 1.0)[0] - np.eye(3)
    return model, matrix


@pytest.mark.parametrize("preconditioner", ["jacobi", "multigrid", "amg"])
@pytest.mark.parametrize("k, tol", [(1e3, 1e-8), (1e12, 1e-2), (1e22, None)])
def test_preconditioners_stay_positive_definite_on_near_singular_barrier_blocks(preconditioner, k,
                                                                                tol):
    """Barrier blocks up to 1e22 times the inertia: the setup does not divide by zero, the
    preconditioner stays symmetric positive definite on the free space, and PCG solves as
    far as the stored matrix allows (its product carries rounding ε·k/m relative to the
    solution: at 1e22 nothing is left to solve to, and PCG ends finite)."""
    model, matrix = contact_system(k)
    constraints = ConstraintFilter(model.kind)
    pre = make_preconditioner(preconditioner, model.pattern, model.faces)
    pre.update(model.mesh.positions, constraints)
    pre.setup(matrix, constraints)
    n = model.n_vertices
    free = np.repeat(model.free, 3)
    out = np.empty((n, 3))
    cols = []
    for a in np.flatnonzero(free):
        e = np.zeros(3 * n)
        e[a] = 1.0
        if preconditioner != "jacobi":
            pre.apply(e.reshape(-1, 3), out)
        else:
            out = np.einsum("vij,vj->vi", pre.inverse, e.reshape(-1, 3))
        cols.append(out.ravel()[free].copy())
    b = np.array(cols).T
    np.testing.assert_allclose(b, b.T, atol=1e-10 * np.abs(b).max())
    eig = np.linalg.eigvalsh(0.5 * (b + b.T))  # the barrier directions get 1/(k + m) ≈ 0
    assert eig.min() >= -1e-12 * eig.max()
    rhs = np.random.default_rng(1).normal(size=(n, 3))
    sol = np.zeros_like(rhs)
    its, res = filtered_pcg(matrix, rhs, sol, constraints, tol or 1e-8, 2000, pre)
    assert np.all(np.isfinite(sol)) and np.isfinite(res)
    if tol is not None:
        assert res <= tol


@pytest.mark.parametrize("k, left", [(1e3, False), (1e22, True)])
def test_multigrid_block_inverses_are_spd_inverse3s_with_barrier_blocks_left_to_a_second_pass(k,
                                                                                            left):
    """The multigrid's fine block inverses are spd_inverse3's of the filtered diagonal blocks,
    bit for bit, floors included; at 1e22 the barrier blocks fail the cofactor test, which
    setup_levels leaves to its second pass (eigen_inverses), at 1e3 none does."""
    from clothtool.sim.linalg.filter import PINNED
    from clothtool.sim.linalg.multigrid import Hierarchy, setup_levels

    model, matrix = contact_system(k)
    constraints = ConstraintFilter(model.kind)
    pre = Hierarchy.for_mesh(model.pattern, model.faces)
    pending = setup_levels(matrix.values, constraints.kind, constraints.active, matrix.floor,
                           pre.arrays, pre.pending, pre.pending_floor)
    fine = {int(v) for v in pre.pending[:pending] if v < model.n_vertices}
    assert bool(fine) == left and fine <= {5, 17, 40, 41, 77}  # only barrier blocks
    pre.setup(matrix, constraints)
    expected = np.empty((3, 3))
    for v in range(model.n_vertices):
        pinned = model.kind[v] == PINNED
        block = np.eye(3) if pinned else matrix.values[model.pattern.diag[v]]
        spd_inverse3(block, 1.0 if pinned else matrix.floor[v], expected)
        np.testing.assert_array_equal(pre.diag_inv[v], expected)


@pytest.mark.parametrize("k", [1e3, 1e22])
def test_amg_fine_sweeps_are_those_of_the_matrix_rounded_to_single_precision(k):
    """The mode multigrid's fine and first coarse sweeps read single-precision copies of their
    matrices in double arithmetic: its cycle is bit for bit the cycle whose sweeps there read
    the matrices rounded to single precision (a fixed linear operator), and a block beyond
    single precision's range is clamped to it, not made infinite."""
    from clothtool.sim.linalg.multilevel import ModeMultigrid

    model, matrix = contact_system(k)
    constraints = ConstraintFilter(model.kind)
    single = ModeMultigrid(model.pattern, model.faces)
    double = ModeMultigrid(model.pattern, model.faces, smoother=np.float64)
    for pre in (single, double):
        pre.update(model.mesh.positions, constraints)
        pre.setup(matrix, constraints)
    rhs = np.random.default_rng(2).normal(size=(model.n_vertices, 3))
    rhs[~model.free] = 0.0
    out_single, out_double, out_exact = (np.empty_like(rhs) for _ in range(3))
    single.apply(rhs, out_single)
    double.apply(rhs, out_exact)
    double.fine[:] = matrix.values.astype(np.float32)
    double.first[:] = double.first.astype(np.float32)
    double.apply(rhs, out_double)
    assert single.fine.dtype == single.first.dtype == np.float32
    np.testing.assert_array_equal(out_single, out_double)
    assert not np.array_equal(out_single, out_exact)  # the rounding is there to see
    np.testing.assert_allclose(out_single, out_exact, rtol=0,
                               atol=1e-4 * np.abs(out_exact).max())
    matrix.values[model.pattern.diag[5]] = 1e60 * np.eye(3)  # beyond single precision
    single.setup(matrix, constraints)
    assert np.all(np.isfinite(single.fine))
    assert np.abs(single.fine[model.pattern.diag[5]]).max() == np.finfo(np.float32).max
    single.apply(rhs, out_single)
    assert np.all(np.isfinite(out_single))


@pytest.mark.parametrize("material", [{}, {"damping_model": "strain", "stretch": 2e4}])
def test_animated_capsule_through_a_hanging_sheet_runs_to_the_end(tmp_path, material):
    """Issue 17 (a): a capsule mesh of radius 8 cm moving at 0.6 m/s through a 20×20 sheet
    pinned along its top edge, 0.3 m above its lower edge. Barrier blocks reach 1e22 times
    the inertia: their cofactor inverses were indefinite or divided by zero in the multigrid
    setup, and after each CCD-cut step the stale PCG guess made Newton repeat the cut step.
    With ``damping_model: strain`` (and 2e4 N/m) the Newton steps that still carried the
    capsule were solved loosely, one PCG iteration each: the capsule stopped 1.9 cm short
    at frame 29."""
    x, faces = capsule(radius=0.08, half_length=0.2, around=24, rings=6)
    folder = tmp_path / "capsule"
    folder.mkdir()
    for k in range(31):
        write_ply(folder / f"capsule_{k:03d}.ply", x + [0.0, -0.2, -0.2 + 0.6 * k / 30], faces)
    result = simulate({"mesh": {"grid": {"nx": 20, "ny": 20, "plane": "xy"}},
                       "material": material,
                       "scene": {"pins": ["top_edge"],
                                 "colliders": [{"mesh": {"frames": str(folder), "fps": 30}}]},
                       "time": {"fps": 30, "frames": 30}, "output": {"dir": str(tmp_path / "out")}},
                      progress=False)
    assert result.frames_written == 31


def test_crumpled_sheet_at_64_steps_per_frame_runs_to_the_end(tmp_path):
    """Issue 17 (b): a 16×16 sheet released from random displacements of up to 0.6 cell
    (folded and inverted triangles, whose hinges give near-singular bending blocks) at 64
    steps per frame."""
    mesh = grid_mesh(GridSpec(nx=16, ny=16, plane="xz"))
    rng = np.random.default_rng(0)
    x = mesh.positions + rng.uniform(-0.6, 0.6, mesh.positions.shape) / 15
    write_ply(tmp_path / "crumpled.ply", x, mesh.faces,
              vertex_properties={"s": mesh.uv[:, 0], "t": mesh.uv[:, 1]})
    result = simulate({"mesh": {"ply": str(tmp_path / "crumpled.ply")},
                       "solver": {"substeps": 64}, "time": {"fps": 30, "frames": 10},
                       "output": {"dir": str(tmp_path / "out")}}, progress=False)
    assert result.frames_written == 11 and result.max_stretch < 3.0
