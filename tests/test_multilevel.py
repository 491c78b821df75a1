"""The mode multigrid's pieces against what they promise: the prolongators hold every rigid
motion and in-plane shear of their aggregates, the Galerkin products equal Pᵀ A P, the
relaxation sweeps are block Gauss–Seidel, and the cycle is a symmetric positive definite
preconditioner that solves what the others solve."""

import numpy as np
import pytest
import scipy.sparse as sps
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.sim.linalg.aggregation import aggregate, coarsen, transposes
from clothtool.sim.linalg.blocks import BlockMatrix, BlockPattern, ConstraintFilter
from clothtool.sim.linalg.filter import FREE, PINNED
from clothtool.sim.linalg.galerkin import galerkin
from clothtool.sim.linalg.modes import (M, coarse_prolongator, coarser_sums, fine_prolongator,
                                        node_frames, node_sums)
from clothtool.sim.linalg.multilevel import ModeMultigrid
from clothtool.sim.linalg.relaxation import (block_inverses, forward_from_zero,
                                             forward_from_zero3, gauss_seidel, gauss_seidel3)
from clothtool.sim.model.mesh import grid_mesh
from clothtool.sim.model.config import GridSpec


def rotation(a, b, c):
    """A rotation matrix from three angles."""
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rz @ ry @ rx


def sheet(n, angles=(0.0, 0.0, 0.0), shift=(0.0, 0.0, 0.0)):
    """An n×n grid of 1 m, turned and moved rigidly: positions, faces, its triangle graph."""
    mesh = grid_mesh(GridSpec(nx=n, ny=n, width=1.0, height=1.0, plane="xz"))
    x = mesh.positions @ rotation(*angles).T + np.asarray(shift)
    graph = BlockPattern(len(x), mesh.faces)
    return x, mesh.faces, graph


def first_level(x, graph, free):
    agg, nc = aggregate(graph.row_ptr, graph.col)
    sums = node_sums(x, free, agg, nc)
    geometry = node_frames(*sums)
    q = np.zeros((len(x), 3, M))
    fine_prolongator(x, free, agg, *geometry, q)
    return agg, nc, sums, geometry, q


def prolongator_matrix(p, agg, nc):
    """P (n·b × nc·M) as a sparse matrix from its blocks."""
    n, b, m = p.shape
    rows = np.repeat(np.arange(n * b), m)
    cols = (m * np.repeat(agg, b)[:, None] + np.arange(m)).ravel()
    return sps.csr_matrix((p.ravel(), (rows, cols)), shape=(n * b, nc * m))


def residual_outside(p_matrix, field):
    """‖field − P c‖ / ‖field‖ for the least-squares c."""
    coef = sps.linalg.lsqr(p_matrix, field, atol=1e-14, btol=1e-14, iter_lim=10000)[0]
    return np.linalg.norm(field - p_matrix @ coef) / np.linalg.norm(field)


@settings(max_examples=25, deadline=None)
@given(st.tuples(*[st.floats(-np.pi, np.pi)] * 3), st.tuples(*[st.floats(-2, 2)] * 3),
       st.tuples(*[st.floats(-1, 1)] * 3), st.tuples(*[st.floats(-1, 1)] * 3),
       st.floats(-1, 1), st.floats(-1, 1))
def test_fine_prolongator_holds_rigid_motions_and_in_plane_shears(angles, shift, t, w, s1, s2):
    """On a flat sheet in any position, t + ω × x and every traceless symmetric strain of its
    plane (the shears that cost cloth little) are in the range of P, aggregate by aggregate."""
    x, _, graph = sheet(9, angles, shift)
    free = np.ones(len(x), bool)
    agg, nc, _, _, q = first_level(x, graph, free)
    p = prolongator_matrix(q, agg, nc)
    r = rotation(*angles)
    e1, e2 = r[:, 0], r[:, 2]  # the sheet's plane (xz before the turn)
    strain = s1 * (np.outer(e1, e2) + np.outer(e2, e1)) + s2 * (np.outer(e1, e1) - np.outer(e2, e2))
    field = np.asarray(t) + np.cross(np.asarray(w), x) + x @ strain.T
    if np.linalg.norm(field) < 1e-6:
        return
    assert residual_outside(p, field.ravel()) < 1e-9


