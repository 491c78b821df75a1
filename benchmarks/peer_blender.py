"""Blender's own cloth on a scene of bench_peers.py, run headless in bpy (Blender as a module).

    .venv-bpy/bin/python benchmarks/peer_blender.py SCENE.npz OUT.npz

Run by ``python -m benchmarks peers`` with the Python of ``.venv-bpy`` (bpy 5.0.1 needs Python
3.11 and pins numpy < 2: ``python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install
bpy==5.0.1``), so it imports bpy and numpy only, never clothtool. SCENE.npz holds the mesh
(``vertices`` (N, 3), ``quads`` (Q, 4)), ``pins`` (vertex indices pinned by a vertex group),
``frames``, ``fps``, and for a drop ``sphere`` (centre x, y, z, radius), ``segments``,
``rings`` and ``distance`` (m: the collision and self-collision distances and the sphere's
outer thickness, self-collision on). Blender's cloth settings are its defaults otherwise
(quality 5 steps per frame). Frame 1 is the rest state; ``frames`` frames are simulated
after it. OUT.npz: ``positions`` (frames + 1, N, 3), ``cpu`` (s: the process's CPU time of
the frames' evaluation, every thread) and ``quality`` (steps per frame).
"""

import sys
import time

import bpy
import numpy as np


def build(scene):
    """The cloth object (and the sphere collider of a drop) in an empty scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    frames = int(scene["frames"])
    sc.frame_start, sc.frame_end = 1, frames + 1
    sc.render.fps = int(scene["fps"])
    sc.gravity = (0.0, 0.0, -9.81)
    mesh = bpy.data.meshes.new("cloth")
    mesh.from_pydata(scene["vertices"].tolist(), [], scene["quads"].tolist())
    mesh.update()
    cloth = bpy.data.objects.new("cloth", mesh)
    sc.collection.objects.link(cloth)
    mod = cloth.modifiers.new("cloth", "CLOTH")
    pins = scene["pins"].tolist()
    if pins:
        group = cloth.vertex_groups.new(name="pin")
        group.add(pins, 1.0, "REPLACE")
        mod.settings.vertex_group_mass = "pin"
    if "sphere" in scene:
        x, y, z, radius = scene["sphere"].tolist()
        distance = float(scene["distance"])
        bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=(x, y, z),
                                             segments=int(scene["segments"]),
                                             ring_count=int(scene["rings"]))
        sphere = bpy.context.active_object
        sphere.modifiers.new("collision", "COLLISION")
        sphere.collision.thickness_outer = distance
        mod.collision_settings.use_self_collision = True
        mod.collision_settings.distance_min = distance
        mod.collision_settings.self_distance_min = distance
    mod.point_cache.frame_start, mod.point_cache.frame_end = 1, frames + 1
    return sc, cloth, mod


def run(scene):
    sc, cloth, mod = build(scene)
    n = len(scene["vertices"])
    positions = np.empty((int(scene["frames"]) + 1, n, 3))
    started = time.process_time()
    for k in range(len(positions)):
        sc.frame_set(k + 1)
        evaluated = cloth.evaluated_get(bpy.context.evaluated_depsgraph_get())
        co = np.empty(3 * n)
        evaluated.data.vertices.foreach_get("co", co)
        positions[k] = co.reshape(n, 3)
    cpu = time.process_time() - started
    return positions, cpu, mod.settings.quality


if __name__ == "__main__":
    scene = dict(np.load(sys.argv[1]))
    positions, cpu, quality = run(scene)
    np.savez(sys.argv[2], positions=positions, cpu=cpu, quality=quality)
    print(f"blender: {positions.shape[1]} vertices, {len(positions) - 1} frames, quality "
          f"{quality}, {cpu:.2f} s CPU")
