"""The import contract of the package (docs/architecture.md): layers, no upward import, no cycle.

Every ``import`` of a clothtool module counts, at module level or inside a function (a lazy
import is still a dependency). The layers, top to bottom:

1. ``clothtool.cli``
2. ``sweeps``: runs of ``sim`` and ``analysis`` over parameter grids, and their report;
3. ``results``, ``analysis``, ``sim``: independent, none imports another (a finished result
   is read through ``io``);
4. ``contact``, ``geometry``, ``io``;
5. the base: every other module (``errors``, ``fields``, ``vec3``, ``config_tools``, …).

A module imports only from its own layer's package or from layers below. Inside ``sim`` the
rooms have floors of their own, top to bottom: the modules at ``sim``'s top (``api``,
``output``, ``scene``, ``textile``), ``sim.solvers`` (one module per method; ``sim.model.methods``
names them as strings), ``sim.solve``, ``sim.model``, ``sim.energies``, ``sim.linalg``; a room
imports only its own floor and the floors below. And the import graph has no cycle.
"""

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "clothtool"
LAYERS = (
    ("clothtool.cli",),
    ("clothtool.sweeps",),
    ("clothtool.results", "clothtool.analysis", "clothtool.sim"),
    ("clothtool.contact", "clothtool.geometry", "clothtool.io"),
)
INDEPENDENT = {2}  # layers whose packages must not import one another
SIM_FLOORS = ("clothtool.sim.solvers", "clothtool.sim.solve", "clothtool.sim.model",
              "clothtool.sim.energies", "clothtool.sim.linalg")  # top to bottom, inside sim


def module_name(path, root=PACKAGE):
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(root=PACKAGE):
    """{module: [(imported clothtool module, line)]} of every module under ``root``."""
    modules = {module_name(p, root): p for p in sorted(root.rglob("*.py"))}
    graph = {}
    for name, path in modules.items():
        edges = []
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                edges += [(a.name, node.lineno) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([node.module] if node.module else []))
                for a in node.names:  # `from pkg import module` imports pkg.module
                    edges.append((f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base,
                                  node.lineno))
        graph[name] = list(dict.fromkeys((target, line) for target, line in edges
                                         if target.split(".")[0] == "clothtool" and target != name))
    return graph, modules


def layer_of(module):
    """(layer index, its package) of a module; the base is len(LAYERS)."""
    for index, packages in enumerate(LAYERS):
        for package in packages:
            if module == package or module.startswith(package + "."):
                return index, package
    return len(LAYERS), "base"


def sim_floor(module):
    """The floor of a ``sim`` module (0 for the top modules, 1 for ``sim.solvers``, …), or None."""
    for index, room in enumerate(SIM_FLOORS, start=1):
        if module == room or module.startswith(room + "."):
            return index
    return 0 if module.startswith("clothtool.sim.") else None


def violations(graph, modules, root=PACKAGE):
    found = []
    for source, edges in graph.items():
        here, package = layer_of(source)
        for target, line in edges:
            there, other = layer_of(target)
            where = f"{modules[source].relative_to(root.parent)}:{line} imports {target}"
            if there < here:
                found.append(f"{where}: {other} is above {package}")
            elif there == here and package != other and here in INDEPENDENT:
                found.append(f"{where}: {package} and {other} are independent")
            a, b = sim_floor(source), sim_floor(target)
            if a is not None and b is not None and b < a:
                found.append(f"{where}: {target.rsplit('.', 1)[0]} is a floor above "
                             f"{source.rsplit('.', 1)[0]}")
    return found


def cycles(graph):
    """The strongly connected components of more than one module (Tarjan), as frozensets."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w, _ in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(frozenset(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_upward_or_sideways_import():
    graph, modules = imports()
    found = violations(graph, modules)
    assert not found, "import contract broken (docs/architecture.md):\n  " + "\n  ".join(found)


def test_no_import_cycle():
    graph, _ = imports()
    found = [sorted(c) for c in cycles(graph)]
    assert not found, "import cycles: " + "; ".join(" ↔ ".join(c) for c in found)


def test_the_contract_catches_what_it_forbids(tmp_path):
    """An upward import, a sideways import between independent packages, a reach from a
    lower floor of sim into a higher one and a cycle, each in a throw-away package, are each
    reported."""
    root = tmp_path / "clothtool"
    files = {
        "__init__.py": "", "errors.py": "from clothtool.io import h5\n",
        "io/__init__.py": "", "io/h5.py": "from clothtool import errors\n",
        "sim/__init__.py": "", "sim/energies/energy.py": "from clothtool.sim.solvers.springs import k\n",
        "sim/solvers/__init__.py": "", "sim/solvers/springs.py": "k = 1\n",
        "results/__init__.py": "", "results/info.py": "def f():\n    from clothtool.analysis import summary\n",
        "analysis/__init__.py": "", "analysis/summary.py": "",
    }
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    graph, modules = imports(root)
    found = violations(graph, modules, root)
    assert any("errors.py:1 imports clothtool.io.h5: clothtool.io is above base" in f for f in found)
    assert any("results/info.py:2 imports clothtool.analysis.summary: clothtool.results and "
               "clothtool.analysis are independent" in f for f in found)
    assert any("sim/energies/energy.py:1 imports clothtool.sim.solvers.springs" in f for f in found)
    assert cycles(graph) == [frozenset({"clothtool.errors", "clothtool.io.h5"})]


@pytest.mark.parametrize("module,layer", [("clothtool.cli", 0), ("clothtool.sweeps.pool", 1),
                                          ("clothtool.sim.solvers.vbd", 2),
                                          ("clothtool.io.result", 3), ("clothtool.fields", 4)])
def test_layers_are_where_the_docs_say(module, layer):
    assert layer_of(module)[0] == layer