def test_fine_prolongator_leaves_out_pinned_vertices_and_dilation():
    x, _, graph = sheet(9)
    free = np.ones(len(x), bool)
    free[[0, 8]] = False
    agg, nc, _, _, q = first_level(x, graph, free)
    assert np.all(q[~free] == 0.0)
    p = prolongator_matrix(q, agg, nc)
    dilation = (x - x.mean(0)) * np.array([1.0, 0.0, 1.0])  # stretches the fibres: not a mode
    assert residual_outside(p, dilation.ravel()) > 0.1


@settings(max_examples=15, deadline=None)
@given(st.tuples(*[st.floats(-np.pi, np.pi)] * 3), st.tuples(*[st.floats(-1, 1)] * 3),
       st.tuples(*[st.floats(-1, 1)] * 3), st.floats(-1, 1), st.floats(-1, 1))
def test_coarse_prolongators_carry_the_modes_down_every_level(angles, t, w, s1, s2):
    """P₀T₁T₂… of a flat sheet holds the rigid motions and in-plane shears on every level:
    the coarse transfer is exact where the aggregates share a plane."""
    x, faces, graph = sheet(17, angles)
    free = np.ones(len(x), bool)
    levels, maps = coarsen(graph.row_ptr, graph.col, (graph.row_ptr, graph.col), 2)
    assert len(maps) >= 3
    agg, nc = maps[0][0], len(levels[1][0]) - 1
    sums = node_sums(x, free, agg, nc)
    geometry = node_frames(*sums)
    q = np.zeros((len(x), 3, M))
    fine_prolongator(x, free, agg, *geometry, q)
    p = prolongator_matrix(q, agg, nc)
    r = rotation(*angles)
    e1, e2 = r[:, 0], r[:, 2]
    strain = s1 * (np.outer(e1, e2) + np.outer(e2, e1)) + s2 * (np.outer(e1, e1) - np.outer(e2, e2))
    field = (np.asarray(t) + np.cross(np.asarray(w), x) + x @ strain.T).ravel()
    if np.linalg.norm(field) < 1e-6:
        return
    for lev in range(1, len(maps)):
        cagg, cn = maps[lev][0], len(levels[lev + 1][0]) - 1
        csums = coarser_sums(*sums, cagg, cn)
        cgeometry = node_frames(*csums)
        tr = np.zeros((len(cagg), M, M))
        coarse_prolongator(sums[0], *geometry, cagg, *cgeometry, tr)
        p = p @ prolongator_matrix(tr, cagg, cn)
        assert residual_outside(p, field) < 1e-8, lev
        sums, geometry = csums, cgeometry


def random_block_matrix(row_ptr, col, b, rng):
    """A symmetric positive definite matrix on a block pattern, and its blocks."""
    n = len(row_ptr) - 1
    values = rng.normal(size=(len(col), b, b))
    a = sps.bsr_matrix((values, col, row_ptr), shape=(n * b, n * b)).toarray()
    a = a + a.T + 4 * b * np.abs(a).sum(1).max() * np.eye(n * b)
    blocks = np.array([a[b * i:b * i + b, b * j:b * j + b]
                       for i in range(n) for j in col[row_ptr[i]:row_ptr[i + 1]]])
    return a, blocks


def modes_form(b):
    """Where a prolongator block (b × M) of the modes may be non-zero, the identity's entries
    1: the translations' rows [I₃ | e_k × d | L_s d] (no k-th entry in rotation k's column)
    and, on a coarse level (b = M), a node's own rotations (diagonal) and shears (2×2)."""
    form = np.zeros((b, M))
    form[:3, :] = 1.0
    for k in range(3):
        form[k, 3 + k] = 0.0
    if b == M:
        form[3:, :3] = 0.0
        form[3:6, 3:6] = np.eye(3)
        form[6:, 6:] = 1.0
    return form


