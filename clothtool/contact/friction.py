"""Smoothed Coulomb friction as a dissipative potential (Li et al. 2020, "Incremental
Potential Contact", §5).

Each contact pair k of the lag (the barrier's active pairs at the lag positions) keeps
its normal force λ_k (the barrier's −∂E/∂d, N), an orthonormal tangent basis T_k (3×2,
⟂ its normal), its closest-point weights w_k on its cloth vertices (0 on collider
vertices) and c_k, the collider's own surface velocity weighted the same way (0 for
cloth–cloth pairs). At cloth positions x the pair's tangential relative velocity at the
end of the step is

    v_k(x) = T_kᵀ (Σ_j w_kj (x_j − b_j)/ĥ + c_k),

b and ĥ the integrator's base and velocity step (backward Euler: x_n and h; BDF2:
(4x_n − x_{n−1})/3 and 2h/3, so that v is the integrator's own velocity). Friction adds

    D(x) = Σ_k μ_k λ_k ĥ F0(‖v_k‖),    F0'(v) = f1(v/ε_v),  f1(s) = 2s − s² (s < 1), 1 beyond,

F0(v) = ε_v (s² − s³/3) for s = v/ε_v < 1 and v − ε_v/3 beyond, to the incremental
potential. Its force −∇_{x_j} D = −μλ f1(s) w_j T v̂ is Coulomb's μλ against the slip
above ε_v and a stiff viscous hold below it: a sheet on an incline creeps at most at
ε_v where Coulomb's law says it sticks. The Hessian per pair is w wᵀ ⊗ B with

    B = (μλ/ĥ) T [F0''(v) v̂v̂ᵀ + F0'(v)/v (I − v̂v̂ᵀ)] Tᵀ,  F0'' = (2 − 2s)/ε_v, F0'/v = (2 − s)/ε_v
    (s < 1), F0'' = 0, F0'/v = 1/v beyond,

positive semi-definite as it stands (IPC's f1 is built for that), and 2μλ/(ĥε_v) T Tᵀ at
v = 0. λ, T, w and c are lagged: the Newton loop re-lags them at its solution until the
friction force they give stops changing (:mod:`clothtool.sim.solve.contact`). A sliding
pair's zero curvature along v̂ lets Newton's steps overshoot across the stick–slip threshold
and back; where a pair's slip has reversed against its reference (its slip when lagged),
or (``solver.overshoot_bound``) a Newton step of the same lag turned its slip from sliding
to the other side (:func:`slip_overshoots`), Newton's matrix takes instead the curvature
μλ/(ĥ‖v‖) T Tᵀ of the half-quadratic bound ‖v‖ ≤ ‖v‖²/(2v₀) + v₀/2 at v₀ = ‖v‖ (the
potential itself is unchanged), which makes the step shorter there. Only pairs that did
overshoot take it: on every sliding pair it slows a sheet sliding down an incline 3.4–4.4 %
below Coulomb's rate (the step test stops such linear convergence early); on the overshot
pairs alone it moves the 15° cloth-on-cloth slide 2.3 % off that rate, so it is an option.
With ``solver.slow_slip_bound`` v_b, every pair slipping slower than v_b takes the isotropic
curvature (μλ/ĥ) F0'(v)/v T Tᵀ of the bound F0(‖u‖) ≤ F0(v) + F0'(v)(‖u‖² − v²)/(2v)
(:func:`bound_slow_slips`): slips of a few ε_v, which the Newton tolerance does not
resolve, are where the twisted sheet's Newton steps oscillate.
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner


@njit(cache=True)
def f0(v, eps_v):
    """F0(v) = ∫₀^v f1(u/ε_v) du."""
    s = v / eps_v
    if s < 1.0:
        return eps_v * (s * s - s * s * s / 3.0)
    return v - eps_v / 3.0


@njit(cache=True)
def f1(v, eps_v):
    """f1(v/ε_v) = F0'(v): 2s − s² below ε_v, 1 beyond."""
    s = v / eps_v
    if s < 1.0:
        return s * (2.0 - s)
    return 1.0


