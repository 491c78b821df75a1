"""PLY meshes in numpy: a validating reader and an atomic writer.

Formats: ascii, binary_little_endian, binary_big_endian; any scalar property type;
polygon faces (fan-triangulated, the triangle → source-face map kept); any extra
vertex properties (normals, colours, ``s t`` / ``u v`` texture coordinates).
Vertex order is the correspondence between frames: nothing is merged or reordered.

Binary vertex blocks are read with one ``np.frombuffer`` at their offset. A face
block that is byte-identical to a known one (``reuse=``) is not parsed again,
which is what makes reading the frames of a sequence cheap.

Every defect is an :class:`~clothtool.errors.InputError` naming the file and the
element: header counts are checked against the file size before anything is
allocated, so a header that declares 10¹² vertices fails at once.
"""

import os
import re
import struct
from dataclasses import dataclass, field

import numpy as np

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path
from clothtool.io.files import reading

SCALAR_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_TYPE_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int",
               "u4": "uint", "f4": "float", "f8": "double"}
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
FACE_LIST_NAMES = ("vertex_indices", "vertex_index")
CORNER_UV_NAMES = ("texcoord",)  # face list of u v per corner, as MeshLab writes it
MAX_HEADER_BYTES = 1 << 20
_PROBE_BYTES = 4096  # read first, so that a large file that is not a PLY is not read whole
REUSED = object()  # marks a face block taken from ``reuse`` without parsing
_END_HEADER = re.compile(rb"(?:^|\n)end_header[ \t\r]*\n")  # the line, not a word in a comment
_END_HEADER_LINE = re.compile(rb"(?:^|\n)end_header[ \t\r]*$")


@dataclass(frozen=True)
class Property:
    name: str
    dtype: str  # numpy type code of the value (of the items, for a list)
    count_dtype: str | None = None  # numpy type code of the list length, None for a scalar

    @property
    def is_list(self):
        return self.count_dtype is not None


@dataclass(frozen=True)
class Element:
    name: str
    count: int
    properties: tuple

    def has_lists(self):
        return any(p.is_list for p in self.properties)

    def scalar_dtype(self, byteorder):
        """Structured numpy dtype of one record (elements without list properties)."""
        return np.dtype([(p.name, byteorder + p.dtype) for p in self.properties])


@dataclass(frozen=True)
class PlyHeader:
    format: str  # 'ascii', 'binary_little_endian' or 'binary_big_endian'
    elements: tuple
    comments: tuple
    size: int  # bytes up to and including the end_header line

    @property
    def byteorder(self):
        return _FORMATS[self.format]

    def element(self, name):
        for el in self.elements:
            if el.name == name:
                return el
        return None


@dataclass
class PlyMesh:
    """A triangle mesh as read from a PLY (or OBJ) file.

    ``faces`` are triangles (polygons fan-triangulated), ``face_source[k]`` is the
    index of the file's polygon that triangle k came from. ``corner_uv[k, j]`` is the
    texture position of corner j of triangle k (PLY face ``texcoord``, OBJ ``vt``): on a
    uv seam one vertex has two.
    """

    vertices: np.ndarray  # (N, 3) float64
    faces: np.ndarray  # (M, 3) int64
    face_source: np.ndarray  # (M,) int64
    vertex_properties: dict = field(default_factory=dict)
    header: PlyHeader | None = None
    face_block: bytes = b""  # raw bytes of the face element, for reuse checks
    corner_uv: np.ndarray | None = None  # (M, 3, 2) per-corner texture coordinates, or None
    corner_uv_missing: np.ndarray | None = None  # (M,) bool: triangles without corner uv
    source_lines: np.ndarray | None = None  # (F,) file line of each source face (OBJ only)
    obj_faces: object = None  # OBJ: what a later frame needs to reuse ``face_block`` (io.obj)

    @property
    def uv(self):
        """(N, 2) float64 texture coordinates (``s t``, ``u v``, …), or None."""
        return uv_of(self.vertex_properties)


def uv_of(vertex_properties):
    for a, b in UV_NAMES:
        if a in vertex_properties and b in vertex_properties:
            return np.stack([vertex_properties[a], vertex_properties[b]], axis=1).astype(np.float64)
    return None


