"""``vbd``: Vertex Block Descent (Chen, Macklin, Yang, Kaufman, Pradhan, Kim, SIGGRAPH 2024,
"Vertex Block Descent").

One step minimises the same incremental potential as ``implicit``
(:mod:`clothtool.sim.solve.newton`)

    E(x) = 1/(2h²) ‖x − y‖²_M + W(x) + 1/2 (x − x_n)ᵀ D (x − x_n),   y = x_n + h v_n + h² g,

with the finite-element W of :mod:`clothtool.sim.energies.energy` (membrane, dihedral or
quadratic bending) and D = (β/h) K(x_n) (β = material.damping, K the PSD-projected
elastic Hessian at the start of the step), by block coordinate descent over the
vertices: vertex i takes one Newton step on E as a function of x_i alone,

    x_i ← x_i − H_ii⁻¹ g_i,   g_i = m_i/h² (x_i − y_i) + Σ_e ∇_i W_e + (β/h) Σ_e Σ_b K_e,ib(x_n) (x_b − x_n,b),
                             H_ii = m_i/h² I + Σ_e K_e,ii(x) + (β/h) Σ_e K_e,ii(x_n)

(paper eq. 5–9), e running over the triangles and hinges around i. The element
gradients and Hessians are those of the implicit method's kernels, evaluated per vertex
(:func:`~clothtool.sim.energies.membrane.membrane_vertex`, the (i, i) block of
:func:`~clothtool.sim.energies.membrane.membrane_element` without the 9×9; the dihedral angle gradient of
:mod:`clothtool.geometry` with the Gauss–Newton Hessian of
:func:`~clothtool.sim.energies.bending.dihedral_assemble`;
:func:`~clothtool.sim.energies.bending.quadratic_element`), PSD-projected, restricted to
the vertex's 3×3 block, so H_ii is positive definite. Vertices are visited in
graph-colour order (vertices of one colour share no triangle and no hinge, so the
result does not depend on the order within a colour and a colour could be updated in
parallel; the kernel is serial: numba threads per colour cost more than they saved here);
``solver.iterations`` sweeps over all colours per step, starting from the paper's
adaptive guess (§3.4) x = x_n + h v_n + h² ã, ã = g · clamp(a_n·ĝ/‖g‖, 0, 1) per
vertex, a_n = (v_n − v_{n−1})/h the last step's acceleration (g before the first step):
y in free fall, so free fall is exact, and x_n + h v_n at rest, so a resting sheet
is a fixed point of the sweeps only where ∇E = 0 (starting from y instead, a few sweeps
stop short of the minimum and the sheet settles below its equilibrium). With
``solver.chebyshev_rho`` = ρ > 0 each sweep is Chebyshev-accelerated (paper §3.6, after Wang 2015): x⁽ᵏ⁾ = ω_k(x̄⁽ᵏ⁾ − x⁽ᵏ⁻²⁾) + x⁽ᵏ⁻²⁾ with
ω_1 = 1, ω_2 = 2/(2 − ρ²), ω_k = 4/(4 − ρ²ω_{k−1}), when a step has at least 5 sweeps: with
2 or 3 the step ends on the large first extrapolations (ω_2 = 1.68 at ρ = 0.9) and the
24×24 benchmark sheet hanging from two corners blew up at 4 to 64 substeps; from 5 sweeps on
it never did, and ρ = 0.9 (the default) lowered the error at all but one of the settings
measured (docs/solvers.md). With ``solver.vbd_tolerance`` > 0 a step stops sweeping once
‖g‖/‖M g_gravity‖ ≤ tolerance, g the vertex gradients met during the sweep.

Pinned vertices stay at x_n; colliders project vertices out after the step (no
contact forces in the sweeps, no friction).
"""

import numpy as np

from clothtool.geometry import dihedral_angle_gradient
from clothtool.numba_setup import njit, njit_inner
from clothtool.sim.energies.bending import quadratic_element
from clothtool.sim.energies.energy import FemElastic
from clothtool.sim.solve.integrator import Integrator, StepReport
from clothtool.sim.energies.membrane import deformation_gradient, membrane_element, membrane_vertex
from clothtool.vec3 import load

