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

And the same figures for the garment sample (``sample_data/garment.yaml``, from
``scripts/make_garment_sample.py``): a two-panel skirt sewn onto a walking mannequin (an animated
OBJ mesh collider), checked against the body too: crossings of the skirt with itself or the
body (ours: one exact test with the body as obstacle; ipctk: the skirt alone and with each
closed part of the body, since the parts of the union overlap one another), the waistband's
largest distance from the body's surface after the weld, and its lowest point against the hips.

Writes ``garment.md`` and ``garment.csv`` into OUT_DIR.
"""

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import markdown_table, write_csv, write_doc_table
from clothtool.geometry import grid_triangles, grid_uv
from clothtool.io.caches.obj_writer import write_obj

FPS, FRAMES = 30, 60
WIDTH, HEIGHT, NX, NY = 0.4, 0.4, 17, 17
DEPTH, RADIUS, SPEED = 0.12, 0.08, 0.5


def panel(nx, ny, width, height):
    """(uv, faces) of a criss-cross grid panel of ``width`` × ``height`` m from the origin."""
    return grid_uv(nx, ny, width, height) + [width / 2, height / 2], grid_triangles(nx, ny)


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


SAMPLE = Path(__file__).resolve().parent.parent / "sample_data" / "garment.yaml"
HIP_Y = 0.86  # the sample's hip joints (scripts/make_garment_sample.py)


def check_sample(out, config):
    """The sample's figures from a run's folder ``out`` of the loaded ``config``."""
    from clothtool.contact.broadphase import mesh_edges
    from clothtool.contact.distance import point_triangle_weights
    from clothtool.contact.intersect import has_intersections
    from clothtool.io.ply import read_ply
    from clothtool.sim.model.attach import _nearest_triangles
    from clothtool.sim.model.colliders import load_colliders

    try:
        import ipctk
    except ImportError:
        ipctk = None
    colliders = load_colliders(config.scene.colliders)
    body_faces = colliders.faces
    from clothtool.sim.model.builder import ModelBuilder

    a, b = ModelBuilder.from_config(config).stitches.T
    waist = np.asarray(config.scene.attach[0].vertices)
    frames = sorted(Path(out).glob("frame_*.ply"))
    n = len(read_ply(frames[0]).vertices)
    merge = np.arange(n)
    merge[b] = a
    body0 = colliders.positions(0.0)
    parts = _components(body_faces, len(body0))
    weld, worst_gap, crossings, ipc, waist_off, waist_low, lowest = None, 0.0, 0, 0, 0.0, np.inf, \
        np.inf
    w = np.empty(4)
    for k, path in enumerate(frames):
        frame = read_ply(path)
        x, faces = frame.vertices, frame.faces
        t = k / config.time.fps * config.output.every
        gap = float(np.linalg.norm(x[a] - x[b], axis=1).max())
        if weld is None and gap == 0.0:
            weld = k
        f = merge[faces] if weld is not None else faces
        y = colliders.positions(t)
        both = np.concatenate([x, y])
        obstacle = np.r_[np.zeros(n, bool), np.ones(len(y), bool)]
        crossings += bool(has_intersections(both, np.concatenate([f, body_faces + n]), obstacle))
        if ipctk is not None:
            hit = ipctk.has_intersections(ipctk.CollisionMesh(x, mesh_edges(f), f), x)
            for part in parts:
                pf = np.concatenate([f, part + n])
                hit = hit or ipctk.has_intersections(
                    ipctk.CollisionMesh(both, mesh_edges(pf), pf), both)
            ipc += bool(hit)
        lowest = min(lowest, float(x[:, 1].min()))
        if weld is None:
            continue
        worst_gap = max(worst_gap, gap)
        p = np.concatenate([x[waist], y])
        near = _nearest_triangles(p, body_faces + len(waist), len(waist))
        d = np.array([np.sqrt(point_triangle_weights(p, i, *(body_faces[tri] + len(waist)), w))
                      for i, tri in enumerate(near)])
        waist_off = max(waist_off, float(d.max()))
        d_lo, d_hi = (d, d) if k == weld else (np.minimum(d_lo, d), np.maximum(d_hi, d))
        waist_low = min(waist_low, float(x[waist, 1].min()))
    drift = float((d_hi - d_lo).max()) if weld is not None else np.nan
    return {"weld": weld, "gap": worst_gap, "frames": len(frames), "crossings": crossings,
            "waist_drift": drift,
            "ipctk": ipc if ipctk is not None else "n/a", "waist_off": waist_off,
            "waist_low": waist_low, "lowest": lowest, "vertices": n, "triangles": len(faces),
            "body triangles": len(body_faces)}


def _components(faces, n):
    """The faces of each connected part of a mesh (union-find over its vertices)."""
    root = np.arange(n)

    def find(v):
        while root[v] != v:
            root[v] = root[root[v]]
            v = root[v]
        return v
    for i, j, k in faces:
        for u, v in ((i, j), (j, k)):
            ru, rv = find(u), find(v)
            root[max(ru, rv)] = min(ru, rv)
    label = np.array([find(f[0]) for f in faces])
    return [faces[label == r] for r in np.unique(label)]


def measure_sample():
    import clothtool
    from clothtool.sim.model.config import load_config

    config = load_config(SAMPLE)
    with tempfile.TemporaryDirectory() as tmp:
        c0 = time.process_time()
        result = clothtool.simulate(config, output_dir=tmp, progress=False)
        cpu = time.process_time() - c0
        stats = np.genfromtxt(Path(tmp) / "stats.csv", delimiter=",", names=True)
        got = check_sample(tmp, config)
    wall, weld = stats["wall_s"][1:], got["weld"]
    return {"vertices": got["vertices"], "triangles": got["triangles"],
            "body triangles": got["body triangles"], "frames": got["frames"] - 1,
            "welded at frame": weld, "seam gap after weld mm (goal ≤ 1)": 1e3 * got["gap"],
            "crossing frames, ours (skirt and body)": got["crossings"],
            "crossing frames, ipctk (skirt and body)": got["ipctk"],
            "waistband off the body surface after the weld, largest mm": 1e3 * got["waist_off"],
            "waistband's change of distance from the body after the weld, largest mm":
                1e3 * got["waist_drift"],
            f"waistband lowest m (hips {HIP_Y})": got["waist_low"],
            "lowest vertex m (hem laid at 0.67)": got["lowest"],
            "ms/frame sewing (wall median)": 1e3 * _median(wall[:weld] if weld else wall),
            "ms/frame dressed (wall median)": 1e3 * _median(wall[weld:] if weld else wall[:0]),
            "ms/frame CPU (whole run)": 1e3 * cpu / config.time.frames,
            "Newton/step": result.newton_iterations / max(result.steps, 1)}


def _median(values):
    return float(statistics.median(values)) if len(values) else 0.0


def run(out_dir):
    row = measure()
    print(row, flush=True)
    sample = measure_sample()
    print(sample, flush=True)
    columns = list(row)
    (Path(out_dir) / "garment.md").write_text(
        "## Garment: two panels sewn around a turning capsule (bench_garment.py)\n\n"
        + markdown_table([row], columns)
        + "\n## The garment sample: a skirt sewn onto a walking mannequin "
        "(sample_data/garment.yaml)\n\n" + markdown_table([sample], list(sample)))
    for name, got in (("garment-capsule", row), ("garment-sample", sample)):
        write_doc_table("docs/simulate.md", name, markdown_table(
            [{"quantity": k, "value": v} for k, v in got.items()], ["quantity", "value"]),
            "garment")
    write_csv(Path(out_dir) / "garment.csv", [row], columns)
    write_csv(Path(out_dir) / "garment_sample.csv", [sample], list(sample))


if __name__ == "__main__":
    run(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("bench-results"))
