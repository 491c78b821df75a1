"""The ModelBuilder: config → Model in steps, NVIDIA Newton's ``ModelBuilder`` the pattern.

A builder collects the cloth (its rest mesh and per-triangle material arrays), the panels'
own materials, the seams, the pins, the colliders and the attachments, each checked as it
is added, and :meth:`ModelBuilder.finalize` computes the rest data (D_r⁻¹, rest areas, lumped
masses m_v = Σ ρ_t A_t/3, hinges), the elastic terms (:mod:`clothtool.sim.energies.terms`) and the block
pattern they share, and returns the :class:`~clothtool.sim.model.model.Model`. A sewn garment is
finalized again after its weld (:func:`clothtool.sim.model.seams.weld`), from a builder of the
welded mesh.
"""

import numpy as np

from clothtool.errors import InputError
from clothtool.geometry import hinges
from clothtool.sim.model.config import Plane, Sphere
from clothtool.sim.model.contact_scene import build_contact_scene
from clothtool.sim.linalg.filter import FREE, PINNED
from clothtool.sim.linalg.blocks import BlockPattern
from clothtool.sim.model.mesh import (build_rest_mesh, flat_pattern, plane_pattern,
                                      rest_edge_matrices)
from clothtool.sim.model.methods import barrier_contact, strain_damped
from clothtool.sim.model.model import Model
from clothtool.sim.model.motion import resolve_pin_entries
from clothtool.sim.model.schema import suggest
from clothtool.sim.energies.terms import (DihedralBending, EdgeMembrane, Membrane, NodalMembrane,
                                          PlateBending, QuadraticBending, Stitch, Term)

DEGENERATE = 1e-12  # rest triangle area relative to its squared longest edge


def build_model(config):
    """Model from a validated :class:`~clothtool.sim.model.config.Config`: config → builder → Model."""
    return ModelBuilder.from_config(config).finalize()


