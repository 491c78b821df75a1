"""Friction against closed forms: the incline and the turning sphere.

    python -m benchmarks friction

- Inclines of 15°, 30° and 45° under a 0.3 m sheet, on a ``plane``, a ``box``, a mesh ramp
  and another sheet (``benchmarks/friction_scenes.py``): with μ = tan θ + 0.03 the travel in
  2 s (goal: under 1 mm), with μ = tan θ − 0.1 the acceleration fitted to the second half of
  1 s against g(sin θ − μ cos θ) (goal: within 2 %), and ms per frame.
- Codimensional IPC's turning sphere: a 1 m sheet (16 × 16) dropped on a sphere of
  radius 0.3 m turning at 180°/s about the vertical, μ 0.4, 2 s at 30 fps, undamped (the
  stiffness-proportional damping of ``material.damping`` resists rigid rotation of stressed
  cloth; see docs/simulate.md): the cloth's angular velocity beside the sphere's, and the
  smallest exact distance from the sphere's centre to a cloth triangle over all frames
  (ipctk's point–triangle distance), which must exceed the radius.

Writes ``friction.csv`` and ``friction.md``.
"""

import tempfile
from pathlib import Path

import ipctk
import numpy as np

from benchmarks.common import markdown_table, write_csv, write_doc_table
from benchmarks.friction_scenes import G, SURFACES, incline_motion, turning_sphere
from clothtool.io.ply import read_ply


def run(out_dir):
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for surface in SURFACES:
            for degrees in (15, 30, 45):
                theta = np.radians(degrees)
                hold = Path(tmp) / f"{surface}{degrees}h"
                slide = Path(tmp) / f"{surface}{degrees}s"
                hold.mkdir()
                slide.mkdir()
                travel, _ = incline_motion(hold, surface, theta, np.tan(theta) + 0.03, 2.0)
                mu = np.tan(theta) - 0.1
                _, accel = incline_motion(slide, surface, theta, mu, 1.0)
                exact = G * (np.sin(theta) - mu * np.cos(theta))
                rows.append({"surface": surface, "angle": degrees,
                             "hold travel mm (goal < 1)": f"{1e3 * abs(travel):.3f}",
                             "slide a m/s²": f"{accel:.4f}", "closed form": f"{exact:.4f}",
                             "error % (goal ≤ 2)": f"{100 * (accel / exact - 1):+.2f}"})
                print(rows[-1], flush=True)
        folder = Path(tmp) / "turn"
        folder.mkdir()
        spin, omega, result = turning_sphere(folder)
        faces = None
        closest = np.inf
        centre = np.array([0.0, -0.31, 0.0])
        for path in sorted((folder / "out").glob("frame_*.ply")):
            mesh = read_ply(path)
            faces = mesh.faces if faces is None else faces
            x = mesh.vertices
            d2 = min(ipctk.point_triangle_distance(centre, x[a], x[b], x[c]) for a, b, c in faces)
            closest = min(closest, np.sqrt(d2))
    write_csv(out_dir / "friction.csv", rows, list(rows[0]))
    turn = (f"Turning sphere (r 0.3 m, 180°/s = {omega:.4f} rad/s, μ 0.4; 1 m sheet 16×16, "
            f"2 s at 30 fps): the cloth turns at {np.mean(spin[-30:]):.4f} rad/s over the last "
            f"second ({100 * np.mean(spin[-30:]) / omega:.1f} % of the sphere's); closest cloth "
            f"triangle {1e3 * (closest - 0.3):.3f} mm outside the sphere (ipctk's distance; "
            f"collision margin 2 mm); {1e3 * result.wall_s / len(spin):.0f} ms/frame.")
    text = ("## Friction against closed forms\n\n"
            "A 0.3 m sheet (8×8) on inclines: μ = tan θ + 0.03 must hold (travel in 2 s), "
            "μ = tan θ − 0.1 must slide at g(sin θ − μ cos θ) (acceleration fitted to the "
            "second half of 1 s).\n\n" + markdown_table(rows, list(rows[0])) + "\n\n" + turn + "\n")
    (out_dir / "friction.md").write_text(text)
    write_doc_table("docs/simulate.md", "friction", markdown_table(rows, list(rows[0])) + "\n"
                    + turn, "friction")
    print(text)
