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

import csv
from pathlib import Path

from clothtool.errors import InputError

TABLE = Path(__file__).with_name("fabrics.csv")


def read_table(path=TABLE):
    """{name: (use, fibres, density kg/m², stretching row 0 (C11, C12, C22, C33), bending
    column 0 (edges along u, at 45°, along v))} from the CSV of ARCSim's materials/NAME.json
    values (``#`` lines are its notes)."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = csv.DictReader(line for line in fh if not line.startswith("#"))
        return {r["name"]: (r["use"], r["fibres"], float(r["density"]),
                            tuple(float(r[c]) for c in ("C11", "C12", "C22", "C33")),
                            tuple(float(r[c]) for c in ("ke_u_edges", "ke_45", "ke_v_edges")))
                for r in rows}


ARCSIM = read_table()
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
