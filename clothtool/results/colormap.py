"""Viridis in numpy, for face and vertex colours without matplotlib.

Viridis (van der Walt & Smith, matplotlib 1.5) is perceptually uniform and readable in
greyscale and by colour-blind viewers. The table holds 17 anchors sampled at 0, 1/16, …, 1
from matplotlib's 256-entry table; linear interpolation between them stays within 6/255
of the original in every channel.
"""

import numpy as np

VIRIDIS_ANCHORS = np.array([
    [0.2670, 0.0049, 0.3294], [0.2823, 0.0950, 0.4173], [0.2788, 0.1755, 0.4834],
    [0.2590, 0.2515, 0.5247], [0.2297, 0.3224, 0.5457], [0.1994, 0.3876, 0.5546],
    [0.1727, 0.4488, 0.5579], [0.1490, 0.5081, 0.5572], [0.1276, 0.5669, 0.5506],
    [0.1206, 0.6258, 0.5335], [0.1579, 0.6838, 0.5017], [0.2461, 0.7389, 0.4520],
    [0.3692, 0.7889, 0.3829], [0.5160, 0.8312, 0.2943], [0.6785, 0.8637, 0.1895],
    [0.8456, 0.8873, 0.0997], [0.9932, 0.9062, 0.1439],
])
NAN_COLOR = np.array([128, 128, 128], np.uint8)  # grey for NaN (flagged) values


def viridis(t):
    """RGB in [0, 1], shape (*t.shape, 3), of ``t`` clipped to [0, 1]."""
    t = np.clip(np.asarray(t, np.float64), 0.0, 1.0)
    x = np.linspace(0.0, 1.0, len(VIRIDIS_ANCHORS))
    return np.stack([np.interp(t, x, VIRIDIS_ANCHORS[:, k]) for k in range(3)], axis=-1)


def value_range(values):
    """(lo, hi) of the finite values; (0, 1) if there are none, (v−½, v+½) if all equal."""
    finite = np.asarray(values, np.float64)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return 0.0, 1.0
    lo, hi = float(finite.min()), float(finite.max())
    return (lo - 0.5, hi + 0.5) if lo == hi else (lo, hi)


def colorize(values, lo, hi):
    """(…, 3) uint8 viridis colours of ``values`` mapped linearly from [lo, hi] to [0, 1]
    (clipped); NaN becomes :data:`NAN_COLOR`."""
    values = np.asarray(values, np.float64)
    finite = np.isfinite(values)
    rgb = np.round(viridis((np.where(finite, values, lo) - lo) / (hi - lo)) * 255).astype(np.uint8)
    rgb[~finite] = NAN_COLOR
    return rgb
