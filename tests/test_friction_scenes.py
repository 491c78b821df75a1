"""Friction inside the implicit solve against Coulomb's closed forms, on every kind of surface
(the scenes are in ``benchmarks/friction_scenes.py``, shared with the benchmark)."""

import numpy as np
import pytest

from benchmarks.friction_scenes import (G, SETTLE, SURFACES, incline_motion, incline_scene,
                                        turning_sphere)
from clothtool.io.ply import read_ply
from clothtool.sim.api import simulate


@pytest.mark.parametrize("surface", SURFACES)
@pytest.mark.parametrize("degrees", [15, 30, 45])
def test_static_friction_holds_above_tan_theta(tmp_path, surface, degrees):
    theta = np.radians(degrees)
    travel, _ = incline_motion(tmp_path, surface, theta, np.tan(theta) + 0.03, 2.0)
    assert abs(travel) < 1e-3, travel


@pytest.mark.parametrize("surface", SURFACES)
@pytest.mark.parametrize("degrees", [15, 30, 45])
def test_kinetic_friction_slides_at_the_closed_form(tmp_path, surface, degrees):
    theta = np.radians(degrees)
    mu = np.tan(theta) - 0.1
    _, accel = incline_motion(tmp_path, surface, theta, mu, 1.0)
    assert accel == pytest.approx(G * (np.sin(theta) - mu * np.cos(theta)), rel=0.02)


@pytest.mark.parametrize("surface", ["plane", "cloth"])
@pytest.mark.parametrize("degrees", [15, 30])
def test_slow_slip_bound_holds_and_slides_at_the_closed_forms(tmp_path, surface, degrees):
    """With ``solver.slow_slip_bound`` (slips slower than 0.3 mm/s take the bound's
    curvature), μ = tan θ + 0.03 holds and μ = tan θ − 0.1 slides at g(sin θ − μ cos θ)."""
    _holds_and_slides(tmp_path, surface, np.radians(degrees), {"slow_slip_bound": 3e-4})


@pytest.mark.parametrize("preconditioner, tolerance", [("hybrid", 1e-6), ("multigrid", 5e-7)])
def test_the_slide_does_not_depend_on_the_linear_solve(tmp_path, preconditioner, tolerance):
    """With ``solver.short_step_forcing`` the 15° cloth slide with ``solver.slow_slip_bound``
    is at its closed form under other preconditioners and PCG tolerances: they change each
    solve's path, not the answer. Without it Eisenstat–Walker's forcing stays at its cap after
    line-search-shortened steps, Newton crawls to its cap of steps at one stick–slip step and
    brakes the sheet: 0.555 m/s² under ``hybrid``, 0.843 under ``multigrid`` at 5e-7, for the
    closed form's 0.948."""
    theta, mu = np.radians(15), np.tan(np.radians(15)) - 0.1
    solver = {"slow_slip_bound": 3e-4, "preconditioner": preconditioner, "tolerance": tolerance,
              "short_step_forcing": True}
    _, accel = incline_motion(tmp_path, "cloth", theta, mu, 1.0, solver)
    assert accel == pytest.approx(G * (np.sin(theta) - mu * np.cos(theta)), rel=0.02)


@pytest.mark.parametrize("surface", ["plane", "cloth"])
@pytest.mark.parametrize("degrees", [15, 30, 45])
def test_friction_velocity_test_holds_and_slides_at_the_closed_forms(tmp_path, surface,
                                                                     degrees):
    """With ``solver.friction_velocity_test`` (IPC's convergence test while friction is
    lagged), μ = tan θ + 0.03 holds and μ = tan θ − 0.1 slides at g(sin θ − μ cos θ)."""
    _holds_and_slides(tmp_path, surface, np.radians(degrees), {"friction_velocity_test": True})


def _holds_and_slides(tmp_path, surface, theta, solver):
    """Under the ``solver`` keys, μ = tan θ + 0.03 holds (travel under 1 mm in 2 s) and
    μ = tan θ − 0.1 slides at g(sin θ − μ cos θ) within 2 %."""
    (tmp_path / "hold").mkdir()
    (tmp_path / "slide").mkdir()
    travel, _ = incline_motion(tmp_path / "hold", surface, theta, np.tan(theta) + 0.03, 2.0,
                               solver)
    assert abs(travel) < 1e-3, travel
    mu = np.tan(theta) - 0.1
    _, accel = incline_motion(tmp_path / "slide", surface, theta, mu, 1.0, solver)
    assert accel == pytest.approx(G * (np.sin(theta) - mu * np.cos(theta)), rel=0.02)


def _incline(folder, surface, theta, mu, seconds, solver):
    """(the SimulationResult, the frames' vertices) of an incline scene."""
    folder.mkdir()
    config, _, _ = incline_scene(folder, surface, theta, mu, seconds, solver=solver)
    result = simulate(config, progress=False)
    return result, [read_ply(p).vertices for p in sorted((folder / "out").glob("frame_*.ply"))]


@pytest.mark.parametrize("surface", ["plane", "cloth"])
def test_friction_velocity_test_takes_fewer_newton_steps_at_stick(tmp_path, surface):
    """At 45° with μ = tan θ + 0.03 the sheet sticks at the edge of slipping: each Newton step
    is within the tolerance in velocity while the stick stiffness 2μλ/(ĥε_v) keeps its
    decrement large. With ``solver.friction_velocity_test`` Newton stops there (264 → 180
    Newton steps on the plane, 269 → 198 on cloth) and the sheet still holds."""
    theta = np.radians(45)
    mu, seconds = np.tan(theta) + 0.03, SETTLE + 2.0
    default, _ = _incline(tmp_path / "default", surface, theta, mu, seconds, None)
    ipc, frames = _incline(tmp_path / "ipc", surface, theta, mu, seconds,
                           {"friction_velocity_test": True})
    assert ipc.newton_iterations < 0.8 * default.newton_iterations, (
        ipc.newton_iterations, default.newton_iterations)
    settled = int(round(SETTLE * 30))
    top = frames[0].shape[0] - 64  # the 8 × 8 upper sheet is last (or alone)
    assert np.max(np.abs(frames[-1][top:] - frames[settled][top:])) < 1e-3


def test_friction_velocity_test_leaves_frictionless_contact_alone(tmp_path):
    """Without friction no pair is lagged: the option leaves every step as it was, bit for
    bit (a frictionless sheet sliding down a 30° sheet of cloth)."""
    theta = np.radians(30)
    default, a = _incline(tmp_path / "default", "cloth", theta, 0.0, 1.0, None)
    ipc, b = _incline(tmp_path / "ipc", "cloth", theta, 0.0, 1.0,
                      {"friction_velocity_test": True})
    assert ipc.newton_iterations == default.newton_iterations
    assert len(a) == len(b) == 31
    assert all(np.array_equal(p, q) for p, q in zip(a, b))


def test_cloth_turns_with_a_turning_sphere(tmp_path):
    """Codimensional IPC's test, smaller: μ 0.4, the sphere turning at 180°/s about the
    vertical; after a second the cloth turns with it."""
    spin, omega, _ = turning_sphere(tmp_path, n=10, width=0.8, seconds=1.5)
    assert np.mean(spin[-10:]) == pytest.approx(omega, rel=0.03)
