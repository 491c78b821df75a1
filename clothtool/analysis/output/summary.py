"""The per-pair summary stored as ``/summary`` at analysis time and shown by ``clothtool info``
(its layout and reader: :mod:`clothtool.io.result`).

``/summary`` is a group of (P,) datasets, one per column, in the order of its ``columns``
attribute (:data:`~clothtool.io.result.COLUMNS`):

- ``pair``, ``reference``, ``deformed``: the global pair index and its frames (as ``/pairs``)
- ``lambda1_p5 … lambda1_p95``, ``lambda2_p5 …``, ``area_ratio_p5 …``: 5th/50th/95th
  percentiles of the principal stretches λ1 ≥ λ2 and the area ratio λ1λ2 over the pair's
  triangles (flagged triangles, whose values are NaN, excluded; NaN if none is left). The
  quantities are the registry's ``summary`` entries (:mod:`clothtool.fields`): quantity k of
  a float field summarises its k-th component, in registry order.
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

from clothtool.fields import FIELDS_2D, FIELDS_TET
from clothtool.io.result import (COLUMNS, FLAG_BITS, PERCENTILES, TET_COLUMNS, TET_FLAG_BITS,
                                 TET_INT_COLUMNS, INT_COLUMNS, TOL, add_aliases)

STRETCH = "stretch"  # the field whose first and last components count as stretched/compressed


def summarised(registry_fields):
    """(float fields, integer fields) of ``registry_fields`` that declare summary quantities."""
    return (tuple(f for f in registry_fields if f.summary and not f.integer),
            tuple(f for f in registry_fields if f.summary and f.integer))


def pair_summary(values, registry_fields=FIELDS_2D, flag_bits=FLAG_BITS):
    """The float and count columns of one pair (everything but pair/reference/deformed).

    ``values``: name → (M, …) array of each field of ``registry_fields`` that declares summary
    quantities (quantity k of a float field is its k-th component, flattened); the integer
    one is the flags, counted per bit of ``flag_bits``. Elements that are not finite in every
    summarised float field (the flagged ones) are left out of the percentiles and fractions.
    """
    from clothtool.analysis.output.percentiles import percentiles  # numba: not for `clothtool info`

    floats, ints = summarised(registry_fields)
    arrays = {f.name: np.asarray(values[f.name]).reshape(len(values[f.name]), -1) for f in floats}
    # the common case is checked with one cheap pass per field: views, no copies
    if not all(np.isfinite(a.sum()) for a in arrays.values()):
        valid = np.logical_and.reduce([np.isfinite(a).all(axis=1) for a in arrays.values()])
        arrays = {name: a[valid] for name, a in arrays.items()}
    row = {}
    qs = np.array(PERCENTILES, np.float64)
    for f in floats:
        for k, name in enumerate(f.summary):
            column = np.ascontiguousarray(arrays[f.name][:, k])
            values_k = percentiles(column, qs)  # = np.percentile, 4× faster
            row.update({f"{name}_p{p}": float(v) for p, v in zip(PERCENTILES, values_k)})
    lam = arrays[STRETCH]
    n = len(lam)  # unflagged elements
    row["compressed"] = float(np.count_nonzero(lam[:, -1] < 1 - TOL)) / n if n else np.nan
    row["stretched"] = float(np.count_nonzero(lam[:, 0] > 1 + TOL)) / n if n else np.nan
    for f in ints:
        flags = np.asarray(values[f.name])
        row["flagged"] = int(np.count_nonzero(flags))
        for name, bit in flag_bits:
            row[name] = int(np.count_nonzero(flags & bit))
    return row


class SummaryWriter:
    """Creates ``/summary`` in an open HDF5 file and fills it one pair at a time."""

    def __init__(self, h5, pairs, offset, tets=False):
        self.tets = tets
        self.fields, self.flag_bits = (FIELDS_TET, TET_FLAG_BITS) if tets else (FIELDS_2D, FLAG_BITS)
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

    def add(self, p, buffers):
        """The row of pair ``p`` from its buffers (name → array of each summarised field)."""
        for name, value in pair_summary(buffers, self.fields, self.flag_bits).items():
            self.data[name][p] = value

    def close(self):
        """Write the columns (P values each: small, kept in memory until the end)."""
        for name in self.columns:
            self.group.create_dataset(name, data=self.data[name])
        if not self.tets:
            add_aliases(self.group)
