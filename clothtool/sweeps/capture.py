"""A captured sequence and its distance to a simulated one, frame by frame.

The capture is a folder, glob or list of PLY/OBJ frames (:func:`clothtool.io.frames.discover_frames`):
frame 0 the initial state, frame k the simulation's output frame k. Two ways to compare:

- **vertex for vertex** (``vertex``), when the capture has the config's mesh (the same
  vertex count and faces): the residual of frame k is x_sim,k − x_cap,k per vertex;
- **surface to surface** (``surface``), when it does not (a scan, a remeshed capture): the
  residual of captured vertex p at frame k is p − c(p), c(p) the closest point of the
  simulated surface at frame k (:func:`surface_offsets`).

Either way the residual is a vector per point, so its length is the distance the report
gives and least squares sees a smooth function of the simulated positions (an unsigned
distance has a kink at 0). Frame 0 is not compared: it is the config's initial state in every
simulation. A capture that starts slightly off it is first moved rigidly onto it
(:func:`register`) when the rigid motion stands out of frame 0's scatter; what is left at
frame 0 (a capture that does not start from the config's shape) is reported, not fitted.
"""

import math
from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError

COMPARISONS = ("auto", "vertex", "surface")
NEAREST = 8  # candidate triangles per point before the exactness check
ICP_ITERATIONS = 30
RIGID_ALPHA = 1e-3  # a rigid motion fitted to noise alone stands out this rarely (F-test)


@dataclass
class Capture:
    """The captured frames (``frames``: (K+1, N, 3)), their faces, the files, and how they
    are compared with the simulation (``mode``: 'vertex' or 'surface')."""

    frames: np.ndarray
    faces: np.ndarray
    paths: list
    mode: str

    @property
    def points(self):
        """Compared points per frame × compared frames (frames 1..K)."""
        return self.frames.shape[1] * (len(self.frames) - 1)

    def residual(self, simulated, faces):
        """The residual vector of a simulated sequence (``simulated``: (K+1, V, 3), its mesh's
        ``faces``), frames 1..K, three numbers per compared point."""
        if self.mode == "vertex":
            return (simulated[1:] - self.frames[1:]).ravel()
        return np.concatenate([surface_offsets(self.frames[k], simulated[k], faces).ravel()
                               for k in range(1, len(self.frames))])

    def distances(self, residual):
        """(K, N) distance of each compared point at frames 1..K, from a residual vector."""
        return np.sqrt((residual.reshape(len(self.frames) - 1, -1, 3) ** 2).sum(axis=2))


def read_capture(capture, count, positions, faces, compare="auto"):
    """The capture ``capture`` (frames as :func:`~clothtool.io.frames.discover_frames` takes
    them), checked: ``count`` frames (the config's output frames, the initial one included),
    finite positions, one mesh throughout; ``positions``, ``faces``: the config's initial mesh.
    ``compare``: 'vertex' (the capture must have the config's mesh), 'surface', or 'auto'
    (vertex for vertex when the meshes match). Errors name ``capture`` or ``compare``."""
    from clothtool.io.frames import discover_frames, read_mesh

    if compare not in COMPARISONS:
        raise InputError(f"must be one of {', '.join(COMPARISONS)}", keyword="compare",
                         value=compare)
    try:
        paths = discover_frames(capture)
    except InputError as exc:
        raise InputError(exc.detail, keyword="capture", value=_shown(capture)) from None
    if len(paths) != count:
        raise InputError(f"{len(paths)} frames, but the config writes {count} (frame 0 the "
                         "initial state, then time.frames / output.every)", keyword="capture",
                         value=_shown(capture))
    first = read_mesh(paths[0])
    frames = np.empty((count, len(first.vertices), 3))
    for k, path in enumerate(paths):
        mesh = first if k == 0 else read_mesh(path)
        if len(mesh.vertices) != len(first.vertices) or not np.array_equal(mesh.faces, first.faces):
            raise InputError(f"{path}: not the mesh of {paths[0]} (every frame of a capture has "
                             "the same vertices and faces)", keyword="capture", value=_shown(capture))
        if not np.all(np.isfinite(mesh.vertices)):
            bad = int(np.flatnonzero(~np.isfinite(mesh.vertices).all(axis=1))[0])
            raise InputError(f"{path}: vertex {bad} is not finite (NaN or infinite)",
                             keyword="capture", value=_shown(capture))
        frames[k] = mesh.vertices
    same = len(first.vertices) == len(positions) and np.array_equal(first.faces, faces)
    if compare == "vertex" and not same:
        raise InputError(f"vertex for vertex needs the config's mesh ({len(positions)} vertices, "
                         f"{len(faces)} triangles); {paths[0]} has {len(first.vertices)} vertices "
                         f"and {len(first.faces)} triangles: compare surface to surface",
                         keyword="compare", value=compare)
    mode = "vertex" if compare == "vertex" or (compare == "auto" and same) else "surface"
    return Capture(frames, np.asarray(first.faces, np.int64), paths, mode)


