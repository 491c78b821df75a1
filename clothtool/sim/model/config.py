"""Simulation config: YAML → validated, frozen dataclasses, every section and key declared here.

Every problem is an :class:`~clothtool.errors.InputError` whose one-line message names the
file and the dotted key (``material.stretch``), says what is wrong and, for an unknown key,
suggests the closest valid one. The toolkit the sections are declared with is
:mod:`clothtool.sim.model.schema`: a key is one :func:`~clothtool.sim.model.schema.setting` line (default,
check and meaning: docs/simulate.md's key table is written from them by
``scripts/reference_tables.py``), a section one dataclass plus its line in :class:`Config`, a collider kind one
dataclass plus its entry in ``COLLIDER_KINDS``; what no single key can check is the section's
``finish``.

Relative paths (``mesh.ply``, ``mesh.obj``, ``output.dir``) are resolved against the config file's folder;
a config given as a dict resolves them against the current folder.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Mapping

import yaml

from clothtool import fabrics, lab_units
from clothtool.errors import InputError
from clothtool.lab_units import STANDARD_GRAVITY
from clothtool.sim.model import methods
from clothtool.sim.model.schema import (Section, as_dict, choice, choices, flag, integer,
                                        integer_or, listing, number, one_of, pair_or_number,
                                        path, resolve_paths, section, setting, suggest, tagged,
                                        type_error, vector3)

__all__ = ["load_config", "resolved_yaml", "as_dict", "Config", "SECTIONS", "COLLIDER_KINDS"]

PLANES = ("xy", "xz", "yz")
BEND_MODELS = ("hessian", "dihedral", "quadratic")
MEMBRANE_MODELS = ("triangle", "nodal", "edge")
DAMPING_MODELS = ("strain", "frozen")  # the strains' change potential, or βK(x_n) frozen
METHODS = tuple(methods.METHODS)
PRECONDITIONERS = ("jacobi", "multigrid", "amg", "hybrid", "auto")
PBD_VARIANTS = ("gauss-seidel", "jacobi", "hierarchical")
INTEGRATORS = ("bdf2", "euler")
OUTPUT_FORMATS = ("ply", "obj", "mdd", "usd")

positive = number(minimum=0, exclusive=True)
non_negative = number(minimum=0)


# ---------------------------------------------------------------------------- mesh


@dataclass(frozen=True)
class GridSpec(Section):
    """A regular grid of ``nx`` × ``ny`` vertices, centred, in ``plane``; row ny−1 is the top."""

    nx: int = setting(30, integer(minimum=2), "vertices per row (≥ 2); vertex index j·nx + i")
    ny: int = setting(30, integer(minimum=2), "vertices per column (≥ 2); row ny − 1 is the top")
    width: float = setting(1.0, positive, "m, along the plane's first axis, centred on the origin")
    height: float = setting(1.0, positive, "m, along the plane's second axis")
    plane: str = setting("xy", choice(PLANES), "`xy`, `xz` or `yz`")


def vertex_list(value, key):
    """A non-empty list of vertex indices ≥ 0 (checked against the mesh later)."""
    if not isinstance(value, list) or not value:
        raise type_error(key, "a non-empty list of vertex indices", value)
    for j, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise type_error(f"{key}[{j}]", "a vertex index (an integer ≥ 0)", v)
    return tuple(value)


def seam_side(value, key):
    """A seam side: a list of vertex indices, or the name of an OBJ group (``g``) whose
    boundary edges are the side."""
    if isinstance(value, str) and value:
        return value
    if not isinstance(value, list):
        raise type_error(key, "a list of vertex indices or an OBJ group's name", value)
    return vertex_list(value, key)


@dataclass(frozen=True)
class Seam(Section):
    """Two boundary polylines sewn together: vertex ``a[i]`` to ``b[i]``; a side may name an
    OBJ group instead, whose boundary edges are the polyline."""

    a: tuple | str = setting((), seam_side,
                             "one side: vertex indices, or an OBJ group whose boundary edges "
                             "are the side")
    b: tuple | str = setting((), seam_side, "the other side; vertex a[i] is sewn to b[i]")

    def finish(self, given, key):
        for side in ("a", "b"):
            if side not in given:
                raise InputError(f"{key} needs '{side}' (a list of vertex indices or an OBJ "
                                 "group's name)")
        if isinstance(self.a, tuple) and isinstance(self.b, tuple) and len(self.a) != len(self.b):
            raise InputError(f"{key}: a has {len(self.a)} vertices and b {len(self.b)}; "
                             "a[i] is sewn to b[i]")
        return self


@listing(Seam)
def seam_list(value, key):
    if not isinstance(value, list):
        raise type_error(key, "a list of seams {a: [...], b: [...]} or {a: group, b: group}",
                         value)
    return tuple(Seam.build(item, f"{key}[{i}]") for i, item in enumerate(value))


@dataclass(frozen=True)
class Sewing(Section):
    """The sewing phase of ``mesh.seams``: stitches of ``stiffness`` N/m per metre of seam pull
    each pair together until every pair is within ``weld`` m (None: 1.25 × the self-collision
    thickness), then the pairs are welded; not closed after ``time`` s is a failure.
    ``gravity``: whether gravity acts while the garment is sewn (off: the panels stay where
    they are laid out)."""

    stiffness: float = setting(1000.0, positive,
                               "N/m per metre of seam: the stitches that pull the sides "
                               "together, to start with (doubled for a pair behind its goal, "
                               "which closes at a constant rate)")
    weld: float | None = setting(None, positive,
                                 "m: the seam is welded once every pair is within this (— = "
                                 "1.25 × the self-collision thickness)")
    time: float = setting(2.0, positive, "s: a seam not welded by then is a failure")
    gravity: bool = setting(False, flag,
                            "gravity while the garment is sewn (off: the panels stay where they "
                            "are laid out)")


@dataclass(frozen=True)
class MeshSpec(Section):
    """Exactly one of ``grid``, ``ply`` and ``obj``. ``uv_scale``: metres per uv unit of a
    file's texture coordinates. ``seams``: boundary polylines of panels sewn together
    (``sewing``), their two sides' rest lengths within ``seam_tolerance`` (relative).
    ``weld_closed``: seams already closed in the file (boundary vertices of different panels
    within ``weld_tolerance`` m of each other) are welded at the start."""

    grid: GridSpec | None = section(GridSpec, optional=True,
                                    doc="a regular grid (exactly one of `mesh.grid`, "
                                        "`mesh.ply`, `mesh.obj`)")
    ply: Path | None = setting(None, path,
                               "rest mesh from a PLY instead of a grid: its face `texcoord` "
                               "(per corner) or `s t`/`u v` × `mesh.uv_scale` are the rest "
                               "shape, its positions the initial state; without uv the mesh is "
                               "its own rest state")
    obj: Path | None = setting(None, path,
                               "a garment (or any mesh) from an OBJ: per-corner `vt` × "
                               "`mesh.uv_scale` are each triangle's rest shape, `g`/`usemtl` "
                               "names its panels "
                               "([Garments](#garments-patterns-per-panel-materials-seams-attach))")
    uv_scale: float = setting(1.0, positive, "m per uv unit of a file's texture coordinates")
    seams: tuple = setting((), seam_list,
                           "`- {a: [vertices], b: [vertices]}`: boundary polylines sewn a[i] to "
                           "b[i], then welded (needs `scene.self_collision`)")
    seam_tolerance: float = setting(0.02, non_negative,
                                    "largest relative difference of a seam's two sides' rest "
                                    "lengths")
    sewing: Sewing = section(Sewing)
    weld_closed: bool = setting(True, flag,
                                "weld seams closed in the file at the start: boundary vertices "
                                "of different panels within `mesh.weld_tolerance` of each other "
                                "(as pattern software exports a sewn garment)")
    weld_tolerance: float = setting(1.0e-4, positive,
                                    "m, how close two panels' boundary vertices are to be welded "
                                    "at the start")

    def finish(self, given, key):
        if sum(getattr(self, k) is not None for k in ("grid", "ply", "obj")) != 1:
            raise InputError("mesh needs exactly one of mesh.grid, mesh.ply and mesh.obj")
        return self


# ---------------------------------------------------------------------------- material


def one_word(value, key):
    """A non-empty string (checked against its table later)."""
    if not isinstance(value, str) or not value:
        raise type_error(key, "a name", value)
    return value


KES_KEYS = {"density": "W", "bend": "B", "shear": "G", "stretch": "EMT"}


def correction(value, key):
    """``plate_correction``: true, false or ``fitted``."""
    if not (isinstance(value, bool) or value == "fitted"):
        raise type_error(key, "true, false or fitted", value)
    return value


def both_or_neither(bend, key):
    """A [warp, weft] ``bend`` bends both ways or not at all."""
    if isinstance(bend, tuple) and (bend[0] > 0.0) != (bend[1] > 0.0):
        raise InputError(f"{key}: warp and weft both > 0, or 0 (no bending)")


@dataclass(frozen=True)
class Kes(Section):
    """KES-F values (Kawabata): B, G, EMT, W in the lab's units, each optional; B and EMT one
    number or [warp, weft]."""

    B: float | tuple | None = setting(None, pair_or_number(exclusive=True),
                                      "gf·cm²/cm, bending rigidity: `bend` = 9.80665e-5 B N·m "
                                      "(warp, weft)")
    G: float | None = setting(None, positive,
                              "gf/(cm·deg), shear stiffness: `shear` = 56.19 G N/m")
    EMT: float | tuple | None = setting(None, pair_or_number(exclusive=True),
                                        "%, strain at 500 gf/cm: `stretch` = 490.33/(EMT/100) "
                                        "N/m, the secant (warp, weft)")
    W: float | None = setting(None, positive, "mg/cm², mass per area: `density` = 0.01 W kg/m²")

    def finish(self, given, key):
        if not given:
            raise InputError(f"{key}: give at least one of B, G, EMT and W")
        for name in given:
            if getattr(self, name) is None:
                raise InputError(f"{key}.{name}: missing value")
        return self


@dataclass(frozen=True)
class Material(Section):
    """Areal density (kg/m²), membrane stiffnesses (N/m), bending stiffness (N·m), damping (s).

    ``stretch`` and ``rest_stretch`` are a number or [along u (warp), along v (weft)];
    ``rest_stretch`` holds Baraff–Witkin's rest length factors b_u, b_v; ``bend`` too may be
    [warp, weft]. ``bending_length`` c (m, the cantilever test's; a number or
    [warp, weft]) may replace ``bend``: k_b = ρ g c³ with g = 9.81 m/s².
    ``membrane_model``: stretch and shear per ``triangle`` (linear elements), or ``nodal``:
    warp and weft stretch on each vertex's smoothed metric FᵀF (which locks less when the
    sheet bends off the mesh's lines) and shear per triangle (implicit method; the others
    and a mesh resting curved without uv keep ``triangle``), or ``edge``: stretch and shear
    on each edge's smoothed metric, on any mesh (implicit method; the others keep
    ``triangle``).
    ``preset`` (a measured fabric, :mod:`clothtool.fabrics`) and ``kes`` (KES-F values,
    :mod:`clothtool.lab_units`) fill the keys the section does not give; ``kes`` wins
    over ``preset``.
    """

    density: float = setting(0.2, positive, "kg/m²")
    stretch: float | tuple = setting(5000.0, pair_or_number(exclusive=False),
                                     "N/m (energy density over rest area): one number or "
                                     "`[warp, weft]`, the stiffness along u and along v of the "
                                     "rest uv (a grid's first and second axis)")
    rest_stretch: float | tuple = setting(1.0, pair_or_number(exclusive=True),
                                          "Baraff–Witkin's rest length factors b_u, b_v: one "
                                          "number or `[b_u, b_v]`; the sheet rests at λ_u = "
                                          "b_u, λ_v = b_v of its uv pattern (1.1: 10 % longer "
                                          "along u). Different warp and weft values need rest "
                                          "uv (a grid, or a PLY with texture coordinates)")
    shear: float = setting(50.0, non_negative, "N/m, in-plane shear stiffness")
    bend: float | tuple = setting(1.0e-5, pair_or_number(exclusive=False),
                                  "N·m, flexural rigidity per unit width: one number or "
                                  "`[warp, weft]`, bending along u and along v (the twist "
                                  "takes √(warp · weft); different values need rest uv; "
                                  "the hinge models take each hinge's rigidity across its "
                                  "edge) ([Textile units](#textile-units-and-tests)); 0 turns "
                                  "bending off")
    damping: float = setting(0.01, non_negative,
                             "s, β of the damping (`damping_model`: of the strains' change, "
                             "or stiffness-proportional); 0 = none")
    bend_model: str = setting("hessian", choice(BEND_MODELS),
                              "`hessian` (plate bending with the stated rigidity on any mesh "
                              "that rests flat, with or without uv, panels of their own bend "
                              "or damping included; a mesh resting curved and garment "
                              "patterns per corner use `dihedral`), `dihedral` (the hinge "
                              "model: soft on a grid, stiff on other meshes: the "
                              "cantilever table) or `quadratic` (its linearisation; flat rest states "
                              "only); [Textile units](#textile-units-and-tests)")
    damping_model: str = setting("strain", choice(DAMPING_MODELS),
                                 "`strain`: stretch, shear and bending damped by the "
                                 "dissipation potential of their change over the step, "
                                 "which no rigid motion feels (a sheet on a turning sphere "
                                 "follows it, a crumpled start relaxes at one step per "
                                 "frame, a hanging sheet swings; the other methods damp "
                                 "with their own βK); `frozen`: D = βK(x_n)/ĥ, the "
                                 "stiffness at the start of the step, which resists "
                                 "rotation (the cloth creeps: fewer Newton steps; see Time "
                                 "stepping)")
    bending_length: float | tuple | None = setting(None, pair_or_number(exclusive=True),
                                                   "m, instead of `bend`: the cantilever test's "
                                                   "bending length c (or `[warp, weft]`), "
                                                   "`bend` = `density` · 9.81 · c³ (giving "
                                                   "both is an error)")
    plate_correction: bool | str = setting(False, correction,
                                           "`hessian` bending: correct the smoothing of each "
                                           "vertex's Hessian estimate (a fourth-order term, "
                                           "β h²‖∇Ĥ‖², β = 0.15), so that folds a few triangles "
                                           "wide keep their bending energy on a coarse mesh; "
                                           "`fitted`: β fitted on the mesh's own plane waves "
                                           "(a polar mesh needs more than a grid) "
                                           "([Textile units](#textile-units-and-tests))")
    membrane_model: str = setting("triangle", choice(MEMBRANE_MODELS),
                                  "`triangle` (stretch and shear per linear triangle) or "
                                  "`nodal`: warp and weft stretch on each vertex's smoothed "
                                  "metric FᵀF, shear per triangle, so the drape depends less on "
                                  "the mesh (linear triangles lock where a fold crosses them). "
                                  "Any mesh that rests flat, with uv or without (its own plane), "
                                  "garment panels included (a seam vertex has a cell in each "
                                  "panel); a mesh resting curved without uv and the methods "
                                  "other than `implicit` keep `triangle`. `edge`: stretch and "
                                  "shear on each edge's smoothed metric (its two triangles'), "
                                  "on any mesh, uv or none, seams included (implicit method)")
    preset: str | None = setting(None, one_word,
                                 "a measured fabric (Wang et al. 2011, as ARCSim ships them): "
                                 "its density, stretch, shear and bend fill the keys not given "
                                 "([Measured fabrics](#measured-fabrics-materialpreset))")
    kes: Kes | None = section(Kes, optional=True,
                              doc="KES-F values: they fill density, bend, shear and stretch "
                                  "(giving a key and its KES value is an error; "
                                  "[Textile units](#textile-units-and-tests))")

    def finish(self, given, key):
        """The keys not given from ``preset``, then from ``kes``; ``bend`` = ρ g c³ from
        ``bending_length`` c and ``density`` ρ (not both bend and c)."""
        values = {}
        if self.preset is not None:
            values = {k: v for k, v in fabrics.preset(self.preset, f"{key}.preset").items()
                      if k not in given and not (k == "bend" and self.bending_length)}
        if self.kes is not None:
            for name, value in lab_units.from_kes(as_dict(self.kes)).items():
                if name in given:
                    raise InputError(f"{key}: give one of {name} and kes.{KES_KEYS[name]}, "
                                     "not both")
                values[name] = value
        material = replace(self, **values)
        both_or_neither(material.bend, f"{key}.bend")
        if self.bending_length is None:
            return material
        if "bend" in given or (self.kes is not None and self.kes.B is not None):
            raise InputError(f"{key}: give one of bend (N·m), kes.B and bending_length (m)")
        c = self.bending_length
        rho_g = material.density * STANDARD_GRAVITY
        return replace(material, bend=tuple(rho_g * x ** 3 for x in c) if isinstance(c, tuple)
                       else rho_g * c ** 3)


@dataclass(frozen=True)
class PanelMaterial(Section):
    """One panel's material: the keys of ``material`` it changes (None: the ``material``
    value) and, instead of an OBJ group or material name, its triangles (``faces``)."""

    density: float | None = setting(None, positive, "as `material.density` (— = that value)")
    stretch: float | tuple | None = setting(None, pair_or_number(exclusive=False),
                                            "as `material.stretch`")
    rest_stretch: float | tuple | None = setting(None, pair_or_number(exclusive=True),
                                                 "as `material.rest_stretch`")
    shear: float | None = setting(None, non_negative, "as `material.shear`")
    bend: float | tuple | None = setting(None, pair_or_number(exclusive=False),
                                         "as `material.bend`")
    damping: float | None = setting(None, non_negative, "as `material.damping`")
    faces: tuple | None = setting(None, vertex_list,
                                  "the panel's triangles, when NAME is not an OBJ group or "
                                  "material")
    preset: str | None = setting(None, one_word,
                                 "as `material.preset`: the fabric's density, stretch, shear "
                                 "and bend for the panel's keys not given")

    def finish(self, given, key):
        both_or_neither(self.bend, f"{key}.bend")
        if self.preset is None:
            return self
        return replace(self, **{k: v for k, v in fabrics.preset(self.preset, f"{key}.preset")
                                .items() if k not in given})


@listing(PanelMaterial, ".NAME")
def panel_materials(value, key):
    """{panel name: :class:`PanelMaterial`}: an OBJ group (g) or material (usemtl) name, or
    any name with ``faces``."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise type_error(key, "a mapping of panel names to materials", value)
    return {str(name): PanelMaterial.build(body, f"{key}.{name}") for name, body in value.items()}


