"""Barrier contact in the Newton loop: mesh colliders and self-collision, never crossing.

The incremental potential gains the barrier of :mod:`clothtool.contact.barrier` over
vertex–triangle and edge–edge pairs of one vertex array: the cloth's N vertices, then
the colliders' (held: they follow their own motion). Cloth–collider pairs keep
``scene.collision_margin`` apart, cloth–cloth pairs ``self_collision.thickness``; the
barrier acts within DHAT beyond that. Its stiffness κ = KAPPA·m̄·DHAT²/h² (J, m̄ the
mean vertex mass) makes the barrier's stiffness comparable to the inertia term M/h²
at the activation distance. Each Newton step's gradient and matrix take the barrier's
gradient and Gauss–Newton Hessian (diagonal blocks in the matrix, the rest
matrix-free in the PCG), and the line search starts from the collision-free fraction
of the step (additive CCD), so every accepted iterate is intersection-free (Li et al.
2020, "Incremental Potential Contact", §5). Moving pins and animated colliders move
with the Newton steps (the pins as prescribed components of the solve, the colliders
through the linearised barrier force they exert) and are held to the same fraction; a
step that cannot bring them to their positions in ``solver.newton_iterations`` is a
numerical failure.

Candidate pairs are found for a reference configuration and a reach ρ_v per vertex
(the larger of DELTA and 1.5 times the motion expected of the vertex in the step: h v,
or its pin's or collider's own) and kept while every vertex stays within its reach, so
the broad phase runs about once per step, or less in slow motion, and moving parts get
a wide reach without widening it elsewhere.

Friction (Coulomb, coefficient of the collider or ``self_collision.friction``) acts on
the velocities after the step, pair by pair in a fixed order: the relative tangential
velocity of the closest points loses at most μ λ h Σ_k w_k²/m_k, λ the pair's barrier
force (Bridson, Fedkiw & Anderson 2002, "Robust treatment of collisions, contact and
friction for cloth animation", §7.2). Positions are not changed.
"""

from dataclasses import dataclass

import numpy as np
from numba import njit

from clothtool.contact.barrier import (contact_assemble, contact_energy,
                                       gauss_newton_add_diagonal, gauss_newton_coupling,
                                       pair_thickness, solve_operator)
from clothtool.contact.broadphase import contact_stencils, mesh_edges
from clothtool.contact.ccd import collision_free_step, near_pairs
from clothtool.contact.intersect import intersecting_pairs
from clothtool.errors import InputError, NumericalError

DHAT = 1.0e-3  # m: activation distance of the barrier beyond the thickness
KAPPA = 1.0  # barrier stiffness in units of m̄ DHAT² / h²
DELTA = 2.0e-3  # m: smallest reach of a candidate set beyond its reference positions


@dataclass
class ContactScene:
    """The contact data of a Model: one vertex array of cloth (first) and colliders."""

    n_cloth: int
    colliders: object  # ColliderMeshes or None
    faces: np.ndarray  # (F, 3) cloth faces, then collider faces
    edges: np.ndarray  # (E, 2)
    obstacle: np.ndarray  # (N + V,) bool: collider vertices
    rest: np.ndarray  # (N + V, 3) rest shape (edge lengths of the mollifier)
    self_contact: bool
    xi_self: float
    xi_obstacle: float
    mu_self: float
    mu: np.ndarray  # (N + V,) friction of each collider vertex (0 for cloth)

    @property
    def n_total(self):
        return len(self.obstacle)


def build_contact_scene(config, mesh):
    """The :class:`ContactScene` of a config and its rest mesh, or None without mesh
    colliders and self-collision."""
    from clothtool.sim.meshcollider import load_colliders

    scene = config.scene
    colliders = load_colliders(scene.colliders)
    if colliders is None and scene.self_collision is None:
        return None
    n = len(mesh.positions)
    v = colliders.n_vertices if colliders is not None else 0
    faces = [mesh.faces]
    rest = [mesh.rest3d]
    if colliders is not None:
        faces.append(colliders.faces + n)
        rest.append(colliders.positions(0.0))
    faces = np.concatenate(faces).astype(np.int64)
    obstacle = np.zeros(n + v, dtype=np.bool_)
    obstacle[n:] = True
    mu = np.zeros(n + v)
    if colliders is not None:
        mu[n:] = colliders.friction
    sc = scene.self_collision
    return ContactScene(n, colliders, faces, mesh_edges(faces), obstacle,
                        np.ascontiguousarray(np.concatenate(rest)), sc is not None,
                        sc.thickness if sc is not None else 0.0, scene.collision_margin,
                        sc.friction if sc is not None else 0.0, mu)


