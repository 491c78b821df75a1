"""The spring network shared by ``mass-spring``, ``pbd``, ``xpbd`` and ``projective``: an
elastic energy like :mod:`clothtool.sim.energies.membrane` and :mod:`clothtool.sim.energies.bending`.

Springs come from the mesh (course notes: "store every triangle edge, sort, remove
duplicates"): every triangle edge is a spring, and with bending on, every hinge
(i, j, k, l) adds a bend spring between the two opposite vertices k and l. Each
spring has the energy ½ k_e (‖x_i − x_j‖ − L_e)², with L_e its rest length.

Stiffness from the material (N/m per unit area, so refining the mesh keeps the
material): an edge of rest length L whose adjacent rest triangles have total area
A, at angle θ to the warp (u) direction of the rest coordinates, gets

    k_e = ((k_u cos²θ + k_v sin²θ) cos²2θ + 4 k_shear sin²2θ) · A / L²

(k_u, k_v: material.stretch along u and v) so on a grid the axis edges are the
structural springs (k_e = k_u along u, k_v along v in the interior, reproducing the
membrane's uniaxial stiffnesses) and the diagonals are
the shear springs (4 k_shear A/L² = 2 k_shear reproduces Ψ_shear = k_h/2 (f0·f1)²
to first order). A mesh without rest uv treats every edge as structural. The rest
length factors b_u, b_v (material.rest_stretch) make every spring's rest length that
of the rest state F = diag(b_u, b_v): ‖(b_u Δu, b_v Δv)‖ for an edge (Δu, Δv) of the
rest uv (b‖e‖ without uv, where b_u = b_v). A bend
spring gets k_e = 2c/L_kl², with c = k_bend ‖ē‖²/(2(Ā_k + Ā_l)) the hinge's dihedral
coefficient (so ½k_e(L_kl θ)² = cθ²): a dimensional stand-in, not a calibrated
bending model — a spring across a flat hinge resists bending only to second order
in the angle (the "locking" and weak-bending limits of the course notes).

Kernels (numba, float64, serial, allocation-free in their loops):

- :func:`spring_energy`, :func:`spring_assemble` (gradient and the Hessian
  k[d̂d̂ᵀ + max(0, 1 − L/‖d‖)(I − d̂d̂ᵀ)]: the compressed-spring term, negative
  when ‖d‖ < L, is dropped, the PSD clamp of the notes).

The constraint kernels of ``pbd``, ``xpbd`` and ``projective`` on this network are in
:mod:`clothtool.sim.solvers.constraints`.
"""

from dataclasses import dataclass

import numpy as np

from clothtool.numba_setup import njit

EPS = 1e-12


@dataclass
class Springs:
    i: np.ndarray  # (E,) int64
    j: np.ndarray  # (E,) int64
    rest: np.ndarray  # (E,) rest lengths, m
    k: np.ndarray  # (E,) stiffness, N/m
    structural: np.ndarray  # (E,) bool: a stretch spring (strain limiting applies)
    n_bend: int  # bend springs are the last n_bend entries

    @property
    def pairs(self):
        return np.stack([self.i, self.j], axis=1)

    def __len__(self):
        return len(self.i)


def build_springs(model):
    """Springs of a :class:`~clothtool.sim.model.model.Model` (see the module docstring)."""
    faces = model.faces
    n = model.n_vertices
    rest3d = model.mesh.rest3d
    a = faces.ravel()
    b = np.roll(faces, -1, axis=1).ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * n + hi
    uniq, inverse = np.unique(key, return_inverse=True)
    ei, ej = (uniq // n).astype(np.int64), (uniq % n).astype(np.int64)
    adj_area = np.bincount(inverse, weights=np.repeat(model.area, 3), minlength=len(uniq))
    d = rest3d[ej] - rest3d[ei]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    k_u, k_v, b_u, b_v = model.stretch
    if model.mesh.uv is not None:
        theta = np.arctan2(d[:, 1], d[:, 0])
        cos2 = np.cos(2.0 * theta) ** 2
        k_axis = k_u * np.cos(theta) ** 2 + k_v * np.sin(theta) ** 2
    else:
        cos2 = np.ones(len(uniq))
        k_axis = np.full(len(uniq), k_u)  # the Model has k_u = k_v, b_u = b_v without uv
    k = (k_axis * cos2 + 4.0 * model.k_shear * (1.0 - cos2)) * adj_area / length ** 2
    structural = cos2 >= 0.5
    n_bend = 0
    if model.bend_model is not None and len(model.hinge):
        bi, bj = model.hinge[:, 2], model.hinge[:, 3]
        db = rest3d[bj] - rest3d[bi]
        lb = np.sqrt(np.einsum("ij,ij->i", db, db))
        kb = 2.0 * model.hinge_coef / lb ** 2
        ei, ej = np.concatenate([ei, bi]), np.concatenate([ej, bj])
        d, length, k = np.concatenate([d, db]), np.concatenate([length, lb]), np.concatenate([k, kb])
        structural = np.concatenate([structural, np.zeros(len(bi), np.bool_)])
        n_bend = len(bi)
    # rest lengths of the rest state F = diag(b_u, b_v): an edge (du, dv) rests at ‖(b_u du, b_v dv)‖
    length = np.sqrt((b_u * d[:, 0]) ** 2 + (b_v * d[:, 1]) ** 2 + (b_u * d[:, 2]) ** 2)
    keep = k > 0.0
    if not np.all(keep):  # e.g. shear = 0: diagonals carry nothing
        ei, ej, length, k, structural = ei[keep], ej[keep], length[keep], k[keep], structural[keep]
        n_bend = int(np.count_nonzero(keep[len(keep) - n_bend:])) if n_bend else 0
    return Springs(ei.astype(np.int64), ej.astype(np.int64), length, k, structural, n_bend)


# ---------------------------------------------------------------------------- energy


@njit(cache=True)
def spring_energy(x, si, sj, rest, k):
    total = 0.0
    for e in range(si.shape[0]):
        i, j = si[e], sj[e]
        d0, d1, d2 = x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]
        c = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - rest[e]
        total += 0.5 * k[e] * c * c
    return total


@njit(cache=True)
def spring_assemble(x, si, sj, rest, k, slots, grad, values):
    """W(x); adds ∇W to grad and the PSD-clamped spring Hessians to the block values.

    slots (E, 4): the (i,i), (i,j), (j,i), (j,j) block slots of each spring.
    """
    total = 0.0
    h = np.empty((3, 3))
    for e in range(si.shape[0]):
        i, j = si[e], sj[e]
        d = (x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2])
        length = max(np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), EPS)
        c = length - rest[e]
        total += 0.5 * k[e] * c * c
        s = k[e] * c / length
        for p in range(3):
            grad[i, p] += s * d[p]
            grad[j, p] -= s * d[p]
        across = 1.0 - rest[e] / length
        if across < 0.0:  # compressed: the indefinite part is dropped (PSD clamp)
            across = 0.0
        for p in range(3):
            for q in range(3):
                dd = d[p] * d[q] / (length * length)
                h[p, q] = k[e] * ((1.0 - across) * dd + (across if p == q else 0.0))
        for p in range(3):
            for q in range(3):
                values[slots[e, 0], p, q] += h[p, q]
                values[slots[e, 1], p, q] -= h[p, q]
                values[slots[e, 2], p, q] -= h[p, q]
                values[slots[e, 3], p, q] += h[p, q]
    return total