# ---------------------------------------------------------------------------- header


def parse_header(data, path):
    """Parse the header at the start of ``data`` (bytes). Returns a :class:`PlyHeader`."""
    if not data:
        raise InputError(f"{path}: empty file, not a PLY file")
    if not data.startswith(b"ply"):
        raise InputError(f"{path}: not a PLY file (does not start with 'ply')")
    match = _END_HEADER.search(data, 0, MAX_HEADER_BYTES)
    if match is None:
        if _END_HEADER_LINE.search(data, 0, MAX_HEADER_BYTES):
            raise InputError(f"{path}: PLY header has no line break after 'end_header'")
        raise InputError(f"{path}: PLY header has no 'end_header' line")
    raw = data[:match.end()]
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(f"{path}: header line {line}: non-ASCII byte at offset {exc.start}") from None
    lines = [ln.strip() for ln in text.replace("\r", "").split("\n")]
    fmt, elements, comments = None, [], []
    for number, line in enumerate(lines[1:], start=2):
        words = line.split()
        if not words or words[0] in ("end_header",):
            continue
        key = words[0]
        if key in ("comment", "obj_info"):
            comments.append(line[len(key):].strip())
        elif key == "format":
            if len(words) != 3 or words[1] not in _FORMATS:
                raise InputError(f"{path}: header line {number}: unknown PLY format {line!r}")
            fmt = words[1]
        elif key == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise InputError(f"{path}: header line {number}: bad element line {line!r}")
            if any(el[0] == words[1] for el in elements):
                raise InputError(f"{path}: header line {number}: element {words[1]!r} declared twice")
            elements.append([words[1], int(words[2]), []])
        elif key == "property":
            if not elements:
                raise InputError(f"{path}: header line {number}: property before any element")
            prop = _parse_property(words, path, number, line)
            if any(p.name == prop.name for p in elements[-1][2]):
                raise InputError(f"{path}: header line {number}: property {prop.name!r} declared "
                                 f"twice in element {elements[-1][0]!r}")
            elements[-1][2].append(prop)
        else:
            raise InputError(f"{path}: header line {number}: unknown keyword {key!r}")
    if fmt is None:
        raise InputError(f"{path}: PLY header has no 'format' line")
    els = tuple(Element(n, c, tuple(p)) for n, c, p in elements)
    return PlyHeader(fmt, els, tuple(comments), match.end())


def _parse_property(words, path, number, line):
    if len(words) == 3 and words[1] != "list":
        return Property(words[2], _scalar_type(words[1], path, number))
    if len(words) == 5 and words[1] == "list":
        count = _scalar_type(words[2], path, number)
        if count[0] == "f":
            raise InputError(f"{path}: header line {number}: list length type {words[2]!r} is not an integer")
        return Property(words[4], _scalar_type(words[3], path, number), count)
    raise InputError(f"{path}: header line {number}: bad property line {line!r}")


def _scalar_type(name, path, number):
    try:
        return SCALAR_TYPES[name]
    except KeyError:
        raise InputError(f"{path}: header line {number}: unknown property type {name!r}") from None


# ---------------------------------------------------------------------------- reading


def read_ply(path, *, reuse=None):
    """Read a PLY file into a :class:`PlyMesh`.

    ``reuse``: a :class:`PlyMesh` read before; when this file's face block is
    byte-identical to ``reuse.face_block``, its faces are taken without parsing.
    """
    path = os.fspath(path)
    with reading(path, "a PLY file") as fh:
        data = fh.read(_PROBE_BYTES)
        if len(data) == _PROBE_BYTES:  # a large file: is it a PLY before reading it all?
            if not data.startswith(b"ply"):
                parse_header(data, path)  # raises "not a PLY file"
            fh.seek(0)
            data = fh.read()
    return parse_ply(data, path, reuse=reuse)


