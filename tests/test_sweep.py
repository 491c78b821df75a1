"""clothtool sweep / sweep-report: expansion of grid, zip and random specs, the folder and
its manifest, local runs on a process pool, resume after Ctrl-C, failures, bad input."""

import contextlib
import csv
import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import running, wait_until
from hypothesis import given, settings
from hypothesis import strategies as st

import clothtool
from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.sweeps import spec
from clothtool.sweeps.report import TIMING

CLOTHTOOL = [sys.executable, "-m", "clothtool.cli"]

BASE = """\
mesh: {grid: {nx: 6, ny: 6, width: 0.5, height: 0.5, plane: xy}}
material: {stretch: 5000.0, bend: 1.0e-5}
scene: {pins: [top_corners]}
solver: {tolerance: 1.0e-2}
time: {fps: 30, frames: 6}
"""
GRID_12 = ["--grid", "material.stretch=1e3,3e3,1e4,3e4", "--grid", "material.bend=1e-6,1e-5,1e-4"]


def write_base(tmp_path, text=BASE, name="base.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def cli(*args, cwd=None, env=None):
    return subprocess.run([*CLOTHTOOL, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=600)


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def deterministic(rows):
    """The report's rows without the wall-time columns."""
    return [{k: v for k, v in row.items() if k not in TIMING} for row in rows]


def frames_of(folder):
    return {p.name: p.read_bytes() for p in sorted(Path(folder).glob("frame_*.ply"))}


# ------------------------------------------------------------------------------ expansion


def test_grid_is_the_product_first_key_slowest():
    runs = spec.expand(grid=["a.x=1,2,3", "b.y=[0, 1],x"])
    assert runs == [{"a.x": 1, "b.y": [0, 1]}, {"a.x": 1, "b.y": "x"}, {"a.x": 2, "b.y": [0, 1]},
                    {"a.x": 2, "b.y": "x"}, {"a.x": 3, "b.y": [0, 1]}, {"a.x": 3, "b.y": "x"}]
    assert spec.expand(grid={"a": [1e3, 1e4]}) == spec.expand(grid=["a=1e3,1e4"])
    assert isinstance(spec.expand(grid=["a=1e3"])[0]["a"], float)  # YAML 1.2 reading of 1e3


def test_zip_takes_lists_together_and_multiplies_with_the_grid():
    runs = spec.expand(grid=["g=0,1"], zipped=["a=1,2", "b=x,y"])
    assert runs == [{"g": 0, "a": 1, "b": "x"}, {"g": 0, "a": 2, "b": "y"},
                    {"g": 1, "a": 1, "b": "x"}, {"g": 1, "a": 2, "b": "y"}]
    with pytest.raises(InputError, match="same length .a has 2, b has 3"):
        spec.expand(zipped=["a=1,2", "b=1,2,3"])
    with pytest.raises(InputError, match="swept twice"):
        spec.expand(grid=["a=1,2"], zipped=["a=1,2"])


def test_random_samples_are_seeded_and_in_range():
    ranges = ["k=1e3:1e5:log", "d=0:0.05", "n=2:4:int"]
    runs = spec.expand(random=200, ranges=ranges, seed=7)
    assert runs == spec.expand(random=200, ranges=ranges, seed=7)
    assert runs != spec.expand(random=200, ranges=ranges, seed=8)
    k = np.array([r["k"] for r in runs])
    assert k.min() >= 1e3 and k.max() <= 1e5
    # log-uniform: about half the samples below the geometric mean 1e4
    assert 0.35 < np.mean(k < 1e4) < 0.65
    assert {r["n"] for r in runs} == {2, 3, 4} and all(isinstance(r["n"], int) for r in runs)
    assert all(0 <= r["d"] <= 0.05 for r in runs)


@settings(max_examples=50, deadline=None)
@given(lo=st.floats(-1e6, 1e6), width=st.floats(0, 1e6), seed=st.integers(0, 2**32 - 1),
       count=st.integers(1, 20), log=st.booleans())
def test_random_samples_stay_in_their_range(lo, width, seed, count, log):
    if log:
        lo = abs(lo) + 1e-3
    hi = lo + width
    runs = spec.expand(random=count, ranges={"x": (lo, hi, "log" if log else "linear")}, seed=seed)
    assert len(runs) == count
    assert all(lo <= r["x"] <= hi for r in runs)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.lists(st.integers(-5, 5), min_size=1, max_size=4), min_size=1, max_size=3))
