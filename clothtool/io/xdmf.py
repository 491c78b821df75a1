"""An XDMF (version 2) file beside an analysis result, so that ParaView opens it as a time series.

``out.xdmf`` next to ``out.h5`` holds only XML; the numbers stay in the HDF5 file, which it
names without a folder (keep the two together). One grid per pair, at time = the pair's
deformed frame index: triangles ``/mesh/faces``, points ``/frame_vertices[d]`` (the deformed
frame d), and every ``/face/<name>`` (cell data) and ``/vertex/<name>`` (point data) of that
pair. A field of k components per item is one array with k components (2×2 tensors:
xx, xy, yx, yy, row-major; 3-vectors as Vector, 3×3 as Tensor).

Each array of a pair is a whole HDF5 dataset: a *view* in the group ``/xdmf`` of the result,
``/xdmf/pair_<p>/points`` = ``/frame_vertices[d]`` and ``/xdmf/pair_<p>/<group>/<name>`` =
``/<group>/<name>[p]``. A view is an HDF5 virtual dataset (HDF5 ≥ 1.10) that maps onto the
stored rows: it holds no numbers (about 1 kB of metadata each) and changes no other dataset.
The XDMF addresses only whole datasets because ParaView's default XDMF reader (Xdmf3, in
ParaView 5.11) cannot read a ``HyperSlab`` DataItem, while the legacy "XDMF Reader"
(vtkXdmfReader) reads both forms; with views, both readers load every step.

Cell topologies are listed in :data:`TOPOLOGIES` (triangles ``/mesh/faces`` with cell data
``/face``; a tetrahedral result's ``/mesh/tets`` with cell data ``/tet``). A result with
several of them gets, per step, a spatial collection of one grid each.
"""

import os
from html import escape  # (xml.sax.saxutils would import urllib and ssl: 25 ms of start-up)

import numpy as np

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path
from clothtool.io.result import VIEWS

TOPOLOGIES = (("mesh/faces", "face", "Triangle"), ("mesh/tets", "tet", "Tetrahedron"))
POINT_GROUP = "vertex"
CENTERS = tuple((group, "Cell") for _, group, _ in TOPOLOGIES) + ((POINT_GROUP, "Node"),)
_NUMBER_TYPES = {"f": "Float", "i": "Int", "u": "UInt"}


def xdmf_path(h5_path):
    """``out.h5`` → ``out.xdmf`` (same folder)."""
    path = os.path.splitext(os.fspath(h5_path))[0] + ".xdmf"
    if os.path.abspath(path) == os.path.abspath(h5_path):
        raise InputError(f"{h5_path}: an HDF5 result cannot be named .xdmf")
    return path


def write_xdmf(h5_path, path=None):
    """Write the XDMF of the result ``h5_path`` to ``path`` (default :func:`xdmf_path`),
    atomically (temporary name, then rename); (re)writes the views ``/xdmf`` in the result.
    Returns the path written."""
    import h5py

    path = path or xdmf_path(h5_path)
    with h5py.File(h5_path, "r+") as h5:
        text = xdmf_text(h5, os.path.basename(h5_path))
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
    return path


def _number_type(dtype):
    dtype = np.dtype(dtype)
    if dtype.itemsize == 1:
        return "UChar" if dtype.kind == "u" else "Char", 1
    return _NUMBER_TYPES[dtype.kind], dtype.itemsize


def _kind(item):
    """(AttributeType, view item shape) of a field whose items have shape ``item``: Scalar,
    Vector (3), Tensor (3×3), else Matrix with prod(item) components, stored as 1 × k (the
    shape for which both readers make k components per item)."""
    k = int(np.prod(item, dtype=np.int64))
    if k == 1:
        return "Scalar", ()
    if item == (3,):
        return "Vector", (3,)
    if item == (3, 3):
        return "Tensor", (3, 3)
    return "Matrix", (1, k)


class _Views:
    """Creates the views: virtual datasets, each one row of a stored dataset (reshaped), made
    with h5py's low-level API: the 490 views of a 49-pair result take about 20 ms, a quarter of
    the time through ``h5py.VirtualLayout``."""

    def __init__(self, h5):
        from h5py import h5d, h5p, h5s, h5t

        self.h5d, self.h5p, self.h5s, self.h5t = h5d, h5p, h5s, h5t
        self.root = h5.id
        self.lcpl = h5p.create(h5p.LINK_CREATE)
        self.lcpl.set_create_intermediate_group(True)
        self.sources = {}

    def add(self, name, dataset, row, shape):
        source = self.sources.get(dataset.name)
        if source is None:
            source = self.sources[dataset.name] = (
                self.h5s.create_simple(dataset.shape), dataset.name.encode(),
                self.h5t.py_create(dataset.dtype), (0,) * (dataset.ndim - 1),
                (1, *dataset.shape[1:]))
        space, path, type_id, zeros, count = source
        space.select_hyperslab((row, *zeros), count)
        view = self.h5s.create_simple(shape)
        dcpl = self.h5p.create(self.h5p.DATASET_CREATE)
        dcpl.set_virtual(view, b".", path, space)
        self.h5d.create(self.root, name.encode(), type_id, view, dcpl=dcpl, lcpl=self.lcpl)


