"""Measured fabric presets (``material.preset``) and a lab's units in and out
(``material.kes``, ``clothtool fabric``), against hand calculations.

- ARCSim's 11oz black denim converted by hand (stretch 2C, shear C₃₃, bend k_e/4);
- every preset positive definite; the one fabric whose measured tensor is not, named;
- ARCSim's hinge energy on a rolled grid and an equilateral mesh: k_e/4 of flexural rigidity;
- KES-F B, G, EMT, W and ASTM D1388's c = (B/W)^(1/3) in the lab's own units;
- a preset config runs; bad input is one line and exit code 2.
"""

import hashlib
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.geometry import dihedral_angles, hinges
from clothtool import fabrics, lab_units
from clothtool.sim import lab_sheet
from clothtool.sim.model.config import load_config, resolved_yaml
from clothtool.sim.textile import strip


def material(**keys):
    return load_config({"mesh": {"grid": {"nx": 4, "ny": 4}}, "material": keys}).material


# ---------------------------------------------------------------------------- presets


def test_denim_by_hand():
    """materials/11oz-black-denim.json: density 0.324, stretching row 0 (205.352005,
    10.234077, 1013.88629, 53.387184), bending column 0 (64.196457, 73.384567, 96.951576)e-6.
    stretch = 2·205.352005 = 410.70401 and 2·1013.88629 = 2027.77258 N/m; shear 53.387184;
    bend [B_u, B_v] = [96.951576e-6/4, 64.196457e-6/4] = [24.237894e-6, 16.049114e-6] N·m
    (B_u from the hinges across a strip along u: edges along v, the table's third row)."""
    m = material(preset="11oz-black-denim")
    assert m.density == 0.324
    assert m.stretch == pytest.approx((410.70401, 2027.77258), rel=1e-12)
    assert m.shear == pytest.approx(53.387184, rel=1e-12)
    assert m.bend == pytest.approx((24.237894e-6, 16.049114e-6), rel=1e-12)
    assert fabrics.rigidities("11oz-black-denim") == pytest.approx(
        (24.237894e-6, 73.384567e-6 / 4, 16.049114e-6), rel=1e-7)


@pytest.mark.parametrize("name", fabrics.PRESETS)
def test_every_preset_is_positive_definite(name):
    """Our stretch and shear energy ½(k_u ε_u² + k_v ε_v² + k_h γ²) is positive definite when
    its three stiffnesses are; the bend and density are positive."""
    m = material(preset=name)
    assert min(m.stretch) > 0 and m.shear > 0 and min(m.bend) > 0 and m.density > 0
    c11, c12, c22, c33 = fabrics.ARCSIM[name][3]
    tensor = np.array([[c11, c12], [c12, c22]])
    measured_pd = np.linalg.eigvalsh(tensor).min() > 0
    assert (fabrics.coupling(name) is not None) == measured_pd
    assert measured_pd == (name != "navy-sparkle-sweat")  # the one the docs name


def test_the_fabric_table_is_arcsims_to_the_bit():
    """clothtool/fabrics.csv, read at import, holds the very floats the presets had when they
    were code rows (the sha256 of the table's sorted items' repr, which round-trips every
    float, taken from those rows), in ARCSim's order, and ships with the package."""
    digest = hashlib.sha256(repr(sorted(fabrics.ARCSIM.items())).encode()).hexdigest()
    assert digest == "b9deeebddd06d2d8f5d402d2e9308fce72c4f25c4c971b01ca5b56ac2d140913"
    assert fabrics.PRESETS == tuple(sorted(fabrics.PRESETS)) and len(fabrics.PRESETS) == 10
    pyproject = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    assert fabrics.TABLE.name in pyproject["tool"]["setuptools"]["package-data"]["clothtool"]


def test_the_fabric_table_reads_its_columns(tmp_path):
    table = tmp_path / "t.csv"
    table.write_text("# a note\nname,use,fibres,density,C11,C12,C22,C33,ke_u_edges,ke_45,ke_v_edges\n"
                     "x,jeans,\"99% cotton, 1% spandex\",0.3,1,2,3,4,5e-6,6e-6,7e-6\n")
    assert fabrics.read_table(table) == {
        "x": ("jeans", "99% cotton, 1% spandex", 0.3, (1.0, 2.0, 3.0, 4.0), (5e-6, 6e-6, 7e-6))}


