"""Contact kernels against ipctk on a rolled, twisted 2500-vertex sheet (issue 12).

    python benchmarks/bench_contact.py [OUT_DIR]          # default bench-results/

The sheet (``clothtool.contact.shapes.rolled_sheet``, 50 × 50) is rolled into a
spiral whose layers lie 3–12 mm apart and twisted by π along its axis: a stand-in
for the twisted cloth rope. Per stage, the median wall time over repeats of one
Newton iteration's contact work, ours (numba, one thread) against ipctk with one
and with two threads:

- collision set: ours the candidate stencils over the position (grid broad phase and
  a distance filter), ipctk ``NormalCollisions.build`` (its broad phase and distance
  types, deduplicated); activation distance d̂ = 4 mm, no thickness;
- barrier gradient and Hessian: ours the exact gradient and the Hessian's pair-operator
  entries (Gauss–Newton blocks, ``barrier_blocks``), ipctk ``gradient`` and ``hessian``
  with PSD clamping (normalised log barrier at stiffness d̂², the same energy as ours);
- CCD over a smooth motion that squeezes the layers together and, at the tight end,
  through each other (so the collision-free step is below 1): ours broad phase over the motion + additive CCD, ipctk
  ``compute_collision_free_stepsize`` with its default (Tight Inclusion, provably
  conservative) and with its additive CCD;
- the exact intersection test, ours and ``ipctk.has_intersections``.

Writes ``contact.csv`` and ``contact.md`` into OUT_DIR.
"""

import statistics
import sys
import time
from pathlib import Path

import ipctk
import numpy as np

from benchmarks.common import markdown_table, write_csv
from clothtool.contact.barrier import barrier_blocks, contact_assemble, pair_geometry
from clothtool.contact.broadphase import contact_stencils, mesh_edges
from clothtool.contact.ccd import collision_free_step
from clothtool.contact.intersect import has_intersections
from clothtool.contact.shapes import rolled_sheet

DHAT = 0.004
REPEAT = 15


def median_ms(fun, repeat=REPEAT):
    fun()  # compile / warm up
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        fun()
        times.append(time.perf_counter() - started)
    return 1e3 * statistics.median(times)


def scene():
    x0, faces = rolled_sheet(n=50, gap=(0.003, 0.012))
    x1, _ = rolled_sheet(n=50, gap=(-0.002, 0.009), twist=np.pi + 0.05)
    return x0, x1 - x0, faces


def ours(x, dx, faces):
    n = len(x)
    edges = mesh_edges(faces)
    obstacle = np.zeros(n, dtype=np.bool_)
    zero = np.zeros_like(x)
    points, planes, radius = np.arange(n), np.zeros((0, 2), np.int64), np.zeros(n)
    geometry = pair_geometry(obstacle, radius, x, 0.0, 0.0, DHAT, DHAT)

    def collision_set():
        return contact_stencils(x, zero, np.zeros(n), points, faces, edges, planes, n, obstacle,
                                radius, True, DHAT)

    stencils = collision_set()
    k = len(stencils)
    grad = np.zeros_like(x)
    act, w, nrm, coef = np.zeros(k, np.int64), np.zeros((k, 4)), np.zeros((k, 3)), np.zeros(k)
    force, tilt = np.zeros(k), np.zeros((k, 2, 4))
    rows, w_out, blocks = np.zeros((3 * k, 4), np.int64), np.zeros((3 * k, 4)), np.zeros((3 * k, 3, 3))

    def derivatives():
        grad[:] = 0.0
        out = contact_assemble(x, stencils, geometry, 1.0, grad, act, w, nrm, coef, force, tilt)
        barrier_blocks(stencils, act, out[1], w, nrm, coef, force, tilt, x, rows, w_out, blocks)
        return out

    def ccd():
        st = contact_stencils(x, dx, np.zeros(n), points, faces, edges, planes, n, obstacle,
                              radius, True, 0.0)
        return collision_free_step(x, dx, st, geometry, 1.0)

    _, n_active, _ = derivatives()
    return {"collision set": median_ms(collision_set), "gradient + Hessian": median_ms(derivatives),
            "CCD": median_ms(ccd, 5), "intersection test": median_ms(lambda: has_intersections(x, faces)),
            "pairs": n_active, "step": ccd()}


def ipc(x, dx, faces, threads):
    ipctk.set_num_threads(threads)
    mesh = ipctk.CollisionMesh(x, mesh_edges(faces), faces)
    # the same energy as ours with κ = 1: κ d̂² B(d²/d̂²)
    potential = ipctk.BarrierPotential(ipctk.NormalizedClampedLogBarrier(), DHAT, DHAT**2)
    collisions = ipctk.NormalCollisions()
    x1 = x + dx

    def collision_set():
        collisions.build(mesh, x, DHAT)

    def derivatives():
        potential.gradient(collisions, mesh, x)
        potential.hessian(collisions, mesh, x, ipctk.PSDProjectionMethod.CLAMP)

    collision_set()
    row = {"collision set": median_ms(collision_set), "gradient + Hessian": median_ms(derivatives),
           "CCD": median_ms(lambda: ipctk.compute_collision_free_stepsize(mesh, x, x1), 3),
           "intersection test": median_ms(lambda: ipctk.has_intersections(mesh, x)),
           "pairs": len(collisions), "step": ipctk.compute_collision_free_stepsize(mesh, x, x1)}
    additive = ipctk.AdditiveCCD()
    row["CCD (additive)"] = median_ms(
        lambda: ipctk.compute_collision_free_stepsize(mesh, x, x1, narrow_phase_ccd=additive), 3)
    return row


def run(out_dir):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    x, dx, faces = scene()
    rows = [{"route": "clothtool (numba, 1 thread)", **ours(x, dx, faces)}]
    for threads in (1, 2):
        rows.append({"route": f"ipctk {ipctk.__version__} ({threads} thread{'s' * (threads > 1)})",
                     **ipc(x, dx, faces, threads)})
    stages = ("collision set", "gradient + Hessian", "CCD")
    for r in rows:
        r["per Newton iteration"] = sum(r[s] for s in stages)
    columns = ["route", "pairs", *stages, "CCD (additive)", "per Newton iteration",
               "intersection test", "step"]
    write_csv(out_dir / "contact.csv", rows, columns)
    text = ("## Contact kernels against ipctk (rolled 50 × 50 sheet, d̂ = 4 mm)\n\n"
            "Median ms per call on this machine. `pairs`: our active stencils (vertex–triangle and "
            "edge–edge, not deduplicated) and ipctk's collisions (deduplicated by distance type). "
            "`step`: the collision-free fraction of the squeezing motion. Written by "
            "`python benchmarks/bench_contact.py`.\n\n" + markdown_table(rows, columns))
    (out_dir / "contact.md").write_text(text)
    print(text)


if __name__ == "__main__":
    run(sys.argv[1] if len(sys.argv) > 1 else "bench-results")
