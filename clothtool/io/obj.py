"""Wavefront OBJ meshes in numpy: a validating reader (garment pipelines write OBJ sequences).

Statements: ``v x y z`` (an optional ``w`` and trailing vertex colours are ignored),
``vt u [v [w]]``, ``vn``, and ``f`` with ``a``, ``a/b``, ``a//c`` or ``a/b/c`` corners,
1-based or negative (relative to the vertices defined so far) indices. Polygons are
fan-triangulated with the triangle → source-face map kept. ``o g s usemtl mtllib l p`` and
the other grouping, material and free-form statements and ``#`` comments are ignored.
The order of the ``v`` lines is the correspondence between frames: nothing is merged or
reordered. Texture indices give per-corner texture coordinates ``corner_uv`` (M, 3, 2), so
a uv seam (one vertex, two texture positions) is kept.

Fast path: the file is classified line by line on its first bytes with numpy, the ``v`` and
``vt`` lines are parsed in one pass each (:mod:`clothtool.io.numbers`, correctly rounded, or
``np.fromstring`` for numbers off its fast path), and faces with one corner count and
one corner form with another. Anything irregular (mixed polygons or corner forms, comments at
the end of a line, indented statements) takes a per-line path, which also finds the line of
any defect: every error is an :class:`~clothtool.errors.InputError` naming file and line.

In a sequence the faces are parsed once: when a file's ``f`` lines are its last lines
(``face_block``) and a later file ends with the same bytes after as many ``v``, ``vt`` and
``vn`` lines, only the part before them is read and the faces are taken over (``reuse=``).
"""

import os
import warnings

import numpy as np

from clothtool.errors import InputError
from clothtool.io.files import read_bytes
from clothtool.io.numbers import parse_rows
from clothtool.io.ply import PlyMesh, fan

_PROBE_BYTES = 4096
_WS = np.zeros(256, bool)
_WS[[9, 10, 11, 12, 13, 32]] = True
_DIGIT = np.zeros(256, bool)
_DIGIT[48:58] = True
_FACE_OK = _WS | _DIGIT
_FACE_OK[[ord("-"), ord("/")]] = True
SLASH, MINUS = ord("/"), ord("-")
IGNORED = frozenset(b"o g s usemtl mtllib l p vp cstype deg bmat step curv curv2 surf parm "
                    b"trim hole scrv sp end con mg lod usemap maplib shadow_obj trace_obj ctech "
                    b"stech bevel c_interp d_interp call csh".split())
# corner forms, by (slashes, double slashes) per corner: the fields each corner has
_FORMS = {(0, 0): "v", (1, 0): "vt", (2, 1): "vn", (2, 0): "vtn"}
_LIMIT = 1 << 62  # an index beyond this is out of range whatever the file


def read_obj(path, *, reuse=None):
    """Read an OBJ file into a :class:`~clothtool.io.ply.PlyMesh`. ``reuse``: a mesh read
    before; when this file ends with its face block, the faces are not parsed again."""
    path = os.fspath(path)
    return parse_obj(read_bytes(path, "an OBJ file"), path, reuse=reuse)


class _FaceBlock:
    """What the face block of a mesh depends on: the counts of lines, ``v``, ``vt`` and ``vn``
    lines before it, and each triangle corner's texture index (None without ``vt``)."""

    def __init__(self, counts, texture_corner):
        self.counts, self.texture_corner = counts, texture_corner