def test_a_presets_keys_are_overridden_one_by_one():
    m = material(preset="royal-target", shear=80.0, damping=0.05)
    assert m.shear == 80.0 and m.damping == 0.05
    assert m.density == 0.22 and m.stretch == pytest.approx((2 * 2016.55456, 2 * 2034.97644))
    c = material(preset="royal-target", bending_length=[0.03, 0.02])
    assert c.bend == pytest.approx((0.22 * 9.81 * 0.03 ** 3, 0.22 * 9.81 * 0.02 ** 3))


def test_a_preset_reads_back_from_its_resolved_yaml(tmp_path):
    import yaml

    config = load_config({"mesh": {"grid": {"nx": 4, "ny": 4}},
                          "material": {"preset": "gray-interlock", "shear": 20}})
    again = load_config(yaml.safe_load(resolved_yaml(config)))
    assert again.material.stretch == config.material.stretch
    assert again.material.shear == 20 and again.material.bend == config.material.bend


def test_a_panel_takes_a_preset():
    config = load_config({"mesh": {"grid": {"nx": 4, "ny": 4}},
                          "materials": {"cuff": {"preset": "ivory-rib-knit", "bend": 2e-5,
                                                 "faces": [0, 1]}}})
    cuff = config.materials["cuff"]
    assert cuff.density == 0.276 and cuff.shear == pytest.approx(83.175644)
    assert cuff.bend == 2e-5
    assert config.materials["cuff"].stretch == pytest.approx((2 * 42.871021, 2 * 65.166023))


def test_unknown_preset_lists_the_names():
    with pytest.raises(InputError) as err:
        material(preset="denim")
    message = str(err.value)
    assert "\n" not in message and "material.preset" in message
    assert all(name in message for name in fabrics.PRESETS)


def arcsim_hinge_rigidity(uv, faces, kappa=5.0):
    """ARCSim's hinge energy Σ k_e ‖e‖²θ²/(8(A₁+A₂)) (k_e = 1) of the pattern rolled onto a
    cylinder of curvature κ along u, over κ²/2 × the area: the rigidity per unit k_e."""
    x = np.stack([np.sin(kappa * uv[:, 0]) / kappa, uv[:, 1],
                  (1.0 - np.cos(kappa * uv[:, 0])) / kappa], axis=1)
    h, pair = hinges(faces, len(uv))
    e1 = uv[faces[:, 1]] - uv[faces[:, 0]]
    e2 = uv[faces[:, 2]] - uv[faces[:, 0]]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    theta = dihedral_angles(x, h)
    a_pair = area[pair[:, 0]] + area[pair[:, 1]]
    length2 = np.sum((uv[h[:, 0]] - uv[h[:, 1]]) ** 2, axis=1)
    energy = np.sum(length2 * theta ** 2 / (8.0 * a_pair))
    return energy / (kappa ** 2 / 2 * area.sum())


def test_arcsim_hinges_store_a_quarter_of_ke():
    """On clothtool's grid and on an equilateral mesh (60 cells a side; the missing boundary
    hinges take 1–3 %) a rolled sheet stores (k_e/4) κ²/2 per area: k_e excludes the 1/4."""
    uv, faces, _ = strip(0.6, 0.6, 0.01, "grid", clamp=False)
    assert arcsim_hinge_rigidity(uv, faces) == pytest.approx(0.25, rel=0.03)
    from scipy.spatial import Delaunay

    n, h = 60, 0.01
    j, i = np.mgrid[0:n, 0:n]
    pts = np.stack([(i + 0.5 * (j % 2)) * h, j * h * math.sqrt(3) / 2], axis=-1).reshape(-1, 2)
    assert arcsim_hinge_rigidity(pts, Delaunay(pts).simplices.astype(np.int64)) == \
        pytest.approx(0.25, rel=0.03)


def test_a_preset_config_runs(tmp_path):
    from clothtool.sim.api import simulate

    result = simulate({"mesh": {"grid": {"nx": 8, "ny": 8, "width": 0.3, "height": 0.3}},
                       "material": {"preset": "11oz-black-denim"},
                       "scene": {"pins": ["top_corners"]}, "time": {"frames": 3}},
                      output_dir=tmp_path / "out", progress=False)
    assert len(list((tmp_path / "out").glob("frame_*.ply"))) == 4
    assert result is not None