def test_prolongators_have_the_modes_form():
    """What :func:`galerkin` skips is zero in the prolongators a run builds: a curved sheet
    with a pinned vertex, every level (a node without a free vertex has no modes at all)."""
    x, faces, _ = sheet(17, (0.4, -0.3, 0.2))
    x[:, 1] += 0.2 * np.sin(3 * x[:, 0]) * np.cos(2 * x[:, 2])
    pattern = BlockPattern(len(x), faces)
    kind = np.full(len(x), FREE, np.int8)
    kind[0] = PINNED
    mg = ModeMultigrid(pattern, faces)
    mg.update(x, ConstraintFilter(kind))
    assert np.all(mg.q0[:, modes_form(3) == 0.0] == 0.0)
    assert np.all(mg.q0[0] == 0.0) and np.all(mg.q0[1:, :, :3] == np.eye(3))
    transfer = mg.transfer[:mg.node_off[-2]]  # the coarsest level transfers nowhere
    supported = transfer.any(axis=(1, 2))
    assert supported.sum() > 0.9 * len(supported)
    assert np.all(transfer[supported][:, :3, :3] == np.eye(3))
    assert np.all(mg.transfer[:, modes_form(M) == 0.0] == 0.0)


@pytest.mark.parametrize("pinned", [(), (3, 40)])
def test_galerkin_products_equal_the_sparse_triple_product(pinned):
    rng = np.random.default_rng(4)
    x, faces, graph = sheet(9, (0.3, 0.2, 0.1))
    pattern = BlockPattern(len(x), faces)
    levels, maps = coarsen(pattern.row_ptr, pattern.col, (graph.row_ptr, graph.col), 4)
    a, blocks = random_block_matrix(pattern.row_ptr, pattern.col, 3, rng)
    skip = np.zeros(len(x), bool)
    skip[list(pinned)] = True
    agg, slot_map = maps[0]
    nc = len(levels[1][0]) - 1
    sums = node_sums(x, ~skip, agg, nc)
    geometry = node_frames(*sums)
    q = np.zeros((len(x), 3, M))
    fine_prolongator(x, ~skip, agg, *geometry, q)
    out = np.zeros((len(levels[1][1]), M, M))
    galerkin(pattern.row_ptr, pattern.col, blocks, skip, slot_map, transposes(*levels[1]), q,
             out)
    p = prolongator_matrix(q, agg, nc).toarray()
    s = np.diag(np.repeat(~skip, 3).astype(float))
    expected = p.T @ s @ a @ s @ p
    got = sps.bsr_matrix((out, levels[1][1], levels[1][0]), shape=expected.shape).toarray()
    np.testing.assert_allclose(got, expected, atol=1e-12 * np.abs(expected).max())
    # and a coarse level through its own transfer blocks
    cagg, cslot = maps[1]
    cn = len(levels[2][0]) - 1
    tr = rng.normal(size=(nc, M, M)) * modes_form(M)
    tr[:, :3, :3] = np.eye(3)
    a1, cblocks = random_block_matrix(levels[1][0], levels[1][1], M, rng)
    cout = np.zeros((len(levels[2][1]), M, M))
    galerkin(levels[1][0], levels[1][1], cblocks, np.zeros(nc, bool), cslot,
             transposes(*levels[2]), tr, cout)
    t = prolongator_matrix(tr, cagg, cn).toarray()
    expected = t.T @ a1 @ t
    got = sps.bsr_matrix((cout, levels[2][1], levels[2][0]), shape=expected.shape).toarray()
    np.testing.assert_allclose(got, expected, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("b", [3, M])
def test_sweeps_are_block_gauss_seidel(b):
    rng = np.random.default_rng(6)
    x, faces, _ = sheet(6)
    pattern = BlockPattern(len(x), faces)
    a, blocks = random_block_matrix(pattern.row_ptr, pattern.col, b, rng)
    n = len(x)
    inv = np.array([np.linalg.inv(a[b * i:b * i + b, b * i:b * i + b]) for i in range(n)])
    r = rng.normal(size=(n, b))
    rows, cols = np.indices(a.shape) // b  # block row and column of every entry
    lower = np.where(rows >= cols, a, 0.0)
    upper = np.where(rows <= cols, a, 0.0)
    x0 = rng.normal(size=(n, b))
    expected_forward = x0.ravel() + np.linalg.solve(lower, r.ravel() - a @ x0.ravel())
    expected_backward = x0.ravel() + np.linalg.solve(upper, r.ravel() - a @ x0.ravel())
    sweep = gauss_seidel3 if b == 3 else gauss_seidel
    for forward, expected in ((True, expected_forward), (False, expected_backward)):
        got = x0.copy()
        sweep(pattern.row_ptr, pattern.col, pattern.diag, blocks, inv, r, got, forward)
        np.testing.assert_allclose(got.ravel(), expected, rtol=1e-10, atol=1e-12)
    got, res = np.zeros((n, b)), np.zeros((n, b))
    if b == 3:
        forward_from_zero3(pattern.row_ptr, pattern.col, pattern.diag, blocks,
                           blocks[pattern.diag], inv, r, got, res)
    else:
        forward_from_zero(pattern.row_ptr, pattern.col, pattern.diag, blocks, blocks, inv, r,
                          got, res)
    np.testing.assert_allclose(got.ravel(), np.linalg.solve(lower, r.ravel()), rtol=1e-10)
    np.testing.assert_allclose(res.ravel(), r.ravel() - a @ got.ravel(), atol=1e-10)


def test_fine_sweeps_subtract_blocks_in_stream_order():
    """The fine sweeps' floating-point order, bit for bit: the forward sweep subtracts a row's
    blocks first to last, the backward one last to first (one descending stream), each block's
    product summed over its columns in order; single-precision blocks in double arithmetic."""
    rng = np.random.default_rng(7)
    x, faces, _ = sheet(5)
    pattern = BlockPattern(len(x), faces)
    n = len(x)
    _, blocks = random_block_matrix(pattern.row_ptr, pattern.col, 3, rng)
    single = blocks.astype(np.float32)
    inv = rng.normal(size=(n, 3, 3))
    r, x0 = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    for forward in (True, False):
        expected = x0.copy()
        for i in (range(n) if forward else range(n - 1, -1, -1)):
            slots = [s for s in range(pattern.row_ptr[i], pattern.row_ptr[i + 1])
                     if s != pattern.diag[i]]
            t = [float(v) for v in r[i]]
            for s in (slots if forward else slots[::-1]):
                a, xj = single[s].astype(np.float64), expected[pattern.col[s]]
                for p in range(3):
                    t[p] -= a[p, 0] * xj[0] + a[p, 1] * xj[1] + a[p, 2] * xj[2]
            d = inv[i]
            expected[i] = [d[p, 0] * t[0] + d[p, 1] * t[1] + d[p, 2] * t[2] for p in range(3)]
        got = x0.copy()
        gauss_seidel3(pattern.row_ptr, pattern.col, pattern.diag, single, inv, r, got, forward)
        assert np.array_equal(got, expected)


def test_block_inverses_keep_to_the_supported_modes():
    """A coarse diagonal block whose node has modes without support (zero rows and columns, an
    aggregate of two vertices has no shear) is inverted on the rest, finite and symmetric."""
    rng = np.random.default_rng(2)
    g = rng.normal(size=(M, M))
    block = g @ g.T + np.eye(M)
    block[6:, :] = 0.0
    block[:, 6:] = 0.0
    out = np.zeros((1, M, M))
    block_inverses(block[None], np.array([0]), np.array([False]), out)
    np.testing.assert_allclose(out[0, :6, :6], np.linalg.inv(block[:6, :6]), rtol=1e-10)
    assert np.all(np.isfinite(out)) and np.allclose(out[0], out[0].T)
    block_inverses(block[None], np.array([0]), np.array([True]), out)
    assert np.all(out == 0.0)


def test_mode_multigrid_needs_a_mesh_to_coarsen():
    x, faces, _ = sheet(3)
    with pytest.raises(ValueError, match="COARSEST"):
        ModeMultigrid(BlockPattern(len(x), faces), faces)
