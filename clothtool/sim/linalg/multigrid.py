"""Aggregation multigrid with the rigid-body modes, used as the PCG preconditioner
(``solver.preconditioner``).

Block-Jacobi PCG needs O(√κ) iterations and κ grows like k h²/m, so stiff cloth
at one step per frame takes hundreds. A multilevel preconditioner removes the
smooth error that a local smoother cannot reach. What is smooth for an elastic
sheet is what costs it no strain: the six rigid motions of a patch, three
translations and three rotations (the near-null space of Vaněk, Mandel & Brezina
1996, "Algebraic multigrid by smoothed aggregation for second and fourth order
elliptic problems", §3). A coarse space of translations only misses the in-plane
rotations and the bending of a patch about its own lines.

- **Setup, once per mesh** (only the patterns): greedy aggregation (Vaněk et al.
  phases 1–3: an aggregate is a vertex and its free neighbours, left-overs join a
  neighbouring aggregate) of the triangle adjacency, then of each coarse pattern,
  until at most ``COARSEST`` nodes remain. Each block slot (i, j) of a level maps to
  the slot (agg i, agg j) of the next.
- **Per solve** (:func:`setup_levels`): the tentative prolongator of each
  aggregate by a QR of its near-null space (Vaněk et al. §3, eq. 3.3): on the mesh
  B_i = [I | −[x_i − o]×] (3×6, the rigid motions about the centroid o at the
  current positions), B_agg = Q R, the rows of Q are the prolongator's blocks
  P_i (3×6 on the mesh, 6×6 below) and R (6×6) is the aggregate's near-null space
  on the next level, so P B_c = B exactly. Pinned vertices have zero rows (they do
  not move), and a mode an aggregate cannot carry (three vertices on a line do not
  turn about it) is dropped. The coarse matrices are the Galerkin products
  A_c = Pᵀ A P, one pass over each level's blocks; the fine operator is the
  filtered S A S + (I − S) that PCG works with. The coarsest level is factored
  densely (Cholesky).
- **Cycle** (:func:`vcycle`): a multiplicative V-cycle with one forward block
  Gauss–Seidel sweep before each coarse correction and one backward sweep after
  it (Saad, "Iterative Methods for Sparse Linear Systems", 2nd ed., §13.2–13.3). The
  backward sweep is the adjoint of the forward one, so the cycle is symmetric, and
  positive definite since the floored block inverses D̃ satisfy 2D̃ − D ≻ 0: a
  valid PCG preconditioner.
"""

import numpy as np
from numba import njit

from clothtool.sim.filter import FREE, PINNED, SLIDING
from clothtool.sim.linalg.blocks import BlockPattern
from clothtool.vec3 import spd_inverse3

COARSEST = 32  # nodes at which the hierarchy stops (dense Cholesky of ≤ 6·32 unknowns)
OMEGA = 0.6  # block-Jacobi smoothing weight (λmax(D⁻¹A) ≤ 2 for these matrices)
PIVOT = 1e-12  # smallest Cholesky pivot relative to its diagonal entry
DROP = 1e-8  # a mode whose part beyond the aggregate's other modes is this small is dropped
MODES = 6  # rigid-body modes per coarse node


@njit(cache=True)
def _aggregate(row_ptr, col):
    """Greedy aggregation of a graph; returns (aggregate of each node, number of aggregates)."""
    n = row_ptr.shape[0] - 1
    agg = np.full(n, -1, dtype=np.int64)
    count = 0
    # phase 1: a node whose neighbours are all free starts an aggregate with them
    for i in range(n):
        if agg[i] >= 0:
            continue
        free = True
        for s in range(row_ptr[i], row_ptr[i + 1]):
            if agg[col[s]] >= 0:
                free = False
                break
        if free:
            for s in range(row_ptr[i], row_ptr[i + 1]):
                agg[col[s]] = count
            count += 1
    # phase 2: left-overs join an aggregate of a neighbour
    first = agg.copy()
    for i in range(n):
        if first[i] >= 0:
            continue
        for s in range(row_ptr[i], row_ptr[i + 1]):
            if first[col[s]] >= 0:
                agg[i] = first[col[s]]
                break
    # phase 3: what is still alone forms aggregates with its unaggregated neighbours
    for i in range(n):
        if agg[i] >= 0:
            continue
        for s in range(row_ptr[i], row_ptr[i + 1]):
            if agg[col[s]] < 0:
                agg[col[s]] = count
        agg[i] = count
        count += 1
    return agg, count