BEND_NONE, BEND_DIHEDRAL, BEND_QUADRATIC, BEND_HESSIAN = 0, 1, 2, 3
CHEBYSHEV_MIN_SWEEPS = 5  # below this Chebyshev is off (docstring)
SINGULAR = 1e-300  # a 3×3 block whose determinant is below this is left alone (never with mass)


# ---------------------------------------------------------------------------- colouring


def incidence(elements, n):
    """Compressed vertex → element table: vertex v is corner ``corner[k]`` of element
    ``element[k]`` for k in ``ptr[v]:ptr[v+1]``, elements in increasing order."""
    elements = np.asarray(elements, dtype=np.int64)
    width = elements.shape[1] if elements.ndim == 2 else 0
    vertex = elements.ravel()
    element = np.repeat(np.arange(len(elements), dtype=np.int64), width)
    corner = np.tile(np.arange(width, dtype=np.int64), len(elements))
    order = np.lexsort((element, vertex))
    ptr = np.searchsorted(vertex[order], np.arange(n + 1)).astype(np.int64)
    return ptr, element[order], corner[order]


@njit(cache=True)
def greedy_colours(n, pairs):
    """Colour of each vertex, greedily in index order: the smallest colour not taken by an
    already coloured neighbour (``pairs`` (P, 2), both directions not needed)."""
    degree = np.zeros(n + 1, np.int64)
    for p in range(pairs.shape[0]):
        degree[pairs[p, 0] + 1] += 1
        degree[pairs[p, 1] + 1] += 1
    ptr = np.cumsum(degree)
    fill = ptr[:-1].copy()
    nbr = np.empty(ptr[-1], np.int64)
    for p in range(pairs.shape[0]):
        a, b = pairs[p, 0], pairs[p, 1]
        nbr[fill[a]] = b
        fill[a] += 1
        nbr[fill[b]] = a
        fill[b] += 1
    colour = np.full(n, -1, np.int64)
    taken = np.full(n + 1, -1, np.int64)  # taken[c] == v: colour c is used next to v
    for v in range(n):
        for k in range(ptr[v], ptr[v + 1]):
            c = colour[nbr[k]]
            if c >= 0:
                taken[c] = v
        c = 0
        while taken[c] == v:
            c += 1
        colour[v] = c
    return colour


def colour_groups(n, elements, free):
    """Free vertices grouped by colour so that no two of a group share an element:
    (ptr, vertices) with group c = ``vertices[ptr[c]:ptr[c+1]]`` in increasing order.
    ``elements``: a list of (E, k) vertex-index arrays (triangles, hinges)."""
    pairs = [np.stack([e[:, a], e[:, b]], axis=1) for e in elements if len(e)
             for a in range(e.shape[1]) for b in range(a + 1, e.shape[1])]
    pairs = np.concatenate(pairs).astype(np.int64) if pairs else np.zeros((0, 2), np.int64)
    colour = greedy_colours(n, pairs)
    vertices = np.flatnonzero(free)
    vertices = vertices[np.argsort(colour[vertices], kind="stable")].astype(np.int64)
    counts = np.bincount(colour[vertices], minlength=colour.max() + 1 if n else 0)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64), vertices


# ---------------------------------------------------------------------------- kernels


@njit(cache=True)
def damping_data(x, faces, dr_inv, area, stretch, k_shear, bend, hinge, tri_hf, tri_f, hinge_out):
    """What the damping matrix D = (β/h) K(x_n) needs, at x = x_n: per triangle the projected
    ∂²Ψ/∂vec F² (M, 6, 6) and F = (f0, f1) (M, 6) (its K is A Bᵀ H_F B, B = ∂vec F/∂x), and
    ∇θ of every dihedral hinge (H, 12), whose Gauss–Newton Hessian is 2c ∇θ∇θᵀ (zero for
    a degenerate hinge)."""
    g, hess = np.empty(9), np.empty((9, 9))
    for t in range(tri_hf.shape[0]):
        x0, x1, x2 = load(x, faces[t, 0]), load(x, faces[t, 1]), load(x, faces[t, 2])
        membrane_element(x0, x1, x2, dr_inv[t], area[t], stretch[t], k_shear[t], True, g, hess,
                         tri_hf[t])
        f0, f1 = deformation_gradient(x0, x1, x2, dr_inv[t])
        for p in range(3):
            tri_f[t, p] = f0[p]
            tri_f[t, 3 + p] = f1[p]
    if bend == BEND_DIHEDRAL:
        for h in range(hinge_out.shape[0]):
            dihedral_angle_gradient(load(x, hinge[h, 0]), load(x, hinge[h, 1]),
                                    load(x, hinge[h, 2]), load(x, hinge[h, 3]), hinge_out[h])


