"""Reading OBJ frames (issue 13): clothtool's numpy reader against trimesh and meshio; and a
whole OBJ sequence analysed against the same sequence as binary PLY.

    python -m benchmarks obj             # writes bench-results/obj.csv and obj.md

One frame of the 224×224-vertex (99 458-triangle) sheet of bench_analyze.py, written as OBJ
three ways: ``v`` + ``f a b c``; ``v`` + ``vt`` + ``f a/b`` (one texture position per vertex,
as garment tools write it); and the same with every face a quad (``f`` of 4 corners, which
clothtool fan-triangulates). Each reader is timed on each file in this process (file in the
page cache), median of REPEAT reads: clothtool ``read_obj``, ``trimesh.load(path,
process=False)`` and ``meshio.read(path)``. meshio is an optional benchmark extra; without it
its rows are left out.

Sequence: SEQ_FRAMES frames of bench_analyze.py's sheet, its coordinates rounded to 6 decimals,
as binary little-endian float64 PLY and as OBJ (``v`` with %.9g, the same numbers, + ``f a b
c``); whole
``clothtool analyze`` commands (numba cache warm), medians of RUNS interleaved runs, and the
largest difference between the two results' /face/stretch (0: the same numbers).
Both tables are README.md's ``obj`` table.
"""

import pathlib
import statistics
import time

import h5py
import numpy as np

from benchmarks.bench_analyze import make_sequence
from benchmarks.common import clothtool_cmd, markdown_table, run_timed, write_csv, write_doc_table

REPEAT = 5
SEQ_FRAMES = 20
RUNS = 3


def obj_text(vertices, faces, uv=None):
    """OBJ bytes: %.9g coordinates; with ``uv`` one vt per vertex and ``f a/a`` corners."""
    parts = [b"# clothtool benchmark\no sheet\n",
             _rows("v", vertices)]
    if uv is not None:
        parts.append(_rows("vt", uv))
    idx = faces + 1
    if uv is None:
        parts.append(_rows("f", idx, "%d"))
    else:
        parts.append(_rows("f", np.repeat(idx, 2, axis=1), "%d/%d"))
    return b"".join(parts)