# ---------------------------------------------------------------------------- scene
#
# A collider's ``kind`` is its name in the config; ``barrier`` colliders are contact surfaces
# (implicit solver, intersection-free), the others vertex constraints projected after a step.


@dataclass(frozen=True)
class Rotate(Section):
    """Turn about the axis through ``center`` at ``speed`` rad/s (right-hand rule) until
    ``until`` s (None: the whole run)."""

    center: tuple = setting((0.0, 0.0, 0.0), vector3(), "m, a point of the axis")
    axis: tuple = setting((1.0, 0.0, 0.0), vector3(nonzero=True),
                          "the axis' direction (right-hand rule)")
    speed: float = setting(0.0, number(), "rad/s")
    until: float | None = setting(None, non_negative, "s, turning stops then (— = the whole run)")


@dataclass(frozen=True)
class Translate(Section):
    """Move at ``velocity`` m/s until ``until`` s (None: the whole run)."""

    velocity: tuple = setting((0.0, 0.0, 0.0), vector3(), "m/s")
    until: float | None = setting(None, non_negative, "s, moving stops then (— = the whole run)")


@dataclass(frozen=True)
class Motion(Section):
    """A collider's rigid motion: x(t) = c + T(t) + R(θ(t))(x₀ − c), turning about the axis
    through ``rotate.center`` (which moves with the translation) and moving at
    ``translate.velocity``, each until its own ``until``."""

    rotate: Rotate | None = section(Rotate, optional=True)
    translate: Translate | None = section(Translate, optional=True)

    def finish(self, given, key):
        if self.rotate is None and self.translate is None:
            raise InputError(f"{key} needs rotate and/or translate")
        return self


