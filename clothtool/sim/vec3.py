"""3-vectors as tuples inside numba kernels (no heap allocation in per-element loops)."""

from numba import njit


@njit(cache=True)
def load(a, i):
    """Row i of an (N, 3) array as a tuple."""
    return (a[i, 0], a[i, 1], a[i, 2])


@njit(cache=True)
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True)
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True)
def scale(s, a):
    return (s * a[0], s * a[1], s * a[2])


@njit(cache=True)
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
