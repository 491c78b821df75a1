"""Smoothed Coulomb friction (IPC, Li et al. 2020, §5): the mollifier f0/f1, the potential's
gradient and Hessian against finite differences and against ipctk's FrictionPotential, and
the lag (normal forces, tangent bases, a rigid collider's surface velocity).

ipctk 1.x writes the dissipative potential in velocities, D_ipc(v) = Σ μλ f0_ipc(‖Tᵀv‖),
with f0_ipc = our F0 + ε_v/3 (a constant); ours is in positions, D(x) = Σ μλ ĥ F0(‖v(x)‖)
with v = (x − base)/ĥ, so D = ĥ (D_ipc − Σ μλ ε_v/3), ∇_x D = ∇_v D_ipc and
∇²_x D = ∇²_v D_ipc / ĥ.
"""

import ipctk
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.contact.barrier import (EDGE_EDGE, POINT_PLANE, POINT_TRIANGLE, contact_assemble,
                                       pair_geometry)
from clothtool.contact.friction import (bound_reversed_slips, bound_slow_slips, f0, f1,
                                        friction_assemble, friction_energy, friction_lag,
                                        reference_slips, slip_overshoots, tangent_basis)


def dense_friction_hessian(rows, weights, blocks, count, n):
    """H = Σ_k (w_k w_kᵀ) ⊗ B_k on the cloth vertices (< n), dense (3n × 3n)."""
    h = np.zeros((n, 3, n, 3))
    for k in range(count):
        for i in range(4):
            for j in range(4):
                if rows[k, i] < n and rows[k, j] < n:
                    h[rows[k, i], :, rows[k, j], :] += weights[k, i] * weights[k, j] * blocks[k]
    return h.reshape(3 * n, 3 * n)


def assemble(x, base, h_eff, eps_v, lag, count, n):
    """(D, ∇D (n, 3), dense Hessian) from friction_assemble."""
    rows, weights, bases, mu_lambda, c = lag
    grad = np.zeros((len(x), 3))
    blocks = np.zeros((count, 3, 3))
    e = friction_assemble(x, base, h_eff, eps_v, rows, weights, bases, mu_lambda, c, count, n, grad,
                          blocks)
    assert not grad[n:].any()  # held vertices take no force
    return e, grad[:n], dense_friction_hessian(rows, weights, blocks, count, n)


def slip(x, base, h_eff, lag, k):
    """v_k = T_kᵀ (Σ_j w_kj (x_j − b_j)/ĥ + c_k), by numpy (cloth weights only)."""
    rows, weights, bases, _, c = lag
    r = c[k] + sum(weights[k, j] * (x[rows[k, j]] - base[rows[k, j]]) for j in range(4)) / h_eff
    return bases[k].T @ r


# ---------------------------------------------------------------- the mollifier


@pytest.mark.parametrize("eps_v", [1e-3, 0.05, 2.0])
def test_f0_f1_closed_forms(eps_v):
    for s in [0.0, 1e-6, 0.1, 0.5, 0.99, 1.0, 1.5, 10.0, 1e4]:
        v = s * eps_v
        if s < 1.0:
            assert f0(v, eps_v) == pytest.approx(eps_v * (s * s - s**3 / 3.0), rel=1e-14, abs=0)
            assert f1(v, eps_v) == pytest.approx(2.0 * s - s * s, rel=1e-14, abs=0)
        else:
            assert f0(v, eps_v) == pytest.approx(v - eps_v / 3.0, rel=1e-14)
            assert f1(v, eps_v) == 1.0
    # C¹ at ε_v (F0 = 2ε/3, f1 = 1 from both sides), F0(0) = f1(0) = 0, f1 rises monotonically
    below, above = np.nextafter(eps_v, 0.0), eps_v
    assert f0(below, eps_v) == pytest.approx(f0(above, eps_v), rel=1e-12)
    assert f0(above, eps_v) == pytest.approx(2.0 * eps_v / 3.0, rel=1e-14)
    assert f1(below, eps_v) == pytest.approx(1.0, rel=1e-12)
    assert f0(0.0, eps_v) == 0.0 and f1(0.0, eps_v) == 0.0
    s = np.linspace(0.0, 2.0, 201)
    assert np.all(np.diff([f1(q * eps_v, eps_v) for q in s]) >= 0.0)


