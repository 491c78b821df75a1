"""Shapes made from formulas for contact tests, benchmarks and sample scenes (no downloads)."""

import numpy as np

from clothtool.sim.config import GridSpec
from clothtool.sim.mesh import grid_mesh


def rolled_sheet(n=50, width=1.0, turns=3.0, radius=0.02, gap=(0.003, 0.012), twist=np.pi):
    """An n × n sheet rolled into a spiral around the y axis and twisted along it.

    Row j (at y) follows the Archimedean spiral r = radius + g(y) φ/2π, φ ∈ [0, 2π turns],
    so that consecutive layers lie g(y) apart, with g growing linearly over ``gap`` from one
    end to the other; the whole cross-section turns by ``twist`` (rad) along y. Layers come
    as close as the gap: a stand-in for cloth twisted into a rope. Returns (x (n², 3), faces).
    """
    mesh = grid_mesh(GridSpec(nx=n, ny=n, width=width, height=width))
    u = (mesh.uv[:, 0] / width + 0.5)  # 0 … 1 across a row
    s = (mesh.uv[:, 1] / width + 0.5)  # 0 … 1 along the axis
    phi = 2.0 * np.pi * turns * u
    g = gap[0] + (gap[1] - gap[0]) * s
    r = radius + g * phi / (2.0 * np.pi)
    angle = phi + twist * s
    x = np.stack([r * np.cos(angle), mesh.uv[:, 1], r * np.sin(angle)], axis=1)
    return x, mesh.faces
