"""The 3D (Kabsch) variant inside ``analyze_sequence`` (``clothtool analyze --kabsch``, spec §3).

Datasets, beside the 2D ones (P pairs, N vertices, M triangles, E interior edges):

    /vertex/rotation (P, N, 3, 3)   /vertex/angle (P, N)   /vertex/residual (P, N)   /vertex/flags (P, N) uint8
    /face/F3 /face/R3 /face/U3 (P, M, 3, 3)   /face/stretch3 (P, M, 3)   /face/directions3 (P, M, 3, 3)
    /edge/dihedral_change (P, E)   /edge/flags (P, E) uint8
    /mesh/edges (E, 2)   /mesh/edge_opposite (E, 2)

``--fields`` names them by their last path component; ``flags`` selects /face/flags and, with
``--kabsch``, /vertex/flags and /edge/flags. The one-ring and edge tables are built once.
"""

import numpy as np

from clothtool.analysis.dihedral import dihedral_fields
from clothtool.analysis.kabsch import face_fields3, vertex_fields
from clothtool.analysis.topology import interior_edges, one_ring

SHAPES = {("vertex", "rotation"): (3, 3), ("vertex", "angle"): (), ("vertex", "residual"): (),
          ("vertex", "flags"): (),
          ("face", "F3"): (3, 3), ("face", "R3"): (3, 3), ("face", "U3"): (3, 3), ("face", "stretch3"): (3,),
          ("face", "directions3"): (3, 3),
          ("edge", "dihedral_change"): (), ("edge", "flags"): ()}
KABSCH_FIELDS = tuple(name for (group, name) in SHAPES if name != "flags")


class Variant3D:
    """The requested 3D datasets of one analysis: tables and output buffers made once, filled
    for every pair by :meth:`compute` (float fields in ``dtype``, flags uint8). /face/flags is
    not among them: the 2D kernel writes it, with the same bits 0–2 as the F3 kernel's."""

    def __init__(self, faces, n_vertices, fields, dtype, tol):
        self.faces, self.tol = faces, tol
        wanted = {key for key in SHAPES if key[1] in fields and key != ("face", "flags")}
        self.groups = {group for group, _ in wanted}
        sizes = {"vertex": n_vertices, "face": len(faces), "edge": 0}
        if "vertex" in self.groups:
            self.offsets, self.neighbours = one_ring(faces, n_vertices)
        if "edge" in self.groups:
            self.edges, self.opposite = interior_edges(faces, n_vertices)
            sizes["edge"] = len(self.edges)
        self.buffers = {key: np.empty((sizes[key[0]] if key in wanted else 0, *shape),
                                      np.uint8 if key[1] == "flags" else dtype)
                        for key, shape in SHAPES.items()}
        self.wanted = [key for key in SHAPES if key in wanted]

    def write_tables(self, mesh_group):
        """/mesh/edges and /mesh/edge_opposite, when edge datasets are written."""
        if "edge" in self.groups:
            mesh_group.create_dataset("edges", data=self.edges)
            mesh_group.create_dataset("edge_opposite", data=self.opposite)

    def compute(self, x_ref, x_def):
        """Fill the buffers for one pair of (N, 3) float64 positions; returns {(group, name): array}."""
        b = self.buffers
        if "vertex" in self.groups:
            vertex_fields(x_ref, x_def, self.offsets, self.neighbours,
                          *(b["vertex", n] for n in ("rotation", "angle", "residual", "flags")))
        if "face" in self.groups:
            face_fields3(x_ref, x_def, self.faces, self.tol,
                         *(b["face", n] for n in ("F3", "R3", "U3", "stretch3", "directions3")),
                         np.empty(0, np.uint8))
        if "edge" in self.groups:
            dihedral_fields(x_ref, x_def, self.edges, self.opposite, self.tol,
                            b["edge", "dihedral_change"], b["edge", "flags"])
        return {key: b[key] for key in self.wanted}
