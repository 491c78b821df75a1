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


SI_KEYS = ("density", "stretch", "rest_stretch", "shear", "bend", "damping", "bend_model",
           "damping_model", "membrane_model")


def simulated_drape(material, spacing=0.01):
    """The Cusick drape coefficient of a material section, simulated
    (:func:`clothtool.sim.textile.cusick_drape`, a grid disc of ``spacing`` m, damping
    CUSICK_DAMPING so that it comes to rest)."""
    from clothtool.sim.textile import CUSICK_DAMPING, cusick_drape

    keys = {k: getattr(material, k) for k in SI_KEYS}
    return cusick_drape({**keys, "damping": CUSICK_DAMPING}, spacing)[0]


def report(material, drape=None):
    """A material section as a YAML ``material`` block (its SI keys) followed by comment lines
    giving it in a lab's units (with ``drape``, its simulated Cusick drape coefficient) and,
    for a preset, the fabric's measured rigidity at 45° and its Poisson coupling."""
    from clothtool.sim import fabrics

    def g(value):
        return f"{value:.6g}"

    def pair(value):
        return f"[{g(value[0])}, {g(value[1])}]" if isinstance(value, tuple) else g(value)

    lab = to_lab(material)
    emt = " / ".join("over 100" if e is None else f"{e:.3g}" for e in lab["EMT"])
    lines = ["material:", f"  density: {g(material.density)}",
             f"  stretch: {pair(material.stretch)}", f"  shear: {g(material.shear)}",
             f"  bend: {pair(material.bend)}",
             "# in a lab's units (warp / weft):",
             f"#   W {lab['W']:.4g} mg/cm² ({lab['grams per m2']:.4g} g/m²)",
             "#   B " + " / ".join(f"{b:.4g}" for b in lab["B"]) + " gf·cm²/cm (KES-F)",
             "#   bending length c " + " / ".join(f"{c:.3g}" for c in lab["bending length"])
             + " cm (ASTM D1388, (bend/(density·9.81))^(1/3))",
             f"#   G {lab['G']:.3g} gf/(cm·deg) (KES-F)",
             f"#   EMT {emt} % (the linear stretch at 500 gf/cm)"]
    if drape is not None:
        lines.append(f"#   Cusick drape coefficient {100 * drape:.1f} % (simulated: 30 cm disc "
                     "on an 18 cm pedestal, 10 mm grid, damping 0.05 s, 3 s at 60 fps)")
    if material.preset is not None:
        use, fibres = fabrics.ARCSIM[material.preset][:2]
        b45 = fabrics.rigidities(material.preset)[1]
        r = fabrics.coupling(material.preset)
        lines += [f"# {material.preset}: {use}, {fibres} (Wang, O'Brien & Ramamoorthi 2011, "
                  "via ARCSim)",
                  f"#   measured B at 45°: {b45 / KES_B:.4g} gf·cm²/cm",
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


def fit_report(material, fit):
    """A material block with the bending that :func:`clothtool.sim.drape_fit.fit_drape` found
    (``fit``), and what it rests on."""
    from dataclasses import replace

    lines = []
    if fit.sbatch:
        lines.append(f"# a round waits for Slurm: {fit.sbatch}; rerun this command once it ended")
    if fit.bend is None:
        return "\n".join(lines)
    lines.append(report(replace(material, bend=fit.bend), fit.coefficient))
    lines.append(f"# fitted to a drape coefficient of {100 * fit.target:g} %: bending length "
                 f"{100 * fit.bending_length:.3g} cm, simulated {100 * fit.coefficient:.1f} % "
                 f"({len(fit.runs)} simulations)")
    return "\n".join(lines)