@settings(max_examples=200, deadline=None)
@given(s=st.floats(1e-3, 50.0), eps_v=st.floats(1e-4, 10.0))
def test_f0_derivative_is_f1(s, eps_v):
    """F0' = f1 by central differences, on both sides of ε_v (not straddling it)."""
    v = s * eps_v
    step = 1e-6 * eps_v * min(1.0, s)
    if abs(s - 1.0) * eps_v < 2 * step:
        return
    fd = (f0(v + step, eps_v) - f0(v - step, eps_v)) / (2 * step)
    assert fd == pytest.approx(f1(v, eps_v), rel=1e-6, abs=1e-9)


@pytest.mark.parametrize("eps_v", [1e-3, 0.05, 2.0])
def test_f0_f1_match_ipctk(eps_v):
    """ipctk's smooth_friction_f0 is our F0 + ε_v/3; f1, f1/v and f2 = F0'' agree."""
    for s in [0.0, 1e-6, 0.1, 0.5, 0.999, 1.0, 1.001, 3.0, 1e3]:
        v = s * eps_v
        assert ipctk.smooth_friction_f0(v, eps_v) == pytest.approx(f0(v, eps_v) + eps_v / 3.0, rel=1e-13)
        assert ipctk.smooth_friction_f1(v, eps_v) == pytest.approx(f1(v, eps_v), rel=1e-13, abs=1e-300)
        if v > 0.0:
            assert ipctk.smooth_friction_f1_over_x(v, eps_v) == pytest.approx(f1(v, eps_v) / v, rel=1e-12)
        f2 = (2.0 - 2.0 * s) / eps_v if s < 1.0 else 0.0
        assert ipctk.smooth_friction_f2(v, eps_v) == pytest.approx(f2, rel=1e-12, abs=1e-12 / eps_v)


# ---------------------------------------------------------------- the potential


def tangent_basis_np(n):
    return tangent_basis(np.asarray(n, float) / np.linalg.norm(n))


@pytest.mark.parametrize("n", [[0, 0, 1], [1, 0, 0], [0, -1, 0], [0.3, -0.8, 0.52], [1e-9, 1, 1e-9]])
def test_tangent_basis_is_orthonormal_and_perpendicular(n):
    n = np.asarray(n, float) / np.linalg.norm(n)
    t = tangent_basis(n)
    assert np.allclose(t.T @ t, np.eye(2), atol=1e-14)
    assert np.allclose(n @ t, 0.0, atol=1e-14)
    assert np.allclose(t @ t.T, np.eye(3) - np.outer(n, n), atol=1e-14)


REGIMES = {"slip": (1.3, 6.0), "stick": (0.05, 0.85), "mixed": None}


def random_lag(rng, n, n_held, count, eps_v, h_eff, regime, x, base):
    """``count`` random friction pairs on n cloth and n_held held vertices, each with c set
    so that its slip ‖v_k‖/ε_v at x lies in the regime's range."""
    rows = np.empty((count, 4), np.int64)
    weights = np.zeros((count, 4))
    bases = np.empty((count, 3, 2))
    mu_lambda = rng.uniform(0.1, 5.0, count)
    c = np.zeros((count, 3))
    for k in range(count):
        rows[k] = rng.choice(n + n_held, 4, replace=False)
        weights[k] = rng.uniform(-1.0, 1.0, 4)
        weights[k, rows[k] >= n] = 0.0  # friction_lag leaves collider weights 0
        normal = rng.normal(size=3)
        bases[k] = tangent_basis_np(normal)
        lo, hi = REGIMES[regime] if regime != "mixed" else REGIMES[("slip", "stick")[k % 2]]
        s = rng.uniform(lo, hi)
        angle = rng.uniform(0, 2 * np.pi)
        want = s * eps_v * (np.cos(angle) * bases[k][:, 0] + np.sin(angle) * bases[k][:, 1])
        cloth = sum(weights[k, j] * (x[rows[k, j]] - base[rows[k, j]]) for j in range(4)) / h_eff
        c[k] = want - cloth + rng.normal() * normal  # the normal part is projected out
    return rows, weights, bases, mu_lambda, c


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), regime=st.sampled_from(sorted(REGIMES)),
       eps_v=st.sampled_from([1e-3, 0.02, 0.5]), h_eff=st.sampled_from([1e-3, 1 / 60, 0.1]))
