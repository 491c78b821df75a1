"""Baraff–Witkin stretch and shear in the finite-element form of Kim 2020.

T. Kim, "A Finite Element Formulation of Baraff-Witkin Cloth", SCA 2020.
With rest edge matrix D_m (from uv) and deformed edge matrix D_s = [x1 − x0, x2 − x0],
the 3×2 deformation gradient F = D_s D_m⁻¹ has columns f0 = w_u, f1 = w_v (warp, weft).
Energy densities (J/m², stiffnesses in N/m), integrated over the rest area A:

    Ψ_stretch = k_s/2 · [(‖f0‖ − 1)² + (‖f1‖ − 1)²]
    Ψ_shear   = k_h/2 · (f0·f1)²

Baraff–Witkin's conditions C = a(‖w_u‖ − 1), C = a w_u·w_v scale with the square of
the triangle area; these densities do not, so refining a mesh converges.

Hessians w.r.t. vec F = (f0, f1), closed-form eigensystems (Kim 2020 §4–5):

- stretch, per column f: k_s[f̂f̂ᵀ + (1 − 1/‖f‖)(I − f̂f̂ᵀ)]; eigenvalue k_s along f̂,
  k_s(1 − 1/‖f‖) twice across it (negative under compression, clamped at 0);
- shear: k_h[ggᵀ + s·H₆] with s = f0·f1, g = (f1, f0), H₆ = [[0, I], [I, 0]].
  With u = f0 + f1, w = f1 − f0: eigenvalue s on the +1 space of H₆ less
  ŝ = (u, u)/√(2‖u‖²), −s on the −1 space less d̂ = (w, −w)/√(2‖w‖²), and on
  span(ŝ, d̂) the 2×2 matrix [[¾U − ¼W, ½√(UW)], [½√(UW), ¾W − ¼U]] (U = ‖u‖², W = ‖w‖²),
  whose determinant −3(U − W)²/16 ≤ 0 gives one eigenvalue ≥ 0 and one ≤ 0.

The projected element Hessian is Bᵀ H_F⁺ B with B = ∂vec F/∂x, PSD because H_F⁺ is.
"""

import numpy as np
from numba import njit, prange

EPS = 1e-12


@njit(cache=True)
def _deformation(x0, x1, x2, dinv):
    """F's columns f0, f1 and the shape-function weights α, β: f0 = Σ α_v x_v, f1 = Σ β_v x_v."""
    a, b, c, d = dinv[0, 0], dinv[0, 1], dinv[1, 0], dinv[1, 1]
    f0 = np.empty(3)
    f1 = np.empty(3)
    for p in range(3):
        e1 = x1[p] - x0[p]
        e2 = x2[p] - x0[p]
        f0[p] = a * e1 + c * e2
        f1[p] = b * e1 + d * e2
    alpha = np.array([-a - c, a, c])
    beta = np.array([-b - d, b, d])
    return f0, f1, alpha, beta


@njit(cache=True)
def membrane_energy(x0, x1, x2, dinv, area, k_stretch, k_shear):
    """A · (Ψ_stretch + Ψ_shear) of one triangle."""
    f0, f1, _, _ = _deformation(x0, x1, x2, dinv)
    n0 = np.sqrt(f0 @ f0)
    n1 = np.sqrt(f1 @ f1)
    s = f0 @ f1
    return area * (0.5 * k_stretch * ((n0 - 1.0) ** 2 + (n1 - 1.0) ** 2) + 0.5 * k_shear * s * s)


@njit(cache=True)
def _stretch_block(f, k, project, out, offset):
    """Add k[f̂f̂ᵀ + c(I − f̂f̂ᵀ)], c = 1 − 1/‖f‖ (clamped at 0 when projecting), at (offset, offset)."""
    n = max(np.sqrt(f @ f), EPS)
    c = 1.0 - 1.0 / n
    if project and c < 0.0:
        c = 0.0
    for p in range(3):
        for q in range(3):
            ff = f[p] * f[q] / (n * n)
            out[offset + p, offset + q] += k * (ff + c * ((1.0 if p == q else 0.0) - ff))


