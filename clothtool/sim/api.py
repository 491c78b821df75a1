"""``clothtool.simulate``: config → PLY frames and statistics."""

import statistics
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from clothtool.errors import InputError, NumericalError
from clothtool.sim.model.config import Config, load_config


@dataclass
class SimulationResult:
    output_dir: Path
    frames_written: int
    steps: int
    newton_iterations: int
    cg_iterations: int
    max_stretch: float
    wall_s: float
    sweeps: int = 0
    substeps: int = 0
    first_step_s: float = 0.0  # the first solver step, which includes compiling the kernels
    step_s: list = field(default_factory=list)  # wall time of every later solver step
    notes: list = field(default_factory=list)  # what the run found and did (the log's lines)

    def describe(self):
        steps = max(self.steps, 1)
        timing = f"compile+first step {self.first_step_s:.2f} s"
        if self.step_s:
            timing += (f", then {1000.0 * statistics.median(self.step_s):.1f} ms/step median, "
                       f"{1000.0 * statistics.fmean(self.step_s):.1f} mean")
        work = [f"{self.newton_iterations / steps:.1f} Newton, {self.cg_iterations / steps:.1f} "
                f"CG iterations/step" if self.newton_iterations else "", f"{self.sweeps / steps:.0f} sweeps/step" if self.sweeps else "",
                f"{self.substeps / steps:.0f} internal steps/step" if self.substeps else ""]
        return (f"{self.frames_written} frames in {self.output_dir}/ ({self.steps} steps; {timing}; "
                + ", ".join(w for w in work if w) + (", " if any(work) else "")
                + f"max stretch {self.max_stretch:.4f})")


def simulate(config_or_path, *, output_dir=None, overrides=None, progress=True, log=None):
    """Run a simulation and write its frames; returns a :class:`SimulationResult`.

    ``config_or_path``: a YAML path, a dict, or a loaded :class:`Config`.
    ``output_dir`` overrides ``output.dir`` (relative to the current folder).
    ``overrides``: dotted keys → values, as in :func:`~clothtool.sim.model.config.load_config`.
    ``log``: called with each line of what the run finds and does (the seams welded at the
    start, the sewing's stiffness), as it happens; the lines are also the result's ``notes``.
    Raises :class:`~clothtool.errors.InputError` for a bad config or output path and
    :class:`~clothtool.errors.NumericalError` when the run blows up; frames
    written before that stay valid.
    """
    from tqdm import tqdm

    from clothtool.sim.model.builder import ModelBuilder
    from clothtool.sim.solve.integrator import StepReport
    from clothtool.sim.model.methods import make_integrator
    from clothtool.sim.output import CONTACT_COLUMNS, STATS_COLUMNS, ColliderTrack, FrameWriter
    from clothtool.sim.model.seams import (check_sewing, sewing_gap_text, sewn, stitch_level,
                                           tighten)

    if isinstance(config_or_path, Config):
        if overrides:
            raise TypeError("overrides need a config path or dict, not a loaded Config")
        config = config_or_path
    else:
        config = load_config(config_or_path, overrides=overrides)
    out_dir = Path(output_dir) if output_dir is not None else config.output.dir
    notes = []

    def note(line):
        notes.append(line)
        if log is not None:
            log(line)

    builder = ModelBuilder.from_config(config)
    model = builder.finalize()
    raised = False  # has the sewing raised the stitch stiffness
    refused = None  # the first frame whose weld failed the welded start's check
    # frames keep the file's vertices and faces, after a weld too
    written_mesh = model.mesh if builder.file_mesh is None else builder.file_mesh
    for a, b, count, length in builder.closed_seams:
        note(f"mesh: welded the closed seam {a}–{b} at the start: {count} vertex pairs, "
             f"{length:.4g} m (mesh.weld_closed, mesh.weld_tolerance "
             f"{config.mesh.weld_tolerance:g} m)")
    for key, a, b, closed, count in builder.listed_closed:
        sides = f" ({a}–{b})" if isinstance(a, str) and isinstance(b, str) else ""
        note(f"{key}{sides}: already closed in the file, " + (
            f"all {count} vertex pairs welded at the start: nothing to sew" if closed == count
            else f"{closed} of its {count} vertex pairs welded at the start, the others sewn"))
    integrator = make_integrator(model, config.solver, config.step)
    state = model.initial_state()
    frames, every, substeps = config.time.frames, config.output.every, config.solver.substeps
    max_speed = config.solver.max_speed
    totals = StepReport()
    written, worst_stretch = 0, 0.0
    step_times = []
    started = time.perf_counter()

    contact = getattr(integrator, "contact", None)
    columns = STATS_COLUMNS + (CONTACT_COLUMNS if contact is not None else ())
    usd = "usd" in config.output.format
    gravity = np.asarray(config.scene.gravity, float)
    with FrameWriter(out_dir, written_mesh.faces, written_mesh.uv, columns,
                     formats=config.output.format, corner_uv=written_mesh.corner_uv,
                     fps=config.time.fps, panels=written_mesh.groups,
                     up="Z" if abs(gravity[2]) > abs(gravity[1]) else "Y",
                     colliders=ColliderTrack(config, written_mesh.positions)
                     if usd and config.scene.colliders else None) as writer:

        def record(frame, report, wall):
            nonlocal written, worst_stretch
            kinetic, elastic, gravity = integrator.energies(state)
            stretch = integrator.max_stretch(state)
            worst_stretch = max(worst_stretch, stretch)
            if contact is not None:  # the exact test: no frame with a crossing is written
                contact.check_frame(state.x, state.time, frame, out_dir)
            writer.write_frame(frame, state.x if model.file_vertex is None
                               else state.x[model.file_vertex], state.time)
            writer.write_stats(dict(
                frame=frame, time=state.time, kinetic=kinetic, elastic=elastic, gravity=gravity,
                newton_iterations=report.newton_iterations, cg_iterations=report.cg_iterations,
                residual=report.residual, max_stretch=stretch, wall_s=wall, sweeps=report.sweeps,
                substeps=report.substeps, contacts=report.contacts,
                min_separation=report.min_separation))
            written += 1

        record(0, StepReport(), 0.0)
        _write_config(config, out_dir)  # once the start has passed its checks
        bar = tqdm(range(1, frames + 1), desc="simulate", unit="frame", file=sys.stderr,
                   disable=not (progress and sys.stderr.isatty()))
        for frame in bar:
            t0 = time.perf_counter()
            report = StepReport()
            for _ in range(substeps):
                s0 = time.perf_counter()
                try:
                    report.add(integrator.step(state))
                except NumericalError as exc:
                    raise NumericalError(_blowup(frame, str(exc), out_dir)) from None
                step_times.append(time.perf_counter() - s0)
                speed = _max_speed(state.v)
                if not (np.all(np.isfinite(state.x)) and speed <= max_speed):
                    what = ("non-finite positions or velocities" if not np.isfinite(speed)
                            else f"velocities exploded (max speed {speed:.3g} m/s > solver.max_speed "
                                 f"{max_speed:g})")
                    raise NumericalError(_blowup(frame, what, out_dir))
            totals.add(report)
            if model.stitches is not None:  # sewing: weld once every seam pair is close
                welded = _weld(builder, model, state, config) if sewn(model, state.x,
                                                                      builder) else None
                if isinstance(welded, str):  # its welded start would cross: sew on
                    if refused is None:
                        refused = frame
                        note(f"mesh.seams: sewn at frame {frame} but not welded: the welded "
                             f"garment's start fails the contact's check ({welded}); sewing "
                             "on until it passes")
                    if state.time >= config.mesh.sewing.time:
                        raise NumericalError(
                            f"simulation failed at frame {frame}: mesh.seams sewn since frame "
                            f"{refused} but not welded in mesh.sewing.time "
                            f"({config.mesh.sewing.time:g} s): the welded garment's start "
                            f"fails the contact's check ({welded})")
                elif welded is not None:
                    note(f"mesh.seams: sewn and welded at frame {frame} (t = {state.time:.3g} s)"
                         + (f", the stitch stiffness raised to {stitch_level(builder):.3g} N/m "
                            "per metre of seam" if raised else ""))
                    builder, state, model, integrator = welded
                    contact = integrator.contact
                else:
                    if state.time >= config.mesh.sewing.time:
                        note(f"mesh.seams: not closed at frame {frame}: "
                             f"{sewing_gap_text(model, state.x)}, the stitch stiffness raised to "
                             f"{stitch_level(builder):.3g} N/m per metre of seam")
                    check_sewing(model, state.x, state.time, builder, frame)
                    if tighten(model, state.x, state.time, builder) is not None:
                        raised = True  # behind the goal: stiffer stitches, the same state
                        model = builder.finalize()
                        integrator = make_integrator(model, config.solver, config.step)
                        contact = integrator.contact
            if frame % every == 0:
                record(frame, report, time.perf_counter() - t0)
        bar.close()

    return SimulationResult(out_dir, written, frames * substeps, totals.newton_iterations,
                            totals.cg_iterations, worst_stretch, time.perf_counter() - started,
                            sweeps=totals.sweeps, substeps=totals.substeps,
                            first_step_s=step_times[0] if step_times else 0.0,
                            step_s=step_times[1:], notes=notes)


