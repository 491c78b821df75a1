"""What ``analyze`` stores besides the face fields, pair by pair:

- ``/frame_vertices`` (T, N, 3), storage dtype, chunked per frame: the positions of every
  frame, written once, as it is read (frames a ``--pairs`` slice does not read stay NaN);
  the XDMF's geometry.
- ``/summary``: :mod:`clothtool.analysis.output.summary`.
- ``/vertex/<field>_avg`` (P, N, …): :mod:`clothtool.vertex_average`, if asked for.
"""

import numpy as np

from clothtool.io.h5 import create_pair_dataset
from clothtool.analysis.output.summary import SummaryWriter
from clothtool.vertex_average import SUFFIX, VertexAverager, rest_areas


class PairExtras:
    """Creates the datasets in the open result ``h5`` and fills them from each pair's buffers.

    ``tets``: a tetrahedral result (summary over tetrahedra; ``faces`` None, nothing averaged).
    The vertex averages go through the caller's pair writer: :attr:`datasets` are its extra
    datasets and :meth:`buffers` its extra arrays, keyed ``vertex/<field>_avg``.
    """

    def __init__(self, h5, pairs, offset, n_frames, faces, n_vertices, averaged, store,
                 compression, tets=False):
        self.positions = create_pair_dataset(h5, "frame_vertices", n_frames, (n_vertices, 3),
                                             store, compression, fillvalue=np.nan)
        self.stored = np.zeros(n_frames, bool)
        self.table = SummaryWriter(h5, pairs, offset, tets=tets)
        self.averaged = averaged
        self.averager = VertexAverager(faces, n_vertices) if averaged else None
        self.shapes = {}
        self.datasets = {}
        for name, item_shape in averaged.items():
            key = f"vertex/{name}{SUFFIX}"
            self.shapes[key] = (n_vertices, *item_shape)
            self.datasets[key] = create_pair_dataset(h5.require_group("vertex"), name + SUFFIX,
                                                     len(pairs), self.shapes[key], store,
                                                     compression)
        self.store = store

    def buffers(self):
        return {key: np.empty(shape, self.store) for key, shape in self.shapes.items()}

    def frame(self, index, x):
        """Store the positions of frame ``index`` (−1, an external reference, is skipped)."""
        if index >= 0 and not self.stored[index]:
            self.positions[index] = x
            self.stored[index] = True

    def summarise(self, p, buffers):
        """The summary row of pair ``p`` from the fields in its ``buffers``."""
        self.table.add(p, buffers)

    def pair(self, p, buffers, dinv, frames=()):
        """The vertex averages of pair ``p`` (into ``buffers``), from the face fields in
        ``buffers`` and the reference's D_r⁻¹ (for the rest areas); ``frames``: (index,
        positions) of the pair's frames, stored if not yet (:meth:`frame`)."""
        for index, x in frames:
            self.frame(index, x)
        if self.averaged:
            areas = rest_areas(dinv)
            for name in self.averaged:
                buffers[f"vertex/{name}{SUFFIX}"][...] = self.averager(buffers[name], areas)

    def close(self):
        self.table.close()
