"""``clothtool sweep-report``: one table of a sweep's runs, the per-frame series beside it,
and plots of any metric against any parameter.

``report.csv``, one row per run: ``run``, the parameters, ``status``, ``error``, ``seconds``
(the run's wall time), and for each done run, from its ``stats.csv``: ``frames`` written,
``ms_per_frame`` (median wall time of a simulated frame), ``max_stretch`` (largest over the
frames), ``kinetic``, ``elastic``, ``gravity`` (the last frame's energies, J) and
``min_separation`` (smallest over the frames, m; NaN without contact); with ``--analyze``,
from its ``analysis.h5`` ``/summary``: the last frame's percentiles ``final_lambda1_p5`` …
``final_area_ratio_p95``, and over all frames ``max_lambda1_p95`` and ``min_lambda2_p5``.

``report.h5``: ``/table/<column>`` (R,) (numbers float64, text UTF-8 strings; the columns'
order in the attribute ``columns``), ``/series/<run>/stats/<column>`` (frames,) and
``/series/<run>/analysis/<column>`` (pairs,), the run's ``stats.csv`` and analysis summary.
``seconds`` and ``ms_per_frame`` (and the ``wall_s`` series) are wall times: they differ
from one execution of the same sweep to the next; every other value is deterministic.
"""

import csv
import io
import math
import statistics
from dataclasses import dataclass, field
from pathlib import Path

from clothtool.errors import InputError
from clothtool.sweeps.layout import SweepFolder, format_value, write_text
from clothtool.sweeps.run import ANALYSIS

TIMING = ("seconds", "ms_per_frame")
METRICS = ("frames", "ms_per_frame", "max_stretch", "kinetic", "elastic", "gravity",
           "min_separation")
QUANTITIES = ("lambda1", "lambda2", "area_ratio")
ANALYSIS_METRICS = (*(f"final_{q}_p{p}" for q in QUANTITIES for p in (5, 50, 95)),
                    "max_lambda1_p95", "min_lambda2_p5")
REPORT_CSV, REPORT_H5 = "report.csv", "report.h5"


@dataclass
class SweepReport:
    """What :func:`sweep_report` wrote: the table (``columns``, ``rows`` as dicts) and
    files."""

    output_dir: Path
    columns: list
    rows: list
    csv: Path
    h5: Path
    plots: list = field(default_factory=list)

    def count(self, status):
        return sum(1 for r in self.rows if r["status"] == status)

    def describe(self):
        lines = [f"wrote {self.csv} and {self.h5}: {len(self.rows)} runs, {self.count('done')} "
                 f"done, {self.count('failed')} failed, {self.count('pending')} not done"]
        lines += [f"  {r['run']}: {r['error']}" for r in self.rows if r["status"] == "failed"]
        lines += [f"wrote {p}" for p in self.plots]
        return "\n".join(lines)


def sweep_report(output_dir, *, plot=(), against=None, plot_format="png"):
    """Gather the sweep in ``output_dir``: rewrite its manifest from the runs' statuses
    and write ``report.csv`` and ``report.h5`` there. ``plot``: metric names (columns of the
    table) to draw against the parameter ``against`` (default: the first parameter), one
    figure each, ``METRIC-vs-PARAM.png`` in ``output_dir``. Returns a :class:`SweepReport`."""
    folder = SweepFolder(output_dir)
    record = folder.read()
    params = record["parameters"]
    plot = [plot] if isinstance(plot, str) else list(plot or ())
    analysed = record["analysis"] is not None
    columns = ["run", *params, "status", "error", "seconds", *METRICS,
               *(ANALYSIS_METRICS if analysed else ())]
    if plot:
        against = _check_plot(plot, against, params, columns)
    statuses = folder.statuses(record)
    folder.write_manifest(record, statuses)
    rows, series = [], {}
    for run in record["runs"]:
        rid = run["run"]
        st = statuses[rid] or {"status": "pending"}
        row = {"run": rid, **run["params"], "status": st["status"], "error": st.get("error", ""),
               "seconds": st.get("seconds", math.nan)}
        row.update({m: math.nan for m in (*METRICS, *(ANALYSIS_METRICS if analysed else ()))})
        if st["status"] == "done":
            stats = read_stats(folder.run_dir(rid) / "stats.csv")
            row.update(run_metrics(stats))
            series[rid] = {"stats": stats}
            if analysed:
                summary = read_analysis(folder.run_dir(rid) / ANALYSIS)
                row.update(analysis_metrics(summary))
                series[rid]["analysis"] = summary
        rows.append(row)
    report = SweepReport(folder.root, columns, rows, folder.root / REPORT_CSV,
                         folder.root / REPORT_H5)
    write_text(report.csv, table_csv(columns, rows))
    write_h5(report.h5, record, columns, rows, series)
    for metric in plot:
        report.plots.append(plot_metric(report, metric, against, plot_format))
    return report


