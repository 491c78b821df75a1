"""The files of a sweep folder, each written atomically (temporary name, then rename):

    runs/sweep.json            what the sweep is: base config, runs and their parameters,
                               analysis options (a rerun must match it)
    runs/manifest.csv          run, one column per parameter, status, error, seconds
    runs/run_0000/config.yaml  the run's resolved config (``clothtool simulate`` reruns it)
    runs/run_0000/status.json  written by whoever ran the run, when it ended: done or failed
                               (with the one-line error and exit code); absent = not done

A run is done exactly when its ``status.json`` says so; frames of a run that was
interrupted stay in its folder, marked not done, and are replaced when it runs again.
"""

import csv
import io
import json
import os
from pathlib import Path

import yaml

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path

SWEEP_FILE = "sweep.json"
MANIFEST = "manifest.csv"
CONFIG = "config.yaml"
STATUS = "status.json"
FORMAT = 1


def write_text(path, text):
    """``text`` into ``path``, complete or not at all."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)


def run_ids(count):
    width = max(4, len(str(count - 1)))
    return [f"run_{i:0{width}d}" for i in range(count)]


def format_value(value):
    """A parameter value as written in the manifest and the report: YAML flow style,
    so that it reads back as the same value (floats by their shortest repr)."""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, bool) or value is None:
        return yaml.safe_dump(value, default_flow_style=True).split("\n")[0]
    if isinstance(value, (int, str)):
        return str(value)
    return yaml.safe_dump(value, default_flow_style=True, width=10**6).strip()


class SweepFolder:
    """A sweep's output folder and what it records (:data:`SWEEP_FILE`)."""

    def __init__(self, root):
        self.root = Path(root)

    @property
    def exists(self):
        return (self.root / SWEEP_FILE).is_file()

    def run_dir(self, run):
        return self.root / run

    def read(self):
        path = self.root / SWEEP_FILE
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"{self.root}: not a sweep folder (no {SWEEP_FILE}); "
                             "clothtool sweep writes one") from None
        except (OSError, ValueError) as exc:
            raise InputError(f"{path}: cannot read: {exc}") from None
        if not isinstance(record, dict) or record.get("format") != FORMAT:
            raise InputError(f"{path}: not a sweep record of this clothtool version")
        return record

    def check_new_or_same(self, record):
        """The folder is free for ``record`` (absent, empty or holding the same sweep), or
        an InputError says why not."""
        if not self.root.exists():
            return
        if not self.root.is_dir():
            raise InputError(f"{self.root}: exists and is not a folder")
        if not self.exists:
            if any(self.root.iterdir()):
                raise InputError(f"{self.root}: holds files but no sweep ({SWEEP_FILE}); "
                                 "give an empty or new folder")
            return
        old = self.read()
        for what, label in (("base_config", "base config"), ("runs", "runs"),
                            ("analysis", "analysis options")):
            if old.get(what) != record[what]:
                raise InputError(f"{self.root}: holds a different sweep (its {label} differ); "
                                 "give another folder, or the same base config and options to "
                                 "resume it")

    def write_record(self, record):
        self.root.mkdir(parents=True, exist_ok=True)
        write_text(self.root / SWEEP_FILE, json.dumps(record, indent=1) + "\n")

    def write_run_config(self, run, config):
        folder = self.run_dir(run)
        folder.mkdir(exist_ok=True)
        path = folder / CONFIG
        text = ("# clothtool sweep: this run's resolved config; clothtool simulate reruns it "
                "in this folder\n" + yaml.safe_dump(config, sort_keys=False))
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            write_text(path, text)

    # ------------------------------------------------------------------ status of runs

    def status(self, run):
        """The run's status record ({'status': 'done' | 'failed', …}) or None (not done)."""
        try:
            return json.loads((self.run_dir(run) / STATUS).read_text(encoding="utf-8"))
        except (FileNotFoundError, ValueError):
            return None

    def clear_status(self, run):
        try:
            os.remove(self.run_dir(run) / STATUS)
        except FileNotFoundError:
            pass

    def write_status(self, run, status):
        write_text(self.run_dir(run) / STATUS, json.dumps(status) + "\n")

    def statuses(self, record):
        return {r["run"]: self.status(r["run"]) for r in record["runs"]}

    # ------------------------------------------------------------------ manifest

    def write_manifest(self, record, statuses):
        """manifest.csv: one row per run with its parameters and status (pending when it
        has no status record)."""
        keys = record["parameters"]
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["run", *keys, "status", "error", "seconds"])
        for run in record["runs"]:
            st = statuses.get(run["run"]) or {}
            seconds = st.get("seconds")
            writer.writerow([run["run"], *(format_value(run["params"][k]) for k in keys),
                             st.get("status", "pending"), st.get("error", ""),
                             "" if seconds is None else f"{seconds:.3f}"])
        write_text(self.root / MANIFEST, buf.getvalue())
