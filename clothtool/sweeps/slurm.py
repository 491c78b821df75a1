"""Runs on a Slurm cluster: a job-array script, one array task per batch of
``per_task`` runs, each task running ``clothtool sweep-task`` on its runs.

The script names the batches itself (a bash array indexed by
``SLURM_ARRAY_TASK_ID``), so it stays valid whatever else happens to the folder; a
task skips runs that are already done, and writes each run's ``status.json`` as the
run ends (the tasks never write a shared file). ``clothtool sweep-report`` gathers
the statuses into the manifest and the table. The folder must be on a file system
that the compute nodes share, and the tasks use the Python environment that wrote
the script (its interpreter's absolute path).
"""

import shlex
import sys

from clothtool.errors import InputError
from clothtool.sweeps.layout import SweepFolder

SCRIPT = "sweep.sbatch"
LOGS = "slurm-logs"


def batches(runs, per_task):
    return [runs[i:i + per_task] for i in range(0, len(runs), per_task)]


def write_script(root, runs, per_task, cpus=1, job_name="clothtool-sweep"):
    """Write ``root/sweep.sbatch`` for the ``runs`` (ids) not yet done; returns (path,
    number of tasks)."""
    folder = SweepFolder(root)
    groups = batches(runs, per_task)
    root_abs = folder.root.resolve()
    (root_abs / LOGS).mkdir(exist_ok=True)
    python = shlex.quote(sys.executable)
    lines = [
        "#!/bin/bash",
        f"#SBATCH --job-name={job_name}",
        f"#SBATCH --array=0-{len(groups) - 1}"
        f"               # {len(runs)} runs, {per_task} per task",
        f"#SBATCH --cpus-per-task={cpus}         # must fit your nodes (sinfo -o '%n %c')",
        f"#SBATCH --output={root_abs / LOGS}/%A_%a.out",
        "# written by clothtool sweep --slurm; submit with: sbatch " + shlex.quote(str(root_abs / SCRIPT)),
        "RUNS=(",
        *(f"  {shlex.quote(' '.join(group))}" for group in groups),
        ")",
        "export NUMBA_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}",
        f"exec {python} -m clothtool.cli sweep-task {shlex.quote(str(root_abs))} "
        "${RUNS[$SLURM_ARRAY_TASK_ID]}",
        "",
    ]
    from clothtool.sweeps.layout import write_text

    path = root_abs / SCRIPT
    write_text(path, "\n".join(lines))
    path.chmod(0o755)
    return path, len(groups)


def run_task(root, runs):
    """A Slurm task's work: run each of ``runs`` that is not done yet, in order.
    Returns {run: status} of the runs it ran."""
    from clothtool.sweeps.run import run_one

    folder = SweepFolder(root)
    record = folder.read()
    known = {r["run"] for r in record["runs"]}
    unknown = [r for r in runs if r not in known]
    if unknown:
        raise InputError(f"{root}: no run {unknown[0]!r} in this sweep")
    out = {}
    for run in runs:
        status = folder.status(run)
        if status is not None and status.get("status") == "done":
            continue
        out[run] = run_one(folder.root, run, record["analysis"])
    return out
