"""Config helpers for parameter sweeps: ``simulate --set key=value`` overrides and the
commented default config printed by ``clothtool init-config``.

An override is ``dotted.key=value``: the key walks nested mappings (a missing mapping is
created, so ``--set solver.substeps=4`` works when the file has no ``solver`` section) and
integer parts index lists (``scene.gravity.1=-3.7``); the value is parsed as YAML, so
``5e3`` is a float (YAML 1.2 style; PyYAML alone would read it as a string), ``[0, -9.81, 0]`` a list, ``true`` a bool and ``plane`` a string.
Whether the key and value are valid is the config loader's business (it names the key).
"""

import copy
import re

import yaml

from clothtool.errors import InputError

DEFAULT_CONFIG = """\
# clothtool simulation config: every key with its default (docs/simulate.md has them all).
# SI units: metres, kilograms, seconds.
# Run it with:  clothtool simulate config.yaml   (override entries with --set key=value)
# Paths are relative to this file's folder.

mesh:
  # a regular grid: nx × ny vertices (at least 2 each), centred on the origin in the named
  # plane (xy, xz or yz), `width` along its first axis and `height` along its second;
  # row j = ny − 1 is the top row, vertex index = j·nx + i. Here a horizontal sheet (xz)
  # that hangs from two corners and drapes over the sphere (an upright xy sheet would
  # start inside it)
  grid: {nx: 30, ny: 30, width: 1.0, height: 1.0, plane: xz}
  # or a mesh file instead of `grid` (its s,t / u,v texture coordinates, when present,
  # are the rest shape, in metres per uv unit times uv_scale):
  # ply: rest.ply
  # uv_scale: 1.0
  # a garment (implicit): an OBJ whose per-corner vt × uv_scale are each triangle's rest
  # shape, with its panels' seams sewn and welded (needs scene.self_collision):
  # obj: garment.obj
  # seams: [{a: [10, 11, 12], b: [40, 41, 42]}]   # vertex a[i] sewn to b[i]
  # seam_tolerance: 0.02                        # the sides' rest lengths may differ by 2 %
  # sewing: {stiffness: 1000.0, weld: null, time: 2.0, gravity: false}   # stiffness doubled
  #                                           # for a pair behind its goal, so seams close in time
  # weld_closed: true       # seams closed in the file (panels' coincident boundary vertices,
  # weld_tolerance: 1.0e-4  # within this many m) are welded at the start

material:
  density: 0.2          # kg/m², areal mass density
  stretch: 5000.0       # N/m, membrane stiffness: one number, or [warp, weft] (along u, along v)
  rest_stretch: 1.0     # rest length factors b_u, b_v: one number or [b_u, b_v]; 1.1 = rests 10 % longer
  shear: 50.0           # N/m, in-plane shear stiffness
  bend: 1.0e-5          # N·m, flexural rigidity: one number or [warp, weft] (or bending_length: c in m, bend = ρ g c³)
  damping: 0.01         # s, β of the damping (damping_model); 0 = none
  bend_model: hessian   # hessian (plate: the stated rigidity on any flat-resting mesh), dihedral (hinges) or quadratic
  damping_model: strain # strain (stretch, shear and bending damped by their change over the step: a rigid motion feels none; the other methods use their own βK) or frozen (βK at the step's start: resists rotation, the cloth creeps)
  bending_length: null  # m, instead of bend: the cantilever test's c, bend = density · 9.81 · c³
  plate_correction: false  # hessian plate: add back the energy its smoothing loses (folds a few triangles wide); fitted: β fitted on the mesh
  membrane_model: triangle  # triangle, nodal (stretch smoothed per vertex and panel: drapes alike on any mesh) or edge (stretch and shear smoothed per edge, any mesh)
  preset: null          # a measured fabric (clothtool fabric --list): fills the keys not given here
  kes: null             # KES-F values {B: gf·cm²/cm, G: gf/cm·deg, EMT: %, W: mg/cm²} for those keys
  # stiffnesses are per unit area (energy density integrated over the rest area), so
  # refining the mesh converges to the same shape instead of changing it

materials: {}         # per panel (an OBJ g or usemtl name, or {faces: [...]}): keys of material, e.g. {sleeve: {stretch: 2000.0}}

scene:
  gravity: [0, -9.81, 0]        # m/s²
  pins: [top_corners]           # named vertex sets and/or vertex indices held in place
  # moving pins (implicit): a group of vertices on a rigid motion of their initial positions,
  #   - {vertices: left_edge, rotate: {center: [0, 0, 0], axis: [1, 0, 0], speed: 1.0472, until: 10.0}}
  #   - {vertices: [12, 13], translate: {velocity: [0, 0, 0.5], until: 2.0}}
  colliders:
    - sphere: {center: [0, -0.5, 0], radius: 0.3}   # each may also set friction: 0.0
    - plane: {point: [0, -1, 0], normal: [0, 1, 0]}  # the cloth stays on the side n points to
    # more kinds, in any mix (implicit; the other methods project onto spheres and planes only):
    #   - capsule: {a: [-0.3, -0.6, 0], b: [0.3, -0.6, 0], radius: 0.1}
    #   - box: {center: [0, -0.8, 0], size: [1, 0.2, 1], axis: [0, 1, 0], angle: 0.0}
    #   - mesh: {ply: body.ply, friction: 0.3}      (or obj: body.obj), static, or animated:
    #   - mesh: {frames: body/, fps: 30, friction: 0.3}
    # every collider may move rigidly (implicit), e.g. a sphere turning at 180°/s:
    #   - sphere: {center: [0, -0.5, 0], radius: 0.3, friction: 0.4,
    #              motion: {rotate: {center: [0, -0.5, 0], axis: [0, 1, 0], speed: 3.1416}}}
    # (motion: {rotate: {center, axis, speed, until}, translate: {velocity, until}}, both allowed)
  collision_margin: 2.0e-3      # m, cloth rests this far from a collider surface (implicit:
                                # never closer than margin − activation_distance)
  activation_distance: null     # m, depth of the contact barrier's wall inside the margin;
                                # null = ¾ of the margin (and of the self-collision thickness)
  self_collision: null          # cloth–cloth contact (implicit), e.g. {thickness: 0.002, friction: 0.2}
  attach: []                    # garment vertices carried by a collider (implicit), e.g. {vertices: [0, 1], to: 0}

solver:
  method: implicit      # implicit (Baraff–Witkin), mass-spring, pbd, xpbd, projective, explicit, vbd (docs/solvers.md)
  integrator: bdf2      # implicit, mass-spring: bdf2 (second order) or euler (backward Euler)
  substeps: 1           # solver steps per frame
  tolerance: 1.0e-6     # relative residual of the linear solve (the first Newton step's; later ones ask less)
  max_iterations: 500   # conjugate-gradient iterations per solve, at most
  preconditioner: auto  # auto (amg on stiff models, multigrid on soft ones), multigrid (aggregation V-cycle), amg (rigid and shear modes), hybrid or jacobi
  newton_iterations: 20 # Newton steps per solver step, at most (1 = Baraff–Witkin's linearised step)
  newton_tolerance: 0.04  # m/s, Newton stops when the largest velocity correction max|Δx|/h is below
  friction_velocity: 1.0e-4  # m/s, contact friction holds below this sliding speed (IPC's ε_v)
  overshoot_bound: false  # contact friction: a slip a Newton step turned over takes the bound's curvature
  slow_slip_bound: 0.0  # m/s, contact friction: slips slower than this take the bound's curvature (0 = off)
  forcing_from_second: false  # contact: the linear solves' Eisenstat–Walker ratio starts at Newton's second iterate
  short_step_forcing: false  # after a step the line search shortened to s, the next linear solve asks for s times the forcing
  first_forcing: 0.0  # contact: Newton's first linear solve of a step asks for this relative residual (0 = solver.tolerance)
  first_cut_iterations: 20  # contact: Newton's first linear solve of a step stops after this many iterations when CCD cuts its guess short (not while sewing; 0 = off)
  friction_velocity_test: false  # contact: with lagged friction pairs, Newton stops once its whole proposal's max|Δx|/h is below newton_tolerance (IPC's test, no decrement)
  line_search: true     # backtracking line search on the Newton steps
  stiffness_continuation: auto  # implicit: solve each step first with the membrane 10^n … 10× softer (stiff cloth at large steps); auto = n from k·ĥ²/m; 0 = off
  continuation_after: 20  # with stiffness_continuation: only solves Newton alone stalls on (unconverged after this many steps, half of them stiffness-bound); 0 = every solve
  max_speed: 1000.0     # m/s, a faster vertex counts as a blow-up (exit code 3)
  iterations: 10        # pbd, xpbd, projective, vbd: constraint sweeps / local-global iterations / vertex sweeps per step
  pbd_variant: gauss-seidel  # pbd: gauss-seidel (symmetric sweeps), jacobi or hierarchical
  relaxation: 1.0       # pbd jacobi: α in x_i += Σ corrections / (n_i + α)
  pbd_stiffness: 1.0    # pbd: per-constraint stiffness in (0, 1]
  strain_limit: 0.0     # pbd: keep edges within [1 − ε, 1 + ε] of rest length; 0 = off
  cfl: 0.5              # explicit: internal steps of at most cfl × the critical step; 0 = off
  chebyshev_rho: 0.9    # vbd: Chebyshev acceleration with spectral radius estimate ρ in [0, 1), from 5 sweeps per step; 0 = off
  vbd_tolerance: 0.0    # vbd: stop a step's sweeps once ‖∇E‖/‖M g‖ ≤ this; 0 = always `iterations` sweeps

time:
  fps: 30               # frames per second of simulated time
  frames: 120           # frames to simulate after the initial state

output:
  dir: out/             # frame_00000.ply (initial state), frame_00001.ply, …, stats.csv
  every: 1              # write every n-th frame
  format: [ply]         # some of ply (frames here), obj (obj/, uv per corner), mdd (cache/cloth.mdd: one point cache + its base mesh cache/cloth.obj)
"""


