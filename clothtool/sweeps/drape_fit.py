"""The bending length whose simulated Cusick test gives a measured drape coefficient, fitted
through parameter sweeps (:mod:`clothtool.sweeps`): each round is a sweep over
``material.bending_length`` of the Cusick scene (:func:`clothtool.sim.textile.cusick_drape`'s:
a 30 cm disc on an 18 cm pedestal, 10 mm grid, 6 s at 60 fps, damping 0.05 s), on the local
pool or as a Slurm array; the answer comes with its discretisation error (one more run, on a
14 mm disc).

The drape coefficient rises with the bending length c. Round 1 runs c = 0.3, 0.8, 2.2, 6 cm;
each later round three values in the bracket around the target: c* where the coefficient,
interpolated linearly in log c between the bracket's ends, meets the target, and c* e^{±w/6},
w the bracket's width in log c. It stops at the first run within ``tolerance`` points of the
target, or after 10 runs (three rounds); the answer is the run nearest the target, its
coefficient simulated, not interpolated. A round left to Slurm returns with its ``sbatch``
command; the same call once the array has ended goes on from the runs on disk.
"""

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from clothtool.errors import InputError
from clothtool.lab_units import STANDARD_GRAVITY

FIRST = (0.003, 0.008, 0.022, 0.06)  # m, round 1's bending lengths
ROUNDS = 3
SPACING, FPS, SECONDS = 0.01, 60, 6.0  # 6 s: a 10 mm disc at rest (after 3 s it creeps)


@dataclass
class DrapeFit:
    """``bending_length`` (m) and ``bend`` (N·m, ρ · 9.81 · c³) of the run nearest ``target``
    (a fraction), its simulated ``coefficient`` on a grid disc of ``spacing`` m and that
    coefficient's estimated discretisation ``error`` (:func:`clothtool.sim.textile.
    drape_error`); ``runs``: (c, coefficient) of every run so far; ``sbatch``: set when a
    round waits for Slurm (the rest is then the best so far)."""

    target: float
    density: float
    bending_length: float | None = None
    bend: float | None = None
    coefficient: float | None = None
    runs: list = field(default_factory=list)
    sbatch: str | None = None
    spacing: float = SPACING
    error: float | None = None

    def settle(self):
        """Take the run nearest the target as the answer; returns self."""
        if self.runs:
            c, d = min(self.runs, key=lambda r: abs(r[1] - self.target))
            self.bending_length, self.coefficient = c, d
            self.bend = self.density * STANDARD_GRAVITY * c ** 3
        return self


def fit_drape(material, target, output_dir, *, jobs=1, slurm=False, tolerance=0.005):
    """Fit the bending length of ``material`` (a material section) to the drape coefficient
    ``target`` (a fraction in (0, 1)); the sweeps go to ``output_dir/round_K``."""
    if not 0.0 < target < 1.0:
        raise InputError("a drape coefficient is between 0 and 100 %", keyword="target",
                         value=f"{100 * target:g} %")
    from clothtool.sweeps import sweep

    root = Path(output_dir)
    base = _write_scene(material, root)
    fit = DrapeFit(target, material.density)
    values = list(FIRST)
    for k in range(1, ROUNDS + 1):
        folder = root / f"round_{k}"
        result = sweep(base, folder, grid={"material.bending_length": values}, jobs=jobs,
                       slurm=slurm)
        if result.sbatch:
            fit.sbatch = result.sbatch
            return fit.settle()
        fit.runs += _coefficients(folder)
        if abs(fit.settle().coefficient - target) <= tolerance:
            break
        if k < ROUNDS:
            values = _next_round(fit.runs, target)
    fit.error = _discretisation_error(material, fit)
    return fit