def test_grid_runs_count_in_mixed_radix(lists):
    """Run i is digit d_k of i in the mixed radix of the list lengths, last key fastest."""
    grid = {f"k{i}": values for i, values in enumerate(lists)}
    runs = spec.expand(grid=grid)
    assert len(runs) == math.prod(len(v) for v in lists)
    for i, run in enumerate(runs):
        rest = i
        for k in reversed(range(len(lists))):
            rest, digit = divmod(rest, len(lists[k]))
            assert run[f"k{k}"] == lists[k][digit]


def test_values_split_on_top_level_commas_only():
    assert spec.split_values("1e3, [0, -9.81, 0] ,{a: 1, b: 2},x") == \
        ["1e3", "[0, -9.81, 0]", "{a: 1, b: 2}", "x"]


# ------------------------------------------------------------------------------ bad input


@pytest.mark.parametrize("args, message", [
    (["--grid", "material.strech=1e3,1e4"],
     "--grid material.strech=1000.0: unknown key 'material.strech' (did you mean 'stretch'?)"),
    (["--grid", "material.stretch=1e3,-1"], "--grid material.stretch=-1: material.stretch must be ≥ 0"),
    (["--random", "4", "--seed", "0", "--range", "material.stretch=1e5:1e3"],
     "--range material.stretch=1e5:1e3: min 100000 is greater than max 1000"),
    (["--random", "4", "--range", "material.stretch=1e3:1e5"],
     "--random 4: a random sweep needs a seed, so that it can be resumed and repeated: give --seed"),
    (["--range", "material.stretch=1e3:1e5"], "--range material.stretch: ranges are drawn from only"),
    (["--zip", "material.stretch=1,2", "--zip", "material.bend=1"], "--zip material.stretch: zipped"),
    (["--grid", "material.stretch"], "--grid material.stretch: expected dotted.key=v1,v2,…"),
    (["--random", "4", "--seed", "0", "--range", "material.stretch=0:1e5:log"], "a log range needs lo > 0"),
    (["--grid", "scene.pins.7=1,2"], "--grid scene.pins.7=1: scene.pins.7: scene.pins is a list of 1; '7' is not an index"),
    (["--jobs", "0", "--grid", "material.stretch=1,2"], "--jobs 0: must be a positive integer"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, args, message):
    base = write_base(tmp_path)
    result = CliRunner().invoke(main, ["sweep", str(base), "-o", str(tmp_path / "runs"), *args])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clothtool: error: "), result.output
    assert message in lines[0]
    assert not (tmp_path / "runs").exists()


def test_a_sweep_in_a_terminal_shows_its_progress_bar(tmp_path, monkeypatch):
    """With stderr a terminal the sweep counts its runs on a bar (which has no total)."""
    import clothtool.cli as cli

    monkeypatch.setattr(cli, "_progress_enabled", lambda quiet: not quiet)
    out = CliRunner().invoke(main, ["sweep", str(write_base(tmp_path)), "-o", str(tmp_path / "runs"),
                                    "--grid", "material.bend=1e-5,2e-5"])
    assert out.exit_code == 0, out.output
    assert "2 runs, 2 done, 0 failed" in out.output and "sweep: 2run [" in out.output


def test_a_combination_that_is_invalid_names_the_run(tmp_path):
    base = write_base(tmp_path)  # each value is valid alone; pbd has no bdf2
    result = CliRunner().invoke(main, ["sweep", str(base), "-o", str(tmp_path / "runs"), "--zip",
                                       "solver.method=implicit,pbd", "--zip",
                                       "solver.integrator=euler,bdf2"])
    assert result.exit_code == 2
    assert result.output == ("clothtool: error: run_0001 (solver.method=pbd, solver.integrator=bdf2): "
                             "solver.method: 'pbd' does not support solver.integrator: bdf2 "
                             "(supported by: implicit, mass-spring)\n")
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("kwargs, message", [
    (dict(grid=["material.stretch=[1,"]), "grid=material.stretch=[1,: value '[1,' is"),
    (dict(grid=["material.strech=1e3"]), "grid=material.strech=1000.0: unknown key"),
    (dict(random=2, seed=0, ranges=["material.stretch=x:2"]),
     "ranges=material.stretch=x:2: lo and hi must be numbers"),
    (dict(random=2, ranges=["material.stretch=1:2"]), "random=2: a random sweep needs a seed, "
     "so that it can be resumed and repeated: give seed=0"),
    (dict(zip=["material.stretch=1,2"], random=2, seed=0, ranges=["material.stretch=1:2"]),
     "ranges=material.stretch: material.stretch is swept twice (in more than one of grid, zip "
     "and ranges)"),
    (dict(settings=["material.strech=1"]), "settings=material.strech=1: unknown key"),
    (dict(settings=["time.frames=2", "material.stretch=-1"]),
     "settings=material.stretch=-1: material.stretch must be ≥ 0"),
    (dict(settings=["nokey"]), "settings='nokey': expected dotted.key=value"),
    (dict(analyze=True, fields="strech"), "fields=strech: unknown field 'strech'; choose from"),
    (dict(analyze=True, fields="stretch,angle"), "fields=stretch,angle: 'angle' belongs to the "
     "3D variant, which a sweep's analysis does not run; choose among the 2D fields"),
    (dict(jobs=0), "jobs=0: must be a positive integer"),
])
def test_library_errors_name_its_keywords(tmp_path, kwargs, message):
    """clothtool.sweep's errors name its keyword arguments, never the command line's options
    (which the CLI substitutes: --set for settings=)."""
    from clothtool.cli import OPTIONS

    base = write_base(tmp_path)
    with pytest.raises(InputError) as caught:
        clothtool.sweep(base, tmp_path / "runs", **kwargs)
    assert str(caught.value).startswith(message) and "--" not in str(caught.value)
    assert caught.value.format(OPTIONS).startswith(f"{OPTIONS[caught.value.keyword]} ")
    assert not (tmp_path / "runs").exists()


def test_pins_that_do_not_fit_the_mesh_fail_before_any_run(tmp_path):
    """A named pin set on a PLY mesh, or a vertex index past its end, is refused while the
    sweep is checked: one line, nothing written (as simulate would refuse each run)."""
    from conftest import grid

    x, faces = grid(5, 5, 0.4, 0.4)
    clothtool.write_ply(tmp_path / "rest.ply", x, faces)
    ply_base = BASE.replace("mesh: {grid: {nx: 6, ny: 6, width: 0.5, height: 0.5, plane: xy}}",
                            "mesh: {ply: rest.ply}")
    base = write_base(tmp_path, ply_base)
    indexed = write_base(tmp_path, ply_base.replace("[top_corners]", "[20, 24]"), "indexed.yaml")
    for base, args, message in (
            (base, ["--grid", "material.stretch=1e3,1e4"],
             f"clothtool: error: {base}: scene.pins[0]: pin set 'top_corners' needs a grid mesh"),
            (indexed, ["--grid", "scene.pins=[20, 24],[20, 25]", "-j", "2"],
             "clothtool: error: --grid scene.pins=[20, 25]: scene.pins[1]: vertex index 25 out of "
             "range (the mesh has 25 vertices)")):
        result = CliRunner().invoke(main, ["sweep", str(base), "-o", str(tmp_path / "runs"), *args])
        assert result.exit_code == 2, result.output
        assert result.output.startswith(message) and result.output.count("\n") == 1, result.output
        assert not (tmp_path / "runs").exists()
    assert not _pool_processes(os.getpid())  # the -j 2 pool, started before the check, is gone


def test_a_folder_with_a_different_sweep_is_refused_untouched(tmp_path):
    base = write_base(tmp_path)
    runs = tmp_path / "runs"
    assert cli("sweep", base, "-o", runs, "--grid", "material.stretch=1e3,1e4", "-q").returncode == 0
    before = {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in runs.rglob("*") if p.is_file()}
    for args in (["--grid", "material.stretch=1e3,2e4"], ["--grid", "material.bend=1e-5,1e-4"],
                 ["--grid", "material.stretch=1e3,1e4", "--set", "time.frames=3"],
                 ["--grid", "material.stretch=1e3,1e4", "--analyze"]):
        result = cli("sweep", base, "-o", runs, *args)
        assert result.returncode == 2
        assert result.stderr.startswith(f"clothtool: error: {runs}: holds a different sweep")
        assert result.stderr.count("\n") == 1
    assert {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in runs.rglob("*") if p.is_file()} == before
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    result = cli("sweep", base, "-o", tmp_path / "other", "--grid", "material.stretch=1e3")
    assert result.returncode == 2 and "holds files but no sweep" in result.stderr
    assert os.listdir(tmp_path / "other") == ["notes.txt"]


# ------------------------------------------------------------------------------ running


def test_runs_are_the_configs_simulate_would_run(tmp_path):
    """Each run's frames are byte-identical to `clothtool simulate BASE --set …` of its
    parameters; its folder holds the resolved config; the manifest lists every run."""
    base = write_base(tmp_path)
    runs = tmp_path / "runs"
    result = cli("sweep", base, "-o", runs, "--grid", "material.stretch=1e3,1e4",
                 "--zip", "material.bend=1e-6,1e-4", "--zip", "scene.gravity=[0, -9.81, 0],[0, -3, 0]",
                 "--set", "time.frames=4", "-j", "2")
    assert result.returncode == 0, result.stderr
    assert "4 runs, 4 done, 0 failed" in result.stdout
    manifest = read_csv(runs / "manifest.csv")
    assert [r["run"] for r in manifest] == ["run_0000", "run_0001", "run_0002", "run_0003"]
    assert list(manifest[0]) == ["run", "material.stretch", "material.bend", "scene.gravity",
                                 "status", "error", "seconds"]
    assert manifest[3]["scene.gravity"] == "[0, -3, 0]" and manifest[3]["material.stretch"] == "10000.0"
    assert all(r["status"] == "done" for r in manifest)
    ref = tmp_path / "ref"
    assert cli("simulate", base, "-o", ref, "-q", "--set", "material.stretch=1e4",
               "--set", "material.bend=1e-4", "--set", "scene.gravity=[0, -3, 0]",
               "--set", "time.frames=4").returncode == 0
    assert frames_of(runs / "run_0003") == frames_of(ref) and len(frames_of(ref)) == 5
    # the resolved config reruns the same run in its folder
    again = cli("simulate", runs / "run_0001" / "config.yaml", "-q")
    assert again.returncode == 0
    assert frames_of(runs / "run_0001") == frames_of(runs / "run_0001")


def test_paths_of_the_base_are_resolved_for_the_runs(tmp_path):
    """A base config with a relative mesh path runs from its run folders."""
    from conftest import grid

    x, faces = grid(5, 5, 0.4, 0.4)
    (tmp_path / "meshes").mkdir()
    clothtool.write_ply(tmp_path / "meshes" / "rest.ply", x, faces)
    base = write_base(tmp_path / "meshes", BASE.replace(
        "mesh: {grid: {nx: 6, ny: 6, width: 0.5, height: 0.5, plane: xy}}", "mesh: {ply: rest.ply}")
        .replace("pins: [top_corners]", "pins: [20, 24]"))
    result = clothtool.sweep(base, tmp_path / "runs", grid={"material.stretch": [1e3, 1e4]})
    assert result.done == 2 and not result.failed
    config = (tmp_path / "runs" / "run_0000" / "config.yaml").read_text()
    assert f"ply: {tmp_path / 'meshes' / 'rest.ply'}" in config


def test_failed_runs_are_named_and_the_sweep_goes_on(tmp_path):
    """2 of 12 configs blow up (exit 3): the other 10 finish, the manifest names the 2."""
    base = write_base(tmp_path)
    speeds = ["1000"] * 12
    speeds[4] = speeds[9] = "0.01"  # gravity makes the sheet faster than this in one step
    stiff = ",".join(str(1000 * (i + 1)) for i in range(12))
    runs = tmp_path / "runs"
    result = cli("sweep", base, "-o", runs, "--zip", f"material.stretch={stiff}",
                 "--zip", f"solver.max_speed={','.join(speeds)}", "-j", "2")
    assert result.returncode == 3, result.stderr
    assert "12 runs, 10 done, 2 failed" in result.stdout
    manifest = {r["run"]: r for r in read_csv(runs / "manifest.csv")}
    failed = {k: r["error"] for k, r in manifest.items() if r["status"] == "failed"}
    assert set(failed) == {"run_0004", "run_0009"}
    for run, error in failed.items():
        assert error.startswith("simulation blew up at frame 1: velocities exploded")
        assert error in result.stdout
    assert sum(r["status"] == "done" for r in manifest.values()) == 10
    report = cli("sweep-report", runs)
    assert report.returncode == 0
    table = {r["run"]: r for r in read_csv(runs / "report.csv")}
    assert table["run_0004"]["status"] == "failed" and table["run_0004"]["max_stretch"] == ""
    assert float(table["run_0005"]["max_stretch"]) > 1.0
    # a rerun does not retry them unless asked
    again = cli("sweep", base, "-o", runs, "--zip", f"material.stretch={stiff}",
                "--zip", f"solver.max_speed={','.join(speeds)}")
    assert again.returncode == 3 and "(0 ran now" in again.stdout
    again = cli("sweep", base, "-o", runs, "--zip", f"material.stretch={stiff}",
                "--zip", f"solver.max_speed={','.join(speeds)}", "--retry-failed")
    assert again.returncode == 3 and "(2 ran now" in again.stdout


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_ctrl_c_then_rerun_completes_only_the_missing_runs(tmp_path):
    """Ctrl-C (SIGINT to the process group) stops a 12-run sweep midway: exit 130, no
    temporary file, every run folder complete or marked not done; the rerun runs only
    the missing ones, and the table equals that of an uninterrupted sweep.

    No clock: once 3 runs are done the pool and its workers are frozen (SIGSTOP to the
    pool's process group), the Ctrl-C goes to the caller, and they are let go on (SIGCONT)
    only when the caller's stop (SIGTERM) is waiting at the pool: however slow the machine,
    no run is handed out after the Ctrl-C, so the sweep stops midway."""
    base = write_base(tmp_path, BASE.replace("nx: 6, ny: 6", "nx: 10, ny: 10")
                      .replace("frames: 6", "frames: 40"))
    runs, whole = tmp_path / "runs", tmp_path / "whole"
    with running([*CLOTHTOOL, "sweep", base, "-o", runs, *GRID_12, "-j", "2"], group=True) as proc:
        wait_until(proc, lambda: len(list(runs.glob("run_*/status.json"))) >= 3, "3 runs done")
        pool, = _pool_processes(proc.pid)  # the leader of its own process group
        os.killpg(pool, signal.SIGSTOP)
        frozen = {p.parent.name for p in runs.glob("run_*/status.json")}
        os.killpg(proc.pid, signal.SIGINT)
        wait_until(proc, lambda: _signal_pending(pool, signal.SIGTERM), "the pool's SIGTERM")
        with contextlib.suppress(ProcessLookupError):
            os.killpg(pool, signal.SIGCONT)
        _, stderr = proc.communicate()
    assert proc.returncode == 130 and stderr.decode() == "clothtool: interrupted\n"
    assert not [p for p in runs.rglob("*") if ".tmp-" in p.name]
    manifest = {r["run"]: r["status"] for r in read_csv(runs / "manifest.csv")}
    done = {p.parent.name for p in runs.glob("run_*/status.json")}
    # no more than the two workers' runs at the Ctrl-C ran on
    assert len(frozen) >= 3 and len(done) <= len(frozen) + 2 and len(done) < 12
    assert {r for r, s in manifest.items() if s == "done"} <= done
    for run in done:
        assert json.loads((runs / run / "status.json").read_text())["status"] == "done"
        assert len(frames_of(runs / run)) == 41
    result = cli("sweep", base, "-o", runs, *GRID_12, "-j", "2")
    assert result.returncode == 0, result.stderr
    assert f"({12 - len(done)} ran now" in result.stdout
    assert cli("sweep", base, "-o", whole, *GRID_12, "-j", "2").returncode == 0
    assert cli("sweep-report", runs).returncode == 0 and cli("sweep-report", whole).returncode == 0
    assert deterministic(read_csv(runs / "report.csv")) == deterministic(read_csv(whole / "report.csv"))
    for run in sorted(p.name for p in whole.glob("run_*")):
        assert frames_of(runs / run) == frames_of(whole / run)


# ------------------------------------------------------------------------------ report


def test_library_sweep_with_analysis_and_report(tmp_path):
    base = write_base(tmp_path)
    seen = []
    result = clothtool.sweep(base, tmp_path / "runs", random=3, seed=1,
                             ranges={"material.stretch": (1e3, 1e5, "log")}, jobs=2, analyze=True,
                             on_done=lambda run, status: seen.append(run))
    assert (result.runs, result.done, result.failed) == (3, 3, {})
    assert sorted(seen) == ["run_0000", "run_0001", "run_0002"]
    report = clothtool.sweep_report(tmp_path / "runs", plot=["final_lambda1_p95", "elastic"])
    assert [p.name for p in report.plots] == ["final_lambda1_p95-vs-material.stretch.png",
                                              "elastic-vs-material.stretch.png"]
    assert all(p.stat().st_size > 1000 for p in report.plots)
    row = report.rows[1]
    run_dir = tmp_path / "runs" / "run_0001"
    # the metrics against the run's own files, computed another way
    stats = np.genfromtxt(run_dir / "stats.csv", delimiter=",", names=True)
    assert row["max_stretch"] == stats["max_stretch"].max()
    assert row["elastic"] == stats["elastic"][-1] and row["frames"] == len(stats)
    assert row["ms_per_frame"] == pytest.approx(1000 * np.median(stats["wall_s"][1:]))
    ref = tmp_path / "ref.h5"
    clothtool.analyze_sequence(str(run_dir), str(ref), reference="uv")
    import h5py

    with h5py.File(ref) as h5:
        assert row["final_lambda1_p95"] == pytest.approx(h5["summary/lambda1_p95"][-1], rel=1e-12)
        assert row["max_lambda1_p95"] == pytest.approx(h5["summary/lambda1_p95"][:].max(), rel=1e-12)
    with h5py.File(report.h5) as h5:
        assert list(h5.attrs["columns"]) == report.columns
        assert h5["table/material.stretch"][1] == row["material.stretch"]
        assert h5["table/status"][1].decode() == "done"
        np.testing.assert_array_equal(h5["series/run_0001/stats/elastic"][:], stats["elastic"])
        assert "series/run_0001/analysis/lambda1_p95" in h5
    table = read_csv(report.csv)
    assert list(table[0]) == report.columns and float(table[1]["elastic"]) == row["elastic"]


def test_report_errors(tmp_path):
    base = write_base(tmp_path)
    clothtool.sweep(base, tmp_path / "runs", grid=["material.stretch=1e3,1e4"])
    runner = CliRunner()
    result = runner.invoke(main, ["sweep-report", str(tmp_path / "runs"), "--plot", "nope"])
    assert result.exit_code == 2 and "--plot nope: not a metric of the table" in result.output
    result = runner.invoke(main, ["sweep-report", str(tmp_path / "runs"), "--plot", "elastic",
                                  "--against", "material.bend"])
    assert result.exit_code == 2 and "--against material.bend: not a parameter" in result.output
    result = runner.invoke(main, ["sweep-report", str(tmp_path)])
    assert result.exit_code == 2 and "not a sweep folder" in result.output


def _descendants(pid):
    """Process ids below ``pid`` (Linux /proc)."""
    children = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    out, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def _open_files(pid):
    try:
        return [os.path.realpath(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
    except OSError:
        return []


def _signal_pending(pid, signum):
    """Is ``signum`` pending for process ``pid`` (sent, not yet delivered)? Linux's
    /proc/PID/status gives the pending set as a hex mask (ShdPnd: sent to the process)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:  # it has ended: nothing is pending any more
        return True
    mask = int(status.split("ShdPnd:")[1].split()[0], 16)
    return bool(mask >> (signum - 1) & 1)


def _pool_processes(pid):
    """The sweep pool processes below ``pid`` (not their workers, forks with the same command
    line)."""
    found = {}
    for child in _descendants(pid):
        try:
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
            parent = int(Path(f"/proc/{child}/stat").read_text().rsplit(")", 1)[1].split()[1])
        except OSError:
            continue
        if b"clothtool.sweeps.pool import serve" in cmdline:
            found[child] = parent
    return [child for child, parent in found.items() if parent not in found]


def _group_alive(pgid):
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_a_pool_process_that_dies_stops_its_workers_and_the_rerun_resumes(tmp_path):
    """SIGKILL to the pool process in the middle of the runs: its workers are stopped (their
    runs left not done, no temporary file), the sweep says so in one line (exit code 1), and
    running it again completes every run."""
    base = write_base(tmp_path, BASE.replace("frames: 6", "frames: 200"))
    runs = tmp_path / "runs"
    args = [*CLOTHTOOL, "sweep", str(base), "-o", str(runs), "-j", "2",
            "--grid", "material.stretch=1e3,2e3,3e3,4e3"]
    with running(args) as proc:
        wait_until(proc, (runs / "run_0000" / "frame_00010.ply").exists, "frame 10 written")
        pool, = _pool_processes(proc.pid)
        os.kill(pool, signal.SIGKILL)
        stdout, stderr = proc.communicate()
    assert proc.returncode == 1, stderr
    assert stderr.decode() == (
        "clothtool: error: the process that runs the sweep's workers died (killed by signal "
        "SIGKILL); the runs it had not finished are not done: run the sweep again to resume\n")
    assert not _group_alive(pool)  # its workers are gone too
    assert not [p for p in runs.rglob("*") if ".tmp-" in p.name]
    for status in runs.glob("run_*/status.json"):  # the stopped runs have none
        assert json.loads(status.read_text())["status"] == "done"
    again = cli(*args[3:])
    assert again.returncode == 0, again.stderr
    assert all(r["status"] == "done" for r in read_csv(runs / "manifest.csv"))


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_a_worker_that_dies_fails_its_run_only(tmp_path):
    """SIGKILL to a pool worker in the middle of a run: that run fails naming the signal,
    a new worker takes the rest, every other run is done."""
    base = write_base(tmp_path, BASE.replace("frames: 6", "frames: 400"))
    runs = tmp_path / "runs"
    with running([*CLOTHTOOL, "sweep", base, "-o", runs, "-j", "2",
                  "--grid", "material.stretch=1e3,2e3,3e3,4e3"]) as proc:
        wait_until(proc, (runs / "run_0000" / "frame_00010.ply").exists, "frame 10 written")
        # the worker running run_0000: the one with a file of its folder open (stats.csv)
        victim = next(pid for pid in _descendants(proc.pid)
                      if any(str(runs / "run_0000") in path for path in _open_files(pid)))
        os.kill(victim, signal.SIGKILL)
        stdout, stderr = proc.communicate()
    assert proc.returncode == 3, stderr
    manifest = {r["run"]: r for r in read_csv(runs / "manifest.csv")}
    assert manifest["run_0000"]["status"] == "failed"
    assert manifest["run_0000"]["error"] == \
        "the worker process running this run died (killed by signal SIGKILL)"
    assert [manifest[f"run_000{i}"]["status"] for i in (1, 2, 3)] == ["done"] * 3
