"""``clothtool fit`` on captures with known answers, and on a peer's sequence.

    python -m benchmarks fit          (not in the default make bench: about 10 minutes of CPU)

- ``strip``: the bundled capture (sample_data/strip/capture: a 10 cm strip clamped at one end,
  falling from horizontal, simulated at bend 1e-4 N·m and damping 0.02 s, 0.3 mm of noise on
  every coordinate), fitted from sample_data/strip.yaml's values three times off, vertex for
  vertex; and by Nelder–Mead on the same residual (the method the fit does not use);
- ``strip-delaunay``: the same capture fitted on Delaunay strips of 5, 3.5 and 2.5 mm (surface to
  surface: no correspondence), and the same fits to the capture without its noise, whose error
  is the discretisation's own bias (the two meshes' strips bend differently); and on a 2.5 mm
  grid, where the noiseless capture's error is the bias of the capture's own 5 mm grid;
- ``hanging-sheet``: a 0.6 m sheet held at two corners, falling from horizontal (frozen
  damping, as the strip's), 0.3 mm of noise:
  stretch, bend and damping at once (a stiff fabric, bend 1e-4 N·m) from three times off, over
  SEEDS noise draws; and stretch and bend of the sample's limp fabric (bend 1e-5), where
  doubling the bending moves the sequence a fraction of a millimetre;
- ``blender-sheet``: Blender's own cloth (bpy, its defaults) on bench_peers' sheet (24 × 24,
  1.1 m, two corners, 2 s) fitted with our stretch, bend and damping: the RMS distance before and
  after, and what the fit says it cannot pin down. Needs bpy (bench_peers: BPY_PYTHON or
  .venv-bpy).

Each fit runs in this process (jobs=1), so its CPU time is the process's. Tables: docs/simulate.md
(fit, fit-methods, fit-mesh, fit-peer) and bench-results/fit.md.
"""

import importlib.util
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import ROOT, markdown_table, write_doc_table

SCENES = ("strip", "strip-delaunay", "hanging-sheet", "blender-sheet")
STRIP_RANGES = ["material.bend=1e-6:1e-3:log", "material.damping=1e-3:0.1:log"]
SHEET_RANGES = ["material.stretch=500:50000:log", "material.bend=1e-6:1e-3:log",
                "material.damping=1e-3:0.3:log"]
SEEDS = (1, 2, 3, 4, 5, 6)
SPACINGS = (0.005, 0.0035, 0.0025)  # the Delaunay strips
FINE_GRID = 0.0025  # and a finer grid than the capture's, for the capture's own bias
NOISE = 3.0e-4
Z95 = 1.96