def parse_obj(data, path="<bytes>", *, reuse=None):
    """Parse OBJ ``data`` (bytes); see :func:`read_obj`."""
    if not data or data.isspace():
        raise InputError(f"{path}: empty file, not an OBJ file")
    block = getattr(reuse, "obj_faces", None) and reuse.face_block
    if block and data.endswith(block) and (len(data) == len(block)
                                           or data[len(data) - len(block) - 1] == 10):
        mesh = _with_faces_of(data[:len(data) - len(block)], path, reuse)
        if mesh is not None:
            return mesh
    lines = _Lines(data)
    if lines.indented():
        return _finish(_parse_per_line(data, path), path)
    kind = lines.kind
    others = np.flatnonzero(kind == _OTHER)
    for i in others:
        words = data[lines.starts[i]:lines.ends[i]].split(b"#", 1)[0].split()
        if words and words[0] not in IGNORED:
            raise InputError(f"{path}: line {i + 1}: unknown statement "
                             f"{words[0].decode('ascii', 'replace')!r}")
    parsed = {"v": _vectors(lines, _V, path, data), "vt": _vectors(lines, _VT, path, data)}
    n_normals = int(np.count_nonzero(kind == _VN))
    faces = _faces_fast(lines)
    if faces is None:
        faces = _faces_per_line(data, lines, path)
    mesh, texture_corner = _build((parsed["v"], parsed["vt"], n_normals, faces), path)
    rows = np.flatnonzero(kind == _F)
    if len(rows) and (kind[rows[0]:] == _F).all():  # the faces are the file's last lines
        mesh.face_block = data[lines.starts[rows[0]]:]
        mesh.obj_faces = _FaceBlock((int(rows[0]), len(parsed["v"]), len(parsed["vt"]),
                                     n_normals), texture_corner)
    return mesh


def _with_faces_of(head, path, reuse):
    """The mesh of a file that is ``head`` followed by the face block of ``reuse``: ``head``
    read, the faces taken over; None when ``head`` is not plain ``v``/``vt``/``vn`` lines (and
    ignored statements) as many as ``reuse`` had."""
    lines = _Lines(head) if head else None
    if lines is None or lines.indented() or (lines.kind == _F).any():
        return None
    for i in np.flatnonzero(lines.kind == _OTHER):
        words = head[lines.starts[i]:lines.ends[i]].split(b"#", 1)[0].split()
        if words and words[0] not in IGNORED:
            return None  # the full parse names the line
    vertices, uv = _vectors(lines, _V, path, head), _vectors(lines, _VT, path, head)
    known = reuse.obj_faces
    if known.counts != (len(lines.starts), len(vertices), len(uv),
                        int(np.count_nonzero(lines.kind == _VN))):
        return None
    corner_uv, missing = None, reuse.corner_uv_missing
    if known.texture_corner is not None:
        corner_uv = uv[known.texture_corner]
        corner_uv[missing] = np.nan
    return PlyMesh(vertices, reuse.faces, reuse.face_source, face_block=reuse.face_block,
                   corner_uv=corner_uv, corner_uv_missing=missing,
                   source_lines=reuse.source_lines, obj_faces=known)


# ---------------------------------------------------------------------------- lines

_OTHER, _V, _VT, _VN, _F, _COMMENT, _EMPTY = range(7)


class _Lines:
    """Line starts, ends and statement kinds of a buffer, from its first bytes."""

    def __init__(self, data):
        buf = np.frombuffer(data, np.uint8)
        self.buf = buf
        n = len(buf)
        nl = np.flatnonzero(buf == 10)
        starts = np.concatenate([[0], nl + 1])
        ends = np.concatenate([nl, [n]])
        if starts[-1] == n:  # the file ends with a line break
            starts, ends = starts[:-1], ends[:-1]
        self.starts, self.ends = starts, ends
        pad = np.concatenate([buf, np.full(3, 10, np.uint8)])
        c0, c1, c2 = pad[starts], pad[starts + 1], pad[starts + 2]
        self.c0 = c0
        ws1, ws2 = _WS[c1], _WS[c2]
        kind = np.full(len(starts), _OTHER, np.int8)
        kind[c0 == ord("#")] = _COMMENT
        kind[ends == starts] = _EMPTY
        v = c0 == ord("v")
        kind[v & ws1] = _V
        kind[v & (c1 == ord("t")) & ws2] = _VT
        kind[v & (c1 == ord("n")) & ws2] = _VN
        kind[(c0 == ord("f")) & ws1] = _F
        self.kind = kind
        self._tokens = None

    def indented(self):
        """True when a statement line starts with whitespace (the per-line path handles it)."""
        lead = np.flatnonzero(_WS[self.c0] & (self.kind == _OTHER))
        for i in lead:
            words = bytes(self.buf[self.starts[i]:self.ends[i]]).split(b"#", 1)[0].split()
            if words:
                return True
        return False

    def tokens(self):
        """Whitespace-separated words on each line (keyword included). Any byte ≤ 32 counts as
        whitespace here; a control character that is not makes ``np.fromstring`` fail, and
        the per-line path then names it."""
        if self._tokens is None:
            ws = self.buf <= 32
            first = ~ws
            first[1:] &= ws[:-1]
            at = np.flatnonzero(first)
            self._tokens = np.searchsorted(at, self.ends) - np.searchsorted(at, self.starts)
        return self._tokens

    def text(self, which, keyword):
        """The bytes (uint8, a copy) of the lines ``which`` (a line mask), their keyword blanked."""
        rows = np.flatnonzero(which)
        n = len(self.buf)
        if rows[-1] - rows[0] + 1 == len(rows):  # one block of lines (the usual case)
            begin = self.starts[rows[0]]
            stop = self.starts[rows[-1] + 1] if rows[-1] + 1 < len(self.starts) else n
            out = self.buf[begin:stop].copy()
            line_starts = self.starts[rows] - begin
        else:
            span = np.diff(np.concatenate([self.starts, [n]]))
            out = self.buf[np.repeat(which, span)]
            line_starts = np.cumsum(span[rows]) - span[rows]
        for k in range(keyword):
            out[line_starts + k] = 32
        return out


