"""The docs' reference tables are the code's: the config key table of docs/simulate.md is the
config schema's declarations, the field tables are the field registry
(scripts/reference_tables.py writes them)."""

import importlib.util
import re
from pathlib import Path

import yaml

from clothtool.config_tools import DEFAULT_CONFIG
from clothtool.sim.model.config import COLLIDER_KINDS, Config
from clothtool.sim.model.schema import key_rows

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("reference_tables",
                                              ROOT / "scripts" / "reference_tables.py")
reference_tables = importlib.util.module_from_spec(spec)
spec.loader.exec_module(reference_tables)


def docs_key_table():
    """{key: default as shown} of the config key table in docs/simulate.md."""
    text = (ROOT / "docs" / "simulate.md").read_text()
    rows = re.findall(r"^\| `([^`]+)` \| (.*?) \| ", text, re.M)
    return dict(rows)


def init_config_keys(node, prefix=""):
    """The dotted keys of ``clothtool init-config``'s config (not its sections), list items as
    ``key[]`` and a collider as ``scene.colliders[].KIND``."""
    keys = []
    for name, value in node.items():
        key = f"{prefix}{name}"
        if isinstance(value, dict) and name != "materials":
            keys += init_config_keys(value, key + ".")
            continue
        keys.append(key)
        if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for item in value:
                if key == "scene.colliders":
                    (kind, body), = item.items()
                    keys += init_config_keys(body, f"{key}[].{kind}.")
                else:
                    keys += init_config_keys(item, f"{key}[].")
    return keys


def test_every_table_is_written_from_the_code():
    _, stale = reference_tables.stale()
    assert stale == [], f"stale tables {stale}: run python scripts/reference_tables.py"


def test_every_schema_key_is_in_the_docs_with_the_schema_default():
    table = docs_key_table()
    rows = key_rows(Config)
    assert len(rows) > 100
    for key, default, doc in rows:
        assert key in table, key
        if not doc.startswith("as `"):
            assert table[key] == reference_tables.format_default(default), key
    assert table["scene.collision_margin"] == "0.002"  # 2 mm (the docs once said 0.001)
    for kind in COLLIDER_KINDS:
        assert f"scene.colliders[].{kind}.friction" in table


def test_every_init_config_key_is_in_the_docs_table():
    table = docs_key_table()
    keys = init_config_keys(yaml.safe_load(DEFAULT_CONFIG))
    assert "scene.colliders[].sphere.radius" in keys and "solver.vbd_tolerance" in keys
    assert [k for k in keys if k not in table] == []


def test_a_changed_default_makes_the_table_stale(monkeypatch):
    rows = reference_tables.config_rows()
    monkeypatch.setattr(reference_tables, "config_rows",
                        lambda: [(k, "0.001" if k == "scene.collision_margin" else d, m)
                                 for k, d, m in rows])
    _, stale = reference_tables.stale()
    assert stale == ["config keys"]
