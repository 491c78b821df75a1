"""The spring network shared by ``mass-spring``, ``pbd``, ``xpbd`` and ``projective``.

Springs come from the mesh (course notes: "store every triangle edge, sort, remove
duplicates"): every triangle edge is a spring, and with bending on, every hinge
(i, j, k, l) adds a bend spring between the two opposite vertices k and l. Each
spring has the energy ½ k_e (‖x_i − x_j‖ − L_e)², with L_e its rest length.

Stiffness from the material (N/m per unit area, so refining the mesh keeps the
material): an edge of rest length L whose adjacent rest triangles have total area
A, at angle θ to the warp (u) direction of the rest coordinates, gets

    k_e = ((k_u cos²θ + k_v sin²θ) cos²2θ + 4 k_shear sin²2θ) · A / L²

(k_u, k_v: material.stretch along u and v) so on a grid the axis edges are the
structural springs (k_e = k_u along u, k_v along v in the interior, reproducing the
membrane's uniaxial stiffnesses) and the diagonals are
the shear springs (4 k_shear A/L² = 2 k_shear reproduces Ψ_shear = k_h/2 (f0·f1)²
to first order). A mesh without rest uv treats every edge as structural. The rest
length factors b_u, b_v (material.rest_stretch) make every spring's rest length that
of the rest state F = diag(b_u, b_v): ‖(b_u Δu, b_v Δv)‖ for an edge (Δu, Δv) of the
rest uv (b‖e‖ without uv, where b_u = b_v). A bend
spring gets k_e = 2c/L_kl², with c = k_bend ‖ē‖²/(2(Ā_k + Ā_l)) the hinge's dihedral
coefficient (so ½k_e(L_kl θ)² = cθ²): a dimensional stand-in, not a calibrated
bending model — a spring across a flat hinge resists bending only to second order
in the angle (the "locking" and weak-bending limits of the course notes).

Kernels (numba, float64, serial, allocation-free in their loops):

- :func:`spring_energy`, :func:`spring_assemble` (gradient and the Hessian
  k[d̂d̂ᵀ + max(0, 1 − L/‖d‖)(I − d̂d̂ᵀ)]: the compressed-spring term, negative
  when ‖d‖ < L, is dropped, the PSD clamp of the notes);
- :func:`pbd_gauss_seidel`, :func:`pbd_jacobi`, :func:`strain_limit_pass` (PBD);
- :func:`xpbd_sweep` (XPBD, with its damping term);
- :func:`pd_local_rhs` (Projective Dynamics' local step and Σ w Aᵀp).
"""

from dataclasses import dataclass

import numpy as np
from numba import njit

EPS = 1e-12


@dataclass
class Springs:
    i: np.ndarray  # (E,) int64
    j: np.ndarray  # (E,) int64
    rest: np.ndarray  # (E,) rest lengths, m
    k: np.ndarray  # (E,) stiffness, N/m
    structural: np.ndarray  # (E,) bool: a stretch spring (strain limiting applies)
    n_bend: int  # bend springs are the last n_bend entries

    @property
    def pairs(self):
        return np.stack([self.i, self.j], axis=1)

    def __len__(self):
        return len(self.i)


def build_springs(model):
    """Springs of a :class:`~clothtool.sim.model.Model` (see the module docstring)."""
    faces = model.faces
    n = model.n_vertices
    rest3d = model.mesh.rest3d
    a = faces.ravel()
    b = np.roll(faces, -1, axis=1).ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * n + hi
    uniq, inverse = np.unique(key, return_inverse=True)
    ei, ej = (uniq // n).astype(np.int64), (uniq % n).astype(np.int64)
    adj_area = np.bincount(inverse, weights=np.repeat(model.area, 3), minlength=len(uniq))
    d = rest3d[ej] - rest3d[ei]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    k_u, k_v, b_u, b_v = model.stretch
    if model.mesh.uv is not None:
        theta = np.arctan2(d[:, 1], d[:, 0])
        cos2 = np.cos(2.0 * theta) ** 2
        k_axis = k_u * np.cos(theta) ** 2 + k_v * np.sin(theta) ** 2
    else:
        cos2 = np.ones(len(uniq))
        k_axis = np.full(len(uniq), k_u)  # the Model has k_u = k_v, b_u = b_v without uv
    k = (k_axis * cos2 + 4.0 * model.k_shear * (1.0 - cos2)) * adj_area / length ** 2
    structural = cos2 >= 0.5
    n_bend = 0
    if model.bend_model is not None and len(model.hinge):
        bi, bj = model.hinge[:, 2], model.hinge[:, 3]
        db = rest3d[bj] - rest3d[bi]
        lb = np.sqrt(np.einsum("ij,ij->i", db, db))
        kb = 2.0 * model.hinge_coef / lb ** 2
        ei, ej = np.concatenate([ei, bi]), np.concatenate([ej, bj])
        d, length, k = np.concatenate([d, db]), np.concatenate([length, lb]), np.concatenate([k, kb])
        structural = np.concatenate([structural, np.zeros(len(bi), np.bool_)])
        n_bend = len(bi)
    # rest lengths of the rest state F = diag(b_u, b_v): an edge (du, dv) rests at ‖(b_u du, b_v dv)‖
    length = np.sqrt((b_u * d[:, 0]) ** 2 + (b_v * d[:, 1]) ** 2 + (b_u * d[:, 2]) ** 2)
    keep = k > 0.0
    if not np.all(keep):  # e.g. shear = 0: diagonals carry nothing
        ei, ej, length, k, structural = ei[keep], ej[keep], length[keep], k[keep], structural[keep]
        n_bend = int(np.count_nonzero(keep[len(keep) - n_bend:])) if n_bend else 0
    return Springs(ei.astype(np.int64), ej.astype(np.int64), length, k, structural, n_bend)


# ---------------------------------------------------------------------------- energy


@njit(cache=True)
def spring_energy(x, si, sj, rest, k):
    total = 0.0
    for e in range(si.shape[0]):
        i, j = si[e], sj[e]
        d0, d1, d2 = x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]
        c = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - rest[e]
        total += 0.5 * k[e] * c * c
    return total


