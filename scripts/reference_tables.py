"""Write the reference tables of the docs from the code: the config keys (key, default,
meaning) from the config schema's declarations, the analysis fields from the field registry.

    python scripts/reference_tables.py           # rewrite the tables in README.md and docs/
    python scripts/reference_tables.py --check   # exit 1 naming the stale tables

Each table stands between ``<!-- generated: NAME -->`` and ``<!-- end generated: NAME -->``
in its Markdown file; tests/test_reference_tables.py fails when one differs from the code.
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from clothtool import fields  # noqa: E402
from clothtool.sim.model.config import Config  # noqa: E402
from clothtool.sim.model.schema import key_rows  # noqa: E402


def format_default(value):
    """A default as the table shows it: — for none, YAML spelling otherwise."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return re.sub(r"e([+-])0*(\d)", lambda m: "e" + m.group(1).lstrip("+") + m.group(2),
                      f"{value:g}")
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(format_default(v).strip("`") for v in value) + "]"
    if isinstance(value, dict):
        return "{}" if not value else str(value)
    if isinstance(value, (str, Path)):
        return f"`{value}`"
    return str(value)


def cell(text):
    return str(text).replace("|", "\\|")


def config_rows():
    """(key, default as shown, meaning) of every config key."""
    return [(key, format_default(default), doc) for key, default, doc in key_rows(Config)]


def config_table():
    lines = ["| key | default | meaning |", "| --- | --- | --- |"]
    lines += [f"| `{key}` | {cell(default)} | {cell(doc)} |" for key, default, doc in config_rows()]
    return "\n".join(lines)


def shape(f):
    if f.integer:
        return "uint8"
    return "×".join(map(str, f.shape)) if len(f.shape) > 1 else str(f.shape[0]) if f.shape \
        else "scalar"


def field_table(selected):
    lines = ["| field | shape | meaning |", "| --- | --- | --- |"]
    lines += [f"| `{f.name}` | {shape(f)} | {cell(f.definition)} |" for f in selected]
    return "\n".join(lines)


def dataset_table(selected):
    """The 3D variant's datasets: path, shape with the leading (P, count) axes, definition."""
    count = {"vertex": "N", "face": "M", "edge": "E"}
    lines = ["| dataset | shape | definition |", "| --- | --- | --- |"]
    for f in selected:
        dims = ", ".join(["P", count[f.group], *map(str, f.shape)])
        lines.append(f"| `/{f.key}` | ({dims}){' uint8' if f.integer else ''} | "
                     f"{cell(f.definition)} |")
    return "\n".join(lines)


TABLES = {  # name: (file, the table's text)
    "config keys": ("docs/simulate.md", config_table),
    "2D fields": ("README.md", lambda: field_table(
        [f for f in fields.FIELDS_2D if not f.extended])),
    "extended 2D fields": ("README.md", lambda: field_table(
        [f for f in fields.FIELDS_2D if f.extended])),
    "tet fields": ("README.md", lambda: field_table(fields.FIELDS_TET)),
    "3D variant datasets": ("docs/kabsch.md", lambda: dataset_table(
        [f for f in fields.REGISTRY if f.kernel in ("kabsch", "face3d", "dihedral")])),
}


def block(name):
    return re.compile(rf"(<!-- generated: {re.escape(name)} -->\n)(.*?)(\n<!-- end generated: "
                      rf"{re.escape(name)} -->)", re.S)


def stale():
    """{file: its text with every table rewritten}, for the files whose tables differ; and the
    names of those tables."""
    texts, names = {}, []
    for name, (file, table) in TABLES.items():
        text = texts.get(file) or (ROOT / file).read_text()
        match = block(name).search(text)
        if match is None:
            raise SystemExit(f"{file}: no <!-- generated: {name} --> block")
        if match.group(2) != table():
            names.append(name)
            text = text[:match.start(2)] + table() + text[match.end(2):]
        texts[file] = text
    return {f: t for f, t in texts.items() if t != (ROOT / f).read_text()}, names


def main(argv):
    changed, names = stale()
    if "--check" in argv:
        if names:
            print("stale: " + ", ".join(names) + " (python scripts/reference_tables.py)")
            return 1
        return 0
    for file, text in changed.items():
        (ROOT / file).write_text(text)
        print(f"wrote {file}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
