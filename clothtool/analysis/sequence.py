"""``analyze_sequence``: walk a PLY sequence in pairs and stream per-triangle fields to HDF5.

One frame is in memory at a time (plus the current reference), so peak memory
depends on the mesh, not on the number of frames. The rest-state data D_r⁻¹ is
computed once per reference frame, not once per pair.
"""

import os
import time
from dataclasses import dataclass

import numpy as np

from clothtool.analysis.deformation2d import (DEGENERATE_TOL, KernelPlan, allocate_rest,
                                              deformation_fields,
                                              deformation_fields_and_next_rest,
                                              reference_from_positions, reference_from_uv)
from clothtool.analysis.output.extras import PairExtras
from clothtool.analysis.output.slices import parse_pair_slice
from clothtool.analysis.pairs import (EXTERNAL, AnalysisSummary, RestCache, create_field_datasets,
                                      kernel_threads_beside_writer, stream_pairs,
                                      write_common_header)
from clothtool.errors import InputError
from clothtool.fields import FIELDS_2D, FIELDS_TET, NAMES_2D, parse_fields
from clothtool.fields import field as registry_field
from clothtool.io.frames import FrameReader, discover_frames, is_tet_path
from clothtool.io.h5 import (AtomicH5, PairWriter, check_not_an_input, check_output_path,
                              parse_compression)
from clothtool.io.xdmf import xdmf_path, xdmf_text
from clothtool.vertex_average import parse_vertex_average

REFERENCE_MODES = ("previous", "first", "uv")


def parse_dtype(dtype):
    try:
        dt = np.dtype(dtype)
    except TypeError:
        dt = None
    if dt not in (np.float32, np.float64):
        raise InputError("not float32 or float64", keyword="dtype", value=repr(dtype))
    return dt


class _Rest(RestCache):
    """(D_r⁻¹, basis, flags) of each reference triangle mesh or of the uv rest shape."""

    def __init__(self, reader, reference, uv_scale):
        super().__init__()
        self.reader, self.reference, self.uv_scale = reader, reference, uv_scale
        self.faces = reader.faces
        self.external = None
        if reference == "uv":
            from clothtool.io.uv import rest_uv

            self.external = ("uv", rest_uv(reader.first, reader.paths[0]))  # per corner or vertex
        elif reference not in REFERENCE_MODES:
            if not os.path.isfile(reference):
                raise InputError(f"{reference!r} is not previous, first, uv or an existing "
                                 "PLY or OBJ file", keyword="reference")
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

    def compute(self, positions):
        if self.external is not None and self.external[0] == "uv":
            uv = self.external[1]
            return reference_from_uv(uv.points, uv.faces, float(self.uv_scale), DEGENERATE_TOL)
        return reference_from_positions(positions, self.faces, DEGENERATE_TOL)


def plan_pairs(n_frames, reference):
    """The (reference frame, deformed frame) pairs for a reference mode."""
    if reference == "previous":
        pairs = [(i, i + 1) for i in range(n_frames - 1)]
    elif reference == "first":
        pairs = [(0, i) for i in range(1, n_frames)]
    else:
        pairs = [(EXTERNAL, i) for i in range(n_frames)]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


@dataclass(frozen=True)
class AnalysisPlan:
    """Everything an analysis will do, checked, before it reads a frame or writes a byte:
    made by :func:`plan_analysis`, run by :func:`run_analysis`."""

    frames: tuple  # paths, natural order
    output: str
    xdmf: str  # written beside output
    reference: str  # previous, first, uv or a PLY path
    uv_scale: float
    pairs: tuple  # (reference, deformed) frame indices of the pairs computed; −1: external
    pair_offset: int  # global index of the first of them
    pairs_total: int  # pairs of the whole sequence
    fields: tuple  # stored, registry order
    averaged: tuple  # 2D fields stored as vertex averages too
    kabsch: bool
    dtype: np.dtype  # storage of float fields
    compression: tuple  # h5py keyword arguments as (key, value) pairs
    tets: bool = False  # a tetrahedral sequence (clothtool.analysis.tet_sequence)

    @property
    def computed(self):
        """The fields the 2D or tet kernel computes: those stored, averaged or summarised."""
        wanted = {*self.fields, *self.averaged}
        return tuple(f.name for f in (FIELDS_TET if self.tets else FIELDS_2D)
                     if f.name in wanted or f.summary)


