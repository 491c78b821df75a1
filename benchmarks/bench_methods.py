"""Solver methods: error against a converged reference against time, on three scenes (issue 11).

    python -m benchmarks methods          # or: python -m benchmarks.bench_methods [out_dir]

Writes into the output folder:

- ``methods.csv`` / ``methods.md``: for each scene × method (every one of the registry;
  ``implicit`` and ``mass-spring`` with both integrators) × steps per frame × iteration
  budget (VBD at 32 steps per frame under ``--full`` only, which alone writes
  docs/solvers.md's verdict, fronts and VBD tables): wall time per frame and the error, the
  largest vertex distance to the scene's converged reference over every frame; per scene
  the Pareto front, whether the default (implicit, BDF2, default Newton settings, one step
  per frame) is on it for errors of 1 cm and more, and the orders of convergence of
  ``euler`` and ``bdf2`` (error at h, h/2, h/4); ``methods_<scene>.png``: error against
  time, the front drawn, the default marked (skipped with a message without matplotlib);
- ``stability.csv`` / ``stability.md``: time step × stretch stiffness per method, from a
  random initial state and from a fully flattened one;
- ``profile.md``: where a step's time goes, stage by stage.

The scenes, 0.5 s at 30 fps (15 frames):

- ``plate``: 0.5 m × 0.5 m, 12×12 grid, stretch 1e4 N/m, shear 1e3 N/m, bend 1e-3 N·m,
  no damping, pinned at one corner, released horizontally;
- ``hanging``: sample_data/hanging_sheet.yaml (1 m sheet, two corners pinned, damping
  0.01 s) at 16×16 instead of 32×32;
- ``drape``: a free 1 m sheet, 16×16, undamped, falling on a sphere (r = 0.25 m).

The reference of each scene is the implicit method with BDF2 at 64 steps per frame
(``--full``: 128), Newton and PCG solved tightly (the same ODE as the default's, damping
included); under ``--full`` its own convergence is its distance to the same at half its steps.
They are most of the benchmark's time, so they are kept, keyed by the scene's config and the
simulator's source, and recomputed only when either changes: the default ones in the
repository (benchmarks/references.py; ``--full`` rewrites them from its half-step runs),
``--full``'s in the output folder (``methods_reference_<scene>_<key>.npz``).
The other methods solve other discretisations (springs, constraints) of the same cloth, so
part of their error is their model's, which is the point of the comparison.
"""

import math
import pathlib
import sys
import time

import numpy as np
import yaml

from benchmarks.common import FULL, full_or, markdown_table, pyplot, write_csv, write_doc_table
from benchmarks.references import key, stored
from clothtool.sim.solvers.compare import run_in_memory

ROOT = pathlib.Path(__file__).resolve().parents[1]
FRAMES = 15  # 0.5 s at 30 fps
CHECKPOINTS = tuple(range(1, FRAMES + 1))
# the references' Newton and PCG tolerances: on the plate at 128 steps per frame 1.7e-8 m from
# 1e-9 m/s and 1e-10 (2.7 mm is the distance to 64 steps per frame); Newton to 1e-5 m/s rather
# than 1e-6 moves the three scenes' first four frames at 64 steps per frame by 0.3–2.2 nm at a
# third to half the CPU (Newton steps a step: 12.5, 19.2, 18.8 at 1e-6; 8.9, 8.7, 16.9 at 1e-5)
TIGHT = dict(integrator="bdf2", newton_iterations=60, newton_tolerance=1e-5, tolerance=1e-8,
             max_iterations=3000)
REF_STEPS = full_or(128, 64)  # 64: 2.7 mm from 128 on the plate, well below the 1 cm verdict
CM = 0.01  # the default must be on the front for errors of 1 cm and more
# Baraff–Witkin's linearised step: backward Euler, one Newton step (the default before BDF2)
ONE_STEP = dict(integrator="euler", newton_iterations=1, newton_tolerance=1e-6)
SCENES = ("plate", "hanging", "drape")
DEFAULT_LABEL = "implicit bdf2"