class ModelBuilder:
    """Add the cloth, then its materials, seams, pins, colliders and attachments; finalize."""

    def __init__(self):
        self.mesh = None
        self.material = None
        self.stitches = np.zeros((0, 2), np.int64)  # (S, 2) vertex pairs sewn together
        self.stitch_stiffness = np.zeros(0)  # (S,) N/m, raised while sewing (seams.tighten)
        self.stitch_stiffness0 = np.zeros(0)  # (S,) N/m as configured
        self.stitch_gap0 = np.zeros(0)  # (S,) m, each pair's gap at the start
        self.pinned = np.zeros(0, np.int64)
        self.pin_motions = []
        self.config = None  # the config whose scene the colliders come from
        self.origin = None  # (N, 3) positions at t = 0, when they differ from mesh.positions
        self.file_vertex = None  # (N_file,) the model vertex of each vertex of the file
        self.attach, self.attach_vertices = (), []  # scene.attach and each entry's vertices
        self.attach_time = 0.0  # when the attachments take hold (a sewn garment: its weld)
        self.sewing, self.weld_distance = None, 0.0  # mesh.sewing and its weld distance (m)
        self.file_mesh = None  # the mesh as the file gives it, when its closed seams are welded
        self.closed_seams = []  # (panel, panel, vertices, length m) welded at the start
        self.listed_closed = []  # (key, a, b, pairs welded, pairs) of mesh.seams closed in the file

    @classmethod
    def from_config(cls, config):
        from clothtool.sim.model.seams import add_config_seams

        builder = cls()
        mesh = build_rest_mesh(config.mesh)
        if config.mesh.weld_closed:
            builder.add_closed_cloth(mesh, config.material, config.mesh.weld_tolerance)
        else:
            builder.add_cloth(mesh, config.material)
        builder.add_materials(config.materials)
        add_config_seams(builder, config.mesh, config.scene)
        builder.add_pins(config.scene.pins)
        builder.add_colliders(config)
        builder.add_attachments(config.scene.attach)
        return builder

    # ------------------------------------------------------------------ the cloth

    def add_cloth(self, mesh, material):
        """The rest mesh and one material for every triangle (``material``, a
        :class:`~clothtool.sim.model.config.Material`)."""
        n, faces = len(mesh.positions), mesh.faces
        where = f"{mesh.path}: " if mesh.path is not None else "mesh: "
        if faces.min() < 0 or faces.max() >= n:
            raise InputError(f"{where}face index out of range")
        dr = rest_edge_matrices(mesh)
        det = dr[:, 0, 0] * dr[:, 1, 1] - dr[:, 0, 1] * dr[:, 1, 0]
        area = 0.5 * np.abs(det)
        edges = _rest_edges(mesh)
        longest = np.max(np.einsum("mkp,mkp->mk", edges, edges), axis=1)
        bad = np.flatnonzero(area <= DEGENERATE * longest)
        if len(bad):
            raise InputError(f"{where}rest triangle {bad[0]} is degenerate (zero area in the rest "
                             f"{'uv' if flat_pattern(mesh) else 'mesh'}); {len(bad)} such "
                             "triangles")
        self.mesh, self.material, self.dr, self.area = mesh, material, dr, area
        m = len(faces)
        k, b = _warp_weft(material.stretch, material.rest_stretch, mesh, "material")
        self.tri_stretch = np.tile(np.concatenate([k, b]), (m, 1))
        self.tri_shear = np.full(m, material.shear)
        self.tri_density = np.full(m, material.density)
        self.tri_bend = np.tile(_bend_pair(material.bend, 1.0), (m, 1))
        self.tri_damping = np.full(m, material.damping)
        return self

    def add_closed_cloth(self, mesh, material, tolerance):
        """The cloth with its closed seams welded (:func:`clothtool.sim.model.seams.weld_closed_seams`):
        seams, pins and attachments added later name the file's vertices."""
        from clothtool.sim.model.seams import check_apart, weld_closed_seams

        welded, file_vertex, found = weld_closed_seams(mesh, tolerance)
        self.add_cloth(welded, material)
        if file_vertex is not None:
            self.file_mesh, self.file_vertex, self.closed_seams = mesh, file_vertex, found
            check_apart(welded, "the welded garment crosses itself")
        return self

    def to_model(self, ids):
        """Model vertices of the file's vertices ``ids``."""
        ids = np.asarray(ids, np.int64)
        return ids if self.file_vertex is None else self.file_vertex[ids]

    @property
    def n_file(self):
        """The file's vertex count."""
        return len((self.mesh if self.file_mesh is None else self.file_mesh).positions)

    def add_materials(self, materials, key="materials"):
        """Each panel's own material (``{name: PanelMaterial}``): its triangles are an OBJ
        group's or material's, or its ``faces``; the keys it gives replace ``material``'s."""
        mesh = self.mesh
        m = len(mesh.faces)
        for name, panel in materials.items():
            here = f"{key}.{name}"
            if panel.faces is not None:
                tri = np.asarray(panel.faces, np.int64)
                if tri.max() >= m:
                    j = int(np.argmax(tri >= m))
                    raise InputError(f"{here}.faces[{j}]: triangle {int(tri[j])} out of range "
                                     f"(the mesh has {m} triangles)")
            else:
                groups = mesh.groups or {}
                if name not in groups:
                    known = ", ".join(sorted(groups)) if groups else "none"
                    raise InputError(f"{here}: {mesh.path or 'the mesh'} has no group (g) or "
                                     f"material (usemtl) {name!r}{suggest(name, groups)} "
                                     f"(its groups: {known}); or give the panel's faces")
                tri = groups[name]
            if panel.stretch is not None or panel.rest_stretch is not None:
                old = self.tri_stretch[tri[0]]
                k, b = _warp_weft(panel.stretch if panel.stretch is not None else tuple(old[:2]),
                                  panel.rest_stretch if panel.rest_stretch is not None
                                  else tuple(old[2:]), mesh, here)
                self.tri_stretch[tri] = np.concatenate([k, b])
            if panel.bend is not None:
                self.tri_bend[tri] = _bend_pair(panel.bend, self._plate_rigidity()[1])
            for attr, value in (("tri_shear", panel.shear), ("tri_density", panel.density),
                                ("tri_damping", panel.damping)):
                if value is not None:
                    getattr(self, attr)[tri] = value
        return self

    def add_stitches(self, pairs, stiffness):
        """Vertex pairs (S, 2) pulled together by the stitch term, ``stiffness`` (S,) N/m each."""
        self.stitches = np.concatenate([self.stitches, np.asarray(pairs, np.int64)])
        self.stitch_stiffness = np.concatenate([self.stitch_stiffness, stiffness])
        self.stitch_stiffness0 = self.stitch_stiffness.copy()
        return self

    # ------------------------------------------------------------------ the scene

    def add_pins(self, entries, key="scene.pins"):
        """Pinned vertices and the moving pin groups (scene.pins entries)."""
        pinned, motions = resolve_pin_entries(entries, self.n_file, self.mesh.grid_shape, key)
        pinned = np.unique(self.to_model(pinned))
        motions = [type(m)(np.unique(self.to_model(m.vertices)), m.motion) for m in motions]
        self.pinned = np.union1d(self.pinned, pinned).astype(np.int64)
        self.pin_motions = self.pin_motions + motions
        return self

    def add_colliders(self, config):
        """The colliders of ``config.scene`` (contact barrier or projected, by its method)."""
        self.config = config
        return self

    def add_attachments(self, attach, key="scene.attach"):
        """Vertices carried by a collider's surface (:mod:`clothtool.sim.model.attach`): moving pins."""
        from clothtool.sim.model.attach import check_attach

        self.attach = attach
        if self.file_mesh is None:
            self.attach_vertices = check_attach(attach, self.mesh, self.pinned, key)
        else:
            pinned = np.flatnonzero(np.isin(self.file_vertex, self.pinned))
            self.attach_vertices = [np.unique(self.to_model(v)) for v in
                                    check_attach(attach, self.file_mesh, pinned, key)]
        return self

    def welded(self, model, state):
        """(builder, state) of the garment with its seams welded (:func:`clothtool.sim.model.seams.weld`):
        the same triangles on fewer vertices, each with its rest shape and material, pins and
        attachments renumbered, no stitches."""
        from clothtool.sim.model.seams import weld

        (mesh, origin, file_vertex, pinned, motions), state = weld(self, model, state)
        out = ModelBuilder()
        out.mesh, out.material, out.config = mesh, self.material, self.config
        out.file_mesh, out.closed_seams = self.file_mesh, self.closed_seams
        out.dr, out.area = self.dr, self.area
        for attr in ("tri_stretch", "tri_shear", "tri_density", "tri_bend", "tri_damping"):
            setattr(out, attr, getattr(self, attr))
        out.pinned, out.pin_motions = pinned, motions
        out.origin, out.file_vertex = origin, file_vertex
        out.attach, out.attach_time = self.attach, state.time
        out.attach_vertices = [np.unique(file_vertex[v]) for v in self.attach_vertices]
        return out, state

    # ------------------------------------------------------------------ finalize

    def finalize(self):
        """The :class:`~clothtool.sim.model.model.Model` of everything added."""
        mesh, config = self.mesh, self.config
        n, faces = len(mesh.positions), mesh.faces
        dr_inv = np.linalg.inv(self.dr)
        mass = np.zeros(n)
        np.add.at(mass, faces.ravel(), np.repeat(self.tri_density * self.area / 3.0, 3))
        if np.any(mass == 0):
            raise InputError(f"mesh: vertex {np.flatnonzero(mass == 0)[0]} belongs to no triangle")

        # the methods with barrier contact take every collider into it; the others project
        # vertices out of spheres and planes (clothtool.contact.projection)
        contact = build_contact_scene(config, mesh) if barrier_contact(config) else None
        pinned, pin_motions = self.pinned, list(self.pin_motions)
        if self.attach and not len(self.stitches):  # a garment is attached once it is sewn
            from clothtool.sim.model.attach import attach_motions

            attached = attach_motions(self.attach, self.attach_vertices, contact.colliders,
                                      mesh.positions, self.attach_time)
            pin_motions += attached
            pinned = np.union1d(pinned, np.concatenate([a.vertices for a in attached]))
        free = np.ones(n, dtype=np.bool_)
        free[pinned] = False
        kind = np.full(n, FREE, dtype=np.int8)
        kind[pinned] = PINNED
        projected = () if contact is not None else config.scene.colliders
        spheres = [c for c in projected if isinstance(c, Sphere)]
        planes = [c for c in projected if isinstance(c, Plane)]
        sphere_arr = np.array([[*c.center, c.radius] for c in spheres],
                              dtype=np.float64).reshape(-1, 4)
        plane_arr = np.array([[*c.point, *(np.asarray(c.normal) / np.linalg.norm(c.normal))]
                              for c in planes], dtype=np.float64).reshape(-1, 6)

        gravity = np.asarray(config.scene.gravity, dtype=np.float64)
        if len(self.stitches) and not self.sewing.gravity:
            gravity = np.zeros(3)  # sewn without gravity (mesh.sewing.gravity)
        bend_model, hinge, hinge_faces, rest_angle, coef, weights = self._bending()
        plate = plate_matrix = None
        if bend_model == "hessian":
            from clothtool.sim.energies.plate import FITTED, SHARPEN, plate_matrices

            uv = mesh.uv if mesh.uv is not None else plane_pattern(mesh.rest3d)
            rigidity, anisotropy = self._plate_rigidity()
            q, correction = plate_matrices(
                uv, faces, self._per_vertex(rigidity), anisotropy, pinned,
                sharpen={False: 0.0, True: SHARPEN, FITTED: FITTED}[self.material.plate_correction])
            plate = _csr(q if correction is None else q + correction)
            plate_matrix = None if correction is None else _csr(q)
        membrane_model, cells, frames = self._membrane_model()
        terms = _elastic_terms(faces, dr_inv, self.area, self.tri_stretch, self.tri_shear,
                               bend_model, plate, n, hinge, rest_angle, coef, weights,
                               membrane_model, plate_matrix, cells, frames)
        if len(self.stitches):
            terms.append(Stitch(self.stitches, self.stitch_stiffness.copy()))
        beta = self.tri_damping
        strain = np.any(beta > 0.0) and strain_damped(config)
        bend_damping = plate_damping = None
        elements = [t.elements for t in terms]
        if strain and plate is not None:
            # the plate's strain (the Hessian of x over its pattern) is linear in x: its
            # dissipation potential has the plate's own matrix, β k_b Q
            plate_damping = self._damped_plate(plate_matrix or plate, q, uv, rigidity, anisotropy,
                                               pinned)
        elif strain and len(hinge):  # the bending dissipation's hinges in the matrix too
            bend_damping = coef * beta[hinge_faces].mean(axis=1)
            elements.append(hinge)
        pattern = BlockPattern(n, *elements)
        constant = _bind(terms, pattern)
        damping_terms = damping_constant = strain_damping = None
        if strain:
            # stretch, shear and bending damped by the dissipation potential of their change
            # (clothtool.sim.energies.dissipation), β per triangle and hinge
            strain_damping = np.column_stack([self.tri_stretch[:, :2] * beta[:, None],
                                              self.tri_shear * beta])
        elif np.any(beta != beta[0]):
            # per-panel damping: D = (1/ĥ) Σ β_e K_e, β_e per element
            scaled = self.tri_stretch.copy()
            scaled[:, :2] *= beta[:, None]
            damped_plate = None
            if plate is not None:
                damped_plate = self._damped_plate(plate_matrix or plate, q, uv, rigidity,
                                                   anisotropy, pinned)
            damping_terms = _elastic_terms(faces, dr_inv, self.area, scaled,
                                           self.tri_shear * beta, bend_model, damped_plate, n,
                                           hinge, rest_angle,
                                           coef * beta[hinge_faces].mean(axis=1), weights,
                                           membrane_model, cells=cells, frames=frames)
            damping_constant = _bind(damping_terms, pattern)
        hinged = bend_model in ("dihedral", "quadratic")
        return Model(
            mesh=mesh, dr_inv=dr_inv, area=self.area, mass=mass,
            stretch=self.tri_stretch[0].copy(), k_shear=float(self.tri_shear[0]),
            damping=float(beta.max()), gravity=gravity,
            bend_model=bend_model, hinge=hinge, hinge_rest_angle=rest_angle, hinge_coef=coef,
            hinge_weights=weights, plate=plate, pinned=pinned, free=free, kind=kind,
            spheres=sphere_arr, planes=plane_arr,
            collision_margin=config.scene.collision_margin,
            pattern=pattern,
            tri_slots=pattern.slots(faces),
            hinge_slots=pattern.slots(hinge) if hinged else np.zeros((0, 16), np.int64),
            constant_hessian=constant, pin_motions=pin_motions, contact=contact,
            terms=terms, tri_stretch=self.tri_stretch, tri_shear=self.tri_shear,
            stitches=next((t for t in terms if isinstance(t, Stitch)), None),
            origin=self.origin, file_vertex=self.file_vertex,
            damping_terms=damping_terms, damping_constant=damping_constant,
            strain_damping=strain_damping, bend_damping=bend_damping, plate_damping=plate_damping,
            hinge_damping_slots=pattern.slots(hinge) if bend_damping is not None else None,
        )

    def _damped_plate(self, plate, q, uv, rigidity, anisotropy, pinned):
        """The plate (ptr, col, val) with each vertex's k_v β_v in place of k_v, on the plate's
        own sparsity (β the triangles' damping, one value: val · β; ``pinned`` its clamps)."""
        from clothtool.sim.energies.plate import hessian_bending_matrix, on_pattern

        beta = self.tri_damping
        if np.all(beta == beta[0]):
            return (*plate[:2], plate[2] * beta[0])
        damped = hessian_bending_matrix(uv, self.mesh.faces,
                                        self._per_vertex(rigidity * beta), anisotropy, pinned)
        return (*plate[:2], on_pattern(q, damped))

    def _per_vertex(self, value):
        """(N,) the area-weighted mean over each vertex's triangles of a per-triangle value."""
        n, faces = len(self.mesh.positions), self.mesh.faces
        weight = np.bincount(faces.ravel(), np.repeat(self.area, 3), minlength=n)
        return np.bincount(faces.ravel(), np.repeat(self.area * value, 3), minlength=n) / weight

    def _plate_rigidity(self):
        """(√(B_u B_v) per triangle, B_u/B_v): one warp/weft ratio for the whole mesh (the
        plate's orthotropy is a scaling of its pattern)."""
        bent = self.tri_bend[np.all(self.tri_bend > 0.0, axis=1)]
        ratio = bent[:, 0] / bent[:, 1] if len(bent) else np.ones(1)
        if np.ptp(ratio) > 1e-12 * ratio.max():
            raise InputError("materials: a panel's bend [warp, weft] needs the warp/weft "
                             "ratio of material.bend (one number keeps that ratio)")
        return np.sqrt(self.tri_bend.prod(axis=1)), float(ratio[0])

    def _membrane_model(self):
        """(``material.membrane_model``, its cells, the edge cells' frames) on the implicit
        method. ``nodal`` wherever the triangles' material frames meet at a vertex: a pattern
        per vertex (uv, or a flat mesh's own plane), or per corner (a garment's panels: a seam
        vertex has a cell in each panel, :func:`~clothtool.sim.energies.membrane_nodal.
        frame_cells`); ``edge`` on any mesh (:func:`~clothtool.sim.energies.membrane_edge.
        edge_cells`, unfolded frames where there is no pattern); else ``triangle`` (a mesh
        resting curved without uv under ``nodal``, the other methods, no membrane)."""
        from clothtool.sim.energies.membrane_edge import edge_cells, unfolded_frames
        from clothtool.sim.energies.membrane_nodal import frame_cells

        mesh, model = self.mesh, self.material.membrane_model
        method = None if self.config is None else self.config.solver.method
        if (model == "triangle" or method not in (None, "implicit")
                or not (np.any(self.tri_stretch[:, :2] > 0.0) or np.any(self.tri_shear > 0.0))):
            return "triangle", None, None
        pattern = mesh.uv is not None or plane_pattern(mesh.rest3d) is not None
        if model == "edge":
            cells = edge_cells(mesh.faces, mesh.corner_uv)
            if mesh.corner_uv is not None or pattern:
                return "edge", cells, None
            return "edge", cells, unfolded_frames(mesh.faces, self.dr, cells)
        if mesh.corner_uv is not None:
            return "nodal", frame_cells(mesh.faces, mesh.corner_uv), None
        if pattern:
            return "nodal", None, None
        return "triangle", None, None

    def _bending(self):
        """(model, hinges, rest angles, c_h, quadratic weights): c_h = k_b ‖ē‖²/(2(Ā_k + Ā_l)),
        k_b the mean of the hinge's two triangles'; empty when bending is off or the mesh has
        no interior edge."""
        from clothtool.geometry import dihedral_angles
        from clothtool.sim.energies.bending import quadratic_weights

        mesh, material = self.mesh, self.material
        empty = (None, np.zeros((0, 4), np.int64), np.zeros((0, 2), np.int64), np.zeros(0),
                 np.zeros(0), None)
        if not np.any(self.tri_bend > 0.0):
            return empty
        faces = mesh.faces
        hinge, hinge_faces = hinges(faces, len(mesh.positions))
        if len(hinge) == 0:
            return empty
        if not flat_pattern(mesh) and np.any(self.tri_bend[:, 0] != self.tri_bend[:, 1]):
            raise InputError("material.bend: different warp and weft values need rest uv (a "
                             "grid, or a PLY or OBJ with texture coordinates)")
        tri_area = self.area[hinge_faces]
        edge = _hinge_rest_edges(mesh, hinge, hinge_faces)
        bend = _hinge_rigidity(self.tri_bend[hinge_faces].mean(axis=1), edge)
        coef = bend * np.einsum("hp,hp->h", edge, edge) / (2.0 * tri_area.sum(axis=1))
        # a uv pattern is flat by definition; a PLY without uv rests in its own shape
        flat = flat_pattern(mesh)
        rest_angle = np.zeros(len(hinge)) if flat else dihedral_angles(mesh.rest3d, hinge)
        weights = None
        model = material.bend_model
        if model == "hessian" and mesh.uv is None and (mesh.corner_uv is not None
                                                       or plane_pattern(mesh.rest3d) is None):
            # a mesh that rests in its own curved shape or a pattern per corner (garment
            # panels): the dihedral model (a flat mesh without uv is its own pattern: its
            # plane's coordinates)
            model = "dihedral"
        if material.bend_model == "quadratic":
            if mesh.uv is None and mesh.corner_uv is not None:
                raise InputError("material.bend_model: 'quadratic' needs a rest pattern per "
                                 "vertex (a grid, or a PLY with uv); use 'dihedral'")
            if np.max(np.abs(rest_angle)) > 1e-6:
                raise InputError("material.bend_model: 'quadratic' needs a flat rest state "
                                 "(a grid, or a PLY with uv); use 'dihedral'")
            weights = quadratic_weights(mesh.rest3d, hinge)
        return model, hinge, hinge_faces, rest_angle, coef, weights