def test_friction_gradient_and_hessian_match_finite_differences(seed, regime, eps_v, h_eff):
    rng = np.random.default_rng(seed)
    n, n_held, count = 6, 2, 5
    base = rng.normal(size=(n + n_held, 3))
    x = base + eps_v * h_eff * rng.normal(size=base.shape)
    lag = random_lag(rng, n, n_held, count, eps_v, h_eff, regime, x, base)
    speeds = [np.linalg.norm(slip(x, base, h_eff, lag, k)) / eps_v for k in range(count)]
    assert all(0.04 < s < 6.1 for s in speeds)  # the construction holds
    e, grad, hess = assemble(x, base, h_eff, eps_v, lag, count, n)
    want = sum(lag[3][k] * h_eff * f0(speeds[k] * eps_v, eps_v) for k in range(count))
    assert e == pytest.approx(want, rel=1e-10)
    assert e == pytest.approx(friction_energy(x, base, h_eff, eps_v, *lag, count, n), rel=1e-14)
    # central differences with a step far below the velocity scale ε_v ĥ of the positions
    step = 1e-4 * eps_v * h_eff
    fd_grad = np.empty(3 * n)
    fd_hess = np.empty((3 * n, 3 * n))
    for a in range(3 * n):
        xp, xm = x.copy(), x.copy()
        xp[a // 3, a % 3] += step
        xm[a // 3, a % 3] -= step
        fd_grad[a] = (friction_energy(xp, base, h_eff, eps_v, *lag, count, n)
                      - friction_energy(xm, base, h_eff, eps_v, *lag, count, n)) / (2 * step)
        fd_hess[:, a] = (assemble(xp, base, h_eff, eps_v, lag, count, n)[1]
                         - assemble(xm, base, h_eff, eps_v, lag, count, n)[1]).ravel() / (2 * step)
    scale_g, scale_h = np.abs(grad).max(), np.abs(hess).max()
    assert np.abs(grad.ravel() - fd_grad).max() < 1e-5 * scale_g
    assert np.abs(hess - fd_hess).max() < 1e-5 * scale_h
    assert np.allclose(hess, hess.T, atol=1e-12 * scale_h)
    assert np.linalg.eigvalsh(hess).min() > -1e-10 * scale_h


def one_pair(eps_v, h_eff, v):
    """One cloth vertex (0) against a held one (1) on a pair with weights (1, −1), normal z,
    mu_lambda 2 and slip velocity v (3,) at x = 0 (c carries it)."""
    lag = (np.array([[0, 1, 1, 1]]), np.array([[1.0, 0.0, 0.0, 0.0]]),
           tangent_basis_np([0, 0, 1])[None], np.array([2.0]), np.asarray(v, float)[None])
    x = np.zeros((2, 3))
    return assemble(x, x, h_eff, eps_v, lag, 1, 1)


def test_coulomb_force_in_slip_and_stiff_hold_at_rest():
    eps_v, h_eff = 0.01, 0.02
    # sliding at 5 ε_v along (3, 4)/5 with a normal part: force μλ against the slip
    _, grad, hess = one_pair(eps_v, h_eff, [0.03, 0.04, 7.0])
    assert np.allclose(grad[0], 2.0 * np.array([0.6, 0.8, 0.0]), rtol=1e-12)
    # beyond ε_v the Hessian is (μλ/ĥ)/v (I − v̂v̂ᵀ) in the plane, nothing along n or v̂
    v_hat = np.array([0.6, 0.8, 0.0])
    perp = np.array([-0.8, 0.6, 0.0])
    assert np.allclose(hess, 2.0 / h_eff / 0.05 * np.outer(perp, perp), atol=1e-9)
    # at rest: 2μλ/(ĥ ε_v) T Tᵀ, no force
    _, grad, hess = one_pair(eps_v, h_eff, [0.0, 0.0, 1.0])
    assert not grad.any()
    assert np.allclose(hess, 2.0 * 2.0 / (h_eff * eps_v) * np.diag([1.0, 1.0, 0.0]), atol=1e-9)
    # in the smoothed stick region the force is μλ f1(v) along v̂
    _, grad, _ = one_pair(eps_v, h_eff, 0.3 * eps_v * v_hat)
    assert np.allclose(grad[0], 2.0 * (0.6 - 0.09) * v_hat, rtol=1e-12)


# ---------------------------------------------------------------- against ipctk


def lag_pair(x, faces, edges, obstacle, st, dhat, kappa, mu, mu_self=None):
    """Our pipeline on one pair: contact_assemble at x, then friction_lag (static colliders)."""
    n_total = len(x)
    geo = pair_geometry(obstacle, np.zeros(n_total), x, 0.0, 0.0, dhat, dhat)
    grad = np.zeros_like(x)
    act, w, nrm, coef, force = (np.zeros(1, np.int64), np.zeros((1, 4)), np.zeros((1, 3)),
                                np.zeros(1), np.zeros(1))
    _, n_act, _ = contact_assemble(x, st, geo, kappa, grad, act, w, nrm, coef, force,
                                   np.zeros((1, 2, 4)))
    assert n_act == 1
    n = int((~obstacle).sum())
    lag = (np.zeros((1, 4), np.int64), np.zeros((1, 4)), np.zeros((1, 3, 2)), np.zeros(1),
           np.zeros((1, 3)))
    count = friction_lag(x, st, act, n_act, w, nrm, force, obstacle, np.full(n_total, mu),
                         mu if mu_self is None else mu_self, np.zeros((n_total, 3)),
                         np.zeros((n_total, 9)), np.zeros(n_total, bool), n, *lag)
    assert count == 1
    return lag, force[0], n


@pytest.mark.parametrize("kind", ["fv", "ee"])
@pytest.mark.parametrize("regime", ["slip", "stick", "rest"])
@pytest.mark.parametrize("seed", range(4))
def test_friction_matches_ipctk_friction_potential(kind, regime, seed):
    """A cloth vertex over a collider triangle (face–vertex) and two crossing cloth edges
    (edge–edge): our normal force λ is ipctk's normal_force_magnitude (barrier stiffness
    κ d̂²), and D, ∇D and ∇²D are ipctk's FrictionPotential in the velocities v = (x − x_lag)/ĥ
    scaled as in the module docstring."""
    rng = np.random.default_rng(seed)
    dhat, kappa, mu, eps_v, h_eff = 0.02, 3.0, 0.4, 0.01, 1 / 60
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if kind == "fv":
        y = np.array([[0.3, 0.2, 0.008], [0, 0, 0], [1, 0, 0], [0, 1, 0]]) @ q.T
        faces, edges = np.array([[1, 2, 3]]), np.array([[1, 2], [2, 3], [1, 3]])
        st_ = np.array([[0, 1, 2, 3, POINT_TRIANGLE]])
        obstacle = np.array([False, True, True, True])
    else:
        y = np.array([[-0.5, 0.1, 0], [0.5, 0, 0], [0.1, -0.5, 0.01], [0, 0.5, 0.011]]) @ q.T
        faces, edges = np.zeros((0, 3), np.int64), np.array([[0, 1], [2, 3]])
        st_ = np.array([[0, 1, 2, 3, EDGE_EDGE]])
        obstacle = np.zeros(4, bool)
    lag, force, n = lag_pair(y, faces, edges, obstacle, st_, dhat, kappa, mu)
    mesh = ipctk.CollisionMesh(y, edges, faces)
    normal = ipctk.NormalCollisions()
    normal.build(mesh, y, dhat)
    barrier = ipctk.BarrierPotential(ipctk.NormalizedClampedLogBarrier(), dhat, kappa * dhat**2)
    tangential = ipctk.TangentialCollisions()
    tangential.build(mesh, y, normal, barrier, mu)
    found = tangential.fv_collisions if kind == "fv" else tangential.ee_collisions
    assert len(tangential) == len(found) == 1  # (read through the list: ipctk's tc[i] crashes at exit)
    assert found[0].normal_force_magnitude == pytest.approx(force, rel=1e-10)
    assert lag[3][0] == pytest.approx(mu * force, rel=1e-14)
    t_ipc = found[0].tangent_basis
    assert np.allclose(lag[2][0] @ lag[2][0].T, t_ipc @ t_ipc.T, atol=1e-12)  # the same plane
    # velocities of the cloth (collider vertices at rest), vertex 0's tangential part set so
    # that the pair's tangential slip has the regime's speed
    speed = {"slip": 3.0, "stick": 0.4, "rest": 0.0}[regime] * eps_v
    velocity = np.zeros_like(y)
    velocity[:n] = eps_v * rng.normal(size=(n, 3))
    angle = rng.uniform(0.0, 2 * np.pi)
    target = speed * np.array([np.cos(angle), np.sin(angle)])
    basis, w0 = lag[2][0], lag[1][0, 0]
    velocity[0] += basis @ (target - slip(y + h_eff * velocity, y, h_eff, lag, 0)) / w0
    x = y + h_eff * velocity
    v_now = np.linalg.norm(slip(x, y, h_eff, lag, 0))
    assert v_now == pytest.approx(speed, abs=1e-12 * eps_v)
    e, grad, hess = assemble(x, y, h_eff, eps_v, lag, 1, n)
    friction = ipctk.FrictionPotential(eps_v)
    mu_lambda = mu * force
    assert e == pytest.approx(h_eff * (friction(tangential, mesh, velocity) - mu_lambda * eps_v / 3.0),
                              rel=1e-9, abs=1e-15)
    g_ipc = friction.gradient(tangential, mesh, velocity).reshape(-1, 3)
    assert np.allclose(grad, g_ipc[:n], rtol=1e-9, atol=1e-12 * mu_lambda)
    h_ipc = friction.hessian(tangential, mesh, velocity).toarray()[:3 * n, :3 * n] / h_eff
    assert np.allclose(hess, h_ipc, rtol=1e-9, atol=1e-9 * np.abs(h_ipc).max())


# ---------------------------------------------------------------- the lag


def rigid_velocity(field, q):
    """u(q) = v + ω × (q − centre) of a field row (centre, ω, v)."""
    return field[6:] + np.cross(field[3:6], q - field[:3])


def lag_one(x, st_, obstacle, radius, field=None, velocity=None, mu=0.5, mu_self=0.2, dhat=0.05):
    """contact_assemble then friction_lag for one pair; returns (lag, count, pair data)."""
    n_total = len(x)
    n = int((~obstacle).sum())
    geo = pair_geometry(obstacle, radius, x, 0.0, 0.0, dhat, dhat)
    act, w, nrm, coef, force = (np.zeros(1, np.int64), np.zeros((1, 4)), np.zeros((1, 3)),
                                np.zeros(1), np.zeros(1))
    _, n_act, _ = contact_assemble(x, st_, geo, 1.0, np.zeros_like(x), act, w, nrm, coef, force,
                                   np.zeros((1, 2, 4)))
    assert n_act == 1 and force[0] > 0
    rigid = np.zeros(n_total, bool)
    fields = np.zeros((n_total, 9))
    if field is not None:
        rigid[n:] = True
        fields[n:] = field
    lag = (np.zeros((1, 4), np.int64), np.zeros((1, 4)), np.zeros((1, 3, 2)), np.zeros(1),
           np.zeros((1, 3)))
    mus = np.where(obstacle, mu, 0.0)
    vel = np.zeros((n_total, 3)) if velocity is None else velocity
    count = friction_lag(x, st_, act, n_act, w, nrm, force, obstacle, mus, mu_self, vel, fields,
                         rigid, n, *lag)
    return lag, count, (w[0], nrm[0], force[0]), n


# rotating about the axis k̂ = (0.3, 0.4, 0.866…) through (0.1, −0.2, 0.5) at 2 rad/s, translating
SPIN = np.r_[[0.1, -0.2, 0.5], 2.0 * np.array([0.3, 0.4, np.sqrt(0.75)]), [0.05, 0.0, -0.02]]


def test_friction_lag_of_a_sphere_takes_its_rigid_velocity_at_the_cloth_contact_point():
    """A cloth triangle under a rotating sphere (its centre, radius R, a vertex–triangle pair):
    c = u(q) at the closest point q on the triangle, the cloth weights are the barrier's."""
    big_r = 0.3
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.2, big_r + 0.01]], float)
    obstacle = np.array([False, False, False, True])
    lag, count, (w, nrm, force), n = lag_one(x, np.array([[3, 0, 1, 2, POINT_TRIANGLE]]), obstacle,
                                              np.array([0, 0, 0, big_r]), SPIN)
    rows, weights, bases, mu_lambda, c = lag
    assert count == 1 and list(rows[0]) == [3, 0, 1, 2]
    assert weights[0, 0] == 0.0 and np.allclose(weights[0, 1:], w[1:])
    q = np.array([0.3, 0.2, 0.0])
    assert np.allclose(-w[1:] @ x[:3], q)
    assert np.allclose(c[0], rigid_velocity(SPIN, q), rtol=1e-12)
    assert mu_lambda[0] == pytest.approx(0.5 * force)
    assert np.allclose(bases[0] @ bases[0].T, np.eye(3) - np.outer(nrm, nrm), atol=1e-14)
    # the cloth at rest is dragged along the sphere's tangential surface velocity
    grad = np.zeros((4, 3))
    friction_assemble(x, x, 0.01, 1e-3, *lag, count, n, grad, np.zeros((1, 3, 3)))
    u_t = bases[0] @ bases[0].T @ rigid_velocity(SPIN, q)
    force_cloth = -grad[:3].sum(axis=0)  # the triangle's vertices take −w_j of it each
    assert np.allclose(force_cloth, mu_lambda[0] * u_t / np.linalg.norm(u_t), rtol=1e-10)


