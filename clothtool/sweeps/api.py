"""``clothtool.sweep``: expand a base config into runs, record them, run them (a local
process pool) or write a Slurm job array for them; resume what is not done."""

import copy
import json
import shlex
import time
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path

from clothtool.errors import InputError
from clothtool.sweeps import spec
from clothtool.sweeps.layout import FORMAT, SweepFolder, format_value, run_ids

ANALYSIS_FIELDS = "stretch,area_ratio,flags"  # what the report's percentiles need


@dataclass
class SweepResult:
    """What :func:`sweep` did. ``failed``: run → its one-line error (this call's and
    earlier calls' failures); ``sbatch``: the command that submits the Slurm array."""

    output_dir: Path
    runs: int
    done: int
    ran: int
    failed: dict = field(default_factory=dict)
    seconds: float = 0.0
    script: Path | None = None
    tasks: int = 0
    sbatch: str | None = None
    todo: int = 0  # runs the Slurm script runs

    def describe(self):
        if self.script is not None:
            return (f"wrote {self.script}: {self.todo} of {self.runs} runs to do in "
                    f"{self.tasks} array tasks; submit with\n"
                    f"  {self.sbatch}\nthen, once all tasks have ended: clothtool sweep-report "
                    f"{self.output_dir}")
        lines = [f"{self.output_dir}/: {self.runs} runs, {self.done} done, {len(self.failed)} failed"
                 f" ({self.ran} ran now, in {self.seconds:.1f} s); "
                 f"table: clothtool sweep-report {self.output_dir}"]
        lines += [f"  {run}: {error}" for run, error in self.failed.items()]
        return "\n".join(lines)


