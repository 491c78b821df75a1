"""``clothtool.fit``: the material values that make a simulation move as a captured sequence
moved.

The unknowns are the ``ranges`` keys, each mapped onto u ∈ [0, 1] across its range (in log
space for a ``log`` range: u = log(v/lo) / log(hi/lo)). The residual r(u) is the vector of
offsets between the simulated and the captured frames (:mod:`clothtool.sweeps.capture`),
and scipy's trust-region reflective least squares (``least_squares(method='trf')``, Branch,
Coleman & Li 1999) minimises ½‖r‖² over the box. Its Jacobian is a forward difference per
column, a step of STEP (2 %) in each value (in log space for a log range: v·1.02), backward
at the range's top; the columns of one Jacobian are one round of simulations, run on the
local pool (``jobs``) or as one Slurm array.

Every simulation is a run of a sweep (:func:`clothtool.sweeps.api.sweep`), a round per
folder ``output_dir/runs/round_NNN``. A rerun replays the optimiser from the start and reads
the residual of every point it asks for again from the runs on disk (the optimiser is
deterministic given its function values), so an interrupted fit goes on where it stopped and a
round left to Slurm is picked up once its array has ended.

Each iteration ends when the estimated distance to the minimum, the Gauss–Newton step in
units of the values' uncertainty (gᵀ(JᵀJ)⁻¹g / s², g = Jᵀr, as MINUIT's EDM) is below EDM:
the next step would move the values by less than a tenth of their ±; least_squares' own
tolerances end a fit to a capture without scatter.

At the fit, J (per log v) gives the Gauss–Newton covariance C = s² (JᵀJ)⁻¹, s² = ‖r‖²/(m − n)
(m residuals, n values): σ = √C_ii, relative for a log range; the report's ± is its 95 %
interval, 1.96 σ. It is the capture's scatter seen through the Jacobian; a difference the
simulation keeps from frame to frame (another mesh's discretisation, a model that cannot
follow the capture) is not scatter and is not in it. Its share of the RMS is estimated from the
residual's correlation c from one frame to the next: systematic ≈ RMS·√c. A value is not pinned
down by the capture when σ exceeds LOOSE (10 %; 1 % of a linear range), or when doubling it (a
tenth of a linear range) moves the sequence less than that systematic part; values are told
apart only in combination when a direction of the values (a right singular vector of J scaled
so) is weak in the same sense and shares itself among them.
"""

import copy
import itertools
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from clothtool.errors import InputError
from clothtool.sweeps.fit_runs import Budget, FitRuns, Waiting
from clothtool.sweeps.layout import write_text

STEP = 0.02  # finite-difference step: a 2 % change of the value (of the range, linear)
LOOSE = 0.1  # σ beyond which a value is loose: relative (log range), × a tenth of a linear range
MEMBER = 0.3  # a value's share of a weak direction that makes it one of the values tied
EDM = 0.01  # stop when the next step would move the values by less than 0.1 σ
MAX_SIMULATIONS = 40
FTOL, XTOL = 1e-8, 1e-5  # least_squares' own tolerances (cost; step in u: ~1e-4 of a value)
FORMAT = 1
RECORD = "fit.json"
STOPPED = "converged: the next step would move the values by less than a tenth of their ±"


@dataclass
class Parameter:
    """A fitted key: its range [lo, hi] (``log``: in log space) and its start value."""

    key: str
    lo: float
    hi: float
    log: bool
    start: float

    def unit(self, value):
        if self.log:
            return math.log(value / self.lo) / math.log(self.hi / self.lo)
        return (value - self.lo) / (self.hi - self.lo)

    def value(self, u):
        u = min(max(float(u), 0.0), 1.0)
        if u == self.unit(self.start):  # the start as the config gives it, not rounded
            return self.start
        if self.log:
            return min(max(self.lo * math.exp(u * math.log(self.hi / self.lo)), self.lo), self.hi)
        return self.lo + u * (self.hi - self.lo)

    @property
    def step(self):
        """The finite-difference step in u."""
        return math.log1p(STEP) / math.log(self.hi / self.lo) if self.log else STEP

    @property
    def per_unit(self):
        """d(log v)/du for a log range, dv/du for a linear one."""
        return math.log(self.hi / self.lo) if self.log else self.hi - self.lo


