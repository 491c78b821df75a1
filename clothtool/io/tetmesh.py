"""Reading tetrahedral meshes: VTK XML unstructured grids (.vtu), legacy VTK unstructured
grids (.vtk) and Gmsh (.msh, formats 2.2 and 4.1) through meshio, TetGen (.node + .ele) with
a reader of ours (meshio's needs a .ele of the same name beside each .node; a sequence of
.node frames often shares one .ele).

Only ``tetra`` cells are kept, in file order; other cells (triangles, lines, quadratic
tetrahedra, …) are counted and ignored. Every failure is an :class:`InputError` naming the
file, whatever the underlying reader raised.
"""

import contextlib
import io
import os
import re
from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError
from clothtool.io.frames import TET_EXTENSIONS, FrameReader

FORMATS = dict(zip(TET_EXTENSIONS, (("vtu", "VTK XML unstructured grid"),
                                     ("vtk", "legacy VTK file"), ("gmsh", "Gmsh mesh"),
                                     ("tetgen", "TetGen .node file"))))


@dataclass
class TetMesh:
    """One frame: ``vertices`` (N, 3) float64, ``tets`` (M, 4) int64, and ``other_cells``,
    the number of cells of other types that were ignored; ``ele`` the TetGen .ele read."""

    vertices: np.ndarray
    tets: np.ndarray
    other_cells: int = 0
    ele: str | None = None


