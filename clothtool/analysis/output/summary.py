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

A tetrahedral result (:data:`TET_COLUMNS`, from the registry's ``tet`` fields) has the same
columns over its tetrahedra with λ1 ≥ λ2 ≥ λ3 (``lambda3_p*`` added), ``volume_ratio_p*`` for
the area ratio's, ``compressed`` counting λ3 < 1 − TOL, and the count ``inverted``
(det F < 0, bit 4 of ``/tet/flags``) in place of ``uv_flipped``.
"""

import numpy as np

from clothtool.analysis.fields import FIELDS_2D, FIELDS_TET
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
TET_QUANTITIES = tuple(q for f in FIELDS_TET if not f.integer for q in f.summary)  # λ1–λ3, J
TET_FLAG_BITS = (("reference_degenerate", 1), ("deformed_degenerate", 2), ("nonfinite", 4),
                 ("inverted", 16))
TET_COLUMNS = ("pair", "reference", "deformed",
               *(f"{q}_p{p}" for q in TET_QUANTITIES for p in PERCENTILES),
               "compressed", "stretched", "flagged", *(name for name, _ in TET_FLAG_BITS))
TET_INT_COLUMNS = {"pair", "reference", "deformed", "flagged", *(n for n, _ in TET_FLAG_BITS)}


def pair_summary(stretch, area_ratio, flags, tets=False):
    """The float and count columns of one pair (everything but pair/reference/deformed)
    from its (M, 2) stretches, (M,) area ratios and (M,) flags; with ``tets``, (M, 3)
    stretches and volume ratios."""
    stretch, area_ratio = np.asarray(stretch), np.asarray(area_ratio)
    if np.isfinite(stretch.sum()):  # the common case, checked with one cheap pass: views, no copies
        lam, j = [stretch[:, k] for k in range(stretch.shape[1])], area_ratio
    else:
        valid = np.isfinite(stretch).all(axis=1)
        lam, j = [stretch[valid, k] for k in range(stretch.shape[1])], area_ratio[valid]
    from clothtool.analysis.output.percentiles import percentiles  # numba: not for `clothtool info`

    row = {}
    qs = np.array(PERCENTILES, np.float64)
    for name, q in zip(TET_QUANTITIES if tets else QUANTITIES, [*lam, j]):
        values = percentiles(np.ascontiguousarray(q), qs)  # = np.percentile, 4× faster
        row.update({f"{name}_p{p}": float(v) for p, v in zip(PERCENTILES, values)})
    n = len(j)  # unflagged elements
    row["compressed"] = float(np.count_nonzero(lam[-1] < 1 - TOL)) / n if n else np.nan
    row["stretched"] = float(np.count_nonzero(lam[0] > 1 + TOL)) / n if n else np.nan
    row["flagged"] = int(np.count_nonzero(flags))
    for name, bit in TET_FLAG_BITS if tets else FLAG_BITS:
        row[name] = int(np.count_nonzero(np.asarray(flags) & bit))
    return row


class SummaryWriter:
    """Creates ``/summary`` in an open HDF5 file and fills it one pair at a time."""

    def __init__(self, h5, pairs, offset, tets=False):
        self.tets = tets
        self.columns = TET_COLUMNS if tets else COLUMNS
        ints = TET_INT_COLUMNS if tets else INT_COLUMNS
        group = h5.create_group("summary")
        group.attrs["columns"] = list(self.columns)
        group.attrs["percentiles"] = list(PERCENTILES)
        group.attrs["tolerance"] = TOL
        n = len(pairs)
        self.data = {c: np.zeros(n, np.int64 if c in ints else np.float64) for c in self.columns}
        self.data["pair"][:] = offset + np.arange(n)
        self.data["reference"][:] = pairs[:, 0]
        self.data["deformed"][:] = pairs[:, 1]
        self.group = group

    def add(self, p, stretch, area_ratio, flags):
        for name, value in pair_summary(stretch, area_ratio, flags, self.tets).items():
            self.data[name][p] = value

    def close(self):
        """Write the columns (P values each: small, kept in memory until the end)."""
        for name in self.columns:
            self.group.create_dataset(name, data=self.data[name])
        if not self.tets:
            add_aliases(self.group)


def add_aliases(group):
    """Soft links ``J_p…`` → ``area_ratio_p…`` in a ``/summary`` group, so that scripts that
    read the old column names keep working."""
    import h5py

    for old, new in ALIASES.items():
        if new in group and old not in group:
            group[old] = h5py.SoftLink(f"{group.name}/{new}")
