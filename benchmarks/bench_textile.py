"""The textile lab's tests, swept over meshes and resolutions, and what bending costs.

    python -m benchmarks textile

Writes ``bench-results/textile.md`` and ``textile_drape.png``:

- cantilever (ASTM D1388): tip drop against the elastica at overhangs of 1, 2 and 3
  bending lengths, strips along a grid, at 45° to one, on a Delaunay mesh and on a grid
  jittered by 35 % of the spacing, at 20 divisions along the strip (``--full``: and 40, and
  strips across a grid and from a second Delaunay seed), for the ``hessian`` bending (the
  default) with the ``triangle`` (the default) and ``nodal`` membranes and for ``dihedral``
  (static equilibrium, :mod:`clothtool.sim.solve.statics`);
- hanging strips along warp, weft and bias against ρgL²/(2k) (k along the bias from
  :func:`clothtool.sim.textile.bias_modulus`), with each membrane model;
- Cusick drape (BS 5058: a 30 cm disc on an 18 cm pedestal): the drape coefficient on a
  grid, the grid turned 45° and a Delaunay mesh at 10 mm (and 7.5 mm under ``--full``),
  with the ``triangle`` membrane (``--full``: each membrane model), simulated to rest with the implicit method (a 6-fold ripple
  of 2 mm seeds the folds alike on every mesh);
- ``--full`` only: the membrane models' cost: ms/step of the 64×64 hanging sheet,
  alternating in one run; bending's cost: the 64×64 hanging sheet
  (sample_data/hanging_sheet.yaml) at one step per frame, CPU ms per step with bending and
  with ``bend: 0``, in this checkout and in a clone of the commit before the plate model
  (``BASE`` below, made with ``git clone``); bending's share is the difference; 3
  alternating runs in one process each, the median.

Only ``--full`` writes docs/simulate.md's cantilever and drape tables (they show 40 divisions,
7.5 mm and the nodal membrane); the hanging strips' table is the same in both.
"""

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import FULL, full_or, markdown_table, pyplot, sim_imports, write_doc_table

HERE = Path(__file__).resolve().parent.parent
BASE_COMMIT = "1e6cea5"
BASE = Path(os.environ.get("CLOTHTOOL_BASE", f"/tmp/base-{os.getpid()}"))
G = 9.81
DEFAULT_BEND, DEFAULT_MEMBRANE = "hessian", "triangle"  # material.bend_model, membrane_model
DRAPE_SPACINGS = full_or((0.01, 0.0075), (0.01,))  # m; the picture shows the finest
DRAPE_MEMBRANES = full_or(("triangle", "nodal"), ("triangle",))  # material.membrane_model
# Alternating runs of each cost comparison (a process each: start-up and kernel loading are
# most of its CPU time); the figure is the median of 20 steps' CPU time in each run.
COST_REPEAT = 3
# Divisions along the cantilever strip, for the other models and for the defaults: a 40-division
# strip costs about 4× a 20-division one, so 40 under --full only (and only it writes the doc's
# table, which shows both).
CANTILEVER_DIVISIONS = {False: full_or((20, 40), (20,)), True: full_or((20, 40), (20,))}
# The strips' meshes: ``across`` (the grid strip cut across its rows: the same errors as
# ``grid`` to every digit docs/simulate.md shows) and a second Delaunay seed under --full only.
CANTILEVER_MESHES = full_or((("grid", 0), ("across", 0), ("rot45", 0), ("delaunay", 0),
                             ("delaunay", 2), ("jittered", 0)),
                            (("grid", 0), ("rot45", 0), ("delaunay", 0), ("jittered", 0)))