def read_tet_mesh(path, reuse=None):
    """Read one tetrahedral mesh file. ``reuse``: a :class:`TetMesh` read before (the first
    frame); a TetGen frame that shares its .ele file does not parse it again."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise InputError(f"{path}: not a tetrahedral mesh file (expected "
                         f"{', '.join(TET_EXTENSIONS)})")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a folder")
    if not os.path.isfile(path):
        raise InputError(f"{path}: no such file")
    if ext == ".node":
        return _read_tetgen(path, reuse)
    return _read_meshio(path, *FORMATS[ext])


def _reason(exc):
    text = " ".join(str(exc).split())
    if isinstance(exc, MemoryError):
        return "out of memory (is a count in the file wrong?)"
    return (f"{type(exc).__name__}: {text}" if text else type(exc).__name__)[:300]


@contextlib.contextmanager
def _address_space_for(path):
    """Cap this process's address space at its current size plus 1 GiB plus 64× the file's
    size while meshio reads ``path``: a corrupted count or tag makes some of its readers
    allocate (and fill) arrays of that size, e.g. Gmsh 4.1's node-tag table of max(tag) + 1
    entries, which would take the machine's memory for minutes; with the cap it is an
    immediate MemoryError. Linux only (/proc); elsewhere nothing is capped."""
    try:
        import resource

        with open("/proc/self/statm") as fh:
            size = int(fh.read().split()[0]) * resource.getpagesize()
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        yield
        return
    cap = size + (1 << 30) + 64 * os.path.getsize(path)
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    if soft != resource.RLIM_INFINITY and soft <= cap:
        yield
        return
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _read_meshio(path, fmt, label):
    import importlib

    # The format's own reader: meshio.read() prints and calls sys.exit(1) on a ReadError.
    reader = importlib.import_module(f"meshio.{fmt}").read
    try:
        # meshio prints warnings with rich
        with contextlib.redirect_stderr(io.StringIO()), _address_space_for(path):
            mesh = reader(path)
        points = np.asarray(mesh.points, dtype=np.float64)
        blocks = [(block.type, np.asarray(block.data)) for block in mesh.cells]
    except Exception as exc:  # meshio raises many types on broken files; all mean "bad input"
        raise InputError(f"{path}: cannot read as {label}: {_reason(exc)}") from None
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"{path}: points of shape {points.shape}; 3D points are needed")
    tets = [data for kind, data in blocks if kind == "tetra"]
    other = {}
    for kind, data in blocks:
        if kind != "tetra":
            other[kind] = other.get(kind, 0) + len(data)
    if not tets or not sum(len(t) for t in tets):
        found = ", ".join(f"{n} {kind}" for kind, n in other.items()) or "none"
        raise InputError(f"{path}: no tetrahedra in the file (cells: {found})")
    try:
        tets = np.concatenate(tets).astype(np.int64, copy=False).reshape(-1, 4)
    except (ValueError, TypeError) as exc:  # blocks of another shape than (k, 4)
        raise InputError(f"{path}: tetrahedra of an unexpected shape: {_reason(exc)}") from None
    return TetMesh(points, _checked_indices(path, tets, len(points)), sum(other.values()))


def _checked_indices(path, tets, n):
    if tets.size and (tets.min() < 0 or tets.max() >= n):
        bad = tets.min() if tets.min() < 0 else tets.max()
        raise InputError(f"{path}: tetrahedron vertex index {bad} is outside 0..{n - 1}")
    return np.ascontiguousarray(tets)


# ---------------------------------------------------------------- TetGen

_COMMENT = re.compile(rb"#[^\n]*")


def _numbers(path, data, what):
    """The whitespace-separated tokens of a TetGen file, comments stripped."""
    tokens = _COMMENT.sub(b"", data).split()
    if not tokens:
        raise InputError(f"{path}: empty {what} file")
    return tokens


def _ints(path, tokens, count, what):
    try:
        return [int(t) for t in tokens[:count]]
    except ValueError:
        raise InputError(f"{path}: {what} header is not {count} integers") from None


def _table(path, tokens, rows, cols, dtype, what):
    if len(tokens) < rows * cols:
        raise InputError(f"{path}: {what} has {len(tokens)} numbers, the header announces "
                         f"{rows} rows of {cols}")
    try:
        values = np.array(tokens[:rows * cols], dtype=np.float64).reshape(rows, cols)
    except ValueError:
        raise InputError(f"{path}: {what} holds something that is not a number") from None
    if dtype is not np.float64:
        if not np.isfinite(values).all() or (values != np.round(values)).any():
            raise InputError(f"{path}: {what} holds a non-integer index")
        values = values.astype(dtype)
    return values


def _read_node(path):
    with open(path, "rb") as fh:
        tokens = _numbers(path, fh.read(), ".node")
    if len(tokens) < 4:
        raise InputError(f"{path}: .node header needs 4 numbers (points, dimension, "
                         "attributes, boundary markers)")
    n, dim, attrs, markers = _ints(path, tokens, 4, ".node")
    if dim != 3 or n < 0 or attrs < 0 or markers not in (0, 1):
        raise InputError(f"{path}: .node header '{n} {dim} {attrs} {markers}' is not "
                         "N 3 ATTRIBUTES 0|1")
    table = _table(path, tokens[4:], n, 4 + attrs + markers, np.float64, "the point list")
    numbers = table[:, 0]
    base = int(numbers[0]) if n else 0
    if not np.array_equal(numbers, base + np.arange(n)) or base not in (0, 1):
        raise InputError(f"{path}: points are not numbered consecutively from 0 or 1")
    return np.ascontiguousarray(table[:, 1:4]), base


def _read_ele(path, base, n):
    if not os.path.isfile(path):
        raise InputError(f"{path}: no such file")
    with open(path, "rb") as fh:
        tokens = _numbers(path, fh.read(), ".ele")
    if len(tokens) < 3:
        raise InputError(f"{path}: .ele header needs 3 numbers (tetrahedra, nodes per "
                         "tetrahedron, region attribute)")
    m, per, region = _ints(path, tokens, 3, ".ele")
    if m < 0 or per not in (4, 10) or region not in (0, 1):
        raise InputError(f"{path}: .ele header '{m} {per} {region}' is not M 4|10 0|1")
    if m == 0:
        raise InputError(f"{path}: no tetrahedra in the file")
    table = _table(path, tokens[3:], m, 1 + per + region, np.int64, "the tetrahedron list")
    return _checked_indices(path, np.ascontiguousarray(table[:, 1:5]) - base, n)  # corners first


def ele_path(node_path):
    """The .ele of a .node frame: the one of the same name, else the only .ele in its folder."""
    own = os.path.splitext(node_path)[0] + ".ele"
    if os.path.isfile(own):
        return own
    folder = os.path.dirname(node_path) or "."
    found = sorted(f for f in os.listdir(folder) if f.lower().endswith(".ele"))
    if len(found) == 1:
        return os.path.join(os.path.dirname(node_path), found[0])
    if not found:
        raise InputError(f"{node_path}: no {os.path.basename(own)} and no other .ele file "
                         "beside it")
    raise InputError(f"{node_path}: no {os.path.basename(own)}, and several .ele files beside "
                     f"it ({', '.join(found[:3])}{', …' if len(found) > 3 else ''})")


def _read_tetgen(path, reuse):
    vertices, base = _read_node(path)
    ele = ele_path(path)
    if reuse is not None and reuse.ele is not None and os.path.samefile(reuse.ele, ele):
        tets = reuse.tets
    else:
        tets = _read_ele(ele, base, len(vertices))
    return TetMesh(vertices, tets, 0, ele)


class TetFrameReader(FrameReader):
    """Reads the frames of a tetrahedral sequence against the first: the same vertex count
    and the same tetrahedra (InputError naming both files otherwise)."""

    cells, cell_word = "tets", "tetrahedra"

    read = staticmethod(read_tet_mesh)

    @property
    def tets(self):
        return self.first.tets


def boundary_faces(x, tets):
    """The boundary surface of a tetrahedral mesh: the triangles that belong to one
    tetrahedron only, oriented with their normal away from it (by the positions ``x``).
    Returns (faces (K, 3) int64, owner (K,): the tetrahedron of each)."""
    tets = np.asarray(tets, np.int64)
    opposite = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])  # face opposite corner i
    faces = tets[:, opposite].reshape(-1, 3)
    owner = np.repeat(np.arange(len(tets)), 4)
    apex = tets.reshape(-1)
    _, first, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True,
                                 return_counts=True)
    keep = np.sort(first[counts == 1])
    faces, owner, apex = faces[keep], owner[keep], apex[keep]
    a, b, c = x[faces[:, 0]], x[faces[:, 1]], x[faces[:, 2]]
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), x[apex] - a) > 0
    faces[inward] = faces[inward][:, [0, 2, 1]]
    return faces, owner