def scene(name, method="implicit", substeps=1, nx=None, frames=FRAMES, material=None, **solver):
    """A benchmark scene as a config dict (see the module docstring)."""
    if name == "plate":
        mat = {"stretch": 1e4, "shear": 1e3, "bend": 1e-3, "damping": 0.0}
        n = nx or 12
        cfg = {"mesh": {"grid": {"nx": n, "ny": n, "width": 0.5, "height": 0.5, "plane": "xz"}},
               "scene": {"pins": [0]}}
    elif name == "hanging":
        cfg = yaml.safe_load((ROOT / "sample_data" / "hanging_sheet.yaml").read_text())
        mat = cfg.pop("material")
        cfg["mesh"]["grid"].update(nx=nx or 16, ny=nx or 16)
        cfg.pop("output", None)
        solver = {**cfg.pop("solver", {}), **solver}
    elif name == "drape":
        mat = {"density": 0.2, "stretch": 5000.0, "shear": 50.0, "bend": 1e-3, "damping": 0.0}
        n = nx or 16
        cfg = {"mesh": {"grid": {"nx": n, "ny": n, "plane": "xz"}},
               "scene": {"pins": [], "colliders": [{"sphere": {"center": [0, -0.3, 0],
                                                                "radius": 0.25}}]}}
    else:
        raise ValueError(name)
    cfg["material"] = {**mat, **(material or {})}
    cfg["time"] = {"fps": 30, "frames": frames}
    cfg["solver"] = {**solver, "method": method, "substeps": substeps}
    return cfg


def error(run, ref):
    """Largest vertex distance (m) to the reference positions ``ref`` (frame → (N, 3)) over
    its frames; inf if the run stopped."""
    return error_to(run.positions, ref)


def error_to(positions, ref):
    """Largest vertex distance (m) of ``positions`` (frame → (N, 3)) to ``ref`` over ``ref``'s
    frames; inf where ``positions`` stops short."""
    worst = 0.0
    for frame, x_ref in ref.items():
        if frame not in positions:
            return math.inf
        worst = max(worst, float(np.linalg.norm(positions[frame] - x_ref, axis=1).max()))
    return worst


def newton_per_step(run, steps):
    return run.newton_iterations / max(run.frames_done * steps, 1)


def default_reference(name, steps):
    """``name``'s reference at ``steps`` steps per frame (the default one at REF_STEPS, or
    ``--full``'s half-step run): positions at CHECKPOINTS, Newton steps a step, seconds to
    solve it; from benchmarks/references/ when it holds it."""
    config = scene(name, "implicit", steps, **TIGHT)

    def solve():
        t0 = time.perf_counter()
        run = run_in_memory(config, CHECKPOINTS, warmup=False)
        return dict(positions=np.stack([run.positions[f] for f in CHECKPOINTS]),
                    newton_per_step=newton_per_step(run, steps),
                    seconds=time.perf_counter() - t0)

    data, cached = stored(f"methods_{name}", [config, steps, CHECKPOINTS], solve)
    return dict(positions=dict(zip(CHECKPOINTS, data["positions"])),
                newton_per_step=float(data["newton_per_step"]), seconds=float(data["seconds"]),
                distance_to_half_step_m=math.nan, cached="yes" if cached else "no")


