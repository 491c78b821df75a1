"""3-vectors as tuples inside numba kernels (no heap allocation in per-element loops), and the
inverse of a symmetric positive semi-definite 3×3 block."""

import numpy as np

from clothtool.numba_setup import njit, njit_inner


@njit_inner(cache=True)
def load(a, i):
    """Row i of an (N, 3) array as a tuple."""
    return (a[i, 0], a[i, 1], a[i, 2])


@njit_inner(cache=True)
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit_inner(cache=True)
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit_inner(cache=True)
def scale(s, a):
    return (s * a[0], s * a[1], s * a[2])


@njit_inner(cache=True)
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit_inner(cache=True)
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


HADAMARD = 1e-8  # det ≥ this · a00·a11·a22: the cofactor inverse is accurate (to ~ε/this)
ROUNDING = 64 * 2.0**-52  # relative size of a 3×3 block's rounding noise in its eigenvalues
JACOBI_SWEEPS = 12  # cyclic Jacobi sweeps at most (3×3 converges quadratically in 3–5)


@njit_inner(cache=True)
def copy_into(a, out):
    """out[:, :] = a for 2-D arrays of one shape, element by element: a slice assignment
    compiles numba's shape-mismatch message (string formatting, about 5 s of CPU in a fresh
    install's first run)."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            out[i, j] = a[i, j]


@njit(cache=True)
def spd_inverse3(a, floor, out):
    """out = an inverse of the symmetric positive semi-definite 3×3 matrix a + (its rounding),
    with every eigenvalue taken as at least ``floor`` (> 0: a known lower bound of the true
    eigenvalues, e.g. the inertia m/h² under PSD stiffness blocks; 0: none known).

    Well-conditioned blocks (det ≥ HADAMARD · a00 a11 a22, Hadamard's bound being det ≤ the
    product of the diagonal for SPD matrices) are inverted by cofactors
    (:func:`cofactor_inverse3`). Otherwise the stored block has lost its small eigenvalues to
    rounding — a barrier block of 1e22·m/h² along one direction over m/h² I stores m/h² below
    the last bit, and its cofactor determinant comes out zero or negative — and the inverse is
    :func:`eigen_inverse3`'s. A matrix with NaN gives NaN."""
    if not cofactor_inverse3(a, out):
        eigen_inverse3(a, floor, out)


@njit_inner(cache=True)
def cofactor_inverse3(a, out):
    """:func:`spd_inverse3`'s first part: True when it wrote out = a⁻¹ by cofactors (a + aᵀ
    halved, well-conditioned: det ≥ HADAMARD · a00 a11 a22 > 0) or NaN (a has NaN), False
    (out untouched) when a needs :func:`eigen_inverse3`. Kernels that meet such blocks only
    at contact call this one and leave those blocks to a second pass, so that the
    eigen-decomposition is compiled only where it runs (about 0.75 s of a first run's
    compilation)."""
    a00, a11, a22 = a[0, 0], a[1, 1], a[2, 2]
    a01, a02, a12 = 0.5 * (a[0, 1] + a[1, 0]), 0.5 * (a[0, 2] + a[2, 0]), 0.5 * (a[1, 2] + a[2, 1])
    c00 = a11 * a22 - a12 * a12
    c01 = a12 * a02 - a01 * a22
    c02 = a01 * a12 - a11 * a02
    det = a00 * c00 + a01 * c01 + a02 * c02
    diagonal = a00 * a11 * a22
    if not (a00 == a00 and a11 == a11 and a22 == a22 and a01 == a01 and a02 == a02
            and a12 == a12):
        out[:, :] = np.nan
        return True
    if a00 > 0.0 and a11 > 0.0 and a22 > 0.0 and det >= HADAMARD * diagonal and det > 0.0:
        r = 1.0 / det
        out[0, 0] = c00 * r
        out[0, 1] = out[1, 0] = c01 * r
        out[0, 2] = out[2, 0] = c02 * r
        out[1, 1] = (a00 * a22 - a02 * a02) * r
        out[1, 2] = out[2, 1] = (a01 * a02 - a00 * a12) * r
        out[2, 2] = (a00 * a11 - a01 * a01) * r
        return True
    return False


@njit_inner(cache=True)
def eigen_inverse3(a, floor, out):
    """out = V diag(1/max(λ, floor)) Vᵀ of a + aᵀ halved, from a cyclic Jacobi
    eigen-decomposition (Golub & Van Loan, "Matrix Computations", §8.5): :func:`spd_inverse3`
    for the blocks that lost their small eigenvalues to rounding. It keeps the large
    eigenvector exact and restores the lost ones to the floor (eigenvalues below ROUNDING ×
    the largest are rounding; with no floor either, out = 0)."""
    a00, a11, a22 = a[0, 0], a[1, 1], a[2, 2]
    a01, a02, a12 = 0.5 * (a[0, 1] + a[1, 0]), 0.5 * (a[0, 2] + a[2, 0]), 0.5 * (a[1, 2] + a[2, 1])
    m = np.empty((3, 3))
    m[0, 0], m[1, 1], m[2, 2] = a00, a11, a22
    m[0, 1] = m[1, 0] = a01
    m[0, 2] = m[2, 0] = a02
    m[1, 2] = m[2, 1] = a12
    v = np.empty((3, 3))  # the identity in loops (np.eye, np.zeros: overloads compiled apart)
    for p in range(3):
        for q in range(3):
            v[p, q] = 1.0 if p == q else 0.0
    scale = abs(a00) + abs(a11) + abs(a22) + abs(a01) + abs(a02) + abs(a12)
    for _ in range(JACOBI_SWEEPS):
        off = abs(m[0, 1]) + abs(m[0, 2]) + abs(m[1, 2])
        if off <= 1e-18 * scale:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                if m[p, q] == 0.0:
                    continue
                # the rotation that zeroes m[p, q] (Rutishauser's smaller angle)
                theta = (m[q, q] - m[p, p]) / (2.0 * m[p, q])
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(3):  # m ← Jᵀ m J, v ← v J
                    mkp, mkq = m[k, p], m[k, q]
                    m[k, p] = c * mkp - s * mkq
                    m[k, q] = s * mkp + c * mkq
                for k in range(3):
                    mpk, mqk = m[p, k], m[q, k]
                    m[p, k] = c * mpk - s * mqk
                    m[q, k] = s * mpk + c * mqk
                for k in range(3):
                    vkp, vkq = v[k, p], v[k, q]
                    v[k, p] = c * vkp - s * vkq
                    v[k, q] = s * vkp + c * vkq
    largest = max(max(m[0, 0], m[1, 1]), m[2, 2])  # max of three compiles an overload of its own
    noise = ROUNDING * largest  # eigenvalues below this are rounding, not stiffness
    if not (floor > 0.0 or noise > 0.0):  # a zero block with no known floor: nothing to invert
        out[:, :] = 0.0
        return
    for k in range(3):
        lam = m[k, k]
        m[k, k] = max(lam, floor) if lam > noise else (floor if floor > 0.0 else noise)
    for p in range(3):
        for q in range(3):
            total = 0.0
            for k in range(3):
                total += v[p, k] * v[q, k] / m[k, k]
            out[p, q] = total
