"""The runs of a sweep: a grid (the product of value lists), zipped lists (taken
together, element by element) and seeded random samples, each run a mapping from
dotted config keys to values.

The runs are the product of three factors, each absent = one empty factor: the
grid's points (the first key varies slowest, as in ``itertools.product``), the
zipped lists' rows, and ``random`` samples drawn with ``numpy.random.default_rng(seed)``,
one key after the other in the order given, sample after sample. A range is
``lo:hi`` (uniform), ``lo:hi:log`` (log-uniform, lo > 0) or ``lo:hi:int`` (an integer
in [lo, hi], both ends included).
"""

import itertools
import math
from collections.abc import Mapping

from clothtool.config_tools import parse_value
from clothtool.errors import InputError

SCALES = ("linear", "log", "int")


def split_values(text):
    """'1e3,[0, 1],x' → ['1e3', '[0, 1]', 'x']: commas inside brackets or braces belong
    to the value."""
    out, depth, current = [], 0, []
    for ch in text:
        if ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        if ch == "," and depth == 0:
            out.append("".join(current).strip())
            current = []
        else:
            current.append(ch)
    out.append("".join(current).strip())
    return out


def _key_and_rest(text, keyword, example):
    key, sep, rest = str(text).partition("=")
    parts = key.strip().split(".")
    if not sep or not all(p.strip() for p in parts) or not rest.strip():
        raise InputError(f"expected dotted.key={example}", keyword=keyword, value=text)
    return key.strip(), rest


def parse_lists(spec, keyword):
    """``grid``/``zip`` as given: a mapping key → list of values, or 'key=v1,v2,…' strings
    (each value read as YAML). Returns {key: [values]} in the order given."""
    if spec is None:
        return {}
    if isinstance(spec, Mapping):
        items = [(str(k), list(v) if isinstance(v, (list, tuple)) else [v]) for k, v in spec.items()]
    else:
        items = []
        for text in ([spec] if isinstance(spec, str) else spec):
            key, rest = _key_and_rest(text, keyword, "v1,v2,…")
            values = split_values(rest)
            if any(not v for v in values):
                raise InputError("an empty value in the list", keyword=keyword, value=text)
            items.append((key, [parse_value(v, keyword=keyword, value=text) for v in values]))
    out = {}
    for key, values in items:
        if key in out:
            raise InputError(f"{key} is given twice", keyword=keyword, value=key)
        if not values:
            raise InputError(f"{key} has no values", keyword=keyword, value=key)
        out[key] = values
    return out


def parse_ranges(spec):
    """``ranges`` as given: a mapping key → (lo, hi[, scale]) or 'key=lo:hi[:log|:int]'
    strings. Returns {key: (lo, hi, scale)}; lo ≤ hi is checked, and lo > 0 for log."""
    if spec is None:
        return {}
    if isinstance(spec, Mapping):
        items = [(str(k), list(v) if isinstance(v, (list, tuple)) else [v], f"{k}={v}")
                 for k, v in spec.items()]
    else:
        items = []
        for text in ([spec] if isinstance(spec, str) else spec):
            key, rest = _key_and_rest(text, "ranges", "lo:hi[:log|:int]")
            items.append((key, rest.split(":"), text))
    out = {}
    for key, fields, shown in items:
        if len(fields) not in (2, 3):
            raise InputError("expected key=lo:hi, key=lo:hi:log or key=lo:hi:int",
                             keyword="ranges", value=shown)
        scale = str(fields[2]).strip() if len(fields) == 3 else "linear"
        if scale not in SCALES:
            raise InputError(f"scale {scale!r} is not one of {', '.join(SCALES)}",
                             keyword="ranges", value=shown)
        try:
            lo, hi = (float(parse_value(str(f).strip(), keyword="ranges", value=shown))
                      for f in fields[:2])
        except (TypeError, ValueError):
            raise InputError("lo and hi must be numbers", keyword="ranges", value=shown) from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise InputError("lo and hi must be finite", keyword="ranges", value=shown)
        if lo > hi:
            raise InputError(f"min {lo:g} is greater than max {hi:g}", keyword="ranges", value=shown)
        if scale == "log" and lo <= 0:
            raise InputError("a log range needs lo > 0", keyword="ranges", value=shown)
        if scale == "int" and not (lo.is_integer() and hi.is_integer()):
            raise InputError("an int range needs integer ends", keyword="ranges", value=shown)
        if key in out:
            raise InputError(f"{key} is given twice", keyword="ranges", value=key)
        out[key] = (lo, hi, scale)
    return out


def sample(ranges, count, seed):
    """``count`` samples of ``ranges`` ({key: (lo, hi, scale)}) from
    ``numpy.random.default_rng(seed)``: a list of {key: value} (floats; ints for 'int')."""
    import numpy as np

    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        row = {}
        for key, (lo, hi, scale) in ranges.items():
            if scale == "log":
                value = math.exp(rng.uniform(math.log(lo), math.log(hi)))
                row[key] = min(max(value, lo), hi)  # exp(log(hi)) may round past hi
            elif scale == "int":
                row[key] = int(rng.integers(int(lo), int(hi), endpoint=True))
            else:
                row[key] = float(rng.uniform(lo, hi))
        out.append(row)
    return out


def expand(grid=None, zipped=None, random=None, ranges=None, seed=None):
    """The runs: a list of {dotted key: value}. See the module docstring."""
    grid, zipped = parse_lists(grid, "grid"), parse_lists(zipped, "zip")
    ranges = parse_ranges(ranges)
    if random is not None:
        if isinstance(random, bool) or not isinstance(random, int) or random < 1:
            raise InputError("must be a positive number of runs", keyword="random", value=random)
        if seed is None:
            raise InputError("a random sweep needs a seed, so that it can be resumed and "
                             "repeated: give {seed}", keyword="random", value=random,
                             mentions={"seed": "seed=0"})
        if not ranges:
            raise InputError("a random sweep needs at least one range to draw from",
                             keyword="random", value=random)
    elif ranges:
        raise InputError("ranges are drawn from only in a random sweep: give {random}",
                         keyword="ranges", value=next(iter(ranges)), mentions={"random": "random=N"})
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        raise InputError("must be an integer ≥ 0", keyword="seed", value=seed)
    lengths = {len(v) for v in zipped.values()}
    if len(lengths) > 1:
        shown = ", ".join(f"{k} has {len(v)}" for k, v in zipped.items())
        raise InputError(f"zipped lists must have the same length ({shown})", keyword="zip",
                         value=next(iter(zipped)))
    seen = set()
    for keyword, keys in (("grid", grid), ("zip", zipped), ("ranges", ranges)):
        for key in keys:
            if key in seen:
                raise InputError(f"{key} is swept twice (in more than one of {{grid}}, {{zip}} "
                                 "and {ranges})", keyword=keyword, value=key,
                                 mentions={"grid": "grid", "zip": "zip", "ranges": "ranges"})
            seen.add(key)
    grid_rows = [dict(zip(grid, values)) for values in itertools.product(*grid.values())]
    zip_rows = [dict(zip(zipped, values)) for values in zip(*zipped.values())] or [{}]
    random_rows = sample(ranges, random, seed) if random is not None else [{}]
    return [{**g, **z, **r} for g in grid_rows for z in zip_rows for r in random_rows]
