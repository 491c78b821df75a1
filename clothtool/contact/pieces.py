"""Stick–slip convergence: the residual on the rigid motions of each piece of cloth.

Friction's stick stiffness 2μλ/(ĥε_v) (:mod:`clothtool.contact.friction`) makes the Newton
steps of cloth that should start sliding tiny, so a step that looks converged can still
hold a slide back; the membrane's stiffness hides a slide from a per-vertex test the same
way (a whole sheet on an incline slides under forces that no single vertex's block
notices), while a per-vertex test against the mass alone never passes where the barrier,
the stick and the membrane hold large forces (the twisted sheet: 5–200 m/s at every
Newton step). Each piece P of cloth (a connected component of the mesh, mass M on its free
vertices, centre c, inertia I) splits the residual g (the gradient of the incremental
potential on the free vertices) into its rigid part, the acceleration a_v = F/M +
I⁻¹τ × (x_v − c) that the force F = Σ g_v and torque τ = Σ (x_v − c) × g_v give the piece
as a body, and the rest r_v = g_v − m_v a_v, which the membrane, the barrier and the
stick hold vertex by vertex. Their velocity changes within the step are

    rigid:  ĥ ‖a_v‖,    rest:  ‖D_v⁻¹ r_v‖ / ĥ,

D_v the vertex's diagonal block of Newton's matrix (m_v/ĥ² for a free vertex alone, so
that both read ĥ‖g_v‖/m_v on a lone vertex). A piece held by pins moves rigidly only as
its held vertices p let it, a + α × (x_p − c) = 0 (a piece held at one vertex turns about
it, at two about their line, at three off a line not at all): (a, α) is then the force's
projection onto those motions in the piece's mass metric; without it the twist, a sheet
held along two edges, read 1.1–1.4 times the rigid share at Newton steps whose every other
figure had converged, for a slide its pins forbid. Forces within a piece (membrane, cloth–cloth
barrier and stick) have no resultant and no moment, so the rigid part is what a slide of
the piece against its colliders, or against another piece, would release. A piece's
slide adds up step after step, so it is held to a share (RIGID_SHARE) of the tolerance.
Pieces smaller than the cloth's components (smoothed aggregation's aggregates, a vertex
and its ring) were measured: the membrane and barrier forces across their borders leave
0.3–1 m/s of rigid residual on the twisted sheet after 8 Newton steps, so the twist stayed
at its cap.
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner

# the share of newton_tolerance a piece's rigid velocity change may take: the 45° cloth-on-
# cloth slide of the friction benchmark came out 3.8 % slow at 1, 0.3 % at 0.3 (unchanged at
# 0.1), while the twist needs 3 Newton steps at 0.3 and 5 at 0.1
RIGID_SHARE = 0.3


def cloth_pieces(faces, n):
    """(n,) int64 piece of each of the n vertices of a triangle mesh (its connected
    component; a vertex on no triangle is a piece of its own), and the number of pieces."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    links = coo_matrix((np.ones(3 * len(faces)), (faces.ravel(), np.roll(faces, 1, axis=1).ravel())),
                       shape=(n, n))
    count, piece = connected_components(links, directed=False)
    return piece.astype(np.int64), int(count)


@njit_inner(cache=True)
def _inverse_psd(a):
    """The pseudo-inverse of a symmetric PSD matrix (eigenvalues below 1e-12 of the largest
    dropped: a piece on a line does not turn about it)."""
    w, q = np.linalg.eigh(a)
    top = max(w[-1], 0.0)
    k = a.shape[0]
    out = np.zeros((k, k))
    for m in range(k):
        if w[m] > 1e-12 * top and w[m] > 0.0:
            for i in range(k):
                for j in range(k):
                    out[i, j] += q[i, m] * q[j, m] / w[m]
    return out


