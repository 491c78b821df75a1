"""Mesh colliders: static or animated triangle meshes, all of a scene in one vertex array.

A static collider is one PLY or OBJ file. An animated one is a folder of frames (PLY or
OBJ, one format, natural order) with the vertex count and faces of the first in every
frame: frame k is shown at time k/fps, positions are linear in time between frames and
the last frame holds after the end. A collider may be open or closed; cloth stays on the
side it starts on (:mod:`clothtool.contact`).
"""

from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError

DEGENERATE = 1e-12  # triangle area relative to its squared longest edge


@dataclass
class ColliderMeshes:
    """The mesh colliders of a scene: ``faces`` (F, 3) into one array of V vertices."""

    faces: np.ndarray  # (F, 3) int64
    frames: list  # per collider: (K, V_i, 3) float64, K ≥ 1 frames
    fps: list  # per collider: frames per second (unused when K = 1)
    offsets: np.ndarray  # (C + 1,) first vertex of each collider
    friction: np.ndarray  # (V,) Coulomb coefficient of each vertex's collider

    @property
    def n_vertices(self):
        return int(self.offsets[-1])

    @property
    def animated(self):
        return any(len(f) > 1 for f in self.frames)

    def positions(self, t):
        """(V, 3) positions at time t."""
        out = np.empty((self.n_vertices, 3))
        for c, (frames, fps) in enumerate(zip(self.frames, self.fps)):
            lo, hi = self.offsets[c], self.offsets[c + 1]
            s = t * fps
            k = int(np.floor(s))
            if len(frames) == 1 or k >= len(frames) - 1:
                out[lo:hi] = frames[-1]
            else:
                a = s - k
                out[lo:hi] = (1.0 - a) * frames[k] + a * frames[k + 1]
        return out


def load_colliders(colliders, key="scene.colliders"):
    """:class:`ColliderMeshes` of the ``MeshCollider`` entries of ``colliders`` (a config's
    scene.colliders), or None when there are none. Every problem is one InputError naming
    the collider's key and file."""
    from clothtool.sim.config import MeshCollider

    faces, frames, fps, sizes, friction = [], [], [], [], []
    base = 0
    for i, c in enumerate(colliders):
        if not isinstance(c, MeshCollider):
            continue
        what, path = c.source
        here = f"{key}[{i}].mesh.{what}"
        try:
            seq, tri = _read(what, path)
        except InputError as exc:
            raise InputError(f"{here}: {exc}") from None
        _check_triangles(seq[0], tri, here, path)
        if not np.all(np.isfinite(seq)):
            raise InputError(f"{here}: {path}: non-finite vertex coordinates")
        faces.append(tri + base)
        frames.append(seq)
        fps.append(c.fps)
        sizes.append(seq.shape[1])
        friction.append(np.full(seq.shape[1], c.friction))
        base += seq.shape[1]
    if not frames:
        return None
    return ColliderMeshes(np.concatenate(faces).astype(np.int64), frames, fps,
                          np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                          np.concatenate(friction))


def _read(what, path):
    """(frames (K, V, 3), faces (F, 3)) of one collider source."""
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