def strip_script():
    spec = importlib.util.spec_from_file_location("make_strip_capture",
                                                  Path(ROOT) / "scripts" / "make_strip_capture.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def timed_fit(*args, **kwargs):
    import clothtool

    started = time.process_time()
    result = clothtool.fit(*args, **kwargs)
    return result, time.process_time() - started


def value_rows(case, scene, result, cpu, true, start):
    rows = []
    for key, value in result.values.items():
        error = math.log(value / true[key])
        half = Z95 * result.sigma[key]
        note = []
        if key in result.loose:
            note.append("not pinned down")
        note += [f"tied with {', '.join(k for k in keys if k != key)}" for keys, _ in result.tied
                 if key in keys]
        rows.append({"case": case, "scene": scene, "compared": result.mode, "key": f"`{key}`",
                     "true": f"{true[key]:.4g}", "start": f"{start[key]:.4g}",
                     "fitted": f"{value:.5g}", "error %": f"{100 * (value / true[key] - 1):+.2f}",
                     "± 95 %": f"{100 * half:.2f}", "covered": "yes" if abs(error) <= half else "no",
                     "simulations": result.simulations, "CPU s": f"{cpu:.1f}",
                     "RMS start → fit mm": f"{1e3 * result.start_rms:.3g} → {1e3 * result.rms:.3g}",
                     "systematic mm": f"{1e3 * result.systematic:.2g}",
                     "doubling moves mm": f"{1e3 * result.doubling[key]:.3g}",
                     "note": "; ".join(note)})
    return rows


def strip_rows(tmp, script, findings):
    config = Path(ROOT) / "sample_data" / "strip.yaml"
    capture = Path(ROOT) / "sample_data" / "strip" / "capture"
    true = {f"material.{k}": v for k, v in script.TRUE.items()}
    start = {f"material.{k}": v for k, v in script.GUESS.items()}
    result, cpu = timed_fit(config, capture, STRIP_RANGES, tmp / "strip")
    print(f"  strip: {result.simulations} simulations, {cpu:.1f} s CPU")
    methods = [method_row("trust-region least squares (clothtool fit)", tmp / "strip", true,
                          result.simulations)]
    methods.append(nelder_mead_row(config, capture, true, start))
    err = {k.split(".")[1]: 100 * (result.values[k] / true[k] - 1) for k in true}
    half = {k.split(".")[1]: 100 * Z95 * result.sigma[k] for k in true}
    findings.append(
        f"- `strip`: from three times off, the bending comes back {err['bend']:+.2f} % and the "
        f"damping {err['damping']:+.2f} % off their true values in {result.simulations} "
        f"simulations ({cpu:.1f} s of CPU); the capture's 0.3 mm of noise leaves "
        f"± {half['bend']:.2f} % and ± {half['damping']:.2f} % (95 %). The trust region is within "
        f"2 % / 5 % after {methods[0]['first within 2 % / 5 % (simulation)']} simulations, "
        f"Nelder–Mead after {methods[1]['first within 2 % / 5 % (simulation)']} "
        f"(it stops after {methods[1]['simulations']}).")
    return value_rows("strip, 2 values", "strip", result, cpu, true, start), methods


def method_row(name, folder, true, simulations):
    import csv

    with open(folder / "fit.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    errors = [(abs(float(r["material.bend"]) / true["material.bend"] - 1),
               abs(float(r["material.damping"]) / true["material.damping"] - 1), float(r["rms_m"]))
              for r in rows]
    return _method(name, errors, simulations)


def _method(name, errors, simulations):
    within = next((i + 1 for i, (b, d, _) in enumerate(errors) if b < 0.02 and d < 0.05), None)
    best = min(errors, key=lambda e: e[2])
    return {"optimiser": name, "simulations": simulations,
            "first within 2 % / 5 % (simulation)": within or "never",
            "bend error % at the end": f"{100 * best[0]:.2f}",
            "damping error % at the end": f"{100 * best[1]:.2f}"}


def nelder_mead_row(config, capture_dir, true, start):
    """scipy's Nelder–Mead on ½‖r‖² in the same log coordinates, from the same start, to the
    same precision in the values (xatol 1e-3 of the log ranges; fatol 1e-7 m², a 1e-4 share of
    the cost the noise leaves), each evaluation a simulation."""
    from scipy.optimize import minimize

    import clothtool
    from clothtool.io.frames import discover_frames, read_mesh
    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.mesh import build_rest_mesh
    from clothtool.sweeps.capture import read_capture

    loaded = load_config(config)
    mesh = build_rest_mesh(loaded.mesh)
    capture = read_capture(capture_dir, loaded.time.frames + 1, mesh.positions, mesh.faces)
    lo, hi = np.array([1e-6, 1e-3]), np.array([1e-3, 0.1])
    keys = list(true)
    errors = []

    def cost(u):
        v = lo * np.exp(np.clip(u, 0.0, 1.0) * np.log(hi / lo))
        with tempfile.TemporaryDirectory() as tmp:
            clothtool.simulate(config, output_dir=tmp, progress=False,
                               overrides=[f"{k}={x}" for k, x in zip(keys, v)])
            x = np.stack([read_mesh(p).vertices for p in discover_frames(tmp)])
        r = capture.residual(x, mesh.faces)
        errors.append((abs(v[0] / true[keys[0]] - 1), abs(v[1] / true[keys[1]] - 1), float(r @ r)))
        return 0.5 * float(r @ r)

    u0 = np.log(np.array([start[k] for k in keys]) / lo) / np.log(hi / lo)
    minimize(cost, u0, method="Nelder-Mead",
             options={"xatol": 1e-3, "fatol": 1e-7, "maxfev": 200,
                      "initial_simplex": [u0, u0 + [0.05, 0.0], u0 + [0.0, 0.05]]})
    print(f"  Nelder–Mead: {len(errors)} simulations")
    return _method("Nelder–Mead (scipy), same start and coordinates", errors, len(errors))