def _csr(q):
    """(ptr, col, val) of a scipy CSR matrix, int64 indices."""
    return q.indptr.astype(np.int64), q.indices.astype(np.int64), q.data


def _elastic_terms(faces, dr_inv, area, stretch, shear, bend_model, plate, n, hinge, rest_angle,
                   coef, weights, membrane_model="triangle", plate_matrix=None, cells=None,
                   frames=None):
    """The membrane and bending terms (none whose stiffness is zero); ``plate_matrix``: the
    plate's Hessian in the solver's matrix when it is not ``plate`` itself (the corrected
    plate: :class:`~clothtool.sim.energies.terms.PlateBending`); ``cells``: the nodal
    membrane's cells (None: one per vertex) or the edge membrane's, ``frames`` its frames."""
    terms = []
    if membrane_model == "edge":  # stretch and shear on the edges' smoothed metric
        terms.append(EdgeMembrane(faces, dr_inv, area, stretch, shear, cells, frames))
    elif membrane_model == "nodal":  # stretch on the vertices' smoothed metric, shear per triangle
        if np.any(stretch[:, :2] > 0.0):
            terms.append(NodalMembrane(faces, dr_inv, area, n, stretch, np.zeros_like(shear),
                                       cells))
        if np.any(shear > 0.0):
            shear_only = stretch.copy()
            shear_only[:, :2] = 0.0
            terms.append(Membrane(faces, dr_inv, area, shear_only, shear))
    elif np.any(stretch[:, :2] > 0.0) or np.any(shear > 0.0):
        terms.append(Membrane(faces, dr_inv, area, stretch, shear))
    if bend_model == "hessian":
        terms.append(PlateBending(plate, n, plate_matrix))
    elif bend_model == "dihedral":
        terms.append(DihedralBending(hinge, rest_angle, coef))
    elif bend_model == "quadratic":
        terms.append(QuadraticBending(hinge, weights, coef))
    return terms