def parse_ply(data, path="<bytes>", *, reuse=None):
    """Parse PLY ``data`` (bytes); see :func:`read_ply`."""
    header = parse_header(data, path)
    vertex_el = header.element("vertex")
    if vertex_el is None:
        raise InputError(f"{path}: no 'vertex' element")
    names = [p.name for p in vertex_el.properties]
    for axis in "xyz":
        if axis not in names:
            raise InputError(f"{path}: vertex element has no '{axis}' property")
    if vertex_el.has_lists():
        raise InputError(f"{path}: list properties in the vertex element are not supported")
    if header.format == "ascii":
        records, face_rows, face_block = _read_ascii(data, header, path, reuse)
    else:
        records, face_rows, face_block = _read_binary(data, header, path, reuse)
    vertex = records["vertex"]
    vertices = _positions(vertex)
    props = {n: vertex[n] for n in names if n not in ("x", "y", "z")}
    if face_rows is REUSED:
        faces, source = reuse.faces, reuse.face_source
        corner_uv, missing = reuse.corner_uv, reuse.corner_uv_missing
        if len(vertices) < len(reuse.vertices) and len(faces) and faces.max() >= len(vertices):
            i = int(source[np.argmax((faces >= len(vertices)).any(axis=1))])
            raise InputError(f"{path}: face {i} has a vertex index outside 0..{len(vertices) - 1}")
    else:
        rows, texcoord = face_rows if face_rows is not None else (None, None)
        faces, source = _triangulate(rows, len(vertices), path)
        corner_uv, missing = _corner_uv(rows, texcoord, path)
    return PlyMesh(vertices, faces, source, props, header, face_block, corner_uv, missing)


def _texcoord(table):
    for name in CORNER_UV_NAMES:
        if name in table:
            return table[name]
    return None


def _corner_uv(rows, texcoord, path):
    """Per-corner uv (M, 3, 2) of the triangles from a face ``texcoord`` list (u v per corner),
    and which triangles have none (an empty list; NaN there). (None, None) without texcoord."""
    if texcoord is None or rows is None or len(rows) == 0:
        return None, None
    lengths = np.array([len(r) for r in rows], np.int64) if not isinstance(rows, np.ndarray) \
        else np.full(len(rows), rows.shape[1], np.int64)
    if isinstance(texcoord, np.ndarray) and texcoord.ndim == 2:
        sizes = np.full(len(texcoord), texcoord.shape[1], np.int64)
    else:
        sizes = np.array([len(t) for t in texcoord], np.int64)
    bad = (sizes != 2 * lengths) & (sizes != 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{path}: face {i} has {sizes[i]} texcoord values for {lengths[i]} "
                         f"corners, expected {2 * lengths[i]} (u v per corner)")
    flat = np.full((int(lengths.sum()), 2), np.nan)
    has = sizes > 0
    if isinstance(texcoord, np.ndarray) and texcoord.ndim == 2:
        if has.all():
            flat = texcoord.reshape(-1, 2).astype(np.float64)
    elif has.any():
        starts = np.cumsum(lengths) - lengths
        values = np.concatenate([np.asarray(t, np.float64) for t, h in zip(texcoord, has) if h])
        at = np.concatenate([np.arange(s, s + n) for s, n, h in zip(starts, lengths, has) if h])
        flat[at] = values.reshape(-1, 2)
    corners, source = fan(lengths)
    return flat[corners], ~has[source]


def fan(lengths):
    """Fan triangulation of polygons with ``lengths`` corners (each ≥ 3), corners numbered
    consecutively: (corner ids (M, 3) int64, source polygon (M,) int64)."""
    lengths = np.asarray(lengths, np.int64)
    per_face = lengths - 2
    source = np.repeat(np.arange(len(lengths), dtype=np.int64), per_face)
    if len(lengths) and (lengths == lengths[0]).all():
        k = int(lengths[0])
        pattern = np.stack([np.zeros(k - 2, np.int64), np.arange(1, k - 1), np.arange(2, k)], 1)
        ids = (np.arange(len(lengths))[:, None, None] * k + pattern).reshape(-1, 3)
        return ids, source
    starts = np.cumsum(lengths) - lengths
    first = np.repeat(starts, per_face)
    j = np.arange(len(source)) - np.repeat(np.cumsum(per_face) - per_face, per_face) + 1
    return np.stack([first, first + j, first + j + 1], axis=1), source


