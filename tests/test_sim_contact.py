"""Contact in the simulator: moving pins, mesh colliders, self-collision (issue 12).

Every frame of the small scenes is checked with ipctk.has_intersections (the IPC
authors' exact-enough test) and with our exact test, and stats.csv's min_separation
stays positive.
"""

import csv
import re
import textwrap

import ipctk
import numpy as np
import pytest
from click.testing import CliRunner

from clothtool.cli import main
from clothtool.contact.broadphase import mesh_edges
from clothtool.contact.intersect import has_intersections
from clothtool.contact.shapes import box, capsule, plate
from clothtool.errors import InputError
from clothtool.io.ply import read_ply, write_ply
from clothtool.sim.api import simulate
from clothtool.sim.model.config import GridSpec, load_config
from clothtool.sim.model.mesh import grid_mesh
from clothtool.sim.model.builder import build_model
from clothtool.sim.model.motion import resolve_pin_entries
from clothtool.sim.model.colliders import load_colliders

SOLVER = {"newton_iterations": 8, "newton_tolerance": 2e-2, "tolerance": 1e-2}


def run(tmp_path, scene, mesh=None, frames=20, fps=60, material=None, name="out", solver=None):
    config = {"mesh": mesh or {"grid": {"nx": 12, "ny": 12, "width": 0.6, "height": 0.6,
                                         "plane": "xz"}},
              "material": {"stretch": 1000.0, "shear": 100.0, "bend": 1e-5, **(material or {})},
              "scene": scene, "solver": {**SOLVER, **(solver or {})},
              "time": {"fps": fps, "frames": frames},
              "output": {"dir": str(tmp_path / name)}}
    return simulate(config, progress=False), tmp_path / name


def frames_of(out):
    paths = sorted(out.glob("frame_*.ply"))
    return [read_ply(p).vertices for p in paths], read_ply(paths[0]).faces


def stats_of(out):
    with open(out / "stats.csv") as fh:
        return list(csv.DictReader(fh))


def assert_intersection_free(out, colliders=()):
    """Every frame: no crossing (ipctk and ours), positive min_separation in stats.csv."""
    xs, faces = frames_of(out)
    n = len(xs[0])
    cx = [c[0] for c in colliders]
    cf = [c[1] for c in colliders]
    all_faces = np.concatenate([faces] + [f + n + sum(len(y) for y in cx[:k])
                                          for k, f in enumerate(cf)]).astype(np.int64)
    obstacle = np.arange(n + sum(len(y) for y in cx)) >= n
    edges = mesh_edges(all_faces)
    for x in xs:
        y = np.concatenate([x] + cx)
        mesh = ipctk.CollisionMesh(y, edges, all_faces)
        assert not ipctk.has_intersections(mesh, y)
        assert not has_intersections(y, all_faces, obstacle)
    rows = stats_of(out)
    assert all(float(r["min_separation"]) > 0.0 for r in rows)
    return xs, rows


def write_mesh(path, shape):
    write_ply(path, *shape)
    return str(path)


# ---------------------------------------------------------------- config and pins


def test_moving_pin_groups_parse_and_move_rigidly():
    cfg = load_config({"mesh": {"grid": {"nx": 5, "ny": 5}}, "scene": {"pins": [
        24,
        {"vertices": "left_edge", "rotate": {"center": [0, 0, 0], "axis": [0, 0, 2],
                                              "speed": np.pi / 2, "until": 1.0}},
        {"vertices": [12, 13], "translate": {"velocity": [0, 0, 0.5]}}]}})
    x0 = np.random.default_rng(0).normal(size=(25, 3))
    pinned, motions = resolve_pin_entries(cfg.scene.pins, 25, (5, 5))
    assert list(pinned) == [0, 5, 10, 12, 13, 15, 20, 24]
    rot, tra = motions
    assert list(rot.vertices) == [0, 5, 10, 15, 20] and list(tra.vertices) == [12, 13]
    p = rot.positions(x0[rot.vertices], 1.0)  # a quarter turn about z: (x, y) → (−y, x)
    assert np.allclose(p, np.stack([-x0[rot.vertices, 1], x0[rot.vertices, 0],
                                    x0[rot.vertices, 2]], 1))
    assert np.allclose(rot.positions(x0[rot.vertices], 7.0), p)  # holds after `until`
    assert np.allclose(tra.positions(x0[[12, 13]], 2.0), x0[[12, 13]] + [0, 0, 1.0])


