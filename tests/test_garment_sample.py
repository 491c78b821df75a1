"""The garment sample (sample_data/garment.yaml): a two-panel skirt sewn onto a walking mannequin.
The script regenerates the committed files; a shortened run (sewn, welded, then dressed for a
few frames) closes its seams, crosses neither itself nor the body (ours and ipctk), and its
waistband rides on the moving body."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import clothtool
from benchmarks.bench_garment import HIP_Y, SAMPLE, check_sample
from clothtool.sim.model.config import load_config

ROOT = Path(__file__).resolve().parent.parent


def test_the_script_writes_the_committed_sample(tmp_path):
    spec = importlib.util.spec_from_file_location("make_garment_sample",
                                                  ROOT / "scripts" / "make_garment_sample.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    script.main(str(tmp_path / "garment"))
    committed = ROOT / "sample_data"
    assert (tmp_path / "garment.yaml").read_text() == (committed / "garment.yaml").read_text()
    names = sorted(p.relative_to(tmp_path).as_posix() for p in (tmp_path / "garment").rglob("*.obj"))
    assert names == sorted(p.relative_to(committed).as_posix()
                           for p in (committed / "garment").rglob("*.obj"))
    for name in names:
        assert (tmp_path / name).read_bytes() == (committed / name).read_bytes(), name


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """The sample for 12 frames: sewn and welded (frame 7), then dressed as the walk starts."""
    out = tmp_path_factory.mktemp("garment")
    config = load_config(SAMPLE, overrides={"time.frames": 12})
    clothtool.simulate(config, output_dir=out, progress=False)
    return check_sample(out, config)


def test_the_sample_is_sewn_closed(short_run):
    assert short_run["weld"] is not None and short_run["weld"] <= 10
    assert short_run["gap"] <= 1e-3  # every seam closed to 1 mm (welded: 0)


def test_the_sample_never_crosses_itself_or_the_body(short_run):
    assert short_run["frames"] == 13
    assert short_run["crossings"] == 0
    if short_run["ipctk"] != "n/a":
        assert short_run["ipctk"] == 0


def test_the_sample_stays_on_the_body(short_run):
    assert short_run["waist_drift"] < 1e-3  # the waistband keeps its distance from the body
    assert short_run["waist_off"] < 0.01  # ... a fitted waist: within 10 mm of the body
    assert short_run["waist_low"] > HIP_Y + 0.2  # it stays at the waist, high above the hips
    assert np.isfinite(short_run["lowest"]) and short_run["lowest"] > 0.6  # nothing slides down
