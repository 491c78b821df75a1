"""The layout of an analysis result (HDF5) and its reader, for ``info``, ``export``, ``plot``
and ``merge``; the analysis writes what is laid out here.

``/summary`` is a group of (P,) datasets, one per column, in the order of its ``columns``
attribute (:data:`COLUMNS`; what each column means: :mod:`clothtool.analysis.output.summary`):
``pair``, ``reference``, ``deformed``; ``<quantity>_p<q>`` for each ``summary`` quantity of a
float field of the registry (:mod:`clothtool.fields`, registry order) and each q of
:data:`PERCENTILES`; ``compressed``, ``stretched`` (fractions, tolerance :data:`TOL`);
``flagged`` and one count per flag bit (:data:`FLAG_BITS`). A tetrahedral result has
:data:`TET_COLUMNS`. The per-pair views the XDMF addresses live in the group :data:`VIEWS`.
"""

import os

from clothtool.errors import InputError
from clothtool.fields import FIELDS_2D, FIELDS_TET

SUMMARY_ALIASES = {f"J_p{p}": f"area_ratio_p{p}" for p in (5, 50, 95)}
"""Old ``/summary`` column names (results before the area_ratio_* columns) → current ones."""
PERCENTILES = (5, 50, 95)
TOL = 1e-5
FLAG_BITS = (("reference_degenerate", 1), ("deformed_degenerate", 2), ("nonfinite", 4),
             ("uv_flipped", 8))
TET_FLAG_BITS = (("reference_degenerate", 1), ("deformed_degenerate", 2), ("nonfinite", 4),
                 ("inverted", 16))
VIEWS = "xdmf"  # the group of per-pair views (virtual datasets) that the XDMF addresses


def summary_columns(registry_fields, flag_bits):
    """(columns, integer columns) of ``/summary`` for the fields of one kernel."""
    quantities = [q for f in registry_fields if not f.integer for q in f.summary]
    counts = ("flagged", *(name for name, _ in flag_bits))
    columns = ("pair", "reference", "deformed",
               *(f"{q}_p{p}" for q in quantities for p in PERCENTILES),
               "compressed", "stretched", *counts)
    return columns, {"pair", "reference", "deformed", *counts}


COLUMNS, INT_COLUMNS = summary_columns(FIELDS_2D, FLAG_BITS)
TET_COLUMNS, TET_INT_COLUMNS = summary_columns(FIELDS_TET, TET_FLAG_BITS)


def open_result(path):
    """An open ``h5py.File`` of a clothtool result, or InputError naming the file."""
    import h5py

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"{path}: no such file")
    try:
        h5 = h5py.File(path, "r")
    except OSError:
        raise InputError(f"{path}: not an HDF5 file") from None
    if "pairs" not in h5 or "mesh" not in h5:
        h5.close()
        raise InputError(f"{path}: not a clothtool analysis result (no /pairs or /mesh)")
    return h5


def read_summary(h5):
    """Columns of ``/summary`` of an open result as a dict name → (P,) array; the columns
    of older results named ``J_p…`` come back as ``area_ratio_p…``."""
    if "summary" not in h5:
        raise InputError(f"{h5.filename}: no /summary in this file; is it a clothtool analyze result?")
    group = h5["summary"]
    return {SUMMARY_ALIASES.get(name, name): group[name][:] for name in group.attrs["columns"]}


def add_aliases(group):
    """Soft links ``J_p…`` → ``area_ratio_p…`` in a ``/summary`` group, so that scripts that
    read the old column names keep working."""
    import h5py

    for old, new in SUMMARY_ALIASES.items():
        if new in group and old not in group:
            group[old] = h5py.SoftLink(f"{group.name}/{new}")