def mesh_rows(tmp, script, findings):
    """The strip's capture on Delaunay strips: its noisy and its clean version."""
    clean = script.write_capture(Path(ROOT) / "sample_data" / "strip.yaml", tmp / "clean",
                                 script.TRUE, noise=0.0)
    noisy = Path(ROOT) / "sample_data" / "strip" / "capture"
    true = {f"material.{k}": v for k, v in script.TRUE.items()}
    rows = []
    for kind, spacing in [("delaunay", s) for s in SPACINGS] + [("grid", FINE_GRID)]:
        name = f"strip_{kind[0]}{round(spacing * 10000)}"
        config = script.write_scene(tmp, name, kind, spacing)
        row = {"scene": "strip-delaunay",
               "fit's mesh": f"{'Delaunay' if kind == 'delaunay' else 'grid'}, {1000 * spacing:g} mm"}
        for label, capture in (("bias (capture without noise)", clean), ("capture", noisy)):
            result, cpu = timed_fit(config, capture, STRIP_RANGES, tmp / f"{name}_{label[:4]}")
            errors = {k.split(".")[1]: 100 * (result.values[k] / true[k] - 1) for k in true}
            row["vertices"] = _vertices(config)
            row[f"{label}: bend %"] = f"{errors['bend']:+.1f}"
            row[f"{label}: damping %"] = f"{errors['damping']:+.2f}"
            if label == "capture":
                row["within 15 %"] = "yes" if max(map(abs, errors.values())) <= 15 else "no"
                row["simulations"] = result.simulations
                row["RMS fit mm"] = f"{1e3 * result.rms:.3g}"
                row["± 95 % bend"] = f"{100 * Z95 * result.sigma['material.bend']:.2f}"
        print(f"  {name}: {row}")
        rows.append(row)
    delaunay, fine = rows[:-1], rows[-1]
    stiffer = float(fine["bias (capture without noise): bend %"]) > 0
    findings.append(
        "- `strip-delaunay`: the same capture on Delaunay strips of "
        + ", ".join(f"{1000 * s:g}" for s in SPACINGS) + " mm: bending "
        + ", ".join(f"{r['capture: bend %']} %" for r in delaunay) + "; the noiseless capture's, "
        "the meshes' own bias: " + ", ".join(f"{r['bias (capture without noise): bend %']} %"
                                            for r in delaunay)
        + f". On a {1000 * FINE_GRID:g} mm grid the noiseless capture's bending comes out "
        f"{fine['bias (capture without noise): bend %']} %: the capture's own "
        f"{1000 * script.SPACING:g} mm grid moves as a finer mesh does with that much "
        f"{'more' if stiffer else 'less'} bending (it is that much "
        f"{'stiffer' if stiffer else 'softer'}).")
    return rows


def _vertices(config):
    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.mesh import build_rest_mesh

    return len(build_rest_mesh(load_config(config).mesh).positions)


