"""``scene.attach``: garment vertices carried by a collider's surface (a waistband on a body).

Each attached vertex is tied at t = 0 (a garment being sewn: when its seams are welded, so
that it is dressed first) to the nearest point of collider K's surface, at the offset it
starts from it, and follows the collider as a moving pin whose goal is that point
and offset (:meth:`Model.pin_goal <clothtool.sim.model.model.Model.pin_goal>`, solved as every moving
pin is: a prescribed part of the Newton step, collision-free):

- an animated mesh: the vertex's coordinates (α, β, γ) in the frame of its nearest triangle,
  x = v₀ + α(v₁ − v₀) + β(v₂ − v₀) + γ n̂ at t = 0 (barycentric on the triangle plus the
  offset along its unit normal), give x(t) from the triangle's vertices at t;
- every other collider moves rigidly (its ``motion``, or not at all): x(t) = c + T(t) +
  R(θ(t))(x₀ − c), the collider's own motion of the vertex's initial position
  (:class:`~clothtool.sim.model.motion.RigidMotion`), which keeps its nearest point and offset;
  tied at t_w, x₀ = c + R(−θ(t_w))(x_w − c − T(t_w)).
"""

from dataclasses import dataclass

import numpy as np

from clothtool.contact.distance import point_triangle_weights
from clothtool.errors import InputError
from clothtool.numba_setup import njit


@dataclass(frozen=True)
class AttachMotion:
    """Vertices carried by collider ``collider`` of ``colliders`` (see the module)."""

    vertices: np.ndarray  # (P,) int64
    colliders: object  # clothtool.sim.model.colliders.Colliders
    collider: int
    x0: np.ndarray  # (P, 3) positions at t = 0
    triangles: np.ndarray | None  # (P, 3) collider vertex indices (an animated mesh), or None
    coords: np.ndarray | None  # (P, 3) α, β, γ in each triangle's frame

    @property
    def motion(self):
        return self.colliders.motions[self.collider]

    def positions(self, x0, t):
        """(P, 3) positions at time t (``x0`` is ignored: the attachment keeps its own)."""
        if self.triangles is None:
            m = self.motion
            return self.x0.copy() if m is None else m.positions(self.x0, t)
        y = self.colliders.positions(t)
        return _in_frames(y, self.triangles, self.coords)


def check_attach(attach, mesh, pinned, key):
    """(P,) int64 vertex lists of the ``scene.attach`` entries; InputError for a vertex out of
    range, pinned, or attached twice."""
    n = len(mesh.positions)
    taken = np.zeros(n, np.bool_)
    taken[pinned] = True
    out = []
    for i, entry in enumerate(attach):
        here = f"{key}[{i}]" if len(attach) > 1 else key
        where = f"{mesh.path}: {here}" if mesh.path is not None else here
        v = np.asarray(entry.vertices, np.int64)
        bad = np.flatnonzero(v >= n)
        if len(bad):
            raise InputError(f"{where}.vertices[{bad[0]}]: vertex {int(v[bad[0]])} out of range "
                             f"(the mesh has {n} vertices)")
        clash = np.flatnonzero(taken[v])
        if len(clash):
            raise InputError(f"{where}.vertices[{clash[0]}]: vertex {int(v[clash[0]])} is already "
                             "pinned or attached")
        taken[v] = True
        out.append(v)
    return out


def attach_motions(attach, vertices, colliders, x, t=0.0):
    """An :class:`AttachMotion` per ``scene.attach`` entry, its ``vertices`` (model indices)
    at positions ``x`` (N, 3) tied at time t to collider ``entry.to``."""
    out = []
    for entry, v in zip(attach, vertices):
        xv = x[v].copy()
        c = entry.to
        lo, hi = colliders.offsets[c], colliders.offsets[c + 1]
        triangles = coords = None
        if len(colliders.frames[c]) > 1:  # an animated mesh: the nearest triangle's frame
            tri = colliders.faces[(colliders.faces >= lo).all(axis=1)
                                  & (colliders.faces < hi).all(axis=1)]
            y = colliders.positions(t)
            nearest = _nearest_triangles(np.concatenate([xv, y]), tri + len(xv), len(xv))
            triangles = tri[nearest]
            coords = _frame_coords(y, triangles, xv)
            x0 = xv
        else:
            motion = colliders.motions[c]
            x0 = xv if motion is None or t == 0.0 else motion.initial_positions(xv, t)
        out.append(AttachMotion(v, colliders, c, x0, triangles, coords))
    return out


@njit(cache=True)
def _nearest_triangles(x, tri, p):
    """(P,) index into tri of the nearest triangle to each of the first p points of x."""
    w = np.empty(4)
    out = np.zeros(p, np.int64)
    for i in range(p):
        best = np.inf
        for t in range(tri.shape[0]):
            d2 = point_triangle_weights(x, i, tri[t, 0], tri[t, 1], tri[t, 2], w)
            if d2 < best:
                best, out[i] = d2, t
    return out


def _frames(y, triangles):
    v0, v1, v2 = y[triangles[:, 0]], y[triangles[:, 1]], y[triangles[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return v0, np.stack([e1, e2, n], axis=2)  # (P, 3), (P, 3, 3) columns e1, e2, n̂


def _frame_coords(y, triangles, x):
    """(P, 3) α, β, γ with x = v₀ + α e₁ + β e₂ + γ n̂ for each triangle."""
    v0, frame = _frames(y, triangles)
    return np.linalg.solve(frame, (x - v0)[:, :, None])[:, :, 0]


def _in_frames(y, triangles, coords):
    v0, frame = _frames(y, triangles)
    return v0 + np.einsum("pij,pj->pi", frame, coords)
