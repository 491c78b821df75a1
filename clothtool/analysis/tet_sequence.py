"""``analyze_sequence`` on a tetrahedral sequence: per-tetrahedron fields streamed to HDF5.

The result has ``/mesh/tets`` (M, 4) instead of ``/mesh/faces`` and the fields of
:mod:`clothtool.analysis.tet` under ``/tet/`` (P, M, …), chunked one pair per row like the
triangle fields; ``/frame_vertices``, ``/pairs``, ``/frames`` and ``/summary`` are as for
triangles. One frame (plus the current reference) is in memory at a time.
"""

import os
import time

import numpy as np

from clothtool.analysis.output.extras import PairExtras
from clothtool.analysis.pairs import (AnalysisSummary, RestCache, create_field_datasets,
                                      kernel_threads_beside_writer, stream_pairs,
                                      write_common_header)
from clothtool.analysis.tet import (DEGENERATE_TOL, KernelPlan, allocate_rest,
                                    rest_from_positions, tet_fields, tet_fields_and_next_rest)
from clothtool.errors import InputError
from clothtool.io.h5 import AtomicH5, PairWriter
from clothtool.io.tetmesh import TetFrameReader, read_tet_mesh
from clothtool.io.xdmf import xdmf_text


def check_tet_options(reference, kabsch, vertex_average):
    """Options of the triangle analysis that do not apply to tetrahedra: one-line errors."""
    if kabsch:
        raise InputError("{kabsch}: the 3D variant is for triangle meshes; a tetrahedral "
                         "sequence already gets the full 3×3 analysis",
                         mentions={"kabsch": "kabsch=True"})
    if reference == "uv":
        raise InputError("tetrahedral meshes have no texture coordinates; use previous, first "
                         "or a mesh file", keyword="reference", value="uv")
    if vertex_average:
        raise InputError("only for triangle meshes", keyword="vertex_average",
                         value=vertex_average)


class _TetRest(RestCache):
    """D_r⁻¹ and flags of the current reference."""

    def __init__(self, reader, external):
        super().__init__()
        self.reader, self.external = reader, external

    def vertices(self):
        return self.external if self.external is not None else self.reader.first.vertices

    def compute(self, positions):
        return rest_from_positions(positions, self.reader.tets, DEGENERATE_TOL)


def run_tet_analysis(plan, *, progress=False, command=None, started=None):
    """Run the :class:`~clothtool.analysis.sequence.AnalysisPlan` of a tetrahedral sequence:
    read the frames, compute, write ``plan.output`` atomically. Returns its AnalysisSummary."""
    started = time.perf_counter() if started is None else started
    reader = TetFrameReader(plan.frames)
    external = None
    if plan.reference not in ("previous", "first"):
        if not os.path.isfile(plan.reference):
            raise InputError(f"{plan.reference!r} is not previous, first or an existing mesh "
                             "file", keyword="reference")
        external = reader.check_same_topology(read_tet_mesh(plan.reference, reuse=reader.first),
                                              plan.reference).vertices
    rest = _TetRest(reader, external)
    pairs = np.array(plan.pairs, dtype=np.int64).reshape(-1, 2)
    m, n = len(reader.tets), reader.n_vertices
    summary = AnalysisSummary(plan.output, len(plan.frames), len(pairs), 0, n, plan.fields,
                              plan.reference, 0.0, tets=m, ignored_cells=reader.first.other_cells)
    compression = dict(plan.compression)
    previous = plan.reference == "previous"

    atomic = AtomicH5(plan.output)
    with atomic as h5:
        write_common_header(h5, plan, pairs, command, DEGENERATE_TOL)
        h5.attrs["ignored_cells"] = reader.first.other_cells
        mesh = h5.create_group("mesh")
        mesh.create_dataset("tets", data=reader.tets)
        mesh.create_dataset("vertices", data=rest.vertices())
        extras = PairExtras(h5, pairs, plan.pair_offset, len(plan.frames), None, n, {},
                            plan.dtype, compression, tets=True)
        datasets = create_field_datasets(h5, "tet", plan.fields, len(pairs), m, plan.dtype,
                                         compression)
        kernel_plan = KernelPlan(m, plan.computed)

        def make_buffers():
            out, out_flags, views = kernel_plan.allocate(plan.dtype)
            return {**views, "kernel/out": out, "kernel/out_flags": out_flags}

        def compute(buffers, d, x_ref, ref, x):
            kernel = (x, reader.tets, *ref, DEGENERATE_TOL, kernel_plan.starts,
                      kernel_plan.needs, buffers["kernel/out"], buffers["kernel/out_flags"])
            if previous:
                # this frame is the next reference: its D_r⁻¹ from the same pass (fresh
                # arrays: the writer thread may still read these)
                next_rest = allocate_rest(m)
                tet_fields_and_next_rest(*kernel, *next_rest)
                rest.put(d, next_rest)
            else:
                tet_fields(*kernel)

        with PairWriter(datasets, make_buffers) as writer, kernel_threads_beside_writer():
            stream_pairs(pairs, reader, rest, writer, summary, extras, compute, progress)
        extras.close()
        atomic.add_sidecar(plan.xdmf, xdmf_text(h5, os.path.basename(plan.output)))
    summary.seconds = time.perf_counter() - started
    return summary


