"""The measured fabrics and a KES-F sheet through the lab's tests.

    python -m benchmarks fabrics

Writes ``bench-results/fabrics.md`` (and, under ``--full``, the presets' and denims' tables of
docs/simulate.md):

- every preset (``material.preset``, :mod:`clothtool.fabrics`): the bending length its
  own data predict along warp (u) and weft (v), c = (B/(ρg))^(1/3), against the simulated
  cantilever's (:func:`clothtool.sim.textile.cantilever_bending_length`: a grid strip of
  overhang 2c, 20 divisions, static equilibrium, read through the elastica), and its
  simulated Cusick drape coefficient (:func:`clothtool.sim.lab_sheet.simulated_drape`: a
  10 mm grid disc clamped at 9 cm, damping 0.05 s, brought to rest) with its discretisation
  error at 10 mm (the change from a 14 mm disc, :func:`clothtool.sim.textile.drape_error`):
  the drapes and the weft cantilevers under ``--full`` only, so only ``--full`` writes the
  docs' tables;
- Kumari & Khurana 2016's six denims (J. Textiles 4614168, Table 5: EMT, B, G, W as
  printed, one value per fabric) as material blocks, the same two tests.
"""

import time

from benchmarks.common import FULL, full_or, markdown_table, write_doc_table

# The cantilevers' directions: along weft (v) under --full only; the errors along warp and weft
# are alike (-0.05 to +0.32 % on the presets, docs/simulate.md), and a denim's bending is one
# value for both.
DIRECTIONS = full_or(("warp", "weft"), ("warp",))

# Kumari & Khurana 2016, Table 5 ("Primary hand values"), fabrics A–F: EMT %, B gf·cm²/cm,
# G gf/(cm·deg), W mg/cm² (as printed: 94–109 mg/cm², i.e. 0.94–1.09 kg/m²)
KUMARI_KHURANA = {
    "A": (5.515, 0.172, 2.180, 104.0),
    "B": (5.735, 0.144, 1.538, 109.32),
    "C": (4.695, 0.227, 3.398, 93.89),
    "D": (5.135, 0.147, 1.613, 107.77),
    "E": (4.710, 0.207, 1.538, 104.0),
    "F": (5.455, 0.148, 1.500, 104.89),
}


def lab_rows(name, material):
    """One row: the resolved material, predicted and simulated bending lengths (warp, weft)
    and the drape coefficient."""
    from clothtool.lab_units import to_lab
    from clothtool.sim.model.config import load_config
    from clothtool.sim.lab_sheet import simulated_drape
    from clothtool.sim.textile import cantilever_bending_length

    resolved = load_config({"mesh": {"grid": {"nx": 2, "ny": 2}}, "material": material}).material
    predicted = to_lab(resolved)["bending length"]
    row = {"fabric": name, "material": resolved, "predicted": predicted, "errors": []}
    started = time.perf_counter()
    for i, direction in enumerate(DIRECTIONS):
        simulated = 100.0 * cantilever_bending_length(material, direction)
        row[f"c {direction} cm"] = f"{predicted[i]:.3f}"
        row[f"simulated {direction} cm"] = f"{simulated:.3f}"
        row["errors"].append(100 * (simulated / predicted[i] - 1))
        row[f"{direction} error"] = f"{row['errors'][-1]:+.2f} %"
    if FULL:  # most of the benchmark's time: the denims' drapes alone about 20 s each
        drape = simulated_drape(resolved)
        row["dc"] = drape.coefficient
        row["drape coefficient"] = f"{100 * drape.coefficient:.1f} % ± {100 * drape.error:.1f}"
    row["wall s"] = f"{time.perf_counter() - started:.0f}"
    print("  ", {k: v for k, v in row.items() if k not in ("material", "errors")}, flush=True)
    return row


def pair(values, fmt):
    return f"[{format(values[0], fmt)}, {format(values[1], fmt)}]"


