"""Run a config in memory and measure it against a reference (benchmarks and tests).

:func:`run_in_memory` steps a config without writing frames and records the
positions at chosen frames, the wall time per frame (after a warm-up step that
compiles the kernels, not counted), the largest principal stretch over the run,
and the total energy (kinetic + the method's elastic + gravitational) per frame.
:func:`position_error` is the RMS vertex distance between two runs at their
common checkpoints, the largest over the checkpoints.
"""

import math
import time
from dataclasses import dataclass, field

import numpy as np

from clothtool.sim.model.config import Config, load_config


@dataclass
class Run:
    method: str
    h: float
    positions: dict = field(default_factory=dict)  # frame → (N, 3)
    wall_per_frame: float = math.nan
    max_stretch: float = 0.0
    energy: list = field(default_factory=list)  # total energy per frame, frame 0 first
    gravity: list = field(default_factory=list)
    newton_iterations: int = 0
    cg_iterations: int = 0
    sweeps: int = 0
    substeps: int = 0
    blew_up: str = ""  # empty when the run stayed finite and bounded
    frames_done: int = 0

    @property
    def ok(self):
        return not self.blew_up

    def energy_drift(self):
        """(E(T) − E(0)) / max|E_gravity(t) − E_gravity(0)|: the energy the run gained (+) or
        lost (−) relative to the potential energy it converted; nan without motion."""
        if len(self.energy) < 2:
            return math.nan
        scale = max(abs(g - self.gravity[0]) for g in self.gravity)
        return (self.energy[-1] - self.energy[0]) / scale if scale > 0 else math.nan


def run_in_memory(config, checkpoints=(), *, warmup=True, bound=100.0, initial=None):
    """Simulate ``config`` (dict, path or Config) and record a :class:`Run`.

    ``initial(model, state)``: optional hook that changes the initial state in place.

    A run is stopped (``blew_up`` set) when positions become non-finite, a
    speed exceeds ``solver.max_speed`` or a vertex leaves a ball of ``bound``
    metres around the origin.
    """
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.methods import make_integrator

    if not isinstance(config, Config):
        config = load_config(config)
    model = build_model(config)
    make = lambda: make_integrator(model, config.solver, config.step)  # noqa: E731
    if warmup:  # compile (numba cache) and factorise once, untimed
        integ = make()
        integ.step(model.initial_state())
    integ = make()
    state = model.initial_state()
    if initial is not None:
        initial(model, state)
    run = Run(config.solver.method, config.step)
    checkpoints = set(checkpoints)
    if 0 in checkpoints:
        run.positions[0] = state.x.copy()

    def record():
        kinetic, elastic, gravity = integ.energies(state)
        run.energy.append(kinetic + elastic + gravity)
        run.gravity.append(gravity)
        run.max_stretch = max(run.max_stretch, integ.max_stretch(state))

    wall = 0.0
    try:
        record()
    except Exception as exc:  # a kernel that fails on the initial state
        run.blew_up = f"frame 0: {type(exc).__name__}: {exc}"
        return run
    for frame in range(1, config.time.frames + 1):
        t0 = time.perf_counter()
        try:
            for _ in range(config.solver.substeps):
                report = integ.step(state)
                run.newton_iterations += report.newton_iterations
                run.cg_iterations += report.cg_iterations
                run.sweeps += report.sweeps
                run.substeps += report.substeps
        except Exception as exc:  # a solver that fails numerically counts as a blow-up
            run.blew_up = f"frame {frame}: {type(exc).__name__}: {exc}"
            break
        wall += time.perf_counter() - t0
        run.frames_done = frame
        with np.errstate(all="ignore"):
            speed = float(np.sqrt(np.max(np.einsum("ij,ij->i", state.v, state.v))))
            reach = float(np.max(np.abs(state.x)))
        if not (np.all(np.isfinite(state.x)) and math.isfinite(speed)):
            run.blew_up = f"frame {frame}: non-finite"
            break
        if speed > config.solver.max_speed or reach > bound:
            run.blew_up = f"frame {frame}: speed {speed:.3g} m/s, |x| {reach:.3g} m"
            break
        try:
            record()
        except Exception as exc:
            run.blew_up = f"frame {frame}: {type(exc).__name__}: {exc}"
            break
        if frame in checkpoints:
            run.positions[frame] = state.x.copy()
    run.wall_per_frame = wall / max(run.frames_done, 1)
    return run


def position_error(run, reference):
    """Largest RMS vertex distance (m) over the checkpoints both runs recorded; inf if
    the run stopped before one of them."""
    worst = 0.0
    for frame, x_ref in reference.positions.items():
        if frame not in run.positions:
            return math.inf
        d = run.positions[frame] - x_ref
        worst = max(worst, float(np.sqrt(np.mean(np.einsum("ij,ij->i", d, d)))))
    return worst