@njit(cache=True)
def spring_assemble(x, si, sj, rest, k, slots, grad, values):
    """W(x); adds ∇W to grad and the PSD-clamped spring Hessians to the block values.

    slots (E, 4): the (i,i), (i,j), (j,i), (j,j) block slots of each spring.
    """
    total = 0.0
    h = np.empty((3, 3))
    for e in range(si.shape[0]):
        i, j = si[e], sj[e]
        d = (x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2])
        length = max(np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), EPS)
        c = length - rest[e]
        total += 0.5 * k[e] * c * c
        s = k[e] * c / length
        for p in range(3):
            grad[i, p] += s * d[p]
            grad[j, p] -= s * d[p]
        across = 1.0 - rest[e] / length
        if across < 0.0:  # compressed: the indefinite part is dropped (PSD clamp)
            across = 0.0
        for p in range(3):
            for q in range(3):
                dd = d[p] * d[q] / (length * length)
                h[p, q] = k[e] * ((1.0 - across) * dd + (across if p == q else 0.0))
        for p in range(3):
            for q in range(3):
                values[slots[e, 0], p, q] += h[p, q]
                values[slots[e, 1], p, q] -= h[p, q]
                values[slots[e, 2], p, q] -= h[p, q]
                values[slots[e, 3], p, q] += h[p, q]
    return total


# ---------------------------------------------------------------------------- PBD / XPBD


@njit(cache=True, inline="always")
def _spring_vector(x, i, j, inv_mass):
    """(ok, w_i + w_j, d = x_i − x_j, ‖d‖); not ok when both ends are pinned or ‖d‖ < EPS."""
    wsum = inv_mass[i] + inv_mass[j]
    d0, d1, d2 = x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]
    length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return wsum != 0.0 and length >= EPS, wsum, d0, d1, d2, length


@njit(cache=True, inline="always")
def _correction(x, i, j, rest, stiff, inv_mass):
    """PBD distance-constraint correction of spring (i, j) (Müller et al. 2007): with
    d = x_i − x_j and s = k'(‖d‖ − L)/(‖d‖(w_i + w_j)), x_i −= s w_i d, x_j += s w_j d.
    Returns (ok, s·w_i, s·w_j, d); not ok when both ends are pinned or ‖d‖ ≈ 0."""
    ok, wsum, d0, d1, d2, length = _spring_vector(x, i, j, inv_mass)
    if not ok:
        return False, 0.0, 0.0, d0, d1, d2
    s = stiff * (length - rest) / (length * wsum)
    return True, s * inv_mass[i], s * inv_mass[j], d0, d1, d2


@njit(cache=True, inline="always")
def _move(y, i, j, wi, wj, d0, d1, d2):
    """y_i −= w_i d, y_j += w_j d."""
    y[i, 0] -= wi * d0
    y[i, 1] -= wi * d1
    y[i, 2] -= wi * d2
    y[j, 0] += wj * d0
    y[j, 1] += wj * d1
    y[j, 2] += wj * d2


@njit(cache=True)
def pbd_gauss_seidel(x, si, sj, rest, stiff, inv_mass, backward):
    """One Gauss–Seidel sweep of distance constraints (Müller et al. 2007).

    stiff (E,): the per-iteration stiffness k' ∈ [0, 1] of each constraint.
    ``backward``: visit the springs in reverse order (alternating the direction
    lets a correction travel across the whole mesh in two sweeps, whichever
    side the pins are on: symmetric Gauss–Seidel).
    """
    m = si.shape[0]
    for r in range(m):
        e = m - 1 - r if backward else r
        i, j = si[e], sj[e]
        ok, wi, wj, d0, d1, d2 = _correction(x, i, j, rest[e], stiff[e], inv_mass)
        if not ok:
            continue
        _move(x, i, j, wi, wj, d0, d1, d2)