@njit(cache=True)
def tangent_basis(n):
    """(3, 2) orthonormal columns ⟂ the unit vector n: the first along n × (the axis least
    aligned with n), the second n × the first."""
    a0, a1, a2 = abs(n[0]), abs(n[1]), abs(n[2])
    e = np.zeros(3)
    if a0 <= a1 and a0 <= a2:
        e[0] = 1.0
    elif a1 <= a2:
        e[1] = 1.0
    else:
        e[2] = 1.0
    t0 = np.array([n[1] * e[2] - n[2] * e[1], n[2] * e[0] - n[0] * e[2], n[0] * e[1] - n[1] * e[0]])
    t0 /= np.sqrt(t0[0] ** 2 + t0[1] ** 2 + t0[2] ** 2)
    t1 = np.array([n[1] * t0[2] - n[2] * t0[1], n[2] * t0[0] - n[0] * t0[2], n[0] * t0[1] - n[1] * t0[0]])
    out = np.empty((3, 2))
    for i in range(3):
        out[i, 0] = t0[i]
        out[i, 1] = t1[i]
    return out


@njit_inner(cache=True)
def _slip(x, base, inv_h, row, w, basis, c, n):
    """v = Tᵀ(Σ_j w_j (x_j − b_j)/ĥ + c) of one pair (cloth vertices j < n only)."""
    r0, r1, r2 = c[0], c[1], c[2]
    for j in range(4):
        v = row[j]
        if v < n and w[j] != 0.0:
            r0 += w[j] * (x[v, 0] - base[v, 0]) * inv_h
            r1 += w[j] * (x[v, 1] - base[v, 1]) * inv_h
            r2 += w[j] * (x[v, 2] - base[v, 2]) * inv_h
    return (basis[0, 0] * r0 + basis[1, 0] * r1 + basis[2, 0] * r2,
            basis[0, 1] * r0 + basis[1, 1] * r1 + basis[2, 1] * r2)


@njit(cache=True)
def friction_energy(x, base, h_eff, eps_v, rows, weights, bases, mu_lambda, c, count, n):
    """D(x) = Σ_k μλ ĥ F0(‖v_k‖) over the first ``count`` lagged pairs (x, base: (≥ n, 3))."""
    total = 0.0
    inv_h = 1.0 / h_eff
    for k in range(count):
        a, b = _slip(x, base, inv_h, rows[k], weights[k], bases[k], c[k], n)
        total += mu_lambda[k] * h_eff * f0(np.sqrt(a * a + b * b), eps_v)
    return total


@njit(cache=True)
def friction_assemble(x, base, h_eff, eps_v, rows, weights, bases, mu_lambda, c, count, n,
                      grad, blocks):
    """D(x); adds ∇D into grad (≥ n, 3) and writes each pair's Hessian block B (3×3, see
    the module) into blocks[k], so that its Hessian is w_k w_kᵀ ⊗ B on its cloth vertices."""
    total = 0.0
    inv_h = 1.0 / h_eff
    for k in range(count):
        basis = bases[k]
        a, b = _slip(x, base, inv_h, rows[k], weights[k], basis, c[k], n)
        v = np.sqrt(a * a + b * b)
        ml = mu_lambda[k]
        total += ml * h_eff * f0(v, eps_v)
        s = v / eps_v
        if s < 1.0:
            along = (2.0 - 2.0 * s) / eps_v  # F0''(v)
            across = (2.0 - s) / eps_v  # F0'(v)/v
        else:
            along = 0.0
            across = 1.0 / v
        # force along T v̂ with magnitude μλ f1; f1(s)/v·(a, b) = F0'(v)/v·(a, b)
        g0 = ml * across * a
        g1 = ml * across * b
        t0 = basis[0, 0] * g0 + basis[0, 1] * g1
        t1 = basis[1, 0] * g0 + basis[1, 1] * g1
        t2 = basis[2, 0] * g0 + basis[2, 1] * g1
        row = rows[k]
        for j in range(4):
            vj = row[j]
            wj = weights[k, j]
            if vj < n and wj != 0.0:
                grad[vj, 0] += wj * t0
                grad[vj, 1] += wj * t1
                grad[vj, 2] += wj * t2
        # 2×2 H2 = along v̂v̂ᵀ + across (I − v̂v̂ᵀ), then B = (μλ/ĥ) T H2 Tᵀ
        if v > 0.0:
            ua, ub = a / v, b / v
        else:
            ua, ub = 1.0, 0.0
        h00 = along * ua * ua + across * (1.0 - ua * ua)
        h01 = (along - across) * ua * ub
        h11 = along * ub * ub + across * (1.0 - ub * ub)
        scale = ml * inv_h
        for p in range(3):
            tp0 = basis[p, 0] * h00 + basis[p, 1] * h01
            tp1 = basis[p, 0] * h01 + basis[p, 1] * h11
            for q in range(3):
                blocks[k, p, q] = scale * (tp0 * basis[q, 0] + tp1 * basis[q, 1])
    return total


