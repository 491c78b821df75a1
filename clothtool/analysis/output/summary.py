"""The per-pair summary stored as ``/summary`` at analysis time and shown by ``clothtool info``
(read back by :func:`clothtool.io.result.read_summary`).

``/summary`` is a group of (P,) datasets, one per column, in the order of its ``columns``
attribute (:data:`COLUMNS`):

- ``pair``, ``reference``, ``deformed``: the global pair index and its frames (as ``/pairs``)
- ``lambda1_p5 … lambda1_p95``, ``lambda2_p5 …``, ``area_ratio_p5 …``: 5th/50th/95th
  percentiles of the principal stretches λ1 ≥ λ2 and the area ratio λ1λ2 over the pair's
  triangles (flagged triangles, whose values are NaN, excluded; NaN if none is left); the
  quantities come from the registry's ``summary`` entries (:mod:`clothtool.analysis.fields`).
  Results written before these names call the area-ratio columns ``J_p5 …``; the old names
  stay readable as links (:data:`ALIASES`).
- ``compressed``: fraction of those triangles with λ2 < 1 − TOL, in compression along
  at least one direction; ``stretched``: fraction with λ1 > 1 + TOL. TOL = 1e-5 (attribute
  ``tolerance``) keeps the round-off of float32 input coordinates (≈1e-6 of an edge on a
  sheet 20 edges wide) out of both, so a rigid motion counts as neither.
- ``flagged``: triangles with any flag bit; ``reference_degenerate``,
  ``deformed_degenerate``, ``nonfinite``, ``uv_flipped``: triangles with each bit of ``/face/flags``.
"""

import numpy as np

from clothtool.analysis.fields import FIELDS_2D
from clothtool.io.result import SUMMARY_ALIASES as ALIASES

PERCENTILES = (5, 50, 95)
TOL = 1e-5
QUANTITIES = tuple(q for f in FIELDS_2D if not f.integer for q in f.summary)  # λ1, λ2, area
FLAG_BITS = (("reference_degenerate", 1), ("deformed_degenerate", 2), ("nonfinite", 4),
             ("uv_flipped", 8))
COLUMNS = ("pair", "reference", "deformed",
           *(f"{q}_p{p}" for q in QUANTITIES for p in PERCENTILES),
           "compressed", "stretched", "flagged", *(name for name, _ in FLAG_BITS))
INT_COLUMNS = {"pair", "reference", "deformed", "flagged", *(name for name, _ in FLAG_BITS)}


def pair_summary(stretch, area_ratio, flags):
    """The float and count columns of one pair (everything but pair/reference/deformed)
    from its (M, 2) stretches, (M,) area ratios and (M,) flags."""
    stretch, area_ratio = np.asarray(stretch), np.asarray(area_ratio)
    if np.isfinite(stretch.sum()):  # the common case, checked with one cheap pass: views, no copies
        l1, l2, j = stretch[:, 0], stretch[:, 1], area_ratio
    else:
        valid = np.isfinite(stretch).all(axis=1)
        l1, l2, j = stretch[valid, 0], stretch[valid, 1], area_ratio[valid]
    from clothtool.analysis.output.percentiles import percentiles  # numba: not for `clothtool info`

    row = {}
    qs = np.array(PERCENTILES, np.float64)
    for name, q in (("lambda1", l1), ("lambda2", l2), ("area_ratio", j)):
        values = percentiles(np.ascontiguousarray(q), qs)  # = np.percentile, 4× faster
        row.update({f"{name}_p{p}": float(v) for p, v in zip(PERCENTILES, values)})
    n = len(l1)  # unflagged triangles
    row["compressed"] = float(np.count_nonzero(l2 < 1 - TOL)) / n if n else np.nan
    row["stretched"] = float(np.count_nonzero(l1 > 1 + TOL)) / n if n else np.nan
    row["flagged"] = int(np.count_nonzero(flags))
    for name, bit in FLAG_BITS:
        row[name] = int(np.count_nonzero(np.asarray(flags) & bit))
    return row


class SummaryWriter:
    """Creates ``/summary`` in an open HDF5 file and fills it one pair at a time."""

    def __init__(self, h5, pairs, offset):
        group = h5.create_group("summary")
        group.attrs["columns"] = list(COLUMNS)
        group.attrs["percentiles"] = list(PERCENTILES)
        group.attrs["tolerance"] = TOL
        n = len(pairs)
        self.data = {c: np.zeros(n, np.int64 if c in INT_COLUMNS else np.float64) for c in COLUMNS}
        self.data["pair"][:] = offset + np.arange(n)
        self.data["reference"][:] = pairs[:, 0]
        self.data["deformed"][:] = pairs[:, 1]
        self.group = group

    def add(self, p, stretch, area_ratio, flags):
        for name, value in pair_summary(stretch, area_ratio, flags).items():
            self.data[name][p] = value

    def close(self):
        """Write the columns (P values each: small, kept in memory until the end)."""
        for name in COLUMNS:
            self.group.create_dataset(name, data=self.data[name])
        add_aliases(self.group)


def add_aliases(group):
    """Soft links ``J_p…`` → ``area_ratio_p…`` in a ``/summary`` group, so that scripts that
    read the old column names keep working."""
    import h5py

    for old, new in ALIASES.items():
        if new in group and old not in group:
            group[old] = h5py.SoftLink(f"{group.name}/{new}")