# ---------------------------------------------------------------------------- lab units


def test_kumari_khurana_bending_rigidity():
    """B 0.144 and 0.227 gf·cm²/cm: × 9.80665e-3 N × 1e-2 m = 1.412e-5 and 2.226e-5 N·m."""
    assert material(kes={"B": 0.144}).bend == pytest.approx(1.41216e-5, rel=1e-5)
    assert material(kes={"B": 0.227}).bend == pytest.approx(2.22611e-5, rel=1e-5)


def test_kes_values_by_hand():
    """G 1 gf/(cm·deg) = 0.980665 N/m per (π/180) rad = 56.1879 N/m; EMT 5 % at 500 gf/cm
    (490.3325 N/m): 9806.65 N/m; W 25 mg/cm² = 0.25 kg/m²; B warp 0.16, weft 0.25 gf·cm²/cm:
    1.56906e-5 and 2.45166e-5 N·m."""
    m = material(kes={"G": 1.0, "EMT": [5.0, 10.0], "W": 25, "B": [0.16, 0.25]})
    assert m.shear == pytest.approx(56.1879, rel=1e-5)
    assert m.stretch == pytest.approx((9806.65, 4903.325), rel=1e-9)
    assert m.density == pytest.approx(0.25, rel=1e-12)
    assert m.bend == pytest.approx((1.569064e-5, 2.4516625e-5), rel=1e-9)


def test_bending_length_in_the_labs_units():
    """ASTM D1388: G = W c³ in mg·cm with W in mg/cm²: B 0.1 gf·cm²/cm = 100 mg·cm and
    W 20 mg/cm² give c = 5^(1/3) = 1.70998 cm (g 9.81 against the gram-force's 9.80665:
    0.01 % apart)."""
    lab = lab_units.to_lab(material(kes={"B": [0.1, 0.8], "W": 20}))
    assert lab["bending length"] == pytest.approx((5 ** (1 / 3), 40 ** (1 / 3)), rel=2e-4)
    assert lab["W"] == pytest.approx(20) and lab["grams per m2"] == pytest.approx(200)


@settings(max_examples=50, deadline=None)
@given(b=st.floats(0.01, 2.0), g=st.floats(0.05, 5.0), emt=st.floats(0.5, 60.0),
       w=st.floats(5.0, 80.0))
def test_kes_in_and_out_agree(b, g, emt, w):
    lab = lab_units.to_lab(material(kes={"B": b, "G": g, "EMT": emt, "W": w}))
    assert lab["B"] == pytest.approx((b, b), rel=1e-12) and lab["G"] == pytest.approx(g, rel=1e-12)
    assert lab["W"] == pytest.approx(w, rel=1e-12)
    assert lab["EMT"] == pytest.approx((emt, emt), rel=1e-12)


def test_kes_and_the_key_it_fills_not_both():
    with pytest.raises(InputError, match="one of bend and kes.B"):
        material(kes={"B": 0.2}, bend=1e-5)
    with pytest.raises(InputError, match="bending_length"):
        material(kes={"B": 0.2}, bending_length=0.02)


def test_fabric_command_prints_a_block_that_loads(tmp_path):
    import yaml

    out = CliRunner().invoke(main, ["fabric", "--kes", "B=0.16,0.25", "--kes", "W=38",
                                    "--kes", "G=0.9", "--kes", "EMT=4.1,7.5"])
    assert out.exit_code == 0, out.output
    block = yaml.safe_load(out.output)["material"]
    assert block["density"] == pytest.approx(0.38)
    assert block["bend"] == pytest.approx((0.16 * 9.80665e-5, 0.25 * 9.80665e-5), rel=1e-5)
    assert "B 0.16 / 0.25 gf·cm²/cm" in out.output
    listed = CliRunner().invoke(main, ["fabric", "--list"])
    assert listed.exit_code == 0 and len(listed.output.splitlines()) == len(fabrics.PRESETS)


