"""A textile lab's units in and out of the ``material`` keys (SI).

KES-F (Kawabata 1980, "The standardization and analysis of hand evaluation", 2nd ed.; the
gram-force is g_n · 1 g = 9.80665e-3 N by definition):

- B, bending rigidity, gf·cm²/cm → ``bend`` N·m: × 9.80665e-3 · 1e-2 = 9.80665e-5;
- G, shear stiffness, gf/(cm·deg) → ``shear`` N/m (per radian of shear angle):
  × 0.980665 · 180/π = 56.19;
- EMT, tensile strain (%) at F_m = 500 gf/cm (490.33 N/m) → ``stretch`` N/m: the secant
  490.33 / (EMT/100) (fabric stiffens as it is pulled: its slope at rest is lower);
- W, mass per area, mg/cm² → ``density`` kg/m²: × 0.01.

ASTM D1388: the cantilever's bending length c and G = W c³ (W weight per area), so
``bend`` = ρ g c³ and c = (``bend``/(ρ g))^(1/3), g = 9.81 m/s² (``material.bending_length``).
The library of ``clothtool fabric`` that runs the simulator is :mod:`clothtool.sim.lab_sheet`.
"""

import math

STANDARD_GRAVITY = 9.81  # m/s², of bending_length → bend (k_b = ρ g c³)
GRAM_FORCE = 9.80665e-3  # N
KES_B = 9.80665e-5  # N·m per gf·cm²/cm: 9.80665e-3 N · 1e-2 m
KES_G = GRAM_FORCE / 1e-2 * 180.0 / math.pi  # N/m per gf/(cm·deg)
KES_FM = 500.0 * GRAM_FORCE / 1e-2  # N/m, the tensile test's largest load, 500 gf/cm
KES_W = 0.01  # kg/m² per mg/cm² (1e-6 kg / 1e-4 m²)


def from_kes(kes):
    """``material`` keys from KES-F values: a mapping with any of B (gf·cm²/cm), G (gf/cm·deg),
    EMT (%), W (mg/cm²); B and EMT a number or (warp, weft)."""
    out = {}
    if kes.get("W") is not None:
        out["density"] = kes["W"] * KES_W
    if kes.get("B") is not None:
        b = kes["B"]
        out["bend"] = tuple(KES_B * x for x in b) if isinstance(b, (tuple, list)) else KES_B * b
    if kes.get("G") is not None:
        out["shear"] = kes["G"] * KES_G
    if kes.get("EMT") is not None:
        emt = kes["EMT"]
        out["stretch"] = (tuple(KES_FM / (e / 100.0) for e in emt) if isinstance(emt, (tuple, list))
                          else KES_FM / (emt / 100.0))
    return out


def bending_length(bend, density, gravity=STANDARD_GRAVITY):
    """ASTM D1388's bending length c = (k_b/(ρ g))^(1/3), m."""
    return (bend / (density * gravity)) ** (1.0 / 3.0)


def to_lab(material):
    """A material section's values in a lab's units: W (mg/cm²), areal weight (g/m²), and
    for warp and weft B (gf·cm²/cm), bending length c (cm), EMT (%: the strain at 500 gf/cm
    of the linear stretch; None above 100 %); G (gf/cm·deg)."""
    stretch, bend = (v if isinstance(v, tuple) else (v, v)
                     for v in (material.stretch, material.bend))
    return {
        "W": material.density / KES_W,
        "grams per m2": material.density * 1000.0,
        "B": tuple(b / KES_B for b in bend),
        "bending length": tuple(100.0 * bending_length(b, material.density) for b in bend),
        "G": material.shear / KES_G,
        "EMT": tuple(100.0 * KES_FM / k if k > KES_FM else None for k in stretch),
    }
