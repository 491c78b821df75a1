"""The time of each frame of a simulated sequence, for pictures of it.

A frame's time is its row in the run's ``stats.csv`` (in the frames' folder, or one folder
up for a run's ``obj/`` frames), else its frame number (``frame_NNNNN``) over the frame
rate, else its index over the frame rate.
"""

import csv
import os
import re
from pathlib import Path

import numpy as np

FRAME_NUMBER = re.compile(r"frame_(\d+)\.")


def frame_times(paths, fps):
    """(K,) time in seconds of each frame file: its ``stats.csv`` row (the run's folder:
    the frames' own, or one up), else frame number / ``fps``, else index / ``fps``."""
    numbers = []
    for k, p in enumerate(paths):
        found = FRAME_NUMBER.match(os.path.basename(p))
        numbers.append(int(found.group(1)) if found else None)
    folder = Path(paths[0]).parent
    recorded = {}
    for stats in (folder / "stats.csv", folder.parent / "stats.csv"):
        if stats.is_file():
            with open(stats, newline="", encoding="ascii", errors="replace") as fh:
                for row in csv.DictReader(fh):
                    try:
                        recorded[int(row["frame"])] = float(row["time"])
                    except (KeyError, TypeError, ValueError):
                        break
            break
    return np.array([recorded[n] if n in recorded else (n if n is not None else k) / fps
                     for k, n in enumerate(numbers)])