def test_friction_lag_of_a_plane_and_a_capsule_takes_their_rigid_velocity():
    # a cloth vertex above a plane through o with unit normal t − o, both plane vertices
    # moving with the same rigid field: c = −u(p) (weights 1 on p, −1 on o)
    normal = np.array([0.2, 0.1, 1.0]) / np.linalg.norm([0.2, 0.1, 1.0])
    o = np.array([0.1, 0.0, -0.1])
    p = o + 0.02 * normal + [0.3, -0.2, 0.04] - ([0.3, -0.2, 0.04] @ normal) * normal
    x = np.vstack([p, o, o + normal])
    lag, count, (w, nrm, force), n = lag_one(x, np.array([[0, 1, 2, 1, POINT_PLANE]]),
                                              np.array([False, True, True]), np.zeros(3), SPIN)
    rows, weights, bases, mu_lambda, c = lag
    assert count == 1 and n == 1 and np.allclose(nrm, normal)
    assert list(weights[0]) == [1.0, 0.0, 0.0, 0.0]
    assert np.allclose(c[0], -rigid_velocity(SPIN, p), rtol=1e-12)
    # a cloth edge across a capsule's axis (radius R): c = −u(q), q on the cloth edge
    big_r = 0.1
    x = np.array([[-0.5, 0.2, 0.0], [0.5, 0.3, 0.0], [0.1, -1, -big_r - 0.01], [0.0, 1, -big_r - 0.01]])
    lag, count, (w, nrm, force), n = lag_one(x, np.array([[0, 1, 2, 3, EDGE_EDGE]]),
                                              np.array([False, False, True, True]),
                                              np.array([0, 0, big_r, big_r]), SPIN)
    rows, weights, bases, mu_lambda, c = lag
    q = w[0] * x[0] + w[1] * x[1]
    assert count == 1 and np.allclose(weights[0], [w[0], w[1], 0.0, 0.0])
    assert np.allclose(c[0], -rigid_velocity(SPIN, q), rtol=1e-12)
    # an animated (non-rigid) collider mesh: c = Σ_j w_j u_j of its vertex velocities
    x = np.array([[0.3, 0.2, 0.01], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    vel = np.array([[9.0, 9, 9], [0.1, 0, 0], [0, 0.2, 0], [0, 0, 0.3]])
    lag, count, (w, _, _), _ = lag_one(x, np.array([[0, 1, 2, 3, POINT_TRIANGLE]]),
                                       np.array([False, True, True, True]), np.zeros(4), velocity=vel)
    assert np.allclose(lag[4][0], w[1:] @ vel[1:]) and np.abs(lag[4][0]).max() > 0


def test_friction_lag_picks_the_pair_coefficient_and_skips_frictionless_pairs():
    x = np.array([[-0.5, 0, 0], [0.5, 0, 0], [0.1, -0.5, 0.01], [0, 0.5, 0.011]])
    st_ = np.array([[0, 1, 2, 3, EDGE_EDGE]])
    cloth = np.zeros(4, bool)
    lag, count, (_, _, force), _ = lag_one(x, st_, cloth, np.zeros(4), mu_self=0.25)
    assert count == 1 and lag[3][0] == pytest.approx(0.25 * force) and not lag[4].any()
    assert lag_one(x, st_, cloth, np.zeros(4), mu_self=0.0)[1] == 0
    assert lag_one(x, st_, np.array([False, False, True, True]), np.zeros(4), mu=0.0)[1] == 0


# ---------------------------------------------------------------- reversed slips, curvature


N_FREE, N_HELD, COUNT, EPS_V, H_EFF = 8, 3, 12, 1e-2, 1.0 / 90.0


def mixed_pairs(seed):
    """(rng, x, base, lag): N_FREE free and N_HELD held vertices at random, their positions
    at the step's start ``base``, and COUNT lagged pairs, some sticking and some sliding."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(N_FREE + N_HELD, 3))
    base = x - H_EFF * rng.normal(size=x.shape)
    return rng, x, base, random_lag(rng, N_FREE, N_HELD, COUNT, EPS_V, H_EFF, "mixed", x, base)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reversed_slips_get_the_half_quadratic_bound_and_the_rest_keep_their_blocks(seed):
    """reference_slips gives each pair's slip at the velocities u; bound_reversed_slips replaces
    the block of each sliding pair whose slip points against its reference by
    (μλ/(ĥ‖v‖)) T Tᵀ — PSD, at least the exact block, equal to it across v̂ — and leaves the
    others (sticking, or sliding along their reference) as friction_assemble wrote them."""
    rng, x, base, lag = mixed_pairs(seed)
    n, count, eps_v, h_eff = N_FREE, COUNT, EPS_V, H_EFF
    rows, weights, bases, mu_lambda, c = lag
    u = (x[:n] - base[:n]) / h_eff
    ref = reference_slips(u, rows, weights, bases, c, count, n)
    for k in range(count):
        np.testing.assert_allclose(ref[k], slip(x, base, h_eff, lag, k), rtol=1e-10, atol=1e-12)
    ref[::3] *= -1.0  # every third pair slid the other way when it was lagged
    blocks = np.zeros((count, 3, 3))
    friction_assemble(x, base, h_eff, eps_v, *lag, count, n, np.zeros((len(x), 3)), blocks)
    bounded = blocks.copy()
    got = bound_reversed_slips(x, base, h_eff, eps_v, *lag, count, n, ref,
                               np.zeros(count, np.bool_), bounded)
    want = 0
    for k in range(count):
        v = slip(x, base, h_eff, lag, k)
        speed = np.linalg.norm(v)
        if k % 3 == 0 and speed >= eps_v:
            want += 1
            tt = bases[k] @ bases[k].T
            np.testing.assert_allclose(bounded[k], mu_lambda[k] / (h_eff * speed) * tt, rtol=1e-12)
            assert np.linalg.eigvalsh(bounded[k] - blocks[k]).min() >= -1e-9 * np.abs(bounded[k]).max()
            across = bases[k] @ np.array([-v[1], v[0]]) / speed
            assert across @ bounded[k] @ across == pytest.approx(across @ blocks[k] @ across, rel=1e-10)
        else:
            np.testing.assert_array_equal(bounded[k], blocks[k])
    assert got == want > 0


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), step=st.floats(0.1, 1.0))
def test_slip_overshoots_marks_sliding_pairs_a_step_turns_over_and_the_bound_takes_them(seed, step):
    """slip_overshoots marks each pair that slides at y (‖v‖ ≥ ε_v) and whose slip at
    y + step·dy points against it, keeps earlier marks, and counts the new ones; a marked
    pair takes the half-quadratic bound in bound_reversed_slips even along its reference."""
    rng, y, base, lag = mixed_pairs(seed)
    n, count, eps_v, h_eff = N_FREE, COUNT, EPS_V, H_EFF
    rows, weights, bases, mu_lambda, c = lag
    dy = 3.0 * h_eff * rng.normal(size=y.shape)
    overshot = np.zeros(count, np.bool_)
    overshot[0] = True  # marked by an earlier step of the same lag
    got = slip_overshoots(y, dy, step, base, h_eff, eps_v, rows, weights, bases, c, count, n,
                          overshot)
    want = np.zeros(count, np.bool_)
    want[0] = True
    for k in range(1, count):
        v0, v1 = slip(y, base, h_eff, lag, k), slip(y + step * dy, base, h_eff, lag, k)
        want[k] = np.linalg.norm(v0) >= eps_v and v0 @ v1 < 0.0
    np.testing.assert_array_equal(overshot, want)
    assert got == want[1:].sum()
    u = (y[:n] - base[:n]) / h_eff
    ref = reference_slips(u, rows, weights, bases, c, count, n)  # every slip along its own
    blocks = np.zeros((count, 3, 3))
    friction_assemble(y, base, h_eff, eps_v, *lag, count, n, np.zeros((len(y), 3)), blocks)
    bounded = blocks.copy()
    bound_reversed_slips(y, base, h_eff, eps_v, *lag, count, n, ref, overshot, bounded)
    for k in range(count):
        v = slip(y, base, h_eff, lag, k)
        if overshot[k] and np.linalg.norm(v) >= eps_v:
            tt = bases[k] @ bases[k].T
            np.testing.assert_allclose(bounded[k], mu_lambda[k] / (h_eff * np.linalg.norm(v)) * tt,
                                       rtol=1e-12)
        else:
            np.testing.assert_array_equal(bounded[k], blocks[k])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), slow=st.sampled_from([0.5 * EPS_V, 2.0 * EPS_V, 5.0 * EPS_V]))
def test_slow_slips_get_the_isotropic_bound_and_the_faster_keep_their_blocks(seed, slow):
    """bound_slow_slips replaces the block of each pair slipping slower than ``slow`` by
    (μλ/ĥ) F0'(v)/v T Tᵀ: the Hessian of its half-quadratic bound μλĥ F0'(v₀)‖v(x)‖²/(2v₀)
    by central differences, PSD, at least the exact block, equal to it across v̂; the
    faster pairs keep friction_assemble's blocks."""
    rng, x, base, lag = mixed_pairs(seed)
    n, count, eps_v, h_eff = N_FREE, COUNT, EPS_V, H_EFF
    rows, weights, bases, mu_lambda, c = lag
    blocks = np.zeros((count, 3, 3))
    friction_assemble(x, base, h_eff, eps_v, *lag, count, n, np.zeros((len(x), 3)), blocks)
    bounded = blocks.copy()
    got = bound_slow_slips(x, base, h_eff, eps_v, slow, *lag, count, n, bounded)
    want = 0
    for k in range(count):
        v = slip(x, base, h_eff, lag, k)
        speed = np.linalg.norm(v)
        if speed >= slow:
            np.testing.assert_array_equal(bounded[k], blocks[k])
            continue
        want += 1
        weight = f1(speed, eps_v) / speed  # F0'(v₀)/v₀

        def bound_gradient(y):
            """∇ of μλĥ F0'(v₀)‖v(y)‖²/(2v₀) on the cloth vertices (n, 3)."""
            u = slip(y, base, h_eff, lag, k)
            g = np.zeros((n, 3))
            for j in range(4):
                if rows[k, j] < n:
                    g[rows[k, j]] += mu_lambda[k] * weight * weights[k, j] * (bases[k] @ u)
            return g

        step = 1e-6
        fd = np.empty((3 * n, 3 * n))
        for a in range(3 * n):
            yp, ym = x.copy(), x.copy()
            yp[a // 3, a % 3] += step
            ym[a // 3, a % 3] -= step
            fd[:, a] = (bound_gradient(yp) - bound_gradient(ym)).ravel() / (2 * step)
        mine = dense_friction_hessian(rows[k:k + 1], weights[k:k + 1], bounded[k:k + 1], 1, n)
        np.testing.assert_allclose(mine, fd, atol=1e-6 * np.abs(mine).max())
        assert np.linalg.eigvalsh(bounded[k] - blocks[k]).min() >= -1e-9 * np.abs(bounded[k]).max()
        across = bases[k] @ np.array([-v[1], v[0]]) / speed
        assert across @ bounded[k] @ across == pytest.approx(across @ blocks[k] @ across, rel=1e-10)
    assert got == want


@settings(max_examples=200, deadline=None)
@given(v0=st.floats(1e-3, 20.0), u=st.floats(0.0, 40.0))
def test_the_slow_slip_bound_is_a_bound_of_the_friction_potential(v0, u):
    """F0(u) ≤ F0(v₀) + F0'(v₀)(u² − v₀²)/(2v₀) for every slip u, equal at u = v₀ (in units
    of ε_v = 1): the curvature bound_slow_slips takes is that of a quadratic above F0."""
    bound = f0(v0, 1.0) + f1(v0, 1.0) * (u * u - v0 * v0) / (2.0 * v0)
    assert f0(u, 1.0) <= bound + 1e-12 * max(1.0, bound)