def cantilever_rows():
    from clothtool.errors import NumericalError
    from clothtool.sim.solve.statics import static_equilibrium
    from clothtool.sim.textile import elastica_tip_drop, specimen_model, strip

    length, width, density = 0.1, 0.025, 0.2
    rows = []
    for model_name, membrane in (("hessian", "triangle"), ("hessian", "nodal"),
                                 ("dihedral", "triangle")):
        for kind, seed in CANTILEVER_MESHES:
            for divisions in CANTILEVER_DIVISIONS[model_name == DEFAULT_BEND
                                                  and membrane == DEFAULT_MEMBRANE]:
                uv, faces, held = strip(length, width, length / divisions, kind, seed=seed)
                tip = np.flatnonzero(uv[:, 0] >= length - 1e-9)
                default = (model_name == DEFAULT_BEND, membrane == DEFAULT_MEMBRANE)
                row = {"model": model_name + (" (default)" if default[0] else ""),
                       "membrane": membrane + (" (default)" if default[1] else ""),
                       "mesh": kind if kind in ("grid", "across", "rot45") else f"{kind} {seed}",
                       "divisions": divisions,
                       "vertices": len(uv)}
                started = time.perf_counter()
                for overhang in (1, 2, 3):
                    bend = density * G * (length / overhang) ** 3
                    with tempfile.TemporaryDirectory() as tmp:
                        model = specimen_model(uv, faces, held, {
                            "density": density, "bend": bend, "stretch": 5000.0, "shear": 50.0,
                            "damping": 0.0, "bend_model": model_name,
                            "membrane_model": membrane}, tmp)
                    try:
                        x = static_equilibrium(model)
                    except NumericalError as exc:
                        row[f"{overhang}c error"] = f"no equilibrium ({exc})"
                        continue
                    drop = -x[tip, 2].mean()
                    ref = elastica_tip_drop(length, bend, density)
                    row[f"{overhang}c error"] = f"{100 * (drop / ref - 1):+.2f} %"
                    row[f"{overhang}c drop mm"] = f"{1000 * drop:.2f}"
                row["s"] = f"{time.perf_counter() - started:.1f}"
                print("  cantilever", row, flush=True)
                rows.append(row)
    return rows


def hanging_rows():
    from clothtool.sim.solve.statics import static_equilibrium
    from clothtool.sim.textile import bias_modulus, specimen_model, strip

    length, width, density, k_u, k_v, k_h = 0.4, 0.01, 0.2, 1000.0, 3000.0, 50.0
    rows = []
    for membrane, spacing in (("triangle", 0.0025), ("triangle", 0.00125), ("nodal", 0.0025),
                              ("nodal", 0.00125)):
        uv, faces, _ = strip(length, width, spacing, "grid", clamp=False)
        top = np.flatnonzero(uv[:, 0] <= 1e-12)
        tip = np.flatnonzero(uv[:, 0] >= length - 1e-12)
        for direction, angle, k in (("warp", 0.0, k_u), ("weft", 90.0, k_v),
                                    ("bias", 45.0, bias_modulus(k_u, k_v, k_h))):
            c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))
            turn = np.array([[c, -s], [s, c]])
            with tempfile.TemporaryDirectory() as tmp:
                model = specimen_model(uv @ turn.T, faces, top, {
                    "density": density, "stretch": [k_u, k_v], "shear": k_h, "bend": 1e-6,
                    "damping": 0.0, "membrane_model": membrane}, tmp,
                    gravity=(G * c, G * s, 0.0))
            x = static_equilibrium(model)
            extension = (x[tip, :2] @ turn[:, 0]).mean() - length
            closed = density * G * length ** 2 / (2 * k)
            rows.append({"membrane": membrane, "direction": direction,
                         "spacing mm": spacing * 1000,
                         "k along the strip N/m": f"{k:.1f}",
                         "extension mm": f"{1000 * extension:.4f}",
                         "ρgL²/(2k) mm": f"{1000 * closed:.4f}",
                         "error": f"{100 * (extension / closed - 1):+.2f} %"})
            print("  hanging", rows[-1], flush=True)
    return rows


DRAPE = dict(radius=0.15, pedestal=0.09, density=0.2, bending_length=0.03, stretch=5000.0,
             shear=50.0, damping=0.05, fps=60, seconds=3.0)