def _fromstring(text, dtype):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            return np.fromstring(text, dtype=dtype, sep=" ")
    except (ValueError, DeprecationWarning):
        return None


def _vectors(lines, kind, path, data):
    """(K, 3) float64 positions of the ``v`` lines or (K, 2) of the ``vt`` lines."""
    which = lines.kind == kind
    rows = np.flatnonzero(which)
    width = 3 if kind == _V else 2
    if len(rows) == 0:
        return np.zeros((0, width))
    table = parse_rows(lines.buf, lines.starts[rows], lines.ends[rows], 1 if kind == _V else 2,
                       7 if kind == _V else 3)  # v x y z [w] [r g b]; vt u [v [w]]
    if table is not None and (3 <= table.shape[1] if kind == _V else 1 <= table.shape[1]):
        if kind == _V:
            return np.ascontiguousarray(table[:, :3])
        return np.column_stack([table[:, 0], table[:, 1] if table.shape[1] > 1
                                else np.zeros(len(rows))])
    counts = lines.tokens()[rows] - 1
    k = int(counts[0])
    if (counts == k).all() and (3 <= k if kind == _V else 1 <= k <= 3):
        keyword = 1 if kind == _V else 2
        values = _fromstring(lines.text(which, keyword).tobytes(), np.float64)
        if values is not None and values.size == k * len(rows):
            table = values.reshape(len(rows), k)
            if kind == _V:
                return np.ascontiguousarray(table[:, :3])
            return np.column_stack([table[:, 0], table[:, 1] if k > 1 else np.zeros(len(rows))])
    out = np.empty((len(rows), width))
    for j, i in enumerate(rows):
        out[j] = _vector_line(data[lines.starts[i]:lines.ends[i]], kind, path, i + 1)
    return out


def _vector_line(line, kind, path, number):
    words = line.split(b"#", 1)[0].split()[1:]
    name = "vertex" if kind == _V else "texture coordinate"
    need, most = (3, None) if kind == _V else (1, 3)
    if len(words) < need or (most and len(words) > most):
        raise InputError(f"{path}: line {number}: {name} has {len(words)} numbers, expected "
                         + ("3 (x y z)" if kind == _V else "1 to 3 (u v w)"))
    values = []
    for word in words[:3 if kind == _V else 2]:
        try:
            values.append(float(word))
        except ValueError:
            raise InputError(f"{path}: line {number}: {word.decode('ascii', 'replace')!r} "
                             "is not a number") from None
    if kind == _VT and len(values) == 1:
        values.append(0.0)
    return values


# ---------------------------------------------------------------------------- faces


class _Corners:
    """Raw face corners: per-corner indices as written (0 where absent), per-face corner counts
    and line numbers, and the vertex / texture / normal counts before each face's line."""

    def __init__(self, v, t, n, has_t, has_n, lengths, line, before):
        self.v, self.t, self.n, self.has_t, self.has_n = v, t, n, has_t, has_n
        self.lengths, self.line, self.before = lengths, line, before