def motion():
    """Every collider's optional ``motion``."""
    return section(Motion, optional=True, what="a mapping (rotate, translate)",
                   doc="a rigid motion (implicit): `rotate` and/or `translate`, x(t) = c + T(t) "
                   "+ R(θ(t))(x₀ − c), the centre moving with the translation")


@dataclass(frozen=True)
class Sphere(Section):
    kind, barrier = "sphere", False

    center: tuple = setting((0.0, 0.0, 0.0), vector3(), "m")
    radius: float = setting(1.0, positive, "m")
    friction: float = setting(0.0, non_negative, "Coulomb's μ against the cloth")
    motion: Motion | None = motion()


@dataclass(frozen=True)
class Plane(Section):
    """The half-space on the side ``normal`` points to, bounded by the plane through
    ``point``."""

    kind, barrier = "plane", False

    point: tuple = setting((0.0, 0.0, 0.0), vector3(), "m, a point of the plane")
    normal: tuple = setting((0.0, 1.0, 0.0), vector3(nonzero=True),
                            "the cloth stays on the side it points to")
    friction: float = setting(0.0, non_negative, "Coulomb's μ")
    motion: Motion | None = motion()


@dataclass(frozen=True)
class Capsule(Section):
    """The points within ``radius`` of the segment from ``a`` to ``b``."""

    kind, barrier = "capsule", True

    a: tuple = setting((-0.5, 0.0, 0.0), vector3(), "m, one end of the segment")
    b: tuple = setting((0.5, 0.0, 0.0), vector3(), "m, the other end")
    radius: float = setting(0.1, positive, "m, the points within it of the segment")
    friction: float = setting(0.0, non_negative, "Coulomb's μ")
    motion: Motion | None = motion()

    def finish(self, given, key):
        if tuple(self.a) == tuple(self.b):
            raise InputError(f"{key}: a and b must differ (use a sphere for a point)")
        return self


