"""Simulation config: YAML → validated, frozen dataclasses.

Every problem is an :class:`~clothtool.errors.InputError` whose one-line message
names the file and the dotted key (``material.stretch``), says what is wrong and,
for an unknown key, suggests the closest valid one (difflib).

Relative paths (``mesh.ply``, ``output.dir``) are resolved against the config
file's folder; a config given as a dict resolves them against the current folder.

PyYAML reads ``1e5`` (no dot) as a string; float keys accept such numeric
strings so that ``stretch: 1e5`` means what it says.
"""

from __future__ import annotations

import difflib
import math
import os
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Mapping

import yaml

from clothtool.errors import InputError
from clothtool.sim import methods

PLANES = ("xy", "xz", "yz")
BEND_MODELS = ("hessian", "dihedral", "quadratic")
STANDARD_GRAVITY = 9.81  # m/s², of bending_length → bend (k_b = ρ g c³)
METHODS = tuple(methods.METHODS)
PRECONDITIONERS = ("jacobi", "multigrid")
PBD_VARIANTS = ("gauss-seidel", "jacobi")
INTEGRATORS = ("bdf2", "euler")


# ---------------------------------------------------------------------------- schema
#
# Each dataclass field carries ``metadata["check"]``: a function (value, key) → value
# that converts and validates one YAML value. Nested sections are dataclasses.


def _number(*, minimum=None, exclusive=False, maximum=None):
    def check(value, key):
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise _type_error(key, "a number", value)
        try:
            value = float(value)
        except ValueError:
            raise _type_error(key, "a number", value) from None
        if not math.isfinite(value):
            raise InputError(f"{key} must be finite, got {value}")
        if minimum is not None and (value < minimum or (exclusive and value == minimum)):
            raise InputError(f"{key} must be {'>' if exclusive else '≥'} {minimum:g}, got {value:g}")
        if maximum is not None and value > maximum:
            raise InputError(f"{key} must be ≤ {maximum:g}, got {value:g}")
        return value
    return check


def _integer(*, minimum):
    def check(value, key):
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            else:
                raise _type_error(key, "an integer", value)
        if value < minimum:
            raise InputError(f"{key} must be ≥ {minimum}, got {value}")
        return value
    return check


def _warp_weft(*, exclusive):
    """A number (the same along u and v) or a list of two: [along u (warp), along v (weft)]."""
    number = _number(minimum=0, exclusive=exclusive)

    def check(value, key):
        if isinstance(value, (list, tuple)):
            if len(value) != 2:
                raise _type_error(key, "a number or a list of 2 numbers [warp, weft]", value)
            return tuple(number(v, f"{key}[{i}]") for i, v in enumerate(value))
        return number(value, key)
    return check


def _below_one(value, key):
    value = _number(minimum=0)(value, key)
    if value >= 1.0:
        raise InputError(f"{key} must be < 1, got {value:g}")
    return value


def _choice(options):
    def check(value, key):
        if value not in options:
            hint = _suggest(str(value), options)
            raise InputError(f"{key} must be one of {', '.join(options)}, got {value!r}{hint}")
        return value
    return check


def _flag(value, key):
    if not isinstance(value, bool):
        raise _type_error(key, "true or false", value)
    return value


def _path(value, key):
    if not isinstance(value, str) or not value:
        raise _type_error(key, "a path", value)
    return Path(value)


def _vector3(*, nonzero=False):
    number = _number()

    def check(value, key):
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise _type_error(key, "a list of 3 numbers", value)
        vec = tuple(number(v, f"{key}[{i}]") for i, v in enumerate(value))
        if nonzero and not any(vec):
            raise InputError(f"{key} must not be the zero vector")
        return vec
    return check


