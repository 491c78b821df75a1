"""The terms of the finite-element elastic energy W(x) = Σ_terms W_term(x).

Each term is a potential over vertex stencils (NVIDIA Newton's ModelBuilder keeps one
array per element kind the same way): ``elements`` are the stencils it couples (rows of
vertex indices, for the block pattern of the system matrix), :meth:`bind` takes each
stencil's block slots in that pattern, :meth:`constant` adds its constant Hessian (a
quadratic term's whole Hessian) to the pattern's values once, :meth:`energy` is W_term(x)
and :meth:`assemble` adds ∇W_term and the rest of its PSD Hessian.
:class:`~clothtool.sim.energies.energy.FemElastic` sums the Model's ``terms``, so a term added here
reaches every method built on it.

- :class:`Membrane`: Baraff–Witkin stretch and shear (Kim 2020, :mod:`clothtool.sim.energies.membrane`),
  per-triangle stiffnesses;
- :class:`NodalMembrane`: the stretch density on each vertex's smoothed metric FᵀF
  (node-based smoothing, :mod:`clothtool.sim.energies.membrane_nodal`; ``material.membrane_model:
  nodal``, beside a shear-only :class:`Membrane`);
- :class:`EdgeMembrane`: stretch and shear on each edge's smoothed metric (edge-based
  smoothing, :mod:`clothtool.sim.energies.membrane_edge`; ``material.membrane_model: edge``);
- :class:`PlateBending`, :class:`DihedralBending`, :class:`QuadraticBending`: the
  ``material.bend_model`` choices (:mod:`clothtool.sim.energies.plate`, :mod:`clothtool.sim.energies.bending`);
- :class:`Stitch`: W = ½ Σ_s k_s ‖x_a − x_b‖², seam pairs pulled together while a garment
  is sewn (:mod:`clothtool.sim.model.seams`).
"""

import numpy as np

from clothtool.numba_setup import njit
from clothtool.sim.energies.bending import (dihedral_assemble, dihedral_total_energy,
                                   quadratic_gradient)
from clothtool.sim.linalg.blocks import scatter_blocks
from clothtool.sim.energies.membrane import membrane_assemble, membrane_total_energy
from clothtool.sim.energies.membrane_edge import (edge_assemble, edge_exact_remainder, edge_parts,
                                                  edge_stresses)
from clothtool.sim.energies.membrane_nodal import nodal_assemble, nodal_energy, nodal_operator, nodal_pairs
from clothtool.sim.energies.plate import hessian_gradient

NO_GRADIENT = np.zeros((0, 3))  # the energy-only call of the kernels that take a gradient


class Term:
    """A potential over the stencils ``elements`` (see the module); no constant Hessian."""

    elements = None
    project = True  # the membrane's Hessian PSD-projected (statics may ask for the exact one)

    def bind(self, pattern):
        pass

    def soften(self, factor):
        """Only the membrane's stiffness is scaled by ``solver.stiffness_continuation``."""

    def constant(self, pattern, values):
        pass


class Membrane(Term):
    """Σ_t A_t Ψ(F_t) with per-triangle (k_u, k_v, b_u, b_v) and k_shear."""

    def __init__(self, faces, dr_inv, area, stretch, shear):
        self.elements = faces
        self.faces, self.dr_inv, self.area = faces, dr_inv, area
        self.stretch = np.ascontiguousarray(stretch, dtype=np.float64)
        self.shear = np.ascontiguousarray(shear, dtype=np.float64)
        self.stiffness = (self.stretch[:, :2].copy(), self.shear.copy())

    def soften(self, factor):
        """Stretch and shear stiffnesses × ``factor`` in place (1 restores them exactly;
        ``solver.stiffness_continuation``)."""
        np.multiply(self.stiffness[0], factor, out=self.stretch[:, :2])
        np.multiply(self.stiffness[1], factor, out=self.shear)

    def bind(self, pattern):
        self.slots = pattern.slots(self.faces)

    def energy(self, x):
        return membrane_total_energy(x, self.faces, self.dr_inv, self.area, self.stretch,
                                     self.shear)

    def assemble(self, x, grad, values):
        return membrane_assemble(x, self.faces, self.dr_inv, self.area, self.stretch, self.shear,
                                 self.project, self.slots, grad, values)


