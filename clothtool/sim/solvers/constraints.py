"""The constraint kernels of ``pbd``, ``xpbd`` and ``projective`` on the spring network of
:mod:`clothtool.sim.energies.springs` (numba, float64, serial, allocation-free in their loops):

- :func:`pbd_gauss_seidel`, :func:`pbd_jacobi`, :func:`strain_limit_pass` (PBD);
- :func:`xpbd_sweep` (XPBD, with its damping term);
- :func:`pd_local_rhs` (Projective Dynamics' local step and Σ w Aᵀp).
"""

import numpy as np

from clothtool.numba_setup import njit
from clothtool.sim.energies.springs import EPS


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