def _positions(vertex):
    """(N, 3) float64 from the x, y, z columns of a vertex record array. When every property
    has one type (the usual case) the block is viewed as an (N, k) table: one copy."""
    dt = vertex.dtype
    types = {dt.fields[name][0] for name in dt.names}
    if len(types) == 1 and len(vertex):
        table = vertex.view(types.pop()).reshape(len(vertex), len(dt.names))
        cols = [dt.names.index(axis) for axis in "xyz"]
        picked = table[:, cols[0]:cols[0] + 3] if cols == list(range(cols[0], cols[0] + 3)) \
            else table[:, cols]
        return picked.astype(np.float64)
    return np.stack([vertex["x"], vertex["y"], vertex["z"]], axis=1).astype(np.float64)


def _face_property(element, path):
    for p in element.properties:
        if p.is_list and p.name in FACE_LIST_NAMES:
            return p
    raise InputError(f"{path}: face element has no 'vertex_indices' list property")


def _read_binary(data, header, path, reuse):
    """Records of every scalar element, the face rows (list of index arrays or an
    (M, k) array; None if reused) and the raw face block."""
    order = header.byteorder
    minimum = header.size + sum(_min_bytes(el) for el in header.elements)
    if minimum > len(data):
        raise InputError(
            f"{path}: truncated: the header declares "
            + ", ".join(f"{el.count} {el.name}" for el in header.elements)
            + f" (at least {minimum} bytes) but the file has {len(data)} bytes")
    offset, records, face_rows, face_block = header.size, {}, None, b""
    for el in header.elements:
        if el.name == "face":
            _face_property(el, path)
        if not el.has_lists():
            dt = el.scalar_dtype(order)
            size = el.count * dt.itemsize
            if offset + size > len(data):
                raise InputError(f"{path}: truncated in element '{el.name}'")
            records[el.name] = np.frombuffer(data, dt, count=el.count, offset=offset)
            offset += size
            continue
        if el.name == "face" and _same_face_block(data, offset, el, reuse):
            face_block = reuse.face_block
            offset += len(face_block)
            face_rows = REUSED
            continue
        start = offset
        table, offset = _read_binary_lists(data, el, order, offset, path)
        if el.name == "face":
            face_block = data[start:offset]
            face_rows = (table[_face_property(el, path).name], _texcoord(table))
    if offset != len(data):
        raise InputError(f"{path}: {len(data) - offset} unexpected bytes after the last element")
    return records, face_rows, face_block


def _same_face_block(data, offset, element, reuse):
    """True when the face block at ``offset`` is byte-identical to ``reuse``'s."""
    if reuse is None or reuse.header is None or reuse.header.element("face") != element:
        return False
    block = reuse.face_block
    return data[offset:offset + len(block)] == block


def _min_bytes(el):
    size = 0
    for p in el.properties:
        size += np.dtype(p.count_dtype if p.is_list else p.dtype).itemsize
    return el.count * size


def _read_binary_lists(data, el, order, offset, path):
    """Read an element with list properties. Fast path: every list has the length
    of the first record's (one structured ``frombuffer``); else record by record."""
    if el.count == 0:
        return {p.name: [] for p in el.properties}, offset
    lengths, probe = [], offset
    for p in el.properties:  # lengths of the first record's lists
        if p.is_list:
            if probe + np.dtype(p.count_dtype).itemsize > len(data):
                raise InputError(f"{path}: truncated in {el.name} 0")
            n = int(np.frombuffer(data, order + p.count_dtype, 1, probe)[0])
            lengths.append(n)
            probe += np.dtype(p.count_dtype).itemsize + max(n, 0) * np.dtype(p.dtype).itemsize
        else:
            probe += np.dtype(p.dtype).itemsize
    if min(lengths) < 0 or probe > len(data):  # let the record reader say what is wrong
        return _read_binary_records(data, el, order, offset, path)
    fields, it = [], iter(lengths)
    for p in el.properties:
        if p.is_list:
            n = next(it)
            fields.append((p.name + "#n", order + p.count_dtype))
            fields.append((p.name, order + p.dtype, (n,)))
        else:
            fields.append((p.name, order + p.dtype))
    dt = np.dtype(fields)
    if el.count == 0 or offset + el.count * dt.itemsize <= len(data):
        table = np.frombuffer(data, dt, count=el.count, offset=offset)
        uniform = all(np.all(table[p.name + "#n"] == n)
                      for p, n in zip([p for p in el.properties if p.is_list], lengths))
        if uniform:
            return {p.name: table[p.name] for p in el.properties}, offset + el.count * dt.itemsize
    return _read_binary_records(data, el, order, offset, path)


