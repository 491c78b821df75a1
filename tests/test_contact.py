"""Contact kernels: distances, barrier, CCD, broad phase and the exact intersection test.

ipctk (the IPC authors' toolkit) is the independent oracle: its distances, its
normalised barrier potential, its CCD and its ``has_intersections``.
"""

import ipctk
import numpy as np
import pytest
from conftest import assemble, dense_operator, hessian_entries

from clothtool.contact.barrier import (EDGE_EDGE, POINT_PLANE, POINT_TRIANGLE, barrier,
                                       barrier_first, barrier_second, contact_energy, mollifier,
                                       pair_geometry)
from clothtool.contact.broadphase import contact_stencils as _contact_stencils
from clothtool.contact.broadphase import mesh_edges
from clothtool.contact.ccd import additive_ccd, collision_free_step
from clothtool.contact.distance import edge_edge_weights, point_triangle_weights
from clothtool.contact.intersect import (NO, UNSURE, YES, exact_segment_triangle,
                                         has_intersections, intersecting_pairs, orient3d,
                                         segment_triangle)
from clothtool.contact.shapes import rolled_sheet
from clothtool.sim.linalg.pairs import (pair_operator, pairs_add_diagonal, pairs_coupling,
                                 pairs_offdiagonal_multiply)

FD_STEP = 1e-7


def central_difference(fun, x):
    """∂fun/∂x (x flat) by central differences."""
    out = []
    for a in range(x.size):
        xp, xm = x.copy(), x.copy()
        xp.flat[a] += FD_STEP
        xm.flat[a] -= FD_STEP
        out.append((np.asarray(fun(xp)) - np.asarray(fun(xm))) / (2 * FD_STEP))
    return np.stack(out, axis=-1)


def random_pair(rng, scale=1.0):
    return rng.normal(size=(4, 3)) * scale


def contact_stencils(x, dx, rho, faces, edges, obstacle, self_contact, r):
    """The candidate stencils (K, 5) of triangle meshes (every vertex a point, no planes,
    no radii)."""
    n = len(x)
    return _contact_stencils(x, dx, rho, np.arange(n), np.asarray(faces, np.int64),
                             np.asarray(edges, np.int64), np.zeros((0, 2), np.int64), n, obstacle,
                             np.zeros(n), self_contact, r)


def geometry(x, xi, dhat, obstacle=None, rest=None, xi_obstacle=None, dhat_obstacle=None):
    """The kernels' pair geometry of meshes without radii (collider wall and activation
    default to the cloth's)."""
    n = len(x)
    return pair_geometry(np.zeros(n, bool) if obstacle is None else obstacle, np.zeros(n),
                         x if rest is None else rest, xi, xi if xi_obstacle is None else xi_obstacle,
                         dhat, dhat if dhat_obstacle is None else dhat_obstacle)


# ---------------------------------------------------------------- distances


@pytest.mark.parametrize("seed", range(200))
def test_distances_match_ipctk(seed):
    rng = np.random.default_rng(seed)
    x = random_pair(rng)
    w = np.empty(4)
    d_pt = point_triangle_weights(x, 0, 1, 2, 3, w)
    assert d_pt == pytest.approx(ipctk.point_triangle_distance(x[0], x[1], x[2], x[3]), rel=1e-10)
    assert np.allclose(w @ x, x[0] - (-w[1:]) @ x[1:])  # r = p − closest point
    assert -w[1:].sum() == pytest.approx(1.0) and np.all(-w[1:] >= -1e-15)
    d_ee = edge_edge_weights(x, 0, 1, 2, 3, w)
    assert d_ee == pytest.approx(ipctk.edge_edge_distance(x[0], x[1], x[2], x[3]), rel=1e-9)
    assert 0.0 <= w[1] <= 1.0 and 0.0 <= -w[3] <= 1.0