@pytest.mark.parametrize("pins, message", [
    ([{"vertices": "left_edge", "translate": {"velocity": [0, 1, 0]}},
      {"vertices": [0], "translate": {"velocity": [0, 1, 0]}}],
     "scene.pins[1]: vertex 0 is also in scene.pins[0]"),
    (["bottom_corners", {"vertices": "left_edge", "translate": {"velocity": [0, 1, 0]}}],
     "scene.pins[0]: vertex 0 is also in scene.pins[1]"),
    ([{"vertices": "left_edge", "translate": {"velocity": [0, 1, 0]}, "rotate": {}}],
     "scene.pins[0]: give at most one of rotate and translate"),
    ([{"translate": {"velocity": [0, 1, 0]}}], "scene.pins[0]: a pin group needs 'vertices'"),
    ([{"vertices": "left_edg"}], "scene.pins[0].vertices: unknown pin set 'left_edg'"),
    ([{"vertices": [99], "rotate": {"axis": [1, 0, 0]}}],
     "scene.pins[0].vertices[0]: vertex index 99 out of range"),
    ([{"vertices": [1], "rotate": {"axis": [0, 0, 0]}}],
     "scene.pins[0].rotate.axis must not be the zero vector"),
    ([{"vertices": [1], "rotate": {"spead": 1.0}}], "unknown key 'scene.pins[0].rotate.spead'"),
    ([{"vertices": [1], "translate": {"velocity": [0, 1, 0], "until": -1}}],
     "scene.pins[0].translate.until must be ≥ 0"),
])
def test_bad_pins_are_one_line_errors(tmp_path, pins, message):
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        simulate({"mesh": {"grid": {"nx": 5, "ny": 5}}, "scene": {"pins": pins},
                  "time": {"frames": 1}, "output": {"dir": str(tmp_path / "o")}}, progress=False)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("scene, message", [
    ({"colliders": [{"mesh": {"ply": "a.ply", "obj": "b.obj"}}]},
     "scene.colliders[0].mesh needs exactly one of ply, obj and frames"),
    ({"colliders": [{"mesh": {}}]}, "scene.colliders[0].mesh needs exactly one of"),
    ({"colliders": [{"mesh": {"ply": "a.ply", "fps": 30}}]}, "scene.colliders[0].mesh.fps applies to frames only"),
    ({"colliders": [{"capsule": {"a": [0, -1, 0], "b": [0, -1, 0]}}]},
     "scene.colliders[0].capsule: a and b must differ"),
    ({"colliders": [{"box": {"size": [1, 0, 1]}}]},
     "scene.colliders[0].box.size: every edge length must be positive"),
    ({"colliders": [{"sphere": {"center": [0, -2, 0], "motion": {}}}]},
     "scene.colliders[0].sphere.motion needs rotate and/or translate"),
    ({"colliders": [{"sphere": {"center": [0, -2, 0], "motion": {"spin": {}}}}]},
     "unknown key 'scene.colliders[0].sphere.motion.spin'"),
    ({"colliders": [{"cylinder": {}}]}, "scene.colliders[0]: unknown collider 'cylinder'"),
    ({"activation_distance": 0.002, "colliders": [{"sphere": {"center": [0, -2, 0]}}]},
     "scene.activation_distance (0.002 m) must be below scene.collision_margin"),
    ({"self_collision": {"thickness": 0}}, "scene.self_collision.thickness must be > 0"),
    ({"self_collision": {"thicknes": 0.1}}, "unknown key 'scene.self_collision.thicknes'"),
    ({"self_collision": 3}, "scene.self_collision must be a mapping"),
])
def test_bad_contact_keys_are_one_line_errors(scene, message):
    """Each is refused at load or when the model is built, naming the key."""
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")
                       .replace("(", r"\(").replace(")", r"\)")):
        build_model(load_config({"mesh": {"grid": {}}, "scene": scene}))


