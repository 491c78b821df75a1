"""The 3D (Kabsch) variant (issue 3): throughput and accuracy, against a batched numpy SVD route.

    python -m benchmarks kabsch          # (or python -m benchmarks.bench_kabsch) writes
                                         # bench-results/kabsch.csv and kabsch.md, and the
                                         # tables of docs/kabsch.md

On a 224×224-vertex grid (99 458 triangles) deformed by a moving, stretching, bending wave, in
one run and with the same one-ring table:
- clothtool's vertex kernel (Horn quaternion + batched Jacobi, numba) with all threads and with
  one thread, against the numpy route (ring covariances by np.add.reduceat, np.linalg.svd on the
  stacked 3×3 matrices, det fix R = V diag(1, 1, det VUᵀ) Uᵀ); both give rotation, angle and
  residual. Medians over repeats; vertex-pairs per second.
- the maximum rotation error of both on the deformation against Horn's method evaluated in
  extended precision (np.longdouble Jacobi, 64-bit mantissa) and against scipy's
  Rotation.align_vectors (float64), and against the exact rotation of a rigid motion; the error
  growth on thin rings (relative eigen-gap down to 1e-8);
- the eigen-solver on random Horn matrices: Jacobi eigenvalues and the adjugate top eigenvector
  against numpy.linalg.eigh, sweeps;
- the whole per-pair cost inside ``analyze --kabsch`` (vertex + face + edge kernels).
"""

import os
import pathlib
import statistics
import time

import numba
import numpy as np
from scipy.spatial.transform import Rotation

from benchmarks.common import full_or, markdown_table, write_csv, write_doc_table
from clothtool.analysis.deformation2d import DEGENERATE_TOL
from clothtool.analysis.kabsch import horn_matrix, vertex_rotations
from clothtool.analysis.symeig import adjugate_eigenvector4, jacobi_eigvals_batch
from clothtool.geometry import one_ring
from clothtool.analysis.variant3d import KABSCH_FIELDS, Variant3D

NX = NY = 224
FRAMES = 6
# timed runs after a warm-up, the medians: clothtool's routes, the numpy route (a tenth as fast)
REPEAT = full_or(7, 3)
NUMPY_REPEAT = full_or(3, 1)


def make_mesh(nx=NX, ny=NY, frames=FRAMES):
    """Flat grid → frames of a travelling wave with in-plane stretch and a slow overall turn."""
    u, v = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny))
    u, v = u.ravel(), v.ravel()
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    a = (j * nx + i).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)])
    xs = []
    for k in range(frames):
        phase = 0.7 * k
        x = np.stack([u * (1 + 0.04 * k) + 0.03 * np.sin(3 * v + phase),
                      v + 0.02 * np.sin(5 * u),
                      0.15 * np.sin(2 * np.pi * u + phase) * np.cos(np.pi * v)], axis=1)
        xs.append(x @ Rotation.from_rotvec([0.1 * k, 0.05 * k, 0.2 * k]).as_matrix().T)
    return faces.astype(np.int64), xs


class NumpyRoute:
    """Kabsch per vertex with numpy only: ring gather, reduceat covariances, batched SVD."""

    def __init__(self, offsets, neighbours):
        n = len(offsets) - 1
        counts = np.diff(offsets) + 1
        self.starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        self.owner = np.repeat(np.arange(n), counts)
        ring = np.empty(counts.sum(), np.int64)
        ring[self.starts] = np.arange(n)
        rest = np.ones(len(ring), bool)
        rest[self.starts] = False
        ring[rest] = neighbours
        self.ring, self.counts = ring, counts

    def __call__(self, x_ref, x_def):
        p, q = x_ref[self.ring], x_def[self.ring]
        p -= (np.add.reduceat(p, self.starts) / self.counts[:, None])[self.owner]
        q -= (np.add.reduceat(q, self.starts) / self.counts[:, None])[self.owner]
        H = np.add.reduceat(p[:, :, None] * q[:, None, :], self.starts)
        U, _, Vt = np.linalg.svd(H)
        d = np.ones((len(H), 3))
        d[:, 2] = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
        R = np.einsum("nji,nj,nkj->nik", Vt, d, U)  # V · diag(1, 1, d) · Uᵀ
        skew = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], 1)
        angle = np.arctan2(0.5 * np.linalg.norm(skew, axis=1), 0.5 * (np.trace(R, axis1=1, axis2=2) - 1))
        r = np.einsum("nij,nj->ni", R[self.owner], p) - q
        residual = np.sqrt(np.add.reduceat(np.sum(r * r, 1), self.starts) / self.counts)
        return R, angle, residual