def sweep(base, output_dir, *, grid=None, zip=None, random=None, ranges=None, seed=None,
          settings=None, jobs=1, slurm=False, per_task=1, analyze=False,
          fields=ANALYSIS_FIELDS, retry_failed=False, on_done=None, pool=None):
    """Run (or, with ``slurm``, prepare) a parameter sweep over the config file ``base``.

    ``grid``: {dotted key: [values]} or ``["key=v1,v2", …]``, the product of the lists;
    ``zip``: the same, lists taken element by element (equal lengths); ``random``: a number
    of samples of ``ranges`` ({key: (lo, hi[, 'log'|'int'])} or ``["key=lo:hi[:log]"]``)
    drawn with ``seed`` (required); the runs are the product of the three
    (:mod:`clothtool.sweeps.spec`). ``settings``: ``["key=value"]`` applied to every run.
    Every run's config is checked before anything is written; an unknown key or bad
    value is an :class:`~clothtool.errors.InputError` naming the keyword and key.

    Writes ``output_dir/`` (:mod:`clothtool.sweeps.layout`). Runs not done run on ``jobs``
    processes (:mod:`clothtool.sweeps.pool`); a run that fails is recorded with its error
    and the sweep goes on; done runs are skipped, failed ones too unless ``retry_failed``.
    ``slurm``: write ``output_dir/sweep.sbatch`` (``per_task`` runs per array task) instead
    of running (:mod:`clothtool.sweeps.slurm`). ``analyze``: analyse each run's frames
    against the rest pattern (``reference='uv'``, ``fields``) into ``run_…/analysis.h5``.
    ``on_done(run, status)`` is called as each run ends. ``pool``: a running
    :class:`~clothtool.sweeps.pool.Pool` (made with the same analysis) to run the runs on in
    place of a pool of ``jobs`` of its own; it is left running. Returns a :class:`SweepResult`.
    """
    started = time.perf_counter()
    for name, value in (("jobs", jobs), ("per_task", per_task)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError("must be a positive integer", keyword=name, value=value)
    analysis = None
    if analyze:
        from clothtool.fields import parse_fields

        try:
            names = parse_fields(fields)
        except InputError as exc:
            if exc.mentions:  # a 3D field: the run's analysis is the 2D one against the uv
                raise InputError(exc.detail.split(";")[0] + ", which a sweep's analysis does "
                                 "not run; choose among the 2D fields", keyword="fields",
                                 value=fields) from None
            raise InputError(exc.detail, keyword="fields", value=fields) from None
        analysis = {"reference": "uv", "fields": ",".join(names)}
    # the pool process starts now, so that its imports overlap the checks and the writing
    own = pool is None and jobs > 1 and not slurm
    if own:
        from clothtool.sweeps.pool import Pool

        pool = Pool(analysis, jobs)
    try:
        record, configs, methods = plan(base, grid=grid, zipped=zip, random=random,
                                        ranges=ranges, seed=seed, settings=settings,
                                        analysis=analysis)
        folder = SweepFolder(output_dir)
        folder.check_new_or_same(record)

        folder.write_record(record)
        for run in record["runs"]:
            folder.write_run_config(run["run"], configs[run["run"]])
        statuses = folder.statuses(record)
        folder.write_manifest(record, statuses)
        todo = [r for r, st in statuses.items() if st is None
                or (retry_failed and st.get("status") == "failed")]
        result = SweepResult(folder.root, len(statuses), 0, 0)

        if slurm:
            from clothtool.sweeps.slurm import write_script

            _count(result, statuses, todo)
            result.todo = len(todo)
            if todo:
                result.script, result.tasks = write_script(folder.root, todo, per_task)
                result.sbatch = f"sbatch {shlex.quote(str(result.script))}"
            return result

        def done(run, status):
            statuses[run] = status
            folder.write_manifest(record, statuses)
            result.ran += 1
            if on_done is not None:
                on_done(run, status)

        if pool is not None and not slurm:
            if todo:
                pool.run(folder.root, todo, methods, done)
        else:
            from clothtool.sweeps.run import run_one

            for run in todo:
                done(run, run_one(folder.root, run, analysis))
    finally:
        if own:
            pool.close()
    _count(result, statuses, [])
    result.seconds = time.perf_counter() - started
    return result


def _count(result, statuses, todo):
    result.done = sum(1 for st in statuses.values() if st and st.get("status") == "done")
    result.failed = {r: st.get("error", "") for r, st in statuses.items()
                     if st and st.get("status") == "failed" and r not in todo}


def plan(base, *, grid=None, zipped=None, random=None, ranges=None, seed=None, settings=None,
         analysis=None):
    """The sweep's record (what ``sweep.json`` holds), each run's resolved config, and the
    ``solver.method`` names the runs use; every config checked, its pins against its mesh
    as well (what the run would refuse when it builds its model). Nothing is written."""
    from clothtool.config_tools import apply_overrides, assign
    from clothtool.sim.model.config import load_config, read_yaml

    base = Path(base)
    base_dir = base.parent.resolve()
    meshes = {}  # mesh file → its vertex count
    loaded = read_yaml(base)
    raw = _with_settings(loaded, settings, apply_overrides)
    rows = spec.expand(grid, zipped, random, ranges, seed)
    origin = {**{k: "grid" for k in spec.parse_lists(grid, "grid")},
              **{k: "zip" for k in spec.parse_lists(zipped, "zip")},
              **{k: "ranges" for k in spec.parse_ranges(ranges)}}
    ids = run_ids(len(rows))

    def load(params, where, keyword=None, start=raw):
        """(raw, Config) of ``start`` with ``params``; an error starts with ``where`` (or is
        about ``keyword``, with ``where`` as its value)."""
        config = copy.deepcopy(start)
        try:
            for key, value in params.items():
                assign(config, key.split("."), value, key)
            checked = load_config(config, base_dir=base_dir)
            _check_pins(checked, meshes)
            return config, checked
        except InputError as exc:
            detail = exc.format().removeprefix("config: ")
            if keyword is None:
                raise InputError(f"{where}: {detail}") from None
            raise InputError(detail, keyword=keyword, value=where) from None

    load({}, str(base), start=loaded)  # the base itself
    for i in range(len(settings or ())):  # then each setting on it, so that an error names it
        load({}, settings[i], "settings", start=_with_settings(loaded, settings[:i + 1],
                                                                apply_overrides))
    # each swept value alone (a range: its ends), so that an error names the keyword and key
    for key, kind in origin.items():
        if kind == "ranges":
            lo, hi, scale = spec.parse_ranges(ranges)[key]
            values = [int(lo), int(hi)] if scale == "int" else [lo, hi]
        else:
            values = spec.parse_lists(grid if kind == "grid" else zipped, kind)[key]
        for value in values:
            load({key: value}, f"{key}={format_value(value)}", kind)
    configs, methods = {}, set()
    for run, params in zip(ids, rows):
        shown = ", ".join(f"{k}={format_value(v)}" for k, v in params.items())
        config, checked = load(params, f"{run} ({shown})")
        methods.add(checked.solver.method)
        resolved = _with_resolved_paths(config, checked)
        if not isinstance(resolved.get("output"), dict):
            resolved["output"] = {}
        resolved["output"]["dir"] = "."
        configs[run] = resolved
    record = {"format": FORMAT, "base": str(base.resolve()), "base_config": raw,
              "parameters": list(origin), "runs": [{"run": r, "params": p} for r, p in zip(ids, rows)],
              "analysis": analysis}
    try:
        record = json.loads(json.dumps(record))
    except (TypeError, ValueError) as exc:
        raise InputError(f"{base}: a value cannot be recorded: {exc}") from None
    return record, configs, methods


def _with_settings(raw, settings, apply_overrides):
    """The base config ``raw`` with the ``settings`` (``key=value`` strings) applied; an
    error names the keyword ``settings``."""
    if not settings:
        return raw
    try:
        return apply_overrides(raw, list(settings))
    except InputError as exc:
        raise InputError(exc.detail, keyword="settings", value=exc.value,
                         mentions=exc.mentions) from None


def _check_pins(config, meshes):
    """The pins of a loaded config resolve on its mesh (named sets need a grid, indices must
    exist), as :func:`clothtool.sim.model.builder.build_model` checks them; ``meshes`` caches the
    vertex count of each mesh file."""
    from clothtool.sim.model.motion import resolve_pin_entries

    grid = config.mesh.grid
    if grid is not None:
        count, shape = grid.nx * grid.ny, (grid.nx, grid.ny)
    else:
        path = config.mesh.ply
        if path not in meshes:
            from clothtool.io.ply import read_ply

            meshes[path] = len(read_ply(path).vertices)
        count, shape = meshes[path], None
    resolve_pin_entries(config.scene.pins, count, shape)


def _with_resolved_paths(raw, config):
    """``raw`` with each relative path replaced by the absolute path the loader resolved
    (``config``, the loaded :class:`~clothtool.sim.model.config.Config`), so that the run's
    config means the same from its own folder."""
    if isinstance(raw, dict) and is_dataclass(config):
        names = {f.name for f in fields(config)}
        if len(raw) == 1 and not names & set(raw):  # a tagged entry: {sphere: {...}}
            (tag, body), = raw.items()
            return {tag: _with_resolved_paths(body, config)}
        return {k: _with_resolved_paths(v, getattr(config, k)) if k in names else v
                for k, v in raw.items()}
    if isinstance(raw, list) and isinstance(config, tuple) and len(raw) == len(config):
        return [_with_resolved_paths(r, c) for r, c in zip(raw, config)]
    if isinstance(raw, str) and isinstance(config, Path):
        return str(config)
    return raw