def _pin_vertices(value, key):
    """A pin-set name or a vertex index (indices are checked against the mesh later)."""
    from clothtool.sim.pins import PIN_SETS

    if isinstance(value, bool) or not isinstance(value, (int, str)):
        raise _type_error(key, "a pin-set name or a vertex index", value)
    if isinstance(value, str) and value not in PIN_SETS:
        raise InputError(f"{key}: unknown pin set {value!r}{_suggest(value, PIN_SETS)}"
                         f" (known: {', '.join(PIN_SETS)})")
    if isinstance(value, int) and value < 0:
        raise InputError(f"{key}: vertex index must be ≥ 0, got {value}")
    return value


def _pins(value, key):
    """Pin entries: set names, vertex indices, and moving groups ``{vertices: …, rotate: {…}}``
    or ``{vertices: …, translate: {…}}`` (:class:`PinGroup`)."""
    if not isinstance(value, list):
        raise _type_error(key, "a list of pin-set names, vertex indices and pin groups", value)
    out = []
    for i, item in enumerate(value):
        here = f"{key}[{i}]"
        if isinstance(item, dict):
            out.append(_pin_group(item, here))
        else:
            out.append(_pin_vertices(item, here))
    return tuple(out)


def _pin_group(raw, key):
    _check_keys(raw, {f.name for f in fields(PinGroup)}, key)
    if "vertices" not in raw:
        raise InputError(f"{key}: a pin group needs 'vertices' (a pin-set name or a list of "
                         "names and vertex indices)")
    vertices = raw["vertices"]
    if isinstance(vertices, list):
        if not vertices:
            raise InputError(f"{key}.vertices must not be empty")
        vertices = tuple(_pin_vertices(v, f"{key}.vertices[{j}]") for j, v in enumerate(vertices))
    else:
        vertices = (_pin_vertices(vertices, f"{key}.vertices"),)
    motions = [m for m in ("rotate", "translate") if raw.get(m) is not None]
    if len(motions) > 1:
        raise InputError(f"{key}: give at most one of rotate and translate")
    kwargs = {"vertices": vertices}
    for name in motions:
        body = raw[name]
        if not isinstance(body, dict):
            raise _type_error(f"{key}.{name}", "a mapping", body)
        cls = Rotate if name == "rotate" else Translate
        kwargs[name] = _build_section(cls, body, f"{key}.{name}", None)
    return PinGroup(**kwargs)


def _field(default, check, **kw):
    if isinstance(default, (list, dict)):
        return field(default_factory=lambda: default, metadata={"check": check}, **kw)
    return field(default=default, metadata={"check": check}, **kw)


@dataclass(frozen=True)
class GridSpec:
    """A regular grid of ``nx`` × ``ny`` vertices, centred, in ``plane``; row ny−1 is the top."""

    nx: int = _field(30, _integer(minimum=2))
    ny: int = _field(30, _integer(minimum=2))
    width: float = _field(1.0, _number(minimum=0, exclusive=True))
    height: float = _field(1.0, _number(minimum=0, exclusive=True))
    plane: str = _field("xy", _choice(PLANES))


@dataclass(frozen=True)
class MeshSpec:
    """Exactly one of ``grid`` and ``ply``. ``uv_scale``: metres per uv unit of a PLY's s,t."""

    grid: GridSpec | None = None
    ply: Path | None = _field(None, _path)
    uv_scale: float = _field(1.0, _number(minimum=0, exclusive=True))


@dataclass(frozen=True)
class Material:
    """Areal density (kg/m²), membrane stiffnesses (N/m), bending stiffness (N·m), damping (s).

    ``stretch`` and ``rest_stretch`` are a number or [along u (warp), along v (weft)];
    ``rest_stretch`` holds Baraff–Witkin's rest length factors b_u, b_v. ``bending_length``
    c (m, the cantilever test's) may replace ``bend``: k_b = ρ g c³ with g = 9.81 m/s².
    """

    density: float = _field(0.2, _number(minimum=0, exclusive=True))
    stretch: float | tuple = _field(5000.0, _warp_weft(exclusive=False))
    rest_stretch: float | tuple = _field(1.0, _warp_weft(exclusive=True))
    shear: float = _field(50.0, _number(minimum=0))
    bend: float = _field(1.0e-5, _number(minimum=0))
    damping: float = _field(0.01, _number(minimum=0))
    bend_model: str = _field("hessian", _choice(BEND_MODELS))
    bending_length: float | None = _field(None, _number(minimum=0))


