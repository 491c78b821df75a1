"""A garment sewn onto a moving body: two flat panels, front and back, 0.24 m apart on either
side of a capsule "torso" (radius 8 cm, axis along y), their side edges sewn (two seams),
their top rows attached to the body, which turns about its axis at 0.5 rad/s from t = 0.

Measures, for ``python -m benchmarks garment``:

- the largest seam gap after the weld (goal ≤ 1 mm) and the frame it welds at;
- crossing frames: our exact test (``clothtool.contact.intersect``) and ``ipctk.has_intersections``
  on every written frame, the garment's welded seam vertices merged (goal 0 and 0);
- whether the garment stays on the body: after the weld, the largest distance of a garment
  vertex from the body's axis, its lowest point at the end, and the attached vertices'
  largest distance from their goal (the body's turn since the weld);
- ms/frame: the wall-time median of ``stats.csv``'s frames while sewing and after the weld,
  and the whole run's CPU time per frame.

Writes ``garment.md`` and ``garment.csv`` into OUT_DIR.
"""

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import markdown_table, write_csv
from clothtool.io.obj_writer import write_obj

FPS, FRAMES = 30, 60
WIDTH, HEIGHT, NX, NY = 0.4, 0.4, 17, 17
DEPTH, RADIUS, SPEED = 0.12, 0.08, 0.5


def panel(nx, ny, width, height):
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    uv = np.stack([i.ravel() * width / (nx - 1), j.ravel() * height / (ny - 1)], axis=1)
    faces = []
    for b in range(ny - 1):
        for a in range(nx - 1):
            v = b * nx + a
            faces += [(v, v + 1, v + nx + 1), (v, v + nx + 1, v + nx)] if (a + b) % 2 else \
                [(v, v + 1, v + nx), (v + 1, v + nx + 1, v + nx)]
    return uv, np.array(faces, np.int64)


def garment(folder):
    """(obj path, seams, top vertices, N): front at z = +DEPTH facing +z, back at z = −DEPTH
    facing −z (its pattern mirrored), x across, y up from −HEIGHT/2 to +HEIGHT/2."""
    uv, faces = panel(NX, NY, WIDTH, HEIGHT)
    n = len(uv)
    front = np.column_stack([uv[:, 0] - WIDTH / 2, uv[:, 1] - HEIGHT / 2, np.full(n, DEPTH)])
    back = np.column_stack([WIDTH / 2 - uv[:, 0], uv[:, 1] - HEIGHT / 2, np.full(n, -DEPTH)])
    x = np.concatenate([front, back])
    path = Path(folder) / "garment.obj"
    corner = uv[faces]
    write_obj(path, x, np.concatenate([faces, faces + n]),
              corner_uv=np.concatenate([corner, corner]),
              groups=(["front", "back"], np.repeat([0, 1], len(faces))))
    rows = np.arange(NY) * NX
    # front's left edge (x = −W/2, column 0) to back's column NX−1 (x = −W/2), and the right
    seams = [{"a": (rows).tolist(), "b": (n + rows + NX - 1).tolist()},
             {"a": (rows + NX - 1).tolist(), "b": (n + rows).tolist()}]
    top = np.flatnonzero(np.isclose(x[:, 1], HEIGHT / 2))
    return path, seams, top, len(x)


def config(path, seams, top, out):
    return {"mesh": {"obj": str(path), "seams": seams},
            "material": {"density": 0.2, "stretch": 5000.0, "shear": 50.0, "bend": 1e-5,
                         "damping": 0.05},
            "scene": {"gravity": [0, -9.81, 0],
                      "colliders": [{"capsule": {"a": [0, -0.4, 0], "b": [0, 0.4, 0],
                                                 "radius": RADIUS, "friction": 0.3,
                                                 "motion": {"rotate": {"axis": [0, 1, 0],
                                                                       "speed": SPEED}}}}],
                      "self_collision": {"thickness": 0.002, "friction": 0.2},
                      "attach": {"vertices": top.tolist(), "to": 0}},
            "time": {"fps": FPS, "frames": FRAMES}, "output": {"dir": str(out)}}


