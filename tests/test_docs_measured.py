"""The docs' measured figures are the benchmarks': each stands in a table between
``<!-- begin NAME -->`` and ``<!-- end NAME -->``, written by the benchmark its last line names
(benchmarks/common.py: write_doc_table) with the commit and date it was measured on; a table
that names a scene the benchmark no longer runs, a method that is not registered or a config
key that no longer exists fails here, and so does a figure typed by hand anywhere else in
README.md or docs/ (:func:`hand_typed`)."""

import importlib
import importlib.util
import re
import subprocess
from pathlib import Path

import pytest

from benchmarks.common import MEASURED, write_doc_table
from clothtool.sim.model.config import (BEND_MODELS, INTEGRATORS, MEMBRANE_MODELS, METHODS,
                                        PRECONDITIONERS, Config)
from clothtool.sim.model.schema import key_rows

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("**/*.md")) + [ROOT / "README.md"]
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


def test_a_table_only_full_measures_is_kept_by_a_quick_run(tmp_path, monkeypatch):
    """``full_only``: without --full the doc keeps its table (the one --full wrote); with it,
    the table is written and its line names ``--full``."""
    from benchmarks import common

    doc = tmp_path / "doc.md"
    doc.write_text("<!-- begin t -->\nold\n<!-- end t -->\n")
    monkeypatch.setattr(common, "FULL", False)
    write_doc_table(str(doc), "t", "| a |\n| --- |\n| 1 |\n", "sweep", full_only=True)
    assert doc.read_text() == "<!-- begin t -->\nold\n<!-- end t -->\n"
    monkeypatch.setattr(common, "FULL", True)
    write_doc_table(str(doc), "t", "| a |\n| --- |\n| 1 |\n", "sweep", full_only=True)
    assert LINE.search(doc.read_text()).group(0).endswith("`python -m benchmarks --full sweep`")


# ---------------------------------------------------------------------------- hand-typed figures
#
# A measured figure is a number in a unit of the machine's work (a time, a rate, a size, a
# ratio of times) or an error against a reference, in a sentence about speed, cost, memory or
# accuracy. Outside the measured blocks there are none: a doc says what the benchmark shows in
# words and points to its table. Bounds (goals, limits, tolerances: ≤ 900 s, within 2 %,
# h = 1 s) are not figures, nor are a scene's inputs in a sentence about something else.

SUP = "⁻⁰¹²³⁴⁵⁶⁷⁸⁹"
NUMBER = (r"(?<![\w.·/^-])\d+(?:[.,]\d+)?(?:\s?[–-]\s?\d+(?:[.,]\d+)?)?"
          rf"(?:\s?[·×]\s?10[{SUP}]+|e[-+]?\d+)?")
# a figure of the machine's wherever it stands: short times, sizes, rates per second (but a
# speed in m/s, rad/s …), CPU-seconds
STRONG = (r"\s?(?:ns|µs|us|ms|milliseconds?)(?![\w])|\s?[kMGT]B(?:/s)?(?![\w])|\s?[KMG]iB(?![\w])"
          r"|\s?bytes\b|\s?(?:[kMG]\s)?(?!(?:m|mm|cm|rad|N|kg|J|W|deg)/s)[A-Za-z][\w-]*/s(?![\w/²])"
          r"|\s?CPU[- ]s(?![\w])")
# a figure of the machine's in a sentence about speed, cost or memory: seconds, minutes, per
# cent, a ratio (1.5×, not the 16 × 5 of a size), millions of something
WEAK = (r"\s?(?:s|seconds?|min|minutes?|%|×(?!\s?\d)|x(?=\s)(?!\s?\d)|[kM](?=\s[a-z]))"
        r"(?![\w/])")
FIGURE = re.compile(rf"({NUMBER})(?:({STRONG})|({WEAK}))")
# an error against a reference (7e-16, 5·10⁻¹⁴), not a quantity in a physical unit
SCI = re.compile(rf"(?<![\w.=])\d(?:\.\d+)?(?:e-\d+|\s?·\s?10⁻[{SUP}]+)(?![\d{SUP}])"
                 r"(?!\s?(?:N|m|kg|J|Pa|s|rad)\b|\s?N·m|\s?N/m)")
COST = re.compile(r"\b(?:cpu|wall[- ](?:time|clock)|faster|slower|speed\w*|throughput|took|takes?|"
                  r"costs?|load average|threads?|cores?|memory|peak|per second|run ?time|overhead|"
                  r"start-?up|times?)\b", re.I)
