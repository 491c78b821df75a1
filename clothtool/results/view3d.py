"""Triangle meshes drawn in 3D with matplotlib (mplot3d), for ``plot`` and ``render``.

The scene's up direction (against gravity) is drawn up. Every triangle of every mesh goes
into one ``Poly3DCollection``, which mplot3d orders back to front by the depth of the
triangles' centroids (a painter's algorithm over the whole scene, so cloth and colliders
occlude one another); each face is lit by Lambert's cosine law, two-sided,
I = ambient + (1 − ambient)·|n̂·l̂|, with the light l̂ from the upper left front of the view.
The axes are equal in length (a sphere looks round) and fixed by the caller's bounds, so
that a sequence of pictures keeps its camera. The projection is orthographic: a collider
moved away from the camera by about its own triangles' size (:func:`push_back`) looks the
same but sorts behind the cloth that rests on it, which the centroid order alone would
let its triangles poke through.
"""

import numpy as np

CLOTH_RGB = (0.80, 0.33, 0.22)
COLLIDER_RGB = (0.72, 0.74, 0.78)
AMBIENT = 0.35
ELEVATION, AZIMUTH = 18.0, -58.0  # degrees: the camera a little above, from the front left
PLANE_SPAN = 1.5  # a plane patch's half-size, in half-sizes of the cloth's bounding cube
VIEW_SPAN = 3.0  # colliders widen the view to at most this many half-sizes about the cloth
ZOOM = 1.4  # the cube of the bounds fills the picture's height at about 1.4


def display_basis(up):
    """(3, 3) rows e1, e2, û: world → display coordinates with ``up`` as display z
    (right-handed; y up gives (x, −z, y))."""
    u = np.asarray(up, float) / np.linalg.norm(up)
    x = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = x - np.dot(x, u) * u
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(u, e1), u])


def light_direction(elevation=ELEVATION, azimuth=AZIMUTH):
    """Unit light direction in display coordinates: from the camera's side, 30° to its left
    and 35° above it."""
    el, az = np.radians(elevation + 35.0), np.radians(azimuth - 30.0)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def lit(x, faces, rgb, light, ambient=AMBIENT):
    """(F, 4) RGBA of each face of ``x`` (display coordinates): ``rgb`` (3,) or (F, 3)
    scaled by ambient + (1 − ambient)·|n̂·l̂|."""
    n = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    norm = np.linalg.norm(n, axis=1)
    cos = np.abs(n @ light) / np.where(norm > 0, norm, 1.0)
    shade = ambient + (1.0 - ambient) * cos
    out = np.ones((len(faces), 4))
    out[:, :3] = np.clip(np.broadcast_to(rgb, (len(faces), 3)) * shade[:, None], 0.0, 1.0)
    return out


def view_direction(elevation=ELEVATION, azimuth=AZIMUTH):
    """Unit vector from the camera into the scene (display coordinates)."""
    el, az = np.radians(elevation), np.radians(azimuth)
    return -np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def push_back(x, faces, elevation=ELEVATION, azimuth=AZIMUTH):
    """``x`` moved away from the camera by its triangles' median edge length (the same
    picture in an orthographic view; it sorts behind what touches it)."""
    if len(faces) == 0:
        return x
    edges = np.linalg.norm(x[faces] - x[np.roll(faces, 1, axis=1)], axis=2)
    return x + float(np.median(edges)) * view_direction(elevation, azimuth)


def bounds(points):
    """(centre (3,), half-size) of the cube that holds ``points`` (display coordinates)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    return (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-9)


def setup_axes(ax, centre, half, elevation=ELEVATION, azimuth=AZIMUTH):
    """Equal axes over the cube (centre, half) of display coordinates, the camera set, no
    panes or ticks."""
    for axis, c in zip("xyz", centre):
        getattr(ax, f"set_{axis}lim")(c - half, c + half)
    ax.set_box_aspect((1, 1, 1), zoom=ZOOM)
    ax.set_proj_type("ortho")
    ax.view_init(elev=elevation, azim=azimuth)
    ax.set_axis_off()


def draw_meshes(ax, meshes):
    """Add [(x (V, 3) display coordinates, faces (F, 3), facecolors (F, 4))] to ``ax`` as
    one collection; returns it."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    triangles = np.concatenate([x[f] for x, f, _ in meshes]) if meshes else np.zeros((0, 3, 3))
    colours = np.concatenate([c for _, _, c in meshes]) if meshes else np.zeros((0, 4))
    # edges in the face colour close the hairline gaps that antialiasing leaves between faces
    collection = Poly3DCollection(triangles, facecolors=colours, edgecolors=colours,
                                  linewidths=0.3)
    ax.add_collection3d(collection)
    return collection


def layout(positions, scene, times):
    """Display coordinates of cloth frames ``positions`` (K, N, 3), of the colliders of
    ``scene`` (a run's scene with ``up`` and ``surfaces(t, centre, extent)``, or None: y
    up) at each of ``times`` (K,), and the view's cube: (cloth (K, N, 3), [[(x, faces)] per
    frame], (centre, half)). The cube holds every frame's cloth, and the colliders within
    VIEW_SPAN half-sizes of it."""
    up = scene.up if scene is not None else np.array([0.0, 1.0, 0.0])
    basis = display_basis(up)
    cloth = positions @ basis.T
    centre, half = bounds(cloth.reshape(-1, 3))
    world_centre = basis.T @ centre
    colliders = [[(s.vertices @ basis.T, s.faces) for s in
                  scene.surfaces(t, world_centre, PLANE_SPAN * half)] for t in times] \
        if scene is not None else [[] for _ in times]
    solid = [x for step in colliders for x, _ in step]
    if solid:
        everything = np.concatenate([cloth.reshape(-1, 3)] + solid)
        everything = np.clip(everything, centre - VIEW_SPAN * half, centre + VIEW_SPAN * half)
        centre, half = bounds(everything)
    return cloth, colliders, (centre, half)