@njit_inner(cache=True)
def _cross_matrix(r):
    """[r]×, the matrix of r × ·."""
    out = np.zeros((3, 3))
    out[0, 1], out[0, 2], out[1, 2] = -r[2], r[1], -r[0]
    out[1, 0], out[2, 0], out[2, 1] = r[2], -r[1], r[0]
    return out


@njit_inner(cache=True)
def _held_modes(c_tc):
    """(6, k) orthonormal basis of the rigid modes (a, L α) that the held vertices allow:
    the null space of CᵀC (``c_tc``, 6 × 6), eigenvalues below 1e-10 of the largest."""
    w, q = np.linalg.eigh(c_tc)
    k = 0
    for m in range(6):
        if w[m] <= 1e-10 * w[5]:
            k += 1
    return q[:, :k].copy()


@njit(cache=True)
def rigid_accelerations(x, g, mass, piece, count, held):
    """(N, 3) a_v = a + α × (x_v − c) of each vertex's piece (see the module): the
    rigid-body acceleration that the forces g (N, 3) give each piece; 0 on a piece with no
    free mass. mass (N,) 0 on vertices held in place; ``held`` (N,) marks them (pins): a
    piece turns and slides only as its held vertices let it, a + α × (x_p − c) = 0 at each
    held p, so (a, α) is the force's projection onto those modes in the piece's mass metric
    (none for a piece held at three points off a line)."""
    n = x.shape[0]
    big_m = np.zeros(count)
    c = np.zeros((count, 3))
    f = np.zeros((count, 3))
    for v in range(n):
        p = piece[v]
        big_m[p] += mass[v]
        for i in range(3):
            c[p, i] += mass[v] * x[v, i]
            f[p, i] += g[v, i]
    for p in range(count):
        if big_m[p] > 0.0:
            for i in range(3):
                c[p, i] /= big_m[p]
    tau = np.zeros((count, 3))
    inertia = np.zeros((count, 3, 3))
    for v in range(n):
        p = piece[v]
        if mass[v] == 0.0:
            continue
        r0, r1, r2 = x[v, 0] - c[p, 0], x[v, 1] - c[p, 1], x[v, 2] - c[p, 2]
        tau[p, 0] += r1 * g[v, 2] - r2 * g[v, 1]
        tau[p, 1] += r2 * g[v, 0] - r0 * g[v, 2]
        tau[p, 2] += r0 * g[v, 1] - r1 * g[v, 0]
        rr = r0 * r0 + r1 * r1 + r2 * r2
        r = (r0, r1, r2)
        for i in range(3):
            inertia[p, i, i] += mass[v] * rr
            for j in range(3):
                inertia[p, i, j] -= mass[v] * r[i] * r[j]
    # the held vertices' constraints C = [I, −[r/L]×] on (a, L α), L the radius of gyration
    length = np.ones(count)
    c_tc = np.zeros((count, 6, 6))
    n_held = np.zeros(count, np.int64)
    for p in range(count):
        if big_m[p] > 0.0:
            trace = inertia[p, 0, 0] + inertia[p, 1, 1] + inertia[p, 2, 2]
            if trace > 0.0:
                length[p] = np.sqrt(trace / big_m[p])
    for v in range(n):
        p = piece[v]
        if not held[v] or big_m[p] == 0.0:
            continue
        n_held[p] += 1
        r = np.empty(3)
        for i in range(3):
            r[i] = (x[v, i] - c[p, i]) / length[p]
        cm = np.zeros((3, 6))
        rx = _cross_matrix(r)
        for i in range(3):
            cm[i, i] = 1.0
            for j in range(3):
                cm[i, 3 + j] = -rx[i, j]
        c_tc[p] += cm.T @ cm
    acc = np.zeros((count, 3))
    alpha = np.zeros((count, 3))
    for p in range(count):
        if big_m[p] == 0.0:
            continue
        if n_held[p] == 0:  # a free piece: F/M and I⁻¹τ
            for i in range(3):
                acc[p, i] = f[p, i] / big_m[p]
            alpha[p] = _inverse_psd(inertia[p]) @ tau[p]
            continue
        z = _held_modes(c_tc[p])
        if z.shape[1] == 0:
            continue
        metric = np.zeros((6, 6))  # the piece's mass in (a, L α)
        force = np.empty(6)
        for i in range(3):
            metric[i, i] = big_m[p]
            force[i] = f[p, i]
            force[3 + i] = tau[p, i] / length[p]
            for j in range(3):
                metric[3 + i, 3 + j] = inertia[p, i, j] / length[p] ** 2
        q = z @ (_inverse_psd(z.T @ metric @ z) @ (z.T @ force))
        for i in range(3):
            acc[p, i] = q[i]
            alpha[p, i] = q[3 + i] / length[p]
    a = np.zeros((n, 3))
    for v in range(n):
        p = piece[v]
        if big_m[p] == 0.0:
            continue
        r0, r1, r2 = x[v, 0] - c[p, 0], x[v, 1] - c[p, 1], x[v, 2] - c[p, 2]
        a[v, 0] = acc[p, 0] + alpha[p, 1] * r2 - alpha[p, 2] * r1
        a[v, 1] = acc[p, 1] + alpha[p, 2] * r0 - alpha[p, 0] * r2
        a[v, 2] = acc[p, 2] + alpha[p, 0] * r1 - alpha[p, 1] * r0
    return a


