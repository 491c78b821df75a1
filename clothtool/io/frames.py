"""Finding the frames of a sequence: a folder, a glob, or a list of files, in natural order.

A sequence is in one format, known from the extension: ``.obj`` files are read as Wavefront
OBJ (:mod:`clothtool.io.obj`), anything else as PLY (:mod:`clothtool.io.ply`)."""

import glob
import os
import re

import numpy as np

from clothtool.errors import InputError

_DIGITS = re.compile(r"(\d+)")
MESH_EXTENSIONS = (".ply", ".obj")


def mesh_format(path):
    """'obj' for a ``.obj`` file (any case), else 'ply'."""
    return "obj" if os.fspath(path).lower().endswith(".obj") else "ply"


def read_mesh(path, *, reuse=None):
    """Read a PLY or OBJ file (by extension) into a :class:`~clothtool.io.ply.PlyMesh`."""
    if mesh_format(path) == "obj":
        from clothtool.io.obj import read_obj

        return read_obj(path, reuse=reuse)
    from clothtool.io.ply import read_ply

    return read_ply(path, reuse=reuse)


def natural_key(path):
    """Sort key that orders embedded numbers by value: ``f2.ply`` before ``f10.ply``."""
    parts = _DIGITS.split(os.path.basename(path))
    return [(0, int(p), "") if p.isdigit() else (1, 0, p.lower()) for p in parts], path


def discover_frames(inputs):
    """Resolve ``inputs`` (a path, a glob or a list of them) to an ordered list of mesh files.

    A folder contributes its ``*.ply`` or ``*.obj`` files (case-insensitive; not both), a glob
    its matches; each folder or glob is sorted naturally, explicit files keep the order given.
    All frames must be in one format.
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    frames = []
    for item in map(os.fspath, inputs):
        if os.path.isdir(item):
            found = [os.path.join(item, f) for f in os.listdir(item)
                     if f.lower().endswith(MESH_EXTENSIONS) and os.path.isfile(os.path.join(item, f))]
            if not found:
                raise InputError(f"{item}: folder contains no .ply or .obj files")
            _one_format(found, f"{item}: folder holds")
            frames.extend(sorted(found, key=natural_key))
        elif os.path.isfile(item):
            frames.append(item)
        elif glob.has_magic(item):
            found = [f for f in glob.glob(item) if os.path.isfile(f)]
            if not found:
                raise InputError(f"{item}: pattern matches no files")
            frames.extend(sorted(found, key=natural_key))
        elif os.path.exists(item):
            raise InputError(f"{item}: not a regular file or folder")
        else:
            raise InputError(f"{item}: no such file or folder")
    _one_format(frames, "the frames are")
    return frames


def _one_format(paths, what):
    formats = {}
    for p in paths:
        formats.setdefault(mesh_format(p), p)
    if len(formats) > 1:
        raise InputError(f"{what} both .ply and .obj files ({os.path.basename(formats['ply'])}, "
                         f"{os.path.basename(formats['obj'])}); a sequence is in one format")


class FrameReader:
    """Reads the frames of a sequence against the topology of the first.

    Every frame must have the first frame's vertex count and faces; a face block
    that is byte-identical to the first frame's is not parsed again.
    """

    def __init__(self, paths):
        self.paths = list(paths)
        self.first = read_mesh(self.paths[0])
        if len(self.first.faces) == 0:
            raise InputError(f"{self.paths[0]}: mesh has no faces")

    @property
    def faces(self):
        return self.first.faces

    @property
    def n_vertices(self):
        return len(self.first.vertices)

    def mesh(self, i):
        """The mesh (:class:`~clothtool.io.ply.PlyMesh`) of frame ``i``, checked against frame 0."""
        if i == 0:
            return self.first
        return self.check_same_topology(read_mesh(self.paths[i], reuse=self.first),
                                        self.paths[i])

    def positions(self, i):
        """(N, 3) float64 positions of frame ``i``."""
        return self.mesh(i).vertices

    def check_same_topology(self, mesh, path):
        first = self.paths[0]
        if len(mesh.vertices) != self.n_vertices:
            raise InputError(f"{path}: {len(mesh.vertices)} vertices, but {first} has "
                             f"{self.n_vertices}; frames must correspond vertex by vertex")
        if mesh.faces is not self.first.faces and not np.array_equal(mesh.faces, self.first.faces):
            raise InputError(f"{path}: faces differ from those of {first}")
        return mesh