def median_seconds(fn, repeat=REPEAT):
    """Median wall time and median process CPU time (all threads) of ``fn()``."""
    fn()  # warm-up (compilation, caches)
    wall, cpu = [], []
    for _ in range(repeat):
        started, cpu_started = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - started)
        cpu.append(time.process_time() - cpu_started)
    return statistics.median(wall), statistics.median(cpu)


def scipy_reference(x_ref, x_def, offsets, neighbours):
    out = np.empty((len(offsets) - 1, 3, 3))
    for i in range(len(offsets) - 1):
        ring = np.r_[i, neighbours[offsets[i]:offsets[i + 1]]]
        p, q = x_ref[ring] - x_ref[ring].mean(0), x_def[ring] - x_def[ring].mean(0)
        out[i] = Rotation.align_vectors(q, p)[0].as_matrix()
    return out


def longdouble_reference(x_ref, x_def, offsets, neighbours):
    """Horn's rotation per vertex with every step in np.longdouble: ring covariances, N(H),
    cyclic Jacobi vectorised over the vertices (10 sweeps), quaternion → matrix."""
    route = NumpyRoute(offsets, neighbours)
    p, q = x_ref[route.ring].astype(np.longdouble), x_def[route.ring].astype(np.longdouble)
    p -= (np.add.reduceat(p, route.starts) / route.counts[:, None])[route.owner]
    q -= (np.add.reduceat(q, route.starts) / route.counts[:, None])[route.owner]
    S = np.add.reduceat(p[:, :, None] * q[:, None, :], route.starts)
    (xx, xy, xz), (yx, yy, yz), (zx, zy, zz) = S[:, 0].T, S[:, 1].T, S[:, 2].T
    A = np.stack([np.stack([xx + yy + zz, yz - zy, zx - xz, xy - yx], 1),
                  np.stack([yz - zy, xx - yy - zz, xy + yx, zx + xz], 1),
                  np.stack([zx - xz, xy + yx, -xx + yy - zz, yz + zy], 1),
                  np.stack([xy - yx, zx + xz, yz + zy, -xx - yy + zz], 1)], 1)
    V = np.broadcast_to(np.eye(4, dtype=np.longdouble), A.shape).copy()
    for _ in range(10):
        for i in range(3):
            for j in range(i + 1, 4):
                apq, d = A[:, i, j], A[:, j, j] - A[:, i, i]
                t = np.where(d >= 0, 2, -2) * apq / (np.abs(d) + np.sqrt(d * d + 4 * apq * apq) + 1e-300)
                c = 1 / np.sqrt(1 + t * t)
                s = t * c
                J = np.broadcast_to(np.eye(4, dtype=np.longdouble), A.shape).copy()
                J[:, i, i], J[:, j, j], J[:, i, j], J[:, j, i] = c, c, s, -s
                A = np.swapaxes(J, 1, 2) @ A @ J
                V = V @ J
    top = np.argmax(np.einsum("nii->ni", A), axis=1)
    w, x, y, z = V[np.arange(len(V)), :, top].T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], 1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], 1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], 1)], 1)


def thin_ring_errors(rng, widths=(1e-1, 1e-2, 1e-3, 1e-4), n=20000):
    """Rigidly moved planar rings of 7 points whose width across their axis is ``w`` × their
    length: the relative eigen-gap is ≈ w², so both routes lose accuracy like ε/w²."""
    rows = []
    for w in widths:
        x = rng.normal(size=(n, 7, 3)) * [1.0, w, 0.0]
        R = Rotation.random(n, random_state=rng).as_matrix()
        y = np.einsum("kij,kmj->kmi", R, x)
        offsets = np.zeros(7 * n + 1, np.int64)
        offsets[1:] = np.cumsum(np.tile([6, 0, 0, 0, 0, 0, 0], n))
        neighbours = (np.arange(n)[:, None] * 7 + np.arange(1, 7)).ravel()
        ours, _, _, flags = vertex_rotations(x.reshape(-1, 3), y.reshape(-1, 3), offsets, neighbours)
        theirs = NumpyRoute(offsets, neighbours)(x.reshape(-1, 3), y.reshape(-1, 3))[0]
        ok = flags[::7] == 0
        rows.append({"width_ratio": w, "unflagged": f"{ok.mean():.3f}",
                     "horn_jacobi_max_err": np.abs(ours[::7][ok] - R[ok]).max() if ok.any() else np.nan,
                     "numpy_svd_max_err": np.abs(theirs[::7] - R).max()})
    return rows


