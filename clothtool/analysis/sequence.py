"""``analyze_sequence``: walk a PLY sequence in pairs and stream per-triangle fields to HDF5.

One frame is in memory at a time (plus the current reference), so peak memory
depends on the mesh, not on the number of frames. The rest-state data D_r⁻¹ is
computed once per reference frame, not once per pair.
"""

import contextlib
import datetime
import functools
import os
import time
from dataclasses import dataclass, field

import numpy as np

from clothtool import __version__, interrupt
from clothtool.analysis.deformation2d import (DEGENERATE_TOL, FIELDS, allocate_fields,
                                              allocate_rest, deformation_fields,
                                              reference_from_positions,
                                              reference_from_uv)
from clothtool.errors import InputError
from clothtool.io.frames import FrameReader, discover_frames
from clothtool.io.h5 import (AtomicH5, PairWriter, check_not_an_input, check_output_path,
                              create_pair_dataset, parse_compression)
from clothtool.results.extras import NEEDED, PairExtras
from clothtool.results.slices import parse_pair_slice
from clothtool.results.vertex_average import parse_vertex_average
from clothtool.results.xdmf import xdmf_path, xdmf_text

REFERENCE_MODES = ("previous", "first", "uv")
EXTERNAL = -1  # the reference index of pairs against a reference mesh or the uv rest shape

FIELD_SHAPES = {"F": (2, 2), "C": (2, 2), "U": (2, 2), "R": (2, 2), "strain": (2, 2),
                "stretch": (2,), "directions": (2, 3), "area_ratio": (), "flags": ()}


def parse_fields(fields, kabsch=False):
    """'all', a comma-separated string or an iterable of names → tuple in canonical order.
    With ``kabsch`` the names of the 3D variant are allowed too (and 'all' includes them)."""
    from clothtool.analysis.variant3d import KABSCH_FIELDS

    known = FIELDS + KABSCH_FIELDS if kabsch else FIELDS
    if fields is None or fields == "all":
        return known
    names = [f.strip() for f in fields.split(",")] if isinstance(fields, str) else list(fields)
    names = [n for n in names if n]
    unknown = [n for n in names if n not in known]
    if unknown and unknown[0] in KABSCH_FIELDS:
        raise InputError(f"--fields: {unknown[0]!r} belongs to the 3D variant; add --kabsch")
    if unknown or not names:
        raise InputError(f"--fields: unknown field {unknown[0]!r}" if unknown else "--fields: empty"
                         f"; choose from {', '.join(known)}")
    return tuple(n for n in known if n in names)


def parse_dtype(dtype):
    try:
        dt = np.dtype(dtype)
    except TypeError:
        dt = None
    if dt not in (np.float32, np.float64):
        raise InputError(f"--dtype: {dtype!r} is not float32 or float64")
    return dt


@dataclass
class AnalysisSummary:
    """What :func:`analyze_sequence` wrote, with a few sanity figures."""

    output: str
    frames: int
    pairs: int
    triangles: int
    vertices: int
    fields: tuple
    reference: str
    seconds: float
    stretch_max: float = float("nan")
    stretch_min: float = float("nan")
    flagged: int = 0
    extra: dict = field(default_factory=dict)

    def describe(self):
        lines = [f"wrote {self.output}: {self.pairs} pairs of {self.frames} frames, "
                 f"{self.triangles} triangles, {self.vertices} vertices "
                 f"(reference: {self.reference}) in {self.seconds:.2f} s",
                 f"  fields: {', '.join(self.fields)}"]
        if np.isfinite(self.stretch_max):
            lines.append(f"  principal stretch: largest λ1 {self.stretch_max:.4f}, "
                         f"smallest λ2 {self.stretch_min:.4f}")
        if "flags" in self.fields:
            lines.append(f"  flagged triangle-pairs (degenerate, non-finite or flipped): {self.flagged}")
        if "angle_max" in self.extra:
            lines.append(f"  3D variant: largest vertex rotation {self.extra['angle_max']:.4f} rad")
        if "vertex_flagged" in self.extra:
            lines.append(f"  flagged vertex-pairs (degenerate ring, non-finite or ambiguous): "
                         f"{self.extra['vertex_flagged']}")
        return "\n".join(lines)


