"""Baraff–Witkin stretch and shear in the finite-element form of Kim 2020.

T. Kim, "A Finite Element Formulation of Baraff-Witkin Cloth", SCA 2020.
With rest edge matrix D_r (from uv) and deformed edge matrix D_d = [x1 − x0, x2 − x0],
the 3×2 deformation gradient F = D_d D_r⁻¹ has columns f0 = w_u, f1 = w_v (warp, weft).
Energy densities (J/m², stiffnesses in N/m), integrated over the rest area A:

    Ψ_stretch = k_u/2 · (‖f0‖ − b_u)² + k_v/2 · (‖f1‖ − b_v)²
    Ψ_shear   = k_h/2 · (f0·f1)²

with warp and weft stiffnesses k_u, k_v and Baraff–Witkin's rest length factors
b_u, b_v (the stretch conditions C_u = a(‖w_u‖ − b_u), C_v = a(‖w_v‖ − b_v) of
Baraff & Witkin 1998, "Large steps in cloth simulation", §4.2); the element kernels take
them as one array ``stretch`` = (k_u, k_v, b_u, b_v), the mesh kernels one such row per
triangle (``stretch`` (M, 4), ``k_shear`` (M,): each panel of a garment its own material). Baraff–Witkin's conditions scale
with the square of the triangle area; these densities do not, so refining a mesh
converges.

Hessians w.r.t. vec F = (f0, f1), closed-form eigensystems (Kim 2020 §4–5):

- stretch, per column f with its (k, b): k[f̂f̂ᵀ + (1 − b/‖f‖)(I − f̂f̂ᵀ)]; eigenvalue k
  along f̂, k(1 − b/‖f‖) twice across it (negative when ‖f‖ < b, clamped at 0);
- shear: k_h[ggᵀ + s·H₆] with s = f0·f1, g = (f1, f0), H₆ = [[0, I], [I, 0]].
  With u = f0 + f1, w = f1 − f0: eigenvalue s on the +1 space of H₆ less
  ŝ = (u, u)/√(2‖u‖²), −s on the −1 space less d̂ = (w, −w)/√(2‖w‖²), and on
  span(ŝ, d̂) the 2×2 matrix [[¾U − ¼W, ½√(UW)], [½√(UW), ¾W − ¼U]] (U = ‖u‖², W = ‖w‖²),
  whose determinant −3(U − W)²/16 ≤ 0 gives one eigenvalue ≥ 0 and one ≤ 0.

The projected element Hessian is Bᵀ H_F⁺ B with B = ∂vec F/∂x, PSD because H_F⁺ is.
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner
from clothtool.vec3 import add, dot, load, scale, sub

EPS = 1e-12


@njit_inner(cache=True)
def deformation(x0, x1, x2, dr_inv):
    """F's columns f0, f1 and the shape-function weights α, β: f0 = Σ α_v x_v, f1 = Σ β_v x_v."""
    a, b, c, d = dr_inv[0, 0], dr_inv[0, 1], dr_inv[1, 0], dr_inv[1, 1]
    e1 = sub(x1, x0)
    e2 = sub(x2, x0)
    f0 = add(scale(a, e1), scale(c, e2))
    f1 = add(scale(b, e1), scale(d, e2))
    return f0, f1, (-a - c, a, c), (-b - d, b, d)


@njit_inner(cache=True)
def deformation_gradient(x0, x1, x2, dr_inv):
    """F's columns (f0, f1) = D_d D_r⁻¹."""
    f0, f1, _, _ = deformation(x0, x1, x2, dr_inv)
    return f0, f1


@njit_inner(cache=True)
def _density(f0, f1, stretch, k_shear):
    n0 = np.sqrt(dot(f0, f0))
    n1 = np.sqrt(dot(f1, f1))
    s = dot(f0, f1)
    return (0.5 * stretch[0] * (n0 - stretch[2]) ** 2 + 0.5 * stretch[1] * (n1 - stretch[3]) ** 2
            + 0.5 * k_shear * s * s)


@njit_inner(cache=True)
def _stress(f0, f1, stretch, k_shear):
    """∂Ψ/∂f0 = k_u(‖f0‖ − b_u) f0/‖f0‖ + k_h s f1 and ∂Ψ/∂f1 (s = f0·f1)."""
    n0 = max(np.sqrt(dot(f0, f0)), EPS)
    n1 = max(np.sqrt(dot(f1, f1)), EPS)
    s = dot(f0, f1)
    g0 = add(scale(stretch[0] * (n0 - stretch[2]) / n0, f0), scale(k_shear * s, f1))
    g1 = add(scale(stretch[1] * (n1 - stretch[3]) / n1, f1), scale(k_shear * s, f0))
    return g0, g1


