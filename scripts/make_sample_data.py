"""Generate sample_data/sheet/: a small cloth sequence with a stretched, a sheared and a bent region.

A 21×21-vertex sheet (800 triangles) over 30 frames: the left third is stretched
along x (up to 30 %), the middle third is sheared (simple shear γ up to 0.5), and the
right third is rolled isometrically onto a cylinder (bent without stretch), while the
whole sheet slowly turns rigidly about the vertical axis. Binary little endian PLY
with ``s t`` texture coordinates = the rest positions (so ``--reference uv`` works).

    python scripts/make_sample_data.py sample_data/sheet
"""

import os
import sys

import numpy as np

from clothtool.io.ply import write_ply


def sheet(nx=21, ny=21, frames=30):
    u, v = np.meshgrid(np.linspace(0.0, 1.0, nx), np.linspace(0.0, 1.0, ny))
    u, v = u.ravel(), v.ravel()
    faces = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            faces += [(a, a + 1, a + nx + 1), (a, a + nx + 1, a + nx)]
    faces = np.array(faces, dtype=np.int64)
    out = []
    for k in range(frames):
        s = k / (frames - 1)
        x = u.copy()
        y = v.copy()
        z = np.zeros_like(u)
        left = u < 1 / 3
        x[left] = u[left] * (1 + 0.3 * s)  # stretch λ = 1.3 along x
        shift = (1 / 3) * 0.3 * s  # the stretched third is longer by this much
        mid = (u >= 1 / 3) & (u < 2 / 3)
        x[mid] = u[mid] + shift
        y[mid] = v[mid] + 0.5 * s * (u[mid] - 1 / 3)  # simple shear, γ = 0.5
        right = u >= 2 / 3
        y[right] = v[right] + 0.5 * s / 3
        arc = u[right] - 2 / 3
        curvature = 6.0 * s  # rolled onto a cylinder of radius 1/curvature
        x0 = 2 / 3 + shift
        if curvature > 0:
            x[right] = x0 + np.sin(arc * curvature) / curvature
            z[right] = (1 - np.cos(arc * curvature)) / curvature
        else:
            x[right] = x0 + arc
        angle = 0.4 * s  # rigid turn about y
        c, sn = np.cos(angle), np.sin(angle)
        pos = np.stack([c * x + sn * z, y, -sn * x + c * z], axis=1)
        out.append(pos)
    return out, faces, u, v


def main(folder):
    os.makedirs(folder, exist_ok=True)
    frames, faces, u, v = sheet()
    for k, pos in enumerate(frames):
        write_ply(os.path.join(folder, f"sheet_{k}.ply"), pos.astype(np.float32), faces,
                  vertex_properties={"s": u.astype(np.float32), "t": v.astype(np.float32)},
                  comments=["clothtool sample: stretched, sheared and bent regions"])


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "sample_data/sheet")