@njit_inner(cache=True)
def membrane_damping(x0, x1, x2, dr_inv, area, a, h_f, f_n, damp, g, hmat):
    """Adds corner a's rows of (β/h) K(x_n)(x − x_n) and its (a, a) block to g and hmat, for one
    triangle: with K = A Bᵀ H_F B, K(x − x_n) = A Bᵀ H_F δF, δF = F(x) − F(x_n) (F is
    linear in x), so row a is A[α(H₀₀δf0 + H₀₁δf1) + β(H₁₀δf0 + H₁₁δf1)] and the block
    A[α²H₀₀ + αβ(H₀₁ + H₁₀) + β²H₁₁] (α, β the corner's weights in f0, f1)."""
    f0, f1 = deformation_gradient(x0, x1, x2, dr_inv)
    al = -dr_inv[0, 0] - dr_inv[1, 0] if a == 0 else dr_inv[a - 1, 0]
    be = -dr_inv[0, 1] - dr_inv[1, 1] if a == 0 else dr_inv[a - 1, 1]
    d = (f0[0] - f_n[0], f0[1] - f_n[1], f0[2] - f_n[2],
         f1[0] - f_n[3], f1[1] - f_n[4], f1[2] - f_n[5])
    wa, wb = damp * area * al, damp * area * be
    for p in range(3):
        acc = 0.0
        for q in range(6):
            acc += (wa * h_f[p, q] + wb * h_f[3 + p, q]) * d[q]
        g[p] += acc
        for q in range(3):
            hmat[p, q] += (al * (wa * h_f[p, q] + wb * h_f[p, 3 + q])
                           + be * (wa * h_f[3 + p, q] + wb * h_f[3 + p, 3 + q]))


