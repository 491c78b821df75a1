"""The Model: everything about a run that does not change while it runs.

Rest data per triangle (D_r⁻¹, rest area), lumped masses m_v = Σ ρA/3, the
energies that are switched on and their parameters, per-hinge bending data,
pins, colliders, and the block pattern of the system matrix with each element's
block slots, and the spring network of the spring-based methods (built on first use,
then kept). A term whose stiffness is zero is left out entirely (no hinges,
no pattern blocks, no kernels), as are pins and colliders when there are none.
"""

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from clothtool.errors import InputError
from clothtool.sim.linalg.blocks import BlockPattern, scatter_blocks
from clothtool.sim.contact import build_contact_scene
from clothtool.sim.filter import FREE, PINNED
from clothtool.sim.config import Plane, Sphere
from clothtool.sim.methods import barrier_contact
from clothtool.geometry import hinges
from clothtool.sim.mesh import build_rest_mesh, rest_edge_matrices
from clothtool.sim.motion import resolve_pin_entries
from clothtool.sim.state import State

DEGENERATE = 1e-12  # rest triangle area relative to its squared longest edge


@dataclass
class Model:
    mesh: object  # RestMesh
    dr_inv: np.ndarray  # (M, 2, 2) D_r⁻¹
    area: np.ndarray  # (M,) rest areas
    mass: np.ndarray  # (N,) lumped masses
    stretch: np.ndarray  # (4,) k_u, k_v (N/m, warp and weft), b_u, b_v (rest length factors)
    k_shear: float
    damping: float  # s
    gravity: np.ndarray  # (3,)
    bend_model: str | None  # "hessian", "dihedral", "quadratic", or None when bend = 0
    hinge: np.ndarray  # (H, 4) i, j, k, l
    hinge_rest_angle: np.ndarray  # (H,)
    hinge_coef: np.ndarray  # (H,) c = k_b ‖ē‖² / (2(Ā_k + Ā_l))
    hinge_weights: np.ndarray | None  # (H, 4) for the quadratic model
    plate: tuple | None  # (ptr, col, val): k_b Q of the hessian model, CSR (clothtool.sim.plate)
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

    @cached_property
    def moving_pinned(self):
        """(P,) vertices of the moving pin groups."""
        if not self.pin_motions:
            return np.zeros(0, dtype=np.int64)
        return np.concatenate([m.vertices for m in self.pin_motions])

    def pin_goal(self, t):
        """(P, 3) positions at time t of :attr:`moving_pinned` (rigid motions of the initial
        positions)."""
        x0 = self.mesh.positions
        return np.concatenate([m.positions(x0[m.vertices], t) for m in self.pin_motions])

    @property
    def faces(self):
        return self.mesh.faces

    @property
    def n_vertices(self):
        return len(self.mass)

    @property
    def has_membrane(self):
        return self.stretch[0] > 0.0 or self.stretch[1] > 0.0 or self.k_shear > 0.0

    @property
    def has_pins(self):
        return len(self.pinned) > 0

    @property
    def has_colliders(self):
        return len(self.spheres) + len(self.planes) > 0

    @cached_property
    def springs(self):
        """The spring network of ``mass-spring``, ``pbd``, ``xpbd`` and ``projective``
        (:func:`~clothtool.sim.springs.build_springs`), built once."""
        from clothtool.sim.springs import build_springs

        return build_springs(self)

    def initial_state(self):
        """Rest positions at rest, pushed out of colliders."""
        from clothtool.sim.collide import resolve_collisions

        state = State(self.mesh.positions.copy(), np.zeros_like(self.mesh.positions))
        if self.has_colliders:
            resolve_collisions(state.x, state.v, self.free, self.spheres, self.planes,
                               self.collision_margin)
        return state