def reference(name, out_dir):
    """The converged reference (BDF2 at REF_STEPS steps per frame, solved tightly) as a dict:
    ``positions`` (frame → (N, 3)), ``distance_to_half_step_m`` (to the same at half the steps,
    its convergence; ``--full`` only, nan without: a third of the references' time),
    ``newton_per_step``, ``seconds`` (to compute it) and ``cached``. The default one is
    :func:`default_reference`; ``--full``'s is read from ``out_dir`` when a file with its key
    is there, else computed with its half-step run (which rewrites the default one's file)."""
    if not FULL:
        return default_reference(name, REF_STEPS)
    config = scene(name, "implicit", REF_STEPS, **TIGHT)
    path = out_dir / f"methods_reference_{name}_{key([config, REF_STEPS, CHECKPOINTS])}.npz"
    if path.exists():
        data = np.load(path)
        return dict(positions=dict(zip(CHECKPOINTS, data["positions"])),
                    distance_to_half_step_m=float(data["distance_to_half_step_m"]),
                    newton_per_step=float(data["newton_per_step"]),
                    seconds=float(data["seconds"]), cached="yes")
    t0 = time.perf_counter()
    fine = run_in_memory(config, CHECKPOINTS, warmup=False)
    half = default_reference(name, REF_STEPS // 2)
    ref = dict(positions=fine.positions,
               distance_to_half_step_m=error_to(half["positions"], fine.positions),
               newton_per_step=newton_per_step(fine, REF_STEPS),
               seconds=time.perf_counter() - t0, cached="no")
    for old in out_dir.glob(f"methods_reference_{name}_*.npz"):
        old.unlink()
    np.savez(path, positions=np.stack([fine.positions[f] for f in CHECKPOINTS]),
             **{k: ref[k] for k in ("distance_to_half_step_m", "newton_per_step", "seconds")})
    return ref


# VBD at 32 steps per frame: over half of VBD's work and a third of the grid's; --full only
# (it alone writes docs/solvers.md's tables, whose drape front ends on VBD ×32 at 20 sweeps,
# 0.231 m, a hair below explicit's 0.233 m, the quick run's last point)
VBD_SUBSTEPS = full_or((1, 4, 16, 32), (1, 4, 16))
# (label, method, extra solver keys, steps per frame, iteration budgets or None)
GRID = [
    (DEFAULT_LABEL, "implicit", {"integrator": "bdf2"}, (1, 2, 4, 8), None),
    ("implicit euler", "implicit", {"integrator": "euler"}, (1, 2, 4, 8), None),
    ("implicit euler, 1 Newton step", "implicit", ONE_STEP, (1, 2, 4), None),
    ("mass-spring bdf2", "mass-spring", {"integrator": "bdf2"}, (1, 2, 4), None),
    ("mass-spring euler", "mass-spring", {"integrator": "euler"}, (1, 2, 4), None),
    ("projective", "projective", {}, (1, 4, 16), (5, 20)),
    ("xpbd", "xpbd", {}, (1, 4, 16, 64), (5, 20)),
    ("pbd", "pbd", {}, (1, 4, 16, 64), (5, 20)),
    ("pbd hierarchical", "pbd", {"pbd_variant": "hierarchical"}, (1, 4, 16), (5, 20)),
    ("explicit", "explicit", {}, (1,), None),  # automatic internal steps (cfl 0.5)
    ("vbd", "vbd", {}, VBD_SUBSTEPS, (5, 10, 20)),
    ("vbd no chebyshev", "vbd", {"chebyshev_rho": 0.0}, (1, 16), (10,)),
]
COLUMNS = ["scene", "method", "substeps", "iterations", "ms_per_frame", "error_m",
           "newton_per_step", "max_stretch", "status"]


# explicit's automatic internal steps beyond this per frame are not run: the damped hanging
# sheet needs 17 216 (β = 0.01 s), one run of 2–3 CPU minutes, more than all its other runs
MAX_EXPLICIT_STEPS = 2000


def explicit_steps(config):
    """Internal steps per frame ``explicit`` takes with its automatic step (cfl 0.5)."""
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config
    from clothtool.sim.solvers.explicit import critical_step

    config = load_config(config)
    h = 1.0 / (config.time.fps * config.solver.substeps)
    return config.solver.substeps * math.ceil(h / (config.solver.cfl
                                                   * critical_step(build_model(config))))


def measure(name, ref, out_rows):
    from clothtool.sim.model.methods import METHODS

    assert {m for _, m, *_ in GRID} == set(METHODS), "every registered method is benchmarked"
    for label, method, extra, substeps, iterations in GRID:
        for sub in substeps:
            for its in (iterations or (None,)):
                kw = dict(extra)
                if its is not None:
                    kw["iterations"] = its
                config = scene(name, method, sub, **kw)
                if method == "explicit" and explicit_steps(config) > MAX_EXPLICIT_STEPS:
                    steps = explicit_steps(config)
                    out_rows.append(dict(scene=name, method=label, substeps=sub, iterations="",
                                         ms_per_frame=math.nan, error_m=math.inf,
                                         newton_per_step="", max_stretch=math.nan,
                                         status=f"not run: {steps} internal steps per frame"))
                    print(f"  {name:8s} {label:30s} not run ({steps} internal steps per frame)")
                    continue
                run = run_in_memory(config, CHECKPOINTS)
                steps = max(run.frames_done * sub, 1)
                row = dict(scene=name, method=label, substeps=sub,
                           iterations=its if its is not None else "",
                           ms_per_frame=1000.0 * run.wall_per_frame, error_m=error(run, ref),
                           newton_per_step=(run.newton_iterations / steps
                                            if method in ("implicit", "mass-spring") else ""),
                           max_stretch=run.max_stretch, status=run.blew_up or "ok")
                out_rows.append(row)
                print(f"  {name:8s} {label:30s} sub {sub:3d} it {str(its):>4s} "
                      f"{row['ms_per_frame']:8.2f} ms/frame  err {row['error_m']:.4f} m  "
                      f"{row['status']}", flush=True)


def pareto(rows):
    """Rows not dominated in (ms_per_frame, error_m)."""
    ok = [r for r in rows if math.isfinite(r["error_m"]) and r["status"] == "ok"]
    ok.sort(key=lambda r: (r["ms_per_frame"], r["error_m"]))
    front, best = [], math.inf
    for r in ok:
        if r["error_m"] < best:
            front.append(r)
            best = r["error_m"]
    return front


def is_default(r):
    return r["method"] == DEFAULT_LABEL and r["substeps"] == 1


def default_verdict(rows):
    """(default row, the runs that dominate it for errors ≥ 1 cm): faster, and with an
    error below the default's or 1 cm, whichever is larger."""
    default = next(r for r in rows if is_default(r))
    bar = max(default["error_m"], CM)
    beaten = [r for r in rows if r is not default and r["status"] == "ok"
              and r["ms_per_frame"] < default["ms_per_frame"] and r["error_m"] < bar]
    return default, beaten


def orders(rows):
    """Error at h, h/2, h/4 (1, 2, 4 steps per frame) and log₂ of the ratios, for the
    implicit method with each integrator (default Newton settings)."""
    out = []
    for name in SCENES:
        for label in (DEFAULT_LABEL, "implicit euler"):
            e = {r["substeps"]: r["error_m"] for r in rows
                 if r["scene"] == name and r["method"] == label}
            out.append({"scene": name, "integrator": label.split()[-1], "error_h": e[1],
                        "error_h/2": e[2], "error_h/4": e[4],
                        "order_h→h/2": math.log2(e[1] / e[2]),
                        "order_h/2→h/4": math.log2(e[2] / e[4])})
    return out


def plot(rows, path, title):
    plt = pyplot()
    if plt is None:
        return False
    fig, ax = plt.subplots(figsize=(8, 5.5))
    labels = list(dict.fromkeys(r["method"] for r in rows))
    markers = "os^vD<>pPX*h"
    for k, label in enumerate(labels):
        pts = [(r["ms_per_frame"], r["error_m"]) for r in rows
               if r["method"] == label and r["status"] == "ok" and math.isfinite(r["error_m"])]
        if pts:
            xs, ys = zip(*pts)
            ax.scatter(xs, ys, marker=markers[k % len(markers)], label=label, s=28)
    front = pareto(rows)
    if front:
        ax.step([r["ms_per_frame"] for r in front], [r["error_m"] for r in front], where="post",
                color="k", lw=1, alpha=0.6, label="Pareto front")
    default = next(r for r in rows if is_default(r))
    ax.scatter([default["ms_per_frame"]], [default["error_m"]], s=220, facecolors="none",
               edgecolors="r", lw=2, label="default (implicit bdf2, 1 step/frame)")
    ax.axhline(CM, color="r", ls=":", lw=1, alpha=0.6)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per frame (ms, 1 core)")
    ax.set_ylabel("largest vertex distance to the converged reference (m, worst frame)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


# ---------------------------------------------------------------------------- stability

STAB_METHODS = [("implicit", "implicit", {}), ("mass-spring", "mass-spring", {}),
                ("projective", "projective", {}), ("xpbd", "xpbd", {}),
                ("pbd gauss-seidel", "pbd", {}), ("pbd jacobi", "pbd", {"pbd_variant": "jacobi"}),
                ("pbd hierarchical", "pbd", {"pbd_variant": "hierarchical"}),
                ("explicit", "explicit", {"cfl": 0.0}), ("explicit auto", "explicit", {}),
                ("vbd", "vbd", {})]
STAB_STIFFNESS = (1e3, 1e4, 1e5, 1e6)
STAB_SUBSTEPS = (1, 8)  # h = 1/30 s and 1/240 s
STAB_STARTS = ("random", "flattened")


def perturbed(start, seed=0):
    """An initial-state hook: ``random`` jitters every free vertex by up to 30 % of the
    grid spacing in all three axes with random velocities up to 1 m/s; ``flattened``
    collapses the sheet onto a line (every triangle has zero area)."""
    def hook(model, state):
        rng = np.random.default_rng(seed)
        free = model.free
        if start == "random":
            spacing = 1.0 / (int(round(math.sqrt(model.n_vertices))) - 1)
            state.x[free] += rng.uniform(-0.3, 0.3, (int(free.sum()), 3)) * spacing
            state.v[free] = rng.uniform(-1.0, 1.0, (int(free.sum()), 3))
        else:
            state.x[free, 2] = 0.0  # the xz sheet squashed onto the x axis
    return hook


def stability(out_dir):
    rows = []
    for label, method, extra in STAB_METHODS:
        for start in STAB_STARTS:
            for k in STAB_STIFFNESS:
                for sub in STAB_SUBSTEPS:
                    cfg = scene("hanging", method, sub, nx=12, frames=15,
                                material={"stretch": k, "shear": k / 100.0, "damping": 0.0},
                                **extra)
                    run = run_in_memory(cfg, (), warmup=False, initial=perturbed(start))
                    status = "ok" if run.ok else "blow-up"
                    if run.ok and run.max_stretch > 2.0:
                        status = "overstretched"
                    rows.append(dict(method=label, start=start, stretch=k, substeps=sub,
                                     h_ms=1000.0 / (30 * sub),
                                     status=status, max_stretch=run.max_stretch,
                                     detail=run.blew_up, ms_per_frame=1000 * run.wall_per_frame))
        print(f"  stability {label}: " + " ".join(r["status"][0] for r in rows if r["method"] == label),
              flush=True)
    write_csv(out_dir / "stability.csv", rows, ["method", "start", "stretch", "h_ms", "status",
                                                "max_stretch", "ms_per_frame", "detail"])
    # one line per method × start, one column per (stiffness, h)
    cols = [f"k={k:.0e}, h={1000 / (30 * s):.3g} ms" for k in STAB_STIFFNESS for s in STAB_SUBSTEPS]
    table = []
    for label, _, _ in STAB_METHODS:
        for start in STAB_STARTS:
            line = {"method": label, "start": start}
            for k in STAB_STIFFNESS:
                for s in STAB_SUBSTEPS:
                    r = next(r for r in rows if r["method"] == label and r["start"] == start
                             and r["stretch"] == k and r["substeps"] == s)
                    mark = {"ok": "ok", "overstretched": "λ>2", "blow-up": "**X**"}[r["status"]]
                    line[f"k={k:.0e}, h={1000 / (30 * s):.3g} ms"] = (
                        f"{mark} {r['max_stretch']:.2f}" if r["status"] != "blow-up" else mark)
            table.append(line)
    text = ("## Stability sweep\n\n12×12 hanging sheet (two corners pinned), 0.5 s, undamped, "
            "stretch stiffness k (N/m) with shear k/100, steps h = 1/30 and 1/240 s. Starts: "
            "`random` (positions jittered by ±30 % of the spacing, velocities up to 1 m/s), "
            "`flattened` (the sheet collapsed onto a line: every triangle has zero area). "
            "Each cell: `ok` with the largest principal stretch of the run, `λ>2` finite but "
            "overstretched (λmax > 2), `**X**` blow-up (non-finite, speed > 1000 m/s or |x| > 100 m).\n\n"
            + markdown_table(table, ["method", "start"] + cols))
    (out_dir / "stability.md").write_text(text)
    write_doc_table(DOC, "stability", markdown_table(table, ["method", "start"] + cols), "methods")
    return rows


# ---------------------------------------------------------------------------- profile


def profile(out_dir, steps=20):
    """Wrap the kernels the implicit integrator calls (module attributes, so the
    hot loop is untouched) and time each stage over ``steps`` steps."""
    import importlib
    import tempfile

    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.methods import make_integrator
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.output import FrameWriter

    # (module, kernel) → stage; each is looked up in the module that calls it
    stages = {("clothtool.sim.energies.terms", "membrane_assemble"): "membrane assembly (stretch+shear)",
              ("clothtool.sim.energies.terms", "hessian_gradient"): "bending (hessian plate)",
              ("clothtool.sim.energies.terms", "dihedral_assemble"): "bending assembly (dihedral)",
              ("clothtool.sim.energies.terms", "quadratic_gradient"): "bending (quadratic)",
              ("clothtool.sim.linalg.blocks", "block_multiply"): "damping products",
              ("clothtool.sim.solve.newton", "filtered_pcg"): "linear solve (PCG)",
              ("clothtool.sim.solve.newton", "resolve_collisions"): "collisions (projection)",
              ("clothtool.sim.solve.newton", "contact_constraints"): "collisions (contact constraints)",
              ("clothtool.sim.solve.newton", "apply_friction"): "collisions (friction)",
              ("clothtool.sim.energies.terms", "membrane_total_energy"): "line search: membrane energy",
              ("clothtool.sim.energies.terms", "dihedral_total_energy"): "line search: bending energy"}
    scenes = {
        "full (bending, damping 0.01 s, sphere, pins)": dict(
            material={"damping": 0.01}, extra={}),
        "bare (no bending, damping, colliders)": dict(
            material={"damping": 0.0, "bend": 0.0}, extra={}),
    }
    rows = []
    for title, spec in scenes.items():
        cfg = scene("drape", "implicit", 1, nx=32, frames=steps, material=spec["material"])
        if title.startswith("full"):
            cfg["scene"]["pins"] = ["top_corners"]
        else:
            cfg["scene"] = {"pins": [], "colliders": []}
        config = load_config(cfg)
        model = build_model(config)
        modules = {k: importlib.import_module(k[0]) for k in stages}
        present = {k: v for k, v in stages.items() if hasattr(modules[k], k[1])}
        timers = {k: [0.0, 0] for k in present}
        originals = {k: getattr(modules[k], k[1]) for k in present}

        def wrap(name, fn):
            def timed(*a, **kw):
                t0 = time.perf_counter()
                out = fn(*a, **kw)
                timers[name][0] += time.perf_counter() - t0
                timers[name][1] += 1
                return out
            return timed

        integ = make_integrator(model, config.solver, config.step)
        state = model.initial_state()
        integ.step(state)  # compile
        for k in present:
            timers[k] = [0.0, 0]
            setattr(modules[k], k[1], wrap(k, originals[k]))
        out_time = 0.0
        try:
            with tempfile.TemporaryDirectory() as tmp, FrameWriter(tmp, model.faces, model.mesh.uv) as w:
                started = time.perf_counter()
                for frame in range(1, steps + 1):
                    integ.step(state)
                    t0 = time.perf_counter()
                    kinetic, elastic, gravity = integ.energies(state)
                    stretch = integ.max_stretch(state)
                    w.write_frame(frame, state.x, state.time)
                    w.write_stats(dict(frame=frame, time=state.time, kinetic=kinetic, elastic=elastic,
                                       gravity=gravity, newton_iterations=1, cg_iterations=0,
                                       residual=0.0, max_stretch=stretch, wall_s=0.0, sweeps=0,
                                       substeps=0))
                    out_time += time.perf_counter() - t0
                total = time.perf_counter() - started
        finally:
            for k, fn in originals.items():
                setattr(modules[k], k[1], fn)
        accounted = sum(t for t, _ in timers.values()) + out_time
        for k, label in present.items():
            t, n = timers[k]
            rows.append(dict(scene=title, stage=label, calls=n, ms_per_step=1000 * t / steps,
                             share=f"{100 * t / total:.1f} %"))
        rows.append(dict(scene=title, stage="output (PLY frame, stats row, energies)", calls=steps,
                         ms_per_step=1000 * out_time / steps, share=f"{100 * out_time / total:.1f} %"))
        rows.append(dict(scene=title, stage="rest (numpy glue in the step)", calls="",
                         ms_per_step=1000 * (total - accounted) / steps,
                         share=f"{100 * (total - accounted) / total:.1f} %"))
        rows.append(dict(scene=title, stage="**total**", calls="", ms_per_step=1000 * total / steps,
                         share="100 %"))
    text = ("## Stage profile (implicit, 32×32, one step per frame)\n\n"
            f"{steps} steps of a 32×32 sheet: each kernel the step calls, timed by wrapping it "
            "from outside (the kernels and the step are unchanged; wrapping costs ~1 µs a call). "
            "The bare scene has no hinges, no damping matrix and no colliders in its Model, so "
            "those kernels are never called (0 calls).\n\n"
            + markdown_table(rows, ["scene", "stage", "calls", "ms_per_step", "share"]))
    (out_dir / "profile.md").write_text(text)
    write_doc_table(DOC, "profile", markdown_table([{**r, "setup": r["scene"]} for r in rows], [
        "setup", "stage", "calls", "ms_per_step", "share"]), "methods")
    return rows


# ---------------------------------------------------------------------------- docs

DOC = "docs/solvers.md"
DOC_COLUMNS = ["scene", "method", "substeps", "iterations", "ms_per_frame", "error_m",
               "max_stretch"]


def doc_tables(rows, verdicts):
    """docs/solvers.md's measured tables: the default's verdict, each scene's Pareto front,
    and VBD against the default and projective on the hanging sheet; ``--full`` only (the
    quick run has no VBD at 32 steps per frame, so its front and VBD's rows are shorter)."""
    write_doc_table(DOC, "methods-verdict", markdown_table(verdicts, [
        "scene", "default_error_m", "default_ms_per_frame", "on_front_for_errors_ge_1cm",
        "front"]), "methods", full_only=True)
    write_doc_table(DOC, "methods-front", markdown_table(
        [r for name in SCENES for r in pareto([r for r in rows if r["scene"] == name])],
        DOC_COLUMNS), "methods", full_only=True)
    vbd = [r for r in rows if r["scene"] == "hanging" and r["status"] == "ok"
           and (r["method"].startswith("vbd") or is_default(r) or r["method"] == "projective")]
    write_doc_table(DOC, "methods-vbd", markdown_table(vbd, DOC_COLUMNS), "methods",
                    full_only=True)


# ---------------------------------------------------------------------------- main


def run(out_dir):
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    rows, refs, verdicts = [], [], []
    for name in SCENES:
        ref = reference(name, out_dir)
        refs.append(dict(scene=name, ref_steps=REF_STEPS,
                         **{k: ref[k] for k in ("distance_to_half_step_m", "newton_per_step",
                                                "seconds", "cached")}))
        print(f"  {name}: reference vs half its steps {ref['distance_to_half_step_m']:.2e} m"
              f" (cached: {ref['cached']})", flush=True)
        measure(name, ref["positions"], rows)
        sub = [r for r in rows if r["scene"] == name]
        default, beaten = default_verdict(sub)
        verdicts.append(dict(scene=name, default_error_m=default["error_m"],
                             default_ms_per_frame=default["ms_per_frame"],
                             on_front_for_errors_ge_1cm="yes" if not beaten else "no",
                             faster_and_more_accurate=", ".join(
                                 f"{r['method']} ×{r['substeps']}"
                                 + (f" it {r['iterations']}" if r["iterations"] != "" else "")
                                 for r in beaten) or "none",
                             front=", ".join(dict.fromkeys(r["method"] for r in pareto(sub)))))
    write_csv(out_dir / "methods.csv", rows, COLUMNS)
    md = ["## Solver methods: error against time on three scenes\n",
          "0.5 s at 30 fps (15 frames). `plate`: 0.5 m × 0.5 m, 12×12, stretch 1e4 N/m, shear "
          "1e3 N/m, bend 1e-3 N·m, undamped, pinned at one corner, released horizontally; "
          "`hanging`: sample_data/hanging_sheet.yaml (damping 0.01 s, two corners pinned) at "
          "16×16; `drape`: a free 1 m sheet, 16×16, undamped, falling on a sphere (r = 0.25 m). "
          "Error: the largest vertex distance to the reference over every frame. Reference: "
          f"implicit, BDF2, {REF_STEPS} steps per frame, Newton and PCG solved tightly (the "
          "default's own ODE, damping included); `distance_to_half_step_m` is its distance to "
          f"the same at {REF_STEPS // 2} steps per frame (`--full` only). Wall time: kernels compiled, no output, "
          "on a shared 2-core machine (load varies: treat differences under ~30 % as noise). "
          "`iterations`: sweeps or local–global iterations per step; `explicit` picks its own "
          f"internal steps (cfl 0.5) and is not run where it would take more than "
          f"{MAX_EXPLICIT_STEPS} per frame (the damped hanging sheet). The other methods discretise the same cloth differently "
          "(springs, constraints), so part of their error is their model's.\n",
          markdown_table(refs, ["scene", "ref_steps", "distance_to_half_step_m",
                                "newton_per_step", "seconds", "cached"]),
          "\n### Is the default on the Pareto front?\n",
          "The default is implicit, BDF2, default Newton settings, one step per frame. It is "
          "dominated for errors of 1 cm and more when another run is faster and has an error "
          "below the default's or 1 cm, whichever is larger. `front`: the methods with a run "
          "on the Pareto front (fastest for its error), from fast to accurate.\n",
          markdown_table(verdicts, ["scene", "default_error_m", "default_ms_per_frame",
                                    "on_front_for_errors_ge_1cm", "faster_and_more_accurate",
                                    "front"]),
          "\n### Orders of convergence (implicit, default Newton settings)\n",
          "Error at h = 1/30 s, h/2 and h/4, and log₂ of the ratios:\n",
          markdown_table(orders(rows), ["scene", "integrator", "error_h", "error_h/2",
                                        "error_h/4", "order_h→h/2", "order_h/2→h/4"])]
    for name in SCENES:
        sub = [r for r in rows if r["scene"] == name]
        md.append(f"\n### {name}: Pareto front\n")
        md.append(markdown_table(pareto(sub), COLUMNS[1:]))
        if plot(sub, out_dir / f"methods_{name}.png", f"{name}: error against time"):
            md.append(f"\n![{name}](methods_{name}.png)\n")
        md.append(f"\n### {name}: all runs\n")
        md.append(markdown_table(sub, COLUMNS[1:]))
    (out_dir / "methods.md").write_text("\n".join(md))
    doc_tables(rows, verdicts)
    print(f"  methods done in {time.perf_counter() - started:.0f} s", flush=True)
    stability(out_dir)
    print(f"  stability done in {time.perf_counter() - started:.0f} s", flush=True)
    profile(out_dir)
    print(f"  profile done in {time.perf_counter() - started:.0f} s", flush=True)


if __name__ == "__main__":
    run(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench-results"))
