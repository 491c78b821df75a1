"""Rigid motions of moving pins and colliders.

A ``rotate`` motion turns about the axis k̂ through c at ω rad/s (right-hand rule),
p(t) = c + R(θ)(p₀ − c) with θ = ω·min(t, until) and Rodrigues' formula
R(θ)u = u cos θ + (k̂ × u) sin θ + k̂ (k̂·u)(1 − cos θ); a ``translate`` motion
moves at velocity u, p(t) = p₀ + u·min(t, until). After ``until`` it holds. A collider's
``motion`` may have both: the centre moves with the translation.
"""

from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError
from clothtool.sim.model.pins import pin_entry_vertices, resolve_pins


@dataclass(frozen=True)
class RigidMotion:
    """x(t) = c + u·min(t, until_u) + R(ω·min(t, until_ω))(x₀ − c) (see the module)."""

    center: np.ndarray  # (3,)
    axis: np.ndarray  # (3,) unit
    speed: float  # rad/s
    until_rotate: float  # s (inf: the whole run)
    velocity: np.ndarray  # (3,) m/s
    until_translate: float

    def positions(self, x0, t):
        """(P, 3) positions at time t of points at x0 (P, 3) at t = 0."""
        turned = rotate(x0 - self.center, self.axis, self.speed * min(t, self.until_rotate))
        return self.center + self.velocity * min(t, self.until_translate) + turned

    def initial_positions(self, x, t):
        """(P, 3) the positions x₀ at t = 0 that the motion takes to x (P, 3) at time t:
        x₀ = c + R(−θ(t))(x − c − T(t))."""
        u = x - self.center - self.velocity * min(t, self.until_translate)
        return self.center + rotate(u, self.axis, -self.speed * min(t, self.until_rotate))

    def field(self, t):
        """(9,) the velocity field at time t as (centre c + T(t), angular velocity ω k̂,
        translation velocity)."""
        out = np.zeros(9)
        out[:3] = self.center + self.velocity * min(t, self.until_translate)
        if t < self.until_rotate:
            out[3:6] = self.speed * self.axis
        if t < self.until_translate:
            out[6:] = self.velocity
        return out


def rotate(u, k, theta):
    """(P, 3) the vectors u (P, 3) turned by θ about the unit axis k̂ (Rodrigues' formula)."""
    c, s = np.cos(theta), np.sin(theta)
    ku = (u * k).sum(axis=1, keepdims=True)
    return u * c + np.cross(k, u) * s + ku * k * (1.0 - c)


def rigid_motion(motion):
    """The :class:`RigidMotion` of a section with ``rotate`` and/or ``translate`` (a
    collider's ``motion``, a pin group), None for None."""
    if motion is None:
        return None
    rot, tra = motion.rotate, motion.translate
    axis = np.asarray(rot.axis if rot else (1.0, 0.0, 0.0), dtype=np.float64)
    inf = np.inf
    return RigidMotion(
        np.asarray(rot.center if rot else (0.0, 0.0, 0.0), dtype=np.float64),
        axis / np.linalg.norm(axis), float(rot.speed) if rot else 0.0,
        inf if rot is None or rot.until is None else float(rot.until),
        np.asarray(tra.velocity if tra else (0.0, 0.0, 0.0), dtype=np.float64),
        inf if tra is None or tra.until is None else float(tra.until))


@dataclass(frozen=True)
class PinMotion:
    """A moving pin group: its vertices on a rigid motion of their initial positions."""

    vertices: np.ndarray  # (P,) int64
    motion: RigidMotion

    def positions(self, x0, t):
        """(P, 3) positions at time t of the group's vertices, initially x0 (P, 3)."""
        return self.motion.positions(x0, t)


def resolve_pin_entries(entries, n_vertices, grid_shape, key="scene.pins"):
    """(pinned, motions): sorted unique pinned vertices of all entries, and a
    :class:`PinMotion` per moving group. A vertex of a group (``{vertices: …}``) that another
    entry also names is an error; plain names and indices may overlap each other."""
    per_entry = []
    for k, entry in enumerate(entries):
        if hasattr(entry, "vertices"):
            verts = resolve_pins(entry.vertices, n_vertices, grid_shape, key=f"{key}[{k}].vertices")
        else:
            verts = pin_entry_vertices(entry, n_vertices, grid_shape, f"{key}[{k}]")
        per_entry.append(verts)
    owner = np.full(n_vertices, -1, dtype=np.int64)  # the group holding each vertex
    for k, entry in enumerate(entries):
        if hasattr(entry, "vertices"):
            _check_disjoint(per_entry[k], owner, k, key)
            owner[per_entry[k]] = k
    for k, entry in enumerate(entries):
        if not hasattr(entry, "vertices"):
            _check_disjoint(per_entry[k], owner, k, key)
    pinned = (np.unique(np.concatenate(per_entry)) if per_entry
              else np.zeros(0, dtype=np.int64))
    motions = []
    for group, verts in zip(entries, per_entry):
        if getattr(group, "motion", None) is not None:
            motions.append(PinMotion(verts, rigid_motion(group)))
    return pinned.astype(np.int64), motions


def _check_disjoint(verts, owner, k, key):
    clash = verts[(owner[verts] >= 0) & (owner[verts] != k)]
    if len(clash):
        raise InputError(f"{key}[{k}]: vertex {clash[0]} is also in {key}[{owner[clash[0]]}]; "
                         "a vertex can be in one pin group only")