def _bind(terms, pattern):
    """Bind the terms to the pattern; the sum of their constant Hessians (None: none)."""
    constant = None
    for term in terms:
        term.bind(pattern)
        if type(term).constant is not Term.constant:
            constant = pattern.zeros() if constant is None else constant
            term.constant(pattern, constant)
    return constant


def _bend_pair(bend, ratio):
    """(B_u, B_v) of a ``bend``: a pair as it is, a number k as k (√ratio, 1/√ratio) (the
    material's warp/weft ratio B_u/B_v)."""
    if isinstance(bend, tuple):
        return np.asarray(bend, np.float64)
    return bend * np.array([np.sqrt(ratio), 1.0 / np.sqrt(ratio)])


def _rest_edges(mesh):
    """(M, 3, 3) the rest edge vectors of every triangle (corner uv embedded when per corner)."""
    if mesh.corner_uv is not None:
        p = np.concatenate([mesh.corner_uv, np.zeros(mesh.corner_uv.shape[:2] + (1,))], axis=2)
        return p - np.roll(p, 1, axis=1)
    f = mesh.faces
    return mesh.rest3d[f] - mesh.rest3d[np.roll(f, 1, axis=1)]


def _hinge_rest_edges(mesh, hinge, hinge_faces):
    """(H, 2) or (H, 3) rest vector of each hinge edge (i, j): in the first face's corner uv
    for a pattern per corner (both faces agree unless the hinge is a seam in uv), else of
    rest3d ((u, v, 0) with uv per vertex)."""
    if mesh.corner_uv is None:
        return mesh.rest3d[hinge[:, 1]] - mesh.rest3d[hinge[:, 0]]
    face = mesh.faces[hinge_faces[:, 0]]  # (H, 3)
    uv = mesh.corner_uv[hinge_faces[:, 0]]  # (H, 3, 2)
    rows = np.arange(len(hinge))
    ci = np.argmax(face == hinge[:, :1], axis=1)
    cj = np.argmax(face == hinge[:, 1:2], axis=1)
    return uv[rows, cj] - uv[rows, ci]


