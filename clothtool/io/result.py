"""The reader of a finished analysis result (HDF5), for ``info``, ``export``, ``plot`` and
``merge``."""

import os

from clothtool.errors import InputError

SUMMARY_ALIASES = {f"J_p{p}": f"area_ratio_p{p}" for p in (5, 50, 95)}
"""Old ``/summary`` column names (results before the area_ratio_* columns) → current ones."""


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
