"""`clothtool simulate`: exit codes, one-line errors, -o and --set."""

import re
import textwrap

import pytest
from conftest import EXAMPLE_CONFIG

from click.testing import CliRunner

from clothtool.cli import main


def write_config(tmp_path, extra=""):
    path = tmp_path / "sheet.yaml"
    path.write_text(textwrap.dedent("""
        mesh: {grid: {nx: 5, ny: 5, plane: xz}}
        scene: {pins: [top_corners]}
        time: {frames: 3}
        output: {dir: from_config}
    """) + extra)
    return path


def test_simulate_writes_frames_where_asked(tmp_path, monkeypatch):
    path = write_config(tmp_path)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, ["simulate", str(path), "-o", "here", "--set", "time.frames=2"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "here").iterdir()) == [
        "config.yaml", "frame_00000.ply", "frame_00001.ply", "frame_00002.ply", "stats.csv"]
    assert "time: {frames: 2}" in (tmp_path / "here" / "config.yaml").read_text()  # as run
    assert "3 frames in here/" in result.output
    # without -o: output.dir, relative to the config's folder
    result = CliRunner().invoke(main, ["simulate", str(path), "--quiet"])
    assert result.exit_code == 0 and result.output == ""
    assert (tmp_path / "from_config" / "frame_00003.ply").exists()


def test_bad_config_is_one_line_and_exit_2(tmp_path):
    path = write_config(tmp_path, "material: {strech: 1.0}\n")
    result = CliRunner().invoke(main, ["simulate", str(path)])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0
    assert "unknown key 'material.strech' (did you mean 'stretch'?)" in result.output
    assert "Traceback" not in result.output


def test_bad_set_is_exit_2(tmp_path):
    result = CliRunner().invoke(main, ["simulate", str(write_config(tmp_path)), "--set", "stretch"])
    assert result.exit_code == 2 and "expected dotted.key=value" in result.output


def test_blow_up_is_exit_3_naming_the_frame(tmp_path):
    path = write_config(tmp_path, "solver: {max_speed: 0.05}\n")
    result = CliRunner().invoke(main, ["simulate", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 3
    assert "blew up at frame 1" in result.output
    assert (tmp_path / "out" / "frame_00000.ply").exists()


def test_output_path_that_is_a_file_is_exit_2(tmp_path):
    (tmp_path / "taken").write_text("x")
    result = CliRunner().invoke(main, ["simulate", str(write_config(tmp_path)), "-o", str(tmp_path / "taken")])
    assert result.exit_code == 2 and "not a folder" in result.output


@pytest.mark.parametrize("method", ["explicit", "xpbd"])
def test_the_spec_example_config_runs(tmp_path, method):
    """The documented example config starts with the sphere inside the upright sheet. The
    methods without barrier contact push the vertices onto the sphere, making zero-area hinges,
    which bend nothing instead of dividing by zero."""
    path = tmp_path / "spec.yaml"
    path.write_text(EXAMPLE_CONFIG.replace("METHOD", method))
    result = CliRunner().invoke(main, ["simulate", str(path), "-q"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "frame_00004.ply").exists()


def test_the_spec_example_starting_inside_the_sphere_is_refused_by_barrier_contact(tmp_path):
    """The implicit method keeps every frame intersection-free, so a start with a triangle
    through the sphere is refused, naming the triangle and the collider, with nothing written."""
    path = tmp_path / "spec.yaml"
    path.write_text(EXAMPLE_CONFIG.replace("METHOD", "implicit"))
    result = CliRunner().invoke(main, ["simulate", str(path), "-q"])
    assert result.exit_code == 2
    assert re.fullmatch(r"clothtool: error: the initial state is not intersection-free: cloth "
                        r"triangle \d+ crosses scene.colliders\[0\].sphere\n", result.output)
    assert not (tmp_path / "out").exists()