@dataclass(frozen=True)
class Sphere:
    center: tuple = _field((0.0, 0.0, 0.0), _vector3())
    radius: float = _field(1.0, _number(minimum=0, exclusive=True))
    friction: float = _field(0.0, _number(minimum=0))


@dataclass(frozen=True)
class Plane:
    point: tuple = _field((0.0, 0.0, 0.0), _vector3())
    normal: tuple = _field((0.0, 1.0, 0.0), _vector3(nonzero=True))
    friction: float = _field(0.0, _number(minimum=0))


@dataclass(frozen=True)
class MeshCollider:
    """A triangle mesh: one ``ply`` or ``obj`` file (static), or a folder of ``frames`` (PLY or
    OBJ, one topology) shown at ``fps``, positions linear in time between frames, the last
    frame held after the end."""

    ply: Path | None = _field(None, _path)
    obj: Path | None = _field(None, _path)
    frames: Path | None = _field(None, _path)
    fps: float = _field(30.0, _number(minimum=0, exclusive=True))
    friction: float = _field(0.0, _number(minimum=0))

    @property
    def source(self):
        """(key, path) of the one mesh source given."""
        return next((k, getattr(self, k)) for k in ("ply", "obj", "frames") if getattr(self, k))


COLLIDER_KINDS = {"sphere": Sphere, "plane": Plane, "mesh": MeshCollider}


@dataclass(frozen=True)
class SelfCollision:
    """Cloth–cloth contact: surfaces kept ``thickness`` (m) apart, Coulomb ``friction``."""

    thickness: float = _field(0.002, _number(minimum=0, exclusive=True))
    friction: float = _field(0.0, _number(minimum=0))


@dataclass(frozen=True)
class Rotate:
    """Turn about the axis through ``center`` at ``speed`` rad/s (right-hand rule) until
    ``until`` s (None: the whole run)."""

    center: tuple = _field((0.0, 0.0, 0.0), _vector3())
    axis: tuple = _field((1.0, 0.0, 0.0), _vector3(nonzero=True))
    speed: float = _field(0.0, _number())
    until: float | None = _field(None, _number(minimum=0))


@dataclass(frozen=True)
class Translate:
    """Move at ``velocity`` m/s until ``until`` s (None: the whole run)."""

    velocity: tuple = _field((0.0, 0.0, 0.0), _vector3())
    until: float | None = _field(None, _number(minimum=0))


@dataclass(frozen=True)
class PinGroup:
    """Pinned vertices (set names and indices) on a rigid motion of their initial positions."""

    vertices: tuple = ()
    rotate: Rotate | None = None
    translate: Translate | None = None

    @property
    def motion(self):
        return self.rotate or self.translate


@dataclass(frozen=True)
class Scene:
    """``collision_margin`` (m): vertices are kept at least this far outside every collider
    (and the surfaces of cloth and mesh colliders this far apart); ``self_collision``:
    cloth–cloth contact, None = off."""

    gravity: tuple = _field((0.0, -9.81, 0.0), _vector3())
    pins: tuple = _field((), _pins)
    colliders: tuple = ()
    collision_margin: float = _field(1.0e-3, _number(minimum=0))
    self_collision: SelfCollision | None = None