def register(capture, positions, faces, move=True, iterations=ICP_ITERATIONS):
    """Move every frame of ``capture`` by the rigid motion that brings its frame 0 nearest the
    config's initial mesh (``positions``, ``faces``), in place, when that motion stands out of
    frame 0's scatter: a capture that starts slightly off (a registration error, another origin
    or up axis) is compared as if it had not.
    Vertex for vertex, the motion is Kabsch's (least squares over the vertices); surface to
    surface, iterative closest points (Besl & McKay 1992): Kabsch onto the closest points of the
    initial surface, ``iterations`` times or until it stops moving; ``move=False`` only
    measures. The motion is fitted to frame 0 alone, so its error from that frame's noise
    (≈ noise/√N) would move every frame alike, a systematic difference the fit's ± does not
    hold; it is applied only when it explains more of frame 0 than six parameters fitted to
    noise do (:func:`rigid_motion_stands_out`).
    Returns (frame 0's RMS distance before, after, translation length (m), rotation
    angle (rad)); a motion not applied is (before, before, 0, 0)."""
    x0 = capture.frames[0]

    def distance(x):
        d = x - positions if capture.mode == "vertex" else surface_offsets(x, positions, faces)
        return float(np.sqrt(np.mean((d ** 2).sum(axis=1))))

    before = distance(x0)
    rotation, shift = np.eye(3), np.zeros(3)
    for _ in range(0 if not move else 1 if capture.mode == "vertex" else iterations):
        moved = x0 @ rotation.T + shift
        target = positions if capture.mode == "vertex" else (
            moved - surface_offsets(moved, positions, faces))
        r, t = kabsch(moved, target)
        rotation, shift = r @ rotation, r @ shift + t
        if np.abs(r - np.eye(3)).max() < 1e-12 and np.abs(t).max() < 1e-12:
            break
    # vertex for vertex a point gives 3 coordinates, surface to surface about 1 (its offset
    # along the normal)
    coordinates = len(x0) * (3 if capture.mode == "vertex" else 1)
    if not rigid_motion_stands_out(before, distance(x0 @ rotation.T + shift), len(x0),
                                   coordinates):
        return before, before, 0.0, 0.0
    capture.frames = capture.frames @ rotation.T + shift
    angle = math.acos(min(max((np.trace(rotation) - 1.0) / 2.0, -1.0), 1.0))
    return before, distance(capture.frames[0]), float(np.linalg.norm(shift)), angle


def rigid_motion_stands_out(before, after, points, coordinates, alpha=RIGID_ALPHA):
    """Whether a rigid motion (6 parameters) that takes frame 0's RMS distance over ``points``
    from ``before`` to ``after`` is more than a fit to its noise: Fisher's F-test of the
    nested least-squares models, F = (S_before − S_after)/6 / (S_after/(m − 6)),
    S = points·RMS², m = ``coordinates``, which noise alone (independent, of equal variance)
    exceeds with probability ``alpha``. A noiseless frame stands out by any motion."""
    from scipy.stats import f as fisher

    gained, left = points * (before ** 2 - after ** 2), points * after ** 2
    if gained <= 0.0:
        return False
    if left == 0.0:
        return True
    return coordinates > 6 and gained / 6.0 / (left / (coordinates - 6)) > fisher.ppf(1.0 - alpha, 6,
                                                                    coordinates - 6)


def kabsch(x, y):
    """The rotation R and translation t minimising Σ‖R x_i + t − y_i‖² (Kabsch 1976)."""
    cx, cy = x.mean(axis=0), y.mean(axis=0)
    u, _, vt = np.linalg.svd((x - cx).T @ (y - cy))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, cy - r @ cx


def _shown(capture):
    if isinstance(capture, (list, tuple)):
        return " ".join(map(str, capture[:2])) + (" …" if len(capture) > 2 else "")
    return str(capture)


def surface_offsets(points, x, faces):
    """p − c(p) for each of ``points`` (P, 3), c(p) the closest point of the triangle surface
    (``x`` (V, 3), ``faces`` (M, 3)). Exact: each point's candidates are its NEAREST
    triangles by centroid, and a point for which a nearer triangle could lie beyond them
    (its best distance plus the largest centroid-to-corner distance reaches past the last
    candidate) takes every triangle within that radius instead."""
    from scipy.spatial import cKDTree

    from clothtool.contact.distance import closest_offsets

    corners = x[faces]
    centroids = corners.mean(axis=1)
    reach = float(np.sqrt(((corners - centroids[:, None]) ** 2).sum(axis=2).max()))
    k = min(NEAREST, len(faces))
    tree = cKDTree(centroids)
    far, near = tree.query(points, k=k)
    near = near.reshape(len(points), k).astype(np.int64)
    far = far.reshape(len(points), k)
    both = np.ascontiguousarray(np.concatenate([x, points]))
    rows = np.arange(len(points))
    out = np.empty((len(points), 3))
    best = closest_offsets(both, faces, len(x), rows, near, out)
    unsure = np.flatnonzero(far[:, -1] < best + reach) if k < len(faces) else rows[:0]
    if len(unsure):  # rare: a point far from the surface, or very unequal triangles
        balls = tree.query_ball_point(points[unsure], best[unsure] + reach)
        wide = np.full((len(unsure), max(len(b) for b in balls)), -1, np.int64)
        for r, ball in enumerate(balls):
            wide[r, :len(ball)] = ball
        again = np.empty((len(unsure), 3))
        closest_offsets(both, faces, len(x), unsure, wide, again)
        out[unsure] = again
    return out
