"""Bad simulation configs and a run that blows up, through the CLI.

Every broken config gives exit code 2 and one line naming the key (or the YAML line);
nothing is written. A run that blows up gives exit code 3 naming the frame, and keeps
the frames and ``stats.csv`` rows written before it.
"""

import csv
import os
import signal
import sys


import pytest
from conftest import interrupt_when
from click.testing import CliRunner

from clothtool.cli import main
from clothtool.io.ply import read_ply

GOOD = """\
mesh:
  grid: {nx: 6, ny: 5, width: 1.0, height: 0.8, plane: xz}
material:
  density: 0.2
  stretch: 5000.0
  shear: 50.0
  bend: 1.0e-5
  damping: 0.01
scene:
  gravity: [0, -9.81, 0]
  pins: [top_corners]
  colliders:
    - sphere: {center: [0, -0.5, 0], radius: 0.3}
time:
  fps: 30
  frames: 3
output:
  dir: out
"""


def stretch(value):
    """GOOD with material.stretch set to ``value`` (YAML text)."""
    return GOOD.replace("stretch: 5000.0", f"stretch: {value}")


def rest_stretch(value):
    """GOOD with material.rest_stretch set to ``value`` (YAML text)."""
    return GOOD.replace("damping: 0.01", f"damping: 0.01\n  rest_stretch: {value}")


# name → (config text, text the message must contain)
CONFIGS = {
    "yaml_unclosed_bracket": (GOOD.replace("[0, -9.81, 0]", "[0, -9.81, 0"), "line "),
    "yaml_tab_indent": (GOOD.replace("  density", "\tdensity"), "line 4"),
    "yaml_bad_indent": (GOOD.replace("  shear: 50.0", "    shear: 50.0"), "line "),
    "not_a_mapping": ("- mesh\n- material\n", "mapping"),
    "empty_file": ("", "mesh"),
    "unknown_section": (GOOD.replace("material:", "materail:"), "materail"),
    "misspelled_key": (GOOD.replace("stretch: 5000.0", "strech: 5000.0"), "material.strech"),
    "unknown_grid_key": (GOOD.replace("plane: xz", "plane: xz, depth: 3"), "mesh.grid.depth"),
    "density_not_a_number": (GOOD.replace("density: 0.2", "density: heavy"), "material.density"),
    "frames_not_an_integer": (GOOD.replace("frames: 3", "frames: 2.5"), "time.frames"),
    "gravity_two_numbers": (GOOD.replace("[0, -9.81, 0]", "[0, -9.81]"), "scene.gravity"),
    "gravity_is_text": (GOOD.replace("[0, -9.81, 0]", "down"), "scene.gravity"),
    "section_is_a_list": (GOOD.replace("time:\n  fps: 30\n  frames: 3", "time: [30, 3]"), "time"),
    "negative_density": (GOOD.replace("density: 0.2", "density: -0.2"), "material.density"),
    "negative_stretch": (stretch("-1"), "material.stretch"),
    "stretch_three_values": (stretch("[1, 2, 3]"), "material.stretch"),
    "stretch_negative_weft": (stretch("[5000, -1]"), "material.stretch[1]"),
    "stretch_weft_text": (stretch("[5000, weft]"), "material.stretch[1]"),
    "rest_stretch_zero": (rest_stretch("[0, 1]"), "material.rest_stretch[0]"),
    "rest_stretch_one_value": (rest_stretch("[1.1]"), "material.rest_stretch"),
    "rest_stretch_negative": (rest_stretch("-1"), "material.rest_stretch"),
    "chebyshev_rho_one": (GOOD.replace("time:", "solver: {method: vbd, chebyshev_rho: 1.0}\ntime:"),
                          "solver.chebyshev_rho"),
    "vbd_with_friction": (GOOD.replace("radius: 0.3}", "radius: 0.3, friction: 0.5}")
                          .replace("time:", "solver: {method: vbd}\ntime:"), "friction"),
    "nx_below_two": (GOOD.replace("nx: 6", "nx: 1"), "mesh.grid.nx"),
    "fps_zero": (GOOD.replace("fps: 30", "fps: 0"), "time.fps"),
    "fps_infinite": (GOOD.replace("fps: 30", "fps: .inf"), "time.fps"),
    "negative_radius": (GOOD.replace("radius: 0.3", "radius: -0.3"), "radius"),
    "unknown_collider": (GOOD.replace("- sphere:", "- cube:"), "cube"),
    "unknown_pin_set": (GOOD.replace("[top_corners]", "[top_corner]"), "top_corner"),
    "pin_index_out_of_range": (GOOD.replace("[top_corners]", "[top_corners, 30]"), "30"),
    "negative_pin_index": (GOOD.replace("[top_corners]", "[-1]"), "scene.pins"),
    "no_mesh": (GOOD.split("material:")[0].replace("mesh:\n  grid: {nx: 6, ny: 5, width: 1.0, "
                                                    "height: 0.8, plane: xz}\n", "")
                + "material:" + GOOD.split("material:")[1], "mesh"),
    "grid_and_ply": (GOOD.replace("plane: xz}", "plane: xz}\n  ply: rest.ply"), "mesh"),
    "missing_ply_mesh": (GOOD.replace("grid: {nx: 6, ny: 5, width: 1.0, height: 0.8, plane: xz}",
                                      "ply: nowhere.ply"), "nowhere.ply"),
    "output_every_zero": (GOOD.replace("dir: out", "dir: out\n  every: 0"), "output.every"),
    "unknown_plane": (GOOD.replace("plane: xz", "plane: xw"), "mesh.grid.plane"),
}


