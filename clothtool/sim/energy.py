"""Elastic energies W(x) as the Newton methods use them: value, gradient, PSD Hessian.

An elastic energy has a block :attr:`pattern` (which vertex pairs it couples),
:meth:`energy` (W at x, for the line search and the statistics) and
:meth:`assemble` (W, ∇W and the PSD-projected Hessian K in block-CSR form).

- :class:`FemElastic`: the finite-element cloth of ``implicit`` and ``explicit``:
  Baraff–Witkin stretch and shear in Kim's form (``membrane``) plus plate (``plate``),
  dihedral or quadratic bending (``bending``);
- :class:`SpringElastic`: the spring network of ``mass-spring``
  (``springs``), Σ ½k_e(‖x_i − x_j‖ − L_e)² with PSD-clamped spring Hessians.
"""

from functools import cached_property

import numpy as np

from clothtool.sim.bending import dihedral_assemble, dihedral_total_energy, quadratic_gradient
from clothtool.sim.linalg.blocks import BlockPattern
from clothtool.sim.membrane import membrane_assemble, membrane_total_energy
from clothtool.sim.plate import hessian_gradient
from clothtool.sim.springs import spring_assemble, spring_energy


def fem_elastic_energy(model, x):
    """W(x) of the finite-element material: stretch + shear (Kim 2020) + bending."""
    total = 0.0
    if model.has_membrane:
        total += membrane_total_energy(x, model.faces, model.dr_inv, model.area,
                                       model.stretch, model.k_shear)
    if model.bend_model == "hessian":
        total += hessian_gradient(x, *model.plate, np.zeros((0, 3)))
    elif model.bend_model == "dihedral":
        total += dihedral_total_energy(x, model.hinge, model.hinge_rest_angle, model.hinge_coef)
    elif model.bend_model == "quadratic":  # an empty gradient array: energy only
        total += quadratic_gradient(x, model.hinge, model.hinge_weights, model.hinge_coef,
                                    np.zeros((0, 3)))
    return total


class FemElastic:
    """Stretch + shear (Kim 2020) + plate, dihedral or quadratic bending, on the Model's pattern."""

    def __init__(self, model):
        self.model = model
        self.pattern = model.pattern

    def energy(self, x):
        return fem_elastic_energy(self.model, x)

    def assemble(self, x, grad, values):
        """W(x); overwrites grad (N, 3) with ∇W and values with the projected Hessian K."""
        model = self.model
        grad[:] = 0.0
        if model.constant_hessian is not None:
            values[:] = model.constant_hessian
        else:
            values[:] = 0.0
        total = 0.0
        if model.has_membrane:
            total += membrane_assemble(x, model.faces, model.dr_inv, model.area, model.stretch,
                                       model.k_shear, model.tri_slots, grad, values)
        if model.bend_model == "hessian":  # its constant Hessian is in constant_hessian
            total += hessian_gradient(x, *model.plate, grad)
        elif model.bend_model == "dihedral":
            total += dihedral_assemble(x, model.hinge, model.hinge_rest_angle, model.hinge_coef,
                                       model.hinge_slots, grad, values)
        elif model.bend_model == "quadratic":
            total += quadratic_gradient(x, model.hinge, model.hinge_weights, model.hinge_coef, grad)
        return total


class SpringElastic:
    """The Model's spring network, on a pattern of its own (one block pair per spring)."""

    def __init__(self, model):
        self.springs = model.springs
        self._n = model.n_vertices

    @cached_property
    def pattern(self):
        """Built on first use: only the Newton method needs it."""
        return BlockPattern(self._n, self.springs.pairs)

    @cached_property
    def slots(self):
        return self.pattern.slots(self.springs.pairs)

    def energy(self, x):
        sp = self.springs
        return spring_energy(x, sp.i, sp.j, sp.rest, sp.k)

    def assemble(self, x, grad, values):
        """W(x); overwrites grad with ∇W and values with the PSD-clamped spring Hessians."""
        sp = self.springs
        grad[:] = 0.0
        values[:] = 0.0
        return spring_assemble(x, sp.i, sp.j, sp.rest, sp.k, self.slots, grad, values)
