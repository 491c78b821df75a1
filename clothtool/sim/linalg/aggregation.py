"""Aggregation of a graph and the coarse patterns it induces (the setup of every multigrid here).

Greedy aggregation (Vaněk, Mandel & Brezina 1996, "Algebraic multigrid by smoothed aggregation
for second and fourth order elliptic problems", phases 1–3): an aggregate is a node and its
free neighbours, left-overs join a neighbouring aggregate, what is still alone forms an
aggregate with its unaggregated neighbours. On the triangle graph of a mesh an aggregate is a
vertex and its one-ring (about seven vertices on a regular grid).

:func:`coarsen` repeats it level by level. Each level's block pattern maps onto the next: the
block slot (i, j) of a level goes to the slot (agg i, agg j) of the next (``slot_map``), so a
Galerkin product is one pass over the blocks of the level above. Only the pattern is used: this
is done once per mesh.
"""

import numpy as np

from clothtool.numba_setup import njit


@njit(cache=True)
def aggregate(row_ptr, col):
    """Greedy aggregation of a graph; returns (aggregate of each node, number of aggregates)."""
    n = row_ptr.shape[0] - 1
    agg = np.empty(n, np.int64)  # all -1, in a loop: np.full compiles an overload of its own
    for i in range(n):
        agg[i] = -1
    count = 0
    # phase 1: a node whose neighbours are all free starts an aggregate with them
    for i in range(n):
        if agg[i] >= 0:
            continue
        free = True
        for s in range(row_ptr[i], row_ptr[i + 1]):
            if agg[col[s]] >= 0:
                free = False
                break
        if free:
            for s in range(row_ptr[i], row_ptr[i + 1]):
                agg[col[s]] = count
            count += 1
    # phase 2: left-overs join an aggregate of a neighbour
    first = agg.copy()
    for i in range(n):
        if first[i] >= 0:
            continue
        for s in range(row_ptr[i], row_ptr[i + 1]):
            if first[col[s]] >= 0:
                agg[i] = first[col[s]]
                break
    # phase 3: what is still alone forms aggregates with its unaggregated neighbours
    for i in range(n):
        if agg[i] >= 0:
            continue
        for s in range(row_ptr[i], row_ptr[i + 1]):
            if agg[col[s]] < 0:
                agg[col[s]] = count
        agg[i] = count
        count += 1
    return agg, count


def coarse_pattern(row_ptr, col, agg, nc):
    """The pattern of the next level and where each block slot of this one goes: returns
    (row_ptr, col, slot_map) with block (i, j) of this level summed into slot slot_map[s] =
    (agg i, agg j) of the next."""
    n = len(row_ptr) - 1
    rows = np.repeat(np.arange(n), np.diff(row_ptr))
    key = agg[rows] * nc + agg[col]
    ukey = np.unique(key)
    counts = np.bincount(ukey // nc, minlength=nc)
    return (np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            (ukey % nc).astype(np.int64), np.searchsorted(ukey, key).astype(np.int64))


def transposes(row_ptr, col):
    """The slot of each block's transpose in a symmetric pattern: block (i, j) → slot of
    (j, i)."""
    n = len(row_ptr) - 1
    rows = np.repeat(np.arange(n), np.diff(row_ptr))
    return np.searchsorted(rows * n + col, col * n + rows).astype(np.int64)


def coarsen(row_ptr, col, graph, coarsest):
    """Levels down to at most ``coarsest`` nodes: the first aggregation follows ``graph`` =
    (row_ptr, col) (the triangle adjacency: bending widens the matrix pattern, which would make
    aggregates too large), the next ones each coarse pattern. Returns a list of (row_ptr, col)
    per level and a list of (agg, slot_map) per level but the last."""
    levels, maps = [(row_ptr, col)], []
    while len(levels[-1][0]) - 1 > coarsest:
        rp, cl = levels[-1]
        agg, nc = aggregate(*(graph if not maps else (rp, cl)))
        if nc >= len(rp) - 1:  # cannot coarsen further
            break
        crp, ccl, slot_map = coarse_pattern(rp, cl, agg, nc)
        levels.append((crp, ccl))
        maps.append((agg, slot_map))
    return levels, maps