@pytest.mark.parametrize("method", ["pbd", "xpbd", "projective", "explicit", "mass-spring"])
def test_methods_without_contact_refuse_it(method):
    for scene, key in [({"self_collision": {}}, "scene.self_collision"),
                       ({"pins": [{"vertices": [0], "translate": {"velocity": [1, 0, 0]}}]},
                        "scene.pins[0].translate")]:
        with pytest.raises(InputError, match=f"does not support {key.replace('[', '.').replace(']', '.')}"):
            load_config({"mesh": {"grid": {}}, "scene": scene, "solver": {"method": method}})


# ---------------------------------------------------------------- collider files


def test_collider_files_static_and_animated(tmp_path):
    x, f = plate(1.0, 1.0)
    write_ply(tmp_path / "p.ply", x, f)
    (tmp_path / "p.obj").write_text("".join(f"v {a} {b} {c}\n" for a, b, c in x)
                                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))
    (tmp_path / "anim").mkdir()
    for k in range(3):
        write_ply(tmp_path / "anim" / f"f{k}.ply", x + [0.0, 0.1 * k, 0.0], f)
    cfg = load_config({"mesh": {"grid": {}}, "scene": {"colliders": [
        {"mesh": {"ply": str(tmp_path / "p.ply"), "friction": 0.3}},
        {"mesh": {"obj": str(tmp_path / "p.obj")}},
        {"mesh": {"frames": str(tmp_path / "anim"), "fps": 10}}]}})
    cm = load_colliders(cfg.scene.colliders)
    assert cm.n_vertices == 12 and cm.faces.max() == 11 and cm.moving
    assert list(cm.friction) == [0.3] * 4 + [0.0] * 8
    for t, dy in [(0.0, 0.0), (0.05, 0.05), (0.15, 0.15), (0.2, 0.2), (5.0, 0.2)]:
        assert np.allclose(cm.positions(t)[8:], x + [0, dy, 0]), t
    assert np.allclose(cm.positions(5.0)[:8], np.vstack([x, x]))


def bad_collider(tmp_path, kind):
    x, f = plate(1.0, 1.0)
    if kind == "missing":
        return {"ply": str(tmp_path / "nothere.ply")}
    if kind == "broken":
        (tmp_path / "b.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 9\n")
        return {"ply": str(tmp_path / "b.ply")}
    if kind == "no triangles":
        write_ply(tmp_path / "pts.ply", x, np.zeros((0, 3), np.int64))
        return {"ply": str(tmp_path / "pts.ply")}
    if kind == "degenerate":
        write_ply(tmp_path / "d.ply", np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]), np.array([[0, 1, 2]]))
        return {"ply": str(tmp_path / "d.ply")}
    if kind == "broken obj":
        (tmp_path / "b.obj").write_text("v 0 0 0\nf 1 2 3\n")
        return {"obj": str(tmp_path / "b.obj")}
    (tmp_path / "anim").mkdir()
    write_ply(tmp_path / "anim" / "f0.ply", x, f)
    if kind == "vertex count changes":
        write_ply(tmp_path / "anim" / "f1.ply", np.vstack([x, [[0, 0, 0]]]), f)
    elif kind == "faces change":
        write_ply(tmp_path / "anim" / "f1.ply", x, f[:, ::-1])
    else:
        return {"frames": str(tmp_path / "nofolder")}
    return {"frames": str(tmp_path / "anim")}


