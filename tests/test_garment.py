"""Garments: rest shapes per corner, per-panel materials, seams and the weld, attach.

Known answers: a welded garment whose panels' patterns differ across the seam rests at its
patterns (stretch 1 on both sides); two strips of 10× different stretch stiffness hanging
under their own weight lengthen by ρgL²/(2k), 10× apart; the stitch term's gradient and
Hessian are finite-difference checked; sewn seams close and weld; attached vertices follow
their collider exactly; every bad input is one line naming the file and the item.
"""

import re

import h5py
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

import clothtool
from clothtool.errors import InputError
from clothtool.io.ply import read_ply
from clothtool.sim.model.builder import ModelBuilder, build_model
from clothtool.sim.model.config import load_config
from clothtool.sim.solve.statics import static_equilibrium
from clothtool.sim.energies.terms import Stitch, stitch_energy

from garment_meshes import apart_pair, panel, welded_pair, write_obj


def welded_obj(tmp_path, **kw):
    x, lf, rf, luv, ruv, seam = welded_pair(**kw)
    return write_obj(tmp_path / "garment.obj", x, [("left", lf, luv), ("right", rf, ruv)]), seam, x


def test_obj_without_uv_is_an_error_naming_the_file(tmp_path):
    uv, faces = panel(3, 3, 1.0, 1.0)
    path = tmp_path / "bare.obj"
    path.write_text("".join(f"v {u} {v} 0\n" for u, v in uv)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))
    with pytest.raises(InputError, match=r"bare\.obj: mesh\.obj has no texture coordinates"):
        build_model(load_config({"mesh": {"obj": str(path)}}))


def test_each_triangle_rests_at_its_own_corners_uv(tmp_path):
    """D_r⁻¹ of every triangle inverts its corners' uv × uv_scale, on both sides of a uv seam."""
    path, _, _ = welded_obj(tmp_path)
    model = build_model(load_config({"mesh": {"obj": str(path), "uv_scale": 2.0}}))
    corner = model.mesh.corner_uv
    assert np.allclose(corner, 2.0 * _read_corner_uv(path))
    dr = np.stack([corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0]], axis=2)
    assert np.allclose(np.einsum("mij,mjk->mik", dr, model.dr_inv), np.eye(2))
    assert np.isclose(model.area.sum(), 4.0 * 2 * 0.2 * 0.3)  # two 0.2 × 0.3 panels, (2×)²


def _read_corner_uv(path):
    from clothtool.io.obj import read_obj

    return read_obj(path).corner_uv


def hanging_config(path, top, frames=20, **extra):
    cfg = {"mesh": {"obj": str(path)},
           "material": {"damping": 0.05},
           "scene": {"pins": [int(v) for v in top]},
           "time": {"fps": 30, "frames": frames}, "output": {"every": frames}}
    for key, value in extra.items():
        cfg.setdefault(key, {}).update(value)
    return cfg


def test_welded_garment_hangs_at_its_patterns_across_a_uv_seam(tmp_path):
    """The right panel's pattern is shifted and turned a quarter against the left's across
    their shared seam vertices; hanging loose, analyze --reference uv measures the result
    against the patterns: median stretch 1.00 ± 0.01 on both sides (a rest shape per vertex
    could not hold both: the seam triangles would be stretched by metres)."""
    path, _, x = welded_obj(tmp_path)
    top = np.flatnonzero(np.isclose(x[:, 1], x[:, 1].max()))
    out = tmp_path / "out"
    clothtool.simulate(hanging_config(path, top), output_dir=out, progress=False)
    clothtool.analyze_sequence(out, tmp_path / "a.h5", reference="uv")
    with h5py.File(tmp_path / "a.h5") as f:
        stretch = f["face/stretch"][-1]  # the last frame, (M, 2)
    m = len(stretch) // 2  # left triangles first, then right (the OBJ's order)
    for side in (stretch[:m], stretch[m:]):
        assert abs(np.median(side[:, 0]) - 1.0) <= 0.01
        assert abs(np.median(side[:, 1]) - 1.0) <= 0.01
    frame = read_ply(out / "frame_00020.ply")
    assert frame.corner_uv is not None and np.allclose(frame.corner_uv, _read_corner_uv(path))