class _Rest:
    """Rest-state data of each reference, computed once and kept while it is used."""

    def __init__(self, reader, reference, uv_scale):
        self.reader, self.reference, self.uv_scale = reader, reference, uv_scale
        self.faces = reader.faces
        self._key, self._data = None, None
        self.external = None
        if reference == "uv":
            from clothtool.io.uv import rest_uv

            self.external = ("uv", rest_uv(reader.first, reader.paths[0]))  # per corner or vertex
        elif reference not in REFERENCE_MODES:
            if not os.path.isfile(reference):
                raise InputError(f"--reference: {reference!r} is not previous, first, uv "
                                 "or an existing PLY or OBJ file")
            from clothtool.io.frames import read_mesh

            mesh = reader.check_same_topology(read_mesh(reference, reuse=reader.first), reference)
            self.external = ("mesh", mesh.vertices)

    def uv_positions(self):
        """The uv rest shape as (N, 3) positions (u, v, 0)·uv_scale, for the 3D variant."""
        uv = self.external[1].vertex_uv() * float(self.uv_scale)
        return np.ascontiguousarray(np.column_stack([uv, np.zeros(len(uv))]), dtype=np.float64)

    def vertices(self):
        """Positions stored as /mesh/vertices: the reference mesh, else frame 0."""
        if self.external is not None and self.external[0] == "mesh":
            return self.external[1]
        return self.reader.first.vertices

    def put(self, index, data):
        """Rest-state data of frame ``index`` computed elsewhere (see ``next_rest``)."""
        self._key, self._data = index, data

    def get(self, index, positions):
        """(D_r⁻¹, basis, flags) of reference ``index`` whose positions are ``positions``."""
        if self._key != index:
            if self.external is not None and self.external[0] == "uv":
                uv = self.external[1]
                self._data = reference_from_uv(uv.points, uv.faces, float(self.uv_scale),
                                               DEGENERATE_TOL)
            else:
                self._data = reference_from_positions(positions, self.faces, DEGENERATE_TOL)
            self._key = index
        return self._data


def plan_pairs(n_frames, reference):
    """The (reference frame, deformed frame) pairs for a reference mode."""
    if reference == "previous":
        pairs = [(i, i + 1) for i in range(n_frames - 1)]
    elif reference == "first":
        pairs = [(0, i) for i in range(1, n_frames)]
    else:
        pairs = [(EXTERNAL, i) for i in range(n_frames)]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def analyze_sequence(inputs, output, *, reference="previous", uv_scale=1.0, fields="all",
                     dtype="float32", compression="none", kabsch=False, progress=False,
                     command=None, pairs=None, vertex_average=None):
    """Analyse a PLY sequence and write the per-triangle fields to ``output`` (HDF5, spec §4).

    ``inputs``: a folder, a glob, a file or a list of them (natural order).
    ``reference``: 'previous' (pairs (i, i+1)), 'first' (pairs (0, i)), 'uv' (the
    texture coordinates times ``uv_scale``) or the path of a PLY mesh.
    ``fields``: 'all' or names from :data:`FIELDS`; only those are computed and stored.
    ``kabsch``: add the 3D variant (:mod:`clothtool.analysis.variant3d`); ``fields`` may then
    also name its datasets.
    ``pairs``: 'START:STOP' or (start, stop): compute only that slice of the pairs
    (:mod:`clothtool.results.slices`). ``vertex_average``: face fields to also store as
    area-weighted vertex averages ``/vertex/<name>_avg``
    (:mod:`clothtool.results.vertex_average`). Always stored: ``/frame_vertices`` and
    ``/summary`` (:mod:`clothtool.results.extras`); ``out.xdmf`` is written beside
    ``out.h5`` (:mod:`clothtool.results.xdmf`).
    Returns an :class:`AnalysisSummary`. Raises :class:`~clothtool.errors.InputError`
    on bad input, before writing anything.
    """
    started = time.perf_counter()
    fields = parse_fields(fields, kabsch)
    store = parse_dtype(dtype)
    h5_compression = parse_compression(compression)
    averaged = parse_vertex_average(vertex_average)
    check_output_path(output)
    xdmf = xdmf_path(output)
    paths = discover_frames(inputs)
    check_not_an_input(output, paths if reference in REFERENCE_MODES else [*paths, reference])
    internal = reference in ("previous", "first")
    if internal and len(paths) < 2:
        raise InputError(f"{paths[0]}: only one frame; --reference {reference} needs at least two")
    reader = FrameReader(paths)
    rest = _Rest(reader, reference, uv_scale)
    all_pairs = plan_pairs(len(paths), reference)
    offset, stop = parse_pair_slice(pairs, len(all_pairs))
    pairs = all_pairs[offset:stop]
    m = len(reader.faces)
    summary = AnalysisSummary(os.fspath(output), len(paths), len(pairs), m, reader.n_vertices,
                              fields, reference, 0.0)

    variant = None
    if kabsch:
        from clothtool.analysis.variant3d import Variant3D

        variant = Variant3D(reader.faces, reader.n_vertices, fields, DEGENERATE_TOL)

    def make_buffers():
        return {**allocate_fields(m, {*fields, *averaged, *NEEDED}, store), **extras.buffers(),
                **(variant.buffers(store) if variant else {})}

    atomic = AtomicH5(output)
    with atomic as h5:
        _write_header(h5, paths, pairs, rest, reader, reference, uv_scale, command, store)
        h5.attrs["pair_offset"] = offset
        h5.attrs["pairs_total"] = len(all_pairs)
        extras = PairExtras(h5, pairs, offset, len(paths), reader.faces, reader.n_vertices,
                            {name: FIELD_SHAPES[name] for name in averaged}, store, h5_compression)
        group = h5.create_group("face")
        datasets = {name: create_pair_dataset(group, name, len(pairs), (m, *FIELD_SHAPES[name]),
                                              np.uint8 if name == "flags" else store, h5_compression)
                    for name in fields if name in FIELDS}
        if variant:
            datasets.update(variant.create_datasets(h5, len(pairs), store, h5_compression))
        with PairWriter({**datasets, **extras.datasets}, make_buffers) as writer, \
                _kernel_threads_beside_writer():
            _stream_pairs(pairs, reader, rest, writer, summary, fields, progress, extras, variant)
        extras.close()
        atomic.add_sidecar(xdmf, xdmf_text(h5, os.path.basename(output)))  # renamed with it
    summary.seconds = time.perf_counter() - started
    return summary


