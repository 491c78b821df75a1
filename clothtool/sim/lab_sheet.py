"""A material as a textile lab's sheet, the library of ``clothtool fabric``: a material section
from a config, a preset or KES-F values (:func:`material_of`), printed as a YAML block with its
lab units (:func:`report`, :mod:`clothtool.lab_units`), its simulated Cusick drape
(:func:`simulated_drape`) and a drape fit's answer (:func:`fit_report`,
:mod:`clothtool.sweeps.drape_fit`).
"""

from dataclasses import dataclass

from clothtool import fabrics
from clothtool.errors import InputError
from clothtool.lab_units import KES_B, bending_length, to_lab

SI_KEYS = ("density", "stretch", "rest_stretch", "shear", "bend", "damping", "bend_model",
           "damping_model", "membrane_model", "plate_correction")


SPACING = 0.01  # m, the Cusick disc's grid


@dataclass
class Drape:
    """A simulated Cusick ``coefficient`` (a fraction), the grid ``spacing`` (m) of its disc
    and its estimated discretisation ``error`` (a fraction; None: not estimated)."""

    coefficient: float
    spacing: float = SPACING
    error: float | None = None

    def describe(self):
        """'74.1 % ± 0.6 (simulated on a 10 mm grid disc; ...)' for a report line."""
        error = "" if self.error is None else f" ± {100 * self.error:.1f}"
        coarse = "" if self.error is None else (
            f"; ± its discretisation error, the change from a "
            f"{1000 * 2 ** 0.5 * self.spacing:.0f} mm disc")
        return (f"{100 * self.coefficient:.1f} %{error} (simulated on a {1000 * self.spacing:g} "
                f"mm grid disc{coarse}; 30 cm disc on an 18 cm pedestal, damping 0.05 s, at "
                "rest)")


def simulated_drape(material, spacing=SPACING):
    """The Cusick drape of a material section, simulated (:func:`clothtool.sim.textile.
    cusick_drape`, a grid disc of ``spacing`` m, damping CUSICK_DAMPING, brought to rest),
    with its discretisation error (:func:`clothtool.sim.textile.drape_error`): a
    :class:`Drape`."""
    from clothtool.sim.textile import CUSICK_DAMPING, cusick_drape, drape_error

    keys = {k: getattr(material, k) for k in SI_KEYS}
    keys = {**keys, "damping": CUSICK_DAMPING}
    coefficient = cusick_drape(keys, spacing)[0]
    return Drape(coefficient, spacing, drape_error(keys, spacing, coefficient))


def report(material, drape=None):
    """A material section as a YAML ``material`` block (its SI keys) followed by comment lines
    giving it in a lab's units (with ``drape``, its simulated Cusick drape, a :class:`Drape`) and,
    for a preset, the fabric's measured rigidity at 45° and its Poisson coupling."""
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
        lines.append(f"#   Cusick drape coefficient {drape.describe()}")
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
    """A material block with the bending that :func:`clothtool.sweeps.drape_fit.fit_drape` found
    (``fit``), and what it rests on."""
    from dataclasses import replace

    lines = []
    if fit.sbatch:
        lines.append(f"# a round waits for Slurm: {fit.sbatch}; rerun this command once it ended")
    if fit.bend is None:
        return "\n".join(lines)
    lines.append(report(replace(material, bend=fit.bend),
                        Drape(fit.coefficient, fit.spacing, fit.error)))
    lines.append(f"# fitted to a drape coefficient of {100 * fit.target:g} %: bending length "
                 f"{100 * fit.bending_length:.3g} cm, simulated {100 * fit.coefficient:.1f} % "
                 f"({len(fit.runs)} simulations)")
    return "\n".join(lines)
