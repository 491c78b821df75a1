"""What a picture of a run needs from its config: the colliders as triangle surfaces at any
time of the run, the frame rate, and which way is up.

Every collider is drawn as the simulation moves it (:meth:`~clothtool.sim.model.colliders.Colliders.positions`:
a mesh's frames linear in time, rigid motions): a sphere as a UV sphere, a capsule as its
cylinder between two hemispheres (one UV sphere split at its equator), a plane as a square
patch about the point of the plane nearest the cloth, a box as its six faces, a mesh as its
own triangles. Flat faces larger than the cloth's triangles are split into smaller ones
(uniform subdivision), so that a painter's algorithm orders them against the cloth.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clothtool.sim.model.colliders import load_colliders
from clothtool.sim.model.config import Config, load_config

RINGS, SEGMENTS = 12, 24  # latitude bands (even: a capsule splits at the equator) and meridians
FLAT_SPLITS = 8  # a box face's and a plane patch's triangles are each split into 8² triangles
RUN_CONFIG = "config.yaml"  # the config a sweep's run folder holds


@dataclass
class Surface:
    """One collider's triangles at one time: ``key`` its config key."""

    key: str
    vertices: np.ndarray  # (V, 3)
    faces: np.ndarray  # (F, 3) int64


class RunScene:
    """The colliders, frame rate and up direction of a run's config."""

    def __init__(self, config):
        self.fps = config.time.fps
        gravity = np.asarray(config.scene.gravity, float)
        norm = np.linalg.norm(gravity)
        self.up = -gravity / norm if norm > 0 else np.array([0.0, 1.0, 0.0])
        self.colliders = load_colliders(config.scene.colliders)
        self.source = config.source

    def surfaces(self, t, centre, extent):
        """[:class:`Surface`] of every collider at time ``t`` (s); a plane is a square of
        half-size ``extent`` about the point nearest ``centre``."""
        c = self.colliders
        if c is None:
            return []
        x = c.positions(t)
        out = []
        for k, key in enumerate(c.keys):
            lo, hi = int(c.offsets[k]), int(c.offsets[k + 1])
            kind = key.rsplit(".", 1)[1]
            if kind == "sphere":
                v, f = capsule_mesh(x[lo], x[lo], c.radius[lo])
            elif kind == "capsule":
                v, f = capsule_mesh(x[lo], x[lo + 1], c.radius[lo])
            elif kind == "plane":
                v, f = subdivide(*plane_patch(x[lo], x[lo + 1] - x[lo], centre, extent), FLAT_SPLITS)
            else:
                own = (c.faces >= lo).all(axis=1) & (c.faces < hi).all(axis=1)
                v, f = x[lo:hi], c.faces[own] - lo
                if kind == "box":
                    v, f = subdivide(v, f, FLAT_SPLITS)
            out.append(Surface(key, v, f))
        return out


def run_scene(config=None, frames_dir=None):
    """The :class:`RunScene` of ``config`` (a path, a dict or a loaded Config), else of the
    ``config.yaml`` in ``frames_dir`` (a sweep's run folder), else None."""
    if config is None and frames_dir is not None and (Path(frames_dir) / RUN_CONFIG).is_file():
        config = Path(frames_dir) / RUN_CONFIG
    if config is None:
        return None
    return RunScene(config if isinstance(config, Config) else load_config(config))


def capsule_mesh(a, b, radius):
    """(vertices, faces) of the points within ``radius`` of the segment a–b: a UV sphere of
    RINGS × SEGMENTS whose southern half is centred on a and northern half on b (a sphere
    when a = b)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = np.linalg.norm(axis)
    k = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    e1 = np.cross(k, [1.0, 0.0, 0.0] if abs(k[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(k, e1)
    half = RINGS // 2
    lat = np.concatenate([np.linspace(-np.pi / 2, 0, half + 1), np.linspace(0, np.pi / 2, half + 1)])
    lon = np.linspace(0, 2 * np.pi, SEGMENTS + 1)[:-1]
    cl, sl = np.cos(lat)[:, None, None], np.sin(lat)[:, None, None]
    ring = np.cos(lon)[None, :, None] * e1 + np.sin(lon)[None, :, None] * e2
    centre = np.where((np.arange(len(lat)) <= half)[:, None, None], a, b)
    v = (centre + radius * (cl * ring + sl * k)).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(len(lat) - 1), np.arange(SEGMENTS), indexing="ij")
    p, q = i * SEGMENTS + j, i * SEGMENTS + (j + 1) % SEGMENTS
    quads = np.stack([p, q, q + SEGMENTS, p + SEGMENTS], axis=-1).reshape(-1, 4)
    return v, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.int64)


def plane_patch(point, normal, centre, extent):
    """(vertices (4, 3), faces (2, 3)) of the square of half-size ``extent`` in the plane
    through ``point`` with ``normal``, centred on the plane's point nearest ``centre``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    c = np.asarray(centre, float)
    c = c - np.dot(c - point, n) * n
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    v = np.array([c + extent * (s * e1 + r * e2) for s, r in corners])
    return v, np.array([[0, 1, 2], [0, 2, 3]], np.int64)


def subdivide(vertices, faces, n):
    """Each triangle split into n² congruent ones (points A + (i/n)(B − A) + (j/n)(C − A),
    i + j ≤ n); the new vertices are not shared between the original triangles."""
    ij = [(i, j) for i in range(n + 1) for j in range(n + 1 - i)]
    index = {p: k for k, p in enumerate(ij)}
    weights = np.array([[1 - (i + j) / n, i / n, j / n] for i, j in ij])
    template = []
    for i, j in ij:
        if i + j < n:
            template.append((index[i, j], index[i + 1, j], index[i, j + 1]))
        if i + j < n - 1:
            template.append((index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]))
    corners = np.asarray(vertices, float)[faces]  # (M, 3, 3)
    v = np.einsum("pk,mkd->mpd", weights, corners).reshape(-1, 3)
    f = np.asarray(template, np.int64)[None] + (len(ij) * np.arange(len(faces)))[:, None, None]
    return v, f.reshape(-1, 3)
