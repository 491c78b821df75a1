"""`--set` overrides and the default config of `clothtool init-config`."""

import pytest
import yaml
from click.testing import CliRunner

from clothtool.cli import main
from clothtool.config_tools import DEFAULT_CONFIG, apply_overrides
from clothtool.errors import InputError

SPEC_DEFAULTS = {  # the documented example, entry by entry, and the simulator's optional
    # settings; the sheet is horizontal (xz), since an upright one (xy) starts inside the sphere
    "mesh": {"grid": {"nx": 30, "ny": 30, "width": 1.0, "height": 1.0, "plane": "xz"}},
    "material": {"density": 0.2, "stretch": 5000.0, "rest_stretch": 1.0, "shear": 50.0, "bend": 1.0e-5,
                 "damping": 0.01, "bend_model": "hessian", "damping_model": "strain",
                 "bending_length": None, "plate_correction": False, "membrane_model": "triangle",
                 "preset": None, "kes": None},
    "materials": {},
    "scene": {"gravity": [0, -9.81, 0], "pins": ["top_corners"],
              "colliders": [{"sphere": {"center": [0, -0.5, 0], "radius": 0.3}},
                            {"plane": {"point": [0, -1, 0], "normal": [0, 1, 0]}}],
              "collision_margin": 2.0e-3, "activation_distance": None, "self_collision": None,
              "attach": []},
    "solver": {"method": "implicit", "integrator": "bdf2", "substeps": 1, "tolerance": 1.0e-6,
               "max_iterations": 500, "preconditioner": "auto",
               "newton_iterations": 20, "newton_tolerance": 0.04, "friction_velocity": 1.0e-4,
               "overshoot_bound": False, "slow_slip_bound": 0.0, "forcing_from_second": False,
               "short_step_forcing": False, "first_forcing": 0.0,
               "first_cut_iterations": 20, "friction_velocity_test": False,
               "line_search": True, "stiffness_continuation": "auto", "continuation_after": 20,
               "max_speed": 1000.0, "iterations": 10, "pbd_variant": "gauss-seidel",
               "relaxation": 1.0, "pbd_stiffness": 1.0, "strain_limit": 0.0, "cfl": 0.5,
               "chebyshev_rho": 0.9, "vbd_tolerance": 0.0},
    "time": {"fps": 30, "frames": 120},
    "output": {"dir": "out/", "every": 1, "format": ["ply"]},
}


def test_init_config_prints_the_commented_spec_defaults():
    result = CliRunner().invoke(main, ["init-config"])
    assert result.exit_code == 0
    assert result.output == DEFAULT_CONFIG
    assert yaml.safe_load(result.output) == SPEC_DEFAULTS
    for line in DEFAULT_CONFIG.splitlines():  # every scalar setting carries a comment
        if line.startswith("  ") and ":" in line and not line.strip().startswith(("#", "-")) \
                and not line.rstrip().endswith(":") and "grid:" not in line and "gravity" not in line:
            assert "#" in line, line


def test_overrides():
    config = yaml.safe_load(DEFAULT_CONFIG)
    out = apply_overrides(config, ["material.stretch=2e4", "scene.gravity.1=-3.7",
                                   "time.frames=10", "mesh.grid.plane=xz", "solver.substeps=4",
                                   "scene.colliders.0.sphere.radius=0.25", "time.frames=12",
                                   "scene.pins=[0, 5, top_corners]", "extra.new.key=on",
                                   "material.bend=[1e-5, 2E+3, -.5e1]"])
    assert out["material"]["stretch"] == 2e4 and isinstance(out["material"]["stretch"], float)
    assert out["scene"]["gravity"] == [0, -3.7, 0]
    assert out["time"]["frames"] == 12  # later wins
    assert out["mesh"]["grid"]["plane"] == "xz"
    assert out["scene"]["colliders"][0]["sphere"]["radius"] == 0.25
    assert out["scene"]["pins"] == [0, 5, "top_corners"]
    assert out["extra"] == {"new": {"key": True}}  # created; the loader rejects unknown keys
    assert out["material"]["bend"] == [1e-5, 2e3, -5.0]
    assert config == yaml.safe_load(DEFAULT_CONFIG)  # input untouched
    assert apply_overrides({}, ["solver.substeps=2"]) == {"solver": {"substeps": 2}}


@pytest.mark.parametrize("assignment,message", [
    ("material.stretch", "expected dotted.key=value"),
    ("material..stretch=1", "expected dotted.key=value"),
    ("time.fps=", "no value"),
    ("scene.gravity.3=1", "scene.gravity is a list of 3; '3' is not an index"),
    ("time.fps.x=1", "time.fps is 30, not a mapping"),
    ("scene.pins=[1, 2", "not valid YAML|expected"),
])
def test_override_errors_name_the_assignment(assignment, message):
    with pytest.raises(InputError, match=message):
        apply_overrides(yaml.safe_load(DEFAULT_CONFIG), [assignment])



def test_default_config_matches_the_simulator():
    """init-config loads in the simulator and shows every setting of its schema, each with the
    simulator's default (except the example's pins and colliders, and the output path)."""
    import clothtool.sim.model.config as sim

    raw = yaml.safe_load(DEFAULT_CONFIG)
    printed = sim.as_dict(sim.load_config(raw))
    assert set(raw["mesh"]["grid"]) == set(sim.as_dict(sim.GridSpec()))
    for section, cls in sim.SECTIONS.items():
        if section == "mesh":
            continue
        for key, default in sim.as_dict(cls()).items():
            assert key in raw[section], f"{section}.{key} is missing from init-config"
            if (section, key) not in {("scene", "pins"), ("scene", "colliders"), ("output", "dir")}:
                assert printed[section][key] == default, f"{section}.{key}"


def test_override_errors_name_the_keyword_and_the_cli_its_option(tmp_path):
    """The library names its keyword argument (``overrides``), never the CLI's flag; the CLI
    shows the same detail under ``--set``, as it shows ``fields=`` under ``--fields``."""
    from clothtool.sim.model.config import load_config

    for overrides in (["material.stretch"], ["time.fps.x=1"], {"time.fps.x": 1}):
        with pytest.raises(InputError) as caught:
            load_config({"mesh": {"grid": {"nx": 3}}, "time": {"fps": 30}}, overrides=overrides)
        assert caught.value.keyword == "overrides" and "--set" not in str(caught.value)
        assert str(caught.value).startswith("overrides='time.fps.x" if "x" in str(overrides)
                                            else "overrides='material.stretch'")
    config = tmp_path / "c.yaml"
    config.write_text("mesh: {grid: {nx: 3}}\ntime: {fps: 30}\n")
    result = CliRunner().invoke(main, ["simulate", str(config), "--set", "time.fps.x=1"])
    assert result.exit_code == 2
    assert "error: --set 'time.fps.x=1': time.fps is 30, not a mapping" in result.output
