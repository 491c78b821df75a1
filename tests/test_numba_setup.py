"""clothtool's kernels are declared with ``clothtool.numba_setup.njit``: the process-wide
settings hold before the first kernel compiles, and no kernel pays for numba's C-callable
wrapper."""

import ast
import pathlib

import numpy as np

from clothtool.numba_setup import njit

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "clothtool"


def _numba_njit_uses(path):
    """Lines of ``path`` that take ``njit`` or ``jit`` from numba itself."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module == "numba":
            if any(alias.name in ("njit", "jit") for alias in node.names):
                lines.append(node.lineno)
        elif (isinstance(node, ast.Attribute) and node.attr in ("njit", "jit")
              and isinstance(node.value, ast.Name) and node.value.id == "numba"):
            lines.append(node.lineno)
    return lines


def test_every_kernel_module_takes_njit_from_numba_setup():
    offenders = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "numba_setup.py":
            continue
        lines = _numba_njit_uses(path)
        if lines:
            offenders[str(path.relative_to(PACKAGE))] = lines
    assert offenders == {}


def test_the_scan_finds_numba_own_njit(tmp_path):
    path = tmp_path / "kernel.py"
    path.write_text("import numba\nfrom numba import njit, prange\n\nf = numba.njit(lambda x: x)\n")
    assert _numba_njit_uses(path) == [2, 4]


def test_kernels_compile_without_the_cfunc_wrapper_and_run_from_python_and_kernels():
    @njit(cache=False)
    def twice(x):
        return 2.0 * x

    @njit(cache=False)
    def total(a):
        s = 0.0
        for v in a:
            s += twice(v)
        return s

    assert twice.targetoptions["no_cfunc_wrapper"] is True
    assert twice(1.5) == 3.0
    assert total(np.array([1.0, 2.0, 3.0])) == 12.0