def _read_binary_records(data, el, order, offset, path):
    """Record-by-record reading of a list element with varying list lengths."""
    readers = []
    for p in el.properties:
        if p.is_list:
            readers.append((p.name, struct.Struct(order + np.dtype(p.count_dtype).char),
                            np.dtype(order + p.dtype)))
        else:
            readers.append((p.name, None, np.dtype(order + p.dtype)))
    columns = {p.name: [] for p in el.properties}
    end = len(data)
    for k in range(el.count):
        for name, count_struct, item in readers:
            if count_struct is None:
                if offset + item.itemsize > end:
                    raise InputError(f"{path}: truncated in {el.name} {k} of {el.count}")
                columns[name].append(np.frombuffer(data, item, 1, offset)[0])
                offset += item.itemsize
                continue
            if offset + count_struct.size > end:
                raise InputError(f"{path}: truncated in {el.name} {k} of {el.count}")
            (n,) = count_struct.unpack_from(data, offset)
            offset += count_struct.size
            if n < 0:
                raise InputError(f"{path}: {el.name} {k}: negative list length {n} in '{name}'")
            if offset + n * item.itemsize > end:
                raise InputError(f"{path}: {el.name} {k}: list '{name}' of length {n} runs past "
                                 f"the end of the file (truncated or corrupt)")
            columns[name].append(np.frombuffer(data, item, n, offset))
            offset += n * item.itemsize
    return columns, offset


def _read_ascii(data, header, path, reuse):
    try:
        body = data[header.size:].decode("ascii")
    except UnicodeDecodeError as exc:
        line = data[:header.size + exc.start].count(b"\n") + 1
        raise InputError(f"{path}: line {line}: non-ASCII byte in an ascii PLY body") from None
    # A record takes at least two bytes ("0\n") per property: check before splitting.
    needed = sum(el.count * max(1, len(el.properties)) for el in header.elements)
    if 2 * needed > len(body) + 1:
        raise InputError(
            f"{path}: truncated: the header declares "
            + ", ".join(f"{el.count} {el.name}" for el in header.elements)
            + f" but the body has only {len(body)} bytes")
    lines = body.split("\n")
    while lines and not lines[-1].strip():
        lines.pop()
    total = sum(el.count for el in header.elements)
    if len(lines) < total:
        raise InputError(f"{path}: truncated: {total} data lines declared, {len(lines)} found")
    if len(lines) > total:
        raise InputError(f"{path}: {len(lines) - total} unexpected lines after the last element")
    header_lines = data[:header.size].count(b"\n")
    records, face_rows, face_block, start = {}, None, b"", 0
    for el in header.elements:
        chunk = lines[start:start + el.count]
        first_line = header_lines + start + 1
        start += el.count
        if el.name == "face":
            _face_property(el, path)
            face_block = "\n".join(chunk).encode("ascii")
            if reuse is not None and face_block == reuse.face_block:
                face_rows = REUSED
                continue
        if el.has_lists():
            table = _ascii_list_records(chunk, el, path, first_line)
            if el.name == "face":
                face_rows = (table[_face_property(el, path).name], _texcoord(table))
        else:
            records[el.name] = _ascii_scalar_records(chunk, el, path, first_line)
    return records, face_rows, face_block


def _ascii_scalar_records(chunk, el, path, first_line):
    n = len(el.properties)
    rows = [ln.split() for ln in chunk]
    for k, row in enumerate(rows):
        if len(row) != n:
            raise InputError(f"{path}: line {first_line + k}: {el.name} {k} has {len(row)} "
                             f"numbers, expected {n}")
    try:
        values = np.array(rows, dtype=np.float64).reshape(el.count, n)
    except ValueError:
        k = next(k for k, row in enumerate(rows) if not _all_numbers(row))
        raise InputError(f"{path}: line {first_line + k}: {el.name} {k}: "
                         f"{_first_bad(rows[k])!r} is not a number") from None
    out = np.empty(el.count, el.scalar_dtype("="))
    with np.errstate(invalid="ignore", over="ignore"):  # like a C reader: cast, flag later
        for j, p in enumerate(el.properties):
            out[p.name] = values[:, j]
    return out


