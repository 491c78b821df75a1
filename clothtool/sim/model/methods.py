"""The registry of simulation methods (``solver.method``): name → class and the config
features it supports, in one place.

Every method implements the :class:`~clothtool.sim.solve.integrator.Integrator` protocol.
A method lists the optional features of a config it handles; a config that asks for
a feature its method does not support is refused with an
:class:`~clothtool.errors.InputError` naming the config key. Adding a method is one
:class:`Method` entry here (and its module).

=============  ==================================================================
method         what it is
=============  ==================================================================
implicit       Baraff–Witkin implicit Euler, Newton + filtered PCG (the default;
               :mod:`clothtool.sim.solvers.implicit`, :mod:`clothtool.sim.solve.newton`)
mass-spring    implicit Euler on a spring network, PSD-clamped spring Hessians
pbd            Position Based Dynamics, Gauss–Seidel, Jacobi or hierarchical, strain
               limiting
xpbd           extended PBD: compliant constraints, same springs as mass-spring
projective     Projective Dynamics: constant prefactored matrix, local projections
explicit       symplectic Euler with (automatic) internal steps, the baseline
vbd            Vertex Block Descent: per-vertex 3×3 Newton steps on implicit's
               incremental potential, in graph-colour order (Chen et al. 2024)
=============  ==================================================================

See ``docs/solvers.md`` for the choice between them.
"""

import importlib
from dataclasses import dataclass

from clothtool.errors import InputError

# optional config features a method may support (pins, spheres and planes work with every
# method: without barrier contact, spheres and planes project vertices out after each step)
FRICTION = "friction"  # Coulomb friction on colliders (scene.colliders[i].*.friction > 0)
CONTACT = "contact"  # barrier contact (capsules, boxes, meshes, moving colliders, self-collision)
MOVING_PINS = "moving pins"  # scene.pins entries with rotate or translate
BDF2 = "bdf2"  # solver.integrator: bdf2 (the default; refused only when a config sets it)
MATERIALS = "per-panel materials"  # materials: per-triangle stiffness, density and bending
SEAMS = "seams"  # mesh.seams: the stitch term and the weld (clothtool.sim.model.seams)
ATTACH = "attach"  # scene.attach: vertices carried by a collider's surface (moving pins)
PANEL_DAMPING = "per-panel damping"  # materials.NAME.damping other than material.damping
STRAIN_DAMPING = "strain damping"  # material.damping_model: strain (clothtool.sim.energies.dissipation)
CONTINUATION = "stiffness continuation"  # solver.stiffness_continuation given (clothtool.sim.solve.newton)
FEATURES = (FRICTION, CONTACT, MOVING_PINS, BDF2, MATERIALS, SEAMS, ATTACH, PANEL_DAMPING,
            STRAIN_DAMPING, CONTINUATION)


@dataclass(frozen=True)
class Method:
    name: str
    target: str  # "module:Class"
    supports: frozenset = frozenset()
    summary: str = ""

    def load(self):
        module, cls = self.target.split(":")
        return getattr(importlib.import_module(module), cls)


METHODS = {m.name: m for m in (
    Method("implicit", "clothtool.sim.solvers.implicit:ImplicitEuler",
           frozenset({FRICTION, CONTACT, MOVING_PINS, BDF2, MATERIALS, SEAMS, ATTACH,
                      PANEL_DAMPING, STRAIN_DAMPING, CONTINUATION}),
           "finite-element cloth, BDF2 or backward Euler, Newton + filtered PCG"),
    Method("mass-spring", "clothtool.sim.solvers.mass_spring:MassSpringImplicit",
           frozenset({BDF2}), "spring network, BDF2 or backward Euler, Newton + PCG"),
    Method("pbd", "clothtool.sim.solvers.pbd:PositionBased", summary="Position Based Dynamics"),
    Method("xpbd", "clothtool.sim.solvers.xpbd:ExtendedPositionBased", summary="extended PBD"),
    Method("projective", "clothtool.sim.solvers.projective:ProjectiveDynamics",
           summary="Projective Dynamics"),
    Method("explicit", "clothtool.sim.solvers.explicit:SymplecticEuler", frozenset({MATERIALS}),
           summary="symplectic Euler with automatic internal steps"),
    Method("vbd", "clothtool.sim.solvers.vbd:VertexBlockDescent", frozenset({MATERIALS}),
           summary="Vertex Block Descent on the finite-element cloth"),
)}


def requested_features(config, given=()):
    """(feature, config key) for each optional feature a :class:`~clothtool.sim.model.config.Config`
    asks for; ``given``: the dotted keys the config file sets (a default ``bdf2`` or
    ``strain`` damping is not a request: the methods without it step by their own
    first-order scheme and damp with their own βK; without continuation, Newton alone)."""
    out = []
    if config.solver.integrator == "bdf2" and "solver.integrator" in given:
        out.append((BDF2, "solver.integrator: bdf2"))
    for i, collider in enumerate(config.scene.colliders):
        if collider.barrier:
            out.append((CONTACT, f"scene.colliders[{i}].{collider.kind}"))
        if collider.motion is not None:
            out.append((CONTACT, f"scene.colliders[{i}].{collider.kind}.motion"))
        if collider.friction > 0:
            out.append((FRICTION, f"scene.colliders[{i}].{collider.kind}.friction"))
    if config.scene.self_collision is not None:
        out.append((CONTACT, "scene.self_collision"))
    for i, pin in enumerate(config.scene.pins):
        motion = getattr(pin, "motion", None)
        if motion is not None:
            out.append((MOVING_PINS, f"scene.pins[{i}].{'rotate' if pin.rotate else 'translate'}"))
    if config.materials:
        out.append((MATERIALS, "materials"))
    for name, panel in config.materials.items():
        if panel.damping is not None and panel.damping != config.material.damping:
            out.append((PANEL_DAMPING, f"materials.{name}.damping"))
    if config.material.damping_model == "strain" and "material.damping_model" in given:
        out.append((STRAIN_DAMPING, "material.damping_model: strain"))
    if config.mesh.seams:
        out.append((SEAMS, "mesh.seams"))
    if config.scene.attach:
        out.append((ATTACH, "scene.attach"))
    if config.solver.stiffness_continuation and "solver.stiffness_continuation" in given:
        out.append((CONTINUATION, "solver.stiffness_continuation"))
    return out


def strain_damped(config):
    """Does the config's method damp by the strains' change (``material.damping_model:
    strain``, the default)? The others damp with their own βK(x_n)."""
    return config.material.damping_model == "strain" and STRAIN_DAMPING in METHODS[
        config.solver.method].supports


def barrier_contact(config):
    """Does the config's method put colliders and self-collision into a contact barrier?"""
    return CONTACT in METHODS[config.solver.method].supports


def check_supported(config, given=()):
    """Raise InputError for the first feature of ``config`` its method does not support."""
    method = METHODS[config.solver.method]
    for feature, key in requested_features(config, given):
        if feature not in method.supports:
            why = (" (it has no barrier contact: spheres and planes only, projected)"
                   if feature == CONTACT else "")
            raise InputError(f"solver.method: {method.name!r} does not support {key}{why} "
                             f"(supported by: {', '.join(m.name for m in METHODS.values() if feature in m.supports)})")


def make_integrator(model, solver, h):
    """The integrator of ``solver.method`` (a :class:`~clothtool.sim.model.config.Solver`) for a model
    and a step h."""
    return METHODS[solver.method].load()(model, solver, h)
