"""Friction inside the implicit solve against Coulomb's closed forms, on every kind of surface
(the scenes are in ``benchmarks/friction_scenes.py``, shared with the benchmark)."""

import numpy as np
import pytest

from benchmarks.friction_scenes import G, SURFACES, incline_motion, turning_sphere


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


def test_cloth_turns_with_a_turning_sphere(tmp_path):
    """Codimensional IPC's test, smaller: μ 0.4, the sphere turning at 180°/s about the
    vertical; after a second the cloth turns with it."""
    spin, omega, _ = turning_sphere(tmp_path, n=10, width=0.8, seconds=1.5)
    assert np.mean(spin[-10:]) == pytest.approx(omega, rel=0.03)
