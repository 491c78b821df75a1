"""clothtool's kernels are declared with ``clothtool.numba_setup.njit``: the process-wide
settings hold before the first kernel compiles, and no kernel pays for numba's C-callable
wrapper. Kernels that only other kernels call are declared with ``njit_inner`` (no CPython
wrapper either), and no Python code refers to one."""

import ast
import pathlib

import numpy as np
import pytest

from clothtool.numba_setup import njit, njit_inner

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "clothtool"
KERNEL_DECORATORS = ("njit", "njit_inner")


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


def _decorator(node):
    call = node.func if isinstance(node, ast.Call) else node
    if isinstance(call, ast.Name):
        return call.id
    return call.attr if isinstance(call, ast.Attribute) else None


def _is_kernel(function):
    return any(_decorator(d) in KERNEL_DECORATORS for d in function.decorator_list)


def _module(root, path):
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


class _References(ast.NodeVisitor):
    """Loads of the names bound to ``inner`` kernels (``local``: name → kernel; ``modules``:
    name → module) outside the bodies of kernels."""

    def __init__(self, local, modules, inner):
        self.local, self.modules, self.inner = local, modules, inner
        self.in_kernel, self.found = [False], []

    def visit_FunctionDef(self, node):
        for child in node.decorator_list + node.args.defaults:
            self.visit(child)
        self.in_kernel.append(_is_kernel(node))
        for child in node.body:
            self.visit(child)
        self.in_kernel.pop()

    visit_AsyncFunctionDef = visit_FunctionDef

    def visit_Name(self, node):
        if isinstance(node.ctx, ast.Load) and node.id in self.local and not self.in_kernel[-1]:
            self.found.append((self.local[node.id], node.lineno))

    def visit_Attribute(self, node):
        dotted, base = [node.attr], node.value
        while isinstance(base, ast.Attribute):
            dotted.append(base.attr)
            base = base.value
        if isinstance(base, ast.Name) and not self.in_kernel[-1]:
            module = self.modules.get(base.id, base.id)
            *path, name = [module] + dotted[::-1]
            if (".".join(path), name) in self.inner:
                self.found.append(((".".join(path), name), node.lineno))
                return
        self.generic_visit(node)


def _python_references_to_inner_kernels(root, folders=("clothtool", "tests", "benchmarks",
                                                         "scripts")):
    """{file: [(kernel, line)]}: every place outside a kernel's body where code under ``root``
    refers to a kernel declared with ``njit_inner`` in its package ``root/clothtool``: a call
    from Python, or the kernel handed to Python code as a value."""
    trees = {path: ast.parse(path.read_text(), str(path))
             for folder in folders for path in sorted((root / folder).rglob("*.py"))}
    inner = set()
    for path, tree in trees.items():
        if path.is_relative_to(root / "clothtool"):
            inner |= {(_module(root, path), node.name) for node in tree.body
                      if isinstance(node, ast.FunctionDef)
                      and any(_decorator(d) == "njit_inner" for d in node.decorator_list)}
    modules_with_kernels = {module for module, _ in inner}
    found = {}
    for path, tree in trees.items():
        this = _module(root, path)
        local = {name: (module, name) for module, name in inner if module == this}
        modules = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                for alias in node.names:
                    if (node.module, alias.name) in inner:
                        local[alias.asname or alias.name] = (node.module, alias.name)
                    elif f"{node.module}.{alias.name}" in modules_with_kernels:
                        modules[alias.asname or alias.name] = f"{node.module}.{alias.name}"
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.asname:
                        modules[alias.asname] = alias.name
        visitor = _References(local, modules, inner)
        visitor.visit(tree)
        if visitor.found:
            found[str(path.relative_to(root))] = visitor.found
    return found


def test_no_python_code_refers_to_a_kernel_without_cpython_wrapper():
    assert _python_references_to_inner_kernels(ROOT) == {}


def test_the_scan_finds_python_references_to_inner_kernels(tmp_path):
    package = tmp_path / "clothtool" / "sub"
    package.mkdir(parents=True)
    (tmp_path / "tests").mkdir()
    (package / "kernels.py").write_text(
        "from clothtool.numba_setup import njit, njit_inner\n"
        "@njit_inner(cache=True)\n"
        "def inner(x):\n"
        "    return 2.0 * x\n"
        "@njit(cache=True)\n"
        "def outer(x):\n"
        "    return inner(x) + 1.0\n"
        "def python(x):\n"
        "    return inner(x)\n")
    (tmp_path / "tests" / "test_kernels.py").write_text(
        "import clothtool.sub.kernels as k\n"
        "from clothtool.sub import kernels\n"
        "from clothtool.sub.kernels import inner as twice, outer\n"
        "from clothtool.numba_setup import njit\n"
        "@njit(cache=False)\n"
        "def through_a_kernel(x):\n"
        "    return twice(x)\n"
        "def test_it():\n"
        "    assert outer(1.0) == through_a_kernel(1.0) + 1.0\n"
        "    assert twice(1.0) == kernels.inner(1.0) == k.inner(1.0)\n"
        "    f = twice\n")
    kernel = ("clothtool.sub.kernels", "inner")
    assert _python_references_to_inner_kernels(tmp_path) == {
        "clothtool/sub/kernels.py": [(kernel, 9)],
        "tests/test_kernels.py": [(kernel, 10), (kernel, 10), (kernel, 10), (kernel, 11)]}


def test_inner_kernels_run_from_kernels_and_raise_from_python():
    @njit_inner(cache=False)
    def twice(x):
        return 2.0 * x

    @njit(cache=False)
    def total(a):
        s = 0.0
        for v in a:
            s += twice(v)
        return s

    assert twice.targetoptions["no_cpython_wrapper"] is True
    assert twice.targetoptions["no_cfunc_wrapper"] is True
    assert total(np.array([1.0, 2.0, 3.0])) == 12.0
    with pytest.raises(TypeError, match="without a CPython wrapper"):
        twice(1.5)
