"""Finding the frames of a sequence: a folder, a glob, or a list of files, in natural order.

A sequence is in one format, known from the extension: ``.obj`` files are read as Wavefront
OBJ (:mod:`clothtool.io.obj`), ``.vtu``, ``.vtk``, ``.msh`` and ``.node`` as tetrahedral meshes
(:mod:`clothtool.io.tetmesh`, by the tetrahedral analysis), anything else as PLY
(:mod:`clothtool.io.ply`)."""

import glob
import os
import re

import numpy as np

from clothtool.errors import InputError

_DIGITS = re.compile(r"(\d+)")
MESH_EXTENSIONS = (".ply", ".obj")
TET_EXTENSIONS = (".vtu", ".vtk", ".msh", ".node")  # as clothtool.io.tetmesh (not imported: start-up)
FRAME_EXTENSIONS = MESH_EXTENSIONS + TET_EXTENSIONS


def mesh_format(path):
    """'obj' for a ``.obj`` file (any case), the extension of a tetrahedral mesh file
    ('vtu', 'vtk', 'msh', 'node'), else 'ply'."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    return ext[1:] if ext in (".obj", *TET_EXTENSIONS) else "ply"


def is_tet_path(path):
    """Whether ``path`` names a tetrahedral mesh file (by its extension)."""
    return os.path.splitext(os.fspath(path))[1].lower() in TET_EXTENSIONS


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

    A folder contributes its ``*.ply`` or ``*.obj`` files, or its tetrahedral meshes (``.vtu``,
    ``.vtk``, ``.msh`` or TetGen ``.node``; case-insensitive; one format), a glob its matches;
    each folder or glob is sorted naturally, explicit files keep the order given. All frames
    must be in one format.
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    frames = []
    for item in map(os.fspath, inputs):
        if os.path.isdir(item):
            found = [os.path.join(item, f) for f in os.listdir(item)
                     if f.lower().endswith(FRAME_EXTENSIONS) and os.path.isfile(os.path.join(item, f))]
            if not found:
                raise InputError(f"{item}: folder contains no .ply or .obj files (nor .vtu, .vtk, "
                                 ".msh or .node tetrahedral meshes)")
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
        order = [ext[1:] for ext in FRAME_EXTENSIONS]
        a, b = sorted(formats, key=order.index)[:2]
        raise InputError(f"{what} both .{a} and .{b} files ({os.path.basename(formats[a])}, "
                         f"{os.path.basename(formats[b])}); a sequence is in one format")


class FrameReader:
    """Reads the frames of a sequence against the topology of the first.

    Every frame must have the first frame's vertex count and cells (``faces``; ``tets`` for
    :class:`~clothtool.io.tetmesh.TetFrameReader`); a face block that is byte-identical to the
    first frame's is not parsed again.
    """

    cells, cell_word = "faces", "faces"

    def __init__(self, paths):
        self.paths = list(paths)
        self.first = self.read(self.paths[0])
        if len(getattr(self.first, self.cells)) == 0:
            raise InputError(f"{self.paths[0]}: mesh has no {self.cell_word}")

    read = staticmethod(read_mesh)  # (path, reuse=None) → mesh

    @property
    def faces(self):
        return self.first.faces

    @property
    def n_vertices(self):
        return len(self.first.vertices)

    def mesh(self, i):
        """The mesh of frame ``i``, checked against frame 0."""
        if i == 0:
            return self.first
        return self.check_same_topology(self.read(self.paths[i], reuse=self.first), self.paths[i])

    def positions(self, i):
        """(N, 3) float64 positions of frame ``i``."""
        return self.mesh(i).vertices

    def check_same_topology(self, mesh, path):
        first = self.paths[0]
        if len(mesh.vertices) != self.n_vertices:
            raise InputError(f"{path}: {len(mesh.vertices)} vertices, but {first} has "
                             f"{self.n_vertices}; frames must correspond vertex by vertex")
        cells, first_cells = getattr(mesh, self.cells), getattr(self.first, self.cells)
        if cells is not first_cells and not np.array_equal(cells, first_cells):
            raise InputError(f"{path}: {self.cell_word} differ from those of {first}")
        return mesh