@dataclass(frozen=True)
class Box(Section):
    """A box of edge lengths ``size`` centred on ``center``, turned by ``angle`` rad about
    ``axis`` (right-hand rule) from axis-aligned."""

    kind, barrier = "box", True

    center: tuple = setting((0.0, 0.0, 0.0), vector3(), "m")
    size: tuple = setting((1.0, 1.0, 1.0), vector3(), "m, edge lengths")
    axis: tuple = setting((0.0, 1.0, 0.0), vector3(nonzero=True),
                          "the box is turned about this axis by `angle` from axis-aligned")
    angle: float = setting(0.0, number(), "rad (right-hand rule)")
    friction: float = setting(0.0, non_negative, "Coulomb's μ")
    motion: Motion | None = motion()

    def finish(self, given, key):
        if min(self.size) <= 0.0:
            raise InputError(f"{key}.size: every edge length must be positive, got {list(self.size)}")
        return self


@dataclass(frozen=True)
class MeshCollider(Section):
    """A triangle mesh: one ``ply`` or ``obj`` file (static), or a folder of ``frames`` (PLY or
    OBJ, one topology) shown at ``fps``, positions linear in time between frames, the last
    frame held after the end."""

    kind, barrier = "mesh", True
    SOURCES = ("ply", "obj", "frames")

    ply: Path | None = setting(None, path,
                               "a static triangle mesh from a PLY (one of `ply`, `obj`, "
                               "`frames`)")
    obj: Path | None = setting(None, path, "a static triangle mesh from an OBJ")
    frames: Path | None = setting(None, path,
                                  "a folder of PLY or OBJ frames (one topology): positions "
                                  "linear in time between frames, the last frame held after the "
                                  "end")
    fps: float = setting(30.0, positive, "frames per second of `frames`")
    friction: float = setting(0.0, non_negative, "Coulomb's μ")
    motion: Motion | None = motion()

    def finish(self, given, key):
        source = one_of(self.SOURCES, {k for k in self.SOURCES if getattr(self, k) is not None},
                        key)
        if "fps" in given and source != "frames":
            raise InputError(f"{key}.fps applies to frames only")
        return self

    @property
    def source(self):
        """(key, path) of the one mesh source given."""
        return next((k, getattr(self, k)) for k in self.SOURCES if getattr(self, k))