@dataclass(frozen=True)
class Solver:
    """The time step and its solve.

    ``integrator``: ``bdf2`` (second order, the default) or ``euler`` (backward Euler),
    each the minimisation of its incremental potential by Newton's method: at most
    ``newton_iterations`` Newton steps per solver step, stopping when the largest
    velocity correction max|Δx|/h and the Newton decrement as a velocity
    √(Δxᵀ H Δx / free mass) are below ``newton_tolerance`` (m/s); each Newton
    step is a PCG solve whose relative residual ``tolerance`` is the finest it asks
    for (later Newton steps ask for less: Eisenstat–Walker); ``preconditioner`` is
    block Jacobi or an aggregation multigrid V-cycle. ``newton_iterations: 1`` is
    Baraff–Witkin's linearised step. A step whose speed exceeds ``max_speed`` (m/s)
    counts as a blow-up.

    ``method`` picks the solver (``clothtool.sim.solvers``, ``docs/solvers.md``):
    ``mass-spring`` uses the Newton/PCG keys above; ``pbd``, ``xpbd`` and
    ``projective`` run ``iterations`` sweeps per step; ``pbd`` also reads
    ``pbd_variant`` (gauss-seidel or jacobi), ``relaxation`` (Jacobi α),
    ``pbd_stiffness`` (0, 1] and ``strain_limit`` (ε: structural springs kept in
    [1 − ε, 1 + ε] of their rest length; 0 = off); ``explicit`` splits each step
    into internal steps of at most ``cfl`` × its estimated critical step (0 = off);
    ``vbd`` runs ``iterations`` vertex sweeps per step, Chebyshev-accelerated with
    spectral radius estimate ``chebyshev_rho`` (0 = off), stopping early once the
    gradient of the step's potential is below ``vbd_tolerance`` × ‖M g‖ (0 = off).
    """

    method: str = _field("implicit", _choice(METHODS))
    integrator: str = _field("bdf2", _choice(INTEGRATORS))
    substeps: int = _field(1, _integer(minimum=1))
    tolerance: float = _field(1.0e-6, _number(minimum=0, exclusive=True, maximum=1))
    max_iterations: int = _field(500, _integer(minimum=1))
    preconditioner: str = _field("multigrid", _choice(PRECONDITIONERS))
    newton_iterations: int = _field(20, _integer(minimum=1))
    newton_tolerance: float = _field(0.04, _number(minimum=0))
    line_search: bool = _field(True, _flag)
    max_speed: float = _field(1000.0, _number(minimum=0, exclusive=True))
    # the alternative methods (clothtool.sim.solvers, docs/solvers.md); ignored by the others
    iterations: int = _field(10, _integer(minimum=1))  # pbd, xpbd, projective, vbd: sweeps per step
    pbd_variant: str = _field("gauss-seidel", _choice(PBD_VARIANTS))  # pbd
    relaxation: float = _field(1.0, _number(minimum=0))  # pbd jacobi: α in Σ Δ / (n_i + α)
    pbd_stiffness: float = _field(1.0, _number(minimum=0, exclusive=True, maximum=1))  # pbd
    strain_limit: float = _field(0.0, _number(minimum=0, maximum=1))  # pbd: ε, 0 = off
    cfl: float = _field(0.5, _number(minimum=0, maximum=1))  # explicit: 0 = no automatic steps
    chebyshev_rho: float = _field(0.9, _below_one)  # vbd: Chebyshev ρ in [0, 1), 0 = off
    vbd_tolerance: float = _field(0.0, _number(minimum=0))  # vbd: stop at ‖∇E‖/‖Mg‖ ≤ this, 0 = off


@dataclass(frozen=True)
class Time:
    fps: float = _field(30.0, _number(minimum=0, exclusive=True))
    frames: int = _field(120, _integer(minimum=0))


@dataclass(frozen=True)
class Output:
    dir: Path = _field(Path("out"), _path)
    every: int = _field(1, _integer(minimum=1))


@dataclass(frozen=True)
class Config:
    mesh: MeshSpec
    material: Material = field(default_factory=Material)
    scene: Scene = field(default_factory=Scene)
    solver: Solver = field(default_factory=Solver)
    time: Time = field(default_factory=Time)
    output: Output = field(default_factory=Output)
    source: Path | None = None  # the config file, for messages; None for a dict

    @property
    def step(self):
        """Solver time step h = 1 / (fps · substeps), seconds."""
        return 1.0 / (self.time.fps * self.solver.substeps)