NAMED_BY_KEY_ONLY = {"missing_ply_mesh", "pin_index_out_of_range"}  # checked against the mesh


def snapshot(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_broken_config_fails_cleanly(tmp_path, name):
    text, culprit = CONFIGS[name]
    config = tmp_path / "config.yaml"
    config.write_text(text)
    before = snapshot(tmp_path)
    result = CliRunner().invoke(main, ["simulate", str(config)])
    assert result.exit_code == 2, (result.output, result.exception)
    message = result.stderr
    assert message.startswith("clothtool: error: ") and message.count("\n") == 1, message
    assert "Traceback" not in result.output
    assert culprit in message, message
    assert "config.yaml" in message or name in NAMED_BY_KEY_ONLY, message
    assert snapshot(tmp_path) == before  # no output folder, no frame, no temporary file


def test_config_corpus_is_large_enough():
    assert len(CONFIGS) >= 20


@pytest.mark.parametrize("args,culprit", [
    (["simulate", "{tmp}/missing.yaml"], "missing.yaml"),
    (["simulate", "{tmp}"], "{tmp}"),
    (["simulate", "{tmp}/latin1.yaml"], "latin1.yaml"),
    (["simulate", "{tmp}/good.yaml", "--set", "material.density=-1"], "material.density"),
    (["simulate", "{tmp}/good.yaml", "--set", "materal.density=1"], "materal"),
    (["simulate", "{tmp}/good.yaml", "--set", "nonsense"], "nonsense"),
    (["simulate", "{tmp}/good.yaml", "-o", "{tmp}/good.yaml"], "good.yaml"),
])
def test_config_files_and_options(tmp_path, args, culprit):
    (tmp_path / "good.yaml").write_text(GOOD)
    (tmp_path / "latin1.yaml").write_bytes("mesh: {grid: {nx: 3}}  # caf\u00e9\n".encode("latin-1"))
    before = snapshot(tmp_path)
    args = [a.format(tmp=tmp_path) for a in args]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, (result.output, result.exception)
    assert result.stderr.startswith("clothtool: error: ") and result.stderr.count("\n") == 1
    assert culprit.format(tmp=tmp_path) in result.stderr, result.stderr
    assert snapshot(tmp_path) == before


BLOW_UP = GOOD.replace("frames: 3", "frames: 20") + "solver:\n  max_speed: 1.0\n"


def written_frames(folder):
    return sorted(p for p in folder.iterdir() if p.suffix == ".ply")


def test_a_run_that_blows_up_keeps_what_it_wrote(tmp_path):
    """Free fall passes 1 m/s after about 0.1 s: frame 4 at 30 fps. Exit code 3 names the
    frame; the frames before it and their stats rows stay, and they are valid."""
    config = tmp_path / "config.yaml"
    config.write_text(BLOW_UP)
    result = CliRunner().invoke(main, ["simulate", str(config), "-q"])
    assert result.exit_code == 3, (result.output, result.exception)
    assert result.stderr.startswith("clothtool: error: ") and result.stderr.count("\n") == 1
    assert "frame 4" in result.stderr
    out = tmp_path / "out"
    frames = written_frames(out)
    assert [p.name for p in frames] == [f"frame_{k:05d}.ply" for k in range(4)]
    for p in frames:
        assert len(read_ply(p).vertices) == 30
    with open(out / "stats.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["frame"]) for r in rows] == [0, 1, 2, 3]
    assert not [p for p in out.iterdir() if ".tmp" in p.name]


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupted_simulation_keeps_whole_frames(tmp_path, signum):
    config = tmp_path / "config.yaml"
    config.write_text(GOOD.replace("nx: 6, ny: 5", "nx: 40, ny: 40").replace("frames: 3", "frames: 100000"))
    out = tmp_path / "out"
    interrupt_when([sys.executable, "-m", "clothtool.cli", "simulate", config, "-q"],
                   lambda: out.is_dir() and len(written_frames(out)) >= 3, signum,
                   "three frames written")
    assert not [p for p in out.iterdir() if ".tmp" in p.name]
    frames = written_frames(out)
    for p in frames:
        assert len(read_ply(p).vertices) == 1600
    with open(out / "stats.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) >= len(frames) - 1  # every complete frame has its row (± the last one)
    assert os.path.getsize(out / "stats.csv") > 0
