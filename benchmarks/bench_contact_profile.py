"""Where contact's time goes, phase by phase: the drop of ``python -m benchmarks peers`` (a 48²
sheet dropped on a sphere with self-collision at 2 mm, 60 frames at 30 fps) and the twist's
first 120 frames (``sample_data/twist.yaml``).

    python -m benchmarks contact_profile

Each phase is the CPU time (``time.process_time``) spent in the functions the contact term
and Newton call for it, wrapped for the run: the broad phase (the candidate stencils), CCD
(the collision-free step and its near pairs), the barrier's assembly (pairs, blocks and the
pair operator), friction (lag, assembly, slip bounds), the line search's contact energies,
the piece test, the intersection check of every frame, and the PCG (with the pair operator's
products); "the rest" is the cloth's own terms and Newton's bookkeeping. With each scene's
Newton iterations, broad phases and CPU ms per step.

Writes ``contact_profile.csv`` and ``contact_profile.md``.
"""

import csv
import tempfile
import time
from pathlib import Path

from benchmarks.bench_peers import scene as peer_scene
from benchmarks.common import markdown_table, write_csv, write_doc_table

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("drop", "twist")
TWIST_FRAMES = 120
# phase: the functions (module, name) it spends its time in
PHASES = {
    "broad phase": [("clothtool.sim.solve.contact", "contact_stencils")],
    "CCD": [("clothtool.sim.solve.contact", "collision_free_step"),
            ("clothtool.sim.solve.contact", "near_pairs")],
    "barrier assembly": [("clothtool.sim.solve.contact", "contact_assemble"),
                         ("clothtool.sim.solve.contact", "barrier_blocks"),
                         ("clothtool.sim.solve.contact", "pair_operator"),
                         ("clothtool.sim.solve.contact", "pairs_add_diagonal")],
    "friction": [("clothtool.sim.solve.contact", name) for name in
                 ("friction_lag", "friction_assemble", "bound_reversed_slips",
                  "bound_slow_slips", "reference_slips", "slip_overshoots")],
    "line search energies": [("clothtool.sim.solve.contact", "contact_energy"),
                             ("clothtool.sim.solve.contact", "friction_energy")],
    "piece test": [("clothtool.sim.solve.contact", "slide_velocity")],
    "intersection check": [("clothtool.sim.solve.contact", "intersecting_pairs")],
    "PCG": [("clothtool.sim.solve.newton", "filtered_pcg")],
}


def timed_phases():
    """Wrap every phase's functions; returns ({phase: [CPU s, calls]}, undo)."""
    import importlib

    timers, undo = {phase: [0.0, 0] for phase in PHASES}, []
    for phase, functions in PHASES.items():
        for module_name, name in functions:
            module = importlib.import_module(module_name)
            inner = getattr(module, name)

            def timed(*args, _inner=inner, _timer=timers[phase], **kwargs):
                started = time.process_time()
                try:
                    return _inner(*args, **kwargs)
                finally:
                    _timer[0] += time.process_time() - started
                    _timer[1] += 1

            setattr(module, name, timed)
            undo.append((module, name, inner))

    def restore():
        for module, name, inner in undo:
            setattr(module, name, inner)

    return timers, restore


def profile(name, out):
    """Rows (one a phase, then "the rest" and the total) of ``name``'s timed run, after an
    untimed one-frame run."""
    from clothtool.sim.api import simulate

    if name == "drop":
        config, over = peer_scene("drop")[0], {}
    else:
        config, over = ROOT / "sample_data" / f"{name}.yaml", {"time.frames": TWIST_FRAMES}
    simulate(config, output_dir=out / "warm", overrides={**over, "time.frames": 1},
             progress=False)
    timers, restore = timed_phases()
    try:
        started = time.process_time()
        result = simulate(config, output_dir=out / "run", overrides=over or None,
                          progress=False)
        cpu = time.process_time() - started
    finally:
        restore()
    steps = max(result.steps, 1)
    with open(out / "run" / "stats.csv") as fh:
        frames = len(list(csv.DictReader(fh))) - 1
    broad = timers["broad phase"][1]
    head = {"scene": name, "frames": frames,
            "Newton it/step": f"{result.newton_iterations / steps:.2f}",
            "broad phases/step": f"{broad / steps:.2f}"}
    rows = [{**head, "phase": phase, "ms/step": f"{1e3 * t / steps:.1f}",
             "calls/step": f"{n / steps:.2f}", "share %": f"{100 * t / cpu:.1f}"}
            for phase, (t, n) in sorted(timers.items(), key=lambda kv: -kv[1][0])]
    rest = cpu - sum(t for t, _ in timers.values())
    rows.append({**head, "phase": "the rest (cloth terms, Newton)",
                 "ms/step": f"{1e3 * rest / steps:.1f}", "calls/step": "",
                 "share %": f"{100 * rest / cpu:.1f}"})
    rows.append({**head, "phase": "total CPU", "ms/step": f"{1e3 * cpu / steps:.1f}",
                 "calls/step": "", "share %": "100.0"})
    return rows


def run(out_dir):
    out_dir = Path(out_dir)
    with tempfile.TemporaryDirectory() as tmp:
        rows = [row for name in SCENES for row in profile(name, Path(tmp) / name)]
    columns = list(rows[0])
    write_csv(out_dir / "contact_profile.csv", rows, columns)
    table = markdown_table(rows, columns)
    (out_dir / "contact_profile.md").write_text("## Contact, phase by phase\n\n" + table + "\n")
    write_doc_table("docs/simulate.md", "contact-profile", table, "contact_profile")
    print(table)