def _faces_fast(lines):
    """Faces with one corner count and one corner form, parsed in one go; None otherwise."""
    which = lines.kind == _F
    rows = np.flatnonzero(which)
    if len(rows) == 0:
        return _empty_corners()
    corners = lines.tokens()[rows] - 1
    k = int(corners[0])
    if k < 3 or not (corners == k).all():
        return None
    text = lines.text(which, 1)
    counts = np.bincount(text, minlength=256)
    if counts[~_FACE_OK].any():
        return None
    # the corner form: every corner (word) has the same numbers of '/' and of '//'
    ws = text <= 32
    first = ~ws
    first[1:] &= ws[:-1]
    word = np.flatnonzero(first)
    n_words = len(rows) * k
    if len(word) != n_words:
        return None
    word_end = np.append(word[1:], len(text))
    at = np.flatnonzero(text == SLASH) if counts[SLASH] else np.zeros(0, np.int64)
    double = at[:-1][np.diff(at) == 1]
    form = None
    for (s, d), name in _FORMS.items():
        if len(at) == s * n_words and len(double) == d * n_words:
            form = name
    if form is None:
        return None
    if len(at):  # s slashes inside each word, d of them doubled
        per = at.reshape(n_words, -1)
        if not ((per[:, 0] > word).all() and (per[:, -1] < word_end).all()):
            return None
        if len(double) and not ((double > word) & (double < word_end)).all():
            return None
        # each '/' between a number and a number or a '/'
        before_, after = text[at - 1], text[np.minimum(at + 1, len(text) - 1)]
        if not ((_DIGIT[before_] | (before_ == SLASH))
                & (_DIGIT[after] | (after == MINUS) | (after == SLASH))).all():
            return None
    if counts[MINUS]:  # every '-' starts a number
        minus = np.flatnonzero(text == MINUS)
        before_, after = text[minus - 1], text[np.minimum(minus + 1, len(text) - 1)]
        if not (((before_ <= 32) | (before_ == SLASH)) & _DIGIT[after]).all():
            return None
    text[at] = 32
    values = _fromstring(text.tobytes(), np.int64)
    per = len(form)
    if values is None or values.size != len(rows) * k * per:
        return None
    table = values.reshape(-1, per)
    zeros = np.zeros(len(table), np.int64)
    has_t = np.full(len(table), "t" in form)
    has_n = np.full(len(table), "n" in form)
    t = table[:, 1] if "t" in form else zeros
    n = table[:, per - 1] if "n" in form else zeros
    return _Corners(table[:, 0], t, n, has_t, has_n, np.full(len(rows), k, np.int64), rows + 1,
                    _before(lines, rows))


def _before(lines, rows):
    """(3, F) counts of v, vt and vn lines before each of the lines ``rows``."""
    return np.stack([np.cumsum(lines.kind == kind)[rows] for kind in (_V, _VT, _VN)])


def _empty_corners():
    e = np.zeros(0, np.int64)
    return _Corners(e, e, e, e.astype(bool), e.astype(bool), e, e, np.zeros((3, 0), np.int64))


def _faces_per_line(data, lines, path):
    rows = np.flatnonzero(lines.kind == _F)
    parsed = [_face_line(data[lines.starts[i]:lines.ends[i]], path, i + 1) for i in rows]
    return _assemble(parsed, rows + 1, _before(lines, rows))


def _assemble(parsed, line, before):
    lengths = np.array([len(p) for p in parsed], np.int64)
    flat = [c for p in parsed for c in p]
    table = np.array(flat, np.int64).reshape(-1, 5)
    return _Corners(table[:, 0], table[:, 1], table[:, 2], table[:, 3].astype(bool),
                    table[:, 4].astype(bool), lengths, np.asarray(line, np.int64),
                    np.asarray(before, np.int64).reshape(3, -1))


def _face_line(line, path, number):
    """Corners of one ``f`` line: (v, t, n, has_t, has_n) each."""
    words = line.split(b"#", 1)[0].split()[1:]
    if len(words) < 3:
        raise InputError(f"{path}: line {number}: face has {len(words)} corners, "
                         "at least 3 are needed")
    out = []
    for word in words:
        parts = word.split(b"/")
        if len(parts) > 3 or not parts[0] or (len(parts) == 3 and not (parts[1] or parts[2])) \
                or (len(parts) == 2 and not parts[1]):
            raise InputError(f"{path}: line {number}: bad face corner "
                             f"{word.decode('ascii', 'replace')!r} (expected a, a/b, a//c or a/b/c)")
        ids = [_index(p, path, number) if p else 0 for p in parts] + [0] * (3 - len(parts))
        out.append((ids[0], ids[1], ids[2], len(parts) > 1 and bool(parts[1]),
                    len(parts) > 2 and bool(parts[2])))
    return out