class NodalMembrane(Term):
    """Σ_v A_v Ψ(C_v), C_v the metric FᵀF averaged over vertex v's third of its triangles
    (``cells``: a cell per vertex and panel, :func:`~clothtool.sim.energies.membrane_nodal.
    nodal_operator`); its stencils couple a vertex with its two-ring."""

    def __init__(self, faces, dr_inv, area, n, stretch, shear, cells=None):
        self.faces, self.dr_inv = faces, dr_inv
        self.operator = nodal_operator(faces, dr_inv, area, n, stretch, shear, cells)
        self.elements = nodal_pairs(*self.operator[:2])

    def bind(self, pattern):
        self.slots = pattern.slots(self.elements)[:, 1]

    def energy(self, x):
        return nodal_energy(x, self.faces, self.dr_inv, *self.operator)

    def assemble(self, x, grad, values):
        return nodal_assemble(x, self.faces, self.dr_inv, *self.operator, self.project, self.slots,
                              grad, values)


class EdgeMembrane(Term):
    """Σ_e A_e Ψ(C_e), C_e the metric FᵀF averaged over edge e's third of its two triangles
    (``cells`` (M, 3): each triangle edge's cell, ``frames``: their unfolded frames or None,
    :mod:`~clothtool.sim.energies.membrane_edge`); stretch and shear, on the triangles'
    blocks (the Hessian's Gauss–Newton part majorised there)."""

    def __init__(self, faces, dr_inv, area, stretch, shear, cells, frames=None):
        self.elements = faces
        self.faces, self.dr_inv, self.area = faces, dr_inv, area
        self.cells = np.ascontiguousarray(cells, np.int64)
        (self.turn, self.weight, self.cell_area, self.stretch,
         self.shear) = edge_parts(area, stretch, shear, self.cells, frames)
        self.metric = np.empty((len(self.cell_area), 3))
        self.stress = np.empty((len(self.cell_area), 9))

    def bind(self, pattern):
        self.slots = pattern.slots(self.faces)

    def stresses(self, x, project):
        """W(x), each cell's metric and stress at x (:func:`~clothtool.sim.energies.
        membrane_edge.edge_stresses`) kept for the assembly."""
        return edge_stresses(x, self.faces, self.dr_inv, self.cells, self.turn, self.weight,
                             self.cell_area, self.stretch, self.shear, project,
                             self.metric, self.stress)

    def energy(self, x):
        return self.stresses(x, self.project)

    def assemble(self, x, grad, values):
        total = self.stresses(x, self.project)
        edge_assemble(x, self.faces, self.dr_inv, self.area, self.cells, self.turn, self.weight,
                      self.stress, self.slots, grad, values)
        return total

    def exact_remainder(self, x):
        """The exact Hessian at x minus :meth:`assemble`'s unprojected one (sparse (3N, 3N),
        :func:`~clothtool.sim.energies.membrane_edge.edge_exact_remainder`): statics adds it
        for its exact Newton steps. Called right after :meth:`assemble` at the same x: it
        reads the cells' ∂²Ψ/∂C² that assembly kept (projection leaves them as they are)."""
        return edge_exact_remainder(x, self.faces, self.dr_inv, self.cells, self.turn,
                                    self.weight, self.cell_area, self.stress)


class PlateBending(Term):
    """½ Σ_c x_cᵀ (k_b Q) x_c, Q in CSR (ptr, col, val) with k_b folded in; constant Hessian.

    ``matrix``: the CSR that goes into the solver's matrix instead of Q (None: Q). The
    corrected plate (``material.plate_correction``) puts its Q + C in ``plate`` and its Q here:
    C couples a vertex with its three-ring, which would double the matrix (and the cost of
    each PCG product); Newton takes the steps of the PSD Q ⪯ Q + C, which the line search on
    the exact energy keeps descending (:mod:`clothtool.sim.energies.plate`)."""

    def __init__(self, plate, n, matrix=None):
        self.plate = plate
        self.matrix = plate if matrix is None else matrix
        ptr, col, _ = self.matrix
        self.elements = np.stack([np.repeat(np.arange(n), np.diff(ptr)), col], axis=1)

    def constant(self, pattern, values):
        slot = pattern.slots(self.elements)[:, 1]
        for p in range(3):
            values[slot, p, p] += self.matrix[2]

    def energy(self, x):
        return hessian_gradient(x, *self.plate, NO_GRADIENT)

    def assemble(self, x, grad, values):
        return hessian_gradient(x, *self.plate, grad)

    def unassembled(self):
        """(3N × 3N scipy CSR) (Q + C − Q) ⊗ I₃: the Hessian the solver's matrix leaves out
        (None when there is none), for the direct solve of statics."""
        if self.matrix is self.plate:
            return None
        import scipy.sparse as sps

        n = len(self.plate[0]) - 1
        full, part = (sps.csr_matrix((v, c, p), shape=(n, n)) for p, c, v in (self.plate,
                                                                             self.matrix))
        return sps.kron(full - part, sps.eye(3), format="csr")


