"""Tetrahedral analysis (issue 13): the kernel against a batched numpy SVD route, with accuracy,
the readers of each format, and a 200k-tetrahedron × 50-frame sequence end to end against its
I/O floor.

    python -m benchmarks tet             # writes bench-results/tet.csv and tet.md

- kernel: a 32³-cube grid cut into 196 608 Kuhn tetrahedra, deformed by a twisting, stretching
  wave with a few tetrahedra pushed through a face (inverted); clothtool's kernel (all fields)
  with all threads and with one, against numpy (F = G·D_r⁻¹ by matmul, np.linalg.svd on the
  (M, 3, 3) stack, the sign fix that makes R proper and λ3 negative when det F < 0, then
  U, R, C, E, J). Tetrahedra per second, medians; the maximum error of both against the same
  quantities in extended precision (np.longdouble one-sided Jacobi) and the numpy route's
  float64 SVD;
- readers: one frame of that mesh in every format, ms per frame through clothtool's readers;
- end to end: ``clothtool analyze`` of 50 legacy binary VTK frames (whole command, numba cache
  warm) against the I/O floor (tet_floor_io.py: read the vertex blocks, write the same
  datasets), one run each (``--full``: medians of 3 interleaved runs); under ``--full``, peak
  memory for 50 and 200 frames (the same frames linked four times): five more analyses.

The kernel and end-to-end tables are README.md's ``tet`` table, the memory its ``tet-memory``
(``--full`` alone writes it), the readers' its ``tet-readers``.
"""

import os
import pathlib
import statistics

import numba
import numpy as np

from benchmarks.common import (FULL, PYTHON, clothtool_cmd, full_or, markdown_table, median_seconds,
                               peak_rss_mb, run_timed, write_csv, write_doc_table)
from clothtool.analysis.tet import (DEGENERATE_TOL, TET_FIELDS, KernelPlan, rest_from_positions,
                                    tet_fields)

HERE = pathlib.Path(__file__).parent
N = 32  # cubes per side: 6·32³ = 196 608 tetrahedra, 33³ = 35 937 vertices
FRAMES = 50
REPEAT = 7  # kernel timings
RUNS = full_or(3, 1)  # end-to-end runs of clothtool and of the floor, interleaved


