"""A sweep on a real single-node Slurm cluster (Debian's slurm-wlm and munge, started here by
tests/slurm_cluster.sh): its frames and table equal the same sweep run locally."""

import os
import re
import shlex
import shutil
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from test_sweep import BASE, CLOTHTOOL, GRID_12, deterministic, frames_of, read_csv, write_base

INSTALL = "apt-get install slurm-wlm munge"
SCRIPT = Path(__file__).with_name("slurm_cluster.sh")


def _idle(env):
    out = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True, env=env)
    return out.returncode == 0 and "idle" in out.stdout


@pytest.fixture(scope="module")
def slurm_env(tmp_path_factory):
    """The environment of a running cluster: one named by SLURM_CONF if its node is idle,
    else one started for these tests (and stopped after them)."""
    env = dict(os.environ)
    if env.get("SLURM_CONF") and shutil.which("sinfo") and _idle(env):
        yield env
        return
    missing = [t for t in ("munged", "slurmctld", "slurmd", "sbatch") if not shutil.which(t)]
    if missing:
        pytest.skip(f"Slurm is not installed ({', '.join(missing)} missing): {INSTALL}")
    if os.geteuid() != 0:
        pytest.skip(f"the Slurm daemons of this test need root ({INSTALL}, then run as root)")
    folder = tmp_path_factory.mktemp("slurm")
    started = subprocess.run(["bash", str(SCRIPT), "start", str(folder)], capture_output=True,
                             text=True, timeout=120)
    if started.returncode != 0:
        pytest.skip(f"Slurm could not be started ({started.stderr.strip()}); {INSTALL}")
    env["SLURM_CONF"] = str(folder / "slurm.conf")
    try:
        yield env
    finally:
        subprocess.run(["bash", str(SCRIPT), "stop", str(folder)], timeout=60)


def test_slurm_array_equals_local_pool(tmp_path, slurm_env):
    base = write_base(tmp_path, BASE)
    on_slurm, local = tmp_path / "slurm", tmp_path / "local"
    prepared = subprocess.run([*CLOTHTOOL, "sweep", str(base), "-o", str(on_slurm), *GRID_12,
                               "--slurm", "--per-task", "3", "--analyze"],
                              capture_output=True, text=True, env=slurm_env, timeout=300)
    assert prepared.returncode == 0, prepared.stderr
    assert "12 of 12 runs to do in 4 array tasks" in prepared.stdout
    line = next(s.strip() for s in prepared.stdout.splitlines() if s.strip().startswith("sbatch "))
    assert not list(on_slurm.glob("run_*/frame_*.ply"))  # nothing ran yet
    submitted = subprocess.run(shlex.split(line), capture_output=True, text=True, env=slurm_env,
                               timeout=60)
    assert submitted.returncode == 0, submitted.stderr
    job = re.search(r"Submitted batch job (\d+)", submitted.stdout).group(1)
    deadline = time.monotonic() + 900
    while subprocess.run(["squeue", "-h", "-j", job], capture_output=True, text=True,
                         env=slurm_env).stdout.strip():
        assert time.monotonic() < deadline, "the Slurm array did not finish in 15 minutes"
        time.sleep(1)
    logs = sorted((on_slurm / "slurm-logs").glob(f"{job}_*.out"))
    assert len(logs) == 4, logs
    assert sum(log.read_text().count(": done in ") for log in logs) == 12

    ran = subprocess.run([*CLOTHTOOL, "sweep", str(base), "-o", str(local), *GRID_12, "-j", "2",
                          "--analyze", "-q"], capture_output=True, text=True, timeout=600)
    assert ran.returncode == 0, ran.stderr
    for folder in (on_slurm, local):
        report = subprocess.run([*CLOTHTOOL, "sweep-report", str(folder)], capture_output=True,
                                text=True, timeout=300)
        assert report.returncode == 0, report.stderr
        assert "12 runs, 12 done, 0 failed, 0 not done" in report.stdout
    assert [r["status"] for r in read_csv(on_slurm / "manifest.csv")] == ["done"] * 12
    table = deterministic(read_csv(on_slurm / "report.csv"))
    assert table == deterministic(read_csv(local / "report.csv"))
    assert all(row["final_lambda1_p95"] for row in table)
    for run in (f"run_{i:04d}" for i in range(12)):
        assert frames_of(on_slurm / run) == frames_of(local / run) and len(frames_of(local / run)) == 7
    with h5py.File(on_slurm / "report.h5") as a, h5py.File(local / "report.h5") as b:
        names = []
        a.visit(names.append)
        for name in names:
            if isinstance(a[name], h5py.Dataset) and not name.endswith(("seconds", "ms_per_frame",
                                                                        "wall_s")):
                np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)