def measure():
    import clothtool
    from clothtool.contact.intersect import has_intersections
    from clothtool.io.ply import read_ply

    with tempfile.TemporaryDirectory() as tmp:
        path, seams, top, n = garment(tmp)
        out = Path(tmp) / "out"
        c0 = time.process_time()
        result = clothtool.simulate(config(path, seams, top, out), progress=False)
        cpu = time.process_time() - c0
        stats = np.genfromtxt(out / "stats.csv", delimiter=",", names=True)
        a = np.concatenate([s["a"] for s in seams])
        b = np.concatenate([s["b"] for s in seams])
        merge = np.arange(n)
        merge[b] = a
        crossings, ipc_crossings, weld_frame, worst_gap = 0, 0, None, 0.0
        off_axis, attach_err, lowest = 0.0, 0.0, 0.0
        try:
            import ipctk
        except ImportError:
            ipctk = None
        for k in range(FRAMES + 1):
            frame = read_ply(out / f"frame_{k:05d}.ply")
            x, faces = frame.vertices, frame.faces
            gap = float(np.linalg.norm(x[a] - x[b], axis=1).max())
            if weld_frame is None and gap == 0.0:
                weld_frame = k
            if weld_frame is not None:
                worst_gap = max(worst_gap, gap)
            f = merge[faces] if weld_frame is not None else faces
            crossings += bool(has_intersections(x, f))
            if ipctk is not None:
                from clothtool.contact.broadphase import mesh_edges

                ipc_crossings += bool(ipctk.has_intersections(
                    ipctk.CollisionMesh(x, mesh_edges(f), f), x))
            if weld_frame is None:
                continue
            if k == weld_frame:  # the attachments take hold at the weld
                x_weld = x[top].copy()
            off_axis = max(off_axis, float(np.sqrt(x[:, 0] ** 2 + x[:, 2] ** 2).max()))
            lowest = float(x[:, 1].min())
            theta = SPEED * (k - weld_frame) / FPS
            c, s = np.cos(theta), np.sin(theta)
            goal = np.column_stack([c * x_weld[:, 0] + s * x_weld[:, 2], x_weld[:, 1],
                                    -s * x_weld[:, 0] + c * x_weld[:, 2]])
            attach_err = max(attach_err, float(np.abs(x[top] - goal).max()))
        wall = stats["wall_s"][1:]
        sew = wall[:weld_frame] if weld_frame else wall
        after = wall[weld_frame:] if weld_frame else wall[:0]
        return {"vertices": n, "triangles": len(faces), "frames": FRAMES,
                "welded at frame": weld_frame, "seam gap after weld mm (goal ≤ 1)": 1e3 * worst_gap,
                "crossing frames, ours": crossings,
                "crossing frames, ipctk": ipc_crossings if ipctk is not None else "n/a",
                "farthest vertex from the body axis after the weld m": off_axis,
                "lowest vertex at the end m (body bottom -0.48)": lowest,
                "attached vertices off their goal m": attach_err,
                "ms/frame sewing (wall median)": 1e3 * _median(sew),
                "ms/frame dressed (wall median)": 1e3 * _median(after),
                "ms/frame CPU (whole run)": 1e3 * cpu / FRAMES,
                "Newton/step": result.newton_iterations / max(result.steps, 1)}


def _median(values):
    return float(statistics.median(values)) if len(values) else 0.0


def run(out_dir):
    row = measure()
    print(row, flush=True)
    columns = list(row)
    (Path(out_dir) / "garment.md").write_text(
        "## Garment: two panels sewn around a turning capsule (bench_garment.py)\n\n"
        + markdown_table([row], columns))
    write_csv(Path(out_dir) / "garment.csv", [row], columns)


if __name__ == "__main__":
    run(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("bench-results"))