@pytest.mark.parametrize("args, words", [
    (["--kes", "B=-0.1"], "material.kes.B must be > 0"),
    (["--kes", "B"], "--kes 'B': expected NAME=VALUE"),
    (["--set", "material.kes.W=null"], "material.kes.W: missing value"),
    (["--preset", "denim"], "unknown fabric 'denim'"),
])
def test_fabric_command_bad_input(args, words):
    out = CliRunner().invoke(main, ["fabric", *args])
    assert out.exit_code == 2
    assert words in out.output and len(out.output.strip().splitlines()) == 1


def plate_of(material, materials=None):
    from clothtool.sim.energies.terms import PlateBending
    from clothtool.sim.model.builder import build_model

    config = load_config({"mesh": {"grid": {"nx": 6, "ny": 5, "width": 0.1, "height": 0.08}},
                          "material": material, "materials": materials or {}})
    return next(t for t in build_model(config).terms if isinstance(t, PlateBending)).plate


def test_a_panels_one_number_keeps_the_materials_warp_weft_ratio():
    """material.bend [4e-5, 1e-5] (ratio 4, √ = 2e-5) and a panel over every triangle with
    bend 1e-5: the panel is [2e-5, 0.5e-5], the plate half the material's."""
    every = {"all": {"faces": list(range(40)), "bend": 1e-5}}
    whole = plate_of({"bend": [4e-5, 1e-5]})
    panel = plate_of({"bend": [4e-5, 1e-5]}, every)
    assert np.array_equal(whole[1], panel[1])
    np.testing.assert_allclose(panel[2], 0.5 * whole[2], rtol=1e-12)
    with pytest.raises(InputError, match="warp/weft ratio of material.bend"):
        plate_of({"bend": [4e-5, 1e-5]}, {"all": {"faces": [0], "bend": [1e-5, 1e-5]}})
    with pytest.raises(InputError, match="warp and weft both > 0"):
        plate_of({"bend": [4e-5, 0.0]})


# ---------------------------------------------------------------------------- drape fit


def test_next_round_interpolates_in_log_c():
    """Runs at c = 1 and 4 cm drape 0.4 and 0.8: the target 0.6 is halfway, at log c = log 2;
    the round is 2 cm and 2 cm · 4^(±1/6)."""
    from clothtool.sweeps.drape_fit import _next_round

    values = _next_round([(0.04, 0.8), (0.01, 0.4)], 0.6)
    assert values == pytest.approx([0.02 * 4 ** (-1 / 6), 0.02, 0.02 * 4 ** (1 / 6)], rel=1e-12)
    with pytest.raises(InputError, match="target is outside"):
        _next_round([(0.01, 0.4), (0.04, 0.8)], 0.9)


@pytest.mark.parametrize("target", [0.35, 0.55, 0.75])
def test_fit_drape_converges_on_a_known_curve(tmp_path, monkeypatch, target):
    """With the sweeps replaced by a known drape curve d(c) = 1/(1 + (2 cm/c)^1.5) (d rises with
    c), the fit lands within 0.5 points of the target in at most 10 runs."""
    import clothtool.sweeps
    from clothtool.sweeps import drape_fit

    ran = []

    def fake_sweep(base, folder, *, grid, **_):
        ran.extend(grid["material.bending_length"])
        folder.mkdir(parents=True)
        (folder / "values").write_text(json.dumps(grid["material.bending_length"]))
        return clothtool.sweeps.SweepResult(folder, 0, 0, 0)

    def curve(folder):
        return [(c, 1.0 / (1.0 + (0.02 / c) ** 1.5)) for c in json.loads((folder / "values").read_text())]

    monkeypatch.setattr(clothtool.sweeps, "sweep", fake_sweep)
    monkeypatch.setattr(drape_fit, "_coefficients", curve)
    monkeypatch.setattr(drape_fit, "_discretisation_error", lambda material, fit: 0.004)
    fit = drape_fit.fit_drape(material(), target, tmp_path)
    assert abs(fit.coefficient - target) <= 0.005 and len(ran) <= 10
    assert fit.bend == pytest.approx(0.2 * 9.81 * fit.bending_length ** 3)
    text = lab_sheet.fit_report(material(), fit)
    assert f"{100 * fit.coefficient:.1f} % ± 0.4 (simulated on a 10 mm grid disc" in text
    assert "the change from a 14 mm disc" in text
    config = load_config(tmp_path / "cusick.yaml")
    assert config.material.damping == 0.05 and len(config.scene.pins) > 0


