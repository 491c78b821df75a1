"""What ``clothtool fit`` writes and says: ``fit.yaml`` (the config with the fitted values,
ready for ``clothtool simulate``), ``fit.csv`` (a row per simulation), ``fit.png`` (the
distance per frame at the start and at the fit, and the path through the values), the report,
and with ``--compare-strain`` the per-triangle stretches of the capture and of the fit."""

import csv
import io
import math

import numpy as np

from clothtool.sweeps.layout import format_value, write_text

OUTPUT_DIR = "simulated"  # fit.yaml's output.dir, beside it
Z95 = 1.96  # the report's ± is the 95 % interval of the values (1.96 σ)


def write_all(result, problem, evals, best, iterates):
    """fit.yaml, fit.csv and fit.png into the fit's folder; returns the paths written."""
    written = [write_yaml(result.output_dir, problem, best), write_csv(result.output_dir,
                                                                      problem, evals)]
    try:
        written.append(write_png(result.output_dir, problem, evals, best, iterates))
    except ImportError:  # matplotlib is an optional extra: the fit stands without its picture
        pass
    return written


def write_yaml(root, problem, best):
    import copy

    import yaml

    from clothtool.config_tools import assign
    from clothtool.sweeps.api import _with_resolved_paths

    raw = copy.deepcopy(problem.raw)
    for key, value in zip(problem.keys, problem.values(best)):
        assign(raw, key.split("."), value, key)
    raw = _with_resolved_paths(raw, problem.config)
    if not isinstance(raw.get("output"), dict):
        raw["output"] = {}
    raw["output"]["dir"] = OUTPUT_DIR
    fitted = ", ".join(f"{k}={format_value(v)}" for k, v in zip(problem.keys, problem.values(best)))
    path = root / "fit.yaml"
    write_text(path, f"# clothtool fit: {problem.base} with {fitted}\n"
                     f"# clothtool simulate {path} writes its frames to {root / OUTPUT_DIR}/\n"
                     + yaml.safe_dump(raw, sort_keys=False))
    return path


def write_csv(root, problem, evals):
    """fit.csv: simulation, round, run, the values, status, RMS and largest distance (m),
    seconds."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["simulation", "round", "run", *problem.keys, "status", "rms_m", "largest_m",
                     "seconds", "error"])
    for i, row in enumerate(evals.rows):
        writer.writerow([i, row["round"], row["run"], *(format_value(v) for v in row["values"]),
                         row["status"], _number(row.get("rms")), _number(row.get("largest")),
                         _number(row.get("seconds")), row["error"]])
    path = root / "fit.csv"
    write_text(path, buf.getvalue())
    return path


def _number(value):
    return "" if value is None else f"{value:.6g}"


def write_png(root, problem, evals, best, iterates):
    """fit.png: RMS distance per frame at the start and at the fit; the values of the
    iterations (two values: their plane, every simulation a dot)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from clothtool.io.atomic import atomic_path

    capture = problem.capture
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    frames = np.arange(1, len(capture.frames))
    for u, label, style in ((evals.start, "start", "--"), (best, "fit", "-")):
        d = capture.distances(evals.residual(u))
        left.plot(frames, 1000 * np.sqrt(np.mean(d ** 2, axis=1)), style,
                  label=f"{label}: {problem.shown(u)}")
    left.set_xlabel("frame")
    left.set_ylabel("RMS distance to the capture (mm)")
    left.set_yscale("log")
    left.legend(fontsize=7)
    path = [evals.start, *iterates]
    if best is not None and (not iterates or not np.allclose(iterates[-1], best)):
        path.append(best)
    values = np.array([problem.values(u) for u in path])
    tried = np.array([row["values"] for row in evals.rows])
    if len(problem.keys) == 2:
        right.scatter(tried[:, 0], tried[:, 1], s=8, color="0.6", label="simulations")
        right.plot(values[:, 0], values[:, 1], "o-", label="iterations")
        right.set_xlabel(problem.keys[0])
        right.set_ylabel(problem.keys[1])
        for axis, p in zip((right.xaxis, right.yaxis), problem.parameters):
            if p.log:
                (right.set_xscale if axis is right.xaxis else right.set_yscale)("log")
    else:
        for i, key in enumerate(problem.keys):
            right.plot(np.arange(len(values)), values[:, i] / values[-1, i], "o-", label=key)
        right.set_xlabel("iteration")
        right.set_ylabel("value / fitted value")
        right.set_yscale("log")
    right.legend(fontsize=7)
    right.set_title("path through the values")
    fig.tight_layout()
    out = root / "fit.png"
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return out