def test_distance_known_answers():
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    w = np.empty(4)
    for p, d2 in [((0.2, 0.2, 0.5), 0.25), ((-1, -1, 0), 2.0), ((0.5, -2, 0), 4.0),
                  ((1, 1, 0), 0.5), ((2, 0, 1), 2.0)]:
        x = np.vstack([p, tri])
        assert point_triangle_weights(x, 0, 1, 2, 3, w) == pytest.approx(d2)
    # crossing, parallel overlapping, end to end, skew beyond an end
    for seg, d2 in [(((0, -1, 1), (0, 1, 1)), 1.0), (((0.2, 0, 0.5), (0.8, 0, 0.5)), 0.25),
                    (((2, 0, 0), (3, 0, 0)), 1.0), (((3, -1, 1), (3, 1, 1)), 5.0)]:
        x = np.array([[-1, 0, 0], [1, 0, 0], *seg], float)
        assert edge_edge_weights(x, 0, 1, 2, 3, w) == pytest.approx(d2)


@pytest.mark.parametrize("seed", range(20))
def test_squared_distance_gradient_is_two_w_r(seed):
    """Danskin: ∇_{x_k} d² = 2 w_k r with the weights held fixed, in every region."""
    rng = np.random.default_rng(seed)
    x = random_pair(rng)
    w = np.empty(4)
    for fun in (point_triangle_weights, edge_edge_weights):
        fun(x, 0, 1, 2, 3, w)
        r = w @ x
        grad = 2.0 * w[:, None] * r[None, :]
        fd = central_difference(lambda y: fun(y.reshape(4, 3), 0, 1, 2, 3, np.empty(4)), x.ravel())
        assert np.allclose(grad.ravel(), fd, atol=1e-6)


# ---------------------------------------------------------------- barrier


def test_barrier_derivatives_match_finite_differences():
    for z in [1e-3, 0.05, 0.3, 0.7, 0.99]:
        assert barrier_first(z) == pytest.approx((barrier(z + 1e-7) - barrier(z - 1e-7)) / 2e-7, rel=1e-6)
        assert barrier_second(z) == pytest.approx(
            (barrier_first(z + 1e-7) - barrier_first(z - 1e-7)) / 2e-7, rel=1e-6)
    assert barrier(1.0) == barrier_first(1.0) == barrier_second(1.0) == 0.0
    assert barrier(1.0 - 1e-4) < 1e-11 and barrier_first(1.0 - 1e-4) > -1e-7  # C² at z = 1
    eps = 0.3
    for c in [0.01, 0.15, 0.29]:
        assert mollifier(c, eps)[1] == pytest.approx(
            (mollifier(c + 1e-8, eps)[0] - mollifier(c - 1e-8, eps)[0]) / 2e-8, rel=1e-6)
    assert mollifier(eps, eps) == (1.0, 0.0) and mollifier(0.0, eps)[0] == 0.0