@njit(cache=True)
def friction_lag(y, stencils, active, n_active, weights, normals, force, obstacle, mu, mu_self,
                 velocity, field, rigid, n, rows, w_out, bases, mu_lambda, c):
    """The lagged friction pairs of the barrier's active pairs at positions y (as
    ``contact_assemble`` leaves them): for each with μ > 0 and a normal force, its stencil,
    its weights on the cloth vertices (< n), its tangent basis, μλ, and c = Σ_j w_j u_j over
    its collider vertices of their surface velocity u_j. A rigidly moving collider's u is its
    velocity field ``field`` (centre, angular velocity, translation velocity: u(q) =
    v + ω × (q − centre)) at the cloth side's closest point q, which is exact for spheres,
    capsules and planes turning under the cloth; an animated mesh's (``rigid`` False) is
    its vertex velocity ``velocity``. The pair's μ is its collider's (``mu`` per vertex) or
    ``mu_self`` for cloth–cloth. Returns the number of pairs written."""
    count = 0
    for a in range(n_active):
        st = stencils[active[a]]
        m = mu_self
        for j in range(4):
            if obstacle[st[j]]:
                m = mu[st[j]]
        if m == 0.0 or force[a] <= 0.0:
            continue
        q = np.zeros(3)  # the cloth side's closest point: Σ w_j x_j / Σ w_j over its vertices
        side = 0.0
        for j in range(4):
            if st[j] < n:
                side += weights[a, j]
                for i in range(3):
                    q[i] += weights[a, j] * y[st[j], i]
        if side != 0.0:
            q /= side
        for i in range(3):
            c[count, i] = 0.0
        for j in range(4):
            v = st[j]
            rows[count, j] = v
            if v < n:
                w_out[count, j] = weights[a, j]
                continue
            w_out[count, j] = 0.0
            if rigid[v]:
                f = field[v]
                r0, r1, r2 = q[0] - f[0], q[1] - f[1], q[2] - f[2]
                u0 = f[6] + f[4] * r2 - f[5] * r1
                u1 = f[7] + f[5] * r0 - f[3] * r2
                u2 = f[8] + f[3] * r1 - f[4] * r0
            else:
                u0, u1, u2 = velocity[v, 0], velocity[v, 1], velocity[v, 2]
            c[count, 0] += weights[a, j] * u0
            c[count, 1] += weights[a, j] * u1
            c[count, 2] += weights[a, j] * u2
        bases[count] = tangent_basis(normals[a])
        mu_lambda[count] = m * force[a]
        count += 1
    return count


@njit(cache=True)
def reference_slips(u, rows, weights, bases, c, count, n):
    """(count, 2) the slip T_kᵀ(Σ_j w_kj u_j + c_k) of each lagged pair at the cloth
    velocities u (N, 3): the direction each pair slid in when it was lagged."""
    out = np.zeros((count, 2))
    for k in range(count):
        r = c[k].copy()
        for j in range(4):
            v = rows[k, j]
            if v < n and weights[k, j] != 0.0:
                for i in range(3):
                    r[i] += weights[k, j] * u[v, i]
        for a in range(2):
            out[k, a] = bases[k, 0, a] * r[0] + bases[k, 1, a] * r[1] + bases[k, 2, a] * r[2]
    return out


@njit(cache=True)
def slip_overshoots(y, dy, step, base, h_eff, eps_v, rows, weights, bases, c, count, n,
                    overshot):
    """Mark in ``overshot`` (count,) each lagged pair that slides at y (‖v‖ ≥ ε_v) and whose
    slip at y + step·dy points against it: a Newton step that carried it through the
    stick–slip threshold to the other side (y, dy: (≥ n, 3), cloth rows first). Returns the
    number newly marked."""
    inv_h = 1.0 / h_eff
    marked = 0
    for k in range(count):
        if overshot[k]:
            continue
        a, b = _slip(y, base, inv_h, rows[k], weights[k], bases[k], c[k], n)
        if a * a + b * b < eps_v * eps_v:
            continue
        a1, b1 = _slip_along(y, dy, step, base, inv_h, rows[k], weights[k], bases[k], c[k], n)
        if a * a1 + b * b1 < 0.0:
            overshot[k] = True
            marked += 1
    return marked


