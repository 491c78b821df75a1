"""The stick–slip residual test of clothtool.contact.pieces: the rigid part of a residual
on each piece of cloth, the rest against Newton's diagonal blocks."""

import numpy as np
from hypothesis import given, settings, strategies as st

from clothtool.contact.pieces import (RIGID_SHARE, cloth_pieces, piece_velocities,
                                      rigid_accelerations, slide_velocity)
from clothtool.sim.model.config import GridSpec
from clothtool.sim.model.mesh import grid_mesh

H = 0.01


def unheld(n):
    """No vertex held."""
    return np.zeros(n, np.bool_)


def sheet(n=5, seed=0):
    """An n × n sheet with a little relief (so that it turns about every axis)."""
    mesh = grid_mesh(GridSpec(nx=n, ny=n, width=0.4, height=0.3, plane="xz"))
    x = mesh.positions.copy()
    x[:, 1] += 0.02 * np.random.default_rng(seed).normal(size=len(x))
    return x, mesh.faces


def test_pieces_are_the_connected_components():
    faces = np.array([[0, 1, 2], [1, 2, 3], [4, 5, 6]])
    piece, count = cloth_pieces(faces, 8)
    assert count == 3  # {0..3}, {4, 5, 6} and the lone vertex 7
    assert len(set(piece[:4])) == 1 and len(set(piece[4:7])) == 1
    assert len({piece[0], piece[4], piece[7]}) == 3


def test_a_lone_vertex_reads_as_the_per_vertex_test_against_its_mass():
    x = np.array([[0.0, 0.0, 0.0]])
    g = np.array([[0.3, -0.4, 0.0]])
    mass = np.array([2.0])
    diag = (mass / H**2)[:, None, None] * np.eye(3)
    rigid, rest = piece_velocities(x, g, mass, diag, H, np.zeros(1, np.int64), 1, unheld(1))
    assert abs(rigid - H * 0.5 / 2.0) <= 1e-15
    assert rest <= 1e-15


def test_a_rigid_field_is_all_rigid_and_its_acceleration_comes_back():
    x, faces = sheet()
    n = len(x)
    mass = np.random.default_rng(1).uniform(0.5, 2.0, n)
    c = mass @ x / mass.sum()
    a0, alpha = np.array([0.2, -1.0, 0.5]), np.array([3.0, -2.0, 1.0])
    field = a0 + np.cross(alpha, x - c)
    g = mass[:, None] * field
    piece, count = cloth_pieces(faces, n)
    a = rigid_accelerations(x, g, mass, piece, count, unheld(n))
    assert np.max(np.abs(a - field)) <= 1e-9 * np.max(np.abs(field))
    diag = np.tile(1e3 * np.eye(3), (n, 1, 1))
    rigid, rest = piece_velocities(x, g, mass, diag, H, piece, count, unheld(n))
    assert abs(rigid - H * np.max(np.linalg.norm(field, axis=1))) <= 1e-9 * rigid
    assert rest <= 1e-9 * rigid


def test_internal_forces_have_no_rigid_part_and_are_measured_against_the_diagonal_block():
    """Equal and opposite forces along the line between two vertices (a spring, a barrier
    pair): no resultant, no moment; the rest is ‖D_v⁻¹ f‖/ĥ."""
    x, faces = sheet()
    n = len(x)
    mass = np.ones(n)
    f = 5.0 * (x[7] - x[3])
    g = np.zeros((n, 3))
    g[3], g[7] = f, -f
    stiff = np.linspace(1e4, 2e4, n)
    diag = stiff[:, None, None] * np.eye(3)
    piece, count = cloth_pieces(faces, n)
    rigid, rest = piece_velocities(x, g, mass, diag, H, piece, count, unheld(n))
    assert rigid <= 1e-12
    want = np.linalg.norm(f) / min(stiff[3], stiff[7]) / H
    assert abs(rest - want) <= 1e-12 * want


def test_held_vertices_are_left_out():
    x, faces = sheet(3)
    n = len(x)
    g = np.random.default_rng(2).normal(size=(n, 3))
    diag = np.tile(np.eye(3), (n, 1, 1))
    piece, count = cloth_pieces(faces, n)
    held = np.ones(n, np.bool_)
    assert piece_velocities(x, g, np.zeros(n), diag, H, piece, count, held) == (0.0, 0.0)
    assert np.all(rigid_accelerations(x, g, np.zeros(n), piece, count, held) == 0.0)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(2, 6), line=st.booleans())
def test_the_rest_has_no_resultant_and_no_moment_on_any_piece(seed, n, line):
    """r = g − m a carries no force and no torque about the piece's centre, on two pieces
    (also on a piece whose vertices lie on a line: it turns about no axis along it)."""
    rng = np.random.default_rng(seed)
    x, faces = sheet(n, seed)
    if line:
        x[:, 1:] = 0.0
    k = len(x)
    x2 = np.vstack([x, x + 1.0])
    faces2 = np.vstack([faces, faces + k])
    mass = rng.uniform(0.1, 3.0, 2 * k)
    g = rng.normal(size=(2 * k, 3))
    piece, count = cloth_pieces(faces2, 2 * k)
    assert count == 2
    a = rigid_accelerations(x2, g, mass, piece, count, unheld(2 * k))
    r = g - mass[:, None] * a
    scale = np.abs(g).sum() * (1.0 + np.abs(x2).max())
    for p in range(2):
        on = piece == p
        c = mass[on] @ x2[on] / mass[on].sum()
        assert np.all(np.abs(r[on].sum(axis=0)) <= 1e-12 * scale)
        moment = np.cross(x2[on] - c, r[on]).sum(axis=0)
        if line:  # only the moment about axes across the line is removed
            moment = moment[1:]
        assert np.all(np.abs(moment) <= 1e-10 * scale)