@numba.njit(cache=True)
def _top_vectors(batches, tops):
    """The adjugate eigenvector of each matrix's largest eigenvalue (Jacobi already ran)."""
    m = batches.shape[0] * batches.shape[3]
    out = np.empty((m, 4))
    b = np.empty((4, 4))
    for c in range(batches.shape[0]):
        for k in range(batches.shape[3]):
            adjugate_eigenvector4(batches[c], k, tops[c * batches.shape[3] + k], b, out[c * batches.shape[3] + k])
    return out


def eigen_accuracy(rng, n_matrices=200000):
    """Horn matrices N(H) of random 3×3 H, as the vertex kernel builds them: Jacobi eigenvalues
    and the adjugate top eigenvector against numpy.linalg.eigh (LAPACK)."""
    h = rng.normal(size=(n_matrices, 3, 3))
    a = np.empty((4, 4, n_matrices))
    for k in range(n_matrices):
        horn_matrix(h[k], 1.0, a, k)
    A = a.transpose(2, 0, 1).copy()
    batches = np.stack([A[s:s + 64].transpose(1, 2, 0) for s in range(0, n_matrices, 64)])
    originals = batches.copy()
    sweeps = [jacobi_eigvals_batch(batch) for batch in batches]
    lam = np.sort(np.einsum("ciik->cki", batches).reshape(-1, 4), axis=1)
    w, v = np.linalg.eigh(A)
    norm = np.abs(w).max(1)
    x = _top_vectors(originals, lam[:, 3].copy())
    err = np.minimum(np.abs(x - v[:, :, 3]).max(1), np.abs(x + v[:, :, 3]).max(1))
    gap = (w[:, 3] - w[:, 2]) / norm
    return [{"quantity": "eigenvalues (Jacobi)", "count": n_matrices,
             "max_error": float((np.abs(lam - w).max(1) / norm).max()), "unit": "‖N‖",
             "sweeps_per_batch_of_64": f"{min(sweeps)}-{max(sweeps)} (median {statistics.median(sweeps):g})"},
            {"quantity": "top eigenvector (adjugate), gap ≥ 1e-2", "count": int((gap >= 1e-2).sum()),
             "max_error": float(err[gap >= 1e-2].max()), "unit": "1"},
            {"quantity": "top eigenvector (adjugate) × relative gap, all", "count": n_matrices,
             "max_error": float((err * gap).max()), "unit": "1"}]