@dataclass
class FitResult:
    """What :func:`fit` found. ``values``: key → fitted value; ``sigma``: key → the 1σ
    uncertainty (relative for a log range, in the key's unit for a linear one);
    ``doubling``: key → RMS displacement (m) of the sequence when the value doubles
    (a linear range: moves by a tenth of the range); ``systematic``: the part of the RMS
    distance that stays from frame to frame (m); ``tied``: ([keys], RMS effect of doubling
    them together along their weak direction) of values told apart only in combination;
    ``loose``: keys the capture does not pin down; ``rms``, ``largest``, ``start_rms``: the
    distance to the capture (m) at the fit and at the start; ``offset0``, ``offset0_left``:
    frame 0's RMS distance to the config's initial state (m) before and after the capture was
    moved onto it; ``sbatch``: set while a round waits for
    Slurm (the rest is the best so far)."""

    output_dir: Path
    mode: str
    parameters: list
    points: int
    frames: int
    values: dict = field(default_factory=dict)
    start_rms: float = float("nan")
    rms: float = float("nan")
    largest: float = float("nan")
    offset0: float = 0.0
    offset0_left: float = 0.0
    systematic: float = 0.0
    sigma: dict = field(default_factory=dict)
    doubling: dict = field(default_factory=dict)
    tied: list = field(default_factory=list)
    loose: list = field(default_factory=list)
    simulations: int = 0
    rounds: int = 0
    seconds: float = 0.0
    stopped: str = ""
    sbatch: str | None = None
    best_run: Path | None = None
    written: list = field(default_factory=list)
    strain: dict | None = None

    def describe(self):
        from clothtool.sweeps.fit_output import describe

        return describe(self)


