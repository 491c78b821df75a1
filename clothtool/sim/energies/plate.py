"""Plate bending with the stated flexural rigidity on any triangulation: the ``hessian`` model.

A sheet bent isometrically out of its flat pattern (u, v) has ∂²x/∂u_i∂u_j = II_ij n,
so the bending energy of a plate with flexural rigidity k_b (N·m) and zero Poisson
ratio, ∫ k_b/2 (κ₁² + κ₂²) dA = ∫ k_b/2 ‖∇²x‖²_F dA, is quadratic in x:

    W_bend(x) = k_b/2 Σ_c x_cᵀ Q x_c   (c = x, y, z; Q constant, N × N, PSD)

(Bergou et al. 2006, "A quadratic bending model for inextensible surfaces", with the
Hessian in place of their Laplacian: the Laplacian energy (κ₁ + κ₂)² lets a narrow strip
twist and saddle for free). Q is built once from the rest pattern:

1. the weak Hessian of each vertex v (the mixed finite elements of Stein et al. 2018,
   "Natural boundary conditions for smoothing in geometry processing"):
   S_v,ij(x) = ∮ φ_v n_i ∂_j x ds − ∫ ∂_iφ_v ∂_j x dA over the piecewise-linear x, with
   the boundary flux so that every affine x (rigid motions included) gives exactly 0;
   symmetrised, in the orthonormal components (H₀₀, √2 H₀₁, H₁₁);
2. calibrated per vertex so that it is exact on quadratic fields: with B_v the map from
   a quadratic's Hessian to S_v, Ĥ_v = B_v⁺ S_v. On a grid B_v = A_v I (nothing
   changes); on irregular meshes the raw weak Hessian is off by tens of per cent, vertex
   by vertex (the cantilever of a Delaunay mesh came out 11 % stiff without this step);
3. components a vertex cannot see (a singular direction of B_v: the twist at a vertex
   whose triangles all have their right angle there, the curvature across a free edge)
   or sees poorly (σ(B_v)/A_v < SEEN: calibrated by 1/σ, such a component would be 1/σ²
   times too stiff at that vertex: on a grid with its vertices jittered by 35 % of the
   spacing, σ down to 0.015 made the largest eigenvalue of Q thousands of times its grid's,
   PCG stalled and the sheet crept at rest) carry no energy at that vertex; the ring
   neighbours that see such a direction e take it over in proportion to their areas,
   W_v = P_v + Σ_w (A_w / Σ_ring A) e_w e_wᵀ, so that every direction is weighed by
   exactly its area, Σ_v A_v W_v = Σ_v A_v I, on any mesh, its free edges included: the
   weak Hessian sees no curvature across a free edge, and the boundary's half-cells get it
   from the vertices one row in. (Handing none over, "no moment across a free edge", left
   those half-cells without it: a uniform bend of a free 6 × 6 grid came out 17 % soft,
   12 × 12 9 %, 24 × 24 4 %: a plate softer on a coarse mesh than on a fine one.) Only a
   clamp, a boundary edge with both ends held, hands nothing across itself: the cloth is
   held flat there. A_v are mixed Voronoi areas (Meyer et al. 2003).

    W_bend = k_b/2 Σ_v A_v Ĥ_v(x)ᵀ W_v Ĥ_v(x),   Q = Σ_v A_v Ĥ_vᵀ W_v Ĥ_v

A quadratic field stores exactly ∫ k_b/2 ‖H‖² dA on a grid of any size (within 2 % on
coarse irregular discs), a cylinder bent along or across any triangulation stores
k_b κ²/2 per unit area, and the cantilever test (ASTM D1388) droops as the elastica says
(``tests/test_textile.py``).
The Hessian k_b Q ⊗ I₃ is constant and PSD; Q couples each vertex with (part of) its two-ring.

**The correction** (``material.plate_correction``). Ĥ_v is a hat-weighted average of ∇²x over
v's one-ring, so a fold of wavenumber k keeps only ≈ 1 − 0.15 (kh)² of its energy (0.82 at
k = 80/m on a 12 mm mesh, the Cusick drape's folds: a coarse disc drapes 5 points too low).
In one dimension the three-point second difference is f″ + h²/12 f⁗ + …, and
∫ (f″ + h²/12 f⁗)² ≈ ∫ f″² − h²/6 ∫ f‴² (by parts): the lost energy is h²/6 ∫ ‖∇H‖², which
is added back,

    C = β Σ_r H̃_rᵀ K_h H̃_r,   K_h = Σ_e w_e ℓ_e² (δ_v − δ_w)(δ_v − δ_w)ᵀ,   W = ½ xᵀ(Q + C)x,

w_e the cotan weights (clamped at 0), ℓ_e the edge's rest length, H̃_v the vertex's estimate
with the components it does not see filled in from the ring neighbours that do (so that a
quadratic field, whose Ĥ is the same at every vertex, gives C = 0: rolled sheets and uniform
twists store what Q alone stores), β = SHARPEN = 0.15 (fitted on plane waves over polar,
grid and Poisson-disc meshes: ≥ 0.95 of the exact energy up to kh ≈ 1; ``plate_correction:
fitted`` fits β on each mesh's own plane waves instead, :func:`fitted_sharpening`: the polar
rings need 0.18 at 12 mm, a grid 0.15). No edge between two
pinned vertices: a clamp's curvature jumps from zero to the moment's, which the correction
would otherwise stiffen (by 2–4 % on a cantilever of 20 divisions). C is PSD and zero on
affine maps; it couples a vertex with its three-ring, so the solvers' matrix keeps Q (the
time steppers' Newton steps with it; static equilibrium adds C to its direct solve).
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner

SEEN = 0.25  # a singular value of B_v/A_v below this: a component vertex v hands over
PRUNE = 1e-10  # |Q_ij| ≤ PRUNE·√(Q_ii Q_jj) is rounding of a cancelled entry: dropped
SQRT2 = np.sqrt(2.0)
SHARPEN = 0.15  # β of the corrected plate (module docstring)
FITTED = "fitted"  # sharpen: β fitted on the mesh (fitted_sharpening)
FIT_WAVE = 0.5  # kh of the plane waves β is fitted on


def hessian_bending_matrix(uv, faces, rigidity=None, anisotropy=1.0, held=None, *, sharpen=0.0):
    """Q (N × N scipy CSR, symmetric PSD) of a flat pattern uv (N, 2), faces (M, 3): unit
    rigidity, or Σ_v k_v A_v Ĥ_vᵀ W_v Ĥ_v with ``rigidity`` k_v (N,) per vertex; with
    ``sharpen`` β > 0, Q + C (:func:`plate_matrices`).

    ``held``: the vertices held in place (pins); a boundary edge with both ends held is a
    clamp, where the plate is held flat: its vertices' half-cells carry no curvature across
    it, and that component is not handed over.

    ``anisotropy`` B_u/B_v: the orthotropic plate ½(B_u x_uu² + 2k x_uv² + B_v x_vv²) with
    k = √(B_u B_v) (the twist at the geometric mean, Huber's plate with zero Poisson ratio) is
    the isotropic plate of rigidity k on the pattern (s, t) = (u/a, a v), a = (B_u/B_v)^(1/8):
    x_ss = a² x_uu, x_tt = x_vv/a², x_st = x_uv and dA_st = dA_uv, so k a⁴ = B_u, k/a⁴ = B_v.
    Every property above (exact on quadratics, each direction weighed by its area) carries
    over."""
    q, c = plate_matrices(uv, faces, rigidity, anisotropy, held, sharpen=sharpen)
    return q if c is None else _pruned(q + c)


def plate_matrices(uv, faces, rigidity=None, anisotropy=1.0, held=None, *, sharpen=0.0):
    """(Q, C): the plate's Q (:func:`hessian_bending_matrix`) and, with ``sharpen`` β > 0,
    the correction C of its smoothing (module docstring; None when β = 0), both scipy CSR;
    ``sharpen`` = FITTED: β fitted on this mesh (:func:`fitted_sharpening`).
    ``held``: the pinned vertices (a clamp; no correction between two of them either)."""
    import scipy.sparse as sps  # 0.4 s to import: only models with plate bending pay it

    a = anisotropy ** 0.125
    uv = np.asarray(uv, np.float64) * np.array([1.0 / a, a])
    uv = uv - uv.mean(axis=0)
    faces = np.asarray(faces, np.int64)
    n = len(uv)
    grad, area, sign = _hat_gradients(uv, faces)
    weak = _weak_hessian(uv, faces, grad, area, sign, n)
    mass = mixed_voronoi_areas(uv, faces)
    # B_v: the weak Hessian of the quadratics with unit orthonormal Hessian components
    x, y = uv[:, 0], uv[:, 1]
    monomials = (0.5 * x * x, x * y / SQRT2, 0.5 * y * y)
    b = np.stack([np.stack([s @ q for q in monomials], axis=1) for s in weak], axis=1)  # (N, 3, 3)
    u, sv, vt = np.linalg.svd(b / mass[:, None, None])
    seen = sv > SEEN
    inv = np.where(seen, 1.0 / np.where(seen, sv, 1.0), 0.0)
    calib = np.einsum("nka,nk,nbk->nab", vt, inv, u)  # B⁺ A (pseudo-inverse of B/A)
    proj = np.einsum("nka,nk,nkb->nab", vt, seen.astype(np.float64), vt)
    clamped, normal = _clamped(uv, faces, sign, n, held)
    yn = np.stack([normal[:, 0] ** 2, SQRT2 * normal[:, 0] * normal[:, 1], normal[:, 1] ** 2], 1)
    weight = proj + _taken_over(faces, n, mass, proj, clamped, yn)
    # Ĥ_r = Σ_c calib[:, r, c] S_c / A ;  Q = Σ_rc Ĥ_rᵀ diag(A W_rc) Ĥ_c
    hat = [sum(sps.diags(calib[:, r, c] / mass) @ weak[c] for c in range(3)).tocsr()
           for r in range(3)]
    k = np.ones(n) if rigidity is None else np.asarray(rigidity, np.float64)
    q = sps.csr_matrix((n, n))
    for r in range(3):
        for c in range(3):
            q = q + hat[r].T @ sps.diags(k * mass * weight[:, r, c]) @ hat[c]
    if sharpen != FITTED and sharpen <= 0.0:
        return _pruned(q), None
    full = _completed(hat, faces, n, mass, proj)
    lap = _edge_laplacian(uv, faces, k, held)
    c = sum(full[r].T @ lap @ full[r] for r in range(3))
    if sharpen == FITTED:
        sharpen = fitted_sharpening(uv, hat, full, weight, mass, k, lap, held)
    return _pruned(q), _pruned(sharpen * c)


def fitted_sharpening(uv, hat, full, weight, mass, k, lap, held):
    """β of ``plate_correction: fitted``: the mesh's own, so that plane waves at kh = FIT_WAVE
    (h = √ of the median A_v) keep their exact energy summed over the interior vertices,

        β = Σ_v (E_v − Q_v) / Σ_v C_v,   E_v = ½ k_v A_v |k|⁴,   Q_v = ½ k_v A_v Ĥ_vᵀ W_v Ĥ_v,

    C_v half of each of v's edges' k_e w_e ℓ_e² ‖ΔH̃‖² (C at β = 1), each summed over cos and
    sin of the wave (their Hessians' squares add to |k|⁴) in 8 directions; v over the
    vertices with a share of C that are not held (the free rim's half-cells and the clamp
    would weigh in their own boundary losses, which C does not model: over every vertex β
    came out 0.27–0.30 on every disc). The 12 mm Cusick discs: polar 0.184, grid 0.152,
    Poisson-disc 0.159 (the single β = 0.15 under-corrects the polar rings: on the folds'
    harmonics cos nφ, n = 12 … 24, their plate lost 3–8 % more than the grid's)."""
    import scipy.sparse as sps

    edges = sps.triu(lap, k=1).tocoo()
    i, j, w = edges.row, edges.col, -edges.data  # each edge once: k_e w_e ℓ_e²
    wave = FIT_WAVE / np.sqrt(np.median(mass))
    exact = np.zeros(len(uv))
    lumped = np.zeros(len(uv))
    share = np.zeros(len(uv))
    for angle in np.pi * np.arange(8) / 8:
        direction = wave * np.array([np.cos(angle), np.sin(angle)])
        for z in (np.cos(uv @ direction), np.sin(uv @ direction)):
            h = np.stack([m @ z for m in hat], axis=1)
            ht = np.stack([m @ z for m in full], axis=1)
            lumped += 0.5 * k * mass * np.einsum("na,nab,nb->n", h, weight, h)
            de = 0.25 * w * ((ht[i] - ht[j]) ** 2).sum(axis=1)
            np.add.at(share, i, de)
            np.add.at(share, j, de)
        exact += 0.5 * k * mass * wave ** 4
    inner = share > 1e-12 * exact
    if held is not None:
        inner[np.asarray(held, np.int64)] = False
    if share[inner].sum() <= 0.0:
        return SHARPEN
    return max((exact[inner] - lumped[inner]).sum() / share[inner].sum(), 0.0)


def _pruned(q):
    """Symmetrised CSR without the entries that cancel to rounding."""
    import scipy.sparse as sps

    n = q.shape[0]
    q = (0.5 * (q + q.T)).tocoo()
    # entries that cancel to rounding (half of them on clothtool's grid: its diagonals carry no
    # weak-Hessian weight) would only widen the solver's matrix
    diag = np.abs(q.diagonal())
    keep = np.abs(q.data) > PRUNE * np.sqrt(diag[q.row] * diag[q.col])
    q = sps.csr_matrix((q.data[keep], (q.row[keep], q.col[keep])), shape=(n, n))
    q.sort_indices()
    return q


def _completed(hat, faces, n, mass, proj):
    """H̃_r (three N × N CSR): each vertex's Hessian estimate Ĥ_v with the components it does
    not see (I − P_v) filled in from the ring neighbours that see them, in proportion to their
    areas: H̃_v = Ĥ_v + Σ_e Σ_w α_vw e eᵀ Ĥ_w; exact on quadratics wherever a neighbour sees
    each direction (the hand-over of :func:`_taken_over`, read the other way)."""
    import scipy.sparse as sps

    lam, vec = np.linalg.eigh(np.eye(3)[None] - proj)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.concatenate([e, e[:, ::-1]]), axis=0)
    v, w = e[:, 0], e[:, 1]  # v lacks a direction, w may lend it
    fill = np.zeros((len(e), 3, 3))
    for j in range(3):
        d = vec[:, :, j]
        dv = d[v]
        lends = (lam[v, j] > 0.5) & (np.einsum("ea,eab,eb->e", dv, proj[w], dv) > 1.0 - SEEN)
        total = np.zeros(n)
        np.add.at(total, v[lends], mass[w[lends]])
        alpha = np.where(lends, mass[w] / np.where(total[v] > 0.0, total[v], 1.0), 0.0)
        fill += alpha[:, None, None] * np.einsum("ea,eb->eab", dv, dv)
    out = []
    for r in range(3):
        m = hat[r].copy()
        for c in range(3):
            g = sps.csr_matrix((fill[:, r, c], (v, w)), shape=(n, n))
            m = m + g @ hat[c]
        out.append(m.tocsr())
    return out


def _edge_laplacian(uv, faces, k, held):
    """K_h = Σ_e k_e max(w_e, 0) ℓ_e² (δ_v − δ_w)(δ_v − δ_w)ᵀ: the cotan Laplacian (w_e, half
    the sum of the cotangents opposite edge e) with each edge's squared rest length ℓ_e², so
    that xᵀ K_h x ≈ ∫ h²‖∇x‖² dA; k_e the mean rigidity of the edge's ends; no edge between
    two ``held`` vertices."""
    import scipy.sparse as sps

    n = len(uv)
    p = uv[faces]
    det = np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                 - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    rows, cols, vals = [], [], []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        cot = np.einsum("mp,mp->m", p[:, b] - p[:, a], p[:, c] - p[:, a]) / det
        rows.append(np.minimum(faces[:, b], faces[:, c]))
        cols.append(np.maximum(faces[:, b], faces[:, c]))
        vals.append(0.5 * cot)
    w = sps.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(n, n)).tocsr().tocoo()  # the two halves of each edge summed
    i, j, w = w.row, w.col, np.maximum(w.data, 0.0)
    pinned = np.zeros(n, np.bool_)
    if held is not None:
        pinned[np.asarray(held, np.int64)] = True
    d = uv[i] - uv[j]
    w = w * np.einsum("ep,ep->e", d, d) * 0.5 * (k[i] + k[j]) * ~(pinned[i] & pinned[j])
    return sps.csr_matrix((np.concatenate([w, w, -w, -w]),
                           (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))),
                          shape=(n, n))


