"""The near-null modes of cloth on each aggregate, and the prolongators they make.

A multigrid's coarse space must hold the error its smoother cannot reduce: the motions that
cost little energy. For a membrane these are the six rigid motions (three translations, three
rotations ω × d) and, because cloth is far softer in shear than in stretch (100–200× for the
presets), the two in-plane shears: a symmetric, traceless strain in the aggregate's tangent
plane, L d with L = e₁e₂ᵀ + e₂e₁ᵀ or e₁e₁ᵀ − e₂e₂ᵀ. Together they are every linear field
d ↦ t + W d of the aggregate's plane but its dilation (which stretches the fibres), so the
shear soft along any warp direction is in the space, and no uv is needed. Measured on
captured Newton systems of a hanging sheet (stretch 2e4 N/m, shear 100 N/m), two-level
PCG to 1e-6: 52–53 iterations with the rigid modes, 36–44 with the shears added.

Each node of a level carries M = 8 unknowns, the amplitudes of these modes about its own
centroid c and in its own frame (e₁, e₂ the two largest principal directions of its fine
vertices, n the normal), scaled by its radius ρ (the RMS distance of its vertices to c) so that
the columns have comparable norms (Vaněk et al. 1996 orthonormalise them instead; scaling needs
no QR and keeps the modes readable). The prolongator is geometric and exact on flat
aggregates:

- **fine → level 1**: vertex i of aggregate A gets Q_i = [I₃ | e_k × d / ρ_A | L_s d / ρ_A]
  (3×8), d = x_i − c_A;
- **level ℓ → ℓ+1**: node a of aggregate A gets T_a (8×8) with φ_a T_a = ψ_A on a's vertices:
  A's translations are a's; a rotation of A about c_A is a's rotation (× ρ_a/ρ_A) plus the
  translation e_k × (c_a − c_A)/ρ_A; a shear of A is the translation L(c_a − c_A)/ρ_A plus
  its projection on a's shears, (ρ_a/ρ_A)⟨L^A, L_j^a⟩/2 (the part of L^A out of a's plane, which
  a curved sheet has, is lost).

Pinned vertices take no part (their rows of Q are zero): the coarse levels see them as held.
Geometry is summed level by level (count, Σx, Σxxᵀ), so a build costs one pass over the
vertices and one over each coarse level's nodes.
"""

import numpy as np

from clothtool.numba_setup import njit

M = 8  # unknowns per coarse node: 3 translations, 3 rotations, 2 in-plane shears


@njit(cache=True)
def node_sums(x, free, agg, nc):
    """Per aggregate: the number of free vertices, Σx (3) and Σxxᵀ (3×3) over them."""
    count = np.zeros(nc)
    first = np.zeros((nc, 3))
    second = np.zeros((nc, 3, 3))
    for i in range(x.shape[0]):
        if not free[i]:
            continue
        a = agg[i]
        count[a] += 1.0
        for p in range(3):
            first[a, p] += x[i, p]
            for q in range(3):
                second[a, p, q] += x[i, p] * x[i, q]
    return count, first, second


@njit(cache=True)
def coarser_sums(count, first, second, agg, nc):
    """The sums of the next level: each aggregate's are the sums of its nodes' (scalar loops: an
    array expression such as ``f[b] += first[a]`` would cost numba seconds of compilation)."""
    c = np.zeros(nc)
    f = np.zeros((nc, 3))
    s = np.zeros((nc, 3, 3))
    for a in range(count.shape[0]):
        b = agg[a]
        c[b] += count[a]
        for p in range(3):
            f[b, p] += first[a, p]
            for q in range(3):
                s[b, p, q] += second[a, p, q]
    return c, f, s


@njit(cache=True)
def node_frames(count, first, second):
    """Centroid c (n, 3), radius ρ (n,) and frame (n, 3, 3) whose rows are e₁, e₂ (the two
    largest principal directions of the node's vertices) and the normal. A node with no free
    vertex, or all of them at one point, has ρ = 0: only its translations are modes."""
    n = count.shape[0]
    centroid = np.zeros((n, 3))
    radius = np.zeros(n)
    frame = np.zeros((n, 3, 3))
    cov = np.empty((3, 3))
    for a in range(n):
        if count[a] == 0.0:
            continue
        for p in range(3):
            centroid[a, p] = first[a, p] / count[a]
        for p in range(3):
            for q in range(3):
                cov[p, q] = second[a, p, q] / count[a] - centroid[a, p] * centroid[a, q]
        trace = cov[0, 0] + cov[1, 1] + cov[2, 2]
        if not trace > 0.0:
            continue
        radius[a] = np.sqrt(trace)
        _, vectors = np.linalg.eigh(cov)  # ascending eigenvalues
        for p in range(3):
            frame[a, 0, p] = vectors[p, 2]
            frame[a, 1, p] = vectors[p, 1]
            frame[a, 2, p] = vectors[p, 0]
    return centroid, radius, frame


