"""Shared builders for the tests: meshes with known geometry, made here (no external data)."""

import time

import numpy as np
import pytest
from scipy.spatial import Delaunay


def grid(nx, ny, width=1.0, height=1.0):
    """Flat (nx × ny)-vertex grid in the xy plane: (vertices (N,3), faces (M,3))."""
    u, v = np.meshgrid(np.linspace(0, width, nx), np.linspace(0, height, ny))
    vertices = np.stack([u.ravel(), v.ravel(), np.zeros(u.size)], axis=1)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    a = (j * nx + i).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)])
    return vertices, faces.astype(np.int64)


def irregular_patch(rng, n=60):
    """Random points in the unit square triangulated by Delaunay (irregular planar patch)."""
    pts = np.concatenate([rng.random((n, 2)), [[0, 0], [1, 0], [0, 1], [1, 1]]])
    tri = Delaunay(pts)
    faces = tri.simplices.astype(np.int64)
    vertices = np.concatenate([pts, np.zeros((len(pts), 1))], axis=1)
    return vertices, faces


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def tangent_basis(vertices, faces):
    """(M, 2, 3) rows t1, t2 of each triangle's tangent frame, by numpy."""
    e1 = vertices[faces[:, 1]] - vertices[faces[:, 0]]
    e2 = vertices[faces[:, 2]] - vertices[faces[:, 0]]
    t1 = e1 / np.linalg.norm(e1, axis=1)[:, None]
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1)[:, None]
    return np.stack([t1, np.cross(n, t1)], axis=1)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


# The example config of the simulator's documentation; METHOD stands for solver.method.
EXAMPLE_CONFIG = """
mesh: {grid: {nx: 12, ny: 12, width: 1.0, height: 1.0, plane: xy}}
material: {density: 0.2, stretch: 5000.0, shear: 50.0, bend: 1.0e-5, damping: 0.01}
scene:
  gravity: [0, -9.81, 0]
  pins: [top_corners]
  colliders:
    - sphere: {center: [0, -0.5, 0], radius: 0.3}
    - plane: {point: [0, -1, 0], normal: [0, 1, 0]}
solver: {method: METHOD, substeps: 1, tolerance: 1.0e-6, max_iterations: 500}
time: {fps: 30, frames: 4}
output: {dir: out/, every: 1}
"""


def interrupt_when(proc, ready, signum, waiting_for, timeout=300):
    """Send ``signum`` to the clothtool process ``proc`` once ``ready()`` holds; check that it
    exits 130 with the one-line message. Returns (stdout, stderr)."""
    try:
        deadline = time.monotonic() + timeout
        while not ready():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, f"{waiting_for} never happened"
            time.sleep(0.02)
        proc.send_signal(signum)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, stderr
    assert stderr.decode() == "clothtool: interrupted\n"
    return stdout, stderr
