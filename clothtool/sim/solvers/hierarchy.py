"""The particle hierarchy of hierarchical PBD (Müller 2008, "Hierarchical Position Based
Dynamics", VRIPHYS, §4).

Level 0 is the mesh (its edges the neighbour graph). Level l + 1 is a subset of level l
chosen greedily so that every particle of level l left out has at least ``K_PARENTS`` of
its level-l neighbours in level l + 1 (visiting the particles in order, one becomes coarse
while fewer than ``K_PARENTS`` of its neighbours are); those neighbours are its parents,
weighted by the inverse of their rest distance, normalised. Two coarse particles are
neighbours on level l + 1 when they are neighbours on level l or parents of a common
particle; each such pair is a distance constraint at its rest distance that only resists
stretching (unilateral, §4.2: a coarse level must not stiffen bending). Levels are added
while the coarse level is at most ``SHRINK`` times the finer one and has more than
``COARSEST`` particles.
"""

from dataclasses import dataclass

import numpy as np

from clothtool.numba_setup import njit

K_PARENTS = 2
SHRINK = 0.7
COARSEST = 16


@dataclass
class Level:
    """One coarse level: its particles (indices into the mesh), its unilateral constraints
    (pairs of mesh indices, rest lengths) and how the finer level's left-out particles
    follow it (``fine``: their mesh indices; ``parent_ptr``/``parent``/``weight``: CSR of
    their parents' mesh indices and weights)."""

    particles: np.ndarray
    i: np.ndarray
    j: np.ndarray
    rest: np.ndarray
    fine: np.ndarray
    parent_ptr: np.ndarray
    parent: np.ndarray
    weight: np.ndarray

    @property
    def limited(self):
        """Every constraint is a stretch limit (the mask the PBD stretch-limit pass takes)."""
        return np.ones(len(self.i), np.bool_)


def _neighbours(n, i, j):
    """Adjacency lists of an undirected graph given by its edges (i, j)."""
    adj = [set() for _ in range(n)]
    for a, b in zip(i.tolist(), j.tolist()):
        if a != b:
            adj[a].add(b)
            adj[b].add(a)
    return adj


def build_levels(rest3d, edge_i, edge_j, keep=()):
    """The coarse levels (coarsest last) of a mesh with rest positions ``rest3d`` and edges;
    the particles in ``keep`` (the pinned ones) are on every level, so that every level
    feels the pins."""
    particles = np.arange(len(rest3d))
    adj = _neighbours(len(rest3d), edge_i, edge_j)  # over mesh indices, level by level
    levels = []
    keep = {int(k) for k in keep}
    while len(particles) > COARSEST:
        coarse = set(keep)
        for p in particles.tolist():
            if sum(1 for q in adj[p] if q in coarse) < K_PARENTS:
                coarse.add(p)
        if len(coarse) > SHRINK * len(particles):
            break
        fine = [p for p in particles.tolist() if p not in coarse]
        ptr, parent, weight = [0], [], []
        pairs = set()
        for p in fine:
            ps = sorted(q for q in adj[p] if q in coarse)
            w = np.array([1.0 / max(np.linalg.norm(rest3d[q] - rest3d[p]), 1e-12) for q in ps])
            parent += ps
            weight += (w / w.sum()).tolist()
            ptr.append(len(parent))
            pairs.update((a, b) for a in ps for b in ps if a < b)
        for p in coarse:
            pairs.update((min(p, q), max(p, q)) for q in adj[p] if q in coarse)
        pairs = sorted(pairs)
        ci = np.array([a for a, _ in pairs], dtype=np.int64)
        cj = np.array([b for _, b in pairs], dtype=np.int64)
        rest = np.linalg.norm(rest3d[ci] - rest3d[cj], axis=1)
        particles = np.array(sorted(coarse), dtype=np.int64)
        levels.append(Level(particles, ci, cj, rest, np.array(fine, dtype=np.int64),
                            np.array(ptr, dtype=np.int64), np.array(parent, dtype=np.int64),
                            np.array(weight)))
        new_adj = [set() for _ in range(len(rest3d))]
        for a, b in pairs:
            new_adj[a].add(b)
            new_adj[b].add(a)
        adj = new_adj
    return levels


def coarse_masses(mass, levels):
    """Per level, the mesh-indexed masses of its particles: a coarse particle carries its own
    mass and its weighted share of each left-out particle's (Müller 2008, §4.1)."""
    out = []
    m = mass.astype(np.float64).copy()
    for lev in levels:
        coarse = np.zeros_like(m)
        coarse[lev.particles] = m[lev.particles]
        counts = np.diff(lev.parent_ptr)
        np.add.at(coarse, lev.parent, np.repeat(m[lev.fine], counts) * lev.weight)
        out.append(coarse)
        m = coarse
    return out


@njit(cache=True)
def prolong(x, start, fine, parent_ptr, parent, weight, inv_mass):
    """x_f = start_f + Σ_j w_fj (x_j − start_j) for the left-out particles f of a level: they
    follow their parents' motion since ``start`` (Müller 2008, §4.3); pinned ones
    (inv_mass 0) stay."""
    for a in range(fine.shape[0]):
        f = fine[a]
        if inv_mass[f] == 0.0:
            continue
        for p in range(3):
            moved = 0.0
            for s in range(parent_ptr[a], parent_ptr[a + 1]):
                j = parent[s]
                moved += weight[s] * (x[j, p] - start[j, p])
            x[f, p] = start[f, p] + moved