@njit(cache=True)
def _shear(frame, s, out):
    """out = L_s of a frame: e₁e₂ᵀ + e₂e₁ᵀ (s = 0) or e₁e₁ᵀ − e₂e₂ᵀ (s = 1)."""
    for p in range(3):
        for q in range(3):
            if s == 0:
                out[p, q] = frame[0, p] * frame[1, q] + frame[1, p] * frame[0, q]
            else:
                out[p, q] = frame[0, p] * frame[0, q] - frame[1, p] * frame[1, q]


@njit(cache=True, inline="always")
def _rotations(d0, d1, d2, out):
    """out[:3, 3 + k] = e_k × d: the rotations' columns of a translation row block."""
    out[1, 3], out[2, 3] = -d2, d1
    out[0, 4], out[2, 4] = d2, -d0
    out[0, 5], out[1, 5] = -d1, d0


@njit(cache=True, inline="always")
def _translation_rows(point, centroid, rho, frame, shear, out):
    """out[:3] = [I₃ | e_k × d | L_s d], d = (point − centroid)/ρ: the rows of a node's
    translations in the modes of its aggregate (centroid, radius ρ, PCA ``frame``); only I₃
    for an aggregate of one point (ρ = 0). ``shear`` (2, 3, 3) receives L_s."""
    for p in range(3):
        out[p, p] = 1.0
    if rho == 0.0:
        return
    d0 = (point[0] - centroid[0]) / rho
    d1 = (point[1] - centroid[1]) / rho
    d2 = (point[2] - centroid[2]) / rho
    _rotations(d0, d1, d2, out)
    for s in range(2):  # s from a loop: a literal s would compile _shear once per value
        _shear(frame, s, shear[s])
    for s in range(2):
        for p in range(3):
            out[p, 6 + s] = shear[s, p, 0] * d0 + shear[s, p, 1] * d1 + shear[s, p, 2] * d2


@njit(cache=True)
def fine_prolongator(x, free, agg, centroid, radius, frame, q):
    """q[i] (3×8) = the modes of vertex i's aggregate at x_i (zero for a pinned vertex)."""
    shear = np.empty((2, 3, 3))
    for i in range(x.shape[0]):
        q[i] = 0.0
        if free[i]:
            a = agg[i]
            _translation_rows(x[i], centroid[a], radius[a], frame[a], shear, q[i])


@njit(cache=True)
def coarse_prolongator(count, centroid, radius, frame, agg, c_centroid, c_radius, c_frame, t):
    """t[a] (8×8): the modes of node a's aggregate A in a's own modes (see the module)."""
    la = np.empty((2, 3, 3))
    lb = np.empty((2, 3, 3))
    for a in range(count.shape[0]):
        t[a] = 0.0
        if count[a] == 0.0:
            continue
        b = agg[a]
        # A's modes at a's centroid: its translations, the translations e_k × (c_a − c_A)/ρ_A
        # of its rotations and L_s (c_a − c_A)/ρ_A of its shears
        _translation_rows(centroid[a], c_centroid[b], c_radius[b], c_frame[b], lb, t[a])
        rho = c_radius[b]
        if rho == 0.0 or radius[a] == 0.0:
            continue
        # a's own rotations and shears, scaled by ρ_a/ρ_A
        ratio = radius[a] / rho
        for k in range(3):
            t[a, 3 + k, 3 + k] = ratio
        for s in range(2):
            _shear(frame[a], s, la[s])
        for s in range(2):
            for j in range(2):
                inner = 0.0
                for p in range(3):
                    for r in range(3):
                        inner += lb[s, p, r] * la[j, p, r]
                t[a, 6 + j, 6 + s] = 0.5 * ratio * inner
