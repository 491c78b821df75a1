"""An XDMF (version 2) file beside an analysis result, so that ParaView opens it as a time series.

``out.xdmf`` next to ``out.h5`` holds only XML; the numbers stay in the HDF5 file, which it
names without a folder (keep the two together). One grid per pair, at time = the pair's
deformed frame index: triangles ``/mesh/faces``, points ``/frame_vertices[d]`` (the deformed
frame d), and every ``/face/<name>`` (cell data) and ``/vertex/<name>`` (point data) of that
pair. A field of k components per item is one array with k components (2×2 tensors:
xx, xy, yx, yy, row-major; 3-vectors as Vector, 3×3 as Tensor). Each pair is a HyperSlab of
its dataset, so nothing is copied; the reader is VTK's vtkXdmfReader ("XDMF Reader" in
ParaView).
"""

import os
from html import escape  # (xml.sax.saxutils would import urllib and ssl: 25 ms of start-up)

import numpy as np

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path

CENTERS = (("face", "Cell"), ("vertex", "Node"))
_NUMBER_TYPES = {"f": "Float", "i": "Int", "u": "UInt"}


def xdmf_path(h5_path):
    """``out.h5`` → ``out.xdmf`` (same folder)."""
    path = os.path.splitext(os.fspath(h5_path))[0] + ".xdmf"
    if os.path.abspath(path) == os.path.abspath(h5_path):
        raise InputError(f"{h5_path}: an HDF5 result cannot be named .xdmf")
    return path


def write_xdmf(h5_path, path=None):
    """Write the XDMF of the result ``h5_path`` to ``path`` (default :func:`xdmf_path`),
    atomically (temporary name, then rename). Returns the path written."""
    import h5py

    path = path or xdmf_path(h5_path)
    with h5py.File(h5_path, "r") as h5:
        text = xdmf_text(h5, os.path.basename(h5_path))
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
    return path


def _number_type(dtype):
    dtype = np.dtype(dtype)
    if dtype.itemsize == 1:
        return "UChar" if dtype.kind == "u" else "Char", 1
    return _NUMBER_TYPES[dtype.kind], dtype.itemsize


def _comment(text):
    """Text that is safe inside an XML comment (no "--")."""
    return escape(text, quote=False).replace("--", "- -")


def _slab(h5_name, dataset, index, comment):
    """DataItem selecting ``dataset[index]`` (all of its other axes) by HyperSlab.

    The XML comment comes first so that VTK's reader has a per-item key for its geometry
    cache (without it, it logs "no caching possible" for every time step)."""
    shape = dataset.shape
    rank = len(shape)
    start = [index] + [0] * (rank - 1)
    count = [1, *shape[1:]]
    number, precision = _number_type(dataset.dtype)
    dims = " ".join(map(str, shape[1:]))
    return (f'<DataItem ItemType="HyperSlab" Dimensions="{dims}"><!-- {_comment(comment)} -->\n'
            f'  <DataItem Dimensions="3 {rank}" Format="XML">'
            f'{" ".join(map(str, start + [1] * rank + count))}</DataItem>\n'
            f'  <DataItem Dimensions="{" ".join(map(str, shape))}" NumberType="{number}" '
            f'Precision="{precision}" Format="HDF">{escape(h5_name, quote=False)}:{dataset.name}</DataItem>\n'
            f'</DataItem>')


def _attribute(h5_name, dataset, p, center):
    """<Attribute> of pair ``p`` of a (P, n, …) dataset: Scalar, Vector (3), Tensor (3×3),
    else Matrix with prod(…) components (a Function reshapes it to n × 1 × k, the shape for
    which vtkXdmfReader makes k components per item)."""
    item = dataset.shape[2:]
    k = int(np.prod(item, dtype=np.int64))
    slab = _slab(h5_name, dataset, p, f"{dataset.name}[{p}]")
    name = '"' + escape(dataset.name.rsplit("/", 1)[1]) + '"'
    if k == 1:
        kind = "Scalar"
    elif item == (3,):
        kind = "Vector"
    elif item == (3, 3):
        kind = "Tensor"
    else:
        kind = "Matrix"
        slab = (f'<DataItem ItemType="Function" Function="$0" '
                f'Dimensions="{dataset.shape[1]} 1 {k}">\n{slab}\n</DataItem>')
    return f'<Attribute Name={name} AttributeType="{kind}" Center="{center}">\n{slab}\n</Attribute>'


def _attribute_keys(h5):
    """(dataset path, XDMF center) of the face and vertex datasets in ``h5``: the registry's
    fields and their vertex averages in registry order, then any others."""
    from clothtool.analysis.fields import REGISTRY
    from clothtool.analysis.output.vertex_average import SUFFIX

    centers = dict(CENTERS)
    known = [f.key for f in REGISTRY] + [f"vertex/{f.name}{SUFFIX}" for f in REGISTRY if f.averageable]
    found = [f"{group}/{name}" for group in centers if group in h5 for name in h5[group]]
    keys = [k for k in known if k in found] + [k for k in found if k not in known]
    return [(key, centers[key.split("/")[0]]) for key in keys]


def xdmf_text(h5, h5_name):
    """The XDMF document of an open result whose file is called ``h5_name``."""
    if "frame_vertices" not in h5:
        raise InputError(f"{h5.filename}: no /frame_vertices; this result predates XDMF "
                         "support, analyse the sequence again")
    faces, positions, pairs = h5["mesh/faces"], h5["frame_vertices"], h5["pairs"][:]
    n_pairs, m, n = len(pairs), faces.shape[0], positions.shape[1]
    counts = {"face": m, "vertex": n}
    fields = [(h5[key], center) for key, center in _attribute_keys(h5)
              if h5[key].ndim >= 2 and h5[key].shape[:2] == (n_pairs, counts[key.split("/")[0]])]
    f_number, f_precision = _number_type(faces.dtype)
    topology = (f'<Topology TopologyType="Triangle" NumberOfElements="{m}">\n'
                f'  <DataItem Dimensions="{m} 3" NumberType="{f_number}" Precision="{f_precision}" '
                f'Format="HDF">{escape(h5_name, quote=False)}:/mesh/faces</DataItem>\n</Topology>')
    grids = []
    for p, (r, d) in enumerate(pairs):
        geometry = _slab(h5_name, positions, int(d), f"{h5_name}:/frame_vertices[{int(d)}]")
        attributes = "\n".join(_attribute(h5_name, ds, p, center) for ds, center in fields)
        grids.append(f'<Grid Name="pair_{p}" GridType="Uniform">\n'
                     f'<!-- pair {p}: frame {int(r)} (reference) to frame {int(d)} -->\n'
                     f'<Time Value="{int(d)}"/>\n{topology}\n'
                     f'<Geometry GeometryType="XYZ">\n{geometry}\n</Geometry>\n{attributes}\n</Grid>')
    body = "\n".join(grids)
    return ('<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
            '<Xdmf Version="2.0">\n<Domain>\n'
            '<Grid Name="pairs" GridType="Collection" CollectionType="Temporal">\n'
            f'{body}\n</Grid>\n</Domain>\n</Xdmf>\n')
