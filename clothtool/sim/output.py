"""Simulation output: ``frame_NNNNN.ply`` files and ``stats.csv``.

Frames are binary little-endian PLY with double coordinates and the rest
coordinates written as ``s t`` vertex properties (metres), or, for a pattern per
corner (a garment), as the face list ``texcoord`` (u v per corner, metres), so that
``clothtool analyze DIR --reference uv`` measures strain against the rest
pattern. A sewn garment is written in the file's vertex numbering (the welded
vertices of a seam at one position). The file number is the frame number (``frame_00000.ply`` is the
initial state). Each PLY is written under a temporary name and renamed, and
every stats row is flushed, so a run that stops early leaves valid files.
"""

import csv
import re
from pathlib import Path

import numpy as np

from clothtool.errors import InputError
from clothtool.io.ply import write_ply

# per frame: Newton steps, PCG iterations, constraint sweeps (pbd, xpbd) or local–global
# iterations (projective), internal steps (explicit), each summed over the frame's steps
STATS_COLUMNS = ("frame", "time", "kinetic", "elastic", "gravity", "newton_iterations",
                 "cg_iterations", "residual", "max_stretch", "wall_s", "sweeps", "substeps")
# with mesh colliders or self-collision: active contact pairs after the frame's last step and
# the smallest distance between contact pairs (cloth–cloth or cloth–collider, m; inf when
# no pair is within reach of the barrier's candidates)
CONTACT_COLUMNS = ("contacts", "min_separation")
FRAME_NAME = re.compile(r"frame_\d{5,}\.ply")


def frame_path(out_dir, frame):
    return Path(out_dir) / f"frame_{frame:05d}.ply"


class FrameWriter:
    """Writes the frames and the statistics of one run into ``out_dir``.

    Frames and ``stats.csv`` left in the folder by an earlier run are removed
    first, so the folder never mixes two runs; other files are left alone.
    """

    def __init__(self, out_dir, faces, uv, columns=STATS_COLUMNS, corner_uv=None):
        self.out_dir = Path(out_dir)
        self.columns = tuple(columns)
        self.faces = faces
        self.properties = {"s": uv[:, 0].copy(), "t": uv[:, 1].copy()} if uv is not None else None
        self.face_properties = ({"texcoord": corner_uv.reshape(len(faces), 6).copy()}
                                if corner_uv is not None else None)
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            raise InputError(f"{self.out_dir}: output path exists and is not a folder") from None
        except OSError as exc:
            raise InputError(f"{self.out_dir}: cannot create the output folder: {exc.strerror}") from None
        try:
            for old in self.out_dir.iterdir():
                if FRAME_NAME.fullmatch(old.name) or old.name == "stats.csv":
                    old.unlink()
            self._stats_file = open(self.out_dir / "stats.csv", "w", newline="", encoding="ascii")
        except OSError as exc:
            raise InputError(f"{self.out_dir}: output folder is not writable: {exc.strerror}") from None
        self._stats = csv.writer(self._stats_file)
        self._stats.writerow(self.columns)
        self._stats_file.flush()

    def write_frame(self, frame, positions):
        write_ply(frame_path(self.out_dir, frame), positions, self.faces,
                  vertex_properties=self.properties, face_properties=self.face_properties)

    def write_stats(self, row):
        self._stats.writerow([_format(row[name]) for name in self.columns])
        self._stats_file.flush()

    def close(self):
        self._stats_file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _format(value):
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return str(int(value))
