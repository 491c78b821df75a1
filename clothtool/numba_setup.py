"""Process-wide numba settings, applied once before the first kernel runs.

Threading layer: numba prefers TBB, then OpenMP, then its own 'workqueue'. OpenMP
workers spin while they wait; on a 2-core machine shared with the HDF5 writer
thread (and with other jobs under ``make -j`` or Slurm) that spinning costs more
CPU than it saves (measured on the 100k-triangle analyze benchmark: 3.0 s of user
time with OpenMP against 2.0 s with workqueue). So clothtool asks for workqueue
unless the user chose a layer with ``NUMBA_THREADING_LAYER``.

Start-up: loading numba's CPU target imports ``numba.np.arraymath``, which imports
``scipy.linalg`` (0.2–0.4 s here) only to decide whether ``np.correlate`` and
``np.convolve`` may call BLAS. clothtool's kernels use neither, so the target is
loaded here with that one import hidden; ``np.dot`` and ``np.linalg`` in kernels
still find BLAS, since their own check runs later, when they are compiled.

Kernels: every module declares its kernels with this module's :func:`njit` (or
:func:`njit_inner` for one that only other kernels call), so these settings hold before the
first one compiles.
"""

import os
import sys

import numba
from numba.core.registry import CPUDispatcher

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"


def _load_cpu_target():
    from numba.core.registry import cpu_target

    name = "scipy.linalg.cython_blas"
    hide = name not in sys.modules
    if hide:
        sys.modules[name] = None  # makes `import scipy.linalg.cython_blas` raise ImportError
    try:
        cpu_target.target_context.refresh()
    finally:
        if hide:
            del sys.modules[name]


_load_cpu_target()


def njit(**options):
    """``numba.njit(**options)`` without the C-callable wrapper numba builds for each function
    (``no_cfunc_wrapper``): it serves only a function passed as a first-class value or through
    ``cfunc``, which no kernel here is, and costs each compiled function about 12 ms of a first
    run's compilation (62 functions on the hanging sheet's default path)."""
    return numba.njit(no_cfunc_wrapper=True, **options)


class KernelOnly(CPUDispatcher):
    """The dispatcher of an :func:`njit_inner` kernel: a call from Python raises instead of
    jumping to the CPython wrapper numba did not build (a segmentation fault)."""

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__module__}.{self.py_func.__qualname__} is compiled "
                        "without a CPython wrapper: call it from a kernel")


def njit_inner(**options):
    """:func:`njit` for a kernel that only other kernels call: also without numba's CPython
    wrapper (``no_cpython_wrapper``), which serves only calls from Python and costs each
    compiled function about 30 ms of a first run's compilation (28 such kernels on the hanging
    sheet's default path). Its dispatcher is a :class:`KernelOnly`: a call from Python raises
    ``TypeError``. tests/test_numba_setup.py checks that no Python code refers to one."""

    def decorate(function):
        kernel = numba.njit(no_cfunc_wrapper=True, no_cpython_wrapper=True, **options)(function)
        if isinstance(kernel, CPUDispatcher):  # not under NUMBA_DISABLE_JIT
            kernel.__class__ = KernelOnly
        return kernel

    return decorate
