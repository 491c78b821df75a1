"""The toolkit the simulation config is declared with: YAML values → checked, frozen dataclasses.

A config section is a frozen dataclass deriving from :class:`Section`; each of its fields is a
:func:`setting` (a default and a check) or a :func:`section` (a nested mapping, another
:class:`Section`). A check is a function ``(value, key) → value`` that converts one YAML value
and raises :class:`~clothtool.errors.InputError` naming the dotted ``key``
(``material.stretch``). What no single setting can check (exactly one of two keys, a key that
applies only with another) is the section's :meth:`Section.finish`.

Every message is one line; an unknown key or choice suggests the closest valid one (difflib).
PyYAML reads ``1e5`` (no dot) as a string, so numbers accept numeric strings.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from pathlib import Path

from clothtool.errors import InputError


class Section:
    """A config section: a frozen dataclass whose fields are :func:`setting` and :func:`section`."""

    @classmethod
    def build(cls, raw, key):
        """The section from the mapping ``raw`` found at dotted ``key``."""
        if raw is None:
            raw = {}
        if not isinstance(raw, dict):
            raise type_error(key, "a mapping", raw)
        declared = {f.name: f for f in dataclasses.fields(cls) if "check" in f.metadata}
        check_keys(raw, declared, key)
        values = {}
        for name, value in raw.items():
            here = f"{key}.{name}" if key else str(name)
            if value is None and declared[name].default is None:
                continue  # an optional setting given as null: its default, None
            values[name] = declared[name].metadata["check"](value, here)
        return cls(**values).finish(set(raw), key)

    def finish(self, given, key):
        """Checks across settings, once all of them are valid; ``given`` are the keys the
        mapping set. Returns the section (a section may return a changed copy)."""
        return self


def setting(default, check, doc):
    """A dataclass field: its ``default``, the ``check`` of a given value and its ``doc``, the
    meaning column of the config key table (Markdown; :func:`key_rows`)."""
    return dataclasses.field(default=default, metadata={"check": check, "doc": doc})


def section(cls, *, optional=False, what="a mapping", doc=""):
    """A nested section: ``cls()`` by default, or None (off) when ``optional``; ``doc``: its
    row in the key table (an optional section's), none when empty."""
    def check(value, key):
        if value is None:
            value = {}  # reached only when not optional: null is the default section
        if not isinstance(value, dict):
            raise type_error(key, what, value)
        return cls.build(value, key)
    metadata = {"check": check, "section": cls, "doc": doc}
    if optional:
        return dataclasses.field(default=None, metadata=metadata)
    return dataclasses.field(default_factory=cls, metadata=metadata)


def listing(items, suffix="[]"):
    """Mark a check that reads several ``items`` (a :class:`Section`, or ``{kind: Section}``
    for a :func:`tagged` list): the key table lists their keys under ``key + suffix``."""
    def mark(check):
        check.items = (items, suffix)
        return check
    return mark


def key_rows(cls, prefix="", seen=None):
    """(dotted key, default, doc) of every setting of the section ``cls`` and of the sections,
    list items and tagged kinds below it, in declaration order: the config key table. A
    section met again is one row saying where its keys are listed."""
    seen = {} if seen is None else seen
    rows = []
    for f in dataclasses.fields(cls):
        if "check" not in f.metadata:
            continue
        key, meta = f"{prefix}{f.name}", f.metadata
        default = f.default
        if default is dataclasses.MISSING:  # a section's (no row) or a mapping's
            default = None if "section" in meta else f.default_factory()
        below = []  # (Section, its prefix)
        if "section" in meta:
            below = [(meta["section"], key + ".")]
        elif hasattr(meta["check"], "items"):
            items, suffix = meta["check"].items
            kinds = items if isinstance(items, dict) else {"": items}
            below = [(k, f"{key}{suffix}.{kind}." if kind else f"{key}{suffix}.")
                     for kind, k in kinds.items()]
        if "section" in meta and meta["section"] in seen:
            rows.append((key, default, f"as `{seen[meta['section']]}`"))
            continue
        if meta["doc"]:
            rows.append((key, default, meta["doc"]))
        for sub, sub_prefix in below:
            seen[sub] = sub_prefix[:-1]
            rows += key_rows(sub, sub_prefix, seen)
    return rows


def tagged(kinds, *, what):
    """A list of one-key mappings ``- kind: {...}``, each built as ``kinds[kind]``."""
    shape = ", ".join(f"{kind}: {{...}}" for kind in kinds)

    def check(value, key):
        if value is None:
            return ()
        if not isinstance(value, list):
            raise type_error(key, f"a list of {what}s ({shape})", value)
        out = []
        for i, item in enumerate(value):
            here = f"{key}[{i}]"
            if not isinstance(item, dict) or len(item) != 1:
                raise type_error(here, f"one of {shape}", item)
            (kind, body), = item.items()
            if kind not in kinds:
                raise InputError(f"{here}: unknown {what} {kind!r}{suggest(str(kind), kinds)}")
            if not isinstance(body, dict):
                raise type_error(f"{here}.{kind}", "a mapping", body)
            out.append(kinds[kind].build(body, f"{here}.{kind}"))
        return tuple(out)
    return listing(kinds)(check)


# ---------------------------------------------------------------------------- checks


def number(*, minimum=None, exclusive=False, maximum=None, below=None):
    """A finite float, ≥ ``minimum`` (> when ``exclusive``), ≤ ``maximum``, < ``below``."""
    def check(value, key):
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise type_error(key, "a number", value)
        try:
            value = float(value)
        except ValueError:
            raise type_error(key, "a number", value) from None
        if not math.isfinite(value):
            raise InputError(f"{key} must be finite, got {value}")
        if minimum is not None and (value < minimum or (exclusive and value == minimum)):
            raise InputError(f"{key} must be {'>' if exclusive else '≥'} {minimum:g}, got {value:g}")
        if maximum is not None and value > maximum:
            raise InputError(f"{key} must be ≤ {maximum:g}, got {value:g}")
        if below is not None and value >= below:
            raise InputError(f"{key} must be < {below:g}, got {value:g}")
        return value
    return check


def integer(*, minimum):
    def check(value, key):
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            else:
                raise type_error(key, "an integer", value)
        if value < minimum:
            raise InputError(f"{key} must be ≥ {minimum}, got {value}")
        return value
    return check


def pair_or_number(*, exclusive):
    """A number ≥ 0 (> 0 when ``exclusive``), or a list of two: [along u (warp), along v (weft)]."""
    one = number(minimum=0, exclusive=exclusive)

    def check(value, key):
        if isinstance(value, (list, tuple)):
            if len(value) != 2:
                raise type_error(key, "a number or a list of 2 numbers [warp, weft]", value)
            return tuple(one(v, f"{key}[{i}]") for i, v in enumerate(value))
        return one(value, key)
    return check


def integer_or(word, *, minimum):
    """An integer ≥ ``minimum``, or the one word ``word``."""
    number_check = integer(minimum=minimum)

    def check(value, key):
        if value == word:
            return value
        if isinstance(value, str):
            raise type_error(key, f"an integer or {word!r}", value)
        return number_check(value, key)
    return check


def choice(options):
    def check(value, key):
        if value not in options:
            raise InputError(f"{key} must be one of {', '.join(options)}, got {value!r}"
                             f"{suggest(str(value), options)}")
        return value
    return check


def choices(options):
    """A non-empty list of distinct names from ``options`` (a single name counts as a list
    of one), as a tuple in the order given."""
    one = choice(options)

    def check(value, key):
        items = [value] if isinstance(value, str) else value
        if not isinstance(items, list) or not items:
            raise type_error(key, f"a list of {spell(options)}", value)
        out = tuple(one(v, f"{key}[{i}]") for i, v in enumerate(items))
        repeated = sorted({v for v in out if out.count(v) > 1})
        if repeated:
            raise InputError(f"{key} names {repeated[0]!r} twice")
        return out
    return check


def flag(value, key):
    if not isinstance(value, bool):
        raise type_error(key, "true or false", value)
    return value


def path(value, key):
    """A path; relative ones are resolved by :func:`resolve_paths`."""
    if not isinstance(value, str) or not value:
        raise type_error(key, "a path", value)
    return Path(value)


def vector3(*, nonzero=False):
    one = number()

    def check(value, key):
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise type_error(key, "a list of 3 numbers", value)
        vec = tuple(one(v, f"{key}[{i}]") for i, v in enumerate(value))
        if nonzero and not any(vec):
            raise InputError(f"{key} must not be the zero vector")
        return vec
    return check


def one_of(keys, given, key):
    """The one name of ``keys`` that ``given`` holds; an InputError unless exactly one."""
    found = [k for k in keys if k in given]
    if len(found) != 1:
        raise InputError(f"{key} needs exactly one of {spell(keys)}")
    return found[0]


def spell(words):
    return ", ".join(words[:-1]) + f" and {words[-1]}" if len(words) > 1 else words[0]


# ---------------------------------------------------------------------------- helpers


def check_keys(raw, valid, prefix):
    for key in raw:
        if key not in valid:
            name = f"{prefix}.{key}" if prefix else str(key)
            raise InputError(f"unknown key '{name}'{suggest(str(key), valid)}")


def suggest(word, options):
    close = difflib.get_close_matches(word, list(options), n=1, cutoff=0.5)
    return f" (did you mean '{close[0]}'?)" if close else ""


def type_error(key, expected, value):
    shown = repr(value)
    if len(shown) > 40:
        shown = shown[:37] + "..."
    return InputError(f"{key} must be {expected}, got {shown}")


def resolve_paths(obj, base):
    """``obj`` with every relative :class:`~pathlib.Path` inside it taken relative to ``base``."""
    if isinstance(obj, Path):
        return base / obj
    if dataclasses.is_dataclass(obj):
        changes = {f.name: resolve_paths(getattr(obj, f.name), base)
                   for f in dataclasses.fields(obj)}
        return dataclasses.replace(obj, **changes)
    if isinstance(obj, tuple):
        return tuple(resolve_paths(v, base) for v in obj)
    return obj


def as_dict(obj):
    """A config (or section) as plain Python data, e.g. to record it beside the output."""
    if dataclasses.is_dataclass(obj):
        return {f.name: as_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple):
        return [as_dict(v) for v in obj]
    if isinstance(obj, dict):
        return {k: as_dict(v) for k, v in obj.items()}
    if isinstance(obj, Path):
        return str(obj)
    return obj
