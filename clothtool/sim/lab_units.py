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
``bend`` = ρ g c³ and c = (``bend``/(ρ g))^(1/3), g = 9.81 m/s² as in ``material.bending_length``.
A report's warp and weft B give one ``bend``, the plate here being isotropic in bending:
their geometric mean √(B_warp B_weft) (each direction's own bending length is then off by
(B_warp/B_weft)^(±1/6)).
"""

import math

from clothtool.errors import InputError

from clothtool.sim.model.config import STANDARD_GRAVITY

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
        out["bend"] = KES_B * (math.sqrt(b[0] * b[1]) if isinstance(b, (tuple, list)) else b)
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
    """A material section's values in a lab's units: W (mg/cm²), areal weight (g/m²), B
    (gf·cm²/cm), bending length c (cm), G (gf/cm·deg) and EMT (%, warp and weft: the strain
    at 500 gf/cm of the linear stretch; None above 100 %)."""
    stretch = material.stretch if isinstance(material.stretch, tuple) else (material.stretch,) * 2
    return {
        "W": material.density / KES_W,
        "grams per m2": material.density * 1000.0,
        "B": material.bend / KES_B,
        "bending length": 100.0 * bending_length(material.bend, material.density),
        "G": material.shear / KES_G,
        "EMT": tuple(100.0 * KES_FM / k if k > KES_FM else None for k in stretch),
    }


def report(material):
    """A material section as a YAML ``material`` block (its SI keys) followed by comment lines
    giving it in a lab's units and, for a preset, the fabric's measured rigidities."""
    from clothtool.sim import fabrics

    def g(value):
        return f"{value:.6g}"

    stretch = (f"[{g(material.stretch[0])}, {g(material.stretch[1])}]"
               if isinstance(material.stretch, tuple) else g(material.stretch))
    lab = to_lab(material)
    emt = " / ".join("over 100" if e is None else f"{e:.3g}" for e in lab["EMT"])
    lines = ["material:", f"  density: {g(material.density)}", f"  stretch: {stretch}",
             f"  shear: {g(material.shear)}", f"  bend: {g(material.bend)}",
             "# in a lab's units:",
             f"#   W {lab['W']:.4g} mg/cm² ({lab['grams per m2']:.4g} g/m²)",
             f"#   B {lab['B']:.4g} gf·cm²/cm (KES-F)",
             f"#   bending length c {lab['bending length']:.3g} cm (ASTM D1388, "
             "(bend/(density·9.81))^(1/3))",
             f"#   G {lab['G']:.3g} gf/(cm·deg) (KES-F)",
             f"#   EMT {emt} % (warp / weft, the linear stretch at 500 gf/cm)"]
    if material.preset is not None:
        use, fibres = fabrics.ARCSIM[material.preset][:2]
        rig = fabrics.rigidities(material.preset)
        c = [100.0 * bending_length(b, material.density) for b in rig]
        r = fabrics.coupling(material.preset)
        lines += [f"# {material.preset}: {use}, {fibres} (Wang, O'Brien & Ramamoorthi 2011, "
                  "via ARCSim)",
                  "#   measured B along u / at 45° / along v: "
                  + " / ".join(f"{b / KES_B:.4g}" for b in rig) + " gf·cm²/cm, c "
                  + " / ".join(f"{x:.3g}" for x in c) + " cm",
                  "#   Poisson coupling dropped: " + (
                      "its small-strain tensor is not positive definite" if r is None else
                      f"with it a strip along u or v is {100 * (1 - r):.3g} % as stiff")]
    return "\n".join(lines)


def material_of(config=None, *, preset=None, kes=(), overrides=()):
    """The material section of ``config`` (a YAML path; None: the defaults) with ``preset``
    (``material.preset``), KES-F values ``kes`` (``"B=0.18"``, ``"EMT=4.1,3.8"`` for warp and
    weft) and ``overrides`` (``"material.shear=40"``) applied, in that order."""
    from clothtool.sim.model.config import load_config

    sets = [f"material.preset={preset}"] if preset is not None else []
    for text in kes:
        name, sep, value = (part.strip() for part in text.partition("="))
        if not sep or not name or not value:
            raise InputError("expected NAME=VALUE (B, G, EMT or W; B=0.16,0.20 gives warp and "
                             "weft)", keyword="kes", value=repr(text))
        sets.append(f"material.kes.{name}=" + (f"[{value}]" if "," in value else value))
    raw = {"mesh": {"grid": {"nx": 2, "ny": 2}}} if config is None else config
    return load_config(raw, overrides=sets + list(overrides)).material
