"""Simulation output: the frames in each of ``output.format``, and ``stats.csv``.

- ``ply``: ``frame_NNNNN.ply``, binary little-endian PLY with double coordinates and the
  rest coordinates written as ``s t`` vertex properties (metres), so that
  ``clothtool analyze DIR --reference uv`` measures strain against the rest pattern;
- ``obj``: ``obj/frame_NNNNN.obj``, the same positions (17 significant digits, read back
  exactly) with the pattern's texture coordinates per corner as ``vt``, so a garment
  re-imports with its texture (:mod:`clothtool.io.caches.obj_writer`);
- ``mdd``: ``cache/cloth.mdd``, one point cache of every written frame with its time in
  seconds (:mod:`clothtool.io.caches.mdd`; Blender's Mesh Cache modifier plays it), and its base
  mesh ``cache/cloth.obj``, the initial state as an OBJ frame;
- ``usd``: ``usd/cloth.usda``, one USD stage: the cloth's mesh with its points sampled at
  every written frame (time code = frame number, the fps as time codes per second), the
  pattern's uv as primvar ``st``, a GeomSubset per panel, and each collider as a mesh of its
  own with its motion (:mod:`clothtool.io.caches.usd`).

Each format other than PLY has a folder of its own, so that every folder holds one format
and ``clothtool analyze`` reads any of them.

The file number is the frame number (``frame_00000`` is the initial state). Each frame is
written under a temporary name and renamed, every stats row is flushed, and the cache is
written whole when the writer closes (also after a blow-up, with the frames up to it), so a
run that stops early leaves valid files. A sewn garment is written in the file's vertex
numbering (the welded vertices of a seam at one position).
"""

import csv
import re
from pathlib import Path

import numpy as np

from clothtool.errors import InputError, NumericalError
from clothtool.io.caches.mdd import MddWriter
from clothtool.io.caches.obj_writer import ObjWriter
from clothtool.io.ply import write_ply

# per frame: Newton steps, PCG iterations, constraint sweeps (pbd, xpbd) or local–global
# iterations (projective), internal steps (explicit), each summed over the frame's steps
STATS_COLUMNS = ("frame", "time", "kinetic", "elastic", "gravity", "newton_iterations",
                 "cg_iterations", "residual", "max_stretch", "wall_s", "sweeps", "substeps")
# with mesh colliders or self-collision: active contact pairs after the frame's last step and
# the smallest distance between contact pairs (cloth–cloth or cloth–collider, m; inf when
# no pair is within reach of the barrier's candidates)
CONTACT_COLUMNS = ("contacts", "min_separation")
PLY_FRAME, OBJ_FRAME = re.compile(r"frame_\d{5,}\.ply"), re.compile(r"frame_\d{5,}\.obj")
OBJ_DIR, CACHE_DIR, USD_DIR = "obj", "cache", "usd"  # folders in the output folder, one format each
CACHE, CACHE_BASE, USD = "cloth.mdd", "cloth.obj", "cloth.usda"


def frame_path(out_dir, frame, fmt="ply"):
    """The file of ``frame`` in format ``fmt`` ('ply' or 'obj')."""
    folder = Path(out_dir) / OBJ_DIR if fmt == "obj" else Path(out_dir)
    return folder / f"frame_{frame:05d}.{fmt}"