class Hierarchy:
    """The multigrid preconditioner: levels of coarse patterns, flattened into arrays with
    per-level offsets for numba (:attr:`arrays`).

    Level 0 is the matrix pattern (``row_ptr``, ``col``); its aggregation follows
    ``graph`` = (row_ptr, col) of the triangle adjacency (bending widens the
    matrix pattern, which would make aggregates too large). ``positions`` (N, 3) are
    where the rigid modes are taken until :meth:`setup` is given others.
    """

    @classmethod
    def for_mesh(cls, pattern, faces, positions):
        """The hierarchy of a matrix pattern whose aggregation follows the triangles."""
        triangles = BlockPattern(pattern.n, faces)
        return cls(pattern.row_ptr, pattern.col, (triangles.row_ptr, triangles.col), positions)

    def setup(self, matrix, constraints, positions=None):
        """Prolongators (rigid modes at ``positions``, else those of the last setup), coarse
        matrices and block inverses of a :class:`~clothtool.sim.linalg.blocks.BlockMatrix`
        filtered by a :class:`~clothtool.sim.linalg.blocks.ConstraintFilter`."""
        if positions is not None:
            self.positions = np.ascontiguousarray(positions, dtype=np.float64)
        self.fine = (matrix.pattern.row_ptr, matrix.pattern.col, matrix.values, constraints.kind,
                     constraints.normal, constraints.active)
        setup_levels(*self.fine, matrix.floor, self.positions, self.arrays)

    def apply(self, rhs, out):
        """out = B rhs (one cycle; :meth:`setup` first)."""
        vcycle(rhs, out, self.fine[0], self.fine[1], self.arrays)

    def __init__(self, row_ptr, col, graph, positions):
        levels = [(row_ptr, col)]
        aggs = []
        while len(levels[-1][0]) - 1 > COARSEST:
            rp, cl = levels[-1]
            n = len(rp) - 1
            agg, nc = _aggregate(*(graph if not aggs else (rp, cl)))
            if nc >= n:  # cannot coarsen further
                break
            rows = np.repeat(np.arange(n), np.diff(rp))
            key = agg[rows] * nc + agg[cl]
            ukey = np.unique(key)
            counts = np.bincount(ukey // nc, minlength=nc)
            levels.append((np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
                           (ukey % nc).astype(np.int64)))
            aggs.append((agg, np.searchsorted(ukey, key).astype(np.int64)))
        if not aggs:
            raise ValueError("multigrid needs a mesh with more than COARSEST vertices")
        sizes = [len(rp) - 1 for rp, _ in levels]
        nnz = [len(cl) for _, cl in levels]
        self.positions = np.ascontiguousarray(positions, dtype=np.float64)
        self.node_off = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.block_off = np.concatenate([[0], np.cumsum(nnz)]).astype(np.int64)
        self.row_ptr = np.concatenate([rp for rp, _ in levels]).astype(np.int64)
        self.row_off = np.concatenate([[0], np.cumsum([s + 1 for s in sizes])]).astype(np.int64)
        self.col = np.concatenate([cl for _, cl in levels]).astype(np.int64)
        self.agg = np.concatenate([a for a, _ in aggs]).astype(np.int64)
        self.slot_map = np.concatenate([m for _, m in aggs]).astype(np.int64)
        # the nodes of each aggregate: members[node_off[l] + member_ptr[row_off[l+1] + a] …]
        # are those of aggregate a of level l + 1 (local node numbers of level l)
        # the slot of block (j, i) for each coarse slot (i, j), local to its level
        transpose = []
        for rp, cl in levels[1:]:
            nl = len(rp) - 1
            rows = np.repeat(np.arange(nl), np.diff(rp))
            transpose.append(np.searchsorted(rows * nl + cl, cl * nl + rows))
        self.transpose = np.concatenate(transpose).astype(np.int64)
        self.members = np.concatenate([np.argsort(a, kind="stable") for a, _ in aggs])
        self.member_ptr = np.zeros(self.row_off[-1], np.int64)
        for lev, (a, _) in enumerate(aggs):
            self.member_ptr[self.row_off[lev + 1] + 1:self.row_off[lev + 2]] = np.cumsum(
                np.bincount(a, minlength=sizes[lev + 1]))
        coarse = self.node_off[-1] - self.node_off[1]
        self.fine_p = np.zeros((sizes[0], 3, MODES))  # P blocks of the mesh's vertices
        self.coarse_p = np.zeros((coarse, MODES, MODES))  # P blocks of coarse nodes (not the last)
        self.modes = np.zeros((coarse, MODES, MODES))  # near-null space of each coarse node
        self.values = np.zeros((self.block_off[-1] - self.block_off[1], MODES, MODES))
        self.fine_inv = np.zeros((sizes[0], 3, 3))
        self.coarse_inv = np.zeros((coarse, MODES, MODES))
        self.coarsest = np.zeros((MODES * sizes[-1], MODES * sizes[-1]))
        self.t = np.zeros((sizes[0], 3))
        self.u = np.zeros((sizes[0], 3))
        self.filtered = np.zeros((nnz[0], 3, 3))  # S A S + (I − S) on the mesh
        self.r = np.zeros((coarse, MODES))
        self.z = np.zeros((coarse, MODES))
        self.w = np.zeros((coarse, MODES))
        self.inverse = np.zeros((0, 3, 3))  # the V-cycle has its own diagonal inverses
        # the tuple the numba kernels take (NO_MULTIGRID has the same layout, no levels)
        self.arrays = (self.node_off, self.block_off, self.row_ptr, self.row_off, self.col,
                       self.agg, self.slot_map, self.members, self.member_ptr, self.fine_p,
                       self.coarse_p, self.modes, self.values, self.fine_inv, self.coarse_inv,
                       self.coarsest, self.t, self.r, self.z, self.w, self.filtered, self.u,
                       self.transpose)


_I = np.zeros(1, np.int64)
_E = np.zeros(0, np.int64)
NO_MULTIGRID = (_I, _I, _I, _I, _E, _E, _E, _E, _E, np.zeros((0, 3, MODES)),
                np.zeros((0, MODES, MODES)), np.zeros((0, MODES, MODES)),
                np.zeros((0, MODES, MODES)), np.zeros((0, 3, 3)), np.zeros((0, MODES, MODES)),
                np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((0, MODES)), np.zeros((0, MODES)),
                np.zeros((0, MODES)), np.zeros((0, 3, 3)), np.zeros((0, 3)), _E)


@njit(cache=True)
def _filtered_block(b, i, j, kind, normal, out):
    """out = S_i B S_j (+ (I − S_i) on the diagonal, so held vertices stay non-singular)."""
    out[:, :] = b
    for side in range(2):
        v = i if side == 0 else j
        if kind[v] == PINNED:
            out[:, :] = 0.0
        elif kind[v] == SLIDING:
            n = normal[v]
            for q in range(3):
                if side == 0:  # rows: (I − nnᵀ) out
                    d = n[0] * out[0, q] + n[1] * out[1, q] + n[2] * out[2, q]
                    for p in range(3):
                        out[p, q] -= n[p] * d
                else:  # columns: out (I − nnᵀ)
                    d = out[q, 0] * n[0] + out[q, 1] * n[1] + out[q, 2] * n[2]
                    for p in range(3):
                        out[q, p] -= d * n[p]
    if i == j:
        if kind[i] == PINNED:
            for p in range(3):
                out[p, p] += 1.0
        elif kind[i] == SLIDING:
            for p in range(3):
                for q in range(3):
                    out[p, q] += normal[i, p] * normal[i, q]


@njit(cache=True, inline="always")
def _fine_block(values, s, i, j, kind, normal, constrained, block):
    """block = the filtered fine block of slot s = (i, j)."""
    if constrained and (kind[i] != FREE or kind[j] != FREE):
        _filtered_block(values[s], i, j, kind, normal, block)
    else:
        for p in range(3):
            for q in range(3):
                block[p, q] = values[s, p, q]


@njit(cache=True)
def _orthonormalise(a, rows, r):
    """a[:rows] = Q, r = R of a[:rows] = Q R (modified Gram–Schmidt, twice, Giraud et al.
    2005 "twice is enough"); a column with a part beyond the others below DROP × its norm
    is zero in Q and its row zero in R."""
    r[:, :] = 0.0
    for k in range(MODES):
        norm0 = 0.0
        for i in range(rows):
            norm0 += a[i, k] * a[i, k]
        norm0 = np.sqrt(norm0)
        for _ in range(2):
            for m in range(k):
                d = 0.0
                for i in range(rows):
                    d += a[i, m] * a[i, k]
                r[m, k] += d
                for i in range(rows):
                    a[i, k] -= d * a[i, m]
        norm = 0.0
        for i in range(rows):
            norm += a[i, k] * a[i, k]
        norm = np.sqrt(norm)
        if norm <= DROP * norm0 or norm == 0.0:
            for i in range(rows):
                a[i, k] = 0.0
        else:
            r[k, k] = norm
            for i in range(rows):
                a[i, k] /= norm


@njit(cache=True)
def _cholesky(a):
    """In-place lower Cholesky factor of a symmetric matrix; a pivot below PIVOT × its diagonal
    entry (lost to rounding, or a zero row) is replaced by that entry (1 for a zero entry), so
    the factor stays that of a symmetric positive definite matrix at least as large."""
    n = a.shape[0]
    for j in range(n):
        diagonal = a[j, j]
        d = diagonal
        for k in range(j):
            d -= a[j, k] * a[j, k]
        if not d > PIVOT * diagonal:
            d = diagonal if diagonal > 0.0 else 1.0
        d = np.sqrt(d)
        a[j, j] = d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / d


@njit(cache=True)
def _spd_inverse(a, out):
    """out = (L Lᵀ)⁻¹ for L the guarded Cholesky factor of a (:func:`_cholesky`)."""
    n = a.shape[0]
    lower = a.copy()
    for i in range(n):  # symmetrise: the Galerkin blocks carry rounding of both triangles
        for j in range(i):
            lower[i, j] = 0.5 * (a[i, j] + a[j, i])
    _cholesky(lower)
    inv = np.zeros((n, n))  # L⁻¹, lower triangular
    for c in range(n):
        inv[c, c] = 1.0 / lower[c, c]
        for i in range(c + 1, n):
            s = 0.0
            for k in range(c, i):
                s -= lower[i, k] * inv[k, c]
            inv[i, c] = s / lower[i, i]
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(max(i, j), n):
                s += inv[k, i] * inv[k, j]
            out[i, j] = s


@njit(cache=True)
def setup_levels(row_ptr0, col0, fine, kind, normal, constrained, floor, x, mg):
    """Prolongators, coarse matrices, block-diagonal inverses of every level, Cholesky of the
    coarsest, for the filtered fine matrix (``fine`` on pattern row_ptr0/col0).

    ``floor`` (N,): a lower bound of the eigenvalues of each fine diagonal block (the inertia
    m/ĥ²; zeros when unknown); a pinned vertex's filtered block is I (bound 1), a sliding
    one's at least min(floor, 1). The fine block inverses keep to it
    (:func:`~clothtool.vec3.spd_inverse3`): contact barriers near their singularity store
    blocks of 1e22·m/ĥ² whose small eigenvalues rounding has erased."""
    (node_off, block_off, row_ptr, row_off, col, agg, slot_map, members, member_ptr, fine_p,
     coarse_p, modes, values, fine_inv, coarse_inv, coarsest) = mg[:16]
    filtered = mg[20]
    levels = node_off.shape[0] - 1
    n = node_off[1]
    c1 = node_off[1]  # coarse node v is modes[v − c1]
    base = block_off[1]
    values[:, :, :] = 0.0
    # level 0: the filtered fine matrix and its block inverses
    for i in range(n):
        for s in range(row_ptr0[i], row_ptr0[i + 1]):
            _fine_block(fine, s, i, col0[s], kind, normal, constrained, filtered[s])
    for i in range(n):
        lower = floor[i]
        if constrained and kind[i] == PINNED:
            lower = 1.0
        elif constrained and kind[i] == SLIDING:
            lower = min(lower, 1.0)
        s = row_ptr0[i]
        while col0[s] != i:
            s += 1
        spd_inverse3(filtered[s], lower, fine_inv[i])
    # level 0 → 1: the rigid modes about the centroid, QR per aggregate
    centre = np.zeros(3)
    for i in range(n):
        for p in range(3):
            centre[p] += x[i, p] / n
    biggest = 0
    for a in range(node_off[2] - node_off[1]):
        biggest = max(biggest, member_ptr[row_off[1] + a + 1] - member_ptr[row_off[1] + a])
    for lev in range(1, levels - 1):
        for a in range(node_off[lev + 2] - node_off[lev + 1]):
            size = member_ptr[row_off[lev + 1] + a + 1] - member_ptr[row_off[lev + 1] + a]
            biggest = max(biggest, 2 * size)
    stack = np.zeros((3 * biggest, MODES))
    r = np.empty((MODES, MODES))
    for a in range(node_off[2] - node_off[1]):
        lo, hi = member_ptr[row_off[1] + a], member_ptr[row_off[1] + a + 1]
        for k in range(hi - lo):
            i = members[lo + k]
            rows = stack[3 * k:3 * k + 3]
            rows[:, :] = 0.0
            if constrained and kind[i] == PINNED:
                continue
            d0, d1, d2 = x[i, 0] - centre[0], x[i, 1] - centre[1], x[i, 2] - centre[2]
            for p in range(3):
                rows[p, p] = 1.0
            # rotation about axis e_k: e_k × d
            rows[1, 3], rows[2, 3] = -d2, d1
            rows[0, 4], rows[2, 4] = d2, -d0
            rows[0, 5], rows[1, 5] = -d1, d0
            if constrained and kind[i] == SLIDING:
                for q in range(MODES):
                    dn = normal[i, 0] * rows[0, q] + normal[i, 1] * rows[1, q] + normal[i, 2] * rows[2, q]
                    for p in range(3):
                        rows[p, q] -= dn * normal[i, p]
        _orthonormalise(stack, 3 * (hi - lo), r)
        for k in range(hi - lo):
            fine_p[members[lo + k]] = stack[3 * k:3 * k + 3]
        modes[a] = r
    # levels ≥ 1 → next: QR of the stacked near-null spaces of each aggregate's nodes
    for lev in range(1, levels - 1):
        n0 = node_off[lev]
        for a in range(node_off[lev + 2] - node_off[lev + 1]):
            lo, hi = member_ptr[row_off[lev + 1] + a], member_ptr[row_off[lev + 1] + a + 1]
            for k in range(hi - lo):
                stack[MODES * k:MODES * k + MODES] = modes[n0 + members[n0 + lo + k] - c1]
            _orthonormalise(stack, MODES * (hi - lo), r)
            for k in range(hi - lo):
                coarse_p[n0 + members[n0 + lo + k] - c1] = stack[MODES * k:MODES * k + MODES]
            modes[node_off[lev + 1] + a - c1] = r
    # Galerkin level 0 → 1: A_c[agg i, agg j] += P_iᵀ A_ij P_j
    t = np.empty((3, MODES))
    for i in range(n):
        if constrained and kind[i] == PINNED:
            continue
        pi = fine_p[i]
        for s in range(row_ptr0[i], row_ptr0[i + 1]):
            j = col0[s]
            if constrained and kind[j] == PINNED:
                continue
            b = filtered[s]
            pj = fine_p[j]
            for p in range(3):
                for q in range(MODES):
                    t[p, q] = b[p, 0] * pj[0, q] + b[p, 1] * pj[1, q] + b[p, 2] * pj[2, q]
            target = values[slot_map[s]]
            for p in range(MODES):
                for q in range(MODES):
                    target[p, q] += pi[0, p] * t[0, q] + pi[1, p] * t[1, q] + pi[2, p] * t[2, q]
    # coarse levels: block inverses, Galerkin to the next
    tc = np.empty((MODES, MODES))
    transpose = mg[22]
    for lev in range(1, levels):
        n0, b0, r0 = node_off[lev], block_off[lev], row_off[lev]
        # A_ij = ½(A_ij + A_jiᵀ): the products round differently on the two sides (by
        # ε × 1e22·m/ĥ² next to a contact barrier), and the sweeps need A exactly symmetric
        for s in range(block_off[lev + 1] - b0):
            u = transpose[b0 - base + s]
            if u < s:
                continue
            a, c = values[b0 + s - base], values[b0 + u - base]
            for p in range(MODES):
                for q in range(MODES if u > s else p + 1):
                    avg = 0.5 * (a[p, q] + c[q, p])
                    a[p, q] = avg
                    c[q, p] = avg
        for i in range(node_off[lev + 1] - n0):
            pi = coarse_p[n0 + i - c1]
            for s in range(row_ptr[r0 + i], row_ptr[r0 + i + 1]):
                src = values[b0 + s - base]
                j = col[b0 + s]
                if lev == levels - 1:
                    continue
                if j == i:
                    _spd_inverse(src, coarse_inv[n0 + i - c1])
                pj = coarse_p[n0 + j - c1]
                for p in range(MODES):
                    for q in range(MODES):
                        acc = 0.0
                        for m in range(MODES):
                            acc += src[p, m] * pj[m, q]
                        tc[p, q] = acc
                target = values[block_off[lev + 1] + slot_map[b0 + s] - base]
                for p in range(MODES):
                    for q in range(MODES):
                        acc = 0.0
                        for m in range(MODES):
                            acc += pi[m, p] * tc[m, q]
                        target[p, q] += acc
    last = levels - 1
    n0, b0, r0 = node_off[last], block_off[last], row_off[last]
    coarsest[:, :] = 0.0
    for i in range(node_off[last + 1] - n0):
        for s in range(row_ptr[r0 + i], row_ptr[r0 + i + 1]):
            j = col[b0 + s]
            for p in range(MODES):
                for q in range(MODES):
                    coarsest[MODES * i + p, MODES * j + q] = values[b0 + s - base, p, q]
    _cholesky(coarsest)  # reads the lower triangle only


@njit(cache=True)
def _cholesky_solve(lower, r, z, lo, hi):
    """z[lo:hi] = A⁻¹ r[lo:hi] with A = L Lᵀ, for (n, MODES) slices flattened row-major."""
    n = MODES * (hi - lo)
    y = np.empty(n)
    for i in range(n):
        s = r[lo + i // MODES, i % MODES]
        for k in range(i):
            s -= lower[i, k] * y[k]
        y[i] = s / lower[i, i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= lower[k, i] * y[k]
        y[i] = s / lower[i, i]
    for i in range(n):
        z[lo + i // MODES, i % MODES] = y[i]


@njit(cache=True)
def _fine_jacobi(row_ptr0, col0, fine, inv, rhs, z, out):
    """out = z + ω D̃⁻¹ (rhs − A z), one damped block-Jacobi sweep on the filtered fine matrix.

    Jacobi rather than Gauss–Seidel on the mesh: a Gauss–Seidel sweep in any order but the
    forward one (its adjoint runs backward) was measured 5–7× slower than a matrix product
    here (the product streams the blocks forward, a backward or coloured sweep does not)."""
    for i in range(rhs.shape[0]):
        s0, s1, s2 = rhs[i, 0], rhs[i, 1], rhs[i, 2]
        for s in range(row_ptr0[i], row_ptr0[i + 1]):
            j = col0[s]
            b = fine[s]
            s0 -= b[0, 0] * z[j, 0] + b[0, 1] * z[j, 1] + b[0, 2] * z[j, 2]
            s1 -= b[1, 0] * z[j, 0] + b[1, 1] * z[j, 1] + b[1, 2] * z[j, 2]
            s2 -= b[2, 0] * z[j, 0] + b[2, 1] * z[j, 1] + b[2, 2] * z[j, 2]
        m = inv[i]
        out[i, 0] = z[i, 0] + OMEGA * (m[0, 0] * s0 + m[0, 1] * s1 + m[0, 2] * s2)
        out[i, 1] = z[i, 1] + OMEGA * (m[1, 0] * s0 + m[1, 1] * s1 + m[1, 2] * s2)
        out[i, 2] = z[i, 2] + OMEGA * (m[2, 0] * s0 + m[2, 1] * s1 + m[2, 2] * s2)


@njit(cache=True)
def _fine_residual(row_ptr0, col0, fine, rhs, z, out):
    """out = rhs − A z on the filtered fine matrix."""
    for i in range(rhs.shape[0]):
        s0, s1, s2 = rhs[i, 0], rhs[i, 1], rhs[i, 2]
        for s in range(row_ptr0[i], row_ptr0[i + 1]):
            j = col0[s]
            b = fine[s]
            s0 -= b[0, 0] * z[j, 0] + b[0, 1] * z[j, 1] + b[0, 2] * z[j, 2]
            s1 -= b[1, 0] * z[j, 0] + b[1, 1] * z[j, 1] + b[1, 2] * z[j, 2]
            s2 -= b[2, 0] * z[j, 0] + b[2, 1] * z[j, 1] + b[2, 2] * z[j, 2]
        out[i, 0] = s0
        out[i, 1] = s1
        out[i, 2] = s2


@njit(cache=True)
def _coarse_sweep(lev, mg, rhs, z, backward):
    """One block Gauss–Seidel sweep z_i += D_i⁻¹ (rhs − A z)_i on coarse level lev ≥ 1."""
    node_off, block_off, row_ptr, row_off, col = mg[:5]
    values, coarse_inv = mg[12], mg[14]
    c1 = node_off[1]
    n0, b0, r0, base = node_off[lev], block_off[lev], row_off[lev], block_off[1]
    size = node_off[lev + 1] - n0
    res = np.empty(MODES)
    for k in range(size):
        i = size - 1 - k if backward else k
        for p in range(MODES):
            res[p] = rhs[n0 + i - c1, p]
        for s in range(row_ptr[r0 + i], row_ptr[r0 + i + 1]):
            j = n0 + col[b0 + s] - c1
            b = values[b0 + s - base]
            for p in range(MODES):
                acc = 0.0
                for q in range(MODES):
                    acc += b[p, q] * z[j, q]
                res[p] -= acc
        m = coarse_inv[n0 + i - c1]
        for p in range(MODES):
            acc = 0.0
            for q in range(MODES):
                acc += m[p, q] * res[q]
            z[n0 + i - c1, p] += acc


@njit(cache=True)
def _coarse_residual(lev, mg, rhs, z, out):
    """out = rhs − A_lev z on coarse level lev ≥ 1."""
    node_off, block_off, row_ptr, row_off, col = mg[:5]
    values = mg[12]
    c1 = node_off[1]
    n0, b0, r0, base = node_off[lev], block_off[lev], row_off[lev], block_off[1]
    for i in range(node_off[lev + 1] - n0):
        for p in range(MODES):
            acc = rhs[n0 + i - c1, p]
            for s in range(row_ptr[r0 + i], row_ptr[r0 + i + 1]):
                j = n0 + col[b0 + s] - c1
                for q in range(MODES):
                    acc -= values[b0 + s - base, p, q] * z[j, q]
            out[n0 + i - c1, p] = acc


@njit(cache=True)
def vcycle(rhs, out, row_ptr0, col0, mg):
    """out = B rhs: a V-cycle; on the mesh a damped block-Jacobi sweep before and after the
    coarse correction, below it forward Gauss–Seidel down and backward Gauss–Seidel up."""
    (node_off, _, _, _, _, agg, _, _, _, fine_p, coarse_p, _, _, fine_inv, _, coarsest, t, r, z,
     w, fine, u) = mg[:22]
    levels = node_off.shape[0] - 1
    n = node_off[1]
    c1 = n
    for i in range(n):  # pre-smooth from zero: ω D̃⁻¹ rhs
        m = fine_inv[i]
        for p in range(3):
            u[i, p] = OMEGA * (m[p, 0] * rhs[i, 0] + m[p, 1] * rhs[i, 1] + m[p, 2] * rhs[i, 2])
    _fine_residual(row_ptr0, col0, fine, rhs, u, t)
    r[:, :] = 0.0
    for i in range(n):  # restrict: r_agg += P_iᵀ t_i
        c = agg[i]
        p = fine_p[i]
        for q in range(MODES):
            r[c, q] += p[0, q] * t[i, 0] + p[1, q] * t[i, 1] + p[2, q] * t[i, 2]
    for lev in range(1, levels - 1):  # down: pre-smooth, restrict the residual
        lo, hi = node_off[lev] - c1, node_off[lev + 1] - c1
        z[lo:hi] = 0.0
        _coarse_sweep(lev, mg, r, z, False)
        _coarse_residual(lev, mg, r, z, w)
        for i in range(lo, hi):
            c = hi + agg[node_off[lev] + i - lo]
            p = coarse_p[i]
            for q in range(MODES):
                acc = 0.0
                for m in range(MODES):
                    acc += p[m, q] * w[i, m]
                r[c, q] += acc
    _cholesky_solve(coarsest, r, z, node_off[levels - 1] - c1, node_off[levels] - c1)
    for lev in range(levels - 2, 0, -1):  # up: prolong the correction, post-smooth
        lo, hi = node_off[lev] - c1, node_off[lev + 1] - c1
        for i in range(lo, hi):
            c = hi + agg[node_off[lev] + i - lo]
            p = coarse_p[i]
            for m in range(MODES):
                acc = 0.0
                for q in range(MODES):
                    acc += p[m, q] * z[c, q]
                z[i, m] += acc
        _coarse_sweep(lev, mg, r, z, True)
    for i in range(n):  # finest level: prolong, post-smooth
        c = agg[i]
        p = fine_p[i]
        for m in range(3):
            acc = 0.0
            for q in range(MODES):
                acc += p[m, q] * z[c, q]
            u[i, m] += acc
    _fine_jacobi(row_ptr0, col0, fine, fine_inv, rhs, u, out)
