"""``clothtool export``: the deformed mesh of one pair as a PLY coloured by a field.

The face field goes in twice: as a float face property (its value, for analysis) and as
``red green blue`` uchar face colours from viridis (:mod:`clothtool.results.colormap`),
which MeshLab shows. Blender's PLY importer reads only vertex colours, so by default the
vertices are coloured too, from the average of the incident faces' values weighted by their
deformed area. A vertex field (``/vertex/<name>``) gives a vertex property and vertex colours.
NaN (flagged) values are grey. A tetrahedral result (``/tet/<name>``) is exported as its
boundary surface (the triangles of one tetrahedron only), each triangle carrying the value
of its tetrahedron.
"""

import numpy as np

from clothtool.errors import InputError
from clothtool.results.colormap import colorize, value_range
from clothtool.io.result import open_result
from clothtool.vertex_average import VertexAverager


def parse_range(spec):
    """'LO:HI' → (lo, hi) floats with lo < hi; None → None (the data's range)."""
    if spec is None:
        return None
    try:
        lo, hi = (float(v) for v in spec.split(":"))
    except ValueError:
        raise InputError(f"{spec!r} is not LO:HI (for example 0.9:1.1)",
                         keyword="color_range") from None
    if not lo < hi:
        raise InputError("LO must be below HI", keyword="color_range", value=spec)
    return lo, hi


def triangle_areas(x, faces):
    """Area of each triangle: ½‖(x1 − x0) × (x2 − x0)‖."""
    e1 = x[faces[:, 1]] - x[faces[:, 0]]
    e2 = x[faces[:, 2]] - x[faces[:, 0]]
    return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


def field_values(h5, pair, field, component):
    """(values, where, name) of pair ``pair`` (global index): the ``component``-th component
    of ``/face/<field>``, ``/tet/<field>`` or ``/vertex/<field>`` (where = the group), and its
    property name (``field``, or ``field_<component>`` for a field with several)."""
    offset = int(h5.attrs.get("pair_offset", 0))
    n_pairs = len(h5["pairs"])
    if not offset <= pair < offset + n_pairs:
        raise InputError(f"not in {h5.filename} (pairs {offset}..{offset + n_pairs - 1})",
                         keyword="pair", value=pair)
    for where in ("face", "tet", "vertex"):
        if where in h5 and field in h5[where]:
            ds = h5[where][field]
            values = ds[pair - offset].reshape(ds.shape[1], -1)
            if not 0 <= component < values.shape[1]:
                raise InputError(f"{h5.filename}: {where}/{field} has {values.shape[1]} "
                                 f"component(s), 0..{values.shape[1] - 1}", keyword="component",
                                 value=component)
            name = field if values.shape[1] == 1 else f"{field}_{component}"
            return values[:, component].astype(np.float64), where, name
    available = [f"{g}/{n}" for g in ("face", "tet", "vertex") if g in h5 for n in h5[g]]
    raise InputError(f"{field!r} is not in {h5.filename}; available: {', '.join(available)}",
                     keyword="field")


def export_ply(h5_path, output, *, pair=0, field="stretch", component=0, color_range=None,
               vertex_colors=True, binary=True):
    """Write the deformed frame of ``pair`` with ``field`` as property and colours to
    ``output`` (PLY, atomic). Returns (property name, (lo, hi) of the colour scale)."""
    from clothtool.io.h5 import check_output_path
    from clothtool.io.ply import write_ply

    check_output_path(output)
    with open_result(h5_path) as h5:
        values, where, name = field_values(h5, pair, field, component)
        ref, deformed = (int(v) for v in h5["pairs"][pair - int(h5.attrs.get("pair_offset", 0))])
        if "frame_vertices" not in h5:
            raise InputError(f"{h5_path}: no /frame_vertices; analyse the sequence again")
        x = h5["frame_vertices"][deformed]
        if where == "tet":
            from clothtool.io.tetmesh import boundary_faces

            faces, owner = boundary_faces(h5["mesh/vertices"][:], h5["mesh/tets"][:])
            values, where = values[owner], "face"
        else:
            faces = h5["mesh/faces"][:]
    lo, hi = color_range or value_range(values)
    vprops, fprops = {}, {}
    if where == "face":
        fprops[name] = values.astype(np.float32)
        rgb = colorize(values, lo, hi)
        fprops.update(red=rgb[:, 0], green=rgb[:, 1], blue=rgb[:, 2])
        if vertex_colors:
            averaged = VertexAverager(faces, len(x))(values, triangle_areas(x.astype(np.float64), faces))
            vrgb = colorize(averaged, lo, hi)
            vprops.update(red=vrgb[:, 0], green=vrgb[:, 1], blue=vrgb[:, 2])
    else:
        vrgb = colorize(values, lo, hi)
        vprops.update({name: values.astype(np.float32), "red": vrgb[:, 0], "green": vrgb[:, 1],
                       "blue": vrgb[:, 2]})
    comments = [f"clothtool export of {h5_path}: pair {pair} (frame {ref} to frame {deformed})",
                f"{where} property {name}; viridis colours over [{lo:.6g}, {hi:.6g}], grey = NaN"]
    write_ply(output, x, faces, vertex_properties=vprops, face_properties=fprops, binary=binary,
              comments=comments)
    return name, (lo, hi)
