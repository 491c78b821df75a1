"""The docs' measured tables are the benchmarks': each stands between ``<!-- begin NAME -->``
and ``<!-- end NAME -->``, written by the benchmark its last line names (benchmarks/common.py:
write_doc_table) with the commit and date it was measured on; a table that names a scene the
benchmark no longer runs, a method that is not registered or a config key that no longer
exists fails here."""

import importlib
import re
from pathlib import Path

import pytest

from benchmarks.common import MEASURED, write_doc_table
from clothtool.sim.model.config import (BEND_MODELS, INTEGRATORS, MEMBRANE_MODELS, METHODS,
                                        PRECONDITIONERS, Config)
from clothtool.sim.model.schema import key_rows

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
BLOCK = re.compile(r"<!-- begin ([\w-]+) -->\n(.*?)<!-- end \1 -->", re.S)
LINE = re.compile(r"^measured on ([0-9a-f]{7,40}\+?|unknown) (\d{4}-\d\d-\d\d) \(load [\d.]+ on "
                  r"\d+ cores\), `python -m benchmarks(?: --full)? (\w+)`$", re.M)
KEYS = {key for key, _, _ in key_rows(Config)}
LEAVES = {key.rsplit(".", 1)[-1] for key in KEYS}
# a column named for a config key whose values are its choices (" (default)" marks the default)
CHOICES = {"method": ("solver.method", METHODS), "preconditioner": ("solver.preconditioner",
                                                                    PRECONDITIONERS),
           "integrator": ("solver.integrator", INTEGRATORS),
           "membrane": ("material.membrane_model", MEMBRANE_MODELS),
           "model": ("material.bend_model", BEND_MODELS)}


def blocks():
    """[(doc, name, body)] of every measured table in the docs."""
    return [(doc.relative_to(ROOT).as_posix(), name, body) for doc in DOCS
            for name, body in BLOCK.findall(doc.read_text())]


def cells(body):
    """{column: [values]} of the Markdown table in ``body``."""
    rows = [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in body.splitlines() if line.startswith("|")]
    if len(rows) < 2:
        return {}
    return {name: [r[k] for r in rows[2:] if k < len(r)] for k, name in enumerate(rows[0])}


def problems(name, body):
    """What is stale in the measured table ``name`` (its text ``body``): no measured line, a
    benchmark that is gone or no longer writes it, a scene it no longer runs, a method that
    is not registered, a config key that does not exist."""
    line = LINE.search(body)
    if line is None:
        return [f"{name}: no 'measured on <commit> <date> …, `python -m benchmarks X`' line"]
    bench = ROOT / "benchmarks" / f"bench_{line.group(3)}.py"
    if not bench.exists():
        return [f"{name}: benchmark {line.group(3)} is gone"]
    found = []
    if f'"{name}"' not in bench.read_text():
        found.append(f"{name}: {bench.name} does not write it")
    table = cells(body)
    if "scene" in table:
        module = importlib.import_module(f"benchmarks.bench_{line.group(3)}")
        scenes = set(getattr(module, "SCENES", ()))
        found += [f"{name}: scene {s!r} is not one of {bench.name}'s SCENES nor a sample config"
                  for s in dict.fromkeys(table["scene"])
                  if s not in scenes and not (ROOT / "sample_data" / f"{s}.yaml").exists()]
    for column, (key, choices) in CHOICES.items():
        for label in dict.fromkeys(table.get(column, ())):
            if label and label.split()[0] not in choices:
                found.append(f"{name}: {column} {label!r} is not a {key}")
    for token in re.findall(r"`([^`]+)`", LINE.sub("", body)):
        key = re.sub(r"\[\w*\]", "[]", token.split(":")[0].strip())
        if token.endswith(".yaml"):
            if not (ROOT / token).exists():
                found.append(f"{name}: {token} does not exist")
        elif re.fullmatch(r"[a-z_]+(\[\])?(\.[a-z_]+(\[\])?)+", key) and key not in KEYS:
            found.append(f"{name}: config key {key} does not exist")
        elif ":" in token and re.fullmatch(r"[a-z_]+", key) and key not in LEAVES:
            found.append(f"{name}: config key {key} does not exist")
    return found


def test_the_docs_have_their_measured_tables():
    names = [name for _, name, _ in blocks()]
    assert len(names) == len(set(names)), "each measured table has its own name"
    assert {"methods-verdict", "methods-front", "accuracy"} <= set(names)


@pytest.mark.parametrize("doc, name, body", blocks(), ids=lambda v: v if "\n" not in v else "")
def test_a_measured_table_names_what_exists(doc, name, body):
    assert problems(name, body) == [], doc


def test_a_stale_table_is_caught():
    """A renamed key, scene or benchmark is reported (the check can fail)."""
    body = ("| scene | method | error_m |\n| --- | --- | --- |\n| hanging | implicit bdf2 | 0.1 |\n"
            "\n" + MEASURED.format(commit="176fdc8", date="2026-12-03", load=1.0, cores=2,
                                   command="python -m benchmarks methods") + "\n")
    assert problems("methods-front", body) == []
    assert problems("methods-front", body.replace("hanging", "sheet")) == [
        "methods-front: scene 'sheet' is not one of bench_methods.py's SCENES nor a sample config"]
    assert problems("methods-front", body.replace("implicit bdf2", "rk4")) == [
        "methods-front: method 'rk4' is not a solver.method"]
    assert problems("methods-front", body.replace("| method |", "| preconditioner |")) == [
        "methods-front: preconditioner 'implicit bdf2' is not a solver.preconditioner"]
    assert problems("methods-front", body + "with `solver.newton_steps` and `damping_mode: x`") == [
        "methods-front: config key solver.newton_steps does not exist",
        "methods-front: config key damping_mode does not exist"]
    assert problems("methods-front", body.replace("benchmarks methods", "benchmarks gone")) == [
        "methods-front: benchmark gone is gone"]
    assert problems("no-such-table", body) == ["no-such-table: bench_methods.py does not write it"]
    assert problems("methods-front", "| a |\n| --- |\n") == [
        "methods-front: no 'measured on <commit> <date> …, `python -m benchmarks X`' line"]


def test_write_doc_table_replaces_only_its_block(tmp_path):
    doc = tmp_path / "doc.md"
    doc.write_text("before\n<!-- begin t -->\nold\n<!-- end t -->\nafter\n")
    write_doc_table(str(doc), "t", "| a |\n| --- |\n| 1 |\n", "methods")
    text = doc.read_text()
    assert text.startswith("before\n<!-- begin t -->\n| a |\n| --- |\n| 1 |\n\nmeasured on ")
    assert text.endswith("`python -m benchmarks methods`\n<!-- end t -->\nafter\n")
    assert LINE.search(text).group(3) == "methods"
    with pytest.raises(ValueError, match="no single <!-- begin u --> … <!-- end u --> block"):
        write_doc_table(str(doc), "u", "| a |", "methods")
