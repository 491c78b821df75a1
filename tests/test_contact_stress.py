"""A stress sweep over contact scenes: nothing internal escapes.

Random mixes of spheres, capsules, boxes, planes and triangle meshes (static or moving up
to 20 m/s), flat and crumpled starts, with and without self-collision, 1–64 steps per
frame, membrane stiffness 1e2–1e6 N/m. Every run either finishes (exit 0), stops with a
one-line numerical failure naming the frame (exit 3), or is refused as starting in
intersection (exit 2, naming the crossing) — never a traceback or an internal error. The
finished runs' frames are free of crossings by ipctk.
"""

import csv

import ipctk
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from clothtool.cli import main
from clothtool.contact.broadphase import mesh_edges
from clothtool.contact.shapes import box
from clothtool.io.ply import read_ply, write_ply
from clothtool.sim.model.config import GridSpec
from clothtool.sim.model.mesh import grid_mesh


def random_scene(rng, folder):
    """A config dict: a 0.4 m sheet at y = 0 (flat or crumpled), colliders below it."""
    n = int(rng.integers(5, 9))
    sheet = grid_mesh(GridSpec(nx=n, ny=n, width=0.4, height=0.4, plane="xz"))
    x = sheet.positions.copy()
    if rng.random() < 0.5:  # crumpled: random displacements of up to 0.6 cell
        x += rng.uniform(-0.6, 0.6, x.shape) * (0.4 / (n - 1))
    write_ply(folder / "rest.ply", x, sheet.faces,
              vertex_properties={"s": sheet.uv[:, 0], "t": sheet.uv[:, 1]})
    speed = float(rng.choice([0.0, 1.0, 5.0, 20.0]))
    colliders = []
    for _ in range(int(rng.integers(1, 4))):
        kind = str(rng.choice(["sphere", "capsule", "box", "plane", "mesh"]))
        depth = float(rng.uniform(0.12, 0.4))  # the top of the collider below the sheet
        c = float(rng.uniform(-0.1, 0.1))
        if kind == "sphere":
            r = float(rng.uniform(0.03, 0.2))
            body = {"center": [c, -depth - r, c], "radius": r}
        elif kind == "capsule":
            r = float(rng.uniform(0.02, 0.1))
            body = {"a": [-0.3, -depth - r, c], "b": [0.3, -depth - r, -c], "radius": r}
        elif kind == "box":
            body = {"center": [c, -depth - 0.1, c], "size": [0.3, 0.2, 0.3],
                    "axis": [0, 1, 0], "angle": float(rng.uniform(0, 1))}
        elif kind == "plane":
            tilt = rng.uniform(-0.3, 0.3, 2)
            body = {"point": [0, -depth, 0], "normal": [float(tilt[0]), 1.0, float(tilt[1])]}
        else:
            path = folder / f"mesh{len(colliders)}.ply"
            write_ply(path, *box([c - 0.15, -depth - 0.2, -0.15], [c + 0.15, -depth, 0.15]))
            body = {"ply": str(path)}
        body["friction"] = float(rng.choice([0.0, 0.3, 1.0]))
        if speed > 0.0 and rng.random() < 0.5:  # rushes up through the sheet's plane
            body["motion"] = {"translate": {"velocity": [0.0, speed, 0.0], "until": 0.05}}
        elif rng.random() < 0.3:
            body["motion"] = {"rotate": {"center": [0, -depth, 0], "axis": [0, 1, 0],
                                         "speed": float(rng.uniform(-6, 6))}}
        colliders.append({kind: body})
    scene = {"gravity": [0.0, -9.81 * float(rng.choice([1.0, 10.0])), 0.0],
             "colliders": colliders}
    if rng.random() < 0.5:
        scene["self_collision"] = {"thickness": 0.004, "friction": float(rng.choice([0.0, 0.3]))}
    if rng.random() < 0.3:
        scene["pins"] = [{"vertices": [n * (n - 1), n * n - 1],
                          "translate": {"velocity": [0.0, -speed, 0.0], "until": 0.1}}]
    return {"mesh": {"ply": "rest.ply"},
            "material": {"stretch": float(10.0 ** rng.uniform(2, 6)), "shear": 50.0,
                         "bend": 1e-5, "density": 0.2},
            "scene": scene,
            "solver": {"substeps": int(rng.choice([1, 4, 16, 64])),
                       "integrator": str(rng.choice(["bdf2", "euler"]))},
            "time": {"fps": 30, "frames": 6}, "output": {"dir": "out"}}


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(16))
def test_random_contact_scenes_finish_or_fail_cleanly(tmp_path, seed):
    config = random_scene(np.random.default_rng(seed), tmp_path)
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(config))
    result = CliRunner().invoke(main, ["simulate", str(tmp_path / "scene.yaml"), "-q"])
    message = result.output.strip()
    assert "Traceback" not in result.output and "internal error" not in message, message
    if result.exit_code == 2:
        assert message.count("\n") == 0 and "not intersection-free" in message, message
        assert not (tmp_path / "out").exists()
        return
    if result.exit_code == 3:
        assert message.count("\n") == 0 and "frame" in message, message
    else:
        assert result.exit_code == 0, message
    paths = sorted((tmp_path / "out").glob("frame_*.ply"))
    assert paths
    cloth = read_ply(paths[0])
    for path in paths:  # the cloth against its own mesh when self-collision is on
        x = read_ply(path).vertices
        if "self_collision" in config["scene"]:
            mesh = ipctk.CollisionMesh(x, mesh_edges(cloth.faces), cloth.faces)
            assert not ipctk.has_intersections(mesh, x), path.name
    with open(tmp_path / "out" / "stats.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert all(float(r["min_separation"]) > 0.0 for r in rows[1:])