@njit(cache=True)
def membrane_energy(x0, x1, x2, dr_inv, area, stretch, k_shear):
    """A · (Ψ_stretch + Ψ_shear) of one triangle; stretch = (k_u, k_v, b_u, b_v)."""
    f0, f1, _, _ = deformation(x0, x1, x2, dr_inv)
    return area * _density(f0, f1, stretch, k_shear)


@njit_inner(cache=True)
def _stretch_block(f, k, b, project, out, offset):
    """Add k[f̂f̂ᵀ + c(I − f̂f̂ᵀ)], c = 1 − b/‖f‖ (clamped at 0 when projecting), at (offset, offset)."""
    n2 = max(dot(f, f), EPS * EPS)
    c = 1.0 - b / np.sqrt(n2)
    if project and c < 0.0:
        c = 0.0
    for p in range(3):
        for q in range(3):
            ff = f[p] * f[q] / n2
            out[offset + p, offset + q] += k * ((1.0 - c) * ff + (c if p == q else 0.0))


@njit_inner(cache=True)
def _shear_eigen(f0, f1):
    """The projected shear Hessian's pieces (module docstring): s = f0·f1, ŝ's and d̂'s
    halves us = u/√(2U), ws = w/√(2W) (zero when undefined), and the non-negative
    eigenvalue λ of the 2×2 block with its eigenvector's halves (top, bottom)
    (λ = 0 and zero halves when it is not positive)."""
    s = dot(f0, f1)
    u = add(f0, f1)
    w = sub(f1, f0)
    big_u = dot(u, u)
    big_w = dot(w, w)
    # ŝ = (u, u)/√(2U), d̂ = (w, −w)/√(2W); zero when undefined (their weight is then 0)
    us = scale(1.0 / np.sqrt(2.0 * big_u), u) if big_u > EPS * EPS else (0.0, 0.0, 0.0)
    ws = scale(1.0 / np.sqrt(2.0 * big_w), w) if big_w > EPS * EPS else (0.0, 0.0, 0.0)
    # the non-negative eigenvalue of the 2×2 block on span(ŝ, d̂)
    a11 = 0.75 * big_u - 0.25 * big_w
    a22 = 0.75 * big_w - 0.25 * big_u
    a12 = 0.5 * np.sqrt(big_u * big_w)
    half = 0.5 * (a11 - a22)
    lam = 0.5 * (a11 + a22) + np.sqrt(half * half + a12 * a12)
    if lam <= 0.0:
        return s, us, ws, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    c1, c2 = a12, lam - a11
    d1, d2 = lam - a22, a12
    if c1 * c1 + c2 * c2 < d1 * d1 + d2 * d2:
        c1, c2 = d1, d2
    norm = np.sqrt(c1 * c1 + c2 * c2)
    if norm == 0.0:  # a12 = 0 and lam = a11 = a22: any unit vector of the block
        c1, c2, norm = 1.0, 0.0, 1.0
    c1 /= norm
    c2 /= norm
    # eigenvector c1 ŝ + c2 d̂ = (c1 us + c2 ws, c1 us − c2 ws)
    return s, us, ws, lam, add(scale(c1, us), scale(c2, ws)), sub(scale(c1, us), scale(c2, ws))


@njit(cache=True, inline="always")
def shear_outer(f0, f1, k, cross, exact, out):
    """Add k ggᵀ, g = (f1, f0) = ∂s/∂vec F of the shear s = f0·f1, to the 6×6 out, and with
    ``exact`` ``cross`` times H₆ = ∂²s/∂vec F² = [[0, I], [I, 0]] (k s H₆: the shear's exact
    Hessian)."""
    for p in range(3):
        for q in range(3):
            out[p, q] += k * f1[p] * f1[q]
            out[p, 3 + q] += k * f1[p] * f0[q]
            out[3 + p, q] += k * f0[p] * f1[q]
            out[3 + p, 3 + q] += k * f0[p] * f0[q]
        if exact:
            out[p, 3 + p] += cross
            out[3 + p, p] += cross


@njit_inner(cache=True)
def _shear_hessian(f0, f1, k, project, out):
    """Add the 6×6 shear Hessian k[ggᵀ + s H₆] (or its PSD projection) to out."""
    if not project:
        shear_outer(f0, f1, k, k * dot(f0, f1), True, out)
        return
    s, us, ws, lam, top, bottom = _shear_eigen(f0, f1)
    # s (P⁺ − ŝŝᵀ) when s > 0, −s (P⁻ − d̂d̂ᵀ) when s < 0; P± = ½[[I, ±I], [±I, I]]
    if s > 0.0:
        for p in range(6):
            for q in range(6):
                same = 0.5 if p % 3 == q % 3 else 0.0
                out[p, q] += k * s * (same - us[p % 3] * us[q % 3])
    elif s < 0.0:
        for p in range(6):
            for q in range(6):
                sign = 1.0 if (p < 3) == (q < 3) else -1.0
                same = 0.5 if p % 3 == q % 3 else 0.0
                out[p, q] -= k * s * sign * (same - ws[p % 3] * ws[q % 3])
    if lam <= 0.0:
        return
    for p in range(6):
        vp = top[p] if p < 3 else bottom[p - 3]
        for q in range(6):
            vq = top[q] if q < 3 else bottom[q - 3]
            out[p, q] += k * lam * vp * vq