SECTIONS = {"mesh": MeshSpec, "material": Material, "scene": Scene,
            "solver": Solver, "time": Time, "output": Output}


# ---------------------------------------------------------------------------- loading


def load_config(config, *, overrides=None) -> Config:
    """Read and validate a config: a YAML path, or an already-parsed dict.

    ``overrides``, applied before validation: a mapping of dotted keys → values
    (``{"material.stretch": 1e5}``; string values are read as YAML scalars), or a
    list of ``"key=value"`` strings as ``--set`` gives them
    (:func:`clothtool.config_tools.apply_overrides`, which also indexes lists).
    """
    if isinstance(config, Mapping):
        raw, source, base = _deep_copy(config), None, Path.cwd()
    else:
        source = Path(os.fspath(config))
        raw = _read_yaml(source)
        base = source.parent
    if isinstance(overrides, Mapping):
        for dotted, value in overrides.items():
            _apply_override(raw, dotted, value)
    elif overrides:
        from clothtool.config_tools import apply_overrides

        raw = apply_overrides(raw, list(overrides))
    label = str(source) if source is not None else "config"
    try:
        cfg = _build_config(raw, base)
    except InputError as exc:
        raise InputError(f"{label}: {exc}") from None
    return Config(**{f.name: getattr(cfg, f.name) for f in fields(cfg) if f.name != "source"},
                  source=source)


def _read_yaml(path: Path):
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: config file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, not a config file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read config: {exc}") from None
    try:
        raw = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"{path}:{where}: YAML syntax error: {problem}") from None
    except RecursionError:
        raise InputError(f"{path}: YAML nested too deeply to be a config") from None
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise InputError(f"{path}: a config is a mapping of sections (mesh, material, …), "
                         f"got {type(raw).__name__}")
    return raw


def _apply_override(raw, dotted, value):
    if isinstance(value, str):
        try:
            value = yaml.safe_load(value)
        except yaml.YAMLError:
            raise InputError(f"--set {dotted}: cannot read value {value!r}") from None
    parts = dotted.split(".")
    node = raw
    for depth, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        if not isinstance(child, dict):
            raise InputError(f"--set {dotted}: {'.'.join(parts[:depth + 1])} is not a section")
        node = child
    node[parts[-1]] = value


def _build_config(raw, base):
    _check_keys(raw, SECTIONS, "")
    if "mesh" not in raw:
        raise InputError("missing section 'mesh' (give mesh.grid or mesh.ply)")
    sections = {}
    for name, cls in SECTIONS.items():
        value = raw.get(name, {})
        if value is None:
            value = {}
        if not isinstance(value, dict):
            raise _type_error(name, "a mapping", value)
        sections[name] = _build_section(cls, value, name, base)
    config = Config(**sections)
    _check_contact_scene(config.scene)
    given = {f"{name}.{key}" for name, section in raw.items() if isinstance(section, dict)
             for key in section}
    methods.check_supported(config, given)
    return config


def _check_contact_scene(scene):
    """Spheres and planes (vertex constraints, projected after the step) cannot share a scene
    with mesh colliders or self-collision (barrier contact, no projection)."""
    meshes = any(isinstance(c, MeshCollider) for c in scene.colliders)
    if not (meshes or scene.self_collision is not None):
        return
    for i, c in enumerate(scene.colliders):
        if not isinstance(c, MeshCollider):
            kind = "sphere" if isinstance(c, Sphere) else "plane"
            with_what = "mesh colliders" if meshes else "scene.self_collision"
            raise InputError(f"scene.colliders[{i}].{kind}: spheres and planes cannot be combined "
                             f"with {with_what}; give this collider as a mesh")