COLLIDER_KINDS = {cls.kind: cls for cls in (Sphere, Plane, Capsule, Box, MeshCollider)}


@dataclass(frozen=True)
class SelfCollision(Section):
    """Cloth–cloth contact: surfaces kept ``thickness`` (m) apart, Coulomb ``friction``."""

    thickness: float = setting(0.002, positive, "m kept between the cloth's surfaces")
    friction: float = setting(0.0, non_negative, "Coulomb's μ between them")


def pin_vertices(value, key):
    """A pin-set name or a vertex index (indices are checked against the mesh later)."""
    from clothtool.sim.model.pins import PIN_SETS

    if isinstance(value, bool) or not isinstance(value, (int, str)):
        raise type_error(key, "a pin-set name or a vertex index", value)
    if isinstance(value, str) and value not in PIN_SETS:
        raise InputError(f"{key}: unknown pin set {value!r}{suggest(value, PIN_SETS)}"
                         f" (known: {', '.join(PIN_SETS)})")
    if isinstance(value, int) and value < 0:
        raise InputError(f"{key}: vertex index must be ≥ 0, got {value}")
    return value


def pin_vertex_list(value, key):
    """One pin-set name or vertex index, or a non-empty list of them."""
    if not isinstance(value, list):
        return (pin_vertices(value, key),)
    if not value:
        raise InputError(f"{key} must not be empty")
    return tuple(pin_vertices(v, f"{key}[{j}]") for j, v in enumerate(value))


@dataclass(frozen=True)
class PinGroup(Section):
    """Pinned vertices (set names and indices) on a rigid motion of their initial positions:
    ``vertices`` with at most one of ``rotate`` and ``translate``."""

    vertices: tuple = setting((), pin_vertex_list,
                              "pin-set names and vertex indices, held on the group's motion")
    rotate: Rotate | None = section(Rotate, optional=True,
                                    doc="turn the group about an axis through `center` at "
                                        "`speed`")
    translate: Translate | None = section(Translate, optional=True,
                                          doc="move the group at `velocity`")

    def finish(self, given, key):
        if "vertices" not in given:
            raise InputError(f"{key}: a pin group needs 'vertices' (a pin-set name or a list of "
                             "names and vertex indices)")
        if self.rotate is not None and self.translate is not None:
            raise InputError(f"{key}: give at most one of rotate and translate")
        return self

    @property
    def motion(self):
        return self.rotate or self.translate


@listing(PinGroup)
def pins(value, key):
    """Pin entries: set names, vertex indices, and moving groups ``{vertices: …, rotate: {…}}``
    or ``{vertices: …, translate: {…}}`` (:class:`PinGroup`)."""
    if not isinstance(value, list):
        raise type_error(key, "a list of pin-set names, vertex indices and pin groups", value)
    return tuple(PinGroup.build(item, f"{key}[{i}]") if isinstance(item, dict)
                 else pin_vertices(item, f"{key}[{i}]") for i, item in enumerate(value))


@dataclass(frozen=True)
class Attach(Section):
    """Garment ``vertices`` tied to collider ``to``'s surface: to its nearest point at t = 0,
    at the distance they start from it, carried with the collider's motion."""

    vertices: tuple = setting((), vertex_list,
                              "garment vertices carried by the collider's surface, at the "
                              "distance they start from it")
    to: int = setting(0, integer(minimum=0), "the collider's index in `scene.colliders`")
    required = ("vertices", "to")  # keys to give even at their default

    def finish(self, given, key):
        for name in self.required:
            if name not in given:
                raise InputError(f"{key} needs '{name}'")
        return self


@listing(Attach)
def attach_list(value, key):
    """One ``{vertices: [...], to: K}`` or a list of them."""
    if isinstance(value, dict):
        return (Attach.build(value, key),)
    if not isinstance(value, list):
        raise type_error(key, "{vertices: [...], to: K} or a list of them", value)
    return tuple(Attach.build(item, f"{key}[{i}]") for i, item in enumerate(value))