def _item(h5_name, name, shape, dtype):
    number, precision = _number_type(dtype)
    return (f'<DataItem Dimensions="{" ".join(map(str, shape))}" NumberType="{number}" '
            f'Precision="{precision}" Format="HDF">{escape(h5_name, quote=False)}:/{name}</DataItem>')


def _fields(h5, n_pairs, counts):
    """[(dataset, group, short name, center, AttributeType, view shape)] of the per-pair cell
    and point data, in :func:`_attribute_keys` order."""
    out = []
    for key, center in _attribute_keys(h5):
        group, name = key.split("/")
        if group not in counts:
            continue
        ds = h5[key]
        shape = ds.shape
        if len(shape) >= 2 and shape[:2] == (n_pairs, counts[group]):
            kind, item = _kind(shape[2:])
            out.append((ds, group, name, center, kind, (shape[1], *item)))
    return out


def _attribute_keys(h5):
    """(dataset path, XDMF center) of the face and vertex datasets in ``h5``: the registry's
    fields and their vertex averages in registry order, then any others."""
    from clothtool.fields import REGISTRY
    from clothtool.vertex_average import SUFFIX

    centers = dict(CENTERS)
    known = [f.key for f in REGISTRY] + [f"vertex/{f.name}{SUFFIX}" for f in REGISTRY if f.averageable]
    found = [f"{group}/{name}" for group in centers if group in h5 for name in h5[group]]
    keys = [k for k in known if k in found] + [k for k in found if k not in known]
    return [(key, centers[key.split("/")[0]]) for key in keys]


def xdmf_text(h5, h5_name):
    """The XDMF document of an open result whose file is called ``h5_name``. If the result is
    open for writing, its views ``/xdmf`` are (re)made first; else they must be there."""
    if "frame_vertices" not in h5:
        raise InputError(f"{h5.filename}: no /frame_vertices; this result predates XDMF "
                         "support, analyse the sequence again")
    positions, pairs = h5["frame_vertices"], h5["pairs"][:]
    n_pairs, n = len(pairs), positions.shape[1]
    meshes = [(h5[path], group, kind) for path, group, kind in TOPOLOGIES if path in h5]
    counts = {group: topology.shape[0] for topology, group, _ in meshes}
    counts[POINT_GROUP] = n
    fields = _fields(h5, n_pairs, counts)
    dtypes = {ds.name: ds.dtype for ds, *_ in fields}

    def view_name(p, what):
        return f"{VIEWS}/pair_{p}/{what}"

    if h5.mode == "r+":
        if VIEWS in h5:
            del h5[VIEWS]
        views = _Views(h5)
        for p, (_, d) in enumerate(pairs):
            views.add(view_name(p, "points"), positions, int(d), (n, 3))
            for ds, group, name, _, _, shape in fields:
                views.add(view_name(p, f"{group}/{name}"), ds, p, shape)
    else:
        missing = [view_name(p, what) for p in range(n_pairs)
                   for what in ["points", *(f"{group}/{name}" for _, group, name, *_ in fields)]
                   if view_name(p, what) not in h5]
        if missing:
            raise InputError(f"{h5.filename}: no /{missing[0]}; write the XDMF with the "
                             "result open for writing (clothtool.io.xdmf.write_xdmf)")

    topologies = {group: f'<Topology TopologyType="{kind}" NumberOfElements="{topology.shape[0]}">\n'
                         f'  {_item(h5_name, topology.name[1:], topology.shape, topology.dtype)}\n'
                         f'</Topology>'
                  for topology, group, kind in meshes}
    steps = []
    for p, (r, d) in enumerate(pairs):
        geometry = (f'<Geometry GeometryType="XYZ">\n'
                    f'  {_item(h5_name, view_name(p, "points"), (n, 3), positions.dtype)}\n</Geometry>')
        grids = []
        for _, cells, _ in meshes:
            attributes = "\n".join(
                f'<Attribute Name="{escape(name)}" AttributeType="{kind}" Center="{center}">\n'
                f'  {_item(h5_name, view_name(p, f"{group}/{name}"), shape, dtypes[ds.name])}\n'
                f'</Attribute>'
                for ds, group, name, center, kind, shape in fields if group in (cells, POINT_GROUP))
            grids.append(f'{topologies[cells]}\n{geometry}\n{attributes}')
        if len(grids) == 1:
            body = grids[0]
        else:
            body = "\n".join(f'<Grid Name="{group}" GridType="Uniform">\n{grid}\n</Grid>'
                             for (_, group, _), grid in zip(meshes, grids))
        kind = 'GridType="Uniform"' if len(grids) == 1 else 'GridType="Collection" CollectionType="Spatial"'
        steps.append(f'<Grid Name="pair_{p}" {kind}>\n'
                     f'<!-- pair {p}: frame {int(r)} (reference) to frame {int(d)} -->\n'
                     f'<Time Value="{int(d)}"/>\n{body}\n</Grid>')
    body = "\n".join(steps)
    return ('<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
            '<Xdmf Version="2.0">\n<Domain>\n'
            '<Grid Name="pairs" GridType="Collection" CollectionType="Temporal">\n'
            f'{body}\n</Grid>\n</Domain>\n</Xdmf>\n')