def drape(kind, spacing, **material):
    """(positions, faces, drape coefficient, folds, wall s, largest speed) of the Cusick test on
    one mesh (:func:`clothtool.sim.textile.cusick_drape`); ``material``: keys that replace or
    add to DRAPE's."""
    from clothtool.sim.textile import cusick_drape, disc

    d = DRAPE
    started = time.perf_counter()
    coefficient, state, faces = cusick_drape(
        {"density": d["density"], "bending_length": d["bending_length"], "stretch": d["stretch"],
         "shear": d["shear"], "damping": d["damping"], **material},
        spacing, kind, seconds=d["seconds"], fps=d["fps"])
    wall = time.perf_counter() - started
    uv, _ = disc(d["radius"], spacing, kind, seed=1)
    r, phi = np.hypot(uv[:, 0], uv[:, 1]), np.arctan2(uv[:, 1], uv[:, 0])
    rim = np.flatnonzero(r >= d["radius"] - 1e-9)
    order = np.argsort(phi[rim])
    reach = np.hypot(state.x[rim, 0], state.x[rim, 1])[order]
    folds = int(np.sum((reach > np.roll(reach, 1)) & (reach >= np.roll(reach, -1))
                       & (reach > np.median(reach))))
    return state.x, faces, coefficient, folds, wall, float(np.abs(state.v).max())


def drape_rows(out_dir):
    rows, shown = [], {}
    for membrane in DRAPE_MEMBRANES:  # compile the kernels
        drape("grid", 0.02, bend_model="hessian", membrane_model=membrane)
    for membrane in DRAPE_MEMBRANES:
        for spacing in DRAPE_SPACINGS:
            for kind in ("grid", "rot45", "delaunay"):
                x, faces, dc, folds, wall, speed = drape(kind, spacing, bend_model="hessian",
                                                         membrane_model=membrane)
                rows.append({"membrane": membrane, "mesh": kind, "spacing mm": spacing * 1000,
                             "vertices": len(x), "drape coefficient": f"{dc:.4f}",
                             "folds": folds, "largest speed at the end mm/s": f"{1000 * speed:.2f}",
                             "wall s": f"{wall:.1f}"})
                print("  drape", rows[-1], flush=True)
                if spacing == DRAPE_SPACINGS[-1]:
                    shown[(membrane, kind)] = (x, faces, dc)
    for membrane in DRAPE_MEMBRANES:
        mine = [r for r in rows if r.get("membrane") == membrane and "vertices" in r]
        for spacing in DRAPE_SPACINGS:
            values = [float(r["drape coefficient"]) for r in mine
                      if r["spacing mm"] == spacing * 1000]
            spread = 100 * (max(values) - min(values)) / np.mean(values)
            rows.append({"membrane": membrane, "mesh": "spread (max − min)/mean",
                         "spacing mm": spacing * 1000, "drape coefficient": f"{spread:.2f} %"})
        for kind in ("grid", "rot45", "delaunay") if len(DRAPE_SPACINGS) > 1 else ():
            values = [float(r["drape coefficient"]) for r in mine if r["mesh"] == kind]
            a, b = (1000 * s for s in DRAPE_SPACINGS)
            rows.append({"membrane": membrane, "mesh": f"{kind}: {a:g} → {b:g} mm",
                         "drape coefficient": f"{100 * (values[1] / values[0] - 1):+.2f} %"})
    _plot_drape(shown, out_dir / "textile_drape.png")
    return rows


def _plot_drape(shown, path):
    plt = pyplot("drape picture")
    if plt is None:
        return
    fig = plt.figure(figsize=(12, 8.4))
    for k, ((membrane, kind), (x, faces, dc)) in enumerate(shown.items()):
        ax = fig.add_subplot(2, 3, k + 1, projection="3d")
        ax.plot_trisurf(x[:, 0], x[:, 1], x[:, 2], triangles=faces, cmap="viridis",
                        linewidth=0.1, edgecolor=(0, 0, 0, 0.15))
        ax.set_title(f"{membrane} membrane, {kind}\ndrape coefficient {dc:.3f}")
        ax.set_box_aspect((1, 1, 0.5))
        ax.view_init(elev=35, azim=30)
        ax.set_axis_off()
    fig.suptitle("Cusick drape, 30 cm disc on an 18 cm pedestal, c = 3 cm, "
                 f"{1000 * DRAPE_SPACINGS[-1]:g} mm spacing")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


