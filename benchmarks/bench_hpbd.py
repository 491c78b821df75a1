"""Hierarchical PBD against plain PBD on a fine sheet, at equal cost (issue 20).

    python -m benchmarks hpbd          # or: python -m benchmarks.bench_hpbd [out_dir]

Writes ``hpbd.md``: the hanging sheet (sample_data/hanging_sheet.yaml) at 128×128, 0.5 s at
30 fps, for ``pbd`` with ``pbd_variant`` gauss-seidel and hierarchical at 1 step per frame × 5–40
sweeps and (``--full``, which alone writes docs/solvers.md's table) 4 × 5–20: median ms per
frame and the error, the largest vertex distance over the frames to the reference
(``implicit``, BDF2, 8 steps per frame, default Newton settings: PBD's error at these
settings is decimetres to metres, the reference's own error centimetres at most), and the
largest stretch. At each hierarchical row's cost, the
error plain PBD reaches at that cost (log-linear interpolation between its two nearest
rows in ms/frame, or its cheapest row's if hierarchical is cheaper still). The reference is
most of the benchmark's time: it is kept in the repository (:func:`reference`).
"""

import math
import pathlib
import sys

import numpy as np

from benchmarks.bench_methods import error, scene
from benchmarks.common import full_or, markdown_table, write_doc_table
from benchmarks.references import stored
from clothtool.sim.solvers.compare import run_in_memory

N = 128
FRAMES = 15
CHECKPOINTS = tuple(range(1, FRAMES + 1))
# (steps per frame, sweeps); 4 steps per frame under --full, which alone writes the doc table
SETTINGS = [(1, 5), (1, 10), (1, 20), (1, 40)] + full_or([(4, 5), (4, 10), (4, 20)], [])


def _at_cost(rows, ms):
    """Plain PBD's error at ``ms`` per frame: the lower envelope of its rows, interpolated."""
    front = []
    for r in sorted(rows, key=lambda r: r["ms_per_frame"]):
        if not front or r["error_m"] < front[-1]["error_m"]:
            front.append(r)
    if ms <= front[0]["ms_per_frame"]:
        return front[0]["error_m"]
    for a, b in zip(front, front[1:]):
        if a["ms_per_frame"] <= ms <= b["ms_per_frame"]:
            t = (ms - a["ms_per_frame"]) / (b["ms_per_frame"] - a["ms_per_frame"])
            return math.exp((1 - t) * math.log(a["error_m"]) + t * math.log(b["error_m"]))
    return front[-1]["error_m"]


def reference():
    """The reference's positions (frame → (N, 3)): implicit, BDF2, 8 steps per frame, most of
    the benchmark's time, so kept in benchmarks/references/ (benchmarks/references.py) in
    float32: 0.1 µm on the 1 m sheet, where PBD's errors here are decimetres."""
    config = scene("hanging", "implicit", 8, nx=N)

    def solve():
        run = run_in_memory(config, CHECKPOINTS, warmup=False)
        return {"positions": np.stack([run.positions[f] for f in CHECKPOINTS]).astype(np.float32)}

    data, _ = stored(f"hpbd_hanging_{N}", [config, CHECKPOINTS], solve)
    return dict(zip(CHECKPOINTS, data["positions"].astype(np.float64)))


def run(out_dir):
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ref = reference()
    rows = []
    for variant in ("gauss-seidel", "hierarchical"):
        for sub, its in SETTINGS:
            r = run_in_memory(scene("hanging", "pbd", sub, nx=N, pbd_variant=variant,
                                    iterations=its), CHECKPOINTS)
            rows.append(dict(variant=variant, substeps=sub, iterations=its,
                             ms_per_frame=1000.0 * r.wall_per_frame, error_m=error(r, ref),
                             max_stretch=r.max_stretch, status=r.blew_up or "ok"))
            print(f"  {variant:13s} {sub} × {its:2d}: {rows[-1]['ms_per_frame']:7.1f} ms/frame, "
                  f"error {rows[-1]['error_m']:.3f} m", flush=True)
    plain = [r for r in rows if r["variant"] == "gauss-seidel" and r["status"] == "ok"]
    for r in rows:
        if r["variant"] == "hierarchical":
            r["plain_error_at_cost_m"] = _at_cost(plain, r["ms_per_frame"])
            r["ratio"] = r["error_m"] / r["plain_error_at_cost_m"]
    md = ["## Hierarchical PBD on a 128×128 sheet\n",
          f"sample_data/hanging_sheet.yaml at {N}×{N} (1 m, two corners pinned), 0.5 s. Error: "
          "largest vertex distance over the frames to implicit BDF2 at 8 steps per frame; "
          "`plain_error_at_cost_m`: plain (Gauss–Seidel) PBD's error at the same ms/frame "
          "(interpolated on its own rows), `ratio` the hierarchical error over it.\n",
          markdown_table(rows, ["variant", "substeps", "iterations", "ms_per_frame", "error_m",
                                "plain_error_at_cost_m", "ratio", "max_stretch", "status"])]
    ratios = [r["ratio"] for r in rows if "ratio" in r and np.isfinite(r["ratio"])]
    if ratios:
        md.append(f"\nMedian ratio {float(np.median(ratios)):.2f}, largest {max(ratios):.2f}.\n")
    (out_dir / "hpbd.md").write_text("\n".join(md))
    write_doc_table("docs/solvers.md", "hpbd", md[2] + "".join(md[3:]), "hpbd", full_only=True)
    return rows


if __name__ == "__main__":
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    run(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench-results"))