def _build_section(cls, raw, prefix, base):
    _check_keys(raw, {f.name for f in fields(cls)}, prefix)
    kwargs = {}
    for f in fields(cls):
        if f.name not in raw:
            continue
        key = f"{prefix}.{f.name}"
        value = raw[f.name]
        if cls is MeshSpec and f.name == "grid":
            if not isinstance(value, dict):
                raise _type_error(key, "a mapping", value)
            kwargs["grid"] = _build_section(GridSpec, value, key, base)
        elif cls is Scene and f.name == "colliders":
            kwargs["colliders"] = _build_colliders(value, key, base)
        elif cls is Scene and f.name == "self_collision":
            if value is None:
                continue
            if not isinstance(value, dict):
                raise _type_error(key, "a mapping (thickness, friction)", value)
            kwargs["self_collision"] = _build_section(SelfCollision, value, key, base)
        elif value is None and f.default is None:
            continue
        else:
            kwargs[f.name] = f.metadata["check"](value, key)
    section = cls(**kwargs)
    if cls is Material and section.bending_length is not None:
        section = _bend_from_bending_length(section, raw, prefix)
    if cls is MeshSpec:
        if (section.grid is None) == (section.ply is None):
            raise InputError("mesh needs exactly one of mesh.grid and mesh.ply")
        if section.ply is not None:
            section = MeshSpec(ply=base / section.ply, uv_scale=section.uv_scale)
    if cls is Output:
        section = Output(dir=base / section.dir, every=section.every)
    if cls is MeshCollider:
        given = [k for k in ("ply", "obj", "frames") if getattr(section, k) is not None]
        if len(given) != 1:
            raise InputError(f"{prefix} needs exactly one of ply, obj and frames")
        if "fps" in raw and given[0] != "frames":
            raise InputError(f"{prefix}.fps applies to frames only")
        section = MeshCollider(**{**{f.name: getattr(section, f.name) for f in fields(section)},
                                  given[0]: base / getattr(section, given[0])})
    return section


def _bend_from_bending_length(material, raw, prefix):
    """``bend`` = ρ g c³ from ``bending_length`` c and ``density`` ρ (not both bend and c)."""
    if "bend" in raw:
        raise InputError(f"{prefix}: give one of bend (N·m) and bending_length (m), not both")
    c = material.bending_length
    return replace(material, bend=material.density * STANDARD_GRAVITY * c ** 3)


def _build_colliders(value, key, base):
    if value is None:
        return ()
    if not isinstance(value, list):
        raise _type_error(key, "a list of colliders (- sphere: {...}, - plane: {...} or "
                          "- mesh: {...})", value)
    out = []
    for i, item in enumerate(value):
        here = f"{key}[{i}]"
        if not isinstance(item, dict) or len(item) != 1:
            raise _type_error(here, "one of sphere: {...}, plane: {...}, mesh: {...}", item)
        (kind, body), = item.items()
        if kind not in COLLIDER_KINDS:
            raise InputError(f"{here}: unknown collider {kind!r}{_suggest(str(kind), COLLIDER_KINDS)}")
        if not isinstance(body, dict):
            raise _type_error(f"{here}.{kind}", "a mapping", body)
        out.append(_build_section(COLLIDER_KINDS[kind], body, f"{here}.{kind}", base))
    return tuple(out)


def _check_keys(raw, valid, prefix):
    for key in raw:
        if key not in valid:
            name = f"{prefix}.{key}" if prefix else str(key)
            raise InputError(f"unknown key '{name}'{_suggest(str(key), valid)}")


def _suggest(word, options):
    close = difflib.get_close_matches(word, list(options), n=1, cutoff=0.5)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _type_error(key, expected, value):
    shown = repr(value)
    if len(shown) > 40:
        shown = shown[:37] + "..."
    return InputError(f"{key} must be {expected}, got {shown}")


def _deep_copy(value):
    if isinstance(value, Mapping):
        return {k: _deep_copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_deep_copy(v) for v in value]
    return value


def as_dict(obj):
    """A config (or section) as plain Python data, e.g. to record it beside the output."""
    if is_dataclass(obj):
        return {f.name: as_dict(getattr(obj, f.name)) for f in fields(obj)}
    if isinstance(obj, tuple):
        return [as_dict(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    return obj