def test_slide_velocity_holds_the_rigid_part_to_its_share():
    x, faces = sheet(3)
    n = len(x)
    mass = np.ones(n)
    g = np.tile([0.0, 0.0, 1.0], (n, 1))  # a uniform push: all rigid
    diag = np.tile(np.eye(3) / H**2, (n, 1, 1))
    piece, count = cloth_pieces(faces, n)
    assert abs(slide_velocity(x, g, mass, diag, H, piece, count, unheld(n)) - H / RIGID_SHARE) <= 1e-12


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_the_rest_is_solved_against_a_full_diagonal_block(seed):
    """Two vertices of a piece pulled together (a spring) and random SPD blocks: no rigid
    part, and the rest is max ‖D_v⁻¹ g_v‖/ĥ, as numpy solves it."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(2, 3))
    f = rng.uniform(0.5, 2.0) * (x[1] - x[0])
    g = np.array([f, -f])
    a = rng.normal(size=(2, 3, 3))
    diag = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(3)
    rigid, rest = piece_velocities(x, g, np.ones(2), diag, H, np.zeros(2, np.int64), 1, unheld(2))
    want = max(np.linalg.norm(np.linalg.solve(diag[v], g[v])) for v in range(2)) / H
    # rounding of the moment ε‖x‖‖f‖ over the inertia m‖d‖²/2, times the lever ‖d‖/2
    d = np.linalg.norm(x[1] - x[0])
    assert rigid <= 1e-12 * H * np.linalg.norm(f) * (1.0 + np.abs(x).max()) / d
    assert abs(rest - want) <= 1e-9 * want


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), held=st.sampled_from(["point", "line", "edges"]))
def test_held_vertices_leave_only_the_rigid_motions_they_allow(seed, held):
    """A piece held at one vertex turns about it: the rest has no moment about that vertex
    and the acceleration vanishes there; held at two vertices it turns only about the line
    through them (no moment along it); held at two edges (the twist) it has no rigid motion
    left. The acceleration field is always rigid."""
    rng = np.random.default_rng(seed)
    x, faces = sheet(5, seed)
    n = len(x)
    pins = {"point": [7], "line": [0, 4], "edges": [0, 5, 10, 15, 20, 4, 9, 14, 19, 24]}[held]
    hold = unheld(n)
    hold[pins] = True
    mass = np.where(hold, 0.0, rng.uniform(0.5, 2.0, n))
    g = np.where(hold[:, None], 0.0, rng.normal(size=(n, 3)))
    piece, count = cloth_pieces(faces, n)
    a = rigid_accelerations(x, g, mass, piece, count, hold)
    r = g - mass[:, None] * a
    scale = np.abs(g).sum()
    if held == "edges":
        assert np.all(a == 0.0)
        return
    p0 = x[pins[0]]
    assert np.all(np.abs(a[pins]) <= 1e-10 * np.abs(a).max())  # the held vertices stay
    moment = np.cross(x - p0, r).sum(axis=0)
    if held == "line":  # about the line's axis only
        axis = (x[pins[-1]] - p0) / np.linalg.norm(x[pins[-1]] - p0)
        moment = moment @ axis
    assert np.all(np.abs(moment) <= 1e-10 * scale)
    # a rigid field: a_v = a_p + α × (x_v − x_p), α from any three vertices off a line
    alpha = np.linalg.lstsq(np.stack([[[0, d[2], -d[1]], [-d[2], 0, d[0]], [d[1], -d[0], 0]]
                                      for d in x - p0]).reshape(-1, 3),
                            (a - a[pins[0]]).ravel(), rcond=None)[0]
    assert np.max(np.abs(a - a[pins[0]] - np.cross(alpha, x - p0))) <= 1e-9 * np.abs(a).max()


def test_a_piece_held_at_two_edges_is_measured_vertex_by_vertex():
    """A sheet pinned along two edges (the twist) cannot slide or turn: a uniform push has no
    rigid part, all of it is the rest against the diagonal blocks."""
    x, faces = sheet(5)
    n = len(x)
    hold = unheld(n)
    hold[[0, 5, 10, 15, 20, 4, 9, 14, 19, 24]] = True
    mass = np.where(hold, 0.0, 1.0)
    g = np.where(hold[:, None], 0.0, np.array([0.0, 0.0, 1.0]))
    diag = np.tile(np.eye(3) / H**2, (n, 1, 1))
    piece, count = cloth_pieces(faces, n)
    rigid, rest = piece_velocities(x, g, mass, diag, H, piece, count, hold)
    assert rigid == 0.0
    assert abs(rest - H) <= 1e-15
