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

material:
  density: 0.2          # kg/m², areal mass density
  stretch: 5000.0       # N/m, membrane stiffness: one number, or [warp, weft] (along u, along v)
  rest_stretch: 1.0     # rest length factors b_u, b_v: one number or [b_u, b_v]; 1.1 = rests 10 % longer
  shear: 50.0           # N/m, in-plane shear stiffness
  bend: 1.0e-5          # N·m, flexural rigidity (or bending_length: c in m, bend = ρ g c³)
  damping: 0.01         # s, stiffness-proportional damping; 0 = none
  bend_model: hessian   # hessian (plate), dihedral (angle-based; curved rest meshes) or quadratic
  bending_length: null  # m, instead of bend: the cantilever test's c, bend = density · 9.81 · c³
  # stiffnesses are per unit area (energy density integrated over the rest area), so
  # refining the mesh converges to the same shape instead of changing it

scene:
  gravity: [0, -9.81, 0]        # m/s²
  pins: [top_corners]           # named vertex sets and/or vertex indices held in place
  # moving pins (implicit): a group of vertices on a rigid motion of their initial positions,
  #   - {vertices: left_edge, rotate: {center: [0, 0, 0], axis: [1, 0, 0], speed: 1.0472, until: 10.0}}
  #   - {vertices: [12, 13], translate: {velocity: [0, 0, 0.5], until: 2.0}}
  colliders:
    - sphere: {center: [0, -0.5, 0], radius: 0.3}   # each may also set friction: 0.0
    - plane: {point: [0, -1, 0], normal: [0, 1, 0]}
    # or triangle meshes (implicit; not together with spheres and planes), static or animated:
    #   - mesh: {ply: body.ply, friction: 0.3}      (or obj: body.obj)
    #   - mesh: {frames: body/, fps: 30, friction: 0.3}
  collision_margin: 1.0e-3      # m, vertices are kept this far outside every collider
  self_collision: null          # cloth–cloth contact (implicit), e.g. {thickness: 0.002, friction: 0.2}

solver:
  method: implicit      # implicit (Baraff–Witkin), mass-spring, pbd, xpbd, projective, explicit, vbd (docs/solvers.md)
  integrator: bdf2      # implicit, mass-spring: bdf2 (second order) or euler (backward Euler)
  substeps: 1           # solver steps per frame
  tolerance: 1.0e-6     # relative residual of the linear solve (the first Newton step's; later ones ask less)
  max_iterations: 500   # conjugate-gradient iterations per solve, at most
  preconditioner: multigrid  # multigrid (aggregation V-cycle) or jacobi (block Jacobi)
  newton_iterations: 20 # Newton steps per solver step, at most (1 = Baraff–Witkin's linearised step)
  newton_tolerance: 0.04  # m/s, Newton stops when the largest velocity correction max|Δx|/h is below
  line_search: true     # backtracking line search on the Newton steps
  max_speed: 1000.0     # m/s, a faster vertex counts as a blow-up (exit code 3)
  iterations: 10        # pbd, xpbd, projective, vbd: constraint sweeps / local-global iterations / vertex sweeps per step
  pbd_variant: gauss-seidel  # pbd: gauss-seidel (symmetric sweeps) or jacobi
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
"""


class _ValueLoader(yaml.SafeLoader):
    """PyYAML's safe loader that also reads exponent floats without a dot (``2e4``)."""


_ValueLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def parse_assignment(text):
    """'a.b.c=value' → (['a', 'b', 'c'], parsed value)."""
    key, sep, raw = text.partition("=")
    parts = key.strip().split(".")
    if not sep or not all(p.strip() for p in parts):
        raise InputError(f"--set {text!r}: expected dotted.key=value, e.g. material.stretch=2e4")
    if not raw.strip():
        raise InputError(f"--set {text!r}: no value after '='")
    try:
        value = yaml.load(raw, Loader=_ValueLoader)
    except yaml.YAMLError as exc:
        problem = getattr(exc, "problem", None) or "not valid YAML"
        raise InputError(f"--set {text!r}: value {raw!r} is {problem}") from None
    return [p.strip() for p in parts], value


def apply_overrides(config, assignments):
    """A deep copy of the mapping ``config`` with each ``key=value`` of ``assignments`` applied
    in order (later ones win)."""
    result = copy.deepcopy(config) if config is not None else {}
    for text in assignments:
        parts, value = parse_assignment(text)
        node = result
        for depth, part in enumerate(parts):
            last = depth == len(parts) - 1
            where = ".".join(parts[:depth]) or "the config"
            if isinstance(node, dict):
                if last:
                    node[part] = value
                else:
                    if node.get(part) is None:
                        node[part] = {}
                    node = node[part]
            elif isinstance(node, list):
                if not (part.lstrip("-").isdigit() and -len(node) <= int(part) < len(node)):
                    raise InputError(f"--set {text!r}: {where} is a list of {len(node)}; "
                                     f"{part!r} is not an index into it")
                if last:
                    node[int(part)] = value
                else:
                    node = node[int(part)]
            else:
                raise InputError(f"--set {text!r}: {where} is {node!r}, not a mapping")
    return result