def on_pattern(q, other):
    """The entries of CSR ``other`` at the stored entries of CSR ``q`` (q.data's order): the
    values of ``other`` on q's sparsity (entries only one of them pruned are rounding)."""
    c = q.tocoo()
    return np.asarray(other[c.row, c.col]).ravel()


def _taken_over(faces, n, mass, proj, clamped, yn):
    """(N, 3, 3): the weight vertex v adds for the components its neighbours cannot see.

    A unit direction e (in the components H₀₀, √2 H₀₁, H₁₁) that vertex w does not see (in
    the range of I − P_w, less the normal curvature ŷ_n ŷ_nᵀ at a clamp, which is held flat)
    is handed to the ring neighbours v that see it fully (eᵀP_v e ≈ 1), in proportion to
    their areas: v adds (A_w / Σ A_v) e eᵀ. Each such direction is then weighed by exactly
    its area, Σ_v A_v W_v = Σ_v A_v I on uniform fields: on clothtool's criss-cross grid half
    the vertices (valence 4) see no twist, and without the hand-over the twist in the
    lattice's axes came out 5–6 % soft at any spacing. At a free edge the weak Hessian sees no
    normal curvature at all; not handing it over left the boundary's half-cells without it, a
    plate O(h) too soft (a uniform bend of a 6 × 6 grid 17 % soft, 12 × 12 9 %). Where w's
    unseen subspace has more than one direction, each is taken along the parts of it that
    its neighbours see (a grid's corner hands H₀₀ to its neighbour along one edge, H₁₁ to
    the one along the other), so that no neighbour takes a direction it sees only in part.
    """
    lost = np.eye(3)[None] - proj
    lost[clamped] -= np.einsum("na,nb->nab", yn[clamped], yn[clamped])
    lam, vec = np.linalg.eigh(lost)  # a projector less a projector: eigenvalues ~0 or ~1
    vec = vec * (lam > 0.5)[:, None, :]
    unseen = np.einsum("nak,nbk->nab", vec, vec)  # U_w: the projector on what w hands over
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.concatenate([e, e[:, ::-1]]), axis=0)  # (w, v) both ways, no self
    w, v = e[:, 0], e[:, 1]
    # T_wv: the part of U_w that v sees fully; the directions are the common eigenvectors of
    # the T_wv of w's ring (they commute on a grid), those of Σ_k 2^k T_wv_k, whose eigenvalue
    # names the set of neighbours that see each direction
    rank = np.arange(len(e)) - np.searchsorted(w, w)  # v's place in w's ring
    some = np.flatnonzero(np.einsum("naa->n", unseen)[w] > 0.5)  # w hands something over
    lam, vec = np.linalg.eigh(np.einsum("eab,ebc,ecd->ead", unseen[w[some]], proj[v[some]],
                                        unseen[w[some]]))
    vec = vec * (lam > 1.0 - SEEN)[:, None, :]
    bits = np.zeros((n, 3, 3))
    np.add.at(bits, w[some], np.exp2(np.minimum(rank[some], 30))[:, None, None]
              * np.einsum("eak,ebk->eab", vec, vec))
    lam, vec = np.linalg.eigh(bits - (np.eye(3)[None] - unseen))  # the rest of I at −1
    out = np.zeros((n, 3, 3))
    for k in range(3):
        d = vec[:, :, k]  # (N, 3)
        handed = lam[:, k] > -0.5  # in U_w's range
        dw = d[w]
        sees = (np.einsum("ea,eab,eb->e", dw, proj[v], dw) > 1.0 - SEEN) & handed[w]
        share = np.zeros(n)
        np.add.at(share, w[sees], mass[v[sees]])
        ok = sees & (share[w] > 0.0)
        c = mass[w[ok]] / share[w[ok]]
        np.add.at(out, v[ok], c[:, None, None] * np.einsum("ea,eb->eab", dw[ok], dw[ok]))
    return np.einsum("nab,nbc,ncd->nad", proj, out, proj)


