"""Finding the frames of a sequence: a folder, a glob, or a list of files, in natural order."""

import glob
import os
import re

from clothtool.errors import InputError

_DIGITS = re.compile(r"(\d+)")


def natural_key(path):
    """Sort key that orders embedded numbers by value: ``f2.ply`` before ``f10.ply``."""
    parts = _DIGITS.split(os.path.basename(path))
    return [(0, int(p), "") if p.isdigit() else (1, 0, p.lower()) for p in parts], path


def discover_frames(inputs):
    """Resolve ``inputs`` (a path, a glob or a list of them) to an ordered list of PLY files.

    A folder contributes its ``*.ply`` files (case-insensitive), a glob its matches; each
    folder or glob is sorted naturally, explicit files keep the order given.
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    frames = []
    for item in map(os.fspath, inputs):
        if os.path.isdir(item):
            found = [os.path.join(item, f) for f in os.listdir(item)
                     if f.lower().endswith(".ply") and os.path.isfile(os.path.join(item, f))]
            if not found:
                raise InputError(f"{item}: folder contains no .ply files")
            frames.extend(sorted(found, key=natural_key))
        elif os.path.isfile(item):
            frames.append(item)
        elif glob.has_magic(item):
            found = [f for f in glob.glob(item) if os.path.isfile(f)]
            if not found:
                raise InputError(f"{item}: pattern matches no files")
            frames.extend(sorted(found, key=natural_key))
        else:
            raise InputError(f"{item}: no such file or folder")
    return frames
