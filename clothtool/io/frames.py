"""Finding the frames of a sequence: a folder, a glob, or a list of files, in natural order."""

import glob
import os
import re

import numpy as np

from clothtool.errors import InputError

_DIGITS = re.compile(r"(\d+)")
TET_EXTENSIONS = (".vtu", ".vtk", ".msh", ".node")  # as clothtool.io.tetmesh (not imported: start-up)


def is_tet_path(path):
    """Whether ``path`` names a tetrahedral mesh file (by its extension)."""
    return os.path.splitext(os.fspath(path))[1].lower() in TET_EXTENSIONS


def natural_key(path):
    """Sort key that orders embedded numbers by value: ``f2.ply`` before ``f10.ply``."""
    parts = _DIGITS.split(os.path.basename(path))
    return [(0, int(p), "") if p.isdigit() else (1, 0, p.lower()) for p in parts], path


def discover_frames(inputs):
    """Resolve ``inputs`` (a path, a glob or a list of them) to an ordered list of frame files.

    A folder contributes its ``*.ply`` files (case-insensitive) or, if it has none, the
    files of the one tetrahedral mesh format it holds (``.vtu``, ``.vtk``, ``.msh`` or TetGen
    ``.node``); a glob its matches; each folder or glob is sorted naturally, explicit files
    keep the order given.
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    frames = []
    for item in map(os.fspath, inputs):
        if os.path.isdir(item):
            files = [f for f in os.listdir(item) if os.path.isfile(os.path.join(item, f))]
            found = [f for f in files if f.lower().endswith(".ply")]
            if not found:
                kinds = sorted({os.path.splitext(f)[1].lower() for f in files}
                               & set(TET_EXTENSIONS))
                if len(kinds) > 1:
                    raise InputError(f"{item}: folder holds several mesh formats "
                                     f"({', '.join(kinds)}); pass a glob such as "
                                     f"'{os.path.join(item, '*' + kinds[0])}'")
                found = [f for f in files if kinds and f.lower().endswith(kinds[0])]
            if not found:
                raise InputError(f"{item}: folder contains no .ply files "
                                 f"(nor {', '.join(TET_EXTENSIONS)} tetrahedral meshes)")
            frames.extend(sorted((os.path.join(item, f) for f in found), key=natural_key))
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
    return frames


class FrameReader:
    """Reads the frames of a sequence against the topology of the first.

    Every frame must have the first frame's vertex count and faces; a face block
    that is byte-identical to the first frame's is not parsed again.
    """

    def __init__(self, paths):
        from clothtool.io.ply import read_ply

        self._read_ply = read_ply
        self.paths = list(paths)
        self.first = read_ply(self.paths[0])
        if len(self.first.faces) == 0:
            raise InputError(f"{self.paths[0]}: mesh has no faces")

    @property
    def faces(self):
        return self.first.faces

    @property
    def n_vertices(self):
        return len(self.first.vertices)

    def mesh(self, i):
        """The :class:`~clothtool.io.ply.PlyMesh` of frame ``i``, checked against frame 0."""
        if i == 0:
            return self.first
        return self.check_same_topology(self._read_ply(self.paths[i], reuse=self.first),
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