def fit(config, capture, ranges, output_dir, *, settings=None, compare="auto", outliers=None,
        register=True, scan=0, jobs=1, slurm=False, max_simulations=MAX_SIMULATIONS,
        compare_strain=False, on_done=None, log=None):
    """Fit the ``ranges`` keys of the simulation ``config`` (a YAML path) to the captured
    frames ``capture`` (a folder, glob or list of PLY/OBJ files: frame 0 the initial state,
    frame k the config's output frame k).

    ``ranges``: {key: (lo, hi[, 'log'])} or ``["key=lo:hi[:log]"]``: any numeric config key
    (``material.bend``, ``material.bend.0`` for the warp of a [warp, weft] pair, damping,
    friction); the fit starts from the config's value (the range's middle when it lies
    outside). ``settings``: ``["key=value"]`` applied to the config first. ``compare``:
    'vertex', 'surface' or 'auto' (:mod:`clothtool.sweeps.capture`). ``register``: move the
    capture rigidly so that its frame 0 lies nearest the config's initial state
    (:func:`~clothtool.sweeps.capture.register`). ``scan``: first simulate ``scan`` values of
    each key across its range (the centres of a grid of scanⁿ cells, one round) and start from
    the one nearest the capture: for keys with local minima (friction). ``outliers``: a
    distance (m) beyond which a residual counts less and less (Cauchy's loss ln(1 + z),
    z = (r/outliers)²), for captures with stray points; None: plain least squares. ``jobs``,
    ``slurm``: how each round runs (as :func:`~clothtool.sweeps.api.sweep`);
    ``max_simulations``: the budget.
    ``compare_strain``: also analyse the capture and the fitted simulation and compare their
    per-triangle stretches. ``on_done(run, status)`` as each simulation ends; ``log(line)``
    with what the fit finds as it goes.

    Everything is checked before a file is written; a bad argument is an
    :class:`~clothtool.errors.InputError` naming it. Writes ``output_dir/fit.yaml`` (the
    config with the fitted values), ``fit.csv`` (a row per simulation), ``fit.png`` and
    ``runs/``; returns a :class:`FitResult`.
    """
    from clothtool.sweeps import fit_output

    started = time.perf_counter()
    log = log or (lambda line: None)
    for name, value in (("jobs", jobs), ("max_simulations", max_simulations)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError("must be a positive integer", keyword=name, value=value)
    pool = None
    if jobs > 1 and not slurm:  # one pool for every round; its imports overlap the checks
        from clothtool.sweeps.pool import Pool

        pool = Pool(None, jobs)
    try:
        problem = _Problem(config, capture, ranges, settings, compare, outliers, max_simulations,
                           register, scan)
        root = Path(output_dir)
        problem.claim(root)
        result = FitResult(root, problem.capture.mode, problem.parameters,
                           problem.capture.frames.shape[1], len(problem.capture.frames) - 1,
                           offset0=problem.offset0, offset0_left=problem.left0)
        log(problem.describe())
        evals = FitRuns(root, problem, jobs, slurm, on_done, pool)
        best, iterates = _solve(problem, evals, result, outliers, max_simulations, log)
    finally:
        if pool is not None:
            pool.close()
    result.simulations, result.rounds = evals.count, evals.rounds
    if best is not None and result.sbatch is None:
        _settle(result, problem, evals, best)
        result.written += fit_output.write_all(result, problem, evals, best, iterates)
        if compare_strain:
            from clothtool.sweeps.fit_output import compare_strains

            result.strain = compare_strains(problem.capture, evals.run_dir(best), root)
    elif best is not None:
        result.values = dict(zip(problem.keys, problem.values(best)))
        result.written.append(fit_output.write_csv(root, problem, evals))
    result.seconds = time.perf_counter() - started
    return result


def _solve(problem, evals, result, outliers, max_simulations, log):
    """Run least_squares from the config's values; (the best point, the iterates)."""
    from scipy.optimize import least_squares

    u0 = np.array([p.unit(p.start) for p in problem.parameters])
    iterates = []

    def callback(intermediate_result):
        iterates.append(np.array(intermediate_result.x))
        log(f"  iteration {len(iterates)}: " + problem.shown(intermediate_result.x)
            + f", RMS {1000 * evals.rms(intermediate_result.x):.3g} mm")
        if _edm(evals, intermediate_result.x) < EDM:
            raise StopIteration

    try:
        if problem.scan:  # a grid over the ranges in one round; start from its nearest point
            axis = (np.arange(problem.scan) + 0.5) / problem.scan
            grid = [np.array(u) for u in itertools.product(axis, repeat=len(u0))]
            evals.evaluate(grid)
            u0 = min(grid, key=lambda u: np.nan_to_num(evals.rms(u), nan=np.inf))
            for p, value in zip(problem.parameters, problem.values(u0)):
                p.start = value
            log(f"  scan: {len(grid)} simulations; the nearest to the capture: "
                f"{problem.shown(u0)}, RMS {1000 * evals.rms(u0):.3g} mm")
        evals.start = u0
        evals.evaluate([u0], with_steps=True)  # the start and its Jacobian: one round
        solution = least_squares(evals.residual, u0, jac=evals.jacobian, bounds=(0.0, 1.0),
                                 method="trf", x_scale="jac", ftol=FTOL, xtol=XTOL, gtol=1e-10,
                                 loss="linear" if outliers is None else "cauchy",
                                 f_scale=1.0 if outliers is None else float(outliers),
                                 max_nfev=max_simulations, callback=callback)
        result.stopped = STOPPED if solution.status == -2 else solution.message
        return solution.x, iterates
    except Waiting as wait:
        result.sbatch = wait.sbatch
    except Budget:
        result.stopped = f"stopped at the budget of {max_simulations} simulations"
    return evals.best(), iterates


def _settle(result, problem, evals, best):
    """The fitted values, distances and what the Jacobian at the fit says of them."""
    residual = evals.residual(best)
    distances = problem.capture.distances(residual)
    start = problem.capture.distances(evals.residual(evals.start))
    result.values = dict(zip(problem.keys, problem.values(best)))
    result.best_run = evals.run_dir(best)
    result.rms, result.largest = float(np.sqrt(np.mean(distances ** 2))), float(distances.max())
    result.start_rms = float(np.sqrt(np.mean(start ** 2)))
    result.systematic = result.rms * math.sqrt(max(_frame_correlation(residual,
                                                                      result.frames), 0.0))
    jac = evals.jacobian(best) / np.array([p.per_unit for p in problem.parameters])  # per log v
    m, n = jac.shape
    s2 = float(residual @ residual) / max(m - n, 1)
    sd = np.sqrt(np.maximum(np.diag(s2 * np.linalg.pinv(jac.T @ jac)), 0.0))
    # what a telling change (a doubling; a tenth of a linear range) does to the sequence, RMS
    shifts = np.array([math.log(2.0) if p.log else 0.1 * (p.hi - p.lo) for p in problem.parameters])
    scaled = jac * shifts / math.sqrt(result.points * result.frames)
    for i, p in enumerate(problem.parameters):
        result.sigma[p.key] = float(sd[i])
        result.doubling[p.key] = float(np.linalg.norm(scaled[:, i]))
        limit = LOOSE if p.log else LOOSE * shifts[i]
        if sd[i] > limit or result.doubling[p.key] < result.systematic:
            result.loose.append(p.key)
    _, effects, directions = np.linalg.svd(scaled, full_matrices=False)
    spread = math.sqrt(s2 / (result.points * result.frames))  # σ along a direction, in shifts
    for effect, direction in zip(effects, directions):
        weak = effect < result.systematic or spread / max(effect, 1e-300) * math.log(2.0) > LOOSE
        members = [k for k, w in zip(problem.keys, direction) if abs(w) > MEMBER]
        if weak and len(members) > 1:
            result.tied.append((members, float(effect)))


def _frame_correlation(residual, frames):
    """Correlation of the residual from one frame to the next: about 0 for a capture's
    scatter, about 1 for a difference the simulation keeps (model, mesh, setup)."""
    r = residual.reshape(frames, -1)
    if frames < 2:
        return 0.0
    a, b = r[:-1].ravel(), r[1:].ravel()
    norm = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / norm if norm > 0 else 0.0


def _edm(evals, u):
    """The estimated distance to the minimum: the Gauss–Newton step from u in units of the
    values' uncertainty, squared (gᵀ(JᵀJ)⁻¹g / s², g = Jᵀr)."""
    r, jac = evals.residual(u), evals.jacobian(u)
    g = jac.T @ r
    s2 = float(r @ r) / max(len(r) - len(u), 1)
    return float(g @ np.linalg.pinv(jac.T @ jac) @ g) / s2 if s2 > 0 else math.inf


# ---------------------------------------------------------------------- the problem


class _Problem:
    """The checked inputs: base config, settings, parameters, capture."""

    def __init__(self, config, capture, ranges, settings, compare, outliers, max_simulations,
                 register, scan):
        from clothtool.config_tools import apply_overrides
        from clothtool.sim.model.config import load_config, read_yaml
        from clothtool.sim.model.mesh import build_rest_mesh
        from clothtool.sweeps import spec
        from clothtool.sweeps.api import _with_settings
        from clothtool.sweeps.capture import read_capture
        from clothtool.sweeps.capture import register as register_capture

        self.base = Path(config)
        self.settings = list(settings or ())
        loaded = read_yaml(self.base)
        raw = _with_settings(loaded, self.settings, apply_overrides)
        base_dir = self.base.parent.resolve()
        try:
            checked = load_config(copy.deepcopy(raw), base_dir=base_dir)
        except InputError as exc:
            raise InputError(f"{self.base}: {exc.format().removeprefix('config: ')}") from None
        parsed = spec.parse_ranges(ranges)
        if not parsed:
            raise InputError("give at least one key to fit (key=lo:hi[:log])", keyword="ranges",
                             value="")
        self.parameters, expanded = [], []
        given = {} if isinstance(ranges, dict) else {
            str(text).partition("=")[0].strip(): str(text) for text in
            ([ranges] if isinstance(ranges, str) else ranges)}
        for key, (lo, hi, scale) in parsed.items():
            shown = given.get(key) or (f"{key}={lo:g}:{hi:g}"
                                       + ("" if scale == "linear" else f":{scale}"))
            if scale == "int":
                raise InputError("a fitted value is a real number: give lo:hi or lo:hi:log",
                                 keyword="ranges", value=shown)
            if lo == hi:
                raise InputError("the range is a single value: nothing to fit (use --set)",
                                 keyword="ranges", value=shown)
            raw, current, pair = _numeric_key(raw, checked, key, shown, base_dir)
            if pair is not None:
                expanded.append(pair)
            for end in (lo, hi):
                _load_with(raw, key, end, base_dir, shown)
            start = current if lo <= current <= hi else (
                math.sqrt(lo * hi) if scale == "log" else 0.5 * (lo + hi))
            self.parameters.append(Parameter(key, lo, hi, scale == "log", float(start)))
        if outliers is not None and not (isinstance(outliers, (int, float)) and outliers > 0
                                         and math.isfinite(outliers)):
            raise InputError("must be a distance > 0 (m)", keyword="outliers", value=outliers)
        self.raw = raw  # the base with the settings and any [warp, weft] pair expanded
        self.base_dir = base_dir
        self.config = load_config(copy.deepcopy(raw), base_dir=base_dir)
        mesh = build_rest_mesh(self.config.mesh)
        count = self.config.time.frames // self.config.output.every + 1
        self.capture = read_capture(capture, count, mesh.positions, mesh.faces, compare)
        self.target = [str(Path(p).resolve()) for p in self.capture.paths]
        self.compare, self.outliers, self.max_simulations = compare, outliers, max_simulations
        self.register = register
        if isinstance(scan, bool) or not isinstance(scan, int) or scan < 0:
            raise InputError("must be a whole number ≥ 0", keyword="scan", value=scan)
        if scan ** len(self.parameters) > max_simulations:
            raise InputError(f"{scan}^{len(self.parameters)} = {scan ** len(self.parameters)} "
                             f"simulations, more than the budget of {max_simulations}",
                             keyword="scan", value=scan)
        self.scan = scan
        self.offset0, self.left0, self.shift, self.angle = register_capture(
            self.capture, mesh.positions, mesh.faces, move=register)
        # the sweeps' --set: the user's, then a number turned into its [warp, weft] pair
        self.sweep_settings = self.settings + [f"{k}={json.dumps(v)}" for k, v in expanded]

    @property
    def keys(self):
        return [p.key for p in self.parameters]

    def values(self, u):
        return [p.value(x) for p, x in zip(self.parameters, u)]

    def shown(self, u):
        return ", ".join(f"{p.key}={v:.4g}" for p, v in zip(self.parameters, self.values(u)))

    def describe(self):
        c = self.capture
        how = ("vertex for vertex" if c.mode == "vertex" else
               "surface to surface (each captured vertex to the simulated surface)")
        line = (f"fit: {len(self.parameters)} value{'s' if len(self.parameters) > 1 else ''} "
                f"from {len(c.frames) - 1} frames of {c.frames.shape[1]} captured vertices, "
                f"compared {how}")
        line += f"; frame 0 is {1000 * self.offset0:.3g} mm RMS from the config's initial state"
        if self.shift > 0.0 or self.angle > 0.0:
            line += (f", {1000 * self.left0:.3g} mm once moved rigidly onto it (by "
                     f"{1000 * self.shift:.3g} mm and {math.degrees(self.angle):.3g}°)")
        elif self.register and self.offset0 > 1e-9:
            line += ", not moved: no rigid motion stands out of its scatter"
        return line

    def record(self):
        return {"format": FORMAT, "config": str(self.base.resolve()), "base_config": self.raw,
                "target": self.target, "ranges": {p.key: [p.lo, p.hi, "log" if p.log else
                                                         "linear"] for p in self.parameters},
                "compare": self.capture.mode, "outliers": self.outliers,
                "register": self.register, "scan": self.scan}

    def claim(self, root):
        """``root`` is free for this fit (absent, empty or holding the same fit), then its
        record is written."""
        record = json.loads(json.dumps(self.record()))
        path = root / RECORD
        if root.exists():
            if not root.is_dir():
                raise InputError(f"{root}: exists and is not a folder")
            if path.is_file():
                try:
                    old = json.loads(path.read_text(encoding="utf-8"))
                except (OSError, ValueError) as exc:
                    raise InputError(f"{path}: cannot read: {exc}") from None
                if old != record:
                    raise InputError(f"{root}: holds a different fit (its config, capture, ranges "
                                     "or comparison differ); give another folder, or the same "
                                     "inputs to resume it")
                return
            if any(root.iterdir()):
                raise InputError(f"{root}: holds files but no fit ({RECORD}); give an empty or "
                                 "new folder")
        root.mkdir(parents=True, exist_ok=True)
        write_text(path, json.dumps(record, indent=1) + "\n")


def _numeric_key(raw, checked, key, shown, base_dir):
    """(raw, value, pair): the config's current value at ``key``, a number; a [warp, weft] key
    (``….0``, ``….1``) of a key the config gives as one number turns it into the pair
    (``pair``: (its key, [v, v]), else None)."""
    parts = key.split(".")
    node, pair = checked, None
    for depth, part in enumerate(parts):
        if isinstance(node, tuple) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif hasattr(node, "__dataclass_fields__") and part in node.__dataclass_fields__:
            node = getattr(node, part)
        elif hasattr(node, "__dataclass_fields__") and part == getattr(node, "kind", None):
            continue  # a tagged entry's tag: scene.colliders.0.sphere.friction
        elif (depth == len(parts) - 1 and part in ("0", "1") and isinstance(node, (int, float))
              and not isinstance(node, bool)):
            from clothtool.config_tools import assign

            pair = (".".join(parts[:-1]), [float(node), float(node)])
            raw = copy.deepcopy(raw)
            assign(raw, parts[:-1], pair[1], key)
        else:
            _load_with(raw, key, 1.0, base_dir, shown)  # the loader's message (did you mean …?)
            _not_numeric(key, shown, None)
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        _not_numeric(key, shown, node)
    return raw, float(node), pair


def _not_numeric(key, shown, node):
    if node is None:
        raise InputError(f"{key} is not a key of the config (a fitted key is a number of it, "
                         "e.g. material.bend)", keyword="ranges", value=shown)
    what = f"[warp, weft] pair: fit {key}.0 and {key}.1" if isinstance(node, tuple) else \
        f"{node!r}, not a number"
    raise InputError(f"{key} is {what}", keyword="ranges", value=shown)


def _load_with(raw, key, value, base_dir, shown):
    from clothtool.config_tools import assign
    from clothtool.sim.model.config import load_config

    config = copy.deepcopy(raw)
    try:
        assign(config, key.split("."), value, key)
        load_config(config, base_dir=base_dir)
    except InputError as exc:
        raise InputError(exc.format().removeprefix("config: "), keyword="ranges",
                         value=shown) from None
