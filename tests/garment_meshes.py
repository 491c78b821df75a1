"""Small garments for the garment tests: flat panels written as an OBJ with ``g`` groups and
per-corner ``vt`` (the pattern), positions laid out in 3D."""

import numpy as np

from clothtool.io.caches.obj_writer import write_obj as write_obj_file


def panel(nx, ny, width, height):
    """(uv (nx·ny, 2), faces) of a regular panel, vertex j·nx + i at (i, j) spacing,
    counter-clockwise in uv."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    uv = np.stack([i.ravel() * width / (nx - 1), j.ravel() * height / (ny - 1)], axis=1)
    faces = []
    for b in range(ny - 1):
        for a in range(nx - 1):
            v = b * nx + a
            faces += [(v, v + 1, v + nx + 1), (v, v + nx + 1, v + nx)]
    return uv, np.array(faces, np.int64)


def write_obj(path, positions, groups):
    """An OBJ of ``positions`` (N, 3) and ``groups``: [(name, faces (K, 3), corner uv (K, 3, 2))],
    each group a ``g`` with its own ``vt`` per corner."""
    write_obj_file(path, positions, np.concatenate([f for _, f, _ in groups]),
                   corner_uv=np.concatenate([c for _, _, c in groups]),
                   groups=([name for name, _, _ in groups],
                           np.repeat(np.arange(len(groups)), [len(f) for _, f, _ in groups])))
    return path


def welded_pair(nx=5, ny=7, width=0.2, height=0.3, shift=(5.0, 2.0)):
    """Two panels side by side in the xy plane sharing the seam column x = 0 (one vertex
    each, welded), the right one's pattern shifted by ``shift`` in uv and turned a quarter:
    (positions, left faces, right faces, left corner uv, right corner uv, seam vertices)."""
    uv, faces = panel(nx, ny, width, height)
    n = nx * ny
    left = np.column_stack([uv[:, 0] - width, uv[:, 1], np.zeros(n)])
    # the right panel: its first column is the left panel's last one
    right_ids = np.arange(n).reshape(ny, nx)
    right_ids = np.where(np.arange(nx)[None, :] == 0, (right_ids // nx) * nx + nx - 1,
                         n + (right_ids // nx) * (nx - 1) + right_ids % nx - 1)
    extra = uv.reshape(ny, nx, 2)[:, 1:].reshape(-1, 2)
    positions = np.concatenate([left, np.column_stack([extra[:, 0], extra[:, 1],
                                                       np.zeros(len(extra))])])
    right_faces = right_ids.ravel()[faces]
    turned = np.stack([-uv[:, 1], uv[:, 0]], axis=1) + np.asarray(shift)  # a quarter turn
    return (positions, faces, right_faces, uv[faces], turned[faces],
            right_ids[:, 0].copy())




def welded_pair_model(folder, material):
    """(the model of :func:`welded_pair` written as an OBJ in ``folder``, with the config's
    ``material`` section, its seam vertices)."""
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config

    x, lf, rf, luv, ruv, seam = welded_pair()
    path = write_obj(folder / "pair.obj", x, [("left", lf, luv), ("right", rf, ruv)])
    return build_model(load_config({"mesh": {"obj": str(path)}, "material": material})), seam

def stretched_and_folded(positions):
    """A welded pair's positions two ways: (left mask, the left panel (x < 0) stretched 1 %
    along x with the right one at rest, the right panel folded 1 rad about the seam x = 0)."""
    left = positions[:, 0] < -1e-9
    stretched = positions.copy()
    stretched[left, 0] *= 1.01
    folded = positions.copy()
    folded[~left, 2] = folded[~left, 0] * np.sin(1.0)
    folded[~left, 0] *= np.cos(1.0)
    return left, stretched, folded

def apart_pair(nx=5, ny=7, width=0.2, height=0.3, gap=0.02):
    """Two separate panels in the xy plane, ``gap`` apart along x: (positions, left faces,
    right faces, left corner uv, right corner uv, a, b) with a the left panel's right edge
    and b the right panel's left edge, both bottom to top (they run opposite ways around
    their panels)."""
    uv, faces = panel(nx, ny, width, height)
    n = nx * ny
    left = np.column_stack([uv[:, 0] - width - 0.5 * gap, uv[:, 1], np.zeros(n)])
    right = np.column_stack([uv[:, 0] + 0.5 * gap, uv[:, 1], np.zeros(n)])
    a = np.arange(ny) * nx + nx - 1
    b = n + np.arange(ny) * nx
    return (np.concatenate([left, right]), faces, faces + n, uv[faces], uv[faces] + [1.0, 0.0],
            a, b)
