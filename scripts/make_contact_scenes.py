"""Generate the collider and cloth meshes of the contact scenes in sample_data/contact/.

- body.ply: a closed capsule (radius 0.15 m, 0.9 m long, along x) under the drape's sheet;
- table.ply: a closed box 1 m × 0.8 m, its top 1 cm under the tablecloth;
- floor.ply: an open 3 m × 3 m plate (two triangles) at y = 0;
- stack.ply: five 0.6 m × 0.6 m sheets (20 × 20 vertices each), 4 cm apart from y = 0.05 m
  up, each turned 15° further about the vertical: the cloth of the stacking scene.

    python scripts/make_contact_scenes.py sample_data/contact
"""

import os
import sys

import numpy as np

from clothtool.contact.shapes import box, capsule, plate
from clothtool.io.ply import write_ply
from clothtool.sim.model.config import GridSpec
from clothtool.sim.model.mesh import grid_mesh


def stack(sheets=5, n=20, size=0.6, first=0.05, gap=0.04, turn=np.radians(15.0)):
    mesh = grid_mesh(GridSpec(nx=n, ny=n, width=size, height=size, plane="xz"))
    xs, fs = [], []
    for k in range(sheets):
        c, s = np.cos(k * turn), np.sin(k * turn)
        x = mesh.positions @ np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
        x[:, 1] = first + k * gap
        xs.append(x)
        fs.append(mesh.faces + k * n * n)
    return np.concatenate(xs), np.concatenate(fs)


def main(out_dir):
    os.makedirs(out_dir, exist_ok=True)
    x, f = capsule(radius=0.15, half_length=0.3)
    write_ply(os.path.join(out_dir, "body.ply"), x + [0.0, -0.2, 0.0], f)
    write_ply(os.path.join(out_dir, "table.ply"), *box([-0.5, -0.8, -0.4], [0.5, -0.01, 0.4]))
    write_ply(os.path.join(out_dir, "floor.ply"), *plate(3.0, 3.0))
    write_ply(os.path.join(out_dir, "stack.ply"), *stack())


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "sample_data/contact")