def _all_numbers(row):
    return _first_bad(row) is None


def _first_bad(row):
    for word in row:
        try:
            float(word)
        except ValueError:
            return word
    return None


def _ascii_list_records(chunk, el, path, first_line):
    rows = [ln.split() for ln in chunk]
    props = el.properties
    if len(props) == 1 and props[0].is_list and rows:  # fast path: uniform integer lists only
        widths = {len(r) for r in rows}
        if len(widths) == 1:
            try:
                table = np.array(rows, dtype=np.int64)
            except (ValueError, OverflowError):
                table = None  # the record reader says where
            if table is not None and np.all(table[:, 0] == table.shape[1] - 1):
                return {props[0].name: table[:, 1:]}
    columns = {p.name: [] for p in props}
    for k, row in enumerate(rows):
        pos, where = 0, f"{path}: line {first_line + k}: {el.name} {k}"
        for p in props:
            if pos >= len(row):
                raise InputError(f"{where} has {len(row)} numbers, too few for its properties")
            if p.is_list:
                n = _ascii_int(row[pos], where)
                if n < 0:
                    raise InputError(f"{where}: negative list length {n} in '{p.name}'")
                if pos + 1 + n > len(row):
                    raise InputError(f"{where}: list '{p.name}' declares {n} items but the line "
                                     f"has {len(row) - pos - 1}")
                try:
                    columns[p.name].append(np.array(row[pos + 1:pos + 1 + n], dtype=np.float64))
                except ValueError:
                    raise InputError(f"{where}: {_first_bad(row[pos + 1:pos + 1 + n])!r} "
                                     "is not a number") from None
                pos += 1 + n
            else:
                try:
                    columns[p.name].append(float(row[pos]))
                except ValueError:
                    raise InputError(f"{where}: {row[pos]!r} is not a number") from None
                pos += 1
        if pos != len(row):
            raise InputError(f"{where} has {len(row) - pos} extra numbers")
    return columns


def _ascii_int(word, where):
    try:
        return int(word)
    except ValueError:
        raise InputError(f"{where}: list length {word!r} is not an integer") from None


def _triangulate(rows, n_vertices, path):
    """Fan-triangulate polygon rows → (faces (M,3) int64, face_source (M,) int64)."""
    if rows is None or len(rows) == 0:
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    if isinstance(rows, np.ndarray) and rows.ndim == 2:
        k = rows.shape[1]
        if k < 3:
            raise InputError(f"{path}: face 0 has {k} corners, at least 3 are needed")
        polys = _indices(rows, np.full(len(rows), k), n_vertices, path).reshape(-1, k)
        if k == 3:
            return np.ascontiguousarray(polys), np.arange(len(polys), dtype=np.int64)
        fan = np.stack([np.zeros(k - 2, np.int64), np.arange(1, k - 1), np.arange(2, k)], axis=1)
        faces = polys[:, fan].reshape(-1, 3)
        return faces, np.repeat(np.arange(len(polys), dtype=np.int64), k - 2)
    lengths = np.array([len(r) for r in rows], dtype=np.int64)
    short = np.flatnonzero(lengths < 3)
    if len(short):
        i = int(short[0])
        raise InputError(f"{path}: face {i} has {lengths[i]} corners, at least 3 are needed")
    flat = _indices(np.concatenate(rows), lengths, n_vertices, path)
    starts = np.cumsum(lengths) - lengths  # offset of each polygon's first corner in flat
    per_face = lengths - 2
    source = np.repeat(np.arange(len(rows), dtype=np.int64), per_face)
    first = np.repeat(starts, per_face)
    j = np.arange(len(source)) - np.repeat(np.cumsum(per_face) - per_face, per_face) + 1
    faces = np.stack([flat[first], flat[first + j], flat[first + j + 1]], axis=1)
    return faces, source


