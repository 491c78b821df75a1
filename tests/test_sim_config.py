"""Simulation config: defaults, paths, and one-line errors that name the key."""

import textwrap
from pathlib import Path

import numpy as np
import pytest

from clothtool.errors import InputError
from clothtool.sim.model.config import load_config
from clothtool.sim.model.builder import build_model
from clothtool.sim.model.pins import grid_pin_set

GRID = {"mesh": {"grid": {"nx": 4, "ny": 3}}}


def write(tmp_path, text):
    path = tmp_path / "cfg.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def error_of(config, **kw):
    with pytest.raises(InputError) as info:
        build_model(load_config(config, **kw))
    message = str(info.value)
    assert "\n" not in message
    return message


def test_defaults_and_relative_paths(tmp_path):
    path = write(tmp_path, """
        mesh: {grid: {nx: 5, ny: 4, plane: xz}}
        output: {dir: frames}
    """)
    cfg = load_config(path)
    assert cfg.material.stretch == 5000.0 and cfg.material.bend_model == "hessian"
    assert cfg.solver.integrator == "bdf2" and cfg.solver.newton_iterations == 20
    assert cfg.solver.newton_tolerance == 0.04 and cfg.time.fps == 30
    assert cfg.output.dir == tmp_path / "frames"
    assert cfg.step == pytest.approx(1 / 30)


def test_numbers_without_a_dot_are_numbers(tmp_path):
    # PyYAML reads 1e5 as a string; stiffnesses are still taken as numbers
    cfg = load_config(write(tmp_path, "mesh: {grid: {}}\nmaterial: {stretch: 1e5}\n"))
    assert cfg.material.stretch == 1e5


@pytest.mark.parametrize("text, expected", [
    ("mesh: {grid: {}}\nmaterial: {strech: 10}\n", "unknown key 'material.strech' (did you mean 'stretch'?)"),
    ("mesh: {grid: {}}\nmaterail: {}\n", "unknown key 'materail' (did you mean 'material'?)"),
    ("mesh: {grid: {}}\nmaterial: {stretch: abc}\n", "material.stretch must be a number, got 'abc'"),
    ("mesh: {grid: {nx: 2.5}}\n", "mesh.grid.nx must be an integer"),
    ("mesh: {grid: {}}\nmaterial: {density: -0.2}\n", "material.density must be > 0"),
    ("mesh: {grid: {nx: 1}}\n", "mesh.grid.nx must be ≥ 2, got 1"),
    ("mesh: {grid: {}}\ntime: {fps: 0}\n", "time.fps must be > 0"),
    ("mesh: {grid: {plane: xw}}\n", "mesh.grid.plane must be one of xy, xz, yz"),
    ("mesh: {grid: {}}\nscene: {gravity: [0, -9.81]}\n", "scene.gravity must be a list of 3 numbers"),
    ("mesh: {grid: {}}\nscene: {pins: [top_corner]}\n", "scene.pins[0]: unknown pin set 'top_corner' (did you mean 'top_corners'?)"),
    ("mesh: {grid: {}}\nscene: {colliders: [{cube: {}}]}\n", "scene.colliders[0]: unknown collider 'cube'"),
    ("mesh: {grid: {}}\nscene: {colliders: [{sphere: {radius: 0}}]}\n", "scene.colliders[0].sphere.radius must be > 0"),
    ("mesh: {grid: {}}\nsolver: {substeps: true}\n", "solver.substeps must be an integer, got True"),
    ("material: {}\n", "missing section 'mesh'"),
    ("mesh: {grid: {}, ply: a.ply}\n", "exactly one of mesh.grid, mesh.ply and mesh.obj"),
])
def test_bad_values_name_the_key(tmp_path, text, expected):
    path = write(tmp_path, text)
    message = error_of(path)
    assert message.startswith(str(path) + ": ")
    assert expected in message


def test_pin_index_out_of_range_names_the_entry():
    message = error_of({**GRID, "scene": {"pins": ["top_corners", 12]}})
    assert "scene.pins[1]: vertex index 12 out of range (the mesh has 12 vertices)" in message


def test_yaml_syntax_error_gives_the_line(tmp_path):
    path = write(tmp_path, """
        mesh:
          grid: {nx: 4, ny: 4
        material: {}
    """)
    message = error_of(path)
    assert message.startswith(f"{path}: line ")
    assert "YAML syntax error" in message
    line = int(message.split("line ")[1].split(",")[0])
    assert line in (3, 4)


def test_missing_config_file(tmp_path):
    assert "config file not found" in error_of(tmp_path / "nope.yaml")


def test_ply_mesh_path_is_relative_to_the_config(tmp_path):
    message = error_of(write(tmp_path, "mesh: {ply: rest.ply}\n"))
    assert str(tmp_path / "rest.ply") in message


def test_overrides_apply_before_validation():
    cfg = load_config(GRID, overrides={"material.stretch": "2e4", "time.frames": 3})
    assert cfg.material.stretch == 2e4 and cfg.time.frames == 3
    with pytest.raises(InputError, match="unknown key 'solver.tolerence'"):
        load_config(GRID, overrides={"solver.tolerence": "1e-3"})


def test_quadratic_bending_needs_a_flat_rest_state(tmp_path):
    from clothtool.io.ply import write_ply

    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]], float)
    write_ply(tmp_path / "bent.ply", verts, np.array([[0, 1, 2], [1, 3, 2]]))
    path = write(tmp_path, "mesh: {ply: bent.ply}\nmaterial: {bend_model: quadratic}\n")
    assert "needs a flat rest state" in error_of(path)


def test_named_pin_sets_follow_the_spec_layout():
    nx, ny = 4, 3
    assert list(grid_pin_set("top_corners", nx, ny)) == [8, 11]
    assert list(grid_pin_set("top_edge", nx, ny)) == [8, 9, 10, 11]
    assert list(grid_pin_set("left_edge", nx, ny)) == [0, 4, 8]
    assert list(grid_pin_set("corners", nx, ny)) == [0, 3, 8, 11]
    model = build_model(load_config({**GRID, "scene": {"pins": ["top_corners", 5, 8]}}))
    assert list(model.pinned) == [5, 8, 11]
    assert not model.free[[5, 8, 11]].any() and model.free.sum() == 9


def test_grid_layout_and_rest_coordinates():
    model = build_model(load_config({"mesh": {"grid": {"nx": 3, "ny": 2, "width": 2.0,
                                                       "height": 1.0, "plane": "xz"}}}))
    x = model.mesh.positions
    np.testing.assert_allclose(x[0], [-1, 0, -0.5])
    np.testing.assert_allclose(x[5], [1, 0, 0.5])  # j = ny − 1 is the top row, index j·nx + i
    np.testing.assert_allclose(model.area.sum(), 2.0)
    np.testing.assert_allclose(model.mass.sum(), 2.0 * 0.2)
    np.testing.assert_allclose(model.mesh.uv[5], [1, 0.5])


def test_scene_without_extras_builds_no_extra_terms():
    model = build_model(load_config({**GRID, "material": {"bend": 0.0, "damping": 0.0}}))
    assert model.bend_model is None and len(model.hinge) == 0
    assert not model.has_pins and not model.has_colliders
    # the pattern holds only the triangle couplings
    bent = build_model(load_config(GRID))
    assert model.pattern.nnzb < bent.pattern.nnzb


def test_example_from_the_spec_loads(tmp_path):
    spec_example = Path(__file__).resolve().parents[1] / "sample_data" / "hanging_sheet.yaml"
    cfg = load_config(spec_example)
    assert cfg.scene.pins == ("top_corners",)