def two_elements(rng, kind, gap):
    """A vertex over a triangle, or two edges, whose closest points are about ``gap`` apart."""
    if kind == "pt":
        x = np.array([[0.3, 0.3, gap], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
        faces, edges = np.array([[1, 2, 3]]), np.array([[1, 2], [2, 3], [1, 3]])
    else:
        x = np.array([[-0.5, 0, 0], [0.5, 0, 0], [0, -0.5, gap], [0.02, 0.5, gap]], float)
        faces, edges = np.zeros((0, 3), np.int64), np.array([[0, 1], [2, 3]])
    x += 0.2 * gap * rng.normal(size=x.shape)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return x @ q.T, faces, edges


@pytest.mark.parametrize("kind", ["pt", "ee"])
@pytest.mark.parametrize("seed", range(5))
def test_barrier_energy_and_gradient_match_ipctk_and_finite_differences(kind, seed):
    rng = np.random.default_rng(seed)
    dhat, kappa = 0.05, 3.0
    x, faces, edges = two_elements(rng, kind, 0.02)
    obstacle = np.zeros(4, bool)
    stencils = contact_stencils(x, np.zeros_like(x), np.zeros(len(x)), faces, edges, obstacle, True, dhat)
    assert len(stencils) == 1 and stencils[0, 4] == (POINT_TRIANGLE if kind == "pt" else EDGE_EDGE)
    geo = geometry(x, 0.0, dhat)
    e, grad, _, _ = assemble(x, stencils, geo, kappa)
    mesh = ipctk.CollisionMesh(x, edges, faces)
    collisions = ipctk.NormalCollisions()
    collisions.build(mesh, x, dhat)
    # ours is κ d̂² B(d²/d̂²), ipctk's normalised barrier with stiffness κ' is κ' B(d²/d̂²)
    potential = ipctk.BarrierPotential(ipctk.NormalizedClampedLogBarrier(), dhat, kappa * dhat**2)
    assert e > 0 and e == pytest.approx(potential(collisions, mesh, x), rel=1e-9)
    assert np.allclose(grad.ravel(), potential.gradient(collisions, mesh, x), rtol=1e-7, atol=1e-12)
    fd = central_difference(lambda y: contact_energy(y.reshape(-1, 3), stencils, geo, kappa), x.ravel())
    assert np.allclose(grad.ravel(), fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_mollified_edge_edge_gradient_matches_finite_differences():
    """Nearly parallel edges: the mollifier term B m'(c) ∇c is in the gradient."""
    x = np.array([[-0.5, 0, 0], [0.5, 0, 0], [-0.5, 0.003, 0.01], [0.5, -0.002, 0.012]])
    rest = x.copy()
    rest[3] = [0.5, 0.3, 0.01]  # ε from the rest shape is large: the pair is mollified
    stencils = np.array([[0, 1, 2, 3, EDGE_EDGE]])
    geo = geometry(x, 0.001, 0.05, rest=rest)
    e, grad, _, _ = assemble(x, stencils, geo, 2.0)
    unmollified = contact_energy(x, stencils, geometry(x, 0.001, 0.05, rest=0.01 * x), 2.0)  # ε ≪ c
    assert 0 < e < 0.5 * unmollified
    fd = central_difference(lambda y: contact_energy(y.reshape(-1, 3), stencils, geo, 2.0), x.ravel())
    assert np.allclose(grad.ravel(), fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


@pytest.mark.parametrize("xi", [0.0, 0.004])
def test_gauss_newton_hessian_is_exact_along_the_normal_of_a_vertex_over_a_face(xi):
    """A vertex over a fixed triangle: d is linear in p, so H_pp = κ g''(d) n nᵀ exactly."""
    x = np.array([[0.3, 0.2, 0.01], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    stencils, dhat, kappa = np.array([[0, 1, 2, 3, POINT_TRIANGLE]]), 0.02, 1.5
    geo = geometry(x, xi, dhat)
    _, grad, pairs, gap = assemble(x, stencils, geo, kappa)
    act, n_act, w, nrm, coef, force, tilt = pairs
    assert n_act == 1 and gap == pytest.approx(0.01)
    assert force[0] > 0 and np.allclose(grad[0], -force[0] * nrm[0])  # pushes p along +n
    assert not tilt.any()  # no radius: no tilt terms
    rows, w_out, blocks, count = hessian_entries(x, stencils, pairs)
    assert count == 1
    hess = dense_operator(rows, w_out, blocks, count, 4)
    fd = central_difference(lambda p: assemble(np.vstack([p, x[1:]]), stencils, geo, kappa)[1][0], x[0])
    assert np.allclose(hess[:3, :3], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    assert np.allclose(hess, hess.T) and np.linalg.eigvalsh(hess).min() > -1e-9 * np.abs(hess).max()


def dense_hessian(stencils, active, n_active, weights, normals, coef, n_vertices):
    """Σ_a coef_a g_a g_aᵀ with g_a = w_a ⊗ n_a on the pair's four vertices, dense (3N × 3N)."""
    h = np.zeros((n_vertices, 3, n_vertices, 3))
    for a in range(n_active):
        st = stencils[active[a]]
        g = weights[a][:, None] * normals[a][None, :]
        for j in range(4):
            for k in range(4):
                h[st[j], :, st[k], :] += coef[a] * np.outer(g[j], g[k])
    return h.reshape(3 * n_vertices, 3 * n_vertices)


def test_pair_operators_split_the_gauss_newton_hessian():
    """diagonal blocks + off-diagonal product = H on the unknowns (vertices < n); the
    coupling is H between unknowns and held vertices."""
    rng = np.random.default_rng(4)
    x, faces = rolled_sheet(n=8, gap=(0.004, 0.006))
    x = np.vstack([x, plate_under(x)])
    faces = np.vstack([faces, [[64, 65, 66]]])
    obstacle = np.arange(67) >= 64
    stencils = contact_stencils(x, np.zeros_like(x), np.zeros(67), faces, mesh_edges(faces),
                                obstacle, True, 0.05)
    _, _, pairs, _ = assemble(x, stencils, geometry(x, 0.001, 0.05, obstacle), 1.0)
    act, n_act, w, nrm, coef = pairs[:5]
    assert n_act > 10 and any(obstacle[stencils[a, :4]].any() for a in act[:n_act])
    h = dense_hessian(stencils, act, n_act, w, nrm, coef, 67)
    rows, w_out, entries, count = hessian_entries(x, stencils, pairs)
    assert count == n_act  # no radii: one Gauss–Newton entry per pair
    assert np.allclose(dense_operator(rows, w_out, entries, count, 67), h)
    v = rng.normal(size=x.shape)
    op = pair_operator(rows, w_out, entries, count, 64)
    blocks = np.zeros((64, 3, 3))
    pairs_add_diagonal(op, np.arange(64), blocks)
    split = np.einsum("vij,vj->vi", blocks, v[:64])
    split = np.vstack([split, np.zeros((3, 3))])
    pairs_offdiagonal_multiply(op, v, split, 1.0)
    assert np.allclose(split[:64].ravel(), h[:192, :192] @ v[:64].ravel())
    out = np.zeros_like(x)
    pairs_coupling(op, v, out, 2.0)
    coupled = h[:192, 192:] @ v[64:].ravel()
    assert np.allclose(out[:64].ravel(), 2.0 * coupled) and np.abs(coupled).max() > 0


def plate_under(x):
    """A big triangle in a plane z = const, 3 mm beyond the lowest z of x."""
    z = x[:, 2].min() - 0.003
    return np.array([[-2.0, -2.0, z], [2.0, -2.0, z], [0.0, 2.0, z]])


def test_energy_is_infinite_inside_the_thickness_and_zero_beyond_activation():
    x = np.array([[0.3, 0.2, 0.01], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    st = np.array([[0, 1, 2, 3, POINT_TRIANGLE]])
    assert contact_energy(x, st, geometry(x, 0.0, 0.01), 1.0) == 0.0
    assert contact_energy(x, st, geometry(x, 0.0, 0.0101), 1.0) > 0.0
    assert contact_energy(x, st, geometry(x, 0.01, 0.01), 1.0) == np.inf
    # the collider's wall and activation apply when a collider vertex takes part
    collider = np.array([0, 1, 1, 1], bool)
    assert contact_energy(x, st, geometry(x, 0.0, 0.01, collider, xi_obstacle=0.02), 1.0) == np.inf
    assert contact_energy(x, st, geometry(x, 0.0, 0.02, collider, dhat_obstacle=0.005), 1.0) == 0.0
    assert contact_energy(x, st, geometry(x, 0.0, 0.005, collider, dhat_obstacle=0.02), 1.0) > 0.0


# ---------------------------------------------------------------- CCD


def test_ccd_head_on_stops_short_of_the_thickness():
    x = np.array([[0.3, 0.3, 1.0], [0, 0, 0], [1, 0, 0], [0, 1, 0]])
    dx = np.zeros((4, 3))
    dx[0, 2] = -2.0  # reaches the plane at t = 0.5, the thickness 0.1 at t = 0.45
    for xi, impact in [(0.0, 0.5), (0.1, 0.45)]:
        t = additive_ccd(x, dx, POINT_TRIANGLE, xi, 0.9, 1.0)
        assert 0.8 * impact < t < impact
    # an edge flying into another one
    x = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 1.0], [0, 1, 1.0]], float)
    dx = np.zeros((4, 3))
    dx[2:, 2] = -4.0  # impact at t = 0.25
    assert 0.8 * 0.25 < additive_ccd(x, dx, EDGE_EDGE, 0.0, 0.9, 1.0) < 0.25


def test_ccd_grazing_and_receding_motions_are_free():
    x = np.array([[0.3, 0.3, 0.02], [0, 0, 0], [1, 0, 0], [0, 1, 0]])
    dx = np.zeros((4, 3))
    dx[0] = [0.5, 0.1, 0.0]  # slides past at height 0.02 over the face and beyond its edge
    assert additive_ccd(x, dx, POINT_TRIANGLE, 0.01, 0.9, 1.0) == 1.0
    dx[0] = [0.0, 0.0, 1.0]
    assert additive_ccd(x, dx, POINT_TRIANGLE, 0.01, 0.9, 1.0) == 1.0
    dx[0] = [1.0, 1.0, -0.01]  # over the hypotenuse and away, never closer than 0.01
    assert additive_ccd(x, dx, POINT_TRIANGLE, 0.0, 0.9, 1.0) == 1.0
    assert additive_ccd(x, np.zeros((4, 3)), POINT_TRIANGLE, 0.0, 0.9, 1.0) == 1.0


def sheet_motion(seed):
    """A rolled sheet and a smooth motion that squeezes its layers together and through."""
    x0, faces = rolled_sheet(n=16, gap=(0.01, 0.02))
    x1, _ = rolled_sheet(n=16, gap=(-0.004, 0.006), twist=np.pi + 0.3)
    rng = np.random.default_rng(seed)
    return x0, x1 - x0 + 0.002 * rng.normal(size=x0.shape), faces


@pytest.mark.parametrize("seed", range(3))
def test_ccd_step_is_free_of_intersections_and_close_to_ipctk(seed):
    x0, dx, faces = sheet_motion(seed)
    edges = mesh_edges(faces)
    obstacle = np.zeros(len(x0), bool)
    assert has_intersections(x0 + dx, faces)  # the full step crosses layers
    stencils = contact_stencils(x0, dx, np.zeros(len(x0)), faces, edges, obstacle, True, 0.0)
    t = collision_free_step(x0, dx, stencils, geometry(x0, 0.0, 0.0), 1.0)
    mesh = ipctk.CollisionMesh(x0, edges, faces)
    t_ipc = ipctk.compute_collision_free_stepsize(mesh, x0, x0 + dx)
    assert 0.5 * t_ipc < t < 1.0
    for s in np.linspace(0.0, t, 40):
        assert not has_intersections(x0 + s * dx, faces)


@pytest.mark.parametrize("seed", range(3))
def test_ccd_with_thickness_keeps_every_pair_apart(seed):
    x0, dx, faces = sheet_motion(seed)
    edges, obstacle, xi = mesh_edges(faces), np.zeros(len(x0), bool), 0.002
    stencils = contact_stencils(x0, dx, np.zeros(len(x0)), faces, edges, obstacle, True, xi)
    t = collision_free_step(x0, dx, stencils, geometry(x0, xi, 0.0), 1.0)
    assert 0.0 < t < 1.0
    # every pair (brute force over all pairs within reach) stays farther than xi
    allst = contact_stencils(x0, dx, np.zeros(len(x0)), faces, edges, obstacle, True, 10.0)
    for s in np.linspace(0.0, t, 20):
        assert assemble(x0 + s * dx, allst, geometry(x0, xi, 1e-9), 1.0)[3] > xi


# ---------------------------------------------------------------- broad phase


def brute_force_pairs(x, faces, edges, obstacle, self_contact, r):
    """Allowed stencils with distance < r, by looping over all pairs."""
    w = np.empty(4)
    found = set()
    for v in range(len(x)):
        for f in faces:
            if v in f or (obstacle[v] and obstacle[f[0]]) or not (self_contact or obstacle[v] or obstacle[f[0]]):
                continue
            if point_triangle_weights(x, v, *f, w) < r * r:
                found.add((v, *f, POINT_TRIANGLE))
    for i, a in enumerate(edges):
        for b in edges[i + 1:]:
            if set(a) & set(b) or (obstacle[a[0]] and obstacle[b[0]]) or not (self_contact or obstacle[a[0]] or obstacle[b[0]]):
                continue
            if edge_edge_weights(x, *a, *b, w) < r * r:
                found.add((*a, *b, EDGE_EDGE))
    return found


@pytest.mark.parametrize("self_contact", [True, False])
def test_broad_phase_finds_every_pair_within_reach(self_contact):
    x, faces = rolled_sheet(n=10, gap=(0.01, 0.03))
    plate = np.array([[-0.3, -0.6, -0.05], [0.3, -0.6, -0.05], [0.0, 0.6, -0.05]])
    x = np.vstack([x, plate])
    faces = np.vstack([faces, [[100, 101, 102]]])
    edges = mesh_edges(faces)
    obstacle = np.arange(len(x)) >= 100
    for motion in (np.zeros_like(x), 0.01 * np.random.default_rng(1).normal(size=x.shape)):
        r = 0.03
        stencils = contact_stencils(x, motion, np.zeros(len(x)), faces, edges, obstacle, self_contact, r)
        got = {tuple(s) for s in stencils}
        assert len(got) == len(stencils)  # each pair once
        assert set(stencils[:, 4]) == {POINT_TRIANGLE, EDGE_EDGE}
        for s in np.linspace(0, 1, 5):
            want = brute_force_pairs(x + s * motion, faces, edges, obstacle, self_contact, r)
            assert want <= got
        assert any(obstacle[list(s[:4])].any() for s in got)
        assert any(not obstacle[list(s[:4])].any() for s in got) == self_contact


# ---------------------------------------------------------------- intersection test


def test_orient3d_filter_is_never_wrong():
    rng = np.random.default_rng(0)
    from clothtool.contact.intersect import _exact_orient3d
    for _ in range(300):
        p = rng.normal(size=(4, 3))
        p[3] = p[0] + rng.random() * (p[1] - p[0]) + rng.random() * (p[2] - p[0])  # coplanar-ish
        p[3] += rng.choice([0.0, 1e-17, 1e-15, 1e-12]) * rng.normal(size=3)
        s = orient3d(*p)
        assert s == 0 or s == _exact_orient3d(*p)


def test_segment_triangle_known_answers():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    cases = [
        (((0.2, 0.2, -1), (0.2, 0.2, 1)), True),  # through the face
        (((0.8, 0.8, -1), (0.8, 0.8, 1)), False),  # beside it
        (((0.2, 0.2, 1e-300), (0.2, 0.2, 1)), False),  # just above
        (((0.2, 0.2, 0.0), (0.2, 0.2, 1)), True),  # touching
        (((0.5, 0.5, -1), (0.5, 0.5, 1)), True),  # through the hypotenuse
        (((-1, 0.5, 0), (2, 0.5, 0)), True),  # coplanar, crossing
        (((-1, 2, 0), (2, 2, 0)), False),  # coplanar, missing
        (((0.1, 0.1, 0), (0.2, 0.1, 0)), True),  # coplanar, inside
        (((1, 1, 0), (2, 2, 0)), False),  # coplanar, outside on the diagonal
        (((0.5, 0.5, 0), (2, 2, 0)), True),  # coplanar, from the hypotenuse out
    ]
    for (p, q), want in cases:
        p, q = np.array(p, float), np.array(q, float)
        assert exact_segment_triangle(p, q, a, b, c) == want, (p, q)
        fast = segment_triangle(p, q, a, b, c)
        assert fast == UNSURE or fast == (YES if want else NO)


@pytest.mark.parametrize("seed", range(100))
def test_intersection_test_matches_ipctk_on_random_triangles(seed):
    rng = np.random.default_rng(seed)
    x = rng.random((9, 3))
    faces = np.arange(9).reshape(3, 3)
    mesh = ipctk.CollisionMesh(x, mesh_edges(faces), faces)
    assert has_intersections(x, faces) == ipctk.has_intersections(mesh, x)


def test_intersection_test_on_a_rolled_sheet_pushed_through_itself():
    x, faces = rolled_sheet(n=30, gap=(0.004, 0.012))
    mesh = ipctk.CollisionMesh(x, mesh_edges(faces), faces)
    assert not has_intersections(x, faces) and not ipctk.has_intersections(mesh, x)
    rng = np.random.default_rng(3)
    for _ in range(5):
        y = x.copy()
        j = rng.integers(0, 30)
        y[j * 30 + 10: j * 30 + 14, 0] *= 1.6  # four vertices of a row pushed out through a layer
        assert has_intersections(y, faces) == ipctk.has_intersections(mesh, y) == True  # noqa: E712
    # a collider triangle through the sheet; pairs of collider elements are not tested
    plate = np.array([[-0.5, 0.0, -0.5], [0.5, 0.0, -0.5], [0.0, 0.0, 0.5]])
    xs = np.vstack([x, plate, plate + [0.0, 0.01, 0.0]])
    fs = np.vstack([faces, [[900, 901, 902], [903, 904, 905]]])
    obstacle = np.arange(len(xs)) >= 900
    pairs = intersecting_pairs(xs, fs, obstacle)
    face_on_plate = fs[pairs[:, 1]].min(axis=1) >= 900
    edge_on_plate = mesh_edges(fs)[pairs[:, 0]].min(axis=1) >= 900
    assert len(pairs) > 0 and np.all(face_on_plate != edge_on_plate)
    assert not has_intersections(np.vstack([plate, plate + [0.0, 0.0, 0.1]]),
                                 np.array([[0, 1, 2], [3, 4, 5]]), np.ones(6, bool))


def test_broad_phase_finds_every_cloth_vertex_near_a_moving_plane():
    """Vertex–plane stencils (p, o, t, o): every cloth vertex that comes within r of the
    plane (o, t) somewhere on the motion, none of the plane's own vertices or colliders."""
    rng = np.random.default_rng(2)
    n_cloth, r = 200, 0.05
    cloth = rng.uniform(-1, 1, size=(n_cloth, 3)) * [1, 1, 0.3]
    normal = np.array([0.2, -0.1, 1.0]) / np.linalg.norm([0.2, -0.1, 1.0])
    o = np.array([0.1, 0.0, -0.1])
    x = np.vstack([cloth, [o, o + normal], [[0, 0, -0.1]]])  # a collider point that is no cloth
    faces = np.zeros((0, 3), np.int64)
    obstacle = np.arange(len(x)) >= n_cloth
    planes = np.array([[n_cloth, n_cloth + 1]])
    points = np.r_[np.arange(n_cloth), n_cloth + 2]
    dx = np.zeros_like(x)
    dx[:n_cloth] = 0.05 * rng.normal(size=(n_cloth, 3))
    dx[n_cloth:n_cloth + 2] = [0.0, 0.0, 0.04]  # the plane translates up
    st = _contact_stencils(x, dx, np.zeros(len(x)), points, faces, np.zeros((0, 2), np.int64),
                           planes, n_cloth, obstacle, np.zeros(len(x)), True, r)
    assert np.all(st[:, 4] == POINT_PLANE) and np.all(st[:, 1:4] == [n_cloth, n_cloth + 1, n_cloth])
    got = set(st[:, 0])
    assert max(got) < n_cloth and len(got) == len(st)
    want = set()
    for s in np.linspace(0, 1, 11):
        y = x + s * dx
        want |= set(np.flatnonzero((y[:n_cloth] - y[n_cloth]) @ normal < r))
    assert want <= got and len(want) > 10
    assert len(got) < n_cloth  # vertices far above the plane are left out


def test_candidates_of_a_reference_motion_hold_every_pair_of_the_motions_within_its_reach():
    """The Newton loop keeps one candidate set per reference motion x → x + m: the pairs near
    its midpoint x + m/2 for vertices within ρ_v = max(DELTA, (½ + SLACK)‖m_v‖) of it, kept
    for every later motion y → y + dy whose end points stay within ρ_v (``_within``): along
    such a motion (the reference motion itself among them) every pair within reach, found
    by brute force, is in the kept set; an end point outside makes ``_within`` refuse."""
    from clothtool.sim.solve.contact import DELTA, SLACK, _radii, _within
    x, faces = rolled_sheet(n=10, gap=(0.01, 0.03))
    edges = mesh_edges(faces)
    obstacle = np.zeros(len(x), bool)
    rng = np.random.default_rng(4)
    r = 0.012
    m = 0.004 * rng.normal(size=x.shape) + np.array([0.01, 0.0, 0.0])  # spread and a drift
    ref, rho = x + 0.5 * m, _radii(m, DELTA, 0.5 + SLACK)
    kept = {tuple(s) for s in contact_stencils(ref, np.zeros_like(x), rho, faces, edges, obstacle,
                                              True, r)}
    assert _within(x, m, ref, rho)

    def within_reach():  # points closer than ρ_v to the midpoint
        d = rng.normal(size=x.shape)
        d *= (0.99 * rho * rng.uniform(size=len(x)) / np.linalg.norm(d, axis=1))[:, None]
        return ref + d

    motions = [(x, m)] + [(y, within_reach() - y) for y in (within_reach() for _ in range(20))]
    for y, dy in motions:
        assert _within(y, dy, ref, rho)
        for t in np.linspace(0.0, 1.0, 3):
            assert brute_force_pairs(y + t * dy, faces, edges, obstacle, True, r) <= kept
    y = ref.copy()
    y[7] += 1.01 * rho[7] * np.array([0.0, 0.0, 1.0])
    assert not _within(y, np.zeros_like(y), ref, rho)