class _ValueLoader(yaml.SafeLoader):
    """PyYAML's safe loader that also reads exponent floats without a dot (``2e4``)."""


_ValueLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def _error(detail, label, culprit):
    """An InputError: ``label: detail``, or the detail with the keyword arguments ``culprit``
    (keyword, value) that the CLI spells as its option."""
    return InputError(f"{label}: {detail}" if label else detail, **culprit)


def parse_value(raw, label=None, **culprit):
    """A value as YAML (``2e4`` a float, ``[0, -9.81, 0]`` a list, ``xz`` a string); an
    :class:`InputError` starts with ``label`` or carries ``culprit`` (keyword, value)."""
    try:
        return yaml.load(raw, Loader=_ValueLoader)
    except yaml.YAMLError as exc:
        problem = getattr(exc, "problem", None) or "not valid YAML"
        raise _error(f"value {raw!r} is {problem}", label, culprit) from None


def parse_assignment(text):
    """'a.b.c=value' → (['a', 'b', 'c'], parsed value). Errors carry the keyword ``overrides``
    (the argument of :func:`apply_overrides` and of ``load_config``; the CLI's ``--set``)."""
    culprit = {"keyword": "overrides", "value": repr(text)}
    key, sep, raw = text.partition("=")
    parts = key.strip().split(".")
    if not sep or not all(p.strip() for p in parts):
        raise InputError("expected dotted.key=value, e.g. material.stretch=2e4", **culprit)
    if not raw.strip():
        raise InputError("no value after '='", **culprit)
    return [p.strip() for p in parts], parse_value(raw, **culprit)