def plan_analysis(inputs, output, *, reference="previous", uv_scale=1.0, fields="all",
                  dtype="float32", compression="none", kabsch=False, pairs=None,
                  vertex_average=None):
    """Check the arguments of :func:`analyze_sequence` and return its :class:`AnalysisPlan`.
    Raises :class:`~clothtool.errors.InputError` naming the keyword at fault. The field names
    are checked after the frames are found: tetrahedral frames have fields of their own."""
    store = parse_dtype(dtype)
    h5_compression = parse_compression(compression)
    check_output_path(output)
    xdmf = xdmf_path(output)
    paths = discover_frames(inputs)
    tets = is_tet_path(paths[0])
    if tets:
        from clothtool.analysis.tet_sequence import check_tet_options

        check_tet_options(reference, kabsch, vertex_average)
    fields = parse_fields(fields, kabsch, tets=tets)
    averaged = parse_vertex_average(vertex_average)
    check_not_an_input(output, paths if reference in REFERENCE_MODES else [*paths, reference])
    if reference in ("previous", "first") and len(paths) < 2:
        raise InputError(f"{paths[0]}: only one frame; reference={reference!r} needs at least two")
    all_pairs = plan_pairs(len(paths), reference)
    offset, stop = parse_pair_slice(pairs, len(all_pairs))
    return AnalysisPlan(
        frames=tuple(paths), output=os.fspath(output), xdmf=xdmf, reference=reference,
        uv_scale=float(uv_scale), pairs=tuple(map(tuple, all_pairs[offset:stop].tolist())),
        pair_offset=offset, pairs_total=len(all_pairs), fields=fields, averaged=averaged,
        kabsch=bool(kabsch), dtype=store, compression=tuple(h5_compression.items()), tets=tets)


def analyze_sequence(inputs, output, *, reference="previous", uv_scale=1.0, fields="all",
                     dtype="float32", compression="none", kabsch=False, progress=False,
                     command=None, pairs=None, vertex_average=None):
    """Analyse a PLY sequence and write the per-triangle fields to ``output`` (HDF5), or a
    tetrahedral sequence (.vtu, .vtk, .msh, TetGen .node) and its per-tetrahedron fields
    (:mod:`clothtool.analysis.tet_sequence`).

    ``inputs``: a folder, a glob, a file or a list of them (natural order).
    ``reference``: 'previous' (pairs (i, i+1)), 'first' (pairs (0, i)), 'uv' (the
    texture coordinates times ``uv_scale``) or the path of a PLY mesh.
    ``fields``: 'all', 'extended' or names from the registry
    (:mod:`clothtool.fields`); only those are computed and stored.
    ``kabsch``: add the 3D variant (:mod:`clothtool.analysis.variant3d`); ``fields`` may then
    also name its datasets.
    ``pairs``: 'START:STOP' or (start, stop): compute only that slice of the pairs
    (:mod:`clothtool.analysis.output.slices`). ``vertex_average``: face fields to also store as
    area-weighted vertex averages ``/vertex/<name>_avg``
    (:mod:`clothtool.vertex_average`). Always stored: ``/frame_vertices`` and
    ``/summary`` (:mod:`clothtool.analysis.output.extras`); ``out.xdmf`` is written beside
    ``out.h5`` (:mod:`clothtool.io.xdmf`).
    Returns an :class:`AnalysisSummary`. Raises :class:`~clothtool.errors.InputError`
    on bad input, before writing anything.
    """
    started = time.perf_counter()
    plan = plan_analysis(inputs, output, reference=reference, uv_scale=uv_scale, fields=fields,
                         dtype=dtype, compression=compression, kabsch=kabsch, pairs=pairs,
                         vertex_average=vertex_average)
    if plan.tets:
        from clothtool.analysis.tet_sequence import run_tet_analysis

        return run_tet_analysis(plan, progress=progress, command=command, started=started)
    return run_analysis(plan, progress=progress, command=command, started=started)