def sheet_config(folder, bend, values, n=16):
    import yaml

    config = {"mesh": {"grid": {"nx": n, "ny": n, "width": 0.6, "height": 0.6, "plane": "xz"}},
              # frozen βK damping, as the strip sample's: the default strain damping leaves the
              # sheet's swing about its pins undamped, a pendulum whose sequence a 2 % change
              # of bending moves by a centimetre within 2 s
              "material": {"density": 0.2, "stretch": values["material.stretch"], "shear": 50.0,
                           "bend": values["material.bend"], "damping": values["material.damping"],
                           "damping_model": "frozen"},
              "scene": {"gravity": [0.0, -9.81, 0.0], "pins": ["top_corners"]},
              "time": {"fps": 30, "frames": 60}, "output": {"dir": "out"}}
    path = Path(folder) / f"sheet_{bend:g}_{n}.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return path


def sheet_rows(tmp, script, findings):
    rows, z = [], []
    true = {"material.stretch": 5000.0, "material.bend": 1e-4, "material.damping": 0.02}
    start = {"material.stretch": 15000.0, "material.bend": 1e-4 / 3, "material.damping": 0.06}
    truth = sheet_config(tmp, 1e-4, true)
    (tmp / "start").mkdir()
    config = sheet_config(tmp / "start", 1e-4, start)
    for seed in SEEDS:
        capture = script.write_capture(truth, tmp / f"sheet_{seed}", {}, seed=seed)
        result, cpu = timed_fit(config, capture, SHEET_RANGES, tmp / f"sheet_fit_{seed}")
        print(f"  hanging sheet, seed {seed}: {result.simulations} simulations, {cpu:.1f} s CPU")
        rows += value_rows(f"hanging sheet, 3 values, noise seed {seed}", "hanging-sheet", result,
                           cpu, true, start)
        z += [math.log(result.values[k] / true[k]) / result.sigma[k] for k in true]
    worst = max(abs(float(r["error %"])) for r in rows)
    findings.append(
        f"- `hanging-sheet`, stretch, bend and damping at once over {len(SEEDS)} noise draws: the "
        f"largest error {worst:.2f} %; the errors over their σ have an RMS of "
        f"{math.sqrt(np.mean(np.square(z))):.2f} (1 for a calibrated σ), and "
        f"{sum(abs(v) <= Z95 for v in z)} of the {len(z)} lie within their 95 % interval.")
    # the sample's limp fabric: stretch and bend only
    true = {"material.stretch": 5000.0, "material.bend": 1e-5, "material.damping": 0.01}
    start = {"material.stretch": 10000.0, "material.bend": 2e-5, "material.damping": 0.01}
    truth = sheet_config(tmp, 1e-5, true)
    (tmp / "limp").mkdir()
    config = sheet_config(tmp / "limp", 1e-5, start)
    capture = script.write_capture(truth, tmp / "sheet_limp", {})
    result, cpu = timed_fit(config, capture, SHEET_RANGES[:2], tmp / "sheet_limp_fit")
    rows += value_rows("hanging sheet, bend 1e-5, 2 values", "hanging-sheet", result, cpu, true,
                       start)
    white = result
    # the same sheet captured on a finer mesh: a difference the 16 × 16 mesh keeps
    capture = script.write_capture(sheet_config(tmp, 1e-5, true, n=24), tmp / "sheet_limp_24", {})
    result, cpu = timed_fit(config, capture, SHEET_RANGES[:2], tmp / "sheet_limp_24_fit")
    rows += value_rows("hanging sheet, bend 1e-5, 2 values, capture on a 24 × 24 mesh",
                       "hanging-sheet", result, cpu, true, start)
    bend = "material.bend"
    findings.append(
        f"- `hanging-sheet` with a limp fabric (bend 1e-5 N·m): doubling the bending moves the "
        f"vertices {1e3 * white.doubling[bend]:.2f} mm RMS, a tenth more stretch "
        f"{1e3 * white.doubling['material.stretch'] * math.log(1.1) / math.log(2):.1f} mm. From "
        f"white noise the bending comes back {100 * (white.values[bend] / true[bend] - 1):+.2f} % "
        f"(± {100 * Z95 * white.sigma[bend]:.1f} %); from a capture on a 24 × 24 mesh, "
        f"{1e3 * result.systematic:.2f} mm of it systematic, "
        f"{100 * (result.values[bend] / true[bend] - 1):+.0f} %, and the fit says "
        + ("it is not pinned down." if bend in result.loose else "nothing of it."))
    return rows