def _rows(keyword, table, fmt="%.9g"):
    k = table.shape[1]
    if fmt == "%d/%d":
        line = keyword + " " + " ".join(["%d/%d"] * (k // 2)) + "\n"
    else:
        line = keyword + " " + " ".join([fmt] * k) + "\n"
    return (line * len(table) % tuple(table.ravel().tolist())).encode()


def quads(nx, ny):
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    a = (j * nx + i).ravel()
    return np.stack([a, a + 1, a + nx + 1, a + nx], 1)


def time_reader(read, path):
    read(path)  # warm (imports, page cache)
    times = []
    for _ in range(REPEAT):
        started = time.perf_counter()
        mesh = read(path)
        times.append(time.perf_counter() - started)
    return statistics.median(times), mesh


def readers():
    import trimesh

    from clothtool.io.obj import read_obj

    out = {"clothtool read_obj": lambda p: read_obj(p),
           "trimesh.load(process=False)": lambda p: trimesh.load(p, process=False)}
    try:
        import meshio
    except ImportError:
        return out
    out["meshio.read"] = lambda p: meshio.read(p)
    return out


def run(out_dir):
    from clothtool.io.ply import read_ply

    out_dir = pathlib.Path(out_dir)
    work = out_dir / "data"
    src = work / "obj_source"
    make_sequence(src, frames=1)
    mesh = read_ply(src / "f0.ply")
    nx = int(round(np.sqrt(len(mesh.vertices))))
    x = mesh.vertices.astype(np.float32).astype(np.float64)
    uv = np.column_stack([np.tile(np.linspace(0, 1, nx), nx), np.repeat(np.linspace(0, 1, nx), nx)])
    files = {"v + f a b c": obj_text(x, mesh.faces),
             "v + vt + f a/b": obj_text(x, mesh.faces, uv),
             "v + vt + quads f a/b (4 corners)": obj_text(x, quads(nx, nx), uv)}
    rows = []
    for label, data in files.items():
        path = work / ("bench_" + label.split(" (")[0].replace(" ", "_").replace("/", "")
                       .replace("+", "") + ".obj")
        path.write_bytes(data)
        ours = None
        for name, read in readers().items():
            seconds, result = time_reader(read, path)
            n_tri = _triangles(result)
            ours = ours or seconds
            rows.append({"file": label, "reader": name, "ms_per_frame": 1e3 * seconds,
                         "MB_per_s": len(data) / 1e6 / seconds, "slower_than_clothtool": seconds / ours,
                         "file_mb": len(data) / 1e6, "triangles": n_tri})
        path.unlink()
    columns = ["file", "reader", "ms_per_frame", "MB_per_s", "slower_than_clothtool", "file_mb",
               "triangles"]
    write_csv(out_dir / "obj.csv", rows, columns)
    with open(out_dir / "obj.md", "w") as fh:
        fh.write("## Reading OBJ (one 224×224-vertex frame, 99 458 triangles; median of "
                 f"{REPEAT} reads, file in the page cache)\n\n")
        fh.write(markdown_table(rows, columns))
        fh.write("\ntriangles: what each reader returns (meshio keeps quads as quad cells, counted "
                 "here as two triangles each). With `process=False` trimesh still splits a vertex "
                 "that has two uv (a seam); clothtool keeps the `v` order and count.\n")
    sequence = sequence_rows(work)
    with open(out_dir / "obj.md", "a") as fh:
        fh.write(f"\n### A sequence of {SEQ_FRAMES} frames, OBJ against binary PLY (whole "
                 f"`clothtool analyze`, medians of {RUNS} interleaved runs)\n\n")
        fh.write(markdown_table(sequence, ["format", "seconds", "ms_per_frame", "vs_ply",
                                           "max_stretch_difference"]))
    write_doc_table("README.md", "obj", markdown_table(rows, columns) + "\n" + markdown_table(
        sequence, ["format", "seconds", "ms_per_frame", "vs_ply", "max_stretch_difference"]), "obj")
    for r in rows:
        print(f"{r['file']:34s} {r['reader']:30s} {r['ms_per_frame']:8.1f} ms "
              f"{r['MB_per_s']:7.1f} MB/s")
    for r in sequence:
        print(f"sequence {r['format']:4s} {r['seconds']:6.2f} s  {r['vs_ply']:.2f}× PLY")


def sequence_rows(work):
    """The same sequence as binary PLY and as OBJ through ``clothtool analyze``."""
    from clothtool.io.ply import read_ply, write_ply

    source, ply, obj = work / "seq_source", work / "seq_ply", work / "seq_obj"
    make_sequence(source, frames=SEQ_FRAMES)
    ply.mkdir(exist_ok=True)
    obj.mkdir(exist_ok=True)
    for k in range(SEQ_FRAMES):
        if not (obj / f"f{k}.obj").exists():
            mesh = read_ply(source / f"f{k}.ply")
            x = np.round(mesh.vertices, 6)  # the same float64 numbers in both files
            write_ply(ply / f"f{k}.ply", x, mesh.faces)
            (obj / f"f{k}.obj").write_bytes(obj_text(x, mesh.faces))
    outs = {"ply": work / "seq_ply.h5", "obj": work / "seq_obj.h5"}
    commands = {name: clothtool_cmd("analyze", folder, "-o", outs[name], "-q")
                for name, folder in (("ply", ply), ("obj", obj))}
    for command in commands.values():
        run_timed(command)  # numba cache warm, files in the page cache
    times = {name: [] for name in commands}
    for _ in range(RUNS):
        for name, command in commands.items():
            times[name].append(run_timed(command, fresh=outs[name]))
    with h5py.File(outs["ply"]) as a, h5py.File(outs["obj"]) as b:
        difference = float(np.nanmax(np.abs(a["face/stretch"][...] - b["face/stretch"][...])))
    ply_s = statistics.median(times["ply"])
    rows = [{"format": name, "seconds": statistics.median(t),
             "ms_per_frame": 1e3 * statistics.median(t) / SEQ_FRAMES,
             "vs_ply": statistics.median(t) / ply_s, "max_stretch_difference": difference}
            for name, t in times.items()]
    for path in [*outs.values(), *(p.with_suffix(".xdmf") for p in outs.values())]:
        path.unlink()
    return rows


def _triangles(result):
    faces = getattr(result, "faces", None)
    if faces is not None:  # clothtool / trimesh
        return int(len(faces))
    return int(sum(len(c.data) * (c.data.shape[1] - 2) for c in result.cells))  # meshio


if __name__ == "__main__":
    run(pathlib.Path("bench-results"))