class DihedralBending(Term):
    """Σ_h c_h (θ_h − θ̄_h)² over hinges (i, j, k, l), Gauss–Newton Hessian."""

    def __init__(self, hinge, rest_angle, coef):
        self.elements = hinge
        self.hinge, self.rest_angle, self.coef = hinge, rest_angle, coef

    def bind(self, pattern):
        self.slots = pattern.slots(self.hinge)

    def energy(self, x):
        return dihedral_total_energy(x, self.hinge, self.rest_angle, self.coef)

    def assemble(self, x, grad, values):
        return dihedral_assemble(x, self.hinge, self.rest_angle, self.coef, self.slots, grad,
                                 values)


class QuadraticBending(Term):
    """Σ_h c_h ‖Σ_a w_ha x_a‖² (Bergou et al. 2006); constant Hessian 2c_h w wᵀ ⊗ I₃."""

    def __init__(self, hinge, weights, coef):
        self.elements = hinge
        self.hinge, self.weights, self.coef = hinge, weights, coef

    def constant(self, pattern, values):
        w = self.weights
        elem = 2.0 * self.coef[:, None, None] * np.einsum("ha,hb->hab", w, w)  # (H, 4, 4)
        blocks = np.einsum("hab,pq->hapbq", elem, np.eye(3)).reshape(-1, 12, 12)
        scatter_blocks(blocks, pattern.slots(self.hinge), values)

    def energy(self, x):
        return quadratic_gradient(x, self.hinge, self.weights, self.coef, NO_GRADIENT)

    def assemble(self, x, grad, values):
        return quadratic_gradient(x, self.hinge, self.weights, self.coef, grad)


class Stitch(Term):
    """W = ½ Σ_s k_s ‖x_{a_s} − x_{b_s}‖² over the stitch pairs (a_s, b_s): a zero-length
    spring per pair. ∇_a W = k_s (x_a − x_b) = −∇_b W; the Hessian k_s [[I, −I], [−I, I]] is
    constant and PSD (eigenvalues 0 and 2k_s)."""

    def __init__(self, pairs, stiffness):
        self.elements = np.ascontiguousarray(pairs, dtype=np.int64)
        self.stiffness = np.ascontiguousarray(stiffness, dtype=np.float64)

    def constant(self, pattern, values):
        k = self.stiffness[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]])  # (S, 2, 2)
        blocks = np.einsum("sab,pq->sapbq", k, np.eye(3)).reshape(-1, 6, 6)
        scatter_blocks(blocks, pattern.slots(self.elements), values)

    def energy(self, x):
        return stitch_energy(x, self.elements, self.stiffness, NO_GRADIENT)

    def assemble(self, x, grad, values):
        return stitch_energy(x, self.elements, self.stiffness, grad)

    def gaps(self, x):
        """(S,) ‖x_a − x_b‖ of every pair."""
        d = x[self.elements[:, 0]] - x[self.elements[:, 1]]
        return np.sqrt(np.einsum("sp,sp->s", d, d))


@njit(cache=True)
def stitch_energy(x, pairs, stiffness, grad):
    """½ Σ k_s ‖x_a − x_b‖²; adds the gradient to grad unless grad is empty."""
    total = 0.0
    with_grad = grad.shape[0] > 0
    for s in range(pairs.shape[0]):
        a, b = pairs[s, 0], pairs[s, 1]
        k = stiffness[s]
        for p in range(3):
            d = x[a, p] - x[b, p]
            total += 0.5 * k * d * d
            if with_grad:
                grad[a, p] += k * d
                grad[b, p] -= k * d
    return total