@dataclass(frozen=True)
class Scene(Section):
    """``collision_margin`` (m): cloth rests this far from every collider surface;
    ``self_collision``: cloth–cloth contact, None = off. The implicit method's contact
    barrier pushes from 4 % beyond the margin (and the thickness) in to its wall
    ``activation_distance`` closer than them (None: three quarters of each), which no pair
    ever crosses; the other methods project
    vertices onto spheres and planes."""

    gravity: tuple = setting((0.0, -9.81, 0.0), vector3(), "m/s²")
    pins: tuple = setting((), pins,
                          "named sets `top_corners`, `bottom_corners`, `corners`, `top_edge`, "
                          "`bottom_edge`, `left_edge`, `right_edge` (grids) and vertex indices; "
                          "and pin groups `{vertices: NAME or [names, indices], rotate: {...}}` "
                          "or `{vertices: …, translate: {...}}` (implicit)")
    colliders: tuple = setting((), tagged(COLLIDER_KINDS, what="collider"),
                               "`- sphere: {...}`, `- plane: {...}` (every method) and `- "
                               "capsule`, `- box`, `- mesh` (implicit: intersection-free "
                               "barrier contact), in any mix; each may move rigidly (`motion`, "
                               "implicit)")
    collision_margin: float = setting(2.0e-3, positive,
                                      "m kept between vertices and collider surfaces (for mesh "
                                      "colliders: between the cloth's and the collider's "
                                      "surfaces)")
    activation_distance: float | None = setting(None, positive,
                                                "m, depth of the contact barrier's wall inside "
                                                "the margin and the self-collision thickness (— "
                                                "= ¾ of each)")
    self_collision: SelfCollision | None = section(
        SelfCollision, optional=True, what="a mapping (thickness, friction)",
        doc="cloth–cloth contact (implicit) keeping the surfaces `thickness` apart; absent = off")
    attach: tuple = setting((), attach_list,
                            "`{vertices: [...], to: K}` or a list: vertices carried by collider "
                            "K's surface (implicit)")

    def finish(self, given, key):
        for i, a in enumerate(self.attach):
            where = f"scene.attach[{i}]" if len(self.attach) > 1 else "scene.attach"
            if a.to >= len(self.colliders):
                raise InputError(f"{where}.to: collider {a.to} out of range (the scene has "
                                 f"{len(self.colliders)} colliders)")
        d = self.activation_distance
        for what, xi in (("scene.collision_margin", self.collision_margin),
                         ("self_collision.thickness",
                          self.self_collision.thickness if self.self_collision else None)):
            if d is not None and xi is not None and d >= xi:
                raise InputError(f"scene.activation_distance ({d:g} m) must be below {what} "
                                 f"({xi:g} m): the barrier's wall is that much closer in")
        return self


# ---------------------------------------------------------------------------- solver, time, output


