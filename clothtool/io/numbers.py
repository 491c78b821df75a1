"""Whitespace-separated decimal numbers → float64, correctly rounded (as ``strtod``), in one
numba pass: the ``v`` and ``vt`` lines of OBJ files.

A number ``[±]digits[.digits][(e|E)[±]digits]`` with at most 18 significant digits is the
integer mantissa m (exact in int64) times 10^e. When m ≤ 2⁵³ and |e| ≤ 22 both m and 10^|e|
are exact doubles, so one multiplication or division, correctly rounded by IEEE 754, gives
the correctly rounded value (Clinger 1990, "How to read floating point numbers accurately",
the fast path). Anything else (more digits, a larger exponent, ``nan``, ``inf``, hex, any
other byte) makes :func:`parse_rows` return None, and the caller takes ``np.fromstring``.
"""

import numpy as np

from clothtool.numba_setup import njit

_POW10 = np.array([10.0 ** k for k in range(23)])  # exact doubles
_MAX_EXACT = 1 << 53


@njit(cache=True, nogil=True, inline="always")
def _space(c):
    return c == 32 or 9 <= c <= 13


@njit(cache=True, nogil=True, inline="always")
def _number(text, i, n, pow10):
    """(ok, value, index after it) of the number at ``text[i]`` (no leading space), ``n`` the
    end of the text; not ok off the fast path."""
    negative = False
    if i < n and (text[i] == 45 or text[i] == 43):  # - +
        negative = text[i] == 45
        i += 1
    mantissa, digits, exponent, seen = 0, 0, 0, False
    fraction = False
    while i < n:
        c = text[i]
        if 48 <= c <= 57:
            seen = True
            if mantissa or c != 48:
                digits += 1
                if digits > 18:
                    return False, 0.0, i
                mantissa = mantissa * 10 + (c - 48)
            if fraction:
                exponent -= 1
        elif c == 46 and not fraction:  # .
            fraction = True
        else:
            break
        i += 1
    if not seen:
        return False, 0.0, i
    if i < n and (text[i] == 101 or text[i] == 69):  # e E
        i += 1
        sign = 1
        if i < n and (text[i] == 45 or text[i] == 43):
            sign = -1 if text[i] == 45 else 1
            i += 1
        if i >= n or not 48 <= text[i] <= 57:
            return False, 0.0, i
        e = 0
        while i < n and 48 <= text[i] <= 57:
            if e < 100000:
                e = e * 10 + (text[i] - 48)
            i += 1
        exponent += sign * e
    if (i < n and not _space(text[i])) or mantissa > _MAX_EXACT or abs(exponent) > 22:
        return False, 0.0, i
    if mantissa == 0:
        value = 0.0
    elif exponent < 0:
        value = mantissa / pow10[-exponent]
    else:
        value = mantissa * pow10[exponent]
    return True, -value if negative else value, i


@njit(cache=True, nogil=True)
def _parse_rows(text, starts, ends, skip, widest, out, pow10):
    """Row r of ``out`` (R, widest) from ``text[starts[r] + skip:ends[r]]``; returns the count
    of numbers every row has, or −1 when the rows differ, one has more than ``widest`` or a
    number is off the fast path."""
    width = -1
    for r in range(len(starts)):
        i, n, count = starts[r] + skip, ends[r], 0
        while True:
            while i < n and _space(text[i]):
                i += 1
            if i >= n:
                break
            ok, value, i = _number(text, i, n, pow10)
            if not ok or count >= widest:
                return -1
            out[r, count] = value
            count += 1
        if width < 0:
            width = count
        elif count != width:
            return -1
    return width


def parse_rows(buf, starts, ends, skip, widest):
    """(R, k) float64: the numbers of each line ``buf[starts[r] + skip:ends[r]]`` (uint8), when
    every line has the same count k ≤ ``widest`` and every number is on the fast path; else
    None."""
    out = np.empty((len(starts), widest), np.float64)
    width = _parse_rows(buf, starts, ends, skip, widest, out, _POW10)
    return out[:, :width] if width >= 0 else None
