"""Shapes made from formulas for contact tests, benchmarks and sample scenes (no downloads)."""

import numpy as np

from clothtool.geometry import grid_triangles, grid_uv


def rolled_sheet(n=50, width=1.0, turns=3.0, radius=0.02, gap=(0.003, 0.012), twist=np.pi):
    """An n × n sheet rolled into a spiral around the y axis and twisted along it.

    Row j (at y) follows the Archimedean spiral r = radius + g(y) φ/2π, φ ∈ [0, 2π turns],
    so that consecutive layers lie g(y) apart, with g growing linearly over ``gap`` from one
    end to the other; the whole cross-section turns by ``twist`` (rad) along y. Layers come
    as close as the gap: a stand-in for cloth twisted into a rope. Returns (x (n², 3), faces).
    """
    uv = grid_uv(n, n, width, width)
    u = (uv[:, 0] / width + 0.5)  # 0 … 1 across a row
    s = (uv[:, 1] / width + 0.5)  # 0 … 1 along the axis
    phi = 2.0 * np.pi * turns * u
    g = gap[0] + (gap[1] - gap[0]) * s
    r = radius + g * phi / (2.0 * np.pi)
    angle = phi + twist * s
    x = np.stack([r * np.cos(angle), uv[:, 1], r * np.sin(angle)], axis=1)
    return x, grid_triangles(n, n)


def capsule(radius=0.15, half_length=0.3, around=32, rings=8):
    """A closed capsule along the x axis, centred on the origin: a cylinder of the given
    radius and length 2·half_length with hemispherical caps. ``around`` vertices per ring,
    ``rings`` rings per cap. Returns (x, faces), faces counter-clockwise seen from outside."""
    phi = np.linspace(0.0, 0.5 * np.pi, rings + 1)[1:]  # from each pole toward the equator
    theta = np.linspace(0.0, 2.0 * np.pi, around, endpoint=False)
    points = [[half_length + radius, 0.0, 0.0]]
    ring_x = ([half_length + radius * np.cos(p) for p in phi]
              + [-half_length - radius * np.cos(p) for p in phi[::-1]])
    ring_r = [radius * np.sin(p) for p in phi] + [radius * np.sin(p) for p in phi[::-1]]
    for rx, rr in zip(ring_x, ring_r):
        points += [[rx, rr * np.cos(t), rr * np.sin(t)] for t in theta]
    points.append([-half_length - radius, 0.0, 0.0])
    x = np.array(points)
    n_rings = len(ring_x)
    faces = []
    ring = lambda k, j: 1 + k * around + j % around  # noqa: E731
    for j in range(around):
        faces.append([0, ring(0, j), ring(0, j + 1)])
        faces.append([len(x) - 1, ring(n_rings - 1, j + 1), ring(n_rings - 1, j)])
    for k in range(n_rings - 1):
        for j in range(around):
            a, b, c, d = ring(k, j), ring(k, j + 1), ring(k + 1, j + 1), ring(k + 1, j)
            faces += [[a, d, c], [a, c, b]]
    return x, np.array(faces, dtype=np.int64)


def box(lo, hi):
    """A closed axis-aligned box from corner lo to corner hi: (x (8, 3), faces (12, 3)),
    counter-clockwise seen from outside."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    x = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]]
                  for i in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return x, np.array(faces, dtype=np.int64)


def plate(width, depth, height=0.0):
    """An open horizontal square plate (two triangles) at y = height, centred on the y axis,
    facing up."""
    w, d = 0.5 * width, 0.5 * depth
    x = np.array([[-w, height, -d], [w, height, -d], [w, height, d], [-w, height, d]])
    return x, np.array([[0, 2, 1], [0, 3, 2]], dtype=np.int64)