@njit(cache=True)
def vertex_system(i, x, x_n, y, mass, inv_h2, faces, dr_inv, area, stretch, k_shear, membrane,
                  tri_ptr, tri_elem, tri_corner, bend, hinge, rest_angle, coef, weights,
                  plate_ptr, plate_col, plate_val,
                  hinge_ptr, hinge_elem, hinge_corner, damp, tri_damp, tri_f, hinge_damp, g, hmat,
                  g12):
    """g_i (3,) and H_ii (3, 3) of the incremental potential at vertex i (module docstring),
    written into g and hmat. ``damp`` = β/h; tri_damp, hinge_damp: :func:`damping_data` at
    x_n (tri_damp the triangles' H_F, tri_f their F); g12 is workspace.

    Membrane: :func:`~clothtool.sim.energies.membrane.membrane_vertex` (the vertex's gradient and
    3×3 block, no 9×9). Bending: the dihedral gradient 2c(θ − θ̄)∇θ and the vertex block
    2c ∇_iθ∇_iθᵀ of its Gauss–Newton Hessian (:func:`~clothtool.sim.energies.bending.dihedral_assemble`),
    from geometry's ∇θ; quadratic: the gradient of
    :func:`~clothtool.sim.energies.bending.quadratic_element` and the block 2c w_i² I of its constant
    Hessian."""
    m = mass[i] * inv_h2
    for p in range(3):
        g[p] = m * (x[i, p] - y[i, p])
        for q in range(3):
            hmat[p, q] = m if p == q else 0.0
    if membrane:
        for k in range(tri_ptr[i], tri_ptr[i + 1]):
            t, a = tri_elem[k], tri_corner[k]
            membrane_vertex(load(x, faces[t, 0]), load(x, faces[t, 1]), load(x, faces[t, 2]),
                            dr_inv[t], area[t], stretch[t], k_shear[t], a, g, hmat)
            if damp > 0.0:
                membrane_damping(load(x, faces[t, 0]), load(x, faces[t, 1]), load(x, faces[t, 2]),
                                 dr_inv[t], area[t], a, tri_damp[t], tri_f[t], damp, g, hmat)
    if bend == BEND_NONE:
        return
    if bend == BEND_HESSIAN:  # W = ½ Σ_c x_cᵀ Q x_c: row i of Q x, the block Q_ii I (constant)
        for k in range(plate_ptr[i], plate_ptr[i + 1]):
            j, q = plate_col[k], plate_val[k]
            for p in range(3):
                g[p] += q * (x[j, p] + damp * (x[j, p] - x_n[j, p]))
            if j == i:
                for p in range(3):
                    hmat[p, p] += q * (1.0 + damp)
        return
    for k in range(hinge_ptr[i], hinge_ptr[i + 1]):
        e, a = hinge_elem[k], hinge_corner[k]
        xi, xj = load(x, hinge[e, 0]), load(x, hinge[e, 1])
        xk, xl = load(x, hinge[e, 2]), load(x, hinge[e, 3])
        c2 = 2.0 * coef[e]
        if bend == BEND_DIHEDRAL:
            delta = dihedral_angle_gradient(xi, xj, xk, xl, g12) - rest_angle[e]
            if delta != delta:  # degenerate hinge (now or at rest): no bending there
                continue
            for p in range(3):
                g[p] += c2 * delta * g12[3 * a + p]
                for q in range(3):
                    hmat[p, q] += c2 * g12[3 * a + p] * g12[3 * a + q]
            if damp > 0.0:  # (β/h) 2c ∇θ_n (∇θ_n · (x − x_n)), ∇θ_n = 0 where degenerate
                gn = hinge_damp[e]
                rate = 0.0
                for b in range(4):
                    vb = hinge[e, b]
                    for q in range(3):
                        rate += gn[3 * b + q] * (x[vb, q] - x_n[vb, q])
                for p in range(3):
                    g[p] += damp * c2 * rate * gn[3 * a + p]
                    for q in range(3):
                        hmat[p, q] += damp * c2 * gn[3 * a + p] * gn[3 * a + q]
        else:  # quadratic: E = c‖Σ w_v x_v‖², Hessian 2c w wᵀ ⊗ I₃ (constant)
            w = weights[e]
            quadratic_element(xi, xj, xk, xl, w, coef[e], g12)
            for p in range(3):
                g[p] += g12[3 * a + p]
                hmat[p, p] += c2 * w[a] * w[a] * (1.0 + damp)
                if damp > 0.0:
                    for b in range(4):
                        vb = hinge[e, b]
                        g[p] += damp * c2 * w[a] * w[b] * (x[vb, p] - x_n[vb, p])


@njit_inner(cache=True)
def _solve3(hm, g, out):
    """out = −H⁻¹ g for a symmetric 3×3 H (adjugate); False when H is singular."""
    c00 = hm[1, 1] * hm[2, 2] - hm[1, 2] * hm[2, 1]
    c01 = hm[1, 2] * hm[2, 0] - hm[1, 0] * hm[2, 2]
    c02 = hm[1, 0] * hm[2, 1] - hm[1, 1] * hm[2, 0]
    det = hm[0, 0] * c00 + hm[0, 1] * c01 + hm[0, 2] * c02
    if not abs(det) > SINGULAR:
        return False
    c11 = hm[0, 0] * hm[2, 2] - hm[0, 2] * hm[2, 0]
    c12 = hm[0, 1] * hm[2, 0] - hm[0, 0] * hm[2, 1]
    c22 = hm[0, 0] * hm[1, 1] - hm[0, 1] * hm[1, 0]
    out[0] = -(c00 * g[0] + c01 * g[1] + c02 * g[2]) / det
    out[1] = -(c01 * g[0] + c11 * g[1] + c12 * g[2]) / det
    out[2] = -(c02 * g[0] + c12 * g[1] + c22 * g[2]) / det
    return True


