"""Moving pins: pinned vertices on a rigid motion of their initial positions.

A ``rotate`` group turns about the axis k̂ through c at ω rad/s (right-hand rule),
p(t) = c + R(θ)(p₀ − c) with θ = ω·min(t, until) and Rodrigues' formula
R(θ)u = u cos θ + (k̂ × u) sin θ + k̂ (k̂·u)(1 − cos θ); a ``translate`` group
moves at velocity u, p(t) = p₀ + u·min(t, until). After ``until`` the group holds.
"""

from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError
from clothtool.sim.pins import pin_entry_vertices, resolve_pins


@dataclass(frozen=True)
class PinMotion:
    vertices: np.ndarray  # (P,) int64
    rotate: bool
    center: np.ndarray  # (3,) rotate
    axis: np.ndarray  # (3,) unit, rotate
    speed: float  # rad/s, rotate
    velocity: np.ndarray  # (3,) m/s, translate
    until: float  # s (inf: the whole run)

    def positions(self, x0, t):
        """(P, 3) positions at time t of the group's vertices, initially x0 (P, 3)."""
        s = min(t, self.until)
        if not self.rotate:
            return x0 + s * self.velocity
        theta = self.speed * s
        k = self.axis
        u = x0 - self.center
        c, sn = np.cos(theta), np.sin(theta)
        ku = (u * k).sum(axis=1, keepdims=True)  # elementwise: no BLAS in the step
        return self.center + u * c + np.cross(k, u) * sn + ku * k * (1.0 - c)


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
        m = getattr(group, "motion", None)
        if m is None:
            continue
        until = np.inf if m.until is None else m.until
        if group.rotate is not None:
            axis = np.asarray(m.axis, dtype=np.float64)
            motions.append(PinMotion(verts, True, np.asarray(m.center, dtype=np.float64),
                                     axis / np.linalg.norm(axis), m.speed, np.zeros(3), until))
        else:
            motions.append(PinMotion(verts, False, np.zeros(3), np.zeros(3), 0.0,
                                     np.asarray(m.velocity, dtype=np.float64), until))
    return pinned.astype(np.int64), motions


def _check_disjoint(verts, owner, k, key):
    clash = verts[(owner[verts] >= 0) & (owner[verts] != k)]
    if len(clash):
        raise InputError(f"{key}[{k}]: vertex {clash[0]} is also in {key}[{owner[clash[0]]}]; "
                         "a vertex can be in one pin group only")