def run(out_dir):
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2024)
    faces, xs = make_mesh()
    n = len(xs[0])
    offsets, neighbours = one_ring(faces, n)
    numpy_route = NumpyRoute(offsets, neighbours)
    pairs = list(zip(xs[:-1], xs[1:]))
    threads = numba.get_num_threads()

    def ours():
        for x_ref, x_def in pairs:
            vertex_rotations(x_ref, x_def, offsets, neighbours)

    def theirs():
        for x_ref, x_def in pairs:
            numpy_route(x_ref, x_def)

    load = os.getloadavg()[0]
    t_ours, c_ours = median_seconds(ours)
    numba.set_num_threads(1)
    t_ours_1, c_ours_1 = median_seconds(ours)
    numba.set_num_threads(threads)
    t_numpy, c_numpy = median_seconds(theirs, repeat=NUMPY_REPEAT)

    variant = Variant3D(faces, n, KABSCH_FIELDS + ("flags",), DEGENERATE_TOL)
    buffers = variant.buffers(np.float32)
    t_variant, c_variant = median_seconds(lambda: [variant.compute(x_ref, x_def, buffers) for x_ref, x_def in pairs])

    # accuracy on the deformation (first pair) and on a rigid motion
    x_ref, x_def = pairs[0]
    reference = scipy_reference(x_ref, x_def, offsets, neighbours)
    extended = longdouble_reference(x_ref, x_def, offsets, neighbours)
    R_ours, angle_ours, res_ours, flags = vertex_rotations(x_ref, x_def, offsets, neighbours)
    R_np, angle_np, res_np = numpy_route(x_ref, x_def)
    R_true = Rotation.from_rotvec([0.4, -2.0, 1.1]).as_matrix()
    rigid = x_ref @ R_true.T + [3.0, -1.0, 2.0]
    R_ours_rigid, _, res_ours_rigid, _ = vertex_rotations(x_ref, rigid, offsets, neighbours)
    R_np_rigid, _, res_np_rigid = numpy_route(x_ref, rigid)

    vp = n * len(pairs)
    rows = [
        {"route": f"clothtool vertex kernel, {threads} threads", "seconds_per_pair": t_ours / len(pairs),
         "vertex_pairs_per_s": vp / t_ours, "speedup_vs_numpy": t_numpy / t_ours,
         "vertex_pairs_per_cpu_s": vp / c_ours,
         "max_rot_err_vs_longdouble": float(np.abs(R_ours - extended).max()),
         "max_rot_err_vs_scipy": np.abs(R_ours - reference).max(),
         "max_rot_err_rigid": np.abs(R_ours_rigid - R_true).max(), "max_residual_rigid": res_ours_rigid.max()},
        {"route": "clothtool vertex kernel, 1 thread", "seconds_per_pair": t_ours_1 / len(pairs),
         "vertex_pairs_per_s": vp / t_ours_1, "speedup_vs_numpy": t_numpy / t_ours_1,
         "vertex_pairs_per_cpu_s": vp / c_ours_1},
        {"route": "numpy route (reduceat + batched np.linalg.svd + det fix)", "seconds_per_pair": t_numpy / len(pairs),
         "vertex_pairs_per_s": vp / t_numpy, "speedup_vs_numpy": 1.0, "vertex_pairs_per_cpu_s": vp / c_numpy,
         "max_rot_err_vs_longdouble": float(np.abs(R_np - extended).max()),
         "max_rot_err_vs_scipy": np.abs(R_np - reference).max(),
         "max_rot_err_rigid": np.abs(R_np_rigid - R_true).max(), "max_residual_rigid": res_np_rigid.max()},
        {"route": f"analyze --kabsch per pair: vertex + face + edge kernels, {threads} threads",
         "seconds_per_pair": t_variant / len(pairs), "vertex_pairs_per_s": vp / t_variant,
         "vertex_pairs_per_cpu_s": vp / c_variant},
    ]
    agreement = {"max_angle_diff": np.abs(angle_ours - angle_np).max(),
                 "max_residual_diff_rel": (np.abs(res_ours - res_np) / res_np.max()).max(),
                 "flagged_vertices": int(np.count_nonzero(flags))}
    thin = thin_ring_errors(rng)
    eigen = eigen_accuracy(rng)

    columns = ["route", "seconds_per_pair", "vertex_pairs_per_s", "speedup_vs_numpy", "vertex_pairs_per_cpu_s",
               "max_rot_err_vs_longdouble", "max_rot_err_vs_scipy", "max_rot_err_rigid",
               "max_residual_rigid"]
    thin_columns = ["width_ratio", "unflagged", "horn_jacobi_max_err", "numpy_svd_max_err"]
    eigen_columns = ["quantity", "count", "max_error", "unit", "sweeps_per_batch_of_64"]
    table = ([{"table": "throughput", **r} for r in rows] + [{"table": "thin_rings", **r} for r in thin]
             + [{"table": "eigen", **r} for r in eigen] + [{"table": "agreement", **agreement}])
    write_csv(out_dir / "kabsch.csv", table,
              ["table", *columns, *thin_columns, *eigen_columns, *agreement])
    md = [f"## 3D (Kabsch) variant\n\n{NX}×{NY} vertices ({n} vertices, {len(faces)} triangles), "
          f"{len(pairs)} pairs of a moving, stretching, bending wave; medians of {REPEAT} runs "
          f"(numpy route: {NUMPY_REPEAT}); {threads} numba threads on {os.cpu_count()} CPUs, load average "
          f"{load:.1f} at the start (other work on the machine slows the wall-clock figures; "
          "vertex_pairs_per_cpu_s counts this process's CPU time, all threads). Rotation errors are "
          "max |R − R_ref| over all entries and vertices; the longdouble reference is Horn's method "
          "with every step in extended precision.\n\n",
          markdown_table(rows, columns),
          f"\nclothtool against the numpy route on the first pair: angles differ by at most "
          f"{agreement['max_angle_diff']:.2g} rad, residuals by {agreement['max_residual_diff_rel']:.2g} "
          f"of the largest; {agreement['flagged_vertices']} vertices flagged.\n",
          "\nThin rings, rigidly moved (relative eigen-gap ≈ width², RING_TOL = 1e-4 flags the "
          "thinnest): rotation error against the exact rotation\n\n",
          markdown_table(thin, thin_columns),
          "\nEigen-solver on Horn matrices N(H) of random H: Jacobi eigenvalues (64 matrices in "
          "lockstep) and the adjugate eigenvector of the largest, against numpy.linalg.eigh\n\n",
          markdown_table(eigen, eigen_columns)]
    (out_dir / "kabsch.md").write_text("".join(md))
    print("".join(md))
    write_doc_table("docs/kabsch.md", "kabsch", md[1] + md[2], "kabsch")
    write_doc_table("docs/kabsch.md", "kabsch-thin-rings", markdown_table(thin, thin_columns),
                    "kabsch")
    write_doc_table("docs/kabsch.md", "kabsch-eigen", markdown_table(eigen, eigen_columns),
                    "kabsch")


if __name__ == "__main__":
    run(pathlib.Path("bench-results"))