@njit(cache=True)
def vbd_sweeps(sweeps, rho, tolerance, scale, vertices, colour_ptr, prev1, prev2, g2, x, x_n, y,
               mass, inv_h2, faces, dr_inv, area, stretch, k_shear, membrane, tri_ptr, tri_elem,
               tri_corner, bend, hinge, rest_angle, coef, weights, plate_ptr, plate_col, plate_val,
               hinge_ptr, hinge_elem, hinge_corner, damp, tri_damp, tri_f, hinge_damp):
    """Up to ``sweeps`` sweeps on x in place: colour by colour, one Newton step on each vertex
    of the colour (no two share an element, so the order within a colour does not matter),
    then, with ρ = ``rho`` > 0, the Chebyshev mix (module docstring; prev1, prev2: x⁽ᵏ⁻¹⁾,
    x⁽ᵏ⁻²⁾).

    Returns (sweeps done, r): r = ‖g‖/``scale``, g the vertices' gradients as each vertex
    met them in the last sweep (the Gauss–Seidel residual), ``scale`` ‖M g_gravity‖ (or,
    when 0, r of the first sweep). With ``tolerance`` > 0 the sweeps stop once r ≤ tolerance.
    g2 (len(vertices),) is workspace."""
    g, hm, dx, g12 = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty(12)
    omega = 1.0
    r = 0.0
    done = 0
    for k in range(sweeps):
        for j in range(vertices.shape[0]):  # colour by colour (vertices sorted by colour)
            i = vertices[j]
            vertex_system(i, x, x_n, y, mass, inv_h2, faces, dr_inv, area, stretch, k_shear,
                          membrane, tri_ptr, tri_elem, tri_corner, bend, hinge, rest_angle, coef,
                          weights, plate_ptr, plate_col, plate_val, hinge_ptr, hinge_elem,
                          hinge_corner, damp, tri_damp, tri_f, hinge_damp, g, hm, g12)
            g2[j] = g[0] * g[0] + g[1] * g[1] + g[2] * g[2]
            if _solve3(hm, g, dx):
                for p in range(3):
                    x[i, p] += dx[p]
        if rho > 0.0:
            omega = 1.0 if k == 0 else (2.0 / (2.0 - rho * rho) if k == 1
                                        else 4.0 / (4.0 - rho * rho * omega))
            for j in range(vertices.shape[0]):
                i = vertices[j]
                for p in range(3):
                    if k > 0:
                        x[i, p] = omega * (x[i, p] - prev2[i, p]) + prev2[i, p]
                    prev2[i, p] = prev1[i, p]
                    prev1[i, p] = x[i, p]
        total = 0.0
        for j in range(vertices.shape[0]):
            total += g2[j]
        if scale <= 0.0:
            scale = np.sqrt(total) if total > 0.0 else 1.0
        r = np.sqrt(total) / scale
        done = k + 1
        if tolerance > 0.0 and r <= tolerance:
            break
    return done, r


@njit(cache=True)
def gradient_norm(vertices, x, x_n, y, mass, inv_h2, faces, dr_inv, area, stretch, k_shear,
                  membrane, tri_ptr, tri_elem, tri_corner, bend, hinge, rest_angle, coef, weights,
                  plate_ptr, plate_col, plate_val, hinge_ptr, hinge_elem, hinge_corner, damp,
                  tri_damp, tri_f, hinge_damp):
    """‖∇E(x)‖ over the free vertices (their g_i at x, nothing moved)."""
    g, hm, g12 = np.empty(3), np.empty((3, 3)), np.empty(12)
    total = 0.0
    for j in range(vertices.shape[0]):
        vertex_system(vertices[j], x, x_n, y, mass, inv_h2, faces, dr_inv, area, stretch, k_shear,
                      membrane, tri_ptr, tri_elem, tri_corner, bend, hinge, rest_angle, coef,
                      weights, plate_ptr, plate_col, plate_val, hinge_ptr, hinge_elem,
                      hinge_corner, damp, tri_damp, tri_f, hinge_damp, g, hm, g12)
        total += g[0] * g[0] + g[1] * g[1] + g[2] * g[2]
    return np.sqrt(total)


# ---------------------------------------------------------------------------- integrator


