"""Computing a slice of the pairs (``analyze --pairs START:STOP``) so that one sequence can be
split over machines; :mod:`clothtool.results.merge` joins the slices.

Every result records its slice as root attributes: ``pair_offset`` (global index of its
first pair) and ``pairs_total`` (pairs of the whole sequence); a full run has
``pair_offset`` 0 and ``pairs_total`` = P.
"""

from clothtool.errors import InputError


def parse_pair_slice(spec, total):
    """``None``/'' → (0, total); 'START:STOP' (either side may be empty) or (start, stop) →
    (start, min(stop, total)). STOP past the end is clipped, so fixed-size chunks of a
    job array need not know P; an empty slice is an error."""
    if spec is None or spec == "":
        return 0, total
    if isinstance(spec, str):
        head, sep, tail = spec.partition(":")
        try:
            if not sep:
                raise ValueError
            start = int(head) if head.strip() else 0
            stop = int(tail) if tail.strip() else total
        except ValueError:
            raise InputError(f"{spec!r} is not START:STOP (for example 0:100)",
                             keyword="pairs") from None
    else:
        start, stop = (int(v) for v in spec)
    if start < 0 or stop < 0:
        raise InputError("negative pair index", keyword="pairs", value=f"{start}:{stop}")
    if start >= min(stop, total):
        raise InputError(f"no pairs in this slice (the sequence has {total} pairs, 0:{total})",
                         keyword="pairs", value=f"{start}:{stop}")
    return start, min(stop, total)