@njit_inner(cache=True)
def _slip_along(y, dy, step, base, inv_h, row, w, basis, c, n):
    """The slip of one pair at y + step·dy."""
    r0, r1, r2 = c[0], c[1], c[2]
    for j in range(4):
        v = row[j]
        if v < n and w[j] != 0.0:
            r0 += w[j] * (y[v, 0] + step * dy[v, 0] - base[v, 0]) * inv_h
            r1 += w[j] * (y[v, 1] + step * dy[v, 1] - base[v, 1]) * inv_h
            r2 += w[j] * (y[v, 2] + step * dy[v, 2] - base[v, 2]) * inv_h
    return (basis[0, 0] * r0 + basis[1, 0] * r1 + basis[2, 0] * r2,
            basis[0, 1] * r0 + basis[1, 1] * r1 + basis[2, 1] * r2)


@njit_inner(cache=True)
def _tangent_block(scale, basis, block):
    """block = scale · T Tᵀ: an isotropic curvature in the pair's tangent plane."""
    for p in range(3):
        for q in range(3):
            block[p, q] = scale * (basis[p, 0] * basis[q, 0] + basis[p, 1] * basis[q, 1])


@njit(cache=True)
def bound_reversed_slips(x, base, h_eff, eps_v, rows, weights, bases, mu_lambda, c, count, n,
                         reference, overshot, blocks):
    """Where a pair slides (‖v‖ ≥ ε_v) against its reference slip (v·v_ref < 0: it reversed
    within the step) or has overshot the stick–slip threshold in a Newton step of this lag
    (``overshot``, :func:`slip_overshoots`), its Hessian block becomes (μλ/(ĥ‖v‖)) T Tᵀ, the
    curvature of the half-quadratic bound ‖v‖ ≤ ‖v‖²/(2v₀) + v₀/2 at v₀ = ‖v‖, in place of
    the zero curvature along v̂ that lets Newton overshoot back and forth across the
    stick–slip threshold. Returns the number of pairs bounded."""
    inv_h = 1.0 / h_eff
    bounded = 0
    for k in range(count):
        a, b = _slip(x, base, inv_h, rows[k], weights[k], bases[k], c[k], n)
        v = np.sqrt(a * a + b * b)
        if v < eps_v or (a * reference[k, 0] + b * reference[k, 1] >= 0.0 and not overshot[k]):
            continue
        scale = mu_lambda[k] * inv_h / v
        _tangent_block(scale, bases[k], blocks[k])
        bounded += 1
    return bounded


@njit(cache=True)
def bound_slow_slips(x, base, h_eff, eps_v, slow, rows, weights, bases, mu_lambda, c, count, n,
                     blocks):
    """Where a pair slips slower than ``slow`` (m/s), its Hessian block becomes the isotropic
    (μλ/ĥ) F0'(v)/v T Tᵀ, the curvature of the half-quadratic bound
    F0(‖u‖) ≤ F0(v) + F0'(v)(‖u‖² − v²)/(2v) at v = ‖v_k‖ (F0' concave on [0, ∞): F0'(v)/v
    falls with v, 2/ε_v at v = 0), in place of F0''(v) along v̂, which is (2 − 2s)/ε_v below
    ε_v and 0 beyond: Newton's steps at slips that the Newton tolerance does not resolve
    then cannot carry them back and forth across the stick–slip threshold (the
    iteratively reweighted step of a norm, Weiszfeld's; Beck & Sabach 2015, "Weiszfeld's
    method: old and new results"). Returns the number of pairs bounded."""
    inv_h = 1.0 / h_eff
    bounded = 0
    for k in range(count):
        a, b = _slip(x, base, inv_h, rows[k], weights[k], bases[k], c[k], n)
        v = np.sqrt(a * a + b * b)
        if v >= slow:
            continue
        s = v / eps_v
        scale = mu_lambda[k] * inv_h * ((2.0 - s) / eps_v if s < 1.0 else 1.0 / v)
        _tangent_block(scale, bases[k], blocks[k])
        bounded += 1
    return bounded
