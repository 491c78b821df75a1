"""Scenes with closed-form friction answers, shared by tests/test_friction_scenes.py and
bench_friction.py: a sheet on an incline (Coulomb's stick and slip) and a sheet on a
turning sphere (Codimensional IPC's test).

A 0.3 m sheet laid on an incline of angle θ holds when μ > tan θ and otherwise slides with
acceleration g(sin θ − μ cos θ); both are measured after the sheet has settled onto its
contact (SETTLE). The incline is a ``plane``, a ``box``, a triangle-mesh ramp,
or another sheet (cloth–cloth, the lower sheet pinned).
"""

import numpy as np

from clothtool.io.ply import read_ply, write_ply
from clothtool.sim.api import simulate
from clothtool.sim.model.config import GridSpec
from clothtool.sim.model.mesh import grid_mesh

G = 9.81
SURFACES = ("plane", "box", "mesh", "cloth")


def incline_scene(folder, surface, theta, mu, seconds, n=8, fps=30, solver=None):
    """The config (a dict) of an n × n sheet of 0.3 m resting on an incline of θ rad with
    friction μ (``solver``: solver keys), and the downhill unit vector. The sheet starts at the
    collision margin (or the self-collision thickness above the lower sheet), at rest."""
    c, s = np.cos(theta), np.sin(theta)
    down = np.array([-c, -s, 0.0])
    normal = np.array([-s, c, 0.0])
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    sheet = grid_mesh(GridSpec(nx=n, ny=n, width=0.3, height=0.3, plane="xz"))
    margin, thickness = 1.0e-3, 2.0e-3
    scene = {"gravity": [0.0, -G, 0.0], "collision_margin": margin}
    x = sheet.positions @ turn.T
    faces, uv = sheet.faces, sheet.uv
    if surface == "cloth":  # a lower sheet 1.2 m down the slope, pinned; the upper at its top
        lower = grid_mesh(GridSpec(nx=4 * n, ny=n + 2, width=1.2, height=0.4, plane="xz"))
        y = lower.positions @ turn.T
        x = np.vstack([y, x - 0.4 * down + 0.98 * thickness * normal])
        faces = np.vstack([lower.faces, sheet.faces + len(y)])
        uv = np.vstack([lower.uv, sheet.uv])
        scene["pins"] = list(range(len(y)))
        scene["self_collision"] = {"thickness": thickness, "friction": mu}
    else:
        x = x + 0.98 * margin * normal
        if surface == "plane":
            body = {"plane": {"point": [0, 0, 0], "normal": normal.tolist()}}
        elif surface == "box":
            body = {"box": {"center": (-0.5 * normal).tolist(), "size": [4.0, 1.0, 4.0],
                            "axis": [0, 0, 1], "angle": theta}}
        else:
            ramp = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], float) @ turn.T
            write_ply(folder / "ramp.ply", ramp, np.array([[0, 2, 1], [0, 3, 2]]))
            body = {"mesh": {"ply": str(folder / "ramp.ply")}}
        next(iter(body.values()))["friction"] = mu
        scene["colliders"] = [body]
    write_ply(folder / "rest.ply", x, faces, vertex_properties={"s": uv[:, 0], "t": uv[:, 1]})
    config = {"mesh": {"ply": str(folder / "rest.ply")},
              "material": {"density": 0.2, "stretch": 1000.0, "shear": 100.0, "bend": 1e-5},
              "scene": scene, "time": {"fps": fps, "frames": int(round(seconds * fps))},
              "output": {"dir": str(folder / "out")}}
    if solver:
        config["solver"] = dict(solver)
    return config, down, n * n


SETTLE = 0.5  # s: the sheet, laid at the margin, settles onto its contact first


def incline_motion(folder, surface, theta, mu, seconds, solver=None):
    """(travel along the slope (m) in ``seconds`` after SETTLE, acceleration fitted to the
    second half of those seconds); ``solver``: solver keys of the run."""
    config, down, n_top = incline_scene(folder, surface, theta, mu, SETTLE + seconds,
                                        solver=solver)
    simulate(config, progress=False)
    paths = sorted((folder / "out").glob("frame_*.ply"))
    centre = np.array([read_ply(p).vertices[-n_top:].mean(axis=0) for p in paths]) @ down
    settled = int(round(SETTLE * config["time"]["fps"]))
    s = centre[settled:] - centre[settled]
    t = np.arange(len(s)) / config["time"]["fps"]
    half = len(t) // 2
    fit = np.polyfit(t[half:], s[half:], 2)
    return s[-1], 2.0 * fit[0]


def turning_sphere(folder, n=16, width=1.0, seconds=2.0, fps=30, mu=0.4, damping=0.0,
                   material=None):
    """A width × width sheet dropped 1 cm onto a sphere of radius 0.3 m turning at 180°/s about
    the vertical, friction μ (``material``: more material keys). Returns (the cloth's angular
    velocity about the vertical per frame (rad/s), the sphere's, the SimulationResult)."""
    omega = np.pi
    centre = [0.0, -0.31, 0.0]
    config = {"mesh": {"grid": {"nx": n, "ny": n, "width": width, "height": width,
                                "plane": "xz"}},
              "material": {"density": 0.2, "stretch": 1000.0, "shear": 100.0, "bend": 1e-5,
                           "damping": damping, **(material or {})},
              "scene": {"colliders": [{"sphere": {
                  "center": centre, "radius": 0.3, "friction": mu,
                  "motion": {"rotate": {"center": centre, "axis": [0, 1, 0], "speed": omega}}}}]},
              "time": {"fps": fps, "frames": int(round(seconds * fps))},
              "output": {"dir": str(folder / "out")}}
    result = simulate(config, progress=False)
    xs = [read_ply(p).vertices for p in sorted((folder / "out").glob("frame_*.ply"))]
    spin = []
    for a, b in zip(xs, xs[1:]):  # the least-squares turn about the vertical axis
        p, q = a[:, [0, 2]], b[:, [0, 2]]
        turn = np.arctan2(np.sum(p[:, 1] * q[:, 0] - p[:, 0] * q[:, 1]), np.sum(p * q))
        spin.append(turn * fps)
    return np.array(spin), omega, result
