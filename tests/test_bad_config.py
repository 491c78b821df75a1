"""Bad simulation configs and a run that blows up, through the CLI.

Every broken config gives exit code 2 and one line naming the key (or the YAML line);
nothing is written. A run that blows up gives exit code 3 naming the frame, and keeps
the frames and ``stats.csv`` rows written before it.
"""

import csv
import os
import signal
import sys
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from conftest import interrupt_when

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


# name → (config text, text the message must contain): one edit of GOOD each
# (bad_configs.yaml), and these
CONFIGS = {name: (GOOD.replace(old, new), culprit) for name, (old, new, culprit)
           in yaml.safe_load((Path(__file__).parent / "bad_configs.yaml").read_text()).items()}
CONFIGS.update({
    "not_a_mapping": ("- mesh\n- material\n", "mapping"),
    "empty_file": ("", "mesh"),
    "vbd_with_friction": (GOOD.replace("radius: 0.3}", "radius: 0.3, friction: 0.5}")
                          .replace("time:", "solver: {method: vbd}\ntime:"), "friction"),
    "no_mesh": (GOOD.split("material:")[0].replace("mesh:\n  grid: {nx: 6, ny: 5, width: 1.0, "
                                                    "height: 0.8, plane: xz}\n", "")
                + "material:" + GOOD.split("material:")[1], "mesh"),
})


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
