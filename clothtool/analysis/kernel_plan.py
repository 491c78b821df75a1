"""The plan of what a field kernel computes for one pair, shared by the triangle kernel
(:mod:`clothtool.analysis.deformation2d`) and the tetrahedron kernel
(:mod:`clothtool.analysis.tet`).

Each field of a kernel has a slot. The kernel's file writes the slot order down (numba
freezes it into the cached kernel, whose cache is keyed on that file only); :class:`Slots`
checks it against the registry's fields of that kernel (:mod:`clothtool.fields`).
A plan gives each slot its offset in the output buffer of its dtype (float fields: ``out``,
the storage dtype; integer fields: ``out_flags``, uint8), or −1 when it is not computed.
Field s occupies buf[start_s : start_s + M·n_s], element k at start_s + k·n_s, i.e. an
(M, *shape) C-contiguous view; ``needs`` is the bitmask of the shared quantities the
requested fields are computed from.
"""

import numpy as np

from clothtool.numba_setup import njit


class Slots:
    """The slots of one kernel: ``names`` in slot order, ``index`` name → slot, ``fields``
    (registry entries) in slot order, ``float_sizes`` (int64, numbers per element of each
    float field, 0 for integer fields: the sizes :func:`fill_nan` takes) and ``need_bits``
    (the kernel's bit for each name in the registry's ``needs``)."""

    def __init__(self, kernel, names, registry_fields, need_bits):
        registry_names = [f.name for f in registry_fields]
        if set(names) != set(registry_names) or len(names) != len(registry_names):
            raise ImportError(f"the {kernel} kernel's slots and the field registry's {kernel} "
                              f"fields differ: {sorted(set(names) ^ set(registry_names))}")
        self.kernel, self.names = kernel, tuple(names)
        self.index = {name: s for s, name in enumerate(names)}
        self.registry = tuple(registry_fields)
        self.fields = tuple(sorted(registry_fields, key=lambda f: self.index[f.name]))
        self.float_sizes = np.array([0 if f.integer else f.size for f in self.fields], np.int64)
        self.need_bits = dict(need_bits)


class KernelPlan:
    """What a kernel computes for M elements: ``starts`` (int64, one per slot, −1 = not
    computed), ``needs`` (bitmask), ``float_size`` and ``flags_size`` (the lengths of the two
    output buffers); ``fields``: the requested names in registry order. Each kernel module
    subclasses it with its :class:`Slots` as ``slots``."""

    slots = None

    def __init__(self, m, fields):
        slots = self.slots
        unknown = set(fields) - set(slots.index)
        if unknown:
            raise ValueError(f"not {slots.kernel} fields: {sorted(unknown)}")
        self.m, self.fields = m, tuple(f.name for f in slots.registry if f.name in fields)
        self.starts = np.full(len(slots.names), -1, np.int64)
        self.needs = 0
        self.float_size = self.flags_size = 0
        for s, f in enumerate(slots.fields):
            if f.name not in fields:
                continue
            if f.integer:
                self.starts[s], self.flags_size = self.flags_size, self.flags_size + m * f.size
            else:
                self.starts[s], self.float_size = self.float_size, self.float_size + m * f.size
            for need in f.needs:
                self.needs |= slots.need_bits[need]

    def allocate(self, dtype):
        """The output buffers (``out`` of ``dtype``, ``out_flags`` uint8) and a dict of their
        (M, *shape) views by field name."""
        out, out_flags = np.empty(self.float_size, dtype), np.empty(self.flags_size, np.uint8)
        views = {}
        for s, f in enumerate(self.slots.fields):
            start = self.starts[s]
            if start >= 0:
                buf = out_flags if f.integer else out
                views[f.name] = buf[start:start + self.m * f.size].reshape(self.m, *f.shape)
        return out, out_flags, views


@njit(cache=True, inline="always")
def fill_nan(k, starts, float_sizes, out):
    """NaN into every computed float field of element k (``float_sizes``: the kernel's
    :attr:`Slots.float_sizes`, a module global of the kernel's file)."""
    for s in range(starts.shape[0]):
        start = starts[s]
        if start >= 0:
            n = float_sizes[s]
            for j in range(n):
                out[start + k * n + j] = np.nan
