"""Every collider of a scene in one vertex array, for the contact barrier.

Each kind enters through its exact geometry (:mod:`clothtool.contact.barrier`):

- ``mesh``: its triangles (a PLY or OBJ file, or a folder of frames shown at ``fps``,
  positions linear in time between frames, the last frame held after the end);
- ``box``: its 12 triangles, which are its surface exactly;
- ``sphere``: its centre, a vertex with the sphere's radius;
- ``capsule``: its axis segment, an edge whose two end vertices carry its radius;
- ``plane``: two vertices o (its point) and t = o + n̂, the unit normal; the cloth stays on
  the side n̂ points to.

A collider with ``motion`` moves rigidly: x(t) = c + T(t) + R(θ(t))(x₀ − c) with
T(t) = u·min(t, until) and θ(t) = ω·min(t, until) (Rodrigues' formula about the unit axis
k̂ through the centre c, which moves with T), so a plane's normal turns with it and a
sphere turns about its centre. Friction sees a rigid collider's own velocity field
u + ω k̂ × (x − c − T(t)) at the contact point, an animated mesh its vertices' velocities.
A mesh may be open or closed; cloth stays on the side it starts on.
"""

from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError
from clothtool.sim.model.motion import rigid_motion

DEGENERATE = 1e-12  # triangle area relative to its squared longest edge


@dataclass
class Colliders:
    """The colliders of a scene: V vertices, collider c owning ``offsets[c]:offsets[c+1]``."""

    keys: list  # per collider: its config key, e.g. "scene.colliders[2].sphere"
    frames: list  # per collider: (K, V_c, 3) float64, K ≥ 1 (K > 1: an animated mesh)
    fps: list  # per collider: frames per second (animated meshes)
    motions: list  # per collider: RigidMotion or None
    offsets: np.ndarray  # (C + 1,)
    faces: np.ndarray  # (F, 3) int64 triangles (meshes and boxes)
    edges: np.ndarray  # (E, 2) int64 capsule axes (the triangles' edges come from faces)
    planes: np.ndarray  # (P, 2) int64 (o, t) vertex pairs
    points: np.ndarray  # (Q,) int64 surface points: all vertices but the planes'
    radius: np.ndarray  # (V,) sphere and capsule radii, 0 elsewhere
    friction: np.ndarray  # (V,) Coulomb coefficient of each vertex's collider

    @property
    def n_vertices(self):
        return int(self.offsets[-1])

    @property
    def moving(self):
        return any(len(f) > 1 for f in self.frames) or any(m is not None for m in self.motions)

    def owner(self, v):
        """The collider index of collider vertex v."""
        return int(np.searchsorted(self.offsets, v, side="right") - 1)

    def positions(self, t):
        """(V, 3) positions at time t."""
        out = np.empty((self.n_vertices, 3))
        for c, (frames, fps, motion) in enumerate(zip(self.frames, self.fps, self.motions)):
            lo, hi = self.offsets[c], self.offsets[c + 1]
            s = t * fps
            k = int(np.floor(s))
            if len(frames) == 1 or k >= len(frames) - 1:
                out[lo:hi] = frames[-1]
            else:
                a = s - k
                out[lo:hi] = (1.0 - a) * frames[k] + a * frames[k + 1]
            if motion is not None:
                out[lo:hi] = motion.positions(out[lo:hi], t)
        return out

    def fields(self, t):
        """(V, 9) each vertex's rigid velocity field at time t (:meth:`RigidMotion.field`;
        zero for static colliders) and (V,) whether it has one (False for animated meshes,
        whose vertices' own velocities count)."""
        out = np.zeros((self.n_vertices, 9))
        rigid = np.ones(self.n_vertices, dtype=np.bool_)
        for c, (frames, motion) in enumerate(zip(self.frames, self.motions)):
            lo, hi = self.offsets[c], self.offsets[c + 1]
            if motion is not None:
                out[lo:hi] = motion.field(t)
            elif len(frames) > 1:
                rigid[lo:hi] = False
        return out, rigid