@njit(cache=True)
def _shear_hessian(f0, f1, k, project, out):
    """Add the 6×6 shear Hessian k[ggᵀ + s H₆] (or its PSD projection) to out."""
    s = f0 @ f1
    if not project:
        for p in range(3):
            for q in range(3):
                out[p, q] += k * f1[p] * f1[q]
                out[p, 3 + q] += k * f1[p] * f0[q]
                out[3 + p, q] += k * f0[p] * f1[q]
                out[3 + p, 3 + q] += k * f0[p] * f0[q]
            out[p, 3 + p] += k * s
            out[3 + p, p] += k * s
        return
    u = f0 + f1
    w = f1 - f0
    big_u = u @ u
    big_w = w @ w
    sh = np.zeros(6)  # ŝ = (u, u)/√(2U)
    dh = np.zeros(6)  # d̂ = (w, −w)/√(2W)
    if big_u > EPS * EPS:
        r = 1.0 / np.sqrt(2.0 * big_u)
        sh[:3] = u * r
        sh[3:] = u * r
    if big_w > EPS * EPS:
        r = 1.0 / np.sqrt(2.0 * big_w)
        dh[:3] = w * r
        dh[3:] = -w * r
    # s on (P⁺ − ŝŝᵀ) when s > 0, −s on (P⁻ − d̂d̂ᵀ) when s < 0
    if s > 0.0:
        for p in range(3):
            out[p, p] += 0.5 * k * s
            out[3 + p, 3 + p] += 0.5 * k * s
            out[p, 3 + p] += 0.5 * k * s
            out[3 + p, p] += 0.5 * k * s
        for p in range(6):
            for q in range(6):
                out[p, q] -= k * s * sh[p] * sh[q]
    elif s < 0.0:
        for p in range(3):
            out[p, p] -= 0.5 * k * s
            out[3 + p, 3 + p] -= 0.5 * k * s
            out[p, 3 + p] += 0.5 * k * s
            out[3 + p, p] += 0.5 * k * s
        for p in range(6):
            for q in range(6):
                out[p, q] += k * s * dh[p] * dh[q]
    # the non-negative eigenvalue of the 2×2 block on span(ŝ, d̂)
    a11 = 0.75 * big_u - 0.25 * big_w
    a22 = 0.75 * big_w - 0.25 * big_u
    a12 = 0.5 * np.sqrt(big_u * big_w)
    half = 0.5 * (a11 - a22)
    lam = 0.5 * (a11 + a22) + np.sqrt(half * half + a12 * a12)
    if lam <= 0.0:
        return
    c1, c2 = a12, lam - a11
    d1, d2 = lam - a22, a12
    if c1 * c1 + c2 * c2 < d1 * d1 + d2 * d2:
        c1, c2 = d1, d2
    norm = np.sqrt(c1 * c1 + c2 * c2)
    if norm == 0.0:  # a12 = 0 and lam = a11 = a22: any unit vector of the block
        c1, c2, norm = 1.0, 0.0, 1.0
    vec = (c1 * sh + c2 * dh) / norm
    for p in range(6):
        for q in range(6):
            out[p, q] += k * lam * vec[p] * vec[q]


@njit(cache=True)
def membrane_element(x0, x1, x2, dinv, area, k_stretch, k_shear, project, grad, hess):
    """Energy of one triangle; writes its gradient (9,) and Hessian (9, 9) (vertex-major).

    ``project``: PSD-project the Hessian through the closed-form eigensystems.
    """
    f0, f1, alpha, beta = _deformation(x0, x1, x2, dinv)
    n0 = max(np.sqrt(f0 @ f0), EPS)
    n1 = max(np.sqrt(f1 @ f1), EPS)
    s = f0 @ f1
    energy = area * (0.5 * k_stretch * ((n0 - 1.0) ** 2 + (n1 - 1.0) ** 2) + 0.5 * k_shear * s * s)
    # ∂Ψ/∂vec F
    g_f = np.empty(6)
    g_f[:3] = k_stretch * (n0 - 1.0) / n0 * f0 + k_shear * s * f1
    g_f[3:] = k_stretch * (n1 - 1.0) / n1 * f1 + k_shear * s * f0
    h_f = np.zeros((6, 6))
    if k_stretch > 0.0:
        _stretch_block(f0, k_stretch, project, h_f, 0)
        _stretch_block(f1, k_stretch, project, h_f, 3)
    if k_shear > 0.0:
        _shear_hessian(f0, f1, k_shear, project, h_f)
    # chain rule through f0 = Σ α_v x_v, f1 = Σ β_v x_v
    for v in range(3):
        for p in range(3):
            grad[3 * v + p] = area * (alpha[v] * g_f[p] + beta[v] * g_f[3 + p])
    for v in range(3):
        for w in range(3):
            aa = area * alpha[v] * alpha[w]
            ab = area * alpha[v] * beta[w]
            ba = area * beta[v] * alpha[w]
            bb = area * beta[v] * beta[w]
            for p in range(3):
                for q in range(3):
                    hess[3 * v + p, 3 * w + q] = (aa * h_f[p, q] + ab * h_f[p, 3 + q]
                                                  + ba * h_f[3 + p, q] + bb * h_f[3 + p, 3 + q])
    return energy


@njit(cache=True, parallel=True)
def membrane_elements(x, faces, dinv, area, k_stretch, k_shear, elem_energy, elem_grad, elem_hess):
    """All triangles in parallel: per-element energy, projected gradient and Hessian."""
    for t in prange(faces.shape[0]):
        elem_energy[t] = membrane_element(
            x[faces[t, 0]], x[faces[t, 1]], x[faces[t, 2]], dinv[t], area[t],
            k_stretch, k_shear, True, elem_grad[t], elem_hess[t])


@njit(cache=True, parallel=True)
def membrane_energies(x, faces, dinv, area, k_stretch, k_shear, elem_energy):
    for t in prange(faces.shape[0]):
        elem_energy[t] = membrane_energy(x[faces[t, 0]], x[faces[t, 1]], x[faces[t, 2]],
                                         dinv[t], area[t], k_stretch, k_shear)


@njit(cache=True)
def max_principal_stretch(x, faces, dinv):
    """Largest λ1 = √(largest eigenvalue of FᵀF) over all triangles."""
    worst = 0.0
    for t in range(faces.shape[0]):
        f0, f1, _, _ = _deformation(x[faces[t, 0]], x[faces[t, 1]], x[faces[t, 2]], dinv[t])
        c00, c11, c01 = f0 @ f0, f1 @ f1, f0 @ f1
        half = 0.5 * (c00 - c11)
        lam = 0.5 * (c00 + c11) + np.sqrt(half * half + c01 * c01)
        worst = max(worst, np.sqrt(lam))
    return worst