# ---------------------------------------------------------------------------- materials


def strips_obj(tmp_path, length=0.5, width=0.05, ny=11):
    """Two separate vertical strips, u across and v down the length, groups left and right."""
    uv, faces = panel(2, ny, width, length)
    n = len(uv)
    x = np.concatenate([np.column_stack([uv[:, 0] - 0.2, uv[:, 1], np.zeros(n)]),
                        np.column_stack([uv[:, 0] + 0.2, uv[:, 1], np.zeros(n)])])
    path = write_obj(tmp_path / "strips.obj", x,
                     [("left", faces, uv[faces]), ("right", faces + n, uv[faces])])
    return path, np.flatnonzero(np.isclose(x[:, 1], length))


def test_panels_with_ten_times_the_stretch_stiffness_strain_ten_times_less(tmp_path):
    """A strip hanging under its own weight lengthens by ρgL²/(2k) (ρ areal density, k the
    stretch stiffness along it): with materials by OBJ group, k = 100 and 1000 N/m, the two
    lengthen 10× apart (within 10 %) and each as the closed form says (within 10 %)."""
    path, top = strips_obj(tmp_path)
    cfg = hanging_config(path, top, material={"stretch": 100.0, "shear": 0.0, "bend": 0.0,
                                              "density": 0.2},
                         materials={"right": {"stretch": 1000.0}})
    model = build_model(load_config(cfg))
    x = static_equilibrium(model)
    n = len(x) // 2
    drop = [model.mesh.positions[:n, 1].min() - x[:n, 1].min(),
            model.mesh.positions[n:, 1].min() - x[n:, 1].min()]
    expected = [0.2 * 9.81 * 0.5 ** 2 / (2 * k) for k in (100.0, 1000.0)]
    assert np.allclose(drop, expected, rtol=0.1)
    assert abs(drop[0] / drop[1] / 10.0 - 1.0) <= 0.1
    assert np.allclose(model.tri_stretch[:len(model.faces) // 2, 0], 100.0)
    assert np.allclose(model.tri_stretch[len(model.faces) // 2:, 0], 1000.0)


def test_panel_densities_set_the_lumped_masses(tmp_path):
    path, top = strips_obj(tmp_path)
    cfg = hanging_config(path, top, materials={"heavy": {"faces": [0, 1], "density": 2.0}})
    model = build_model(load_config(cfg))
    light = build_model(load_config(hanging_config(path, top)))
    area01 = model.area[:2].sum()
    assert np.isclose(model.mass.sum() - light.mass.sum(), (2.0 - 0.2) * area01)


def test_panel_damping_is_each_panels_beta_times_its_stiffness(tmp_path):
    """Per-panel damping, frozen D = (1/ĥ) Σ_e β_e K_e: on two separate strips (β 0.01 and
    0.1 s) the β-scaled terms assemble to β times each strip's stiffness blocks, at a deformed
    state (bending on: the hinges' blocks too); with the strain dissipation
    (``damping_model: strain``), each triangle's and hinge's coefficients carry their strip's β."""
    from clothtool.sim.energies.energy import FemElastic

    path, top = strips_obj(tmp_path)
    strain = hanging_config(path, top, material={"damping": 0.01, "bend": 1e-3,
                                                 "damping_model": "strain"},
                            materials={"right": {"damping": 0.1}})
    model = build_model(load_config(strain))
    tri_beta = model.strain_damping[:, 2] / model.tri_shear
    assert sorted(set(np.round(tri_beta, 12))) == [0.01, 0.1]
    np.testing.assert_allclose(model.strain_damping[:, :2], tri_beta[:, None] * model.tri_stretch[:, :2])
    hinge_beta = model.bend_damping / model.hinge_coef
    assert sorted(set(np.round(hinge_beta, 12))) == [0.01, 0.1]
    assert model.damping_terms is None
    cfg = hanging_config(path, top, material={"damping": 0.01, "bend": 1e-3, "damping_model": "frozen"},
                         materials={"right": {"damping": 0.1}})
    model = build_model(load_config(cfg))
    assert model.damping == 0.1
    rng = np.random.default_rng(3)
    x = model.mesh.positions * [1.1, 1.05, 1.0] + rng.normal(scale=1e-3, size=(model.n_vertices, 3))
    n = model.n_vertices
    k, d = model.pattern.zeros(), model.pattern.zeros()
    FemElastic(model).assemble(x, np.zeros((n, 3)), k)
    FemElastic(model, model.damping_terms, model.damping_constant).assemble(x, np.zeros((n, 3)), d)
    row = np.repeat(np.arange(n), np.diff(model.pattern.row_ptr))
    beta = np.where(row < n // 2, 0.01, 0.1)
    assert np.abs(k).max() > 0
    assert np.allclose(d, beta[:, None, None] * k, rtol=1e-12, atol=1e-12 * np.abs(k).max())
    out = tmp_path / "out"
    clothtool.simulate({**cfg, "time": {"fps": 30, "frames": 3}}, output_dir=out, progress=False)
    vbd = {**cfg, "solver": {"method": "vbd"}}
    with pytest.raises(InputError, match=r"'vbd' does not support materials\.right\.damping"):
        load_config(vbd)


@pytest.mark.parametrize("materials, message", [
    ({"sleeve": {"stretch": 10.0}}, r"materials\.sleeve: .*strips\.obj has no group .*'sleeve'"),
    ({"lft": {"stretch": 10.0}}, r"did you mean 'left'"),
    ({"p": {"faces": [0, 999]}}, r"materials\.p\.faces\[1\]: triangle 999 out of range"),
    ({"left": {"colour": 1}}, r"unknown key 'materials\.left\.colour'"),
])
def test_bad_materials_name_the_key(tmp_path, materials, message):
    path, top = strips_obj(tmp_path)
    with pytest.raises(InputError, match=message):
        build_model(load_config(hanging_config(path, top, materials=materials)))


# ---------------------------------------------------------------------------- the stitch term


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_stitch_gradient_and_hessian_match_finite_differences(seed):
    """∇W and the (constant) Hessian of W = ½ Σ k‖x_a − x_b‖² against central differences;
    the Hessian is PSD."""
    from clothtool.sim.linalg.blocks import BlockMatrix, BlockPattern

    rng = np.random.default_rng(seed)
    n = 6
    pairs = np.array([[0, 3], [1, 4], [2, 5], [0, 5]])
    k = rng.uniform(0.1, 10.0, len(pairs))
    x = rng.normal(size=(n, 3))
    term = Stitch(pairs, k)
    pattern = BlockPattern(n, pairs)
    term.bind(pattern)
    values = pattern.zeros()
    term.constant(pattern, values)
    grad = np.zeros((n, 3))
    energy = term.assemble(x, grad, values)
    assert np.isclose(energy, term.energy(x))
    eps = 1e-6
    fd = np.zeros((n, 3))
    for i in range(n):
        for p in range(3):
            d = np.zeros((n, 3))
            d[i, p] = eps
            fd[i, p] = (term.energy(x + d) - term.energy(x - d)) / (2 * eps)
    assert np.allclose(grad, fd, rtol=1e-6, atol=1e-8)
    dense = BlockMatrix(pattern)
    dense.values[:] = values
    h = dense.to_scipy().toarray()
    cols = []
    for i in range(n):
        for p in range(3):
            d = np.zeros((n, 3))
            d[i, p] = eps
            gp, gm = np.zeros((n, 3)), np.zeros((n, 3))
            stitch_energy(x + d, pairs, k, gp)
            stitch_energy(x - d, pairs, k, gm)
            cols.append(((gp - gm) / (2 * eps)).ravel())
    assert np.allclose(h, np.array(cols).T, rtol=1e-6, atol=1e-6)
    assert np.linalg.eigvalsh(h).min() >= -1e-9


# ---------------------------------------------------------------------------- seams


def apart_obj(tmp_path, **kw):
    x, lf, rf, luv, ruv, a, b = apart_pair(**kw)
    return write_obj(tmp_path / "panels.obj", x, [("left", lf, luv), ("right", rf, ruv)]), a, b, x


def sewing_config(path, a, b, frames=30, **extra):
    cfg = {"mesh": {"obj": str(path), "seams": [{"a": [int(v) for v in a],
                                                 "b": [int(v) for v in b]}]},
           "material": {"damping": 0.05},
           "scene": {"gravity": [0, 0, 0], "self_collision": {"thickness": 0.002}},
           "time": {"fps": 30, "frames": frames}}
    for key, value in extra.items():
        cfg.setdefault(key, {}).update(value)
    return cfg


def test_two_panels_sew_and_weld_closed(tmp_path):
    """Two panels 2 cm apart, sewn along their facing edges: the stitches pull the seam closed
    through the contact barrier (no crossing frame is written), the pairs are welded (0 m apart
    from then on) and the sewn garment rests at its patterns (stretch within 1 %)."""
    path, a, b, x0 = apart_obj(tmp_path)
    out = tmp_path / "out"
    result = clothtool.simulate(sewing_config(path, a, b), output_dir=out, progress=False)
    last = read_ply(out / f"frame_{result.frames_written - 1:05d}.ply")
    assert last.vertices.shape == x0.shape  # the file's vertices, welded ones at one position
    gap = np.linalg.norm(last.vertices[a] - last.vertices[b], axis=1)
    assert gap.max() <= 1e-3
    assert gap.max() == 0.0  # welded
    gaps = [np.linalg.norm(read_ply(out / f"frame_{k:05d}.ply").vertices[a]
                           - read_ply(out / f"frame_{k:05d}.ply").vertices[b], axis=1).max()
            for k in (0, 5)]
    assert gaps[0] == pytest.approx(0.02) and gaps[1] < gaps[0]
    clothtool.analyze_sequence(out, tmp_path / "a.h5", reference="uv")
    with h5py.File(tmp_path / "a.h5") as f:
        stretch = f["face/stretch"][-1]
    assert np.abs(np.median(stretch, axis=0) - 1.0).max() <= 0.01


def test_welded_garment_is_one_surface(tmp_path):
    """After the weld the Model has one vertex per sewn pair, hinges across the seam and no
    stitches; each triangle keeps its own rest shape."""
    path, a, b, x0 = apart_obj(tmp_path)
    config = load_config(sewing_config(path, a, b))
    builder = ModelBuilder.from_config(config)
    model = builder.finalize()
    state = model.initial_state()
    state.x[b] = state.x[a]  # as sewn
    welded_builder, state = builder.welded(model, state)
    welded = welded_builder.finalize()
    assert welded.n_vertices == len(x0) - len(a)
    assert welded.stitches is None and model.stitches is not None
    assert len(welded.hinge) == len(model.hinge) + len(a) - 1
    assert np.array_equal(welded.dr_inv, model.dr_inv)
    assert np.array_equal(welded.file_vertex[a], welded.file_vertex[b])


@pytest.mark.parametrize("change, message", [
    (lambda a, b: (a, b[::-1]), r"panels\.obj: mesh\.seams\[0\]: a and b run the same way"),
    (lambda a, b: (a, b[:-1].tolist() + [9999]), r"mesh\.seams\[0\]\.b\[6\]: vertex 9999 out of "
                                                 r"range"),
    (lambda a, b: (a[:-1], b[1:]), None),  # fine: a shorter seam
    (lambda a, b: (a, np.r_[b[:1], b[2:], b[-1] - 1]), r"mesh\.seams\[0\]\.b: vertices"),
])
def test_bad_seams_are_one_line_errors(tmp_path, change, message):
    path, a, b, _ = apart_obj(tmp_path)
    a2, b2 = change(a, b)
    cfg = sewing_config(path, a2, b2)
    if message is None:
        build_model(load_config(cfg))
        return
    with pytest.raises(InputError, match=message) as err:
        build_model(load_config(cfg))
    assert "\n" not in str(err.value)


def test_a_bad_seam_writes_nothing(tmp_path):
    """An error found while the model is built stops the run before any file is written."""
    path, a, b, _ = apart_obj(tmp_path)
    out = tmp_path / "out"
    with pytest.raises(InputError, match=r"run the same way"):
        clothtool.simulate(sewing_config(path, a, b[::-1]), output_dir=out, progress=False)
    assert not out.exists()


def test_a_ply_with_texcoord_rests_per_corner(tmp_path):
    """A PLY's face texcoord list (u v per corner) is the rest shape, as an OBJ's vt."""
    from clothtool.io.ply import write_ply

    x, lf, rf, luv, ruv, _ = welded_pair()
    faces = np.concatenate([lf, rf])
    corner = np.concatenate([luv, ruv])
    write_ply(tmp_path / "g.ply", x, faces, face_properties={"texcoord": corner.reshape(-1, 6)})
    model = build_model(load_config({"mesh": {"ply": str(tmp_path / "g.ply")}}))
    assert np.allclose(model.mesh.corner_uv, corner)
    dr = np.stack([corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0]], axis=2)
    assert np.allclose(np.einsum("mij,mjk->mik", dr, model.dr_inv), np.eye(2))


def test_seam_sides_of_different_lengths_are_refused(tmp_path):
    """The right panel's pattern 10 % taller than the left's: its seam side is 10 % longer,
    beyond mesh.seam_tolerance 0.02 (and accepted with a tolerance of 0.2)."""
    x, lf, rf, luv, ruv, a, b = apart_pair()
    path = write_obj(tmp_path / "panels.obj", x,
                     [("left", lf, luv), ("right", rf, ruv * [1.0, 1.1])])
    with pytest.raises(InputError, match=r"panels\.obj: mesh\.seams\[0\]: side a is 0\.3 m long "
                                         r"and b 0\.33 m"):
        build_model(load_config(sewing_config(path, a, b)))
    build_model(load_config(sewing_config(path, a, b, mesh={"seam_tolerance": 0.2})))


def test_overlapping_panels_are_refused(tmp_path):
    """The right panel turned upright through the left one: the panels cross at the start."""
    x, lf, rf, luv, ruv, a, b = apart_pair()
    n = len(x) // 2
    x[n:] = np.column_stack([np.full(n, -0.1), x[n:, 1], x[n:, 0] - 0.1])
    path = write_obj(tmp_path / "panels.obj", x, [("left", lf, luv), ("right", rf, ruv)])
    with pytest.raises(InputError, match=r"panels\.obj: the panels overlap at the start"):
        build_model(load_config(sewing_config(path, a, b)))


def test_sewing_needs_self_collision(tmp_path):
    path, a, b, _ = apart_obj(tmp_path)
    cfg = sewing_config(path, a, b)
    del cfg["scene"]["self_collision"]
    with pytest.raises(InputError, match=r"mesh\.seams: sewing needs scene\.self_collision"):
        load_config(cfg)


def test_a_seam_that_does_not_close_in_time_stops_the_run(tmp_path):
    path, a, b, _ = apart_obj(tmp_path)
    cfg = sewing_config(path, a, b, frames=6, mesh={"sewing": {"stiffness": 1e-3, "time": 0.1}})
    with pytest.raises(clothtool.NumericalError, match=r"mesh\.seams did not close in "
                                                       r"mesh\.sewing\.time"):
        clothtool.simulate(cfg, output_dir=tmp_path / "out", progress=False)


# ---------------------------------------------------------------------------- attach


def test_attached_vertices_follow_a_moving_sphere_exactly(tmp_path):
    """A sheet's top row tied to a sphere translating at 0.3 m/s: every frame has those
    vertices at x₀ + u t (the sphere's motion of their initial positions)."""
    path, _, x = welded_obj(tmp_path)
    top = np.flatnonzero(np.isclose(x[:, 1], x[:, 1].max()))
    cfg = {"mesh": {"obj": str(path)},
           "scene": {"colliders": [{"sphere": {
               "center": [0.0, 0.45, 0.0], "radius": 0.14,
               "motion": {"translate": {"velocity": [0.3, 0, 0]}}}}],
                     "attach": {"vertices": [int(v) for v in top], "to": 0}},
           "time": {"fps": 30, "frames": 6}}
    out = tmp_path / "out"
    clothtool.simulate(cfg, output_dir=out, progress=False)
    for k in (3, 6):
        frame = read_ply(out / f"frame_{k:05d}.ply")
        assert np.allclose(frame.vertices[top], x[top] + [0.3 * k / 30, 0, 0], atol=1e-9)


def test_attach_follows_an_animated_mesh_in_its_triangle_frame():
    """Coordinates in the nearest triangle's frame (barycentric plus the offset along its
    normal): a mesh frame turned a quarter about z carries the point turned with it."""
    from types import SimpleNamespace

    from clothtool.sim.model.attach import attach_motions
    from clothtool.sim.model.colliders import Colliders

    tri = np.array([[0, 1, 2], [0, 2, 3]])
    square = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    frames = np.stack([square, square @ turn.T])
    colliders = Colliders(["scene.colliders[0].mesh"], [frames], [1.0], [None], np.array([0, 4]),
                          tri, np.zeros((0, 2), np.int64), np.zeros((0, 2), np.int64),
                          np.arange(4), np.zeros(4), np.zeros(4))
    x = np.array([[0.3, 0.2, 0.01], [-0.5, 0.6, 0.02]])
    entry = SimpleNamespace(vertices=(0, 1), to=0)
    (motion,) = attach_motions([entry], [np.array([0, 1])], colliders, x)
    assert np.allclose(motion.positions(None, 0.0), x)
    assert np.allclose(motion.positions(None, 1.0), x @ turn.T)


def test_attach_taking_hold_later_follows_the_rigid_motion_from_there():
    """Tied at t_w to a collider turning about z at 1 rad/s: at t_w the goal is where the
    vertex is, at t_w + 0.5 it is turned by 0.5 rad more."""
    from clothtool.sim.model.attach import attach_motions
    from clothtool.sim.model.colliders import load_colliders
    from clothtool.sim.model.config import load_config

    scene = load_config({"mesh": {"grid": {}}, "scene": {"colliders": [{"sphere": {
        "center": [0, 0, 0], "radius": 0.1, "motion": {"rotate": {"axis": [0, 0, 1],
                                                                  "speed": 1.0}}}}]}}).scene
    colliders = load_colliders(scene.colliders)
    x = np.array([[0.5, 0.0, 0.0], [0.0, 0.3, 0.2]])
    entry = type("E", (), {"to": 0})()
    (motion,) = attach_motions([entry], [np.array([0, 1])], colliders, x, t=0.7)
    assert np.allclose(motion.positions(None, 0.7), x)
    c, s = np.cos(0.5), np.sin(0.5)
    turned = x @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T
    assert np.allclose(motion.positions(None, 1.2), turned)


def test_a_sewn_garment_is_attached_at_its_weld(tmp_path):
    """Attachments of a garment being sewn take hold when it is welded: from then on the
    attached vertices move with the sphere (0.3 m/s along z), before it they are sewn freely."""
    path, a, b, x0 = apart_obj(tmp_path)
    top = [int(v) for v in np.flatnonzero(np.isclose(x0[:, 1], x0[:, 1].max()))]
    cfg = sewing_config(path, a, b, frames=12)
    cfg["scene"]["colliders"] = [{"sphere": {"center": [0, 0.15, -0.3], "radius": 0.1,
                                             "motion": {"translate": {"velocity": [0, 0, 0.3]}}}}]
    cfg["scene"]["attach"] = {"vertices": top, "to": 0}
    out = tmp_path / "out"
    clothtool.simulate(cfg, output_dir=out, progress=False)
    frames = [read_ply(out / f"frame_{k:05d}.ply").vertices for k in range(13)]
    weld = next(k for k, x in enumerate(frames) if np.array_equal(x[a], x[b]))
    assert 0 < weld < 12
    for k in range(weld + 1, 13):
        assert np.allclose(frames[k][top], frames[weld][top] + [0, 0, 0.3 * (k - weld) / 30],
                           atol=1e-9)


@pytest.mark.parametrize("attach, message", [
    ({"vertices": [0, 99999], "to": 0}, r"garment\.obj: scene\.attach\.vertices\[1\]: vertex "
                                        r"99999 out of range"),
    ({"vertices": [0], "to": 3}, r"scene\.attach\.to: collider 3 out of range"),
    ({"vertices": [0]}, r"scene\.attach needs 'to'"),
])
def test_bad_attach_names_the_item(tmp_path, attach, message):
    path, _, _ = welded_obj(tmp_path)
    cfg = {"mesh": {"obj": str(path)},
           "scene": {"colliders": [{"sphere": {"center": [0, 2, 0], "radius": 0.1}}],
                     "attach": attach}}
    with pytest.raises(InputError, match=message):
        build_model(load_config(cfg))


def seam_lines_obj(tmp_path, lines):
    """The apart pair as panels.obj with ``lines`` {group: vertex list} as ``l`` polylines."""
    path, a, b, x = apart_obj(tmp_path)
    with open(path, "a") as fh:
        for name, ids in lines.items():
            fh.write(f"g {name}\nl " + " ".join(str(int(v) + 1) for v in ids) + "\n")
    return path, a, b, x


def stitch_set(builder):
    return {tuple(p) for p in builder.stitches.tolist()}, np.sort(builder.stitch_stiffness)


@pytest.mark.parametrize("flip_a, flip_b", [(False, False), (True, False), (False, True)])
def test_a_seam_by_obj_groups_is_the_seam_by_vertex_lists(tmp_path, flip_a, flip_b):
    """Sides named by ``l`` groups, given in either direction, sew the same pairs with the same
    stiffness as the vertex lists: a runs along its panel's boundary, b against its own."""
    path, a, b, _ = apart_obj(tmp_path)
    path, a, b, _ = seam_lines_obj(tmp_path, {"right_edge": a[::-1] if flip_a else a,
                                              "left_edge": b[::-1] if flip_b else b})
    by_list = ModelBuilder.from_config(load_config(sewing_config(path, a, b)))
    cfg = sewing_config(path, a, b)
    cfg["mesh"]["seams"] = [{"a": "right_edge", "b": "left_edge"}]
    by_name = ModelBuilder.from_config(load_config(cfg))
    pairs, k = stitch_set(by_list)
    named_pairs, named_k = stitch_set(by_name)
    assert named_pairs == pairs and np.array_equal(named_k, k)


def test_line_groups_read_relative_and_slashed_indices(tmp_path):
    from clothtool.io.obj_groups import line_groups

    path = tmp_path / "l.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\ng one two\nl 1 2/1 -1\ng three\nl -2 -3\n")
    got = line_groups(path)
    assert got["one"].tolist() == [[0, 1], [1, 2]] and got["two"].tolist() == got["one"].tolist()
    assert got["three"].tolist() == [[1, 0]]
    path.write_text("v 0 0 0\nl 1 4\n")
    with pytest.raises(InputError, match=r"l\.obj:2: an l statement needs 2 or more vertices"):
        line_groups(path)


@pytest.mark.parametrize("seam, lines, message", [
    ({"a": "nowhere", "b": "left_edge"}, lambda a: [],
     r"panels\.obj: mesh\.seams\[0\]\.a: no group 'nowhere' in the OBJ \(its groups: left, "
     r"left_edge, right\)"),
    ({"a": "left", "b": "left_edge"}, lambda a: [],  # a face group: its boundary is its outline
     r"mesh\.seams\[0\]\.a: group 'left''s boundary edges are not one open polyline"),
    ({"a": "pieces", "b": "left_edge"}, lambda a: [("pieces", a[:2]), ("pieces", a[3:5])],
     r"mesh\.seams\[0\]\.a: group 'pieces''s boundary edges are not one open polyline"),
    ({"a": "across", "b": "left_edge"}, lambda a: [("across", [6, 7])],
     r"mesh\.seams\[0\]\.a: group 'across': vertices 6 and 7 are not a boundary edge"),
    ({"a": "short", "b": "left_edge"}, lambda a: [("short", a[:-1])],
     r"mesh\.seams\[0\]: a has 6 vertices and b 7; a\[i\] is sewn to b\[i\]"),
])
def test_bad_group_seams_are_one_line_errors(tmp_path, seam, lines, message):
    path, a, b, _ = seam_lines_obj(tmp_path, {"left_edge": apart_pair()[-1]})
    with open(path, "a") as fh:
        for name, ids in lines(a):
            fh.write(f"g {name}\nl " + " ".join(str(int(v) + 1) for v in ids) + "\n")
    cfg = sewing_config(path, a, b)
    cfg["mesh"]["seams"] = [seam]
    with pytest.raises(InputError, match=message) as err:
        build_model(load_config(cfg))
    assert "\n" not in str(err.value)


BAD_INPUTS = {  # each bad-input case of a garment run: (config change, the error's words)
    "lengths": ("seam_tolerance", r"panels\.obj: mesh\.seams\[0\]: side a is .* m long"),
    "orientation": ("reverse_b", r"panels\.obj: mesh\.seams\[0\]: a and b run the same way"),
    "seam vertex": ("seam_vertex", r"panels\.obj: mesh\.seams\[0\]\.b\[0\]: vertex 9999 out of"),
    "attach vertex": ("attach_vertex",
                      r"panels\.obj: scene\.attach\.vertices\[0\]: vertex 9999 out of range"),
    "no uv": ("no_uv", r"bare\.obj: mesh\.obj has no texture coordinates"),
    "overlap": ("overlap", r"panels\.obj: the panels overlap at the start"),
    "group": ("group", r"panels\.obj: mesh\.seams\[0\]\.a: no group 'nowhere'"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_each_bad_garment_input_is_one_line_exit_2_and_writes_nothing(tmp_path, case):
    from click.testing import CliRunner

    from clothtool.cli import main

    change, message = BAD_INPUTS[case]
    x, lf, rf, luv, ruv, a, b = apart_pair()
    if change == "seam_tolerance":
        ruv = ruv * [1.0, 1.1]
    if change == "overlap":
        n = len(x) // 2
        x[n:] = np.column_stack([np.full(n, -0.1), x[n:, 1], x[n:, 0] - 0.1])
    path = write_obj(tmp_path / "panels.obj", x, [("left", lf, luv), ("right", rf, ruv)])
    cfg = sewing_config(path, a, b[::-1] if change == "reverse_b" else b)
    if change == "seam_vertex":
        cfg["mesh"]["seams"][0]["b"][0] = 9999
    if change == "attach_vertex":
        cfg["scene"]["colliders"] = [{"sphere": {"center": [0, 2, 0], "radius": 0.1}}]
        cfg["scene"]["attach"] = {"vertices": [9999], "to": 0}
    if change == "group":
        cfg["mesh"]["seams"] = [{"a": "nowhere", "b": "right"}]
    if change == "no_uv":
        bare = tmp_path / "bare.obj"
        bare.write_text("".join(f"v {p} {q} {r}\n" for p, q, r in x) + "".join(
            f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in np.concatenate([lf, rf])))
        cfg["mesh"]["obj"] = str(bare)
    (tmp_path / "run.yaml").write_text(yaml.safe_dump(cfg))
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["simulate", str(tmp_path / "run.yaml"), "-o", str(out)])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and re.search(message, lines[0]), result.output
    assert not out.exists()