@njit(cache=True)
def membrane_element(x0, x1, x2, dr_inv, area, stretch, k_shear, project, grad, hess, h_f):
    """Energy of one triangle; writes its gradient (9,) and Hessian (9, 9) (vertex-major).

    ``stretch`` = (k_u, k_v, b_u, b_v): warp and weft stiffnesses and rest length factors.
    ``project``: PSD-project the Hessian through the closed-form eigensystems.
    ``h_f`` (6, 6) is workspace; it is left holding ∂²Ψ/∂vec F².
    """
    f0, f1, alpha, beta = deformation(x0, x1, x2, dr_inv)
    energy, g0, g1 = membrane_density(f0, f1, stretch, k_shear, project, h_f)
    to_vertices(alpha, beta, area, g0, g1, h_f, grad, hess)
    return area * energy


@njit_inner(cache=True)
def membrane_density(f0, f1, stretch, k_shear, project, h_f):
    """(Ψ, ∂Ψ/∂f0, ∂Ψ/∂f1) at F = (f0, f1); writes ∂²Ψ/∂vec F² (PSD-projected with
    ``project``) into h_f (6, 6)."""
    g0, g1 = _stress(f0, f1, stretch, k_shear)
    h_f[:, :] = 0.0
    for c in range(2):  # warp at 0, weft at 3 (offsets from the loop: numba would compile
        # _stretch_block once per literal offset)
        if stretch[c] > 0.0:
            _stretch_block(f0 if c == 0 else f1, stretch[c], stretch[2 + c], project, h_f, 3 * c)
    if k_shear > 0.0:
        _shear_hessian(f0, f1, k_shear, project, h_f)
    return _density(f0, f1, stretch, k_shear), g0, g1


@njit_inner(cache=True)
def to_vertices(alpha, beta, area, g0, g1, h_f, grad, hess):
    """The chain rule through f0 = Σ α_v x_v, f1 = Σ β_v x_v: grad (9,) = A (α_v g0 + β_v g1)
    and hess (9, 9) = A Bᵀ h_f B (vertex-major) from a density's vec-F gradient (g0, g1)
    and Hessian h_f (6, 6)."""
    for v in range(3):
        for p in range(3):
            grad[3 * v + p] = area * (alpha[v] * g0[p] + beta[v] * g1[p])
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


@njit(cache=True)
def membrane_vertex(x0, x1, x2, dr_inv, area, stretch, k_shear, a, grad, hess):
    """Adds corner a's gradient (3,) and the (a, a) 3×3 block of the projected Hessian of
    one triangle to grad and hess, without the 9×9 (Vertex Block Descent's per-vertex
    system). With f0 = Σ α_v x_v, f1 = Σ β_v x_v the block is
    A[α² H₀₀ + αβ(H₀₁ + H₁₀) + β² H₁₁] of the projected ∂²Ψ/∂vec F², which by the
    eigensystems above is

        A[α² k_u(ĉ₀) + β² k_v(ĉ₁) + (α + β)² k_h s(½I − us usᵀ)   (s > 0)
                                  − (α − β)² k_h s(½I − ws wsᵀ)   (s < 0)
                                  + k_h λ t tᵀ],   t = α top + β bottom,

    k(ĉ) = k[f̂f̂ᵀ + c(I − f̂f̂ᵀ)] the stretch blocks; equal to the (a, a) block of
    :func:`membrane_element` with ``project``."""
    f0, f1, alpha, beta = deformation(x0, x1, x2, dr_inv)
    al, be = alpha[a], beta[a]
    g0, g1 = _stress(f0, f1, stretch, k_shear)
    for p in range(3):
        grad[p] += area * (al * g0[p] + be * g1[p])
    if stretch[0] > 0.0:
        _stretch_vertex(f0, stretch[0], stretch[2], area * al * al, hess)
    if stretch[1] > 0.0:
        _stretch_vertex(f1, stretch[1], stretch[3], area * be * be, hess)
    if k_shear <= 0.0:
        return
    s, us, ws, lam, top, bottom = _shear_eigen(f0, f1)
    if s > 0.0:
        c, e = area * k_shear * s * (al + be) ** 2, us
    elif s < 0.0:
        c, e = -area * k_shear * s * (al - be) ** 2, ws
    else:
        c, e = 0.0, us
    t = add(scale(al, top), scale(be, bottom))
    lt = area * k_shear * lam
    for p in range(3):
        for q in range(3):
            hess[p, q] += lt * t[p] * t[q] - c * e[p] * e[q]
        hess[p, p] += 0.5 * c