def _hinge_rigidity(bend, edge):
    """Each hinge's k_b from (B_u, B_v) (H, 2) and its rest edge in the pattern: the
    orthotropic plate's rigidity across the edge, (√B_u sin²φ + √B_v cos²φ)², φ the edge's
    angle to u (an edge along u folds the sheet along v: B_v)."""
    if np.array_equal(bend[:, 0], bend[:, 1]):
        return bend[:, 0].copy()
    length2 = np.einsum("hp,hp->h", edge[:, :2], edge[:, :2])
    cos2 = np.divide(edge[:, 0] ** 2, length2, out=np.full(len(edge), 0.5), where=length2 > 0)
    return (np.sqrt(bend[:, 0]) * (1.0 - cos2) + np.sqrt(bend[:, 1]) * cos2) ** 2


def _warp_weft(stretch, rest_stretch, mesh, key):
    """(k_u, k_v), (b_u, b_v) from a stretch and rest_stretch (a number: both)."""
    k = np.broadcast_to(np.asarray(stretch, dtype=np.float64), 2).copy()
    b = np.broadcast_to(np.asarray(rest_stretch, dtype=np.float64), 2).copy()
    if not flat_pattern(mesh):  # no u and v: each triangle is measured in its own tangent frame
        for name, pair in (("stretch", k), ("rest_stretch", b)):
            if pair[0] != pair[1]:
                raise InputError(f"{key}.{name}: different warp and weft values need rest uv "
                                 "(a grid, or a PLY or OBJ with texture coordinates)")
    return k, b
