"""Shared builders for the tests: meshes with known geometry, made here (no external data)."""

import contextlib
import os
import signal
import subprocess
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


def tet_grid(n, rng=None, jitter=0.2):
    """(n+1)³ vertices of a unit-spaced cube grid, each cube cut into the six Kuhn
    tetrahedra sharing its diagonal (positively oriented): (vertices (N,3), tets (6n³, 4)).
    ``jitter`` moves every vertex by up to that fraction of a spacing (with ``rng``)."""
    axis = np.arange(n + 1, dtype=np.float64)
    x = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    if rng is not None:
        x += jitter * (rng.random(x.shape) - 0.5)
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    c = [idx[i:n + i, j:n + j, k:n + k].ravel() for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    paths = [(1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6)]  # corner 0 to corner 7 via a, b
    tets = np.concatenate([np.stack([c[0], c[a], c[b], c[7]], 1) for a, b in paths])
    d = x[tets[:, :3]] - x[tets[:, 3:]]
    negative = np.linalg.det(np.transpose(d, (0, 2, 1))) < 0
    tets[negative, 0], tets[negative, 1] = tets[negative, 1], tets[negative, 0].copy()
    return x, tets.astype(np.int64)


# tetrahedral mesh files: variant → (extension, meshio format, meshio keywords); "tetgen" by hand
TET_VARIANTS = {
    "vtu": (".vtu", "vtu", {}), "vtu_ascii": (".vtu", "vtu", {"binary": False}),
    "vtk": (".vtk", "vtk", {}), "vtk_ascii": (".vtk", "vtk", {"binary": False}),
    "msh22": (".msh", "gmsh22", {}), "msh22_ascii": (".msh", "gmsh22", {"binary": False}),
    "msh41": (".msh", "gmsh", {}), "msh41_ascii": (".msh", "gmsh", {"binary": False}),
    "tetgen": (".node", None, {}),
}


def write_tetgen(node_path, x, tets=None, base=0, ele_path=None):
    """A TetGen .node file (and, with ``tets``, its .ele: same name unless ``ele_path``)."""
    lines = [f"# {len(x)} points", f"{len(x)} 3 0 0"]
    lines += [f"{i + base} {p[0]!r} {p[1]!r} {p[2]!r}" for i, p in enumerate(x.tolist())]
    node_path.write_text("\n".join(lines) + "\n")
    if tets is not None:
        ele_path = ele_path or node_path.with_suffix(".ele")
        rows = [f"{len(tets)} 4 0"] + [f"{i + base} " + " ".join(str(v + base) for v in t)
                                      for i, t in enumerate(tets.tolist())]
        ele_path.write_text("\n".join(rows) + "  # end\n")


def write_tet_file(path_stem, x, tets, variant, triangles=None):
    """Write one frame in ``variant`` (a key of TET_VARIANTS) as ``path_stem`` + extension;
    ``triangles`` (K, 3): extra cells that readers must ignore (not for msh41/tetgen).
    Returns the path."""
    import meshio

    ext, fmt, kw = TET_VARIANTS[variant]
    path = path_stem.with_name(path_stem.name + ext)
    if fmt is None:
        write_tetgen(path, x, tets)
        return path
    cells = [("tetra", tets)]
    cell_data = {}
    if triangles is not None:
        cells = [("triangle", triangles), *cells]
    if fmt.startswith("gmsh"):
        cell_data = {key: [np.ones(len(c), np.int32) for _, c in cells]
                     for key in ("gmsh:physical", "gmsh:geometrical")}
    meshio.write(path, meshio.Mesh(x, cells, cell_data=cell_data), file_format=fmt, **kw)
    return path


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


def simulated(tmp_path_factory, config, name="run"):
    """The output folder of one ``clothtool.simulate`` run of ``config`` (for a module fixture)."""
    import clothtool

    out = tmp_path_factory.mktemp(name)
    clothtool.simulate(config, output_dir=out, progress=False)
    return out


@contextlib.contextmanager
def running(args, group=False):
    """The process ``args`` (stdout and stderr piped; Ctrl-C at its default, as from a terminal,
    even when the suite runs as a background job that ignores it), killed if it still runs at
    the end, its whole process group when ``group`` (a session of its own)."""
    proc = subprocess.Popen(list(map(str, args)), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=group,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        yield proc
    finally:
        if proc.poll() is None:
            if group:
                os.killpg(proc.pid, signal.SIGKILL)
            else:
                proc.kill()
            proc.wait()


def wait_until(proc, ready, waiting_for):
    """Wait until ``ready()`` holds (no clock: a loaded machine only delays it); fail if the
    process ``proc`` ends first."""
    while not ready():
        assert proc.poll() is None, (f"ended before {waiting_for}", proc.communicate())
        time.sleep(0.01)


def interrupt_when(args, ready, signum, waiting_for):
    """Run the clothtool command ``args``, send it ``signum`` once ``ready()`` holds; check that
    it exits 130 with the one-line message. Returns (stdout, stderr)."""
    with running(args) as proc:
        wait_until(proc, ready, waiting_for)
        proc.send_signal(signum)
        stdout, stderr = proc.communicate()
    assert proc.returncode == 130, stderr
    assert stderr.decode() == "clothtool: interrupted\n"
    return stdout, stderr


def dense_operator(rows, weights, blocks, count, n_vertices):
    """H = Σ_k (w_k w_kᵀ) ⊗ B_k of pair-operator entries, dense (3N × 3N)."""
    h = np.zeros((n_vertices, 3, n_vertices, 3))
    for k in range(count):
        for i in range(4):
            for j in range(4):
                h[rows[k, i], :, rows[k, j], :] += weights[k, i] * weights[k, j] * blocks[k]
    return h.reshape(3 * n_vertices, 3 * n_vertices)


def assemble(x, stencils, geo, kappa=1.0):
    """contact_assemble with fresh arrays: (energy, grad, pair data, smallest gap)."""
    from clothtool.contact.barrier import contact_assemble

    k = len(stencils)
    grad = np.zeros_like(x)
    act, w, nrm, coef = np.zeros(k, np.int64), np.zeros((k, 4)), np.zeros((k, 3)), np.zeros(k)
    force, tilt = np.zeros(k), np.zeros((k, 2, 4))
    e, n_act, gap = contact_assemble(x, stencils, geo, kappa, grad, act, w, nrm, coef, force, tilt)
    return e, grad, (act, n_act, w, nrm, coef, force, tilt), gap


def hessian_entries(x, stencils, pairs):
    """The pair-operator entries (rows, weights, blocks, count) of assembled pair data."""
    from clothtool.contact.barrier import barrier_blocks

    act, n_act, w, nrm, coef, force, tilt = pairs
    room = 3 * max(n_act, 1)
    rows, w_out, blocks = np.zeros((room, 4), np.int64), np.zeros((room, 4)), np.zeros((room, 3, 3))
    count = barrier_blocks(stencils, act, n_act, w, nrm, coef, force, tilt, x, rows, w_out, blocks)
    return rows, w_out, blocks, count