COST_SCRIPT = r"""
import sys, time, statistics
sys.path.insert(0, sys.argv[1])
IMPORTS
bend, frames, bend_model = float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
overrides = {"mesh.grid.nx": 64, "mesh.grid.ny": 64, "material.bend": bend,
             "material.bend_model": bend_model}
if len(sys.argv) > 5:
    overrides["material.membrane_model"] = sys.argv[5]
cfg = load_config(sys.argv[1] + "/sample_data/hanging_sheet.yaml", overrides=overrides)
model = build_model(cfg)
integ = make_integrator(model, cfg.solver, cfg.step)
state = model.initial_state()
integ.step(state)
cpu, newton, cg = [], 0, 0
for _ in range(frames):
    t0 = time.process_time()
    r = integ.step(state)
    cpu.append(time.process_time() - t0)
    newton += r.newton_iterations
    cg += r.cg_iterations
print(1000 * statistics.median(cpu), newton / frames, cg / frames, model.pattern.nnzb)
"""


def cost_script(root):
    """COST_SCRIPT with the imports of the checkout at ``root``."""
    return COST_SCRIPT.replace("IMPORTS\n", sim_imports(root))


def cost_rows(repeat=COST_REPEAT, frames=20):
    if not BASE.exists():
        subprocess.run(["git", "clone", "-q", str(HERE), str(BASE)], check=True)
        subprocess.run(["git", "-C", str(BASE), "checkout", "-q", BASE_COMMIT], check=True)
    runs = {}
    for _ in range(repeat):  # alternate so that the machine's load falls on both alike
        for label, root, bend_model in (("before (dihedral, 1e6cea5)", BASE, "dihedral"),
                                        ("after (hessian)", HERE, "hessian")):
            for bend in (1e-5, 0.0):
                out = subprocess.run([sys.executable, "-c", cost_script(root), str(root),
                                      str(bend), str(frames), bend_model], capture_output=True, text=True,
                                     check=True,
                                     cwd=root, env={**os.environ, "PYTHONPATH": str(root)})
                ms, newton, cg, nnzb = out.stdout.split()
                runs.setdefault((label, bend), []).append((float(ms), float(newton), float(cg),
                                                           int(nnzb)))
    rows = []
    share = {}
    for label in ("before (dihedral, 1e6cea5)", "after (hessian)"):
        on = runs[(label, 1e-5)]
        off = runs[(label, 0.0)]
        ms_on = statistics.median(r[0] for r in on)
        ms_off = statistics.median(r[0] for r in off)
        share[label] = ms_on - ms_off
        rows.append({"checkout": label, "ms/step with bending": f"{ms_on:.1f}",
                     "ms/step with bend 0": f"{ms_off:.1f}",
                     "bending's share ms/step": f"{ms_on - ms_off:.1f}",
                     "Newton/step": f"{on[0][1]:.2f}", "PCG/step": f"{on[0][2]:.1f}",
                     "matrix blocks": on[0][3]})
    ratio = share["after (hessian)"] / share["before (dihedral, 1e6cea5)"]
    rows.append({"checkout": "after / before", "bending's share ms/step": f"{ratio:.2f}×"})
    return rows


