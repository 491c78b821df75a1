"""Measured fabrics as material presets (``material.preset``): the ten fabrics of Wang,
O'Brien & Ramamoorthi 2011, "Data-driven elastic models for cloth: modeling and
measurement" (ACM TOG 30(4), 71), in the form ARCSim ships them (``materials/*.json``).

The conversion follows ARCSim's code (Narain et al. 2012; ``conf.cpp``, ``dde.cpp``,
``physics.cpp``), taken at small strain and small curvature:

- ``density``: ARCSim's kg/m², as is.
- stretching: row 0 of the table (C₁₁, C₁₂, C₂₂, C₃₃) is the stiffness at zero strain for
  every direction; ARCSim doubles every stored value before use and its force is the
  gradient of ½(k₀G₀₀² + 2k₁G₀₀G₁₁ + k₂G₁₁² + 2k₃G₀₁²), k = 2C, G = (FᵀF − I)/2 the Green
  strain. With ε ≈ G₀₀ and the shear angle γ = 2G₀₁ this is ours,
  ½(k_u ε_u² + k_v ε_v² + k_h γ²), for ``stretch`` = [2C₁₁, 2C₂₂] and ``shear`` = C₃₃.
  ARCSim's Poisson coupling 2C₁₂ has no counterpart here and is dropped: the strip test's
  modulus with free contraction, 2(C₁₁ − C₁₂²/C₂₂), is lower by the ``coupling`` fraction.
  One fabric's small-strain tensor is not positive definite (navy-sparkle-sweat: C₁₂² =
  395 > C₁₁C₂₂ = 40.9, N²/m²), so no elastic law stands on it; dropping the coupling, its
  diagonal is kept.
- bending: ARCSim's hinge energy is k_e ‖e‖²θ²/(8(A₁ + A₂)), A the rest triangle areas,
  k_e read from the table by the hinge's direction (rows: edge along u, at 45°, along v)
  and curvature (columns; column 0 at zero curvature). A cylinder of curvature κ stores
  k_e κ²/8 per area with it on a grid or an equilateral mesh (0.246 and 0.247 k_e measured,
  60 cells a side; 0.27 on a Delaunay mesh, 0.41–0.42 on a grid turned 45°), so the stored
  k_e does not include that factor and the flexural rigidity is k_e/4 (N·m). A strip along u bends on
  hinges across it (edges along v): ``bend`` = [B_u, B_v] = [k_e(v-edges), k_e(u-edges)]/4
  (the plate's twist takes √(B_u B_v); ARCSim's 45° row is the check, see the docs).
"""

from clothtool.errors import InputError

# name: (use, fibres, density kg/m², stretching row 0 (C11, C12, C22, C33), bending column 0
# (edges along u, at 45°, along v)), the values of ARCSim's materials/NAME.json
ARCSIM = {
    "11oz-black-denim": ("jeans", "99% cotton 1% spandex", 0.324,
                         (205.352005, 10.234077, 1013.88629, 53.387184),
                         (64.196457e-6, 73.384567e-6, 96.951576e-6)),
    "camel-ponte-roma": ("jacket", "60% polyester 40% rayon", 0.284,
                         (31.146198, -12.802702, 44.028667, 31.896357),
                         (36.348366e-6, 33.013252e-6, 37.157593e-6)),
    "gray-interlock": ("t-shirt", "60% cotton 40% polyester", 0.187,
                       (16.593832, -14.69599, 34.477123, 36.860302),
                       (23.191698e-6, 24.749964e-6, 14.267624e-6)),
    "ivory-rib-knit": ("underwear", "95% cotton 5% spandex", 0.276,
                       (42.871021, -0.234556, 65.166023, 83.175644),
                       (46.237591e-6, 30.015930e-6, 32.243889e-6)),
    "navy-sparkle-sweat": ("sweater", "96% polyester 4% spandex", 0.224,
                           (12.486332, -19.875324, 3.272434, 17.616289),
                           (59.469658e-6, 40.072277e-6, 45.625023e-6)),
    "pink-ribbon-brown": ("blanket", "100% polyester", 0.228,
                          (151.503906, 106.02816, 244.830673, 30.250183),
                          (117.070122e-6, 87.509773e-6, 59.774277e-6)),
    "royal-target": ("pants", "65% cotton 35% polyester", 0.22,
                     (2016.55456, 9.170511, 2034.97644, 104.759674),
                     (125.409805e-6, 107.997696e-6, 125.409805e-6)),
    "tango-red-jet-set": ("jacket", "100% polyester", 0.113,
                          (43.067627, 54.373299, 171.424835, 14.3147),
                          (14.293814e-6, 21.9517e-6, 20.345654e-6)),
    "white-dots-on-blk": ("tablecloth", "100% polyester", 0.128,
                          (2002.08618, 0.345588, 2027.48559, 19.189022),
                          (51.713814e-6, 40.65947e-6, 31.282822e-6)),
    "white-swim-solid": ("swimsuit", "87% nylon 13% spandex", 0.204,
                         (47.971176, 6.834521, 104.615456, 60.773663),
                         (60.237942e-6, 58.803211e-6, 51.018833e-6)),
}
PRESETS = tuple(ARCSIM)


def from_arcsim(density, stretching, bending):
    """Our ``material`` keys of an ARCSim material (its small-strain, small-curvature values):
    density ρ; stretch [2C₁₁, 2C₂₂] N/m; shear C₃₃ N/m; bend [B_u, B_v] N·m with
    B_u = k_e(edges along v)/4, B_v = k_e(edges along u)/4."""
    c11, _, c22, c33 = stretching
    along_u_edges, _, along_v_edges = bending
    return {"density": float(density), "stretch": (2.0 * c11, 2.0 * c22), "shear": float(c33),
            "bend": (along_v_edges / 4.0, along_u_edges / 4.0)}


def preset(name, key="material.preset"):
    """The ``material`` keys (density, stretch, shear, bend) of the measured fabric ``name``."""
    if name not in ARCSIM:
        raise InputError(f"{key}: unknown fabric {name!r}; the presets are {', '.join(PRESETS)}")
    _, _, density, stretching, bending = ARCSIM[name]
    return from_arcsim(density, stretching, bending)


def rigidities(name):
    """(B_u, B_45, B_v) N·m of fabric ``name``: its flexural rigidity bending along u (a strip
    cut along u), at 45° and along v, k_e/4 of the hinges across each."""
    along_u_edges, diagonal, along_v_edges = ARCSIM[name][4]
    return along_v_edges / 4.0, diagonal / 4.0, along_u_edges / 4.0


def coupling(name):
    """r = C₁₂²/(C₁₁C₂₂) of fabric ``name``: with ARCSim's Poisson coupling a strip stretched
    along u or v (free to contract) is (1 − r) as stiff as the preset; None where the measured
    small-strain tensor is not positive definite (r ≥ 1)."""
    c11, c12, c22, _ = ARCSIM[name][3]
    r = c12 * c12 / (c11 * c22)
    return None if r >= 1.0 else r


def listing():
    """One line per preset: name, use, fibres and its material keys."""
    lines = []
    for name in PRESETS:
        use, fibres = ARCSIM[name][:2]
        m = preset(name)
        lines.append(f"{name}: {use}, {fibres}; density {m['density']:g} kg/m², stretch "
                     f"[{m['stretch'][0]:.4g}, {m['stretch'][1]:.4g}] N/m, shear "
                     f"{m['shear']:.4g} N/m, bend [{m['bend'][0]:.4g}, {m['bend'][1]:.4g}] N·m")
    return lines