def _indices(values, lengths, n_vertices, path):
    """Flat vertex indices as int64, checked: integral and within 0..n_vertices-1.
    ``lengths`` (corners of each face) locate the face of a bad index for the message."""
    values = np.ravel(values)
    if values.dtype.kind == "f":
        bad = ~np.isfinite(values) | (values != np.round(values))
        if bad.any():
            i = _face_of(int(np.argmax(bad)), lengths)
            raise InputError(f"{path}: face {i} has a non-integer vertex index")
    bad = (values < 0) | (values >= n_vertices)
    if bad.any():
        at = int(np.argmax(bad))
        value = values[at].item()
        raise InputError(f"{path}: face {_face_of(at, lengths)} has vertex index "
                         f"{int(value)} outside 0..{n_vertices - 1}")
    return values.astype(np.int64)


def _face_of(position, lengths):
    return int(np.searchsorted(np.cumsum(lengths), position, side="right"))


# ---------------------------------------------------------------------------- writing


def write_ply(path, vertices, faces, *, vertex_properties=None, face_properties=None,
              binary=True, comments=()):
    """Write a triangle (or polygon) mesh; atomic (temporary file, then rename).

    ``vertices`` (N, 3): written as ``float`` if float32, else ``double``.
    ``faces`` (M, k) int. ``vertex_properties`` / ``face_properties``: dicts of
    name → (N,) / (M,) arrays, written with their own dtype (e.g. ``s t``, or
    ``red green blue`` as uint8); a face property (M, L) is a list of L values per face
    (``texcoord``: u v per corner). Binary output is little endian.
    """
    path = os.fspath(path)
    vertices = np.asarray(vertices)
    if vertices.dtype not in (np.float32, np.float64):
        vertices = vertices.astype(np.float64)
    faces = np.asarray(faces)
    vprops = {k: np.asarray(v) for k, v in (vertex_properties or {}).items()}
    fprops = {k: np.asarray(v) for k, v in (face_properties or {}).items()}
    order = "<" if binary else "="
    vdt = np.dtype([(a, order + vertices.dtype.str[1:]) for a in "xyz"]
                   + [(k, order + v.dtype.str[1:]) for k, v in vprops.items()])
    fdt = np.dtype([("n", "u1"), ("vertex_indices", order + "i4", (faces.shape[1],))]
                   + [f for k, v in fprops.items() for f in (
                       [(k, order + v.dtype.str[1:])] if v.ndim == 1
                       else [(k + "\0n", "u1"), (k, order + v.dtype.str[1:], (v.shape[1],))])])
    lines = ["ply", "format " + ("binary_little_endian" if binary else "ascii") + " 1.0"]
    lines += [f"comment {c}" for c in comments]
    lines.append(f"element vertex {len(vertices)}")
    lines += [f"property {_TYPE_NAMES[vdt[k].str[1:]]} {k}" for k in vdt.names]
    lines.append(f"element face {len(faces)}")
    lines.append("property list uchar int vertex_indices")
    lines += [f"property {_TYPE_NAMES[fdt[k].str[1:]]} {k}" if fprops[k].ndim == 1
              else f"property list uchar {_TYPE_NAMES[fdt[k].base.str[1:]]} {k}"
              for k in fdt.names[2:] if k in fprops]
    lines.append("end_header")
    vrec = np.empty(len(vertices), vdt)
    for j, a in enumerate("xyz"):
        vrec[a] = vertices[:, j]
    for k, v in vprops.items():
        vrec[k] = v
    frec = np.empty(len(faces), fdt)
    frec["n"] = faces.shape[1]
    frec["vertex_indices"] = faces
    for k, v in fprops.items():
        frec[k] = v
        if v.ndim == 2:
            frec[k + "\0n"] = v.shape[1]
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(("\n".join(lines) + "\n").encode("ascii"))
        if binary:
            fh.write(vrec.tobytes())
            fh.write(frec.tobytes())
        else:
            _write_ascii_records(fh, vrec)
            _write_ascii_records(fh, frec)


def _write_ascii_records(fh, rec):
    cols = []
    for name in rec.dtype.names:
        col = rec[name]
        cols.append(col.reshape(len(rec), -1) if col.ndim > 1 else col[:, None])
    for row in zip(*cols):
        fh.write((" ".join(" ".join(_fmt(v) for v in c) for c in row) + "\n").encode("ascii"))


def _fmt(value):
    if isinstance(value, (np.floating, float)):
        return repr(float(value))
    return str(int(value))