def run_analysis(plan, *, progress=False, command=None, started=None):
    """Run an :class:`AnalysisPlan`: read the frames, compute, write ``plan.output``
    atomically. Returns an :class:`AnalysisSummary`."""
    started = time.perf_counter() if started is None else started
    reader = FrameReader(plan.frames)
    rest = _Rest(reader, plan.reference, plan.uv_scale)
    pairs = np.array(plan.pairs, dtype=np.int64).reshape(-1, 2)
    m = len(reader.faces)
    summary = AnalysisSummary(plan.output, len(plan.frames), len(pairs), m, reader.n_vertices,
                              plan.fields, plan.reference, 0.0)
    kernel_plan = KernelPlan(m, plan.computed)
    compression = dict(plan.compression)

    variant = None
    if plan.kabsch:
        from clothtool.analysis.variant3d import Variant3D

        variant = Variant3D(reader.faces, reader.n_vertices, plan.fields, DEGENERATE_TOL)

    def make_buffers():
        out, out_flags, views = kernel_plan.allocate(plan.dtype)
        return {**views, "kernel/out": out, "kernel/out_flags": out_flags, **extras.buffers(),
                **(variant.buffers(plan.dtype) if variant else {})}

    atomic = AtomicH5(plan.output)
    with atomic as h5:
        _write_header(h5, plan, pairs, rest, reader, command)
        extras = PairExtras(h5, pairs, plan.pair_offset, len(plan.frames), reader.faces,
                            reader.n_vertices,
                            {name: registry_field(name).shape for name in plan.averaged}, plan.dtype,
                            compression)
        datasets = create_field_datasets(h5, "face", [n for n in plan.fields if n in NAMES_2D],
                                         len(pairs), m, plan.dtype, compression)
        if variant:
            datasets.update(variant.create_datasets(h5, len(pairs), plan.dtype, compression))
        with PairWriter({**datasets, **extras.datasets}, make_buffers) as writer, \
                kernel_threads_beside_writer():
            _stream_pairs(pairs, reader, rest, writer, summary, kernel_plan, progress, extras,
                          variant)
        extras.close()
        atomic.add_sidecar(plan.xdmf, xdmf_text(h5, os.path.basename(plan.output)))
    summary.seconds = time.perf_counter() - started
    return summary


def _stream_pairs(pairs, reader, rest, writer, summary, kernel_plan, progress, extras, variant):
    """The triangle kernel (and the 3D variant) in the pair loop of
    :func:`~clothtool.analysis.pairs.stream_pairs`."""
    faces = reader.faces
    x_uv = rest.uv_positions() if variant and rest.reference == "uv" else None

    def compute(buffers, d, x_ref, ref, x):
        kernel = (*ref, DEGENERATE_TOL, kernel_plan.starts, kernel_plan.needs,
                  buffers["kernel/out"], buffers["kernel/out_flags"])
        if rest.reference == "previous":
            # This frame is the next pair's reference: its rest data from the same pass
            # (fresh arrays: the writer thread may still read the current ones).
            next_rest = allocate_rest(len(faces))
            deformation_fields_and_next_rest(x, faces, *kernel, *next_rest)
            rest.put(d, next_rest)
        else:
            deformation_fields(x, faces, *kernel)
        if variant:
            variant.compute(x_ref if x_uv is None else x_uv, x, buffers)
            _accumulate_3d(summary, buffers)

    stream_pairs(pairs, reader, rest, writer, summary, extras, compute, progress,
                 report_stretch="stretch" in summary.fields)


def _write_header(h5, plan, pairs, rest, reader, command):
    write_common_header(h5, plan, pairs, command, DEGENERATE_TOL)
    reference = plan.reference
    if reference == "uv":
        h5.attrs["uv_scale"] = plan.uv_scale
    mesh = h5.create_group("mesh")
    mesh.create_dataset("faces", data=reader.faces)
    mesh.create_dataset("face_source", data=reader.first.face_source)
    mesh.create_dataset("vertices", data=rest.vertices())
    if reference == "uv":
        mesh.create_dataset(rest.external[1].name, data=rest.external[1].data)


def _accumulate_3d(summary, buffers):
    angle = buffers["vertex/angle"]
    if angle.size and np.isfinite(angle).any():
        largest = np.fmax(summary.extra.get("angle_max", np.nan), np.nanmax(angle))
        summary.extra["angle_max"] = float(largest)
    if buffers["vertex/flags"].size:
        summary.extra["vertex_flagged"] = (summary.extra.get("vertex_flagged", 0)
                                           + int(np.count_nonzero(buffers["vertex/flags"])))