def build_model(config):
    """Model from a validated :class:`~clothtool.sim.config.Config`."""
    mesh = build_rest_mesh(config.mesh)
    n = len(mesh.positions)
    faces = mesh.faces
    if faces.min() < 0 or faces.max() >= n:
        raise InputError(f"{config.mesh.ply}: face index out of range")
    dr = rest_edge_matrices(mesh)
    det = dr[:, 0, 0] * dr[:, 1, 1] - dr[:, 0, 1] * dr[:, 1, 0]
    area = 0.5 * np.abs(det)
    edges = mesh.rest3d[faces] - mesh.rest3d[np.roll(faces, 1, axis=1)]
    longest = np.max(np.einsum("mkp,mkp->mk", edges, edges), axis=1)
    bad = np.flatnonzero(area <= DEGENERATE * longest)
    if len(bad):
        raise InputError(f"mesh: rest triangle {bad[0]} is degenerate (zero area in the rest "
                         f"{'uv' if mesh.uv is not None else 'mesh'}); {len(bad)} such triangles")
    dr_inv = np.linalg.inv(dr)

    mat = config.material
    mass = np.zeros(n)
    np.add.at(mass, faces.ravel(), np.repeat(mat.density * area / 3.0, 3))
    if np.any(mass == 0):
        raise InputError(f"mesh: vertex {np.flatnonzero(mass == 0)[0]} belongs to no triangle")

    bend_model, hinge, rest_angle, coef, weights = _bending(mesh, area, mat)
    plate = None
    if bend_model == "hessian":
        from clothtool.sim.plate import hessian_bending_matrix

        q = hessian_bending_matrix(mesh.uv, faces) * mat.bend
        plate = (q.indptr.astype(np.int64), q.indices.astype(np.int64), q.data)
    pinned, pin_motions = resolve_pin_entries(config.scene.pins, n, mesh.grid_shape)
    free = np.ones(n, dtype=np.bool_)
    free[pinned] = False
    kind = np.full(n, FREE, dtype=np.int8)
    kind[pinned] = PINNED

    # the methods with barrier contact take every collider into it; the others project
    # vertices out of spheres and planes (clothtool.sim.collide)
    contact = build_contact_scene(config, mesh) if barrier_contact(config) else None
    projected = () if contact is not None else config.scene.colliders
    spheres = [c for c in projected if isinstance(c, Sphere)]
    planes = [c for c in projected if isinstance(c, Plane)]
    sphere_arr = np.array([[*c.center, c.radius] for c in spheres], dtype=np.float64).reshape(-1, 4)
    plane_arr = np.array([[*c.point, *(np.asarray(c.normal) / np.linalg.norm(c.normal))]
                          for c in planes], dtype=np.float64).reshape(-1, 6)

    hinged = bend_model in ("dihedral", "quadratic")
    pairs = None
    if plate is not None:
        rows = np.repeat(np.arange(n), np.diff(plate[0]))
        pairs = np.stack([rows, plate[1]], axis=1)
    pattern = BlockPattern(n, faces, *([hinge] if hinged else []),
                           *([pairs] if pairs is not None else []))
    tri_slots = pattern.slots(faces)
    hinge_slots = pattern.slots(hinge) if hinged else np.zeros((0, 16), np.int64)
    constant = None
    if pairs is not None:  # k_b Q ⊗ I₃
        constant = pattern.zeros()
        slot = pattern.slots(pairs)[:, 1]
        for p in range(3):
            constant[slot, p, p] += plate[2]
    if bend_model == "quadratic":
        constant = pattern.zeros()
        w = weights
        elem = 2.0 * coef[:, None, None] * np.einsum("ha,hb->hab", w, w)  # (H, 4, 4)
        blocks = np.einsum("hab,pq->hapbq", elem, np.eye(3)).reshape(-1, 12, 12)
        scatter_blocks(blocks, hinge_slots, constant)

    return Model(
        mesh=mesh, dr_inv=dr_inv, area=area, mass=mass,
        stretch=_warp_weft(mat, mesh), k_shear=mat.shear, damping=mat.damping,
        gravity=np.asarray(config.scene.gravity, dtype=np.float64),
        bend_model=bend_model, hinge=hinge, hinge_rest_angle=rest_angle, hinge_coef=coef,
        hinge_weights=weights, plate=plate, pinned=pinned, free=free, kind=kind,
        spheres=sphere_arr, planes=plane_arr,
        collision_margin=config.scene.collision_margin,
        pattern=pattern, tri_slots=tri_slots, hinge_slots=hinge_slots, constant_hessian=constant,
        pin_motions=pin_motions, contact=contact,
    )


def _warp_weft(material, mesh):
    """(k_u, k_v, b_u, b_v) from material.stretch and material.rest_stretch (a number: both)."""
    k = np.broadcast_to(np.asarray(material.stretch, dtype=np.float64), 2)
    b = np.broadcast_to(np.asarray(material.rest_stretch, dtype=np.float64), 2)
    if mesh.uv is None:  # no u and v: each triangle is measured in its own tangent frame
        for key, pair in (("stretch", k), ("rest_stretch", b)):
            if pair[0] != pair[1]:
                raise InputError(f"material.{key}: different warp and weft values need rest uv "
                                 "(a grid, or a PLY with texture coordinates)")
    return np.concatenate([k, b])


def _bending(mesh, area, material):
    """Hinges and their rest data; empty when bending is off or the mesh has no interior edge."""
    from clothtool.geometry import dihedral_angles
    from clothtool.sim.bending import quadratic_weights

    empty = (None, np.zeros((0, 4), np.int64), np.zeros(0), np.zeros(0), None)
    if material.bend == 0.0:
        return empty
    faces = mesh.faces
    hinge, hinge_faces = hinges(faces, len(mesh.positions))
    if len(hinge) == 0:
        return empty
    tri_area = area[hinge_faces]
    r = mesh.rest3d
    edge2 = np.einsum("hp,hp->h", r[hinge[:, 1]] - r[hinge[:, 0]], r[hinge[:, 1]] - r[hinge[:, 0]])
    coef = material.bend * edge2 / (2.0 * tri_area.sum(axis=1))
    # a uv pattern is flat by definition; a PLY without uv rests in its own shape
    rest_angle = np.zeros(len(hinge)) if mesh.uv is not None else dihedral_angles(r, hinge)
    weights = None
    model = material.bend_model
    if model == "hessian" and mesh.uv is None:
        model = "dihedral"  # a mesh that rests in its own (curved) shape: the dihedral model
    if material.bend_model == "quadratic":
        if np.max(np.abs(rest_angle)) > 1e-6:
            raise InputError("material.bend_model: 'quadratic' needs a flat rest state "
                             "(a grid, or a PLY with uv); use 'dihedral'")
        weights = quadratic_weights(r, hinge)
    return model, hinge, rest_angle, coef, weights