def _hat_gradients(uv, faces):
    """∇φ_a (M, 3, 2) of the hat functions, triangle areas (M,) and orientation signs (M,)."""
    p = uv[faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    grad = np.empty((len(faces), 3, 2))
    for a in range(3):
        e = p[:, (a + 2) % 3] - p[:, (a + 1) % 3]  # the opposite edge, rotated: ∇φ_a ⟂ it
        grad[:, a, 0] = -e[:, 1] / det
        grad[:, a, 1] = e[:, 0] / det
    return grad, 0.5 * np.abs(det), np.sign(det)


def _boundary_edges(faces):
    """(E, 2) boundary edges in their face's order and the face of each."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    f = np.tile(np.arange(len(faces)), 3)
    lo, hi = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    _, inverse, count = np.unique(lo * (faces.max() + 1) + hi, return_inverse=True,
                                  return_counts=True)
    once = count[inverse] == 1
    return e[once], f[once]


def _outward(uv, edges, face_sign):
    t = uv[edges[:, 1]] - uv[edges[:, 0]]
    length = np.sqrt(np.einsum("ep,ep->e", t, t))
    return np.stack([t[:, 1], -t[:, 0]], 1) * (face_sign / length)[:, None], length


def _weak_hessian(uv, faces, grad, area, sign, n):
    """S_c (three N × N CSR): the weak Hessian components (H₀₀, √2 H₀₁, H₁₁) of every vertex."""
    import scipy.sparse as sps

    comps = ((0, 0, 1.0), (0, 1, SQRT2 / 2), (1, 0, SQRT2 / 2), (1, 1, 1.0))
    out = []
    edges, edge_face = _boundary_edges(faces)
    normal, length = _outward(uv, edges, sign[edge_face])
    for c, pairs in enumerate((comps[0:1], comps[1:3], comps[3:4])):
        rows, cols, vals = [], [], []
        for i, j, w in pairs:
            for a in range(3):
                for b in range(3):
                    rows.append(faces[:, a])
                    cols.append(faces[:, b])
                    vals.append(-w * area * grad[:, a, i] * grad[:, b, j])
            for end in range(2):  # ∮ φ_v n_i ∂_j x: ∫_e φ_v = |e|/2
                for b in range(3):
                    rows.append(edges[:, end])
                    cols.append(faces[edge_face, b])
                    vals.append(w * 0.5 * length * normal[:, i] * grad[edge_face, b, j])
        out.append(sps.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                  shape=(n, n)))
    return out


def _clamped(uv, faces, sign, n, held):
    """The vertices on a clamp (a boundary edge with both ends held) (N,) and their unit
    outward normals (N, 2), from their clamped edges (zero elsewhere)."""
    edges, edge_face = _boundary_edges(faces)
    is_held = np.zeros(n, np.bool_)
    if held is not None:
        is_held[np.asarray(held, np.int64)] = True
    keep = is_held[edges[:, 0]] & is_held[edges[:, 1]]
    edges, edge_face = edges[keep], edge_face[keep]
    normal, _ = _outward(uv, edges, sign[edge_face])
    acc = np.zeros((n, 2))
    np.add.at(acc, edges[:, 0], normal)
    np.add.at(acc, edges[:, 1], normal)
    clamped = np.zeros(n, np.bool_)
    clamped[edges.ravel()] = True
    norm = np.sqrt(np.einsum("np,np->n", acc, acc))
    acc[clamped] /= np.maximum(norm[clamped], 1e-300)[:, None]
    return clamped, acc


def mixed_voronoi_areas(uv, faces):
    """Per-vertex mixed Voronoi areas (Meyer et al. 2003): the Voronoi share of each corner,
    or A/2 (obtuse corner) and A/4 (the others) in an obtuse triangle; they sum to the area."""
    p = uv[faces]
    area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    cot = np.empty((len(faces), 3))
    for a in range(3):
        u, v = p[:, (a + 1) % 3] - p[:, a], p[:, (a + 2) % 3] - p[:, a]
        cot[:, a] = np.einsum("mp,mp->m", u, v) / (2.0 * area)
    l2 = np.stack([np.einsum("mp,mp->m", d, d) for d in
                   (p[:, 2] - p[:, 1], p[:, 0] - p[:, 2], p[:, 1] - p[:, 0])], 1)  # opposite a
    obtuse = cot < 0.0
    any_obtuse = obtuse.any(axis=1)
    out = np.zeros(len(uv))
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        voronoi = (l2[:, c] * cot[:, c] + l2[:, b] * cot[:, b]) / 8.0
        share = np.where(any_obtuse, np.where(obtuse[:, a], area / 2, area / 4), voronoi)
        np.add.at(out, faces[:, a], share)
    return out


# ---------------------------------------------------------------------------- kernels


@njit_inner(cache=True)
def quadratic_form(d, ptr, col, val, grad):
    """½ Σ_c d_cᵀ Q d_c with Q (CSR ptr, col, val) and d (N, 3); adds its gradient Q d to grad
    (N, 3) unless grad is empty."""
    total = 0.0
    add = grad.shape[0] > 0
    for i in range(d.shape[0]):
        q0 = q1 = q2 = 0.0
        for k in range(ptr[i], ptr[i + 1]):
            j = col[k]
            q0 += val[k] * d[j, 0]
            q1 += val[k] * d[j, 1]
            q2 += val[k] * d[j, 2]
        total += 0.5 * (d[i, 0] * q0 + d[i, 1] * q1 + d[i, 2] * q2)
        if add:
            grad[i, 0] += q0
            grad[i, 1] += q1
            grad[i, 2] += q2
    return total


@njit(cache=True)
def hessian_gradient(x, ptr, col, val, grad):
    """W = ½ Σ_c x_cᵀ Q x_c with Q (CSR ptr, col, val, rigidity included); adds ∇W = Q x to
    grad (N, 3) unless grad is empty."""
    return quadratic_form(x, ptr, col, val, grad)


@njit(cache=True)
def hessian_product(ptr, col, val, damp, v, out):
    """out += damp · Q v (the constant Hessian times v)."""
    for i in range(v.shape[0]):
        for k in range(ptr[i], ptr[i + 1]):
            j = col[k]
            for p in range(3):
                out[i, p] += damp * val[k] * v[j, p]