@njit_inner(cache=True)
def _stretch_vertex(f, k, b, weight, hess):
    """Add weight · k[f̂f̂ᵀ + c(I − f̂f̂ᵀ)], c = max(1 − b/‖f‖, 0) (the projected stretch block)."""
    n2 = max(dot(f, f), EPS * EPS)
    c = max(1.0 - b / np.sqrt(n2), 0.0)
    along = weight * k * (1.0 - c) / n2
    across = weight * k * c
    for p in range(3):
        for q in range(3):
            hess[p, q] += along * f[p] * f[q]
        hess[p, p] += across


@njit_inner(cache=True)
def add_triangle(face, slot, g, hess, grad, values):
    """Adds a triangle's gradient g (9,) to grad (N, 3) and its Hessian hess (9, 9) to the
    matrix blocks values[slot[3a + b]] of its corners a, b."""
    for a in range(3):
        v = face[a]
        for p in range(3):
            grad[v, p] += g[3 * a + p]
        for b in range(3):
            block = values[slot[3 * a + b]]
            for p in range(3):
                for q in range(3):
                    block[p, q] += hess[3 * a + p, 3 * b + q]


@njit(cache=True)
def membrane_assemble(x, faces, dr_inv, area, stretch, k_shear, project, slots, grad, values):
    """W_membrane(x); adds its gradient to grad (N, 3) and its Hessian blocks (PSD-projected
    with ``project``) to values (``stretch`` (M, 4), ``k_shear`` (M,) per triangle, as in
    every mesh kernel here)."""
    g = np.empty(9)
    hess = np.empty((9, 9))
    work = np.empty((6, 6))
    total = 0.0
    for t in range(faces.shape[0]):
        total += membrane_element(load(x, faces[t, 0]), load(x, faces[t, 1]), load(x, faces[t, 2]),
                                  dr_inv[t], area[t], stretch[t], k_shear[t], project, g, hess, work)
        add_triangle(faces[t], slots[t], g, hess, grad, values)
    return total


@njit(cache=True)
def membrane_gradient(x, faces, dr_inv, area, stretch, k_shear, grad):
    """Adds ∇W_membrane to grad (N, 3), without the Hessian (the gradient of
    :func:`membrane_element`: A (α_v ∂Ψ/∂f0 + β_v ∂Ψ/∂f1) at vertex v)."""
    for t in range(faces.shape[0]):
        f0, f1, alpha, beta = deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                           load(x, faces[t, 2]), dr_inv[t])
        g0, g1 = _stress(f0, f1, stretch[t], k_shear[t])
        a = area[t]
        for v in range(3):
            vi = faces[t, v]
            for p in range(3):
                grad[vi, p] += a * (alpha[v] * g0[p] + beta[v] * g1[p])


@njit(cache=True)
def membrane_hessian_product(x, faces, dr_inv, area, stretch, k_shear, scale_by, v, out):
    """out += scale_by · K_membrane(x) v, element by element (the projected Hessians of
    :func:`membrane_element`, not assembled)."""
    g = np.empty(9)
    hess = np.empty((9, 9))
    work = np.empty((6, 6))
    for t in range(faces.shape[0]):
        membrane_element(load(x, faces[t, 0]), load(x, faces[t, 1]), load(x, faces[t, 2]),
                         dr_inv[t], area[t], stretch[t], k_shear[t], True, g, hess, work)
        for a in range(3):
            ia = faces[t, a]
            for p in range(3):
                acc = 0.0
                for b in range(3):
                    ib = faces[t, b]
                    for q in range(3):
                        acc += hess[3 * a + p, 3 * b + q] * v[ib, q]
                out[ia, p] += scale_by * acc


@njit(cache=True)
def membrane_total_energy(x, faces, dr_inv, area, stretch, k_shear):
    total = 0.0
    for t in range(faces.shape[0]):
        total += membrane_energy(load(x, faces[t, 0]), load(x, faces[t, 1]), load(x, faces[t, 2]),
                                 dr_inv[t], area[t], stretch[t], k_shear[t])
    return total


@njit(cache=True)
def max_principal_stretch(x, faces, dr_inv):
    """Largest λ1 = √(largest eigenvalue of FᵀF) over all triangles."""
    worst = 0.0
    for t in range(faces.shape[0]):
        f0, f1, _, _ = deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                    load(x, faces[t, 2]), dr_inv[t])
        c00, c11, c01 = dot(f0, f0), dot(f1, f1), dot(f0, f1)
        half = 0.5 * (c00 - c11)
        lam = 0.5 * (c00 + c11) + np.sqrt(half * half + c01 * c01)
        worst = max(worst, np.sqrt(lam))
    return worst
