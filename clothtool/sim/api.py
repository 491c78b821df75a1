"""``clothtool.simulate``: config → PLY frames and statistics."""

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clothtool.errors import NumericalError
from clothtool.sim.config import Config, load_config


@dataclass
class SimulationResult:
    output_dir: Path
    frames_written: int
    steps: int
    newton_iterations: int
    cg_iterations: int
    max_stretch: float
    wall_s: float

    def describe(self):
        per_step = 1000.0 * self.wall_s / max(self.steps, 1)
        return (f"{self.frames_written} frames in {self.output_dir}/ ({self.steps} steps, "
                f"{per_step:.1f} ms/step, {self.cg_iterations / max(self.steps, 1):.1f} CG "
                f"iterations/step, max stretch {self.max_stretch:.4f})")


def simulate(config_or_path, *, output_dir=None, overrides=None, progress=True):
    """Run a simulation and write its frames; returns a :class:`SimulationResult`.

    ``config_or_path``: a YAML path, a dict, or a loaded :class:`Config`.
    ``output_dir`` overrides ``output.dir`` (relative to the current folder).
    ``overrides``: dotted keys → values, as in :func:`~clothtool.sim.config.load_config`.
    Raises :class:`~clothtool.errors.InputError` for a bad config or output path and
    :class:`~clothtool.errors.NumericalError` when the run blows up; frames
    written before that stay valid.
    """
    from tqdm import tqdm

    from clothtool.sim.integrator import StepReport
    from clothtool.sim.model import build_model
    from clothtool.sim.output import FrameWriter
    from clothtool.sim.solvers import make_integrator

    if isinstance(config_or_path, Config):
        if overrides:
            raise TypeError("overrides need a config path or dict, not a loaded Config")
        config = config_or_path
    else:
        config = load_config(config_or_path, overrides=overrides)
    out_dir = Path(output_dir) if output_dir is not None else config.output.dir
    model = build_model(config)
    integrator = make_integrator(model, config.solver, config.step)
    state = model.initial_state()
    frames, every, substeps = config.time.frames, config.output.every, config.solver.substeps
    max_speed = config.solver.max_speed
    totals = StepReport()
    written, worst_stretch = 0, 0.0
    started = time.perf_counter()

    with FrameWriter(out_dir, model.faces, model.mesh.uv) as writer:

        def record(frame, report, wall):
            nonlocal written, worst_stretch
            kinetic, elastic, gravity = integrator.energies(state)
            stretch = integrator.max_stretch(state)
            worst_stretch = max(worst_stretch, stretch)
            writer.write_frame(frame, state.x)
            writer.write_stats(dict(
                frame=frame, time=state.time, kinetic=kinetic, elastic=elastic, gravity=gravity,
                newton_iterations=report.newton_iterations, cg_iterations=report.cg_iterations,
                residual=report.residual, max_stretch=stretch, wall_s=wall))
            written += 1

        record(0, StepReport(), 0.0)
        bar = tqdm(range(1, frames + 1), desc="simulate", unit="frame", file=sys.stderr,
                   disable=not (progress and sys.stderr.isatty()))
        for frame in bar:
            t0 = time.perf_counter()
            report = StepReport()
            for _ in range(substeps):
                try:
                    step = integrator.step(state)
                except NumericalError as exc:
                    raise NumericalError(_blowup(frame, str(exc), out_dir)) from None
                report.newton_iterations += step.newton_iterations
                report.cg_iterations += step.cg_iterations
                report.residual = max(report.residual, step.residual)
                speed = _max_speed(state.v)
                if not (np.all(np.isfinite(state.x)) and speed <= max_speed):
                    what = ("non-finite positions or velocities" if not np.isfinite(speed)
                            else f"velocities exploded (max speed {speed:.3g} m/s > solver.max_speed "
                                 f"{max_speed:g})")
                    raise NumericalError(_blowup(frame, what, out_dir))
            totals.newton_iterations += report.newton_iterations
            totals.cg_iterations += report.cg_iterations
            if frame % every == 0:
                record(frame, report, time.perf_counter() - t0)
        bar.close()

    return SimulationResult(out_dir, written, frames * substeps, totals.newton_iterations,
                            totals.cg_iterations, worst_stretch, time.perf_counter() - started)


def _max_speed(v):
    speed2 = np.einsum("ij,ij->i", v, v)
    return float(np.sqrt(speed2.max())) if len(speed2) else 0.0


def _blowup(frame, what, out_dir):
    kept = f"frames before it are in {out_dir}" if frame > 1 else f"only the initial frame is in {out_dir}"
    return f"simulation blew up at frame {frame}: {what}; {kept}"
