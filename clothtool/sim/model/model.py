"""The Model: everything about a run that does not change while it runs (made by
:mod:`clothtool.sim.model.builder`).

Rest data per triangle (D_r⁻¹, rest area), lumped masses m_v = Σ ρA/3, the
elastic terms that are switched on (:mod:`clothtool.sim.energies.terms`) with their per-element
parameters (per-triangle stiffness, per-hinge bending), per-hinge bending data,
pins, colliders, and the block pattern of the system matrix with each element's
block slots, and the spring network of the spring-based methods (built on first use,
then kept). A term whose stiffness is zero is left out entirely (no hinges,
no pattern blocks, no kernels), as are pins and colliders when there are none.
"""

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from clothtool.sim.linalg.blocks import BlockPattern
from clothtool.sim.model.state import State


@dataclass
class Model:
    mesh: object  # RestMesh
    dr_inv: np.ndarray  # (M, 2, 2) D_r⁻¹
    area: np.ndarray  # (M,) rest areas
    mass: np.ndarray  # (N,) lumped masses
    stretch: np.ndarray  # (4,) material's k_u, k_v (N/m, warp and weft), b_u, b_v (rest length factors)
    k_shear: float  # material.shear (the per-triangle values: tri_stretch, tri_shear)
    damping: float  # s (the largest panel's, with per-panel damping: damping_terms)
    gravity: np.ndarray  # (3,)
    bend_model: str | None  # "hessian", "dihedral", "quadratic", or None when bend = 0
    hinge: np.ndarray  # (H, 4) i, j, k, l
    hinge_rest_angle: np.ndarray  # (H,)
    hinge_coef: np.ndarray  # (H,) c = k_b ‖ē‖² / (2(Ā_k + Ā_l))
    hinge_weights: np.ndarray | None  # (H, 4) for the quadratic model
    plate: tuple | None  # (ptr, col, val): k_b Q of the hessian model, CSR (clothtool.sim.energies.plate)
    pinned: np.ndarray  # (P,) vertex indices
    free: np.ndarray  # (N,) bool
    kind: np.ndarray  # (N,) int8 constraint kind: FREE or PINNED
    spheres: np.ndarray  # (S, 4) centre, radius (projected, without barrier contact)
    planes: np.ndarray  # (Q, 6) point, unit normal (likewise)
    collision_margin: float
    pattern: BlockPattern
    tri_slots: np.ndarray  # (M, 9)
    hinge_slots: np.ndarray  # (H, 16)
    constant_hessian: np.ndarray | None  # block values of the hessian or quadratic bending Hessian
    pin_motions: list = field(default_factory=list)  # PinMotion per moving pin group
    contact: object = None  # ContactScene: mesh colliders and self-collision, or None
    terms: list = field(default_factory=list)  # the elastic terms FemElastic sums
    tri_stretch: np.ndarray | None = None  # (M, 4) each triangle's k_u, k_v, b_u, b_v
    tri_shear: np.ndarray | None = None  # (M,) each triangle's k_shear
    stitches: object = None  # the Stitch term while a garment is sewn (clothtool.sim.model.seams)
    damping_terms: list | None = None  # shear and bending damping: the terms with stiffness × β_e
    damping_constant: np.ndarray | None = None  # their constant Hessian blocks
    # damping_model: strain (clothtool.sim.energies.dissipation): (M, 3) β_t k_u, β_t k_v,
    # β_t k_h; (H,) β_e c_e of the hinges (None without hinge bending) on their slots
    strain_damping: np.ndarray | None = None
    bend_damping: np.ndarray | None = None
    hinge_damping_slots: np.ndarray | None = None
    plate_damping: tuple | None = None  # (ptr, col, val) of β k_b Q: the plate's, in place of hinges
    origin: np.ndarray | None = None  # (N, 3) positions at t = 0 when not mesh.positions (a weld)
    file_vertex: np.ndarray | None = None  # (N_file,) model vertex of each file vertex (a weld)

    @cached_property
    def moving_pinned(self):
        """(P,) vertices of the moving pin groups."""
        if not self.pin_motions:
            return np.zeros(0, dtype=np.int64)
        return np.concatenate([m.vertices for m in self.pin_motions])

    def pin_goal(self, t):
        """(P, 3) positions at time t of :attr:`moving_pinned` (rigid motions of the initial
        positions)."""
        x0 = self.mesh.positions if self.origin is None else self.origin
        return np.concatenate([m.positions(x0[m.vertices], t) for m in self.pin_motions])

    @property
    def faces(self):
        return self.mesh.faces

    @property
    def n_vertices(self):
        return len(self.mass)

    @property
    def has_membrane(self):
        return bool(np.any(self.tri_stretch[:, :2] > 0.0) or np.any(self.tri_shear > 0.0))

    @property
    def has_pins(self):
        return len(self.pinned) > 0

    @property
    def has_colliders(self):
        return len(self.spheres) + len(self.planes) > 0

    @cached_property
    def springs(self):
        """The spring network of ``mass-spring``, ``pbd``, ``xpbd`` and ``projective``
        (:func:`~clothtool.sim.energies.springs.build_springs`), built once."""
        from clothtool.sim.energies.springs import build_springs

        return build_springs(self)

    def initial_state(self):
        """Rest positions at rest, pushed out of colliders."""
        from clothtool.contact.projection import resolve_collisions

        state = State(self.mesh.positions.copy(), np.zeros_like(self.mesh.positions))
        if self.has_colliders:
            resolve_collisions(state.x, state.v, self.free, self.spheres, self.planes,
                               self.collision_margin)
        return state