@dataclass(frozen=True)
class Solver(Section):
    """The time step and its solve.

    ``integrator``: ``bdf2`` (second order, the default) or ``euler`` (backward Euler),
    each the minimisation of its incremental potential by Newton's method: at most
    ``newton_iterations`` Newton steps per solver step, stopping when the largest
    velocity correction max|Δx|/h and the Newton decrement as a velocity
    √(Δxᵀ H Δx / free mass) are below ``newton_tolerance`` (m/s); each Newton
    step is a PCG solve whose relative residual ``tolerance`` is the finest it asks
    for (later Newton steps ask for less: Eisenstat–Walker); ``preconditioner`` is
    block Jacobi or an aggregation multigrid V-cycle (``amg``: its coarse spaces carry
    cloth's near-null modes, rebuilt from the positions at every step; ``hybrid``: ``amg`` for
    the tight solves, ``multigrid`` for the loose ones; ``auto``: ``amg`` on stiff models,
    ``multigrid`` on soft ones). ``newton_iterations: 1`` is
    Baraff–Witkin's linearised step. A step whose speed exceeds ``max_speed`` (m/s)
    counts as a blow-up. ``friction_velocity`` ε_v (m/s) is the sliding speed below which
    contact friction holds (it creeps at most at ε_v where Coulomb's law sticks).

    ``method`` picks the solver (``clothtool.sim.solvers``, ``docs/solvers.md``):
    ``mass-spring`` uses the Newton/PCG keys above; ``pbd``, ``xpbd`` and
    ``projective`` run ``iterations`` sweeps per step; ``pbd`` also reads
    ``pbd_variant`` (gauss-seidel, jacobi or hierarchical), ``relaxation`` (Jacobi α),
    ``pbd_stiffness`` (0, 1] and ``strain_limit`` (ε: structural springs kept in
    [1 − ε, 1 + ε] of their rest length; 0 = off); ``explicit`` splits each step
    into internal steps of at most ``cfl`` × its estimated critical step (0 = off);
    ``vbd`` runs ``iterations`` vertex sweeps per step, Chebyshev-accelerated with
    spectral radius estimate ``chebyshev_rho`` (0 = off), stopping early once the
    gradient of the step's potential is below ``vbd_tolerance`` × ‖M g‖ (0 = off).
    """

    method: str = setting("implicit", choice(METHODS),
                          "this solver; `mass-spring`, `pbd`, `xpbd`, `projective`, `explicit`, "
                          "`vbd` are described in docs/solvers.md")
    integrator: str = setting("bdf2", choice(INTEGRATORS),
                              "`bdf2` (second order) or `euler` (backward Euler), for "
                              "`implicit` and `mass-spring`; the other methods have their own "
                              "first-order stepping and refuse an explicit `bdf2`")
    substeps: int = setting(1, integer(minimum=1), "solver steps per frame (h = 1/(fps·substeps))")
    tolerance: float = setting(1.0e-6, number(minimum=0, exclusive=True, maximum=1),
                               "PCG stop: true relative residual ‖S(b − AΔx)‖/‖Sb‖ of the first "
                               "Newton step; later ones ask for η = 0.9(‖∇E_k‖/‖∇E_{k−1}‖)² "
                               "within [tolerance, 0.15] (Eisenstat–Walker); the sample config "
                               "uses 1e-2")
    max_iterations: int = setting(500, integer(minimum=1), "PCG iterations per Newton step")
    preconditioner: str = setting("auto", choice(PRECONDITIONERS),
                                  "`multigrid` (aggregation of translations), `amg` (aggregation "
                                  "of each aggregate's rigid motions and in-plane shears), "
                                  "`hybrid` (`amg` for the solves to a relative residual of 1e-4 "
                                  "or finer, `multigrid` for the looser ones), `auto` (`amg` "
                                  "when the stiffest membrane k over the free vertices' mean "
                                  "mass m gives k h²/m ≥ 1e5 at the step h, `multigrid` below) or "
                                  "`jacobi` (block Jacobi)")
    newton_iterations: int = setting(20, integer(minimum=1),
                                     "Newton steps per solver step, at most (1 = "
                                     "Baraff–Witkin's linearised step)")
    newton_tolerance: float = setting(0.04, non_negative,
                                      "m/s; Newton stops when a full step's largest velocity "
                                      "correction max|Δx|/h and its decrement as a velocity, "
                                      "√(ΔxᵀHΔx / free mass), are both at most this")
    friction_velocity: float = setting(1.0e-4, positive,
                                       "m/s, IPC's ε_v: contact friction holds below this "
                                       "sliding speed (it creeps at most at ε_v where Coulomb's "
                                       "law sticks)")
    overshoot_bound: bool = setting(False, flag,
                                    "contact friction: a pair whose slip a Newton step turned "
                                    "to the other side takes the curvature of the "
                                    "half-quadratic bound of ‖v‖ for the rest of the step's "
                                    "lag (fewer Newton steps at stick–slip)")
    slow_slip_bound: float = setting(0.0, non_negative,
                                     "m/s; contact friction: a pair slipping slower than this "
                                     "takes the isotropic curvature of the half-quadratic bound "
                                     "of its friction potential in Newton's matrix (fewer "
                                     "Newton steps at stick–slip; the potential is unchanged); "
                                     "0 = off")
    forcing_from_second: bool = setting(False, flag,
                                        "contact: Eisenstat–Walker's ratio starts at Newton's "
                                        "second iterate (the step's start is no iterate of "
                                        "the minimisation), so the second PCG solve asks "
                                        "for 0.15")
    short_step_forcing: bool = setting(False, flag,
                                       "after a Newton step the line search shortened to a "
                                       "fraction s, the next PCG asks for s times "
                                       "Eisenstat–Walker's forcing (at its cap of 0.15 Newton "
                                       "took the same loose direction again: at stick–slip it "
                                       "ran to its cap of steps)")
    first_forcing: float = setting(0.0, number(minimum=0, below=1),
                                   "contact: Newton's first PCG of a step solves to this "
                                   "relative residual (the step from x_n that CCD cuts "
                                   "short at impact); 0 = solver.tolerance")
    first_cut_iterations: int = setting(20, integer(minimum=0),
                                        "contact: when CCD over the step's candidate pairs "
                                        "cuts short the guess of Newton's first PCG of a step "
                                        "(the motion x̃ − x_n runs into a surface), that PCG "
                                        "stops after at most this many iterations (its "
                                        "proposal is cut at the first contact anyway); not "
                                        "while a garment's seams are sewn; 0 = off")
    friction_velocity_test: bool = setting(False, flag,
                                           "contact: while friction pairs are lagged, Newton "
                                           "has converged when its whole proposal's largest "
                                           "velocity correction max|Δx|/h is at most "
                                           "newton_tolerance (IPC's test; the decrement is not "
                                           "asked: friction's stick stiffness makes a tiny Δx "
                                           "carry a large one); friction's own tests kept")
    line_search: bool = setting(True, flag,
                                "halve a Newton step until the incremental potential does not "
                                "increase")
    stiffness_continuation: int | str = setting("auto", integer_or("auto", minimum=0),
                                                "`implicit`: solve each step first with the "
                                                "membrane's stretch and shear (and their "
                                                "damping) 10ⁿ, …, 10× softer, each from the "
                                                "last's solution, then as it is: Newton "
                                                "converges on stiff cloth at large steps (1e6 "
                                                "N/m at h = 1 s: 4); `auto`: n from the "
                                                "stiffness-to-inertia ratio k·ĥ²/m of the "
                                                "stage; 0 = off")
    continuation_after: int = setting(20, integer(minimum=0),
                                      "with `stiffness_continuation`: only a solve that Newton "
                                      "alone has not converged after this many steps, at least "
                                      "half of them bound by the stiffness (velocity correction "
                                      "within `newton_tolerance`, decrement not), is solved "
                                      "again from the step's start through the softer "
                                      "membranes; 0 = every solve starts with them")
    max_speed: float = setting(1000.0, positive, "m/s; faster counts as a blow-up")
    # the alternative methods (clothtool.sim.solvers, docs/solvers.md); ignored by the others
    iterations: int = setting(10, integer(minimum=1),
                              "`pbd`, `xpbd`, `projective`, `vbd`: sweeps per solver step")
    pbd_variant: str = setting("gauss-seidel", choice(PBD_VARIANTS),
                               "`pbd`: `gauss-seidel` (symmetric sweeps), `jacobi` or "
                               "`hierarchical`")
    relaxation: float = setting(1.0, non_negative,
                                "`pbd` jacobi: α in x_i += Σ corrections / (n_i + α)")
    pbd_stiffness: float = setting(1.0, number(minimum=0, exclusive=True, maximum=1),
                                   "`pbd`: per-constraint stiffness in (0, 1]")
    strain_limit: float = setting(0.0, number(minimum=0, maximum=1),
                                  "`pbd`: structural springs kept within [1 − ε, 1 + ε] of "
                                  "their rest length; 0 = off")
    cfl: float = setting(0.5, number(minimum=0, maximum=1),
                         "`explicit`: internal steps of at most `cfl` × the estimated critical "
                         "step; 0 = off")
    chebyshev_rho: float = setting(0.9, number(minimum=0, below=1),
                                   "`vbd`: Chebyshev acceleration with spectral-radius estimate "
                                   "ρ in [0, 1) (only with at least 5 sweeps per step); 0 = off")
    vbd_tolerance: float = setting(0.0, non_negative,
                                   "`vbd`: stop a step's sweeps once the relative gradient "
                                   "‖∇E‖/‖M g‖ is at most this (at most `iterations` sweeps); 0 "
                                   "= always `iterations` sweeps")


@dataclass(frozen=True)
class Time(Section):
    fps: float = setting(30.0, positive, "frames per second")
    frames: int = setting(120, integer(minimum=0), "frames simulated after the initial one")


def output_formats(value, key):
    """``output.format``: names from OUTPUT_FORMATS; Alembic, which is not written, is
    refused with the way to one."""
    for i, item in enumerate([value] if isinstance(value, str) else value
                             if isinstance(value, list) else []):
        if isinstance(item, str) and item.lower() in ("abc", "alembic"):
            raise InputError(f"{key}[{i}]: {item!r}: Alembic is not written; write 'usd' and "
                             "convert it in Blender (import USD, export Alembic)")
    return choices(OUTPUT_FORMATS)(value, key)