ACCURACY = re.compile(r"\b(?:errors?|agree\w*|accura\w*|precision|residual)\b", re.I)
HEADING = re.compile(r"\b(?:performance|speed|timings?)\b", re.I)
# what introduces a table as measured
CALLED_MEASURED = re.compile(r"python -m benchmarks|\bmeasured\b", re.I)
BOUND = re.compile(r"(?:[≤≥<>=±]|\b(?:under|below|above|over|less than|more than))\s*~?\s*$|"
                   r"\b(?:at (?:most|least)|within|goal|capped at|up to)\b[^,;:()]*$", re.I)
CODE = re.compile(r"`[^`]*`")
NUMERIC_CELL = re.compile(r"\s*[~≈+−-]?\d[\d.,]*(?:e[-+]?\d+)?\s?\S{0,12}\s*")
# a column of measured figures by its header
MEASURED_COLUMN = re.compile(r"\b(?:s|ms|µs|seconds?|min|[kMG]B|cpu|wall|speed\w*|time|vs|ratio|"
                             r"errors?)\b|/s\b|×", re.I)


def cells_of(row):
    return row.strip().strip("|").split("|")


def sentences(paragraph):
    """The sentences of a paragraph, each list item apart."""
    found = []
    for item in re.split(r"\n\s*(?=[-*] |\d+\. )", paragraph):
        flat = " ".join(line.strip() for line in item.splitlines())
        found += re.split(r"(?<=[.;!?])\s+(?=[A-Z(`*\[])", flat)
    return found


def figures(text, context, heading):
    """The measured figures in ``text`` (a sentence or a table row) given its ``context`` (the
    sentence, or the row with its table's header) and whether its section is about speed."""
    context = CODE.sub(" ", context)
    cost, accuracy = heading or COST.search(context), ACCURACY.search(context)
    found = [m.group(0).strip() for m in FIGURE.finditer(text)
             if (m.group(2) or cost) and not BOUND.search(text[:m.start()])]
    if accuracy:
        found += [m.group(0) for m in SCI.finditer(text) if not BOUND.search(text[:m.start()])]
    return found


