"""Elastic energies W(x) as the Newton methods use them: value, gradient, PSD Hessian.

An elastic energy has a block :attr:`pattern` (which vertex pairs it couples),
:meth:`energy` (W at x, for the line search and the statistics) and
:meth:`assemble` (W, ∇W and the PSD-projected Hessian K in block-CSR form).

- :class:`FemElastic`: the finite-element cloth of ``implicit``, ``explicit`` and ``vbd``: the
  sum of the Model's ``terms`` (:mod:`clothtool.sim.energies.terms`): Baraff–Witkin stretch and shear in
  Kim's form, plate, dihedral or quadratic bending, and a garment's stitches while it is sewn;
- :class:`SpringElastic`: the spring network of ``mass-spring``
  (``springs``), Σ ½k_e(‖x_i − x_j‖ − L_e)² with PSD-clamped spring Hessians.
"""

from functools import cached_property

import numpy as np

from clothtool.sim.linalg.blocks import BlockPattern
from clothtool.sim.energies.springs import spring_assemble, spring_energy


class FemElastic:
    """W = Σ over the Model's terms, on the Model's pattern (the terms' constant Hessians
    summed once in ``model.constant_hessian``); or over other ``terms`` on that pattern with
    their ``constant`` (per-panel damping's β-scaled terms)."""

    def __init__(self, model, terms=None, constant=None):
        self.model = model
        self.pattern = model.pattern
        self.terms = model.terms if terms is None else terms
        self.constant = model.constant_hessian if terms is None else constant

    def energy(self, x):
        total = 0.0
        for term in self.terms:
            total += term.energy(x)
        return total

    def soften(self, factor):
        """The terms' membrane stiffness × ``factor`` (1 restores it)."""
        for term in self.terms:
            term.soften(factor)

    def project(self, flag):
        """The membrane's Hessian PSD-projected (``flag``, the default) or exact."""
        for term in self.terms:
            term.project = flag

    def assemble(self, x, grad, values):
        """W(x); overwrites grad (N, 3) with ∇W and values with the projected Hessian K."""
        grad[:] = 0.0
        if self.constant is not None:
            values[:] = self.constant
        else:
            values[:] = 0.0
        total = 0.0
        for term in self.terms:
            total += term.assemble(x, grad, values)
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
