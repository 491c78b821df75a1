"""The 3D (Kabsch) variant inside ``analyze_sequence`` (``clothtool analyze --kabsch``).

Datasets, beside the 2D ones (P pairs, N vertices, M triangles, E interior edges):

    /vertex/rotation (P, N, 3, 3)   /vertex/angle (P, N)   /vertex/residual (P, N)
    /vertex/flags (P, N) uint8
    /face/F3 /face/R3 /face/U3 (P, M, 3, 3)   /face/stretch3 (P, M, 3)   /face/directions3 (P, M, 3, 3)
    /edge/dihedral_change (P, E)   /edge/flags (P, E) uint8
    /mesh/edges (E, 2)   /mesh/edge_opposite (E, 2)

``--fields`` names them by their last path component; ``flags`` selects /face/flags and, with
``--kabsch``, /vertex/flags and /edge/flags. /face/flags comes from the 2D kernel, whose bits 0–2
are those of the F3 kernel. The one-ring and edge tables are built once per analysis.
"""

import numpy as np

from clothtool.analysis.dihedral import dihedral_fields
from clothtool.analysis.face3d import face_fields3
from clothtool.fields import NAMES_3D, REGISTRY
from clothtool.analysis.kabsch import vertex_fields
from clothtool.geometry import hinges, one_ring
from clothtool.io.h5 import create_pair_dataset

SHAPES = {f.key: f.shape for f in REGISTRY if f.kernel not in ("2d", "tet")}
KABSCH_FIELDS = NAMES_3D
VERTEX_KEYS = ("vertex/rotation", "vertex/angle", "vertex/residual", "vertex/flags")
FACE_KEYS = ("face/F3", "face/R3", "face/U3", "face/stretch3", "face/directions3")
EDGE_KEYS = ("edge/dihedral_change", "edge/flags")


class Variant3D:
    """The requested 3D datasets of one analysis. The tables are made once; :meth:`buffers`
    makes a set of output arrays (full size for requested datasets, empty for the others) that
    :meth:`compute` fills for one pair."""

    def __init__(self, faces, n_vertices, fields, tol):
        self.faces, self.tol = faces, tol
        self.keys = [key for key in SHAPES if key.split("/")[1] in fields]
        self.groups = {key.split("/")[0] for key in self.keys}
        self.sizes = {"vertex": n_vertices, "face": len(faces), "edge": 0}
        if "vertex" in self.groups:
            self.offsets, self.neighbours = one_ring(faces, n_vertices)
        if "edge" in self.groups:
            hinge, _ = hinges(faces, n_vertices)
            self.edges, self.opposite = np.ascontiguousarray(hinge[:, :2]), np.ascontiguousarray(hinge[:, 2:])
            self.sizes["edge"] = len(self.edges)

    def _shape(self, key):
        return (self.sizes[key.split("/")[0]] if key in self.keys else 0, *SHAPES[key])

    def buffers(self, store):
        return {key: np.empty(self._shape(key), np.uint8 if key.endswith("/flags") else store)
                for key in SHAPES}

    def create_datasets(self, h5, n_pairs, store, compression):
        """The requested datasets in the open result ``h5``, with /mesh/edges and
        /mesh/edge_opposite when edge datasets are among them. Returns {key: dataset}."""
        if "edge" in self.groups:
            h5["mesh"].create_dataset("edges", data=self.edges)
            h5["mesh"].create_dataset("edge_opposite", data=self.opposite)
        return {key: create_pair_dataset(h5.require_group(key.split("/")[0]), key.split("/")[1],
                                         n_pairs, self._shape(key),
                                         np.uint8 if key.endswith("/flags") else store, compression)
                for key in self.keys}

    def compute(self, x_ref, x_def, buffers):
        """Fill ``buffers`` (from :meth:`buffers`) for one pair of (N, 3) float64 positions."""
        if "vertex" in self.groups:
            vertex_fields(x_ref, x_def, self.offsets, self.neighbours,
                          *(buffers[k] for k in VERTEX_KEYS))
        if "face" in self.groups:
            face_fields3(x_ref, x_def, self.faces, self.tol, *(buffers[k] for k in FACE_KEYS),
                         np.empty(0, np.uint8))
        if "edge" in self.groups:
            dihedral_fields(x_ref, x_def, self.edges, self.opposite, self.tol,
                            *(buffers[k] for k in EDGE_KEYS))