@njit(cache=True)
def _within(y, dy, ref, rho):
    """Are y_v and y_v + dy_v within rho_v of ref_v for every v?"""
    for i in range(y.shape[0]):
        a = 0.0
        b = 0.0
        for k in range(3):
            a += (y[i, k] - ref[i, k]) ** 2
            b += (y[i, k] + dy[i, k] - ref[i, k]) ** 2
        if max(a, b) > rho[i] * rho[i]:
            return False
    return True


@njit(cache=True)
def _mean_norm(dy):
    total = 0.0
    for i in range(dy.shape[0]):
        total += np.sqrt(dy[i, 0] ** 2 + dy[i, 1] ** 2 + dy[i, 2] ** 2)
    return total / max(dy.shape[0], 1)


@njit(cache=True)
def _radii(dy, floor, factor):
    """ρ_v = max(floor, factor ‖dy_v‖)."""
    rho = np.empty(dy.shape[0])
    for i in range(dy.shape[0]):
        rho[i] = max(floor, factor * np.sqrt(dy[i, 0] ** 2 + dy[i, 1] ** 2 + dy[i, 2] ** 2))
    return rho


@njit(cache=True)
def _max_norm(dy):
    worst = 0.0
    for i in range(dy.shape[0]):
        worst = max(worst, dy[i, 0] ** 2 + dy[i, 1] ** 2 + dy[i, 2] ** 2)
    return np.sqrt(worst)


@njit(cache=True)
def contact_friction(v, inv_mass, stencils, active, n_active, weights, normals, force,
                     obstacle, mu, mu_self, h):
    """Coulomb friction on velocities v (N + V, 3), in place, pair by pair (see module)."""
    for a in range(n_active):
        st = stencils[active[a]]
        m = mu_self
        for j in range(4):
            if obstacle[st[j]]:
                m = mu[st[j]]
        if m == 0.0 or force[a] == 0.0:
            continue
        u = np.zeros(3)
        denom = 0.0
        for j in range(4):
            denom += weights[a, j] ** 2 * inv_mass[st[j]]
            for i in range(3):
                u[i] += weights[a, j] * v[st[j], i]
        un = u[0] * normals[a, 0] + u[1] * normals[a, 1] + u[2] * normals[a, 2]
        for i in range(3):
            u[i] -= un * normals[a, i]
        ut = np.sqrt(u[0] ** 2 + u[1] ** 2 + u[2] ** 2)
        if denom == 0.0 or ut == 0.0:
            continue
        scale = min(1.0, m * force[a] * h * denom / ut)
        for j in range(4):
            c = -scale * inv_mass[st[j]] * weights[a, j] / denom
            for i in range(3):
                v[st[j], i] += c * u[i]