@njit(cache=True)
def pbd_jacobi(x, si, sj, rest, stiff, inv_mass, relaxation, delta, count):
    """One Jacobi sweep (course notes): every constraint proposes a correction from the
    same positions; vertex i moves by Σ corrections / (n_i + α), α = ``relaxation``.
    delta (N, 3) and count (N,) are workspace."""
    delta[:] = 0.0
    count[:] = 0.0
    for e in range(si.shape[0]):
        i, j = si[e], sj[e]
        ok, wi, wj, d0, d1, d2 = _correction(x, i, j, rest[e], stiff[e], inv_mass)
        if not ok:
            continue
        _move(delta, i, j, wi, wj, d0, d1, d2)
        count[i] += 1.0
        count[j] += 1.0
    for v in range(x.shape[0]):
        if count[v] > 0.0:
            f = 1.0 / (count[v] + relaxation)
            x[v, 0] += f * delta[v, 0]
            x[v, 1] += f * delta[v, 1]
            x[v, 2] += f * delta[v, 2]


@njit(cache=True)
def strain_limit_pass(x, si, sj, rest, limited, inv_mass, lo, hi):
    """Project the length of every spring with limited[e] into [lo·L, hi·L] (Gauss–Seidel,
    full stiffness)."""
    for e in range(si.shape[0]):
        if not limited[e]:
            continue
        i, j = si[e], sj[e]
        ok, wsum, d0, d1, d2, length = _spring_vector(x, i, j, inv_mass)
        if not ok:
            continue
        if length > hi * rest[e]:
            target = hi * rest[e]
        elif length < lo * rest[e]:
            target = lo * rest[e]
        else:
            continue
        s = (length - target) / (length * wsum)
        wi, wj = s * inv_mass[i], s * inv_mass[j]
        _move(x, i, j, wi, wj, d0, d1, d2)


@njit(cache=True)
def xpbd_sweep(x, x_n, si, sj, rest, alpha_tilde, gamma, inv_mass, lam, backward):
    """One Gauss–Seidel XPBD sweep (Macklin et al. 2016, eqs. 18 and 26).

    C = ‖x_i − x_j‖ − L, α̃ = 1/(k h²), γ = α̃ β h (β: stiffness-proportional
    damping, s; γ = 0 without damping). lam (E,) accumulates the multipliers.
    ``backward``: reverse order, as in :func:`pbd_gauss_seidel`.
    """
    m = si.shape[0]
    for r in range(m):
        e = m - 1 - r if backward else r
        i, j = si[e], sj[e]
        ok, wsum, d0, d1, d2, length = _spring_vector(x, i, j, inv_mass)
        if not ok:
            continue
        n0, n1, n2 = d0 / length, d1 / length, d2 / length
        c = length - rest[e]
        at = alpha_tilde[e]
        num = -c - at * lam[e]
        g = gamma[e]
        if g != 0.0:  # ∇C·(x − x_n)
            num -= g * (n0 * (x[i, 0] - x_n[i, 0] - x[j, 0] + x_n[j, 0])
                        + n1 * (x[i, 1] - x_n[i, 1] - x[j, 1] + x_n[j, 1])
                        + n2 * (x[i, 2] - x_n[i, 2] - x[j, 2] + x_n[j, 2]))
        dlam = num / ((1.0 + g) * wsum + at)
        lam[e] += dlam
        wi, wj = dlam * inv_mass[i], dlam * inv_mass[j]
        _move(x, i, j, -wi, -wj, n0, n1, n2)


# ---------------------------------------------------------------------------- PD


@njit(cache=True)
def pd_local_rhs(x, si, sj, rest, k, rhs):
    """Local step: p_e = L_e d̂_e (the nearest vector of rest length); adds Σ k_e A_eᵀ p_e to rhs.

    A_e x = x_i − x_j, so Aᵀp adds p to row i and −p to row j. Returns the spring
    energy at x (= Σ k_e/2 ‖A_e x − p_e‖²).
    """
    total = 0.0
    for e in range(si.shape[0]):
        i, j = si[e], sj[e]
        d0, d1, d2 = x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]
        length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        c = length - rest[e]
        total += 0.5 * k[e] * c * c
        if length < EPS:
            continue
        s = k[e] * rest[e] / length
        rhs[i, 0] += s * d0
        rhs[i, 1] += s * d1
        rhs[i, 2] += s * d2
        rhs[j, 0] -= s * d0
        rhs[j, 1] -= s * d1
        rhs[j, 2] -= s * d2
    return total
