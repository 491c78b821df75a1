"""Warp/weft materials: per-direction stiffness (material.stretch: [k_u, k_v]) and
Baraff–Witkin's rest length factors (material.rest_stretch: [b_u, b_v]), end to end."""

import h5py
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.sim.model.config import load_config
from clothtool.sim.model.methods import make_integrator
from clothtool.sim.model.builder import build_model


@pytest.mark.parametrize("method,solver", [
    ("implicit", {"newton_iterations": 5}),
    ("vbd", {"iterations": 20}),
    ("mass-spring", {"newton_iterations": 5}),
])
def test_a_free_sheet_settles_to_its_rest_stretch(tmp_path, method, solver):
    """Zero gravity, rest_stretch [1.1, 1.0]: the sheet grows to λ_u = 1.1, λ_v = 1.0,
    measured by ``analyze --reference uv``; the larger principal stretch points along u."""
    cfg = {"mesh": {"grid": {"nx": 6, "ny": 6, "plane": "xy"}},
           "material": {"stretch": 2000.0, "shear": 50.0, "bend": 0.0, "damping": 0.05,
                        "rest_stretch": [1.1, 1.0]},
           "scene": {"gravity": [0, 0, 0], "pins": []},
           "solver": {"method": method, **solver},
           "time": {"fps": 30, "frames": 30}, "output": {"dir": "out"}}
    (tmp_path / "sheet.yaml").write_text(yaml.safe_dump(cfg))
    runner = CliRunner()
    result = runner.invoke(main, ["simulate", str(tmp_path / "sheet.yaml"), "-q"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(main, ["analyze", str(tmp_path / "out"), "-o", str(tmp_path / "a.h5"),
                                  "--reference", "uv", "-q"])
    assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "a.h5") as f:
        stretch = f["face/stretch"][-1]  # (faces, 2): λ1 ≥ λ2 of the last pair
        direction = f["face/directions"][-1]  # (faces, 2, 3), in the reference (uv) plane
        first = f["face/stretch"][0]
    np.testing.assert_allclose(first, 1.0, atol=1e-6)  # frame 0 is the uv rest state
    np.testing.assert_allclose(stretch[:, 0], 1.1, atol=1e-3)
    np.testing.assert_allclose(stretch[:, 1], 1.0, atol=1e-3)
    np.testing.assert_allclose(np.abs(direction[:, 0, 0]), 1.0, atol=1e-3)  # λ1 along u


def hanging_strain(stretch, method="implicit"):
    """Mean strain along v (down) of a 1 m sheet hanging from its top edge, settled."""
    cfg = load_config({"mesh": {"grid": {"nx": 9, "ny": 9, "plane": "xy"}},
                       "material": {"stretch": stretch, "shear": 5.0, "bend": 0.0,
                                    "damping": 0.05},
                       "scene": {"pins": ["top_edge"]},
                       "solver": {"method": method, "newton_iterations": 4}})
    model = build_model(cfg)
    integrator = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    for _ in range(60):
        integrator.step(state)
    column = np.arange(4, 81, 9)  # the middle column, bottom to top
    return np.linalg.norm(state.x[column[-1]] - state.x[column[0]]) - 1.0


def test_the_stiffer_direction_strains_ten_times_less():
    """Hanging from its top edge, the sheet is loaded along v: with the weft (v) ten times
    stiffer than the warp it strains about ten times less than with the stiffnesses swapped."""
    soft = hanging_strain([500.0, 50.0])
    stiff = hanging_strain([50.0, 500.0])
    assert 0.01 < soft < 0.1
    assert soft / stiff == pytest.approx(10.0, rel=0.1)
    # the warp stiffness alone hardly matters to a load along v
    assert hanging_strain([5000.0, 50.0]) == pytest.approx(soft, rel=0.05)


def test_spring_rest_lengths_follow_the_rest_stretch():
    """A spring (Δu, Δv) of the rest uv rests at ‖(b_u Δu, b_v Δv)‖; axis springs get k_u and k_v."""
    cfg = load_config({"mesh": {"grid": {"nx": 4, "ny": 4, "plane": "xz"}},
                       "material": {"stretch": [1000.0, 3000.0], "rest_stretch": [1.2, 0.9],
                                    "bend": 0.0},
                       "solver": {"method": "mass-spring"}})
    model = build_model(cfg)
    sp = model.springs
    d = model.mesh.rest3d[sp.j] - model.mesh.rest3d[sp.i]
    np.testing.assert_allclose(sp.rest, np.hypot(1.2 * d[:, 0], 0.9 * d[:, 1]), rtol=1e-14)
    along_u = np.abs(d[:, 1]) < 1e-12
    along_v = np.abs(d[:, 0]) < 1e-12
    spacing = 1.0 / 3
    area = spacing * spacing  # an interior axis edge has two half-cells on its sides
    interior_u = along_u & np.isclose(sp.k, sp.k[along_u].max())
    assert sp.k[interior_u][0] == pytest.approx(1000.0 * area / spacing**2, rel=1e-12)
    assert sp.k[along_v].max() == pytest.approx(3000.0 * area / spacing**2, rel=1e-12)


def test_warp_weft_without_uv_is_refused(tmp_path):
    from clothtool.io.ply import write_ply

    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.1]], float)
    write_ply(tmp_path / "tri.ply", x, np.array([[0, 1, 2]]))
    cfg = load_config({"mesh": {"ply": str(tmp_path / "tri.ply")},
                       "material": {"rest_stretch": [1.1, 1.0]}})
    with pytest.raises(InputError, match="material.rest_stretch: different warp and weft"):
        build_model(cfg)