def tet_mesh(n=N):
    """(vertices, tets): the unit-spaced cube grid, each cube cut into the six Kuhn tetrahedra
    around its diagonal, oriented positively."""
    axis = np.arange(n + 1, dtype=np.float64)
    x = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    c = [idx[i:n + i, j:n + j, k:n + k].ravel() for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    tets = np.concatenate([np.stack([c[0], c[a], c[b], c[7]], 1)
                           for a, b in [(1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6)]])
    d = x[tets[:, :3]] - x[tets[:, 3:]]
    flip = np.linalg.det(d) < 0
    tets[flip, 0], tets[flip, 1] = tets[flip, 1], tets[flip, 0].copy()
    return x, tets.astype(np.int64)


def deform(x, t, n=N):
    """Frame at time t ∈ [0, 1]: a twist about z, a stretching wave, a slow turn."""
    u = x / n
    angle = 0.6 * t * u[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    y = np.stack([c * u[:, 0] - s * u[:, 1], s * u[:, 0] + c * u[:, 1],
                  u[:, 2] * (1 + 0.3 * t) + 0.05 * np.sin(6 * u[:, 0] + 4 * t)], axis=1)
    a = 0.4 * t
    turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    return n * y @ turn.T


def inverted_frame(x, tets, t=0.5, every=997):
    """``deform`` with every ``every``-th tetrahedron's fourth corner pushed through its face
    (the vertex is shared, so neighbours are strained too)."""
    y = deform(x, t)
    for k in range(0, len(tets), every):
        corners = tets[k]
        y[corners[3]] = 2 * y[corners[:3]].mean(0) - y[corners[3]]
    return y


def ours(x_ref, y, tets, rest=None):
    rest = rest or rest_from_positions(x_ref, tets)
    plan = KernelPlan(len(tets), TET_FIELDS)
    out, out_flags, views = plan.allocate(np.float64)
    tet_fields(y, tets, *rest, DEGENERATE_TOL, plan.starts, plan.needs, out, out_flags)
    return views


def numpy_route(x_ref, y, tets, dinv=None):
    """All fields with numpy: matmul for F, batched SVD, Irving's sign fix."""
    if dinv is None:
        dinv = np.linalg.inv(np.transpose(x_ref[tets[:, :3]] - x_ref[tets[:, 3:]], (0, 2, 1)))
    G = np.transpose(y[tets[:, :3]] - y[tets[:, 3:]], (0, 2, 1))
    F = G @ dinv
    W, S, Vt = np.linalg.svd(F)
    flip = np.linalg.det(W) * np.linalg.det(Vt) < 0  # improper W·Vᵀ: det F < 0
    S[flip, 2] *= -1
    W[flip, :, 2] *= -1
    C = np.transpose(F, (0, 2, 1)) @ F
    return {"F": F, "C": C, "strain": 0.5 * (C - np.eye(3)), "stretch": S,
            "R": W @ Vt, "U": np.transpose(Vt, (0, 2, 1)) @ (S[:, :, None] * Vt),
            "directions": Vt, "volume_ratio": np.linalg.det(F)}


def longdouble_reference(x_ref, y, tets, sweeps=12):
    """F, λ (Irving sign), R, U and J in np.longdouble (64-bit mantissa): adjugate inverse of
    D_r and one-sided Jacobi on the columns of F, vectorised over the tetrahedra."""
    ld = np.longdouble
    xr, yd = x_ref.astype(ld), y.astype(ld)
    D = np.transpose(xr[tets[:, :3]] - xr[tets[:, 3:]], (0, 2, 1))
    G = np.transpose(yd[tets[:, :3]] - yd[tets[:, 3:]], (0, 2, 1))
    cols = [D[:, :, i] for i in range(3)]
    det = np.einsum("mi,mi->m", cols[0], np.cross(cols[1], cols[2]))
    dinv = np.stack([np.cross(cols[1], cols[2]), np.cross(cols[2], cols[0]),
                     np.cross(cols[0], cols[1])], axis=1) / det[:, None, None]
    F = np.einsum("mik,mkj->mij", G, dinv)
    A = F.copy()
    V = np.broadcast_to(np.eye(3, dtype=ld), F.shape).copy()
    for _ in range(sweeps):
        for p, q in ((0, 1), (0, 2), (1, 2)):
            a, b = A[:, :, p].copy(), A[:, :, q].copy()
            alpha, beta, gamma = (a * a).sum(1), (b * b).sum(1), (a * b).sum(1)
            zero = gamma == 0
            zeta = (beta - alpha) / np.where(zero, 1, 2 * gamma)
            t = np.where(zero, 0, np.sign(zeta) / (np.abs(zeta) + np.sqrt(1 + zeta * zeta)))
            c = 1 / np.sqrt(1 + t * t)
            s = c * t
            A[:, :, p], A[:, :, q] = c[:, None] * a - s[:, None] * b, s[:, None] * a + c[:, None] * b
            va, vb = V[:, :, p].copy(), V[:, :, q].copy()
            V[:, :, p], V[:, :, q] = c[:, None] * va - s[:, None] * vb, s[:, None] * va + c[:, None] * vb
    sigma = np.sqrt((A * A).sum(1))
    order = np.argsort(-sigma, axis=1)
    sigma = np.take_along_axis(sigma, order, 1)
    A = np.take_along_axis(A, order[:, None, :], 2)
    V = np.take_along_axis(V, order[:, None, :], 2)
    detV = np.einsum("mi,mi->m", V[:, :, 0], np.cross(V[:, :, 1], V[:, :, 2]))
    V[detV < 0, :, 2] *= -1
    A[detV < 0, :, 2] *= -1
    W = A / sigma[:, None, :]
    W[:, :, 2] = np.cross(W[:, :, 0], W[:, :, 1])
    lam = sigma.copy()
    lam[:, 2] *= np.sign(np.einsum("mi,mi->m", W[:, :, 2], A[:, :, 2]))
    return {"F": F, "stretch": lam, "R": W @ np.transpose(V, (0, 2, 1)),
            "U": V @ (lam[:, :, None] * np.transpose(V, (0, 2, 1))),
            "volume_ratio": np.einsum("mi,mi->m", F[:, :, 0], np.cross(F[:, :, 1], F[:, :, 2]))}


def timed(cmd, fresh):
    """Wall time of ``cmd`` after removing its output ``fresh`` and flushing the page cache's
    dirty pages (untimed), so that no run pays for writing back the previous run's gigabytes."""
    if os.path.exists(fresh):
        os.remove(fresh)
    os.sync()
    return run_timed(cmd)


def kernel_rows(x, tets):
    y = inverted_frame(x, tets)
    rest = rest_from_positions(x, tets)
    plan = KernelPlan(len(tets), TET_FIELDS)
    out, out_flags, _ = plan.allocate(np.float64)

    def kernel():
        tet_fields(y, tets, *rest, DEGENERATE_TOL, plan.starts, plan.needs, out, out_flags)

    dinv = np.linalg.inv(np.transpose(x[tets[:, :3]] - x[tets[:, 3:]], (0, 2, 1)))
    threads = numba.get_num_threads()
    rows = []
    t_all = median_seconds(kernel, REPEAT)
    numba.set_num_threads(1)
    t_one = median_seconds(kernel, REPEAT)
    numba.set_num_threads(threads)
    t_np = median_seconds(lambda: numpy_route(x, y, tets, dinv), repeat=3)
    m = len(tets)
    ref = longdouble_reference(x, y, tets)
    mine, theirs = ours(x, y, tets, rest), numpy_route(x, y, tets, dinv)
    inverted = int(np.count_nonzero(mine["flags"] & 16))

    def worst(result, name):
        if name == "stretch":
            return float(np.abs(result[name] - ref[name]).max())
        return float(np.abs(np.asarray(result[name], np.float64) - ref[name].astype(np.float64)).max())

    for label, seconds, result in (
            (f"clothtool kernel, {threads} threads", t_all, mine),
            ("clothtool kernel, 1 thread", t_one, mine),
            ("numpy: matmul + batched SVD + sign fix", t_np, theirs)):
        row = {"route": label, "ms": 1e3 * seconds, "tets_per_s": m / seconds,
               "speedup_vs_numpy": t_np / seconds}
        for name in ("F", "stretch", "R", "U", "volume_ratio"):
            row[f"err_{name}"] = worst(result, name)
        rows.append(row)
    agree = {name: float(np.abs(mine[name] - theirs[name]).max())
             for name in ("F", "stretch", "R", "U", "volume_ratio")}
    return rows, inverted, agree


def write_frames(folder, x, tets, frames=FRAMES):
    import meshio

    folder.mkdir(parents=True, exist_ok=True)
    if len(list(folder.glob("*.vtk"))) == frames:
        return
    for k in range(frames):
        meshio.write(folder / f"f{k}.vtk", meshio.Mesh(deform(x, k / frames), [("tetra", tets)]),
                     binary=True)


def reader_rows(work, x, tets):
    import meshio

    from clothtool.io.tetmesh import read_tet_mesh

    rows = []
    mesh = meshio.Mesh(x, [("tetra", tets)])
    files = {"VTU binary, zlib (meshio default)": ("r.vtu", "vtu", {}),
             "VTU binary, uncompressed": ("r_raw.vtu", "vtu", {"compression": None}),
             "legacy VTK binary": ("r.vtk", "vtk", {"binary": True}),
             "Gmsh 4.1 binary": ("r41.msh", "gmsh", {"binary": True}),
             "Gmsh 2.2 binary": ("r22.msh", "gmsh22", {"binary": True}),
             "VTU ascii": ("r_ascii.vtu", "vtu", {"binary": False})}
    for label, (name, fmt, kw) in files.items():
        path = work / name
        meshio.write(path, mesh, file_format=fmt, **kw)
        seconds = median_seconds(lambda: read_tet_mesh(path), repeat=3)
        rows.append({"format": label, "ms_per_frame": 1e3 * seconds,
                     "file_mb": path.stat().st_size / 1e6})
        path.unlink()
    node = work / "r.node"
    lines = [f"{len(x)} 3 0 0"] + [f"{i} {p[0]!r} {p[1]!r} {p[2]!r}" for i, p in enumerate(x.tolist())]
    node.write_text("\n".join(lines) + "\n")
    ele = work / "r.ele"
    ele.write_text("\n".join([f"{len(tets)} 4 0"] + [f"{i} {a} {b} {c} {d}" for i, (a, b, c, d)
                                                     in enumerate(tets.tolist())]) + "\n")
    seconds = median_seconds(lambda: read_tet_mesh(node), repeat=3)
    rows.append({"format": "TetGen ascii .node + .ele (first frame)", "ms_per_frame": 1e3 * seconds,
                 "file_mb": (node.stat().st_size + ele.stat().st_size) / 1e6})
    first = read_tet_mesh(node)
    seconds = median_seconds(lambda: read_tet_mesh(node, reuse=first), repeat=3)
    rows.append({"format": "TetGen ascii .node, shared .ele (later frames)",
                 "ms_per_frame": 1e3 * seconds, "file_mb": node.stat().st_size / 1e6})
    node.unlink()
    ele.unlink()
    return rows


def peak_memory(work, seq):
    """Peak memory of ``analyze --fields stretch,volume_ratio,flags`` on the sequence and on
    four times as many frames (the same ones linked in turn)."""
    long_seq = work / "tet200"
    long_seq.mkdir(exist_ok=True)
    for k in range(4 * FRAMES):
        link = long_seq / f"f{k}.vtk"
        if not link.exists():
            os.symlink((seq / f"f{k % FRAMES}.vtk").resolve(), link)
    small_cmd = ["analyze", "-o", work / "m.h5", "-q", "--fields", "stretch,volume_ratio,flags"]
    return [{"frames": f, "peak_mb": peak_rss_mb(clothtool_cmd(small_cmd[0], folder, *small_cmd[1:]))}
            for f, folder in ((FRAMES, seq), (4 * FRAMES, long_seq))]


def run(out_dir):
    out_dir = pathlib.Path(out_dir)
    work = out_dir / "data"
    work.mkdir(parents=True, exist_ok=True)
    x, tets = tet_mesh()
    m = len(tets)
    kernel, inverted, agree = kernel_rows(x, tets)
    readers = reader_rows(work, x, tets)

    seq = work / "tet200k"
    write_frames(seq, x, tets)
    out, floor_out = work / "tet.h5", work / "tet_floor.h5"
    analyze = clothtool_cmd("analyze", seq, "-o", out, "-q")
    floor = [PYTHON, HERE / "tet_floor_io.py", seq, floor_out]
    timed(analyze, out)  # numba cache warm
    timings = [(timed(analyze, out), timed(floor, floor_out)) for _ in range(RUNS)]
    ours_s = statistics.median(t[0] for t in timings)
    floor_s = statistics.median(t[1] for t in timings)
    size = os.path.getsize(out) / 1e6
    pairs = FRAMES - 1
    e2e = [{"route": "clothtool analyze (all fields, float32)", "seconds": ours_s,
            "tet_pairs_per_s": m * pairs / ours_s, "vs_floor": ours_s / floor_s, "file_mb": size},
           {"route": "I/O floor (read vertex blocks, write the same datasets)", "seconds": floor_s,
            "tet_pairs_per_s": m * pairs / floor_s, "vs_floor": 1.0,
            "file_mb": os.path.getsize(floor_out) / 1e6}]
    fields = clothtool_cmd("analyze", seq, "-o", work / "s.h5", "-q", "--fields",
                           "stretch,volume_ratio,flags")
    small = statistics.median(timed(fields, work / "s.h5") for _ in range(RUNS))
    e2e.append({"route": "clothtool analyze --fields stretch,volume_ratio,flags", "seconds": small,
                "tet_pairs_per_s": m * pairs / small, "vs_floor": small / floor_s,
                "file_mb": os.path.getsize(work / "s.h5") / 1e6})

    memory = peak_memory(work, seq) if FULL else []

    kcols = ["route", "ms", "tets_per_s", "speedup_vs_numpy", "err_F", "err_stretch", "err_R",
             "err_U", "err_volume_ratio"]
    ecols = ["route", "seconds", "tet_pairs_per_s", "vs_floor", "file_mb"]
    write_csv(out_dir / "tet.csv", kernel + e2e, sorted({*kcols, *ecols}, key=(kcols + ecols).index))
    with open(out_dir / "tet.md", "w") as fh:
        fh.write(f"## tet: {m} tetrahedra ({len(x)} vertices)\n\n")
        fh.write(f"### Kernel, all fields, float64 outputs ({inverted} inverted tetrahedra)\n\n"
                 f"Medians of {REPEAT} (numpy: 3); err_* = max |value − np.longdouble "
                 "reference|.\n\n")
        fh.write(markdown_table(kernel, kcols))
        fh.write("\nclothtool against the numpy route (max |difference|): "
                 + ", ".join(f"{k} {v:.1e}" for k, v in agree.items()) + "\n")
        fh.write("\n### Readers, one frame\n\n")
        fh.write(markdown_table(readers, ["format", "ms_per_frame", "file_mb"]))
        fh.write(f"\n### End to end: {FRAMES} legacy binary VTK frames, {pairs} pairs\n\n"
                 f"Medians of {RUNS} interleaved run(s), whole commands, numba cache warm, dirty "
                 f"pages flushed before each; load average {os.getloadavg()[0]:.1f} at the end "
                 f"on {os.cpu_count()} cores.\n\n")
        fh.write(markdown_table(e2e, ecols))
        fh.write("\n### Peak memory (`--fields stretch,volume_ratio,flags`)\n\n")
        fh.write(markdown_table(memory, ["frames", "peak_mb"]) if memory
                 else "`python -m benchmarks --full tet`\n")
    write_doc_table("README.md", "tet", markdown_table(kernel, kcols) + "\n"
                    + markdown_table(e2e, ecols), "tet")
    write_doc_table("README.md", "tet-memory", markdown_table(memory, ["frames", "peak_mb"]),
                    "tet", full_only=True)
    write_doc_table("README.md", "tet-readers", markdown_table(readers, ["format", "ms_per_frame",
                                                                         "file_mb"]), "tet")
    for result in [*work.glob("*.h5"), *work.glob("*.xdmf")]:
        result.unlink()
    print((out_dir / "tet.md").read_text())


if __name__ == "__main__":
    run(pathlib.Path("bench-results"))