@njit_inner(cache=True)
def _solved_norm(d, b):
    """‖d⁻¹ b‖ for a nonsingular 3×3 d (Cramer's rule)."""
    c00 = d[1, 1] * d[2, 2] - d[1, 2] * d[2, 1]
    c01 = d[1, 2] * d[2, 0] - d[1, 0] * d[2, 2]
    c02 = d[1, 0] * d[2, 1] - d[1, 1] * d[2, 0]
    det = d[0, 0] * c00 + d[0, 1] * c01 + d[0, 2] * c02
    x0 = (c00 * b[0] + (d[0, 2] * d[2, 1] - d[0, 1] * d[2, 2]) * b[1]
          + (d[0, 1] * d[1, 2] - d[0, 2] * d[1, 1]) * b[2])
    x1 = (c01 * b[0] + (d[0, 0] * d[2, 2] - d[0, 2] * d[2, 0]) * b[1]
          + (d[0, 2] * d[1, 0] - d[0, 0] * d[1, 2]) * b[2])
    x2 = (c02 * b[0] + (d[0, 1] * d[2, 0] - d[0, 0] * d[2, 1]) * b[1]
          + (d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0]) * b[2])
    return np.sqrt(x0 * x0 + x1 * x1 + x2 * x2) / abs(det)


@njit(cache=True)
def piece_velocities(x, g, mass, diag, h_eff, piece, count, held):
    """(rigid, rest): the largest velocity change (m/s) within the step that the residual g
    (N, 3) makes through the rigid motions of the pieces, and through the rest against the
    diagonal blocks diag (N, 3, 3) (see the module); mass (N,) 0 on vertices held in place
    (left out; ``held`` marks them), piece (N,) each vertex's piece of ``count``."""
    a = rigid_accelerations(x, g, mass, piece, count, held)
    rigid = 0.0
    rest = 0.0
    res = np.empty(3)
    for v in range(x.shape[0]):
        if mass[v] == 0.0:
            continue
        rigid = max(rigid, h_eff * np.sqrt(a[v, 0] ** 2 + a[v, 1] ** 2 + a[v, 2] ** 2))
        for i in range(3):
            res[i] = g[v, i] - mass[v] * a[v, i]
        rest = max(rest, _solved_norm(diag[v], res) / h_eff)
    return rigid, rest


def slide_velocity(x, g, mass, diag, h_eff, piece, count, held):
    """max(rigid / RIGID_SHARE, rest) of :func:`piece_velocities` (m/s): Newton's residual
    test where friction holds cloth."""
    rigid, rest = piece_velocities(x, g, mass, diag, h_eff, piece, count, held)
    return max(rigid / RIGID_SHARE, rest)