def load_colliders(colliders, key="scene.colliders"):
    """:class:`Colliders` of a config's scene.colliders, or None when there are none. Every
    problem is one InputError naming the collider's key and file."""
    keys, frames, fps, motions = [], [], [], []
    faces, edges, planes, points, radius, friction = [], [], [], [], [], []
    base = 0
    for i, c in enumerate(colliders):
        here = f"{key}[{i}].{c.kind}"
        x, tri, edge, plane, r, point = _geometry(c, here)
        keys.append(here)
        frames.append(x if x.ndim == 3 else x[None])
        fps.append(getattr(c, "fps", 30.0))
        motions.append(rigid_motion(c.motion))
        v = frames[-1].shape[1]
        faces.append(tri + base)
        edges.append(edge + base)
        planes.append(plane + base)
        points.append(point + base)
        radius.append(np.full(v, r))
        friction.append(np.full(v, c.friction))
        base += v
    if not keys:
        return None
    cat = lambda parts, width: np.concatenate(parts).reshape(-1, width).astype(np.int64)  # noqa: E731
    return Colliders(keys, frames, fps, motions, np.cumsum([0] + [f.shape[1] for f in frames]),
                     cat(faces, 3), cat(edges, 2), cat(planes, 2), cat(points, 1).ravel(),
                     np.concatenate(radius), np.concatenate(friction))


def _geometry(c, here):
    """(x (V, 3) or frames (K, V, 3), faces, edges, planes, radius, surface points) of one
    collider."""
    none2, none3 = np.zeros((0, 2), np.int64), np.zeros((0, 3), np.int64)
    if c.kind == "sphere":
        return np.array([c.center], float), none3, none2, none2, c.radius, np.array([0])
    if c.kind == "capsule":
        return (np.array([c.a, c.b], float), none3, np.array([[0, 1]]), none2, c.radius,
                np.array([0, 1]))
    if c.kind == "plane":
        n = np.asarray(c.normal, float)
        o = np.asarray(c.point, float)
        return np.array([o, o + n / np.linalg.norm(n)]), none3, none2, np.array([[0, 1]]), 0.0, \
            np.zeros(0, np.int64)
    if c.kind == "box":
        x, tri = box_mesh(c.center, c.size, c.axis, c.angle)
        return x, tri, none2, none2, 0.0, np.arange(8)
    what, path = c.source
    try:
        seq, tri = _read(what, path)
    except InputError as exc:
        raise InputError(f"{here}.{what}: {exc}") from None
    _check_triangles(seq[0], tri, f"{here}.{what}", path)
    if not np.all(np.isfinite(seq)):
        raise InputError(f"{here}.{what}: {path}: non-finite vertex coordinates")
    return seq, np.asarray(tri, np.int64), none2, none2, 0.0, np.arange(seq.shape[1])


def box_mesh(center, size, axis, angle):
    """(x (8, 3), faces (12, 3)) of a box: edge lengths ``size`` about ``center``, turned by
    ``angle`` about ``axis``; faces counter-clockwise seen from outside."""
    half = 0.5 * np.asarray(size, float)
    x = np.array([[half[0] if i & 1 else -half[0], half[1] if i & 2 else -half[1],
                   half[2] if i & 4 else -half[2]] for i in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], np.int64)
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    cos, sin = np.cos(angle), np.sin(angle)
    turned = x * cos + np.cross(k, x) * sin + (x @ k)[:, None] * k * (1.0 - cos)
    return turned + np.asarray(center, float), faces


def _read(what, path):
    """(frames (K, V, 3), faces (F, 3)) of one mesh collider source."""
    from clothtool.io.frames import FrameReader, discover_frames

    if what == "frames":
        if not path.is_dir():
            raise InputError(f"{path}: not a folder of frames" if path.exists()
                             else f"{path}: no such folder")
        reader = FrameReader(discover_frames(path))
        seq = np.stack([reader.positions(k) for k in range(len(reader.paths))])
        return seq, reader.faces
    if what == "ply":
        from clothtool.io.ply import read_ply as read
    else:
        from clothtool.io.obj import read_obj as read
    if not path.exists():
        raise InputError(f"{path}: no such file")
    mesh = read(path)
    return mesh.vertices[None].astype(np.float64), mesh.faces


def _check_triangles(x, faces, here, path):
    if len(faces) == 0:
        raise InputError(f"{here}: {path}: mesh has no triangles")
    e1, e2 = x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]]
    area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
    longest = np.max([np.einsum("ij,ij->i", e, e) for e in (e1, e2, e2 - e1)], axis=0)
    bad = np.flatnonzero(area2 <= 2.0 * DEGENERATE * longest)
    if len(bad):
        raise InputError(f"{here}: {path}: triangle {bad[0]} is degenerate (zero area); "
                         f"{len(bad)} such triangles")