@dataclass(frozen=True)
class Output(Section):
    """Where and what a run writes: every ``every``-th frame, in each of ``format``: ``ply``
    (binary PLY frames with the rest uv as ``s t``), ``obj`` (OBJ frames in ``obj/`` with
    the pattern's uv per corner), ``mdd`` (one point cache of every written frame with its
    time, ``cache/cloth.mdd``, and its base mesh ``cache/cloth.obj``), ``usd`` (one USD stage
    ``usd/cloth.usda``: the cloth's points at every written frame, its uv, panels and the
    colliders with their motion)."""

    dir: Path = setting(Path("out"), path, "output folder")
    every: int = setting(1, integer(minimum=1), "write every n-th frame")
    format: tuple = setting(("ply",), output_formats,
                            "a list of `ply` (frames in the folder), `obj` (OBJ frames in "
                            "`obj/`, the pattern's uv per corner as `vt`), `mdd` (one point "
                            "cache of every written frame with its time, `cache/cloth.mdd`, "
                            "plus its base mesh `cache/cloth.obj`) and `usd` (one USD "
                            "stage, `usd/cloth.usda`: the cloth's points per frame, its uv, "
                            "panels and the colliders); [Frames for Blender, Maya, "
                            "Houdini](#frames-for-blender-maya-houdini)")


@dataclass(frozen=True)
class Config(Section):
    mesh: MeshSpec = section(MeshSpec)
    material: Material = section(Material)
    materials: dict = field(default_factory=dict, metadata={
        "check": panel_materials,
        "doc": "per panel: keys of `material` it changes; NAME an OBJ group or material, or any "
               "name with `faces: [...]`"})
    scene: Scene = section(Scene)
    solver: Solver = section(Solver)
    time: Time = section(Time)
    output: Output = section(Output)
    source: Path | None = None  # the config file, for messages; None for a dict

    def finish(self, given, key):
        if "mesh" not in given:
            raise InputError("missing section 'mesh' (give mesh.grid, mesh.ply or mesh.obj)")
        if self.mesh.seams and self.scene.self_collision is None:
            raise InputError("mesh.seams: sewing needs scene.self_collision (the panels must "
                             "not pass through each other while they are pulled together)")
        return self

    @property
    def step(self):
        """Solver time step h = 1 / (fps · substeps), seconds."""
        return 1.0 / (self.time.fps * self.solver.substeps)


SECTIONS = {f.name: f.default_factory for f in fields(Config) if f.name != "source"}


# ---------------------------------------------------------------------------- loading


def load_config(config, *, overrides=None, base_dir=None) -> Config:
    """Read and validate a config: a YAML path, or an already-parsed dict.

    ``overrides``, applied before validation: a mapping of dotted keys → values
    (``{"material.stretch": 1e5}``; string values are read as YAML scalars), or a
    list of ``"key=value"`` strings (:func:`clothtool.config_tools.apply_overrides`,
    which also indexes lists).
    ``base_dir``: the folder that a dict's relative paths are relative to (default: the
    current folder).
    """
    if isinstance(config, Mapping):
        raw, source = _deep_copy(config), None
        base = Path(base_dir) if base_dir is not None else Path.cwd()
    else:
        source = Path(os.fspath(config))
        raw = read_yaml(source)
        base = source.parent
    if isinstance(overrides, Mapping):
        for dotted, value in overrides.items():
            _apply_override(raw, dotted, value)
    elif overrides:
        from clothtool.config_tools import apply_overrides

        raw = apply_overrides(raw, list(overrides))
    label = str(source) if source is not None else "config"
    try:
        config = Config.build(raw, "")
        given = {f"{name}.{key}" for name, body in raw.items() if isinstance(body, dict)
                 for key in body}
        methods.check_supported(config, given)
    except InputError as exc:
        raise InputError(f"{label}: {exc}") from None
    return replace(resolve_paths(config, base), source=source)


def resolved_yaml(config: Config) -> str:
    """``config`` as YAML that :func:`load_config` reads back to the same config from any
    folder: every key whose value differs from its default (a key left at its default reads
    back the same), paths absolute."""
    absolute = replace(resolve_paths(config, Path.cwd()), source=None)
    return yaml.safe_dump(_record(absolute), sort_keys=False, default_flow_style=None, width=100)


def _record(value):
    """Plain data of a config value: a section's keys that differ from their defaults."""
    if isinstance(value, Section):
        out = {}
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            default = (f.default_factory() if f.default_factory is not dataclasses.MISSING
                       else f.default)
            if f.name == "bending_length" and getattr(value, "bend", None) is not None:
                continue  # resolved into bend
            if f.name in ("preset", "kes"):
                continue  # resolved into the keys they fill
            if f.name != "source" and (v != default or f.name in getattr(value, "required", ())):
                out[f.name] = ([{c.kind: _record(c)} for c in v] if f.name == "colliders"
                               else _record(v))
        return out
    if isinstance(value, dict):
        return {k: _record(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [_record(v) for v in value]
    if isinstance(value, Path):
        return os.path.abspath(value)
    return value


def read_yaml(path: Path):
    """The mapping in the YAML file ``path``; every problem is a one-line InputError naming it."""
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
    """Set the dotted key ``dotted`` of ``raw`` (an ``overrides`` mapping's entry)."""
    if isinstance(value, str):
        try:
            value = yaml.safe_load(value)
        except yaml.YAMLError:
            raise InputError(f"cannot read value {value!r}", keyword="overrides",
                             value=repr(dotted)) from None
    parts = dotted.split(".")
    node = raw
    for depth, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        if not isinstance(child, dict):
            raise InputError(f"{'.'.join(parts[:depth + 1])} is not a section",
                             keyword="overrides", value=repr(dotted))
        node = child
    node[parts[-1]] = value


def _deep_copy(value):
    if isinstance(value, Mapping):
        return {k: _deep_copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_deep_copy(v) for v in value]
    return value