@pytest.mark.parametrize("kind, message", [
    ("missing", "scene.colliders[0].mesh.ply: .*nothere.ply: no such file"),
    ("broken", "scene.colliders[0].mesh.ply: .*b.ply"),
    ("no triangles", "scene.colliders[0].mesh.ply: .*pts.ply: mesh has no triangles"),
    ("degenerate", "scene.colliders[0].mesh.ply: .*d.ply: triangle 0 is degenerate"),
    ("broken obj", "scene.colliders[0].mesh.obj: .*b.obj"),
    ("vertex count changes", "scene.colliders[0].mesh.frames: .*f1.ply: 5 vertices, but"),
    ("faces change", "scene.colliders[0].mesh.frames: .*f1.ply: faces differ"),
    ("no folder", "scene.colliders[0].mesh.frames: .*nofolder: no such folder"),
])
def test_bad_collider_files_are_one_line_errors_writing_nothing(tmp_path, kind, message):
    config = tmp_path / "c.yaml"
    config.write_text(textwrap.dedent(f"""
        mesh: {{grid: {{nx: 4, ny: 4, plane: xz}}}}
        scene: {{colliders: [{{mesh: {bad_collider(tmp_path, kind)}}}]}}
        time: {{frames: 2}}
    """))
    result = CliRunner().invoke(main, ["simulate", str(config), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert result.output.strip().count("\n") == 0 and "Traceback" not in result.output
    assert re.search(message.replace("[", r"\[").replace("]", r"\]"), result.output), result.output
    assert not (tmp_path / "out").exists()


def test_cloth_starting_inside_the_margin_or_crossing_is_refused(tmp_path):
    body = write_mesh(tmp_path / "plate.ply", plate(2.0, 2.0, height=-0.0003))
    with pytest.raises(InputError, match=r"closer to scene.colliders\[0\].mesh than the contact "
                                         r"barrier's wall \(0.0005 m: scene.collision_margin less "
                                         r"scene.activation_distance\)"):
        run(tmp_path, {"colliders": [{"mesh": {"ply": body}}]}, frames=1)
    body = write_mesh(tmp_path / "box.ply", box([-0.1, -0.1, -0.1], [0.1, 0.1, 0.1]))
    with pytest.raises(InputError, match=r"not intersection-free: cloth triangle \d+ crosses "
                                         r"scene.colliders\[0\].mesh triangle \d+"):
        run(tmp_path, {"colliders": [{"mesh": {"ply": body}}]}, frames=1)
    for shape in ({"sphere": {"center": [0, 0, 0], "radius": 0.1}},
                  {"capsule": {"a": [-0.1, 0, 0], "b": [0.1, 0, 0], "radius": 0.05}},
                  {"plane": {"point": [0, 0.01, 0], "normal": [0, 1, 0]}},
                  {"box": {"size": [0.2, 0.2, 0.2]}}):
        kind = next(iter(shape))
        with pytest.raises(InputError, match=rf"not intersection-free: cloth (triangle|vertex) \d+ "
                                             rf"crosses scene.colliders\[0\].{kind}"):
            run(tmp_path, {"colliders": [shape]}, frames=1)


def _stepped(tmp_path, collider):
    """An integrator of a still sheet (no gravity) 1.5 mm above a collider after one step,
    and its state."""
    from clothtool.sim.model.methods import make_integrator

    config = load_config({
        "mesh": {"grid": {"nx": 9, "ny": 9, "width": 0.4, "height": 0.4, "plane": "xz"}},
        "material": {"stretch": 1000.0, "shear": 100.0, "bend": 1e-5},
        "scene": {"gravity": [0, 0, 0], "colliders": [collider],
                  "self_collision": {"thickness": 0.002}},
        "solver": SOLVER, "time": {"fps": 60, "frames": 1}, "output": {"dir": str(tmp_path)}})
    model = build_model(config)
    integ = make_integrator(model, config.solver, config.step)
    state = model.initial_state()
    integ.step(state)
    return integ, state


def test_the_frame_check_finds_a_planted_crossing_with_the_kept_candidates_or_without(tmp_path):
    """A cloth vertex planted inside a sphere is found whether the step's kept candidates
    hold the planted positions (moved by less than their reach) or a broad phase runs (moved
    far); a cloth triangle planted through a mesh by the exact test; none before planting."""
    from clothtool.sim.solve.contact import _within

    top = -0.0015  # the sphere's top and the plate, under the sheet at y = 0
    integ, state = _stepped(tmp_path, {"sphere": {"center": [0, top - 0.1, 0], "radius": 0.1}})
    contact = integ.contact
    assert contact.crossing(state.x, state.time) is None
    centre = int(np.argmin(np.linalg.norm(state.x[:, [0, 2]], axis=1)))
    for depth, held in ((0.0004, True), (0.03, False)):
        x = state.x.copy()
        x[centre, 1] = top - depth
        y = contact._positions(x, state.time)
        assert _within(y, np.zeros_like(y), contact._ref, contact._rho) == held
        assert re.fullmatch(r"cloth (triangle|vertex) \d+ crosses scene.colliders\[0\].sphere",
                            contact.crossing(x, state.time))
    integ, state = _stepped(tmp_path, {"mesh": {"ply": write_mesh(
        tmp_path / "plate.ply", plate(0.2, 0.2, height=top))}})
    assert integ.contact.crossing(state.x, state.time) is None
    x = state.x.copy()
    x[centre, 1] = -0.05
    assert re.fullmatch(r"cloth triangle \d+ crosses scene.colliders\[0\].mesh triangle \d+",
                        integ.contact.crossing(x, state.time))


def test_the_kept_candidates_hold_every_pair_within_reach_at_every_newton_iterate(tmp_path):
    """The candidates are kept across Newton iterations (and steps) while the vertices stay
    within their reach: at the start and end of every Newton step's motion, every pair
    within reach (brute force over all pairs) is among them. A 6 × 6 sheet with friction
    falling on a plate and onto itself (folded by a pin that moves)."""
    from test_contact import brute_force_pairs

    from clothtool.sim.model.methods import make_integrator
    from clothtool.sim.solve.contact import BarrierContact

    config = load_config({
        "mesh": {"grid": {"nx": 6, "ny": 6, "width": 0.2, "height": 0.2, "plane": "xz"}},
        "material": {"stretch": 1000.0, "shear": 100.0, "bend": 1e-5},
        "scene": {"colliders": [{"mesh": {"ply": write_mesh(
            tmp_path / "plate.ply", plate(0.6, 0.6, height=-0.004)), "friction": 0.3}}],
            "self_collision": {"thickness": 0.002, "friction": 0.2},
            "pins": [{"vertices": [0, 6], "translate": {"velocity": [0.6, 0.0, 0.0]}}]},
        "solver": SOLVER, "time": {"fps": 60, "frames": 1}, "output": {"dir": str(tmp_path)}})
    model = build_model(config)
    integ = make_integrator(model, config.solver, config.step)
    contact = integ.contact
    sc = contact.scene
    seen = {"checks": 0, "pairs": 0}

    def held(y):
        kept = {tuple(st) for st in contact.stencils}
        want = brute_force_pairs(y, sc.faces, sc.edges, sc.obstacle, True, contact.reach)
        assert want <= kept
        seen["checks"] += 1
        seen["pairs"] += len(want)

    free_step = BarrierContact._free_step

    def checked(self):
        step = free_step(self)
        held(self.y)
        held(self.y + self.dy)
        return step

    contact._free_step = checked.__get__(contact)
    state = model.initial_state()
    for _ in range(12):
        integ.step(state)
    assert seen["checks"] >= 24 and seen["pairs"] > 100
    assert contact.crossing(state.x, state.time) is None


@pytest.mark.parametrize("first", [0.0, 1e-3])
def test_first_forcing_is_the_first_pcg_tolerance_of_each_contact_step(tmp_path, monkeypatch,
                                                                        first):
    """``solver.first_forcing``: Newton's first PCG of every step (a stage from x_n, with
    contact) asks for that relative residual, or ``solver.tolerance`` at 0; the later ones
    Eisenstat–Walker's within [tolerance, 0.15]. A sheet falling onto a sphere stays
    intersection-free either way."""
    import clothtool.sim.solve.newton as newton

    asked = []
    pcg, minimise = newton.filtered_pcg, newton.NewtonIntegrator._newton

    def spy(matrix, rhs, dx, constraints, tol, *rest):
        asked[-1].append(tol)
        return pcg(matrix, rhs, dx, constraints, tol, *rest)

    def started(self, *args, **kw):
        asked.append([])
        return minimise(self, *args, **kw)

    monkeypatch.setattr(newton, "filtered_pcg", spy)
    monkeypatch.setattr(newton.NewtonIntegrator, "_newton", started)
    scene = {"colliders": [{"sphere": {"center": [0.0, -0.2, 0.0], "radius": 0.15}}],
             "self_collision": {"thickness": 0.002}}
    _, out = run(tmp_path, scene, frames=12, solver={"tolerance": 1e-6, "first_forcing": first})
    assert_intersection_free(out)
    assert len(asked) >= 12 and sum(len(tols) > 1 for tols in asked) >= 6
    assert all(tols[0] == (first or 1e-6) for tols in asked)
    assert all(1e-6 <= t <= 0.15 for tols in asked for t in tols[1:])


@pytest.mark.parametrize("first", [0, 3])
def test_first_cut_iterations_stops_the_first_pcg_whose_guess_ccd_cuts(tmp_path, monkeypatch,
                                                                       first):
    """``solver.first_cut_iterations`` k: Newton's first PCG of a contact step stops after k
    iterations exactly when CCD over the step's candidates cuts its guess short (the sheet
    falling onto a sphere: the steps at impact, not those of the fall before); every other
    solve keeps ``solver.max_iterations``. The sheet stays intersection-free either way."""
    import clothtool.sim.solve.newton as newton
    from clothtool.sim.solve.potential import Contact

    asked = []
    pcg, minimise = newton.filtered_pcg, newton.NewtonIntegrator._newton

    def spy(matrix, rhs, dx, constraints, tol, max_iter, *rest):
        cut = asked[-1][1].cuts(dx) if not asked[-1][0] else None
        its, res = pcg(matrix, rhs, dx, constraints, tol, max_iter, *rest)
        asked[-1][0].append((max_iter, its, cut))
        return its, res

    def started(self, *args, **kw):
        asked.append(([], next(t.contact for t in self.terms if isinstance(t, Contact))))
        return minimise(self, *args, **kw)

    monkeypatch.setattr(newton, "filtered_pcg", spy)
    monkeypatch.setattr(newton.NewtonIntegrator, "_newton", started)
    scene = {"colliders": [{"sphere": {"center": [0.0, -0.2, 0.0], "radius": 0.15}}],
             "self_collision": {"thickness": 0.002}}
    _, out = run(tmp_path, scene, frames=12, solver={"first_cut_iterations": first})
    assert_intersection_free(out)
    firsts = [solves[0] for solves, _ in asked]
    assert sum(cut for _, _, cut in firsts) >= 2 and sum(not cut for _, _, cut in firsts) >= 2
    for limit, its, cut in firsts:
        assert limit == (first if cut and first else 500) and its <= limit
    assert all(limit == 500 for solves, _ in asked for limit, _, _ in solves[1:])


# ---------------------------------------------------------------- scenes


def test_twist_small_is_intersection_free_and_deterministic(tmp_path):
    """(a) the twist: a 16 × 16 sheet whose ends turn opposite ways, fast."""
    scene = {"gravity": [0, 0, 0], "self_collision": {"thickness": 0.002, "friction": 0.2},
             "pins": [{"vertices": "left_edge", "rotate": {"axis": [0, 1, 0], "speed": 6.0}},
                      {"vertices": "right_edge", "rotate": {"axis": [0, -1, 0], "speed": 6.0}}]}
    mesh = {"grid": {"nx": 16, "ny": 16, "width": 0.75, "height": 0.5, "plane": "yz"}}
    result, out = run(tmp_path, scene, mesh=mesh, frames=45)
    xs, rows = assert_intersection_free(out)
    assert max(int(r["contacts"]) for r in rows) > 50  # the layers do touch
    left = np.arange(16) * 16
    x0 = xs[0][left]
    turned = xs[-1][left]  # 45 frames at 6 rad/s: 4.5 rad about +y
    c, s = np.cos(4.5), np.sin(4.5)
    assert np.allclose(turned, np.stack([x0[:, 0] * c + x0[:, 2] * s, x0[:, 1],
                                         -x0[:, 0] * s + x0[:, 2] * c], 1), atol=1e-9)
    _, again = run(tmp_path, scene, mesh=mesh, frames=45, name="again")
    for a, b in zip(sorted(out.glob("frame_*.ply")), sorted(again.glob("frame_*.ply"))):
        assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("integrator", ["bdf2", "euler"])
def test_drape_over_a_closed_body(tmp_path, integrator):
    """(b) a sheet dropped onto a capsule folds around it and stays outside, with either
    implicit integrator."""
    body = capsule(radius=0.1, half_length=0.15, around=16, rings=4)
    body = (body[0] + [0.0, -0.12, 0.0], body[1])
    path = write_mesh(tmp_path / "body.ply", body)
    scene = {"colliders": [{"mesh": {"ply": path, "friction": 0.3}}],
             "self_collision": {"thickness": 0.002, "friction": 0.2}}
    _, out = run(tmp_path, scene, frames=30, solver={"integrator": integrator})
    xs, rows = assert_intersection_free(out, [body])
    assert int(rows[-1]["contacts"]) > 0
    # outside the capsule (distance to its axis segment beyond the radius) in every frame
    for x in xs:
        q = x - [0.0, -0.12, 0.0]
        along = np.clip(q[:, 0], -0.15, 0.15)
        r = np.linalg.norm(q - np.stack([along, 0 * along, 0 * along], 1), axis=1)
        assert r.min() > 0.1 * np.cos(np.pi / 16)  # the polygon's inner radius
    assert xs[-1][:, 1].min() < -0.15  # it did drape down the sides


def test_stacked_sheets_settle_on_a_plate(tmp_path):
    """(c) three stacked sheets dropped onto a floor plate."""
    m = grid_mesh(GridSpec(nx=8, ny=8, width=0.4, height=0.4, plane="xz"))
    xs, fs = [], []
    for k in range(3):
        c, s = np.cos(0.3 * k), np.sin(0.3 * k)
        x = m.positions @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
        x[:, 1] = 0.02 + 0.02 * k
        xs.append(x)
        fs.append(m.faces + 64 * k)
    write_ply(tmp_path / "stack.ply", np.concatenate(xs), np.concatenate(fs))
    floor = plate(2.0, 2.0)
    path = write_mesh(tmp_path / "floor.ply", floor)
    scene = {"colliders": [{"mesh": {"ply": path, "friction": 0.3}}],
             "self_collision": {"thickness": 0.002, "friction": 0.3}}
    _, out = run(tmp_path, scene, mesh={"ply": str(tmp_path / "stack.ply")}, frames=40)
    frames, rows = assert_intersection_free(out, [floor])
    last = frames[-1]
    heights = [last[64 * k:64 * (k + 1), 1].mean() for k in range(3)]
    assert 0.0 < heights[0] < heights[1] < heights[2] < 0.02  # settled, in order
    assert int(rows[-1]["contacts"]) > 64


def test_tablecloth_pulled_off_a_table(tmp_path):
    """(d) a tablecloth pulled sideways off a table by a moving pin."""
    table = box([-0.25, -0.4, -0.2], [0.25, -0.01, 0.2])
    path = write_mesh(tmp_path / "table.ply", table)
    scene = {"colliders": [{"mesh": {"ply": path, "friction": 0.3}}],
             "self_collision": {"thickness": 0.002, "friction": 0.2},
             "pins": [{"vertices": "right_edge", "translate": {"velocity": [2.0, 0, 0], "until": 0.4}}]}
    _, out = run(tmp_path, scene, mesh={"grid": {"nx": 12, "ny": 12, "width": 0.6, "height": 0.5,
                                                  "plane": "xz"}}, frames=40)
    xs, _ = assert_intersection_free(out, [table])
    right = np.arange(12) * 12 + 11
    assert np.allclose(xs[-1][right, 0] - xs[0][right, 0], 0.8)  # 2 m/s for 0.4 s, then held
    assert xs[-1][:, 0].min() > 0.2  # the cloth has come off the table's far half


def test_no_tunnelling_through_a_thin_open_plate_at_20_m_per_s(tmp_path):
    """A sheet falling 0.1 m at 2000 m/s² meets an open two-triangle plate at √(2·2000·0.1)
    = 20 m/s, within the first step (free fall would take it ½ g h² = 0.28 m down in it)."""
    thin = plate(1.0, 1.0, height=-0.1)
    path = write_mesh(tmp_path / "plate.ply", thin)
    scene = {"gravity": [0, -2000.0, 0], "colliders": [{"mesh": {"ply": path}}]}
    _, out = run(tmp_path, scene, mesh={"grid": {"nx": 8, "ny": 8, "width": 0.4, "height": 0.4,
                                                  "plane": "xz"}}, frames=12)
    xs, rows = assert_intersection_free(out, [thin])
    assert all(x[:, 1].min() > -0.1 for x in xs)  # above the plate in every frame
    assert xs[1][:, 1].max() < -0.09  # and on it from the first step on


def test_pin_dragging_cloth_through_a_collider_is_exit_3_naming_the_frame(tmp_path):
    path = write_mesh(tmp_path / "plate.ply", plate(2.0, 2.0, height=-0.05))
    config = tmp_path / "c.yaml"
    config.write_text(textwrap.dedent(f"""
        mesh: {{grid: {{nx: 6, ny: 6, width: 0.5, height: 0.5, plane: xz}}}}
        scene:
          pins: [{{vertices: left_edge, translate: {{velocity: [0, -1.0, 0]}}}}]
          colliders: [{{mesh: {{ply: {path}}}}}]
        solver: {{newton_iterations: 8, newton_tolerance: 2.0e-2, tolerance: 1.0e-2}}
        time: {{fps: 60, frames: 10}}
    """))
    result = CliRunner().invoke(main, ["simulate", str(config), "-o", str(tmp_path / "out")])
    assert result.exit_code == 3, result.output
    assert result.output.strip().count("\n") == 0
    assert "at frame 3: a moving pin or collider could not reach its position" in result.output
    frames = sorted((tmp_path / "out").glob("frame_*.ply"))
    assert [p.name for p in frames] == ["frame_00000.ply", "frame_00001.ply", "frame_00002.ply"]


def test_animated_collider_pushes_the_cloth_without_crossing(tmp_path):
    """An open plate rising through frames (10 fps, linear in between) lifts a resting sheet."""
    anim = tmp_path / "lift"
    anim.mkdir()
    base = plate(1.0, 1.0, height=-0.05)
    for k in range(4):
        write_ply(anim / f"lift_{k}.ply", base[0] + [0.0, 0.05 * k, 0.0], base[1])
    scene = {"gravity": [0, -9.81, 0], "colliders": [{"mesh": {"frames": str(anim), "fps": 10}}]}
    _, out = run(tmp_path, scene, frames=30, fps=60)
    xs, _ = frames_of(out)
    for k, x in enumerate(xs):
        t = k / 60
        height = -0.05 + 0.5 * min(t, 0.3)
        y = np.concatenate([x, base[0] + [0.0, height + 0.05, 0.0]])
        faces = np.concatenate([frames_of(out)[1], base[1] + len(x)])
        assert not has_intersections(y, faces, np.arange(len(y)) >= len(x))
        assert x[:, 1].min() > height  # above the plate
    assert xs[-1][:, 1].mean() > 0.09  # lifted by 0.1 m


def test_friction_holds_a_sheet_on_a_slope(tmp_path):
    """A sheet on a plate tilted 20°: with μ = 0.8 (> tan 20°) it stays, with μ = 0 it slides."""
    tilt = np.radians(20.0)
    x, f = plate(2.0, 2.0, height=-0.003)
    r = np.array([[np.cos(tilt), -np.sin(tilt), 0], [np.sin(tilt), np.cos(tilt), 0], [0, 0, 1]])
    slope = (x @ r.T, f)
    sheet = tmp_path / "sheet.ply"  # lying on the slope: the grid turned like the plate
    m = grid_mesh(GridSpec(nx=6, ny=6, width=0.3, height=0.3, plane="xz"))
    write_ply(sheet, m.positions @ r.T, m.faces)
    moved = {}
    for mu in (0.0, 0.8):
        path = write_mesh(tmp_path / f"slope{mu}.ply", slope)
        scene = {"colliders": [{"mesh": {"ply": path, "friction": mu}}]}
        _, out = run(tmp_path, scene, mesh={"ply": str(sheet)}, frames=30, name=f"mu{mu}")
        xs, _ = frames_of(out)
        moved[mu] = np.linalg.norm(xs[-1] - xs[0], axis=1).mean()
    assert moved[0.0] > 0.05 and moved[0.8] < 0.2 * moved[0.0]


def test_scene_without_contact_has_no_contact_columns(tmp_path):
    _, out = run(tmp_path, {"pins": ["top_corners"]}, frames=2)
    assert "contacts" not in stats_of(out)[0]