def preset_doc_row(row):
    """A preset's row of docs/simulate.md: its use, its keys, the 45° rigidity ARCSim measured,
    its bending lengths with the simulated cantilever's error, drape and dropped coupling."""
    from clothtool import fabrics

    name, m = row["fabric"], row["material"]
    use, fibres = fabrics.ARCSIM[name][:2]
    r = fabrics.coupling(name)
    return {"preset": f"`{name}`", "use, fibres": f"{use}, {fibres}", "density kg/m²": m.density,
            "stretch [u, v] N/m": pair(m.stretch, ".4g"), "shear N/m": f"{m.shear:.4g}",
            "bend [B_u, B_v] (1e-6 N·m); B at 45°": pair([1e6 * b for b in m.bend], ".2f")
            + f"; {1e6 * fabrics.rigidities(name)[1]:.2f}",
            "c along u / v cm, simulated": " / ".join(f"{c:.3f}" for c in row["predicted"])
            + ": " + " / ".join(f"{e:+.2f}" for e in row["errors"]) + " %",
            "Cusick drape coefficient, 10 mm disc ± its discretisation error":
                row["drape coefficient"],
            "coupling dropped": "not PD" if r is None else f"{100 * r:.2g} %"}


def denim_doc_row(row, values):
    """A denim's row of docs/simulate.md: the lab's values, the block they give, its bending
    length with the simulated cantilever's error, and drape."""
    m = row["material"]
    return {"denim": row["fabric"].removeprefix("K&K "),
            "EMT / B / G / W": " / ".join(f"{v:g}" for v in values),
            "material block out": f"`{{density: {m.density:.4g}, stretch: {m.stretch:.4g}, "
                                  f"shear: {m.shear:.4g}, bend: {m.bend:.4g}}}`",
            "c cm; simulated": f"{row['predicted'][0]:.3f}; {row['errors'][0]:+.2f} %",
            "Cusick, 10 mm disc ± its discretisation error": row["drape coefficient"]}


def run(out_dir):
    from clothtool.fabrics import PRESETS

    started = time.perf_counter()
    presets = [lab_rows(name, {"preset": name}) for name in PRESETS]
    denims = [lab_rows(f"K&K {name}", {"kes": {"EMT": emt, "B": b, "G": g, "W": w}})
              for name, (emt, b, g, w) in KUMARI_KHURANA.items()]
    columns = ["fabric", "c warp cm", "simulated warp cm", "warp error", "c weft cm",
               "simulated weft cm", "weft error"] + ["drape coefficient"] * FULL + ["wall s"]
    text = ("## Measured fabrics\n\n`python -m benchmarks fabrics`: bending length predicted, "
            "(B/(ρg))^(1/3), against the simulated cantilever's (grid strip, overhang 2c, 20 "
            "divisions, static equilibrium, read through the elastica); Cusick drape "
            "coefficient (30 cm disc clamped on an 18 cm pedestal, 10 mm grid, damping 0.05 s, "
            "at rest) ± its discretisation error (the change from a 14 mm disc)"
            + ("" if FULL else "; along weft and the drapes: `python -m benchmarks --full fabrics`")
            + ".\n\n"
            "### Presets (Wang et al. 2011 via ARCSim)\n\n"
            + markdown_table(presets, columns)
            + "\n### Kumari & Khurana 2016's denims (KES-F, Table 5; W as printed)\n\n"
            + markdown_table(denims, columns))
    (out_dir / "fabrics.md").write_text(text)
    if FULL:
        rows = [preset_doc_row(r) for r in presets]
        write_doc_table("docs/simulate.md", "fabrics-presets",
                        markdown_table(rows, list(rows[0])), "fabrics")
        rows = [denim_doc_row(r, v) for r, v in zip(denims, KUMARI_KHURANA.values())]
        write_doc_table("docs/simulate.md", "fabrics-denims",
                        markdown_table(rows, list(rows[0])), "fabrics")
    print(f"  fabrics benchmark in {time.perf_counter() - started:.0f} s")
