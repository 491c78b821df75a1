"""The simulations of a fit (:mod:`clothtool.sweeps.motion_fit`): the residual at points u of
the unit box, each point a run of a sweep in ``root/runs/round_NNN`` (one round per batch of
points the optimiser needs at once: a trial point, a Jacobian's columns).

A point is looked up by its values among the runs on disk before it is simulated, so a rerun of
the fit replays the optimiser on the residuals already computed: an interrupted round is
resumed, a round left to Slurm is read once its array has ended. ``fit.csv`` is rewritten after
every round.
"""

import json
import math

import numpy as np

from clothtool.errors import NumericalError
from clothtool.sweeps.layout import SWEEP_FILE


class Waiting(Exception):
    """A round has been written as a Slurm array; ``sbatch`` submits it."""

    def __init__(self, sbatch):
        super().__init__(sbatch)
        self.sbatch = sbatch


class Failed(NumericalError):
    """A simulation the fit needs failed."""


class Budget(Exception):
    """The next round would pass ``max_simulations``."""


class FitRuns:
    """Residuals at points u, each a simulation: a run of a sweep in ``root/runs/round_NNN``.
    Runs already on disk (done, or written and not done) are found again by their values."""

    def __init__(self, root, problem, jobs, slurm, on_done, pool=None):
        self.root, self.problem = root, problem
        self.jobs, self.slurm, self.on_done, self.pool = jobs, slurm, on_done, pool
        # a trial point's finite-difference points go in its round when rounds run in
        # parallel: an accepted step (most are) then needs no round of its own for its Jacobian
        self.speculate = slurm or jobs > 1
        self.runs = root / "runs"
        self.known = []  # (values tuple, round folder, run id)
        self.cache = {}  # run dir → residual (None: failed)
        self.rows = []  # fit.csv: one per simulation, in the order asked for
        self.start = None
        self.faces = None
        self.rounds = 0
        # the rounds on disk (a round interrupted before its record is empty: it is reused)
        for folder in sorted(self.runs.glob(f"round_*/{SWEEP_FILE}")) if self.runs.is_dir() else ():
            record = json.loads(folder.read_text(encoding="utf-8"))
            for run in record["runs"]:
                self.known.append((tuple(run["params"][k] for k in problem.keys), folder.parent,
                                   run["run"]))
            self.rounds += 1

    @property
    def count(self):
        return len(self.rows)

    def _find(self, values):
        for known, folder, run in self.known:
            if all(math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-300) for a, b in zip(known, values)):
                return folder, run
        return None

    def points_of(self, u, with_steps):
        points = [np.asarray(u, float)]
        if with_steps:
            for i, p in enumerate(self.problem.parameters):
                step = np.array(points[0])
                h = p.step if step[i] + p.step <= 1.0 else -p.step
                step[i] += h
                points.append(step)
        return points

    def evaluate(self, us, with_steps=False):
        """Make sure the points ``us`` (and, ``with_steps``, their finite-difference points)
        have been simulated: one round of those not on disk."""
        points = [q for u in us for q in self.points_of(u, with_steps)]
        wanted = [tuple(self.problem.values(q)) for q in points]
        missing, pending = [], {}
        for values in wanted:
            found = self._find(values)
            if found is None:
                if values not in missing:
                    missing.append(values)
            elif self._status(*found) is None:
                pending.setdefault(found[0], None)
        if self.count + len(missing) > self.problem.max_simulations and missing:
            if with_steps and len(us) == 1 and len(points) > 1:
                return self.evaluate(us)  # the point alone may still fit in the budget
            raise Budget()
        for folder in pending:
            self._run(folder, None)
        if missing:
            self.rounds += 1
            folder = self.runs / f"round_{self.rounds:03d}"
            self._run(folder, missing)
            for i, values in enumerate(missing):
                self.known.append((values, folder, f"run_{i:04d}"))
        for q, values in zip(points, wanted):
            if self._row(values) is None:
                folder, run = self._find(values)
                self.rows.append(self._read(values, folder, run))
        if missing or pending:
            from clothtool.sweeps.fit_output import write_csv

            write_csv(self.root, self.problem, self)

    def _run(self, folder, values):
        """Run (or resume) the round in ``folder``: ``values`` the new runs, None to resume."""
        from clothtool.sweeps.api import sweep

        if values is None:
            record = json.loads((folder / SWEEP_FILE).read_text(encoding="utf-8"))
            values = [tuple(r["params"][k] for k in self.problem.keys) for r in record["runs"]]
        grid = {k: [v[i] for v in values] for i, k in enumerate(self.problem.keys)}
        result = sweep(self.problem.base, folder, zip=grid, settings=self.problem.sweep_settings,
                       jobs=self.jobs, slurm=self.slurm, on_done=self.on_done, pool=self.pool)
        if result.sbatch:
            raise Waiting(result.sbatch)

    def _status(self, folder, run):
        from clothtool.sweeps.layout import SweepFolder

        return SweepFolder(folder).status(run)

    def _row(self, values):
        for row in self.rows:
            if row["values"] == values:
                return row
        return None

    def _read(self, values, folder, run):
        """The residual of a finished run, its row for fit.csv."""
        run_dir = folder / run
        status = self._status(folder, run) or {}
        row = {"values": values, "round": folder.name, "run": run, "dir": run_dir,
               "status": status.get("status", "pending"), "seconds": status.get("seconds"),
               "error": status.get("error", "")}
        if row["status"] == "done" and run_dir not in self.cache:
            self.cache[run_dir] = self._residual_of(run_dir)
        residual = self.cache.get(run_dir)
        if residual is not None:
            d = self.problem.capture.distances(residual)
            row["rms"], row["largest"] = float(np.sqrt(np.mean(d ** 2))), float(d.max())
        return row

    def _residual_of(self, run_dir):
        from clothtool.io.frames import discover_frames, read_mesh

        paths = discover_frames(run_dir)
        capture = self.problem.capture
        if len(paths) != len(capture.frames):
            return None
        meshes = [read_mesh(p) for p in paths]
        if self.faces is None:
            self.faces = np.asarray(meshes[0].faces, np.int64)
        return capture.residual(np.stack([m.vertices for m in meshes]), self.faces)

    def _residual_at(self, u):
        values = tuple(self.problem.values(u))
        row = self._row(values)
        if row is None:  # a trial point; its Jacobian's points too when they cost no round
            self.evaluate([u], with_steps=self.speculate)
            row = self._row(values)
        residual = self.cache.get(row["dir"])
        if residual is None:
            raise Failed(f"the simulation at {self.problem.shown(u)} failed "
                                 f"({row['round']}/{row['run']}: {row['error'] or row['status']}); "
                                 "narrow the ranges so that every simulation in them runs")
        return residual

    # what least_squares calls

    def residual(self, u):
        """r(u); a simulation that fails (a blow-up) returns ten times the start's residual,
        so that the trust region shrinks away from it."""
        try:
            return self._residual_at(u)
        except Failed:
            if self.start is None or np.allclose(u, self.start):
                raise
            return 10.0 * self._residual_at(self.start)

    def jacobian(self, u, f=None):
        self.evaluate([u], with_steps=True)
        points = self.points_of(u, True)
        r0 = self._residual_at(points[0])
        columns = [(self._residual_at(q) - r0) / (q - points[0]).sum() for q in points[1:]]
        return np.stack(columns, axis=1)

    def rms(self, u):
        row = self._row(tuple(self.problem.values(u)))
        return row.get("rms", float("nan")) if row else float("nan")

    def best(self):
        done = [r for r in self.rows if "rms" in r]
        if not done:
            return None
        row = min(done, key=lambda r: r["rms"])
        return np.array([p.unit(v) for p, v in zip(self.problem.parameters, row["values"])])

    def run_dir(self, u):
        return self._row(tuple(self.problem.values(u)))["dir"]