def blender_rows(tmp, findings):
    import yaml

    from benchmarks.bench_peers import BLENDER_INSTALL, peer_python, run_peer, scene
    from clothtool.io.ply import write_ply

    python = peer_python("BPY_PYTHON", ".venv-bpy")
    if python is None:
        return [{"scene": "blender-sheet", "note": f"bpy not installed: {BLENDER_INSTALL}"}]
    config, arrays = scene("sheet", n=24, frames=60)
    config["output"] = {"dir": "out"}
    config["material"]["damping_model"] = "frozen"  # as the hanging sheet's (sheet_config)
    peer = run_peer(python, Path(ROOT) / "benchmarks" / "peer_blender.py", arrays, tmp)
    capture = tmp / "blender"
    capture.mkdir()
    for k, x in enumerate(peer["positions"]):  # Blender's vertices are ours: compared one to one
        write_ply(capture / f"frame_{k:05d}.ply", x, arrays["faces"])
    path = tmp / "blender_sheet.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    ranges = ["material.stretch=10:1e6:log", "material.bend=1e-8:1e-2:log",
              "material.damping=1e-4:1:log"]
    result, cpu = timed_fit(path, capture, ranges, tmp / "blender_fit", max_simulations=80)
    print(f"  blender sheet: {result.describe()}")
    row = {"scene": "blender-sheet", "Blender CPU s": f"{float(peer['cpu']):.2f}",
           "RMS before → after mm": f"{1e3 * result.start_rms:.3g} → {1e3 * result.rms:.3g}",
           "largest after mm": f"{1e3 * result.largest:.3g}",
           "systematic mm": f"{1e3 * result.systematic:.3g}"}
    for key, value in result.values.items():
        row[f"`{key}`"] = f"{value:.4g} (start {config['material'][key.split('.')[1]]:g})"
    row["not pinned down"] = ", ".join(f"`{k}`" for k in result.loose) or "—"
    row["simulations"] = result.simulations
    row["CPU s"] = f"{cpu:.1f}"
    findings.append(
        f"- `blender-sheet`: the RMS distance to Blender's sheet falls from "
        f"{1e3 * result.start_rms:.0f} to {1e3 * result.rms:.0f} mm, {1e3 * result.systematic:.0f} mm "
        "of it systematic: our material cannot make our sheet move as Blender's does, and the fit "
        "says which values that leaves unpinned (" + (", ".join(f"`{k}`" for k in result.loose)
                                                      or "none") + ").")
    return [row]


def run(out_dir):
    script = strip_script()
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        findings = []
        values, methods = strip_rows(tmp, script, findings)
        mesh = mesh_rows(tmp, script, findings)
        values += sheet_rows(tmp, script, findings)
        peer = blender_rows(tmp, findings)
    write_doc_table("docs/simulate.md", "fit-findings", "\n".join(findings), "fit")
    tables = {"fit": values, "fit-methods": methods, "fit-mesh": mesh, "fit-peer": peer}
    text = "## clothtool fit\n\n" + "\n".join(findings) + "\n\n"
    for name, rows in tables.items():
        table = markdown_table(rows, list(dict.fromkeys(k for r in rows for k in r)))
        write_doc_table("docs/simulate.md", name, table, "fit")
        text += f"### {name}\n\n{table}\n"
    (out_dir / "fit.md").write_text(text)
    print(f"  fit benchmark in {time.perf_counter() - started:.0f} s")