def describe(result):
    """The report: fitted values with their uncertainty, distances, what the capture does not
    pin down, the files."""
    if result.sbatch is not None:
        lines = [f"{result.output_dir}/: {result.simulations} simulations so far in "
                 f"{result.rounds} rounds; the next round waits for Slurm: submit it with",
                 f"  {result.sbatch}", "then rerun this command once the array has ended"]
        return "\n".join(lines)
    width = max(len(k) for k in result.values)
    lines = ["fitted" + (" (compared vertex for vertex" if result.mode == "vertex" else
                         " (compared surface to surface") + "; ± at 95 %):"]
    for p in result.parameters:
        value = result.values[p.key]
        spread = f"± {_spread(result, p.key)}"
        note = "  (not pinned down by the capture)" if p.key in result.loose else ""
        lines.append(f"  {p.key:<{width}} = {value:<11.5g} {spread:<10} start "
                     f"{p.start:.4g}{note}")
    lines.append(f"distance to the capture: RMS {_mm(result.rms)} (start {_mm(result.start_rms)}), "
                 f"largest {_mm(result.largest)}, over {result.frames} frames × {result.points} "
                 f"vertices; {_mm(result.systematic)} of it systematic (the same from frame to "
                 "frame), which the ± does not include")
    for keys, effect in result.tied:
        lines.append(f"  {' and '.join(keys)} are told apart only in combination by this "
                     f"capture (changing them together as it allows moves the sequence "
                     f"{_mm(effect)} RMS per doubling): hold all but one with --set")
    for key in result.loose:
        lines.append(f"  {key}: not pinned down by this capture: ± {_spread(result, key)}; "
                     f"doubling it moves the sequence {_mm(result.doubling[key])} RMS against "
                     f"{_mm(result.systematic)} the fit leaves systematically")
    lines.append(f"{result.simulations} simulations in {result.rounds} rounds, "
                 f"{result.seconds:.1f} s" + (f"; {result.stopped}" if result.stopped else ""))
    if result.strain:
        lines.append(result.strain["line"])
    if result.written:
        lines.append("wrote " + ", ".join(str(p) for p in result.written))
    return "\n".join(lines)


def _spread(result, key):
    """The 95 % interval's half width: 1.96 σ, relative for a log range."""
    p = next(p for p in result.parameters if p.key == key)
    half = Z95 * result.sigma.get(key, float("nan"))
    return f"{100 * half:.2g} %" if p.log else f"{half:.2g}"


def _mm(metres):
    return "—" if metres is None or math.isnan(metres) else f"{1000 * metres:.3g} mm"


def compare_strains(capture, run_dir, root):
    """Analyse the capture and the fitted simulation (each against its first frame) into
    ``root/strain/``; the per-triangle difference of λ1 and λ2 (vertex for vertex), or of their
    percentiles (surface to surface)."""
    import h5py

    from clothtool.analysis.sequence import analyze_sequence

    folder = root / "strain"
    folder.mkdir(exist_ok=True)
    stretches = {}
    for name, frames in (("capture", [str(p) for p in capture.paths]), ("fit", str(run_dir))):
        out = folder / f"{name}.h5"
        analyze_sequence(frames, str(out), reference="first", fields="stretch", progress=False,
                         command=f"clothtool fit --compare-strain ({name})")
        with h5py.File(out, "r") as h5:
            stretches[name] = np.asarray(h5["face/stretch"][()], float)
    a, b = stretches["capture"], stretches["fit"]
    q = (50, 95, 100)
    if capture.mode == "vertex":
        diff = np.abs(a - b)
        pct = {f"lambda{c + 1}": np.percentile(diff[..., c], q) for c in range(2)}
        line = ("stretch, fit − capture per triangle (|Δλ|, median / 95th / largest): " + "; ".join(
            f"{k} {v[0]:.2e} / {v[1]:.2e} / {v[2]:.2e}" for k, v in pct.items()))
    else:
        q = (5, 50, 95)
        pct = {f"lambda{c + 1}": np.percentile(b[..., c], q) - np.percentile(a[..., c], q)
               for c in range(2)}
        line = ("stretch percentiles, fit − capture (5th / median / 95th, other meshes): " + "; ".join(
            f"{k} {v[0]:+.2e} / {v[1]:+.2e} / {v[2]:+.2e}" for k, v in pct.items()))
    return {"percentiles": {k: v.tolist() for k, v in pct.items()}, "line": line}
