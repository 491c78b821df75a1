"""The contact data of a Model: one vertex array of the cloth (first) and the colliders.

The cloth's N vertices, then the colliders' (:mod:`clothtool.sim.model.colliders`: meshes and
boxes by their triangles, spheres, capsules and planes by their exact distance), with their
faces, edges, friction coefficients and the barrier's zone per pair kind. Cloth–collider
pairs rest ``scene.collision_margin`` apart, cloth–cloth pairs ``self_collision.thickness``:
the barrier starts to push OUTSIDE (4 %) beyond that distance and rises to infinity at its
wall d closer in, d = ``scene.activation_distance`` or ACTIVATION (¾) of the margin (or
thickness); its width is d̂ = d + OUTSIDE·margin. The Newton loop's contact term
(:mod:`clothtool.sim.solve.contact`) runs on it.
"""

from dataclasses import dataclass

import numpy as np

from clothtool.contact.barrier import pair_geometry
from clothtool.contact.broadphase import mesh_edges
from clothtool.errors import InputError

# activation distance d̂ as a fraction of the margin and the thickness: the wall at a quarter of
# them; with the wall at half, the core of the twist (sample_data/twist.yaml) was pressed
# against it by frame 297 and the pins stopped; at a quarter it runs to its end
ACTIVATION = 0.75
# the barrier reaches this fraction of the margin (thickness) beyond it, so that cloth resting
# under a load sits on both sides of the margin: with the barrier starting at the margin the
# drape rested 6.9 % inside it, with 4 % beyond 3.1 %, and lightly loaded cloth at most 4 % outside
OUTSIDE = 0.04


@dataclass
class ContactScene:
    """The contact data of a Model: one vertex array of cloth (first) and colliders."""

    n_cloth: int
    n_cloth_faces: int
    colliders: object  # clothtool.sim.model.colliders.Colliders or None
    faces: np.ndarray  # (F, 3) cloth faces, then collider triangles
    edges: np.ndarray  # (E, 2) their edges and the capsules' axes
    planes: np.ndarray  # (P, 2) plane vertex pairs (o, t)
    points: np.ndarray  # (Q,) the vertices that are surface points (all but the planes')
    self_contact: bool
    mu_self: float
    mu: np.ndarray  # (N + V,) friction of each collider vertex (0 for cloth)
    geometry: tuple  # clothtool.contact.barrier.pair_geometry

    @property
    def n_total(self):
        return len(self.mu)

    @property
    def obstacle(self):
        return self.geometry[0]

    @property
    def reach(self):
        """How far beyond a surface pairs take part: the largest ξ + d̂ (radii apart)."""
        g = self.geometry
        return max(g[3] + g[5], g[4] + g[6])


def build_contact_scene(config, mesh):
    """The :class:`ContactScene` of a config and its rest mesh, or None without colliders
    and self-collision."""
    from clothtool.sim.model.colliders import load_colliders

    scene = config.scene
    colliders = load_colliders(scene.colliders)
    if colliders is None and scene.self_collision is None:
        return None
    n = len(mesh.positions)
    v = colliders.n_vertices if colliders is not None else 0
    faces, rest, edges = [mesh.faces], [mesh.rest3d], []
    planes, points = np.zeros((0, 2), np.int64), np.arange(n)
    radius, mu = np.zeros(n + v), np.zeros(n + v)
    if colliders is not None:
        faces.append(colliders.faces + n)
        rest.append(colliders.positions(0.0))
        edges.append(colliders.edges + n)
        planes = colliders.planes + n
        points = np.concatenate([points, colliders.points + n])
        radius[n:] = colliders.radius
        mu[n:] = colliders.friction
    faces = np.concatenate(faces).astype(np.int64)
    edges = np.concatenate([mesh_edges(faces)] + edges).astype(np.int64)
    obstacle = np.zeros(n + v, dtype=np.bool_)
    obstacle[n:] = True
    sc = scene.self_collision
    xi_self = sc.thickness if sc is not None else 0.0
    xi_obstacle = scene.collision_margin
    dhat = scene.activation_distance

    def zone(xi, key):  # (wall, width): the barrier acts from ξ(1 + OUTSIDE) to its wall ξ − d
        d = ACTIVATION * xi if dhat is None else dhat
        if d >= xi and xi > 0.0:
            raise InputError(f"scene.activation_distance ({dhat:g} m) must be below {key} "
                             f"({xi:g} m): the barrier's wall is that much closer in")
        return xi - d, d + OUTSIDE * xi

    wall_self, dhat_self = zone(xi_self, "self_collision.thickness")
    wall_obstacle, dhat_obstacle = zone(xi_obstacle, "scene.collision_margin")
    geometry = pair_geometry(obstacle, radius, np.concatenate(rest), wall_self, wall_obstacle,
                             dhat_self, dhat_obstacle)
    return ContactScene(n, len(mesh.faces), colliders, faces, edges, planes.astype(np.int64),
                        points.astype(np.int64), sc is not None,
                        sc.friction if sc is not None else 0.0, mu, geometry)