def _check_plot(plot, against, params, columns):
    if not params:
        raise InputError("this sweep has no parameters to plot against", keyword="plot")
    against = against or params[0]
    if against not in params:
        raise InputError(f"not a parameter of this sweep (it has {', '.join(params)})",
                         keyword="against", value=against)
    numeric = [c for c in columns if c not in ("run", "status", "error", *params)]
    for metric in plot:
        if metric not in numeric:
            raise InputError(f"not a metric of the table (one of {', '.join(numeric)})",
                             keyword="plot", value=metric)
    return against


def read_stats(path):
    """A run's stats.csv as {column: list of floats}."""
    try:
        with open(path, newline="", encoding="ascii") as fh:
            reader = csv.reader(fh)
            header = next(reader)
            columns = {name: [] for name in header}
            for line in reader:
                for name, value in zip(header, line):
                    columns[name].append(float(value))
    except (OSError, StopIteration, ValueError) as exc:
        raise InputError(f"{path}: cannot read the run's statistics: {exc}") from None
    return columns


def read_analysis(path):
    """The /summary columns of a run's analysis as {column: (P,) array}."""
    from clothtool.io.result import open_result, read_summary

    with open_result(path) as h5:
        return read_summary(h5)


def run_metrics(stats):
    wall = stats["wall_s"][1:]
    separation = [s for s in stats.get("min_separation", []) if math.isfinite(s)]
    return {"frames": len(stats["frame"]),
            "ms_per_frame": 1000.0 * statistics.median(wall) if wall else math.nan,
            "max_stretch": max(stats["max_stretch"]),
            **{name: stats[name][-1] for name in ("kinetic", "elastic", "gravity")},
            "min_separation": min(separation) if separation else math.nan}


def analysis_metrics(summary):
    import numpy as np

    out = {f"final_{q}_p{p}": float(summary[f"{q}_p{p}"][-1]) for q in QUANTITIES
           for p in (5, 50, 95)}
    out["max_lambda1_p95"] = float(np.nanmax(summary["lambda1_p95"]))
    out["min_lambda2_p5"] = float(np.nanmin(summary["lambda2_p5"]))
    return out


def _cell(value):
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return format_value(value) if not isinstance(value, str) else value


def table_csv(columns, rows):
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row[c]) for c in columns])
    return buf.getvalue()


def _numeric(values):
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def write_h5(path, record, columns, rows, series):
    import h5py
    import numpy as np

    from clothtool import __version__
    from clothtool.io.h5 import AtomicH5

    text = h5py.string_dtype()
    with AtomicH5(path) as h5:
        h5.attrs["clothtool_version"] = __version__
        h5.attrs["columns"] = np.array(columns, dtype=text)
        h5.attrs["parameters"] = np.array(record["parameters"], dtype=text)
        h5.attrs["base"] = record["base"]
        table = h5.create_group("table")
        for name in columns:
            values = [row[name] for row in rows]
            if _numeric(values):
                table.create_dataset(name, data=np.array(values, dtype=np.float64))
            else:
                table.create_dataset(name, data=np.array([_cell(v) for v in values], dtype=text))
        group = h5.create_group("series")
        for run, parts in series.items():
            for part, columns_of in parts.items():
                sub = group.create_group(f"{run}/{part}")
                for name, values in columns_of.items():
                    sub.create_dataset(name, data=np.asarray(values, dtype=np.float64))


def plot_metric(report, metric, against, fmt="png"):
    """``metric`` of the done runs against the parameter ``against``: one line per
    combination of the other parameters (points, for a random sweep), log axes where the
    values span a factor of 20 or more. Written as ``METRIC-vs-AGAINST.FMT``."""
    import numpy as np

    from clothtool.results.plot import pyplot

    plt = pyplot()
    others = [p for p in report.columns[1:report.columns.index("status")] if p != against]
    groups = {}
    for row in report.rows:
        if row["status"] != "done" or not _numeric([row[against]]):
            continue
        label = ", ".join(f"{p}={_cell(row[p])}" for p in others)
        groups.setdefault(label, []).append((row[against], row[metric]))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    lines = len(groups) <= 10 and all(len(v) > 1 for v in groups.values())
    for label, points in groups.items():
        points.sort()
        x, y = np.array(points, dtype=np.float64).T
        ax.plot(x, y, "o-" if lines else "o", ms=4, label=label or None)
    xs = [x for pts in groups.values() for x, _ in pts]
    ys = [y for pts in groups.values() for _, y in pts if math.isfinite(y)]
    if xs and min(xs) > 0 and max(xs) >= 20 * min(xs):
        ax.set_xscale("log")
    if ys and min(ys) > 0 and max(ys) >= 20 * min(ys):
        ax.set_yscale("log")
    ax.set_xlabel(against)
    ax.set_ylabel(metric)
    done = sum(len(v) for v in groups.values())
    failed = report.count("failed")
    ax.set_title(f"{report.output_dir}: {done} runs" + (f" ({failed} failed, not shown)"
                                                        if failed else ""))
    if lines and any(groups) and len(groups) > 1:
        ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    output = report.output_dir / f"{metric}-vs-{against}.{fmt}"
    from clothtool.io.atomic import atomic_path

    with atomic_path(output) as tmp:
        fig.savefig(tmp, dpi=120, format=fmt)
    plt.close(fig)
    return output