@contextlib.contextmanager
def _kernel_threads_beside_writer():
    """Leave one core to the HDF5 writer thread while the kernels run: on 2 cores the
    100k-triangle benchmark runs in 1.55 s with one kernel thread and 1.7–1.9 s with two."""
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(max(1, threads - 1))
    try:
        yield
    finally:
        numba.set_num_threads(threads)


def _stream_pairs(pairs, reader, rest, writer, summary, fields, progress, extras, variant):
    """Compute every pair, one frame in memory at a time, handing results to ``writer``."""
    faces = reader.faces
    x_uv = rest.uv_positions() if variant and rest.reference == "uv" else None
    last = (0, reader.first.vertices)  # the frame read most recently, reused as a reference
    for p, (r, d) in enumerate(_progress(pairs, progress)):
        interrupt.check()
        r, d = int(r), int(d)
        if r == EXTERNAL:
            x_ref = rest.vertices()
        else:
            x_ref = last[1] if last[0] == r else reader.positions(r)
        ref = rest.get(r, x_ref)
        x = last[1] if last[0] == d else reader.positions(d)
        last = (d, x)
        buffers = writer.buffers()
        # In a 'previous' sequence this frame is the next pair's reference: get its rest
        # data from the same pass (fresh arrays: the writer thread may still read these).
        next_rest = allocate_rest(len(faces) if rest.reference == "previous" else 0)
        deformation_fields(x, faces, *ref, DEGENERATE_TOL, *(buffers[n] for n in FIELDS),
                           *next_rest)
        if len(next_rest[2]):
            rest.put(d, next_rest)
        _accumulate(summary, buffers, fields)
        if variant:
            variant.compute(x_ref if x_uv is None else x_uv, x, buffers)
            _accumulate_3d(summary, buffers)
        writer.write(p, buffers, functools.partial(extras.pair, p, buffers, ref[0],
                                                   ((r, x_ref), (d, x))))


def _write_header(h5, paths, pairs, rest, reader, reference, uv_scale, command, store):
    import h5py

    h5.attrs["clothtool_version"] = __version__
    h5.attrs["reference"] = reference
    h5.attrs["command"] = command or "clothtool.analyze_sequence"
    h5.attrs["created"] = datetime.datetime.now(datetime.timezone.utc).astimezone().isoformat(
        timespec="seconds")
    h5.attrs["degenerate_tol"] = DEGENERATE_TOL
    h5.attrs["dtype"] = store.name
    if reference == "uv":
        h5.attrs["uv_scale"] = float(uv_scale)
    mesh = h5.create_group("mesh")
    mesh.create_dataset("faces", data=reader.faces)
    mesh.create_dataset("face_source", data=reader.first.face_source)
    mesh.create_dataset("vertices", data=rest.vertices())
    if reference == "uv":
        mesh.create_dataset(rest.external[1].name, data=rest.external[1].data)
    h5.create_dataset("frames", data=np.array(paths, dtype=object), dtype=h5py.string_dtype())
    h5.create_dataset("pairs", data=pairs)


def _accumulate(summary, buffers, fields):
    if "stretch" in fields and buffers["stretch"].size:
        s = buffers["stretch"]
        if np.isfinite(s).any():
            summary.stretch_max = float(np.fmax(summary.stretch_max, np.nanmax(s[:, 0])))
            summary.stretch_min = float(np.fmin(summary.stretch_min, np.nanmin(s[:, 1])))
    if "flags" in fields:
        summary.flagged += int(np.count_nonzero(buffers["flags"]))


def _accumulate_3d(summary, buffers):
    angle = buffers["vertex/angle"]
    if angle.size and np.isfinite(angle).any():
        largest = np.fmax(summary.extra.get("angle_max", np.nan), np.nanmax(angle))
        summary.extra["angle_max"] = float(largest)
    if buffers["vertex/flags"].size:
        summary.extra["vertex_flagged"] = (summary.extra.get("vertex_flagged", 0)
                                           + int(np.count_nonzero(buffers["vertex/flags"])))


def _progress(pairs, enabled):
    if not enabled:
        return pairs
    from tqdm import tqdm

    return tqdm(pairs, desc="analyze", unit="pair", leave=False)
