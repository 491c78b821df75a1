"""Barrier contact in the Newton loop: every collider and self-collision, never crossing.

The incremental potential gains the barrier of :mod:`clothtool.contact.barrier` over the
pairs of one vertex array: the cloth's N vertices, then the colliders'
(:mod:`clothtool.sim.model.colliders`: meshes and boxes by their triangles, spheres, capsules
and planes by their exact distance; all held, following their own motion).
Cloth–collider pairs rest ``scene.collision_margin`` apart, cloth–cloth pairs
``self_collision.thickness``: the barrier starts to push OUTSIDE (4 %) beyond that distance
and rises to infinity at its wall d closer in, d = ``scene.activation_distance`` or
ACTIVATION (¾) of the margin (or thickness); its width is d̂ = d + OUTSIDE·margin. Its
stiffness κ d̂² with κ = KAPPA·max(m̄/h², k) (J/m², m̄ the mean vertex mass, k the largest
membrane stiffness) makes the barrier's stiffness comparable to the inertia term M/h² at
the activation distance, so resting cloth sits within a few per cent of the margin, on
either side (measured: 3.1 % inside on the drape, 0.6 % outside on the stack), and no pair
ever comes closer than the wall. Each Newton
step's gradient and matrix take the barrier's gradient and Gauss–Newton Hessian (diagonal
blocks in the matrix, the rest matrix-free in the PCG, :mod:`clothtool.sim.linalg.pairs`), and
the line search starts from the collision-free fraction of the step (additive CCD), so
every accepted iterate is intersection-free (Li et al. 2020, "Incremental Potential
Contact", §5). Moving pins and moving colliders move with the Newton steps (the pins as
prescribed components of the solve, the colliders through the linearised barrier force
they exert) and are held to the same fraction; a step that cannot bring them to their
positions in ``solver.newton_iterations`` is a numerical failure.

Friction (Coulomb, coefficient of the collider or ``self_collision.friction``) is IPC's
smoothed dissipative potential (:mod:`clothtool.contact.friction`) in the same
minimisation: its pairs, normal forces and tangent bases are lagged from the start of
the step and re-lagged at Newton's solution until the friction force they give changes
the velocities by less than ``solver.newton_tolerance``; that change, and Newton's residual,
are measured on the rigid motions of each piece of cloth against its mass and the rest
against Newton's diagonal blocks (:mod:`clothtool.contact.pieces`).

Candidate pairs are found for a reference configuration, the midpoint of the motion
expected of each vertex in the step (h v, or its pin's or collider's own), and a reach ρ_v
per vertex (the larger of DELTA and ½ + SLACK times that motion), and kept while every
vertex stays within its reach, so the broad phase runs about once per step, or less in
slow motion, and moving parts get a wide reach without widening it elsewhere. Where
friction pairs slide against the direction they slid in when lagged, Newton's matrix takes
the half-quadratic bound of the friction (:func:`~clothtool.contact.friction.bound_reversed_slips`).
"""

import numpy as np

from clothtool.contact.barrier import (POINT_PLANE, barrier_blocks, contact_assemble,
                                       contact_energy, pair_distance, pair_thickness)
from clothtool.contact.broadphase import contact_stencils
from clothtool.contact.ccd import collision_free_step, near_pairs
from clothtool.contact.friction import (bound_reversed_slips, bound_slow_slips, friction_assemble,
                                       friction_energy, friction_lag, reference_slips,
                                       slip_overshoots)
from clothtool.contact.intersect import intersecting_pairs
from clothtool.contact.pieces import cloth_pieces, slide_velocity
from clothtool.errors import InputError, NumericalError
from clothtool.numba_setup import njit
from clothtool.sim.linalg.pairs import pair_operator, pairs_add_diagonal, pairs_coupling

KAPPA = 1.0  # barrier stiffness in units of max(m̄/h², k) per d̂²
DELTA = 2.0e-3  # m: smallest reach of a candidate set beyond its reference positions
SLACK = 0.5  # reach of a candidate set beyond its motion's midpoint, per length of the motion
FAST = 1.0e-2  # m: mean motion beyond which each motion gets its own swept candidates


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