class BarrierContact:
    """The contact term of one run's Newton integrator (workspace only, see module)."""

    def __init__(self, scene, mass, free, h, stiffness):
        self.scene = scene
        self.h = h
        n, total = scene.n_cloth, scene.n_total
        self.kappa = KAPPA * max(float(np.mean(mass)) / (h * h), stiffness) * DHAT * DHAT
        self.reach = DHAT + max(scene.xi_obstacle, scene.xi_self)
        self.inv_mass = np.zeros(total)
        self.inv_mass[:n] = np.where(free, 1.0 / mass, 0.0)
        self.y = np.zeros((total, 3))  # cloth then collider positions
        self.dy = np.zeros((total, 3))
        self.target = None  # collider positions at the end of the step
        self._ref = None  # reference positions of the candidate set
        self._rho = None  # (N + V,) reach of the candidate set around them
        self._live_motion = False  # live pairs (of the last CCD's motion) hold the iterate
        self.active = np.zeros(0, np.int64)  # pair data, sized to the largest candidate set
        self.weights, self.normals = np.zeros((0, 4)), np.zeros((0, 3))
        self.coef, self.force = np.zeros(0), np.zeros(0)
        self._grad = np.zeros((total, 3))
        self.operator = None
        self.contacts = 0
        self.min_separation = np.inf

    # ------------------------------------------------------------------ candidates

    def _ensure(self, y, dy):
        """Make the candidates hold every pair within reach on y → y + dy. They are the
        pairs near a reference configuration for vertices within ρ_v of it, and are kept
        while the motions stay so; else ref ← y, ρ_v = max(DELTA, 1.5 ‖dy_v‖) — or, when
        the vertices move more than 2·DELTA on average, the pairs of this motion's swept
        boxes (for its line search and the assembly after it)."""
        if self._ref is not None and _within(y, dy, self._ref, self._rho):
            return
        sc = self.scene
        if _mean_norm(dy) > 2.0 * DELTA:  # the whole scene moves fast: this motion's pairs
            self._ref = None
            self.stencils, self.n_pt = contact_stencils(
                y, dy, np.zeros(len(y)), sc.faces, sc.edges, sc.obstacle, sc.self_contact,
                self.reach)
        else:
            self._ref = y.copy()
            self._rho = _radii(dy, DELTA, 1.5)
            self.stencils, self.n_pt = contact_stencils(
                y, np.zeros_like(y), self._rho, sc.faces, sc.edges, sc.obstacle,
                sc.self_contact, self.reach)
        k = len(self.stencils)
        if len(self.active) < k:
            self.active = np.zeros(k, np.int64)
            self.weights = np.zeros((k, 4))
            self.normals = np.zeros((k, 3))
            self.coef = np.zeros(k)
            self.force = np.zeros(k)

    def _assemble(self, y):
        """contact_assemble at y over the live pairs when y is on their motion, else over the
        candidates; the pairs assembled are kept in ``assembled``."""
        sc = self.scene
        self._grad[:] = 0.0
        if self._live_motion:
            self._live_motion = False
            self.assembled, n_pt = self.live, self.n_live_pt
        else:
            self._ensure(y, np.zeros_like(y))
            self.assembled, n_pt = self.stencils, self.n_pt
        return contact_assemble(y, self.assembled, n_pt, sc.obstacle, sc.rest, sc.xi_self,
                                sc.xi_obstacle, DHAT, self.kappa, self._grad, self.active,
                                self.weights, self.normals, self.coef, self.force)

    # ------------------------------------------------------------------ the step

    def check_initial(self, x0):
        """InputError when the initial cloth crosses a surface or is within a thickness."""
        sc = self.scene
        y = self._positions(x0, 0.0)
        pairs = intersecting_pairs(y, sc.faces, sc.obstacle, sc.edges)
        if len(pairs):
            raise InputError(f"the initial cloth crosses {self._what(pairs[0])}; contact needs "
                             "an intersection-free start")
        self._ensure(y, np.zeros_like(y))
        if contact_energy(y, self.stencils, self.n_pt, sc.obstacle, sc.rest, sc.xi_self,
                          sc.xi_obstacle, 0.0, 1.0) < np.inf:
            return
        for k, st in enumerate(self.stencils):  # name the first pair that is too close
            xi = pair_thickness(st, sc.obstacle, sc.xi_self, sc.xi_obstacle)
            if contact_energy(y, self.stencils[k:k + 1], 1 if k < self.n_pt else 0, sc.obstacle,
                              sc.rest, xi, xi, 0.0, 1.0) == np.inf:
                which = ("collision_margin of a collider" if sc.obstacle[st].any()
                         else "self_collision.thickness of itself")
                raise InputError(f"the initial cloth is within scene.{which} (vertices "
                                 f"{', '.join(map(str, st[st < sc.n_cloth]))}); start it "
                                 "farther away")

    def _what(self, pair):
        sc = self.scene
        e, f = sc.edges[pair[0]], sc.faces[pair[1]]
        return "a collider" if sc.obstacle[np.concatenate([e, f])].any() else "itself"

    def _positions(self, x, t):
        y = np.empty((self.scene.n_total, 3))
        y[:self.scene.n_cloth] = x
        if self.scene.colliders is not None:
            y[self.scene.n_cloth:] = self.scene.colliders.positions(t)
        return y

    def begin(self, x, v, t, moving, goal):
        """Start a step from cloth positions x and velocities v at time t, with the moving
        pins ``moving`` bound for ``goal`` (None without): candidates for the motion the
        step is expected to make (h v, the pins' and colliders' own)."""
        n = self.scene.n_cloth
        self.y = self._positions(x, t)
        expected = np.zeros_like(self.y)
        expected[:n] = self.h * v
        if goal is not None:
            expected[moving] = goal - x[moving]
        if self.scene.colliders is not None and self.scene.colliders.animated:
            self.start = self.y[n:].copy()
            self.target = self.scene.colliders.positions(t + self.h)
            expected[n:] = self.target - self.start
        self._ensure(self.y, expected)

    def assemble(self, x, grad, matrix):
        """E_c at the cloth positions x; adds ∇E_c into grad (N, 3), the diagonal Hessian
        blocks into the matrix, and keeps the rest for the PCG (``operator``)."""
        n = self.scene.n_cloth
        self.y[:n] = x
        energy, n_act, _ = self._assemble(self.y)
        grad += self._grad[:n]
        self.operator = solve_operator(self.assembled, self.active, n_act, self.weights,
                                       self.normals, self.coef, n)
        gauss_newton_add_diagonal(self.operator, matrix.pattern.diag, matrix.values)
        return energy

    def _free_step(self):
        """CCD of the motion dy over the candidates; the pairs that can come within reach
        on it become the live pairs of its line search and of the assembly after it."""
        self._ensure(self.y, self.dy)
        sc = self.scene
        self.live, self.n_live_pt = near_pairs(self.y, self.dy, self.stencils, self.n_pt,
                                               self.reach)
        self._live_motion = True
        return collision_free_step(self.y, self.dy, self.live, self.n_live_pt, sc.obstacle,
                                   sc.xi_self, sc.xi_obstacle, 1.0)

    def max_step(self, dx):
        """The collision-free fraction of the motion: the cloth by dx, the colliders the rest
        of their way to their end-of-step positions."""
        n = self.scene.n_cloth
        self.dy[:n] = dx
        self.dy[n:] = 0.0 if self.target is None else self.target - self.y[n:]
        return self._free_step()

    def add_collider_coupling(self, rhs):
        """rhs (N, 3) −= H_cX ΔX: the barrier's linearised response of the cloth to the rest of
        the colliders' motion ΔX in the step (of the last assembly's pairs)."""
        if self.target is None:
            return
        n = self.scene.n_cloth
        self.dy[:n] = 0.0
        self.dy[n:] = self.target - self.y[n:]
        gauss_newton_coupling(self.operator, self.dy, rhs, -1.0)

    def advance(self, step):
        """Move the colliders by ``step`` of their motion in :meth:`max_step` (exactly to
        their end-of-step positions for a full step)."""
        n = self.scene.n_cloth
        if self.target is not None:
            self.y[n:] = self.target if step == 1.0 else self.y[n:] + step * self.dy[n:]

    def energy(self, step):
        """E_c after moving by ``step`` times the motion of :meth:`max_step`."""
        sc = self.scene
        return contact_energy(self.y + step * self.dy, self.live, self.n_live_pt, sc.obstacle,
                              sc.rest, sc.xi_self, sc.xi_obstacle, DHAT, self.kappa)

    def colliders_behind(self):
        """How far (m) the colliders still are from their positions at the end of the step."""
        if self.target is None:
            return 0.0
        return _max_norm(self.target - self.y[self.scene.n_cloth:])

    def finish(self, state, h_eff):
        """After the step: friction on state.v (ĥ the integrator's velocity step), and the
        contacts and smallest distance."""
        sc = self.scene
        n = sc.n_cloth
        self.y[:n] = state.x
        _, n_act, dmin = self._assemble(self.y)
        self.contacts, self.min_separation = n_act, dmin
        if sc.mu_self > 0.0 or np.any(sc.mu > 0.0):
            v = np.zeros((sc.n_total, 3))
            v[:n] = state.v
            if self.target is not None:  # the colliders' own velocity over the step
                v[n:] = (self.target - self.start) / self.h
            contact_friction(v, self.inv_mass, self.assembled, self.active, n_act, self.weights,
                             self.normals, self.force, sc.obstacle, sc.mu, sc.mu_self, h_eff)
            state.v = v[:n].copy()

    def check_frame(self, x, t, frame, out_dir):
        """NumericalError when the frame at cloth positions x, time t, has a crossing."""
        sc = self.scene
        pairs = intersecting_pairs(self._positions(x, t), sc.faces, sc.obstacle, sc.edges)
        if len(pairs):
            raise NumericalError(f"simulation failed at frame {frame}: the cloth would cross "
                                 f"{self._what(pairs[0])}; frames before it are in {out_dir}")