def _weld(builder, model, state, config):
    """(builder, state, model, integrator) of the garment welded from ``state``, or why its
    welded start fails the contact's start check (a crossing, or a pair inside the barrier's
    wall): each sewn pair jumps to its mean, which can carry a triangle through a surface the
    barrier holds a wall's depth away."""
    from clothtool.sim.model.methods import make_integrator

    welded, start = builder.welded(model, state.copy())
    welded_model = welded.finalize()
    try:
        integrator = make_integrator(welded_model, config.solver, config.step)
    except InputError as exc:
        return str(exc)
    return welded, start, welded_model, integrator


def _write_config(config, out_dir):
    """The resolved config as ``out_dir``/config.yaml (atomic), which ``clothtool render`` and
    ``clothtool simulate`` read back; not when the run's own config is that file (a sweep's
    run folder)."""
    from clothtool.io.atomic import atomic_path
    from clothtool.sim.model.config import resolved_yaml
    from clothtool.sim.scene import RUN_CONFIG

    path = Path(out_dir) / RUN_CONFIG
    if config.source is not None and path.resolve() == Path(config.source).resolve():
        return
    ran = replace(config, output=replace(config.output, dir=Path(out_dir)))
    with atomic_path(path) as tmp:
        Path(tmp).write_text("# clothtool simulate: the resolved config of the frames beside it\n"
                             + resolved_yaml(ran), encoding="utf-8")


def _max_speed(v):
    speed2 = np.einsum("ij,ij->i", v, v)
    return float(np.sqrt(speed2.max())) if len(speed2) else 0.0


def _blowup(frame, what, out_dir):
    kept = f"frames before it are in {out_dir}" if frame > 1 else f"only the initial frame is in {out_dir}"
    return f"simulation blew up at frame {frame}: {what}; {kept}"