def _discretisation_error(material, fit):
    """The fitted coefficient's discretisation error: one Cusick test of the fitted bending
    length on a disc √2 coarser (:func:`clothtool.sim.textile.drape_error`)."""
    from clothtool.sim.lab_sheet import SI_KEYS
    from clothtool.sim.textile import CUSICK_DAMPING, drape_error

    keys = {k: getattr(material, k) for k in SI_KEYS if k != "bend"}
    keys.update(damping=CUSICK_DAMPING, bending_length=fit.bending_length)
    return drape_error(keys, fit.spacing, fit.coefficient)


def _next_round(runs, target):
    """Three bending lengths in the bracket of ``target`` (log c, linear interpolation)."""
    runs = sorted(runs)
    above = [j for j, (_, d) in enumerate(runs) if d >= target]
    if not above or above[0] == 0:
        lo, hi = (100 * min(d for _, d in runs), 100 * max(d for _, d in runs))
        raise InputError(f"bending lengths {runs[0][0] * 100:g}–{runs[-1][0] * 100:g} cm drape "
                         f"{lo:.1f}–{hi:.1f} %; the target is outside", keyword="target",
                         value=f"{100 * target:g} %")
    (ci, di), (cj, dj) = runs[above[0] - 1], runs[above[0]]  # d rises with c
    t = (target - di) / (dj - di)
    mid = math.log(ci) + t * (math.log(cj) - math.log(ci))
    width = (math.log(cj) - math.log(ci)) / 6.0
    return [math.exp(mid + s * width) for s in (-1.0, 0.0, 1.0)]


def _write_scene(material, root):
    """The Cusick scene as a config (``root/cusick.yaml``) and its disc (``root/disc.ply``):
    the material's keys but its bending, damping 0.05 s, the pedestal's vertices pinned."""
    import yaml

    from clothtool.io.ply import write_ply
    from clothtool.sim.lab_sheet import SI_KEYS
    from clothtool.sim.textile import CUSICK, CUSICK_DAMPING, disc

    radius, pedestal = CUSICK
    uv, faces = disc(radius, SPACING, "grid", seed=1, clamp=pedestal)
    edge = pedestal + SPACING / 2  # the outer pinned ring (cusick_drape's clamp)
    r, phi = np.hypot(uv[:, 0], uv[:, 1]), np.arctan2(uv[:, 1], uv[:, 0])
    x = np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)
    x[:, 2] = -0.002 * np.clip(r - edge, 0.0, None) / (radius - edge) * np.cos(6 * phi)
    root.mkdir(parents=True, exist_ok=True)
    write_ply(root / "disc.ply", x, faces,
              vertex_properties={"s": uv[:, 0].copy(), "t": uv[:, 1].copy()})
    keys = {k: getattr(material, k) for k in SI_KEYS if k != "bend"}
    keys = {k: list(v) if isinstance(v, tuple) else v for k, v in keys.items()}
    keys["damping"] = CUSICK_DAMPING
    config = {"mesh": {"ply": "disc.ply"}, "material": keys,
              "scene": {"gravity": [0.0, 0.0, -9.81],
                        "pins": [int(v) for v in np.flatnonzero(r <= edge + 1e-9)]},
              "solver": {"tolerance": 1e-3},
              "time": {"fps": FPS, "frames": int(SECONDS * FPS)},
              "output": {"every": int(SECONDS * FPS)}}
    path = root / "cusick.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return path


def _coefficients(folder):
    """(bending length, drape coefficient) of each done run of the sweep in ``folder``."""
    import yaml

    from clothtool.io.ply import read_ply
    from clothtool.sim.textile import CUSICK, drape_coefficient

    radius, pedestal = CUSICK
    out = []
    for run_dir in sorted(p for p in folder.iterdir() if (p / "status.json").is_file()):
        frames = sorted(run_dir.glob("frame_*.ply"))
        if len(frames) < 2:
            continue  # failed: its error is in the sweep's manifest.csv
        config = yaml.safe_load((run_dir / "config.yaml").read_text())
        mesh = read_ply(frames[-1])
        out.append((float(config["material"]["bending_length"]),
                    drape_coefficient(mesh.vertices, mesh.faces, pedestal, radius,
                                      (0.0, 0.0, 0.0))))
    return out