def membrane_cost_rows(repeat=COST_REPEAT, frames=20):
    """ms/step of the 64×64 hanging sheet (hessian bending) with each membrane model,
    alternating in one run."""
    runs = {}
    for _ in range(repeat):
        for membrane in ("triangle", "nodal"):
            out = subprocess.run([sys.executable, "-c", cost_script(HERE), str(HERE), "1e-5",
                                  str(frames), "hessian", membrane], capture_output=True,
                                 text=True, check=True, cwd=HERE,
                                 env={**os.environ, "PYTHONPATH": str(HERE)})
            ms, newton, cg, nnzb = out.stdout.split()
            runs.setdefault(membrane, []).append((float(ms), float(newton), float(cg), int(nnzb)))
    rows = []
    for membrane, r in runs.items():
        rows.append({"membrane": membrane, "ms/step": f"{statistics.median(x[0] for x in r):.1f}",
                     "Newton/step": f"{r[0][1]:.2f}", "PCG/step": f"{r[0][2]:.1f}",
                     "matrix blocks": r[0][3]})
    ratio = (statistics.median(x[0] for x in runs["nodal"])
             / statistics.median(x[0] for x in runs["triangle"]))
    rows.append({"membrane": "nodal / triangle", "ms/step": f"{ratio:.2f}×"})
    print("  membrane cost", rows, flush=True)
    return rows


def run(out_dir):
    out_dir = Path(out_dir)
    sections, tables = [], []
    started = time.perf_counter()
    if FULL:  # each cost run a process of its own, the commit before the plate in a clone
        cost = cost_rows()
        sections.append("### Cost: 64×64 hanging sheet, one step per frame\n\nCPU ms per step "
                        f"(median of 20 steps, {COST_REPEAT} alternating run(s) each; bending's "
                        "share = with − without bending):\n\n" + markdown_table(cost, list(cost[0])))
        membrane_cost = membrane_cost_rows()
        sections.append("### Cost of the membrane models: 64×64 hanging sheet, hessian bending"
                        f"\n\nCPU ms per step (median of 20 steps, {COST_REPEAT} alternating run(s) "
                        "each):\n\n" + markdown_table(membrane_cost, list(membrane_cost[0])))
        tables += [("textile-cost", cost, list(cost[0])),
                   ("textile-membrane-cost", membrane_cost, list(membrane_cost[0]))]
    else:
        sections.append("### Cost\n\nBending's and the membrane models' cost on the 64×64 "
                        "hanging sheet: `python -m benchmarks --full textile`.\n")
    cant = cantilever_rows()
    sections.append("### Cantilever (ASTM D1388) against the elastica\n\n0.1 m × 25 mm strip, "
                    "0.2 kg/m², stretch 5000 N/m, shear 50 N/m, bending length 0.1/n m for an "
                    "overhang of nc; clamp line halfway between the two pinned rows.\n\n"
                    + markdown_table(cant, list(cant[0])))
    hang = hanging_rows()
    sections.append("### Hanging strip along warp, weft and bias\n\n0.4 m × 10 mm, 0.2 kg/m², "
                    "stretch [1000, 3000] N/m, shear 50 N/m, top edge pinned.\n\n"
                    + markdown_table(hang, list(hang[0])))
    dr = drape_rows(out_dir)
    cols = ["membrane", "mesh", "spacing mm", "vertices", "drape coefficient", "folds",
            "largest speed at the end mm/s", "wall s"]
    sections.append("### Cusick drape (BS 5058)\n\n30 cm disc, 18 cm pedestal, 0.2 kg/m², "
                    "hessian bending, bending length 3 cm, stretch 5000 N/m, shear 50 N/m, "
                    "damping 0.05 s, 3 s at 60 fps (implicit, BDF2); picture: textile_drape.png.\n\n"
                    + markdown_table(dr, cols))
    text = "## Textile tests\n\n`python -m benchmarks textile`\n\n" + "\n".join(sections)
    (out_dir / "textile.md").write_text(text)
    tables += [("textile-cantilever", cant, list(cant[0])),
               ("textile-hanging", hang, list(hang[0])),
               ("textile-drape", dr, cols)]
    for name, rows, columns in tables:
        write_doc_table("docs/simulate.md", name, markdown_table(rows, columns), "textile",
                        full_only=name in ("textile-cantilever", "textile-drape"))
    print(f"  textile benchmark in {time.perf_counter() - started:.0f} s")