class FrameWriter:
    """Writes the frames and the statistics of one run into ``out_dir``.

    ``uv`` (N, 2): the rest coordinates per vertex (the PLY's ``s t``), or None;
    ``corner_uv`` (M, 3, 2): per corner (the OBJ's ``vt``; default ``uv[faces]``);
    ``formats``: some of ``output.format``'s 'ply', 'obj', 'mdd', 'usd'; for 'usd', ``fps``,
    ``panels`` {name: triangles}, ``up`` ('Y' or 'Z') and ``colliders`` (a
    :class:`ColliderTrack` or None). Frames, caches and
    ``stats.csv`` left in the folder by an earlier run are removed first, so the folder
    never mixes two runs; other files are left alone.
    """

    def __init__(self, out_dir, faces, uv, columns=STATS_COLUMNS, *, formats=("ply",),
                 corner_uv=None, fps=30.0, panels=None, up="Y", colliders=None):
        self.out_dir = Path(out_dir)
        self.columns = tuple(columns)
        self.faces = faces
        self.formats = tuple(formats)
        self.properties = {"s": uv[:, 0].copy(), "t": uv[:, 1].copy()} if uv is not None else None
        self.face_properties = ({"texcoord": corner_uv.reshape(len(faces), 6).copy()}
                                if corner_uv is not None else None)
        if corner_uv is None and uv is not None:
            corner_uv = uv[faces]
        self._obj = ObjWriter(faces, corner_uv) if {"obj", "mdd"} & set(self.formats) else None
        self._cache = None
        self._colliders = colliders
        folders = [self.out_dir] + [self.out_dir / name for fmt, name in
                                    (("obj", OBJ_DIR), ("mdd", CACHE_DIR), ("usd", USD_DIR))
                                    if fmt in self.formats]
        for folder in folders:  # every folder checked before any is made: nothing half-made
            if folder.exists() and not folder.is_dir():
                raise InputError(f"{folder}: output path exists and is not a folder")
        for folder in folders:
            try:
                folder.mkdir(parents=True, exist_ok=True)
            except FileExistsError:
                raise InputError(f"{folder}: output path exists and is not a folder") from None
            except OSError as exc:
                raise InputError(f"{folder}: cannot create the output folder: {exc.strerror}") from None
        try:
            self._remove_earlier_run()
            self._stats_file = open(self.out_dir / "stats.csv", "w", newline="", encoding="ascii")
        except OSError as exc:
            raise InputError(f"{self.out_dir}: output folder is not writable: {exc.strerror}") from None
        self._stats = csv.writer(self._stats_file)
        self._stats.writerow(self.columns)
        self._stats_file.flush()
        self._usd = None
        if "usd" in self.formats:
            from clothtool.io.caches.usd import UsdaWriter

            self._usd = UsdaWriter(self.out_dir / USD_DIR / USD, faces, corner_uv, panels,
                                   fps=fps, up=up,
                                   colliders=colliders.meshes if colliders is not None else ())

    def _remove_earlier_run(self):
        for old in self.out_dir.iterdir():
            if PLY_FRAME.fullmatch(old.name) or old.name == "stats.csv":
                old.unlink()
        if (self.out_dir / OBJ_DIR).is_dir():
            for old in (self.out_dir / OBJ_DIR).iterdir():
                if OBJ_FRAME.fullmatch(old.name):
                    old.unlink()
        for folder, name in ((CACHE_DIR, CACHE), (CACHE_DIR, CACHE_BASE), (USD_DIR, USD)):
            if (self.out_dir / folder / name).is_file():
                (self.out_dir / folder / name).unlink()

    def write_frame(self, frame, positions, time):
        """Write ``frame`` (positions (N, 3)) at ``time`` seconds in every format."""
        if "ply" in self.formats:
            write_ply(frame_path(self.out_dir, frame), positions, self.faces,
                      vertex_properties=self.properties, face_properties=self.face_properties)
        if "obj" in self.formats:
            self._obj.write(frame_path(self.out_dir, frame, "obj"), positions)
        if "mdd" in self.formats:
            if self._cache is None:
                self._obj.write(self.out_dir / CACHE_DIR / CACHE_BASE, positions)
                self._cache = MddWriter(self.out_dir / CACHE_DIR / CACHE, len(positions))
            self._cache.add(time, positions)
        if self._usd is not None:
            self._usd.add(frame, positions, self._colliders.positions(time)
                          if self._colliders is not None else ())

    def write_stats(self, row):
        self._stats.writerow([_format(row[name]) for name in self.columns])
        self._stats_file.flush()

    def close(self, ok=True):
        """Close ``stats.csv`` and write the cache (unless not ``ok``)."""
        self._stats_file.close()
        if self._cache is not None:
            self._cache.close(ok)
        if self._usd is not None:
            self._usd.close(ok)

    def __enter__(self):
        return self

    def __exit__(self, kind, value, traceback):
        # a blow-up keeps the frames before it, in the cache too; any other failure writes none
        self.close(ok=kind is None or issubclass(kind, NumericalError))


class ColliderTrack:
    """The colliders of a run's config as triangle meshes of fixed topology
    (:class:`clothtool.sim.scene.RunScene`: a plane a square patch about the cloth's initial
    centre): ``meshes`` [(name, faces)], :meth:`positions` at time t."""

    def __init__(self, config, x0):
        from clothtool.sim.scene import RunScene

        self.scene = RunScene(config)
        self.centre = x0.mean(axis=0)
        self.extent = max(float(np.ptp(x0, axis=0).max()), 1e-3)
        self.meshes = [(s.key.replace("scene.", "").replace("[", "_").replace("]", ""), s.faces)
                       for s in self.scene.surfaces(0.0, self.centre, self.extent)]

    def positions(self, t):
        return [s.vertices for s in self.scene.surfaces(t, self.centre, self.extent)]


def _format(value):
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return str(int(value))