def reference_tables():
    """The names of the docs' reference tables, the code's own (scripts/reference_tables.py
    writes them, tests/test_reference_tables.py holds them to it)."""
    spec = importlib.util.spec_from_file_location("reference_tables",
                                                  ROOT / "scripts" / "reference_tables.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return tuple(module.TABLES)


REFERENCE = re.compile("|".join(
    rf"<!-- generated: {re.escape(n)} -->\n.*?<!-- end generated: {re.escape(n)} -->"
    for n in reference_tables()), re.S)


def hand_typed(text):
    """[(figure, where)]: the measured figures of a doc's ``text`` outside its measured blocks
    and reference tables, and its tables of measured figures (a table the text around it calls
    measured, or names its benchmark for, as one finding)."""
    text = REFERENCE.sub("", BLOCK.sub("", text))
    found, heading = [], False
    paragraphs = [p for p in re.split(r"\n\s*\n", text) if p.strip()]
    for k, paragraph in enumerate(paragraphs):
        lines = paragraph.strip("\n").splitlines()
        if lines[0].startswith("#"):
            heading = bool(HEADING.search(lines[0]))
            lines = lines[1:]
            if not lines:
                continue
        if lines[0].lstrip().startswith("|") and len(lines) > 2:
            head, rows = lines[0], lines[2:]
            around = " ".join(paragraphs[max(k - 1, 0):k] + paragraphs[k + 1:k + 2])
            numeric = [c for row in rows for c in cells_of(row) if NUMERIC_CELL.fullmatch(c)]
            if CALLED_MEASURED.search(around) and len(numeric) >= 2:
                found.append(("a measured table", head))
                continue
            found += [(f, row) for row in rows for f in figures(row, head + " " + row, heading)]
            columns = [MEASURED_COLUMN.search(CODE.sub(" ", c)) for c in cells_of(head)]
            found += [(c, row) for row in rows for c, measured in zip(cells_of(row), columns)
                      if measured and NUMERIC_CELL.fullmatch(c)]
            continue
        found += [(f, s) for s in sentences("\n".join(lines)) for f in figures(s, s, heading)]
    return found


@pytest.mark.parametrize("doc", DOCS, ids=lambda d: d.relative_to(ROOT).as_posix())
def test_no_figure_is_typed_by_hand(doc):
    """Every figure a benchmark measures stands in a block it writes, with the commit and date
    it was measured on (docs/simulate.md's tables); the text around says what they show."""
    found = [f"{figure}: {where[:120]}" for figure, where in hand_typed(doc.read_text())]
    assert found == [], ("figures typed by hand: have the benchmark that measures them write "
                         "them (benchmarks/common.py: write_doc_table), or say in words what "
                         "they show")


# figures as they were typed by hand in the docs before their benchmarks wrote them
TYPED = [
    "`analyze`, 99 458 triangles × 49 pairs, all fields: 1.33 s, 3.7 M triangle-pairs/s.",
    "| command | seconds |\n| --- | --- |\n| `clothtool --help` | 0.07 |",
    "| route | s per pair | vertex-pairs/s |\n|---|---|---|\n| clothtool, 2 threads | 0.032 | 1.57 M |",
    "The 2D kernel does 1.6·10⁷ triangles/s on 2 threads, 1.0·10⁷ on 1.",
    "Peak memory, 50 vs 200 frames: 226 MB vs 228 MB.",
    "Cost: 490 views, 0.3 MB of metadata, about 20 ms to make (the analysis takes about 1.3 s).",
    "Faces are parsed in one pass (about 85 ms for a frame, 2–2.5× faster than trimesh).",
    "Gzip costs 9–11× the run time for a 40 % smaller file, so it is off by default.",
    "The kernel is about 22× faster on one thread with the same accuracy.",
    "Rotations agree with extended precision to 7e-16 and with scipy's to 8e-15.",
    "The twist took 94.6 s of CPU against 139.1 s on main (0.68×).",
    "Under load the analysis takes 1.33 s.",
    "The sheet costs 137 ms CPU per step against 148 ms before.",
    "`strain` costs 1.7–2.1× the CPU of `frozen` on the hanging sheet.",
    "Measured (`python -m benchmarks sweep`): the sweep adds a fixed start, 2–3 s, not a cost "
    "per run: 24 runs take 1.04× runs × one run on one job.",
    "Measured on the loaded machine:\n\n| runs | jobs | one run |\n| --- | --- | --- |\n"
    "| 12 | 1 | 1.38 |\n| 24 | 2 | 1.40 |",
    "## Performance\n\n| what | figure |\n| --- | --- |\n| analyze | 1.33 s |",
]
# inputs, bounds and sizes that are not measured figures
NOT_TYPED = [
    "The plate (0.5 m, 12×12, damping 0.01 s), 0.5 s at 30 fps, shear 1e3 N/m, bend 1e-3 N·m.",
    "`make bench` takes at most 900 s; the goal: ≤ 1.2× the cost, under 2 s a run.",
    "Stiff cloth at h = 1 s costs more Newton steps.",
    "The Cusick drape coefficient is within 2 % of the finer mesh's.",
    "xpbd with 16 × 5 substeps on a 64 × 64 sheet; a sphere turning at π rad/s.",
    "| option | runs |\n| --- | --- |\n| `--grid` | the product of the lists |",
    "RING_TOL = 1e-4 flags the thinnest rings.",
]


@pytest.mark.parametrize("text", TYPED)
def test_a_figure_typed_by_hand_is_found(text):
    assert hand_typed(text), text
    line = MEASURED.format(commit="3ee4668", date="2026-01-01", load=1.0, cores=2,
                           command="python -m benchmarks analyze")
    block = f"<!-- begin t -->\n{text}\n\n{line}\n<!-- end t -->\n"
    assert hand_typed(block) == [], "inside a measured block it is the benchmark's"


@pytest.mark.parametrize("text", NOT_TYPED)
def test_an_input_or_a_bound_is_not_a_figure(text):
    assert hand_typed(text) == []


def git(*args):
    done = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True)
    return done.returncode, done.stdout.strip()


def test_each_measured_line_names_a_commit_of_this_history():
    """A 'measured on <commit>' line names a commit this checkout descends from (a table
    measured on another branch, or a line typed by hand, is caught); skipped outside a full
    git checkout."""
    if git("rev-parse", "--is-shallow-repository") != (0, "false"):
        pytest.skip("not a full git checkout")
    commits = {m.group(1).rstrip("+") for doc in DOCS for m in LINE.finditer(doc.read_text())}
    assert commits
    assert [c for c in sorted(commits)
            if git("merge-base", "--is-ancestor", c, "HEAD")[0] != 0] == []