def test_fit_drape_refuses_a_coefficient_outside_0_100():
    out = CliRunner().invoke(main, ["fabric", "--fit-drape", "100", "-o", "x"])
    assert out.exit_code == 2 and "between 0 and 100" in out.output
    assert len(out.output.strip().splitlines()) == 1


def test_fit_drape_waits_for_slurm_and_goes_on_from_the_runs_on_disk(tmp_path, monkeypatch):
    """A round left to Slurm returns its sbatch command; the same call once the array has
    ended (its runs on disk) goes on to the next round."""
    import clothtool.sweeps
    from clothtool.sweeps import drape_fit

    finished = set()

    def fake_sweep(base, folder, *, grid, slurm, **_):
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "values").write_text(json.dumps(grid["material.bending_length"]))
        result = clothtool.sweeps.SweepResult(folder, 0, 0, 0)
        if slurm and folder.name not in finished:
            result.sbatch = f"sbatch {folder}/sweep.sbatch"
        return result

    def curve(folder):
        return [(c, 1.0 / (1.0 + (0.02 / c) ** 1.5)) for c in json.loads((folder / "values").read_text())]

    monkeypatch.setattr(clothtool.sweeps, "sweep", fake_sweep)
    monkeypatch.setattr(drape_fit, "_coefficients", curve)
    monkeypatch.setattr(drape_fit, "_discretisation_error", lambda material, fit: 0.004)
    first = drape_fit.fit_drape(material(), 0.6, tmp_path, slurm=True)
    assert first.sbatch.endswith("round_1/sweep.sbatch") and first.bend is None
    assert "rerun this command" in lab_sheet.fit_report(material(), first)
    finished.add("round_1")
    second = drape_fit.fit_drape(material(), 0.6, tmp_path, slurm=True)
    assert second.sbatch.endswith("round_2/sweep.sbatch") and len(second.runs) == 4


@pytest.mark.parametrize("direction", ["warp", "weft"])
def test_a_presets_simulated_cantilever_shows_its_own_bending_length(direction):
    """11oz denim: c = (B/(ρg))^(1/3) = 1.968 cm along warp (u), 1.716 cm along weft (v); the
    simulated cantilever, read through the elastica, within 1 % (the benchmark: +0.16, +0.21)."""
    from clothtool.sim.textile import cantilever_bending_length

    b = dict(zip(("warp", "weft"), (24.237894e-6, 16.049114e-6)))[direction]
    c = cantilever_bending_length({"preset": "11oz-black-denim"}, direction)
    assert c == pytest.approx((b / (0.324 * 9.81)) ** (1 / 3), rel=0.01)


def test_cusick_drape_of_a_stiff_and_a_limp_disc():
    """The swimsuit knit's membrane on a 2 cm disc: with a bending length of 1 m it hardly
    droops past its 18 cm pedestal (coefficient near 1); with 5 mm it hangs (well below)."""
    from clothtool.sim.textile import cusick_drape

    base = {"preset": "white-swim-solid", "damping": 0.05}
    stiff = cusick_drape({**base, "bending_length": 1.0}, 0.02, seconds=2.0)[0]
    limp = cusick_drape({**base, "bending_length": 0.005}, 0.02, seconds=2.0)[0]
    assert stiff > 0.97 and limp < 0.6


def test_a_simulated_drape_reports_its_mesh_size_and_discretisation_error(monkeypatch):
    """On a known second-order curve d(h) = 0.7 − 20 h², the error at 10 mm (0.2 points) is the
    change from a disc √2 coarser; the report names the mesh and that disc."""
    from clothtool.sim import textile

    calls = []

    def curve(material, spacing, kind="grid", **_):
        calls.append((spacing, kind))
        return 0.7 - 20.0 * spacing ** 2, None, None

    monkeypatch.setattr(textile, "cusick_drape", curve)
    drape = lab_sheet.simulated_drape(material())
    assert drape.coefficient == pytest.approx(0.698) and drape.error == pytest.approx(0.002)
    assert [s for s, _ in calls] == pytest.approx([0.01, 0.01 * 2 ** 0.5])
    line = next(t for t in lab_sheet.report(material(), drape).splitlines() if "Cusick" in t)
    assert "69.8 % ± 0.2 (simulated on a 10 mm grid disc; ± its discretisation error, the " \
           "change from a 14 mm disc;" in line