def _lagged_pairs(k):
    """Room for k lagged friction pairs: (rows, weights, tangent bases, μλ, c)."""
    return (np.zeros((k, 4), np.int64), np.zeros((k, 4)), np.zeros((k, 3, 2)), np.zeros(k),
            np.zeros((k, 3)))


class BarrierContact:
    """The contact term of one run's Newton integrator (workspace only, see module)."""

    def __init__(self, scene, mass, free, h, stiffness, friction_velocity, overshoot_bound=False,
                 slow_slip=0.0):
        self.scene = scene
        self.overshoot_bound = overshoot_bound  # solver.overshoot_bound
        self.slow_slip = slow_slip  # slips slower take the bound's curvature (0: none)
        self.h = h
        n, total = scene.n_cloth, scene.n_total
        self.kappa = KAPPA * max(float(np.mean(mass)) / (h * h), stiffness)
        self.reach = scene.reach
        self.geometry = scene.geometry
        # analytic colliders (planes, and vertices with a radius: spheres, capsules)
        self.shapes = len(scene.planes) > 0 or bool(np.any(scene.geometry[1] > 0.0))
        self.free_mass = np.where(free, mass, 0.0)
        self.held = ~np.asarray(free, dtype=np.bool_)  # pinned cloth vertices
        self.piece, self.n_pieces = cloth_pieces(scene.faces[:scene.n_cloth_faces], n)
        self.y = np.zeros((total, 3))  # cloth then collider positions
        self.dy = np.zeros((total, 3))
        self.moving = scene.colliders is not None and scene.colliders.moving
        self.target = None  # collider positions at the end of the step (moving colliders)
        self._ref = None  # reference positions of the candidate set
        self._rho = None  # (N + V,) reach of the candidate set around them
        self._live_motion = False  # live pairs (of the last CCD's motion) hold the iterate
        self.active = np.zeros(0, np.int64)  # pair data, sized to the largest candidate set
        self.weights, self.normals = np.zeros((0, 4)), np.zeros((0, 3))
        self.coef, self.force, self.tilt = np.zeros(0), np.zeros(0), np.zeros((0, 2, 4))
        self._rows, self._w = np.zeros((0, 4), np.int64), np.zeros((0, 4))
        self._blocks = np.zeros((0, 3, 3))
        self._grad = np.zeros((total, 3))
        self.operator = None
        self.contacts = 0
        self.min_separation = np.inf
        # friction (clothtool.contact.friction): the lagged pairs, the step's b and ĥ, and
        # the colliders' velocities (vertex velocities and rigid fields) in the step
        self.eps_v = friction_velocity
        self.friction = scene.mu_self > 0.0 or bool(np.any(scene.mu > 0.0))
        self.velocity = np.zeros((total, 3))
        self.field = np.zeros((total, 9))
        self.rigid = np.zeros(total, dtype=np.bool_)
        self.base, self.h_eff = None, h
        self.lag = _lagged_pairs(0)
        self.n_lag = 0
        self.overshot = np.zeros(0, np.bool_)  # lagged pairs a Newton step turned over
        self.iterate = 0  # Newton iterates assembled in the step

    # ------------------------------------------------------------------ candidates

    def _stencils(self, y, dy, rho):
        sc = self.scene
        return contact_stencils(y, dy, rho, sc.points, sc.faces, sc.edges, sc.planes,
                                sc.n_cloth, sc.obstacle, self.geometry[1], sc.self_contact,
                                self.reach)

    def _ensure(self, y, dy):
        """Make the candidates hold every pair within reach on y → y + dy. They are the
        pairs near a reference configuration for vertices within ρ_v of it, and are kept
        while the motions stay so; else ref ← y + dy/2 (the motion's midpoint),
        ρ_v = max(DELTA, (½ + SLACK)‖dy_v‖) — or, when the vertices move more than FAST on
        average, the pairs of this motion's swept boxes (for its line search and the
        assembly after it)."""
        if self._ref is not None and _within(y, dy, self._ref, self._rho):
            return
        if _mean_norm(dy) > FAST:  # the whole scene moves fast: this motion's pairs
            self._ref = None
            self.stencils = self._stencils(y, dy, np.zeros(len(y)))
        else:
            self._ref = y + 0.5 * dy
            self._rho = _radii(dy, DELTA, 0.5 + SLACK)
            self.stencils = self._stencils(self._ref, np.zeros_like(y), self._rho)
        k = len(self.stencils)
        if len(self.active) < k:
            self.active = np.zeros(k, np.int64)
            self.weights = np.zeros((k, 4))
            self.normals = np.zeros((k, 3))
            self.coef = np.zeros(k)
            self.force = np.zeros(k)
            self.tilt = np.zeros((k, 2, 4))

    def _assemble(self, y, held=False):
        """contact_assemble at y over the live pairs when y is on their motion, else over the
        candidates (made to hold y unless ``held`` says they do); the pairs assembled are
        kept in ``assembled``."""
        self._grad[:] = 0.0
        if self._live_motion:
            self._live_motion = False
            self.assembled = self.live
        else:
            if not held:
                self._ensure(y, np.zeros_like(y))
            self.assembled = self.stencils
        return contact_assemble(y, self.assembled, self.geometry, self.kappa, self._grad,
                                self.active, self.weights, self.normals, self.coef, self.force,
                                self.tilt)

    # ------------------------------------------------------------------ crossings

    def crossing(self, x, t):
        """A description of the first crossing of cloth positions x at time t (a cloth
        triangle through a collider, or through another with self-collision), or None. The
        exact edge–triangle test covers the meshes; an analytic collider crosses where its
        distance to a pair's cloth side is ≤ 0, which only pairs within reach can have: those of
        the kept candidates while they hold y, else of a broad phase at y."""
        sc = self.scene
        y = self._positions(x, t)
        pairs = intersecting_pairs(y, sc.faces, sc.obstacle, sc.edges)
        if not sc.self_contact and len(pairs):  # without self-collision cloth may cross itself
            pairs = pairs[sc.obstacle[sc.edges[pairs[:, 0]]].any(axis=1)
                          | sc.obstacle[sc.faces[pairs[:, 1]]].any(axis=1)]
        if len(pairs):
            edge, face = sc.edges[pairs[0][0]], pairs[0][1]
            tri = _face_of_vertices(sc.faces[:sc.n_cloth_faces], edge) if edge[0] < sc.n_cloth else None
            if tri is None:  # a collider edge through a cloth triangle
                return f"cloth triangle {face} crosses {self._collider_name(edge[0], None)}"
            return f"cloth triangle {tri} crosses {self._triangle_name(face)}"
        if not self.shapes:
            return None
        still = np.zeros_like(y)
        held = self._ref is not None and _within(y, still, self._ref, self._rho)
        stencils = self.stencils if held else self._stencils(y, still, np.zeros(len(y)))
        k = _first_shape_crossing(y, stencils, self.geometry[1], sc.obstacle)
        if k < 0:
            return None
        st = stencils[k]
        cloth = [v for v in st[:4] if v < sc.n_cloth]
        collider = next(v for v in st[:4] if v >= sc.n_cloth)
        tri = (_face_of_vertices(sc.faces[:sc.n_cloth_faces], cloth)
               if st[4] != POINT_PLANE else None)
        what = f"cloth triangle {tri}" if tri is not None else f"cloth vertex {cloth[0]}"
        return f"{what} crosses {self._collider_name(collider, None)}"

    def _triangle_name(self, face):
        sc = self.scene
        if face < sc.n_cloth_faces:
            return f"cloth triangle {face}"
        return self._collider_name(sc.faces[face][0], face)

    def _collider_name(self, vertex, face):
        """The config key of the collider owning a vertex, with its triangle when given."""
        cs = self.scene.colliders
        c = cs.owner(vertex - self.scene.n_cloth)
        if face is None:
            return cs.keys[c]
        first = self.scene.n_cloth_faces + int(np.sum(
            cs.faces[:, 0] < cs.offsets[c]))  # the collider's first triangle
        return f"{cs.keys[c]} triangle {face - first}"

    def check_initial(self, x0):
        """InputError when the initial cloth crosses a surface or is within a thickness."""
        what = self.crossing(x0, 0.0)
        if what is not None:
            raise InputError(f"the initial state is not intersection-free: {what}")
        sc = self.scene
        y = self._positions(x0, 0.0)
        self._ensure(y, np.zeros_like(y))
        if contact_energy(y, self.stencils, self.geometry, 1.0) < np.inf:
            return
        r = np.empty(3)
        w = np.empty(4)
        for st in self.stencils:  # name the first pair that is too close
            xi = pair_thickness(st, self.geometry)[0]
            if pair_distance(y, st, w, r) <= xi * xi:
                cloth = ", ".join(str(v) for v in st[:4] if v < sc.n_cloth)
                collider = next((v for v in st[:4] if v >= sc.n_cloth), None)
                which = ("itself" if collider is None
                         else self._collider_name(collider, None))
                key = ("self_collision.thickness" if collider is None
                       else "scene.collision_margin")
                raise InputError(f"the initial cloth (vertices {cloth}) is closer to {which} "
                                 f"than the contact barrier's wall ({xi:g} m: {key} less "
                                 "scene.activation_distance); start it farther away")

    def check_frame(self, x, t, frame, out_dir):
        """NumericalError when the frame at cloth positions x, time t, has a crossing."""
        what = self.crossing(x, t)
        if what is not None:
            raise NumericalError(f"simulation failed at frame {frame}: {what}; frames before "
                                 f"it are in {out_dir}")

    def _positions(self, x, t):
        y = np.empty((self.scene.n_total, 3))
        y[:self.scene.n_cloth] = x
        if self.scene.colliders is not None:
            y[self.scene.n_cloth:] = self.scene.colliders.positions(t)
        return y

    # ------------------------------------------------------------------ the step

    def begin(self, state, moving, goal, base, h_eff):
        """Start a step from ``state`` with the moving pins ``moving`` bound for ``goal``
        (None without): candidates for the motion the step is expected to make (h v, the
        pins' and colliders' own), and the friction pairs lagged at the start (the
        integrator's velocity is (x − base)/ĥ)."""
        n = self.scene.n_cloth
        x, v, t = state.x, state.v, state.time
        self.y = self._positions(x, t)
        expected = np.zeros_like(self.y)
        expected[:n] = self.h * v
        if goal is not None:
            expected[moving] = goal - x[moving]
        if self.moving:
            colliders = self.scene.colliders
            self.target = colliders.positions(t + self.h)
            expected[n:] = self.target - self.y[n:]
            self.velocity[n:] = expected[n:] / self.h
            self.field[n:], self.rigid[n:] = colliders.fields(t + self.h)
        self._ensure(self.y, expected)
        self.iterate = 0
        if self.friction:
            self.base, self.h_eff = base, h_eff
            self._live_motion = False
            self._lag(self.y, v, held=True)

    def _lag(self, y, u, held=False):
        """Lag the friction pairs at the positions y (cloth and colliders), with the cloth
        velocities u for their reference slips."""
        sc = self.scene
        _, n_act, _ = self._assemble(y, held)
        if len(self.lag[0]) < n_act:
            self.lag = _lagged_pairs(len(self.active))
        self.n_lag = friction_lag(y, self.assembled, self.active, n_act, self.weights,
                                  self.normals, self.force, sc.obstacle, sc.mu, sc.mu_self,
                                  self.velocity, self.field, self.rigid, sc.n_cloth, *self.lag)
        rows, w, bases, _, c = self.lag
        self.reference = reference_slips(u, rows, w, bases, c, self.n_lag, sc.n_cloth)
        self.overshot = np.zeros(self.n_lag, np.bool_)

    def _friction_gradient(self, x):
        """∇D (N, 3) of the lagged pairs at cloth positions x."""
        n = self.scene.n_cloth
        grad = np.zeros((n, 3))
        blocks = np.empty((self.n_lag, 3, 3))
        friction_assemble(x, self.base, self.h_eff, self.eps_v, *self.lag, self.n_lag, n, grad,
                          blocks)
        return grad

    def relag(self, x, diag):
        """Re-lag the friction pairs at the cloth positions x; returns how much that changes
        the friction force, as the velocity change within the step that the change makes
        (:meth:`stick_slip`, with Newton's diagonal blocks ``diag``); 0 without friction."""
        if not self.friction:
            return 0.0
        n = self.scene.n_cloth
        before = self._friction_gradient(x)
        self.y[:n] = x
        self._lag(self.y, (x - self.base[:n]) / self.h_eff)
        return self.stick_slip(x, self._friction_gradient(x) - before, diag, self.h_eff)

    def stick_slip(self, x, residual, diag, h_eff):
        """The velocity change (m/s) within the step that a residual force (N, 3) at cloth
        positions x makes: through the rigid motions of each piece of cloth against its mass,
        the rest against the diagonal blocks diag (N, 3, 3) of Newton's matrix
        (:func:`clothtool.contact.pieces.slide_velocity`)."""
        return slide_velocity(x, residual, self.free_mass, diag, h_eff, self.piece,
                              self.n_pieces, self.held)

    def assemble(self, x, grad, matrix):
        """E_c + D at the cloth positions x; adds their gradient into grad (N, 3), the
        diagonal Hessian blocks into the matrix, and keeps the whole Hessian as a pair
        operator for the PCG (``operator``)."""
        n = self.scene.n_cloth
        self.y[:n] = x
        self.iterate += 1
        energy, n_act, _ = self._assemble(self.y)
        grad += self._grad[:n]
        room = 3 * n_act + self.n_lag  # a pair and its tilt terms, and the friction pairs
        if len(self._rows) < room:
            self._rows = np.zeros((2 * room, 4), np.int64)
            self._w = np.zeros((2 * room, 4))
            self._blocks = np.zeros((2 * room, 3, 3))
        n_act = barrier_blocks(self.assembled, self.active, n_act, self.weights, self.normals,
                               self.coef, self.force, self.tilt, self.y, self._rows, self._w,
                               self._blocks)
        size = n_act + self.n_lag
        if self.n_lag:
            rows, w, bases, mu_lambda, c = self.lag
            self._rows[n_act:size] = rows[:self.n_lag]
            self._w[n_act:size] = w[:self.n_lag]
            energy += friction_assemble(x, self.base, self.h_eff, self.eps_v, rows, w, bases,
                                        mu_lambda, c, self.n_lag, n, grad, self._blocks[n_act:size])
            if self.slow_slip > 0.0:
                bound_slow_slips(x, self.base, self.h_eff, self.eps_v, self.slow_slip, rows, w,
                                 bases, mu_lambda, c, self.n_lag, n, self._blocks[n_act:size])
            bound_reversed_slips(x, self.base, self.h_eff, self.eps_v, rows, w, bases, mu_lambda,
                                 c, self.n_lag, n, self.reference, self.overshot,
                                 self._blocks[n_act:size])
        self.operator = pair_operator(self._rows, self._w, self._blocks, size, n)
        pairs_add_diagonal(self.operator, matrix.pattern.diag, matrix.values)
        return energy

    def _free_step(self):
        """CCD of the motion dy over the candidates; the pairs that can come within reach
        on it become the live pairs of its line search and of the assembly after it."""
        self._ensure(self.y, self.dy)
        self.live = near_pairs(self.y, self.dy, self.stencils, self.geometry, self.reach)
        self._live_motion = True
        return collision_free_step(self.y, self.dy, self.live, self.geometry, 1.0)

    def max_step(self, dx):
        """The collision-free fraction of the motion: the cloth by dx, the colliders the rest
        of their way to their end-of-step positions. With ``solver.overshoot_bound``, from the
        step's second Newton iterate on, the sliding friction pairs whose slip it turns to the
        other side are marked (``overshot``; the first iterate is x_n, where the integrator's
        velocity is not the cloth's: BDF2 reads −v_n/2 there, and every slip would look
        turned)."""
        n = self.scene.n_cloth
        self.dy[:n] = dx
        self.dy[n:] = 0.0 if self.target is None else self.target - self.y[n:]
        step = self._free_step()
        if self.overshoot_bound and self.n_lag and self.iterate > 1:
            rows, w, bases, _, c = self.lag
            slip_overshoots(self.y, self.dy, step, self.base, self.h_eff, self.eps_v, rows, w,
                            bases, c, self.n_lag, n, self.overshot)
        return step

    def cuts(self, dx):
        """Does CCD over the current candidate pairs cut the motion short (the cloth by dx,
        the colliders the rest of their way)? Nothing is updated: a hint for the solve, not
        the guarantee (:meth:`max_step` is; pairs the candidates miss are not seen here)."""
        n = self.scene.n_cloth
        dy = np.empty_like(self.y)
        dy[:n] = dx
        dy[n:] = 0.0 if self.target is None else self.target - self.y[n:]
        live = near_pairs(self.y, dy, self.stencils, self.geometry, self.reach)
        return collision_free_step(self.y, dy, live, self.geometry, 1.0) < 1.0

    def add_collider_coupling(self, rhs):
        """rhs (N, 3) −= H_cX ΔX: the barrier's linearised response of the cloth to the rest of
        the colliders' motion ΔX in the step (of the last assembly's pairs)."""
        if self.target is None:
            return
        n = self.scene.n_cloth
        self.dy[:n] = 0.0
        self.dy[n:] = self.target - self.y[n:]
        pairs_coupling(self.operator, self.dy, rhs, -1.0)

    def advance(self, step):
        """Move the colliders by ``step`` of their motion in :meth:`max_step` (exactly to
        their end-of-step positions for a full step)."""
        n = self.scene.n_cloth
        if self.target is not None:
            self.y[n:] = self.target if step == 1.0 else self.y[n:] + step * self.dy[n:]

    def energy(self, step):
        """E_c + D after moving by ``step`` times the motion of :meth:`max_step`."""
        sc = self.scene
        y = self.y + step * self.dy
        e = contact_energy(y, self.live, self.geometry, self.kappa)
        if self.n_lag:
            e += friction_energy(y, self.base, self.h_eff, self.eps_v, *self.lag, self.n_lag,
                                 sc.n_cloth)
        return e

    def colliders_behind(self):
        """How far (m) the colliders still are from their positions at the end of the step."""
        if self.target is None:
            return 0.0
        return _max_norm(self.target - self.y[self.scene.n_cloth:])

    def finish(self, x):
        """After the step at cloth positions x: the number of contacts and the smallest
        distance between surfaces."""
        n = self.scene.n_cloth
        self.y[:n] = x
        _, self.contacts, self.min_separation = self._assemble(self.y)


def _face_of_vertices(faces, vertices):
    """The first triangle of faces holding all the given vertices, or None."""
    hit = np.all([np.any(faces == v, axis=1) for v in vertices], axis=0)
    k = np.flatnonzero(hit)
    return int(k[0]) if len(k) else None


@njit(cache=True)
def _first_shape_crossing(y, stencils, radius, obstacle):
    """The first pair of an analytic collider (a vertex with a radius, or a plane) whose
    surfaces touch or cross at y, or −1."""
    w = np.empty(4)
    r = np.empty(3)
    for k in range(stencils.shape[0]):
        st = stencils[k]
        big_r = 0.0
        shape = st[4] == POINT_PLANE
        for j in range(4):
            if obstacle[st[j]] and radius[st[j]] > 0.0:
                shape = True
                big_r = max(big_r, radius[st[j]])
        if shape and pair_distance(y, st, w, r) <= big_r * big_r:
            return k
    return -1
