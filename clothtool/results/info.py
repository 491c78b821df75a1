"""``clothtool info``: what is in an analysis result, and its per-pair summary as a table or CSV."""

import csv
import io
import os

import numpy as np

from clothtool.io.result import (COLUMNS, FLAG_BITS, INT_COLUMNS, TET_COLUMNS, TET_FLAG_BITS,
                                 TET_INT_COLUMNS, TOL, open_result, read_summary)

REFERENCE_PAIRS = {"previous": "pairs (i, i+1)", "first": "pairs (0, i)", "uv": "uv rest shape"}
TABLE = (("pair", "pair", "{:d}"), ("reference", "ref", "{:d}"), ("deformed", "def", "{:d}"),
         ("lambda1_p5", "λ1 p5", "{:.4f}"), ("lambda1_p50", "λ1 p50", "{:.4f}"),
         ("lambda1_p95", "λ1 p95", "{:.4f}"), ("lambda2_p5", "λ2 p5", "{:.4f}"),
         ("lambda2_p50", "λ2 p50", "{:.4f}"), ("lambda2_p95", "λ2 p95", "{:.4f}"),
         ("area_ratio_p5", "area p5", "{:.4f}"), ("area_ratio_p50", "area p50", "{:.4f}"),
         ("area_ratio_p95", "area p95", "{:.4f}"),
         ("compressed", "compr.", "{:.1%}"), ("stretched", "stretch.", "{:.1%}"),
         ("flagged", "flagged", "{:d}"))
TET_TABLE = (*TABLE[:6], ("lambda3_p5", "λ3 p5", "{:.4f}"), ("lambda3_p50", "λ3 p50", "{:.4f}"),
             ("lambda3_p95", "λ3 p95", "{:.4f}"), ("volume_ratio_p5", "J p5", "{:.4f}"),
             ("volume_ratio_p50", "J p50", "{:.4f}"), ("volume_ratio_p95", "J p95", "{:.4f}"),
             *TABLE[12:], ("inverted", "inverted", "{:d}"))


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def is_tet_result(h5):
    """Whether the open result ``h5`` is of a tetrahedral sequence (``/mesh/tets``)."""
    return "tets" in h5["mesh"]


def describe(path):
    """Multi-line description of the result at ``path`` followed by its summary table."""
    with open_result(path) as h5:
        attrs = h5.attrs
        frames = [_text(f) for f in h5["frames"][:]]
        pairs = h5["pairs"]
        reference = _text(attrs.get("reference", "?"))
        offset, total = int(attrs.get("pair_offset", 0)), int(attrs.get("pairs_total", len(pairs)))
        tets = is_tet_result(h5)
        if tets:
            ignored = int(attrs.get("ignored_cells", 0))
            mesh = (f"{h5['mesh/tets'].shape[0]} tetrahedra"
                    + (f" ({ignored} other cells ignored)" if ignored else ""))
        else:
            mesh = f"{h5['mesh/faces'].shape[0]} triangles"
        span = (f"{len(pairs)} (all)" if len(pairs) == total else
                f"{len(pairs)} of {total} (slice {offset}:{offset + len(pairs)})")
        lines = [f"{path}: clothtool {_text(attrs.get('clothtool_version', '?'))} result, "
                 f"created {_text(attrs.get('created', '?'))}",
                 f"  command:   {_text(attrs.get('command', '?'))}",
                 f"  reference: {reference}"
                 + (f" ({REFERENCE_PAIRS[reference]})" if reference in REFERENCE_PAIRS else ""),
                 f"  frames:    {len(frames)}"
                 + (f" ({frames[0]} … {os.path.basename(frames[-1])})" if frames else ""),
                 f"  pairs:     {span}",
                 f"  mesh:      {mesh}, "
                 f"{h5['mesh/vertices'].shape[0]} vertices, stored as {_text(attrs.get('dtype', '?'))}"]
        for group in ("face", "tet", "vertex", "edge"):
            if group in h5:
                items = ", ".join(f"{name} {'×'.join(map(str, ds.shape[2:])) or 'scalar'}"
                                  for name, ds in h5[group].items())
                lines.append(f"  {group + ':':<10} {items}")
        summary = read_summary(h5)
    flagged = ", ".join(f"{int(summary[name].sum())} {name.replace('_', ' ')}"
                        for name, _ in (TET_FLAG_BITS if tets else FLAG_BITS))
    element = "tetrahedron" if tets else "triangle"
    lines.append(f"  flagged:   {int(summary['flagged'].sum())} {element}-pairs ({flagged})")
    if tets:
        lines += ["", "per pair: percentiles of the principal stretches λ1 ≥ λ2 ≥ λ3 (λ3 < 0: "
                  "inverted) and the volume ratio J = det F; compr./stretch. = fraction of tetrahedra "
                  f"with λ3 < 1 − {TOL:g} / λ1 > 1 + {TOL:g}"]
    else:
        lines += ["", "per pair: percentiles of the principal stretches λ1 ≥ λ2 and the area "
                  f"ratio λ1λ2 (area); compr./stretch. = fraction of triangles with λ2 < 1 − "
                  f"{TOL:g} / λ1 > 1 + {TOL:g}"]
    lines.append(_table(summary, TET_TABLE if tets else TABLE))
    return "\n".join(lines)


def _table(summary, table):
    cells = [[head for _, head, _ in table]]
    for i in range(len(summary["pair"])):
        cells.append([fmt.format(summary[col][i].item()) if np.isfinite(summary[col][i]) else "nan"
                      for col, _, fmt in table])
    widths = [max(len(row[j]) for row in cells) for j in range(len(table))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells)


def summary_csv(path):
    """The ``/summary`` of the result at ``path`` as CSV text: a header row of
    :data:`~clothtool.io.result.COLUMNS`, then one row per pair (floats in full
    precision)."""
    with open_result(path) as h5:
        summary = read_summary(h5)
        tets = is_tet_result(h5)
    columns, ints = (TET_COLUMNS, TET_INT_COLUMNS) if tets else (COLUMNS, INT_COLUMNS)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(columns)
    for i in range(len(summary["pair"])):
        writer.writerow([int(summary[c][i]) if c in ints else repr(float(summary[c][i]))
                         for c in columns])
    return out.getvalue()
