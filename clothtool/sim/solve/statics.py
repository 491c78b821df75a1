"""Static equilibrium: where a sheet comes to rest under gravity with its pins.

Minimises the potential Π(x) = W(x) − Σ_v m_v g·x_v over the free vertices (pinned ones stay
at their initial positions), W the implicit method's elastic energy
(:class:`~clothtool.sim.energies.energy.FemElastic`), by Newton's method with the PSD-projected
Hessian (the corrected plate's whole Q + C, which the time steppers' matrix leaves out), a direct sparse solve (scipy) and a backtracking line search, with gravity applied
in ``load_steps`` equal increments (each one's minimum starts the next: large deflections,
such as a cantilever at three bending lengths, converge from the flat state). No colliders.
The textile tests (cantilever, hanging strip, drape) use it in place of a long damped run.

Where the rest has compressed triangles (a draped disc's folds on a coarse mesh) the projected
Hessian is stiffer than the true one across them and Newton converges only linearly; with
``exact_hessian`` each Newton step first solves with the membrane's exact Hessian (whose
negative curvatures the rest of the sheet outweighs near a minimum; the edge membrane's
with its flap pairs, which the assembled matrix majorises), kept when it descends
and its line search keeps at least ``EXACT_FLOOR`` of it, else the projected step is taken
(a modified Newton method, Nocedal & Wright 2006, §3.4).
"""

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as spla

from clothtool.errors import NumericalError
from clothtool.sim.linalg.blocks import BlockMatrix
from clothtool.sim.energies.energy import FemElastic

RIDGE = 1e-10  # relative diagonal shift: a flat sheet without bending has no normal stiffness
STALL = 1e-5  # a cut Newton step below this × the mesh's extent: converged
EXACT_FLOOR = 1e-3  # the exact Hessian's step is kept when the line search keeps this much of it


def static_equilibrium(model, x=None, *, tolerance=1e-6, max_iterations=100, load_steps=4,
                       exact_hessian=False, counts=None):
    """Positions (N, 3) at rest; ``x``: the start (default the model's initial positions).
    Stops when no free vertex has an out-of-balance force above ``tolerance`` times the
    largest vertex weight, or when the line search cuts a Newton step shorter than 1e-5 of
    the mesh's extent (the potential is then flat to its rounding); raises :class:`~clothtool.errors.NumericalError` when
    ``max_iterations`` Newton steps per load step do not get there. ``exact_hessian``: try
    the membrane's exact Hessian first (module docstring). ``counts``: a dict that gets the
    Newton steps (``newton``), those taken with the exact Hessian (``exact``) and the last
    out-of-balance force over the largest weight (``residual``)."""
    energy = FemElastic(model)
    x = (model.mesh.positions if x is None else np.asarray(x, np.float64)).copy()
    n = model.n_vertices
    free = np.repeat(model.free, 3)
    weight = model.mass[:, None] * model.gravity[None, :]
    grad = np.zeros((n, 3))
    matrix = BlockMatrix(model.pattern)
    extent = float(np.ptp(model.mesh.rest3d, axis=0).max())
    extra = [t.unassembled() for t in energy.terms if hasattr(t, "unassembled")]
    extra = sum(e for e in extra if e is not None)  # the corrected plate's C (terms.PlateBending)
    exact_parts = [t for t in energy.terms if hasattr(t, "exact_remainder")]  # terms.EdgeMembrane
    tally = {"newton": 0, "exact": 0, "residual": 0.0}
    try:
        for step in range(1, load_steps + 1):
            load = weight * (step / load_steps)

            def potential(y):
                return energy.energy(y) - float(np.sum(load * y))

            def newton_step(projected):
                """The Newton step (N, 3) and the gradient on the free coordinates."""
                energy.project(projected)
                energy.assemble(x, grad, matrix.values)
                k = matrix.to_scipy() + extra
                if exact_parts and not projected:
                    k = k + sum(t.exact_remainder(x) for t in exact_parts)
                k = k[free][:, free]
                shift = RIDGE * float(np.abs(k.diagonal()).max() or 1.0)
                g = (grad - load).ravel()[free]
                dx = np.zeros(3 * n)
                if np.abs(g).max() > tolerance * np.abs(load).max():
                    dx[free] = spla.spsolve((k + shift * sps.eye(k.shape[0])).tocsc(), -g)
                return dx.reshape(n, 3), g

            def line_search(dx, floor):
                before, t = potential(x), 1.0
                slack = 1e-13 * abs(before)  # rounding of Π: near the minimum it cannot fall further
                while t > floor and not potential(x + t * dx) <= before + slack:
                    t *= 0.5
                return t

            for _ in range(max_iterations):
                dx, g = newton_step(not exact_hessian)
                tally["residual"] = float(np.abs(g).max() / np.abs(load).max())
                if tally["residual"] <= tolerance:
                    break
                t = 0.0
                if exact_hessian and float(dx.ravel()[free] @ g) < 0.0:
                    t = line_search(dx, EXACT_FLOOR)
                if t > EXACT_FLOOR:
                    tally["exact"] += 1
                else:
                    if exact_hessian:
                        dx, g = newton_step(True)
                    t = line_search(dx, 1e-12)
                if t < 1.0 and np.abs(dx).max() <= STALL * extent:
                    break  # Π no longer falls along a step this short: it is flat to its rounding
                if t <= 1e-12:
                    raise NumericalError(f"static equilibrium: the line search stalled "
                                         f"(load step {step} of {load_steps})")
                x += t * dx
                tally["newton"] += 1
            else:
                raise NumericalError(f"static equilibrium: no convergence in {max_iterations} "
                                     f"Newton steps (load step {step} of {load_steps})")
    finally:
        energy.project(True)
        if counts is not None:
            counts.update(tally)
    return x
