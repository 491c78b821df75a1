"""The OBJ number parser against Python's float() (correctly rounded, as strtod)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.io.numbers import parse_rows


def parse_floats(text, expected):
    """The numbers of ``text`` as one row of ``expected``, or None."""
    buf = np.frombuffer(text, np.uint8)
    table = parse_rows(buf, np.array([0]), np.array([len(buf)]), 0, expected + 1)
    return table[0] if table is not None and table.shape[1] == expected else None


def parsed(words, sep=" "):
    return parse_floats(sep.join(words).encode(), len(words))


@given(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=1,
                max_size=50),
       st.sampled_from(["%.9g", "%.17g", "%r", "%.6f", "%.3e", "%g"]))
@settings(max_examples=300, deadline=None)
def test_agrees_with_float_bit_for_bit(values, fmt):
    words = [repr(v) if fmt == "%r" else fmt % v for v in values]
    got = parsed(words)
    if got is None:  # off the fast path: the caller parses with numpy
        return
    expected = np.array([float(w) for w in words])
    assert np.array_equal(got.view(np.int64), expected.view(np.int64)), words


def test_common_forms_and_signs():
    words = ["0", "-0", "+1.5", "-2.25e-3", "1E2", ".5", "5.", "007", "-0.000000123456789",
             "1234567890123456e-5", "9007199254740992e-22", "0.1e+22"]
    got = parsed(words, " \t\n\r")
    assert got is not None
    assert np.array_equal(got, [float(w) for w in words])
    assert np.signbit(got[1])


@pytest.mark.parametrize("text,count", [
    (b"1 2", 3), (b"1 2 3", 2),  # not the expected count
    (b"nan 1", 2), (b"inf 1", 2), (b"0x10 1", 2), (b"1,5 2", 2), (b"1e 2", 2), (b"- 2", 2),
    (b"1e400 1", 2), (b"1e-30 1", 2),  # exponents off the fast path
    (b"1234567890123456789 1", 2),  # more than 18 digits
    (b"9007199254740993 1", 2),  # mantissa above 2^53
])
def test_off_the_fast_path_is_none(text, count):
    assert parse_floats(text, count) is None


def test_rows_of_one_width():
    text = b"v 1 2 3\nv 4 5 6.5\r\nv -1 0 1e3\n"
    buf = np.frombuffer(text, np.uint8)
    starts, ends = np.array([0, 8, 20]), np.array([7, 19, 30])
    assert parse_rows(buf, starts, ends, 1, 7).tolist() == [[1, 2, 3], [4, 5, 6.5], [-1, 0, 1e3]]
    assert parse_rows(buf, starts, ends, 1, 2) is None  # wider than allowed
    ragged = np.frombuffer(b"v 1 2 3\nv 4 5\n", np.uint8)
    assert parse_rows(ragged, np.array([0, 8]), np.array([7, 13]), 1, 7) is None