def _index(word, path, number):
    try:
        value = int(word)
    except ValueError:
        raise InputError(f"{path}: line {number}: index {word.decode('ascii', 'replace')!r} "
                         "is not an integer") from None
    if abs(value) > _LIMIT:
        raise InputError(f"{path}: line {number}: index {value} is out of range")
    return value


def _resolve(raw, present, before, total, lengths, line, what, path):
    """1-based or negative (relative) OBJ indices → 0-based, checked against ``total``."""
    per_corner_before = np.repeat(before, lengths)
    out = np.where(raw > 0, raw - 1, per_corner_before + raw)
    bad = present & ((raw == 0) | (out < 0) | (out >= total))
    if bad.any():
        at = int(np.argmax(bad))
        face = int(np.searchsorted(np.cumsum(lengths), at, side="right"))
        where = f"{path}: line {int(line[face])}"
        if raw[at] == 0:
            raise InputError(f"{where}: {what} index 0 (OBJ indices start at 1)")
        noun = {"vertex": "vertices", "texture": "texture coordinates", "normal": "normals"}[what]
        have = (f"the file has {total} {noun}" if raw[at] > 0
                else f"{int(per_corner_before[at])} {noun} precede it")
        raise InputError(f"{where}: {what} index {int(raw[at])} is out of range "
                         f"({have})")
    return np.where(present, out, 0)


# ---------------------------------------------------------------------------- whole file


def _parse_per_line(data, path):
    """Every line on its own (indented statements and other irregular files)."""
    v, vt, faces, lines_of_faces, before = [], [], [], [], []
    n_normals = 0
    for number, raw in enumerate(data.split(b"\n"), start=1):
        words = raw.split(b"#", 1)[0].split()
        if not words:
            continue
        key = words[0]
        if key == b"v":
            v.append(_vector_line(raw.strip(), _V, path, number))
        elif key == b"vt":
            vt.append(_vector_line(raw.strip(), _VT, path, number))
        elif key == b"vn":
            n_normals += 1
        elif key == b"f":
            faces.append(_face_line(raw.strip(), path, number))
            lines_of_faces.append(number)
            before.append((len(v), len(vt), n_normals))
        elif key not in IGNORED:
            raise InputError(f"{path}: line {number}: unknown statement "
                             f"{key.decode('ascii', 'replace')!r}")
    corners = _assemble(faces, lines_of_faces, np.array(before, np.int64).T) if faces \
        else _empty_corners()
    return (np.array(v, np.float64).reshape(-1, 3), np.array(vt, np.float64).reshape(-1, 2),
            n_normals, corners)


def _finish(parsed, path):
    """The mesh of the parsed statements."""
    return _build(parsed, path)[0]


def _build(parsed, path):
    """(mesh, each triangle corner's texture index or None) of the parsed statements."""
    vertices, uv, n_normals, c = parsed
    zeros = np.zeros(len(c.v), np.int64)
    vi = _resolve(c.v, np.ones(len(c.v), bool), c.before[0], len(vertices), c.lengths, c.line,
                  "vertex", path)
    ti = _resolve(c.t, c.has_t, c.before[1], len(uv), c.lengths, c.line, "texture", path) \
        if c.has_t.any() else zeros
    if c.has_n.any():
        _resolve(c.n, c.has_n, c.before[2], n_normals, c.lengths, c.line, "normal", path)
    corner, source = fan(c.lengths)
    faces = vi[corner]
    corner_uv = missing = texture_corner = None
    if c.has_t.any():
        texture_corner = ti[corner]
        corner_uv = uv[texture_corner]
        missing = ~c.has_t[corner].all(axis=1)
        corner_uv[missing] = np.nan
    mesh = PlyMesh(vertices, faces, source)
    mesh.corner_uv, mesh.corner_uv_missing, mesh.source_lines = corner_uv, missing, c.line
    return mesh, texture_corner
