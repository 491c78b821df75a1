"""Run every benchmark module's ``run(out_dir)`` and collect the tables under bench-results/.

    python -m benchmarks                 # all
    python -m benchmarks analyze sim     # only bench_analyze.py and bench_sim.py
    python -m benchmarks obj             # OBJ read speed against trimesh and meshio (bench_obj.py)
    python -m benchmarks tet             # tetrahedra: kernel vs numpy SVD, readers, 200k × 50 frames
    python -m benchmarks sweep           # clothtool sweep's overhead against N/jobs × one run
    python -m benchmarks textile         # cantilever, hanging strip, drape; what bending costs
    python -m benchmarks peers           # Blender's cloth and NVIDIA Newton's VBD on our scenes
    python -m benchmarks fit             # clothtool fit: known answers, another mesh, Blender
    python -m benchmarks linalg          # preconditioners' phases; the step vs earlier commits
    python -m benchmarks --full [NAMES]  # the long cases too (benchmarks/common.py: FULL), and
                                         # the benchmarks of FULL_ONLY

A doc's measured table that the default cases would shorten is written under --full only
(common.write_doc_table's ``full_only``); bench-results/ gets every benchmark's files either way.
"""

import importlib
import os
import pathlib
import sys
import time

# Run only under --full or when named: the peers take minutes each (Newton's twist alone
# about 5 minutes of CPU) and need their own venvs; the fits run hundreds of simulations;
# drape_mesh runs the Cusick test some sixty times (4 mm discs included); the linear solve's
# runs a 256² sheet on three trees.
FULL_ONLY = ("bench_peers", "bench_fit", "bench_drape_mesh", "bench_linalg")


def main(argv):
    if "--full" in argv:
        argv = [a for a in argv if a != "--full"]
        os.environ["CLOTHTOOL_BENCH_FULL"] = "1"  # before the modules read it (and for children)
    out_dir = pathlib.Path("bench-results")
    out_dir.mkdir(exist_ok=True)
    here = pathlib.Path(__file__).parent
    names = sorted(p.stem for p in here.glob("bench_*.py"))
    if argv:
        names = [n for n in names if n.removeprefix("bench_") in argv]
    elif os.environ.get("CLOTHTOOL_BENCH_FULL") != "1":
        names = [n for n in names if n not in FULL_ONLY]
    for name in names:
        started = time.perf_counter()
        print(f"== {name}", flush=True)
        importlib.import_module(f"benchmarks.{name}").run(out_dir)
        print(f"== {name} done in {time.perf_counter() - started:.0f} s", flush=True)
    reports = sorted(out_dir.glob("*.md"))
    with open(out_dir / "README.md", "w") as fh:
        fh.write("# Benchmark results\n\nWritten by `make bench`.\n\n")
        for md in reports:
            if md.name != "README.md":
                fh.write(md.read_text() + "\n")
    print(f"tables in {out_dir}/ (summary: {out_dir / 'README.md'})")


if __name__ == "__main__":
    main(sys.argv[1:])