class VertexBlockDescent(Integrator):
    """Vertex Block Descent on the finite-element cloth (module docstring)."""

    energy_class = FemElastic

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        n = model.n_vertices
        self.bend = {None: BEND_NONE, "dihedral": BEND_DIHEDRAL, "quadratic": BEND_QUADRATIC,
                     "hessian": BEND_HESSIAN}[model.bend_model]
        self.tri = incidence(model.faces, n)
        self.hinges = incidence(model.hinge, n)
        empty = np.zeros(0, np.int64)
        self.plate = model.plate if model.plate is not None else (np.zeros(1, np.int64), empty,
                                                                  np.zeros(0))
        self.coupled = [model.faces, model.hinge]  # elements whose vertices interact
        if model.plate is not None:  # the plate couples each vertex with its two-ring
            ptr, col, _ = model.plate
            pairs = np.stack([np.repeat(np.arange(n), np.diff(ptr)), col], axis=1)
            self.coupled.append(pairs[pairs[:, 0] != pairs[:, 1]])
        self.colour_ptr, self.vertices = colour_groups(n, self.coupled, model.free)
        self.weights = (model.hinge_weights if model.hinge_weights is not None
                        else np.zeros((0, 4)))
        damped = model.damping > 0.0
        self.damp = model.damping / h if damped else 0.0
        self.tri_damp = np.zeros((len(model.faces) if damped else 0, 6, 6))
        self.tri_f = np.zeros((len(self.tri_damp), 6))
        dihedral = damped and self.bend == BEND_DIHEDRAL
        self.hinge_damp = np.zeros((len(model.hinge) if dihedral else 0, 12))
        free = self.vertices
        self.scale = float(np.sqrt(np.sum((model.mass[free] ** 2)) * float(model.gravity @ model.gravity)))
        self._g2 = np.zeros(len(free))

    def _args(self, x, x_n, y):
        """The arguments of :func:`vertex_system` after the vertex index."""
        m = self.model
        return (x, x_n, y, m.mass, 1.0 / (self.h * self.h), m.faces, m.dr_inv, m.area, m.tri_stretch,
                m.tri_shear, m.has_membrane, *self.tri, self.bend, m.hinge, m.hinge_rest_angle,
                m.hinge_coef, self.weights, *self.plate, *self.hinges, self.damp, self.tri_damp, self.tri_f,
                self.hinge_damp)

    def prepare(self, x_n):
        """The step's damping data (:func:`damping_data` at x_n; only with damping)."""
        m = self.model
        if self.damp > 0.0:
            damping_data(x_n, m.faces, m.dr_inv, m.area, m.tri_stretch, m.tri_shear, self.bend,
                         m.hinge, self.tri_damp, self.tri_f, self.hinge_damp)

    def solve(self, x, x_n, y, sweeps, rho=0.0, tolerance=0.0):
        """:func:`vbd_sweeps` on x in place (Chebyshev only from ``CHEBYSHEV_MIN_SWEEPS``
        sweeps on); returns (sweeps done, relative residual)."""
        if sweeps < CHEBYSHEV_MIN_SWEEPS:
            rho = 0.0
        if rho > 0.0:
            prev1, prev2 = x.copy(), x.copy()
        else:
            prev1 = prev2 = x
        return vbd_sweeps(sweeps, rho, tolerance, self.scale, self.vertices, self.colour_ptr,
                          prev1, prev2, self._g2, *self._args(x, x_n, y))

    def residual(self, x, x_n, y):
        """‖∇E(x)‖/‖M g‖ over the free vertices, after :meth:`prepare` (x_n)."""
        return gradient_norm(self.vertices, *self._args(x, x_n, y)) / (self.scale or 1.0)

    def sweep(self, x, x_n, y):
        """One Newton step per free vertex, colour by colour, on x in place."""
        self.solve(x, x_n, y, 1)

    def step(self, state):
        solver = self.solver
        y = self._inertial_target(state)
        x = self._initial_guess(state)
        self.prepare(state.x)
        done, residual = self.solve(x, state.x, y, solver.iterations, solver.chebyshev_rho,
                                    solver.vbd_tolerance)
        x_n, v_n = state.x, state.v
        self._finish(state, x)
        state.x_prev, state.v_prev = x_n, v_n
        return StepReport(sweeps=done, residual=residual)

    def _initial_guess(self, state):
        """x_n + h v_n + h² ã (module docstring); pinned vertices at x_n."""
        h, g = self.h, self.model.gravity
        g2 = float(g @ g)
        x = state.x + h * state.v
        if g2 > 0.0:
            if state.v_prev is None:
                along = np.ones(len(x))
            else:
                a = (state.v - state.v_prev) / h  # the last step's acceleration; a·g without BLAS
                along = np.clip((a[:, 0] * g[0] + a[:, 1] * g[1] + a[:, 2] * g[2]) / g2, 0.0, 1.0)
            x += (h * h) * along[:, None] * g
        if self.model.has_pins:
            x[self.model.pinned] = state.x[self.model.pinned]
        return x
