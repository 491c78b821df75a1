"""Small sheets and assembly helpers for the tests of the smoothed membranes (``nodal``: one
cell per vertex, ``edge``: one cell per edge), each as its term on its own block pattern."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.sim.energies.membrane_edge import edge_cells
from clothtool.sim.energies.terms import EdgeMembrane, NodalMembrane
from clothtool.sim.linalg.blocks import BlockMatrix, BlockPattern
from clothtool.sim.textile import disc

KINDS = ["grid", "rot45", "delaunay"]
STRETCH = (5000.0, 3000.0, 1.0, 1.0)


def sheet(kind, stretch=STRETCH, shear=50.0, radius=0.03, spacing=0.01):
    """(uv, faces, dr_inv, area, stretch (M, 4), shear (M,)) of a small disc."""
    uv, faces = disc(radius, spacing, kind, seed=3)
    p = uv[faces]
    dr = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)
    area = 0.5 * np.abs(np.linalg.det(dr))
    m = len(faces)
    return (uv, faces, np.linalg.inv(dr), area, np.tile(np.asarray(stretch, float), (m, 1)),
            np.full(m, float(shear)))


class System:
    """A smoothed membrane ``term`` bound to a pattern of its own elements."""

    def __init__(self, term, n):
        self.term = term
        self.pattern = BlockPattern(n, term.elements)
        term.bind(self.pattern)

    def energy(self, x):
        return self.term.energy(x)

    def assemble(self, x, project):
        """(energy, gradient, matrix values) at x."""
        self.term.project = project
        grad = np.zeros_like(x)
        values = self.pattern.zeros()
        energy = self.term.assemble(x, grad, values)
        return energy, grad, values

    def dense(self, values):
        return dense(self.pattern, values)


def nodal_system(uv, faces, dr_inv, area, stretch, shear):
    """The node-based membrane's :class:`System`."""
    return System(NodalMembrane(faces, dr_inv, area, len(uv), stretch, shear), len(uv))


def edge_system(uv, faces, dr_inv, area, stretch, shear, frames=None):
    """The edge-based membrane's :class:`System`."""
    return System(EdgeMembrane(faces, dr_inv, area, stretch, shear, edge_cells(faces), frames),
                  len(uv))


SYSTEMS = {"nodal": nodal_system, "edge": edge_system}


def sheet_system(membrane, kind, **sheet_args):
    """(the :func:`sheet` of ``kind``, the :class:`System` of ``membrane`` on it)."""
    mesh = sheet(kind, **sheet_args)
    return mesh, SYSTEMS[membrane](*mesh)


def dense(pattern, values):
    return BlockMatrix(pattern, values).to_scipy().toarray()


def flat(uv):
    return np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)


def boundary_vertices(faces, n):
    """(n,) True on the vertices of edges with one triangle."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    e, count = np.unique(edges, axis=0, return_counts=True)
    out = np.zeros(n, bool)
    out[e[count == 1].ravel()] = True
    return out


def random_sheets(max_examples):
    """A hypothesis test over a seed and a mesh kind."""
    return lambda test: settings(max_examples=max_examples, deadline=None)(
        given(seed=st.integers(0, 2**31), kind=st.sampled_from(KINDS))(test))
