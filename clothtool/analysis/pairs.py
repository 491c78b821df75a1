"""The pair loop shared by the triangle analysis (:mod:`clothtool.analysis.sequence`) and the
tetrahedral one (:mod:`clothtool.analysis.tet_sequence`), and the parts of a result both write.

One frame is in memory at a time (plus the current reference): :func:`pair_frames` reuses
the frame read last when the next pair names it again, and :class:`RestCache` keeps the
reference's rest-state data D_r⁻¹ while it is used, so it is computed once per reference
frame, not once per pair.
"""

import contextlib
import datetime
import functools
from dataclasses import dataclass, field

import numpy as np

from clothtool import __version__, interrupt
from clothtool.fields import field as registry_field
from clothtool.io.h5 import create_pair_dataset

EXTERNAL = -1  # the reference index of pairs against a reference mesh or the uv rest shape


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
    tets: int = 0  # a tetrahedral sequence: its tetrahedra (and triangles = 0)
    ignored_cells: int = 0  # cells other than tetrahedra in its first frame

    def describe(self):
        elements = (f"{self.tets} tetrahedra" if self.tets else f"{self.triangles} triangles")
        lines = [f"wrote {self.output}: {self.pairs} pairs of {self.frames} frames, "
                 f"{elements}, {self.vertices} vertices "
                 f"(reference: {self.reference}) in {self.seconds:.2f} s",
                 f"  fields: {', '.join(self.fields)}"]
        if self.ignored_cells:
            lines.append(f"  ignored: {self.ignored_cells} cells that are not tetrahedra")
        if np.isfinite(self.stretch_max):
            lines.append(f"  principal stretch: largest λ1 {self.stretch_max:.4f}, "
                         f"smallest λ{3 if self.tets else 2} {self.stretch_min:.4f}")
        if "flags" in self.fields and self.tets:
            lines.append(f"  flagged tetrahedron-pairs (degenerate, non-finite or inverted): "
                         f"{self.flagged}")
        elif "flags" in self.fields:
            lines.append(f"  flagged triangle-pairs (degenerate, non-finite or flipped): {self.flagged}")
        if "angle_max" in self.extra:
            lines.append(f"  3D variant: largest vertex rotation {self.extra['angle_max']:.4f} rad")
        if "vertex_flagged" in self.extra:
            lines.append(f"  flagged vertex-pairs (degenerate ring, non-finite or ambiguous): "
                         f"{self.extra['vertex_flagged']}")
        return "\n".join(lines)


class RestCache:
    """Rest-state data of the current reference, computed once (:meth:`compute`, in the
    subclass) and kept while it is used."""

    def __init__(self):
        self._key, self._data = None, None

    def put(self, index, data):
        """Rest-state data of frame ``index`` computed elsewhere (see ``next_rest``)."""
        self._key, self._data = index, data

    def get(self, index, positions):
        """The rest-state data of reference ``index`` whose positions are ``positions``."""
        if self._key != index:
            self._data = self.compute(positions)
            self._key = index
        return self._data


@contextlib.contextmanager
def kernel_threads_beside_writer():
    """Leave one core to the HDF5 writer thread while the kernels run: on 2 cores the
    100k-triangle benchmark runs in 1.55 s with one kernel thread and 1.7–1.9 s with two."""
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(max(1, threads - 1))
    try:
        yield
    finally:
        numba.set_num_threads(threads)


def pair_frames(pairs, reader, rest, progress):
    """(p, r, d, x_r, rest data of r, x_d) for every pair (r, d), one frame in memory at a time:
    the frame read last is reused when the next pair names it again."""
    last = (0, reader.first.vertices)
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
        yield p, r, d, x_ref, ref, x


def stream_pairs(pairs, reader, rest, writer, summary, extras, compute, progress,
                 report_stretch=True):
    """Compute every pair, one frame in memory at a time, and hand its buffers to ``writer``.

    ``compute(buffers, d, x_ref, ref, x)`` runs the kernel of the pair (r, d) into
    ``buffers`` (and may ``rest.put`` the rest data of frame d for the next pair). The
    summary row follows here, on this thread: the writer thread is the slower of the two
    (its rows are the I/O floor), so it only writes, stores the frame positions and makes
    the vertex averages (:class:`~clothtool.analysis.output.extras.PairExtras`), overlapping
    the next pair.
    """
    for p, r, d, x_ref, ref, x in pair_frames(pairs, reader, rest, progress):
        buffers = writer.buffers()
        compute(buffers, d, x_ref, ref, x)
        extras.summarise(p, buffers)
        accumulate(summary, buffers["stretch"] if report_stretch else None, buffers["flags"])
        writer.write(p, buffers, functools.partial(extras.pair, p, buffers, ref[0],
                                                   ((r, x_ref), (d, x))))


def write_common_header(h5, plan, pairs, command, tol):
    """Root attributes, ``/frames`` and ``/pairs`` of a result (triangles or tetrahedra)."""
    import h5py

    h5.attrs["clothtool_version"] = __version__
    h5.attrs["reference"] = plan.reference
    h5.attrs["command"] = command or "clothtool.analyze_sequence"
    h5.attrs["created"] = datetime.datetime.now(datetime.timezone.utc).astimezone().isoformat(
        timespec="seconds")
    h5.attrs["degenerate_tol"] = tol
    h5.attrs["dtype"] = plan.dtype.name
    h5.create_dataset("frames", data=np.array(plan.frames, dtype=object),
                      dtype=h5py.string_dtype())
    h5.create_dataset("pairs", data=pairs)
    h5.attrs["pair_offset"] = plan.pair_offset
    h5.attrs["pairs_total"] = plan.pairs_total


def create_field_datasets(h5, group, names, n_pairs, m, store, compression):
    """``/<group>/<name>`` (P, M, *shape) for the registry fields ``names`` of ``group``
    (float fields in ``store``, integer fields uint8)."""
    parent = h5.create_group(group)
    datasets = {}
    for name in names:
        f = registry_field(name, group)
        datasets[name] = create_pair_dataset(parent, name, n_pairs, (m, *f.shape),
                                             np.uint8 if f.integer else store, compression)
    return datasets


def accumulate(summary, stretch, flags):
    """Into ``summary``: the largest λ1 and the smallest last stretch (λ2, or λ3 of
    tetrahedra) of a pair's (M, k) ``stretch`` (None: not reported), and its flagged count."""
    if stretch is not None and stretch.size and np.isfinite(stretch).any():
        summary.stretch_max = float(np.fmax(summary.stretch_max, np.nanmax(stretch[:, 0])))
        summary.stretch_min = float(np.fmin(summary.stretch_min, np.nanmin(stretch[:, -1])))
    summary.flagged += int(np.count_nonzero(flags))


def _progress(pairs, enabled):
    if not enabled:
        return pairs
    from tqdm import tqdm

    return tqdm(pairs, desc="analyze", unit="pair", leave=False)