def apply_overrides(config, overrides):
    """A deep copy of the mapping ``config`` with each ``key=value`` of ``overrides`` applied
    in order (later ones win)."""
    result = copy.deepcopy(config) if config is not None else {}
    for text in overrides:
        parts, value = parse_assignment(text)
        assign(result, parts, value, keyword="overrides", value=repr(text))
    return result


def assign(config, parts, item, label=None, **culprit):
    """Set the entry of the nested mapping ``config`` at the key path ``parts`` (mappings
    created as needed, integer parts index lists) to ``item``, in place; an
    :class:`InputError` when a part does not fit starts with ``label`` or carries
    ``culprit`` (keyword, value)."""
    node = config
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join(parts[:depth]) or "the config"
        if isinstance(node, dict):
            if last:
                node[part] = item
            else:
                if node.get(part) is None:
                    node[part] = {}
                node = node[part]
        elif isinstance(node, list):
            if not (part.lstrip("-").isdigit() and -len(node) <= int(part) < len(node)):
                raise _error(f"{where} is a list of {len(node)}; {part!r} is not an index into "
                             "it", label, culprit)
            if last:
                node[int(part)] = item
            else:
                node = node[int(part)]
        else:
            raise _error(f"{where} is {node!r}, not a mapping", label, culprit)