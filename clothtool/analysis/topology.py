"""Connectivity tables of a triangle mesh, built once per topology with numpy sorting.

Nothing here loops over vertices in Python: every table comes from sorting the
3·M half-edges of the faces and grouping equal keys.
"""

import numpy as np


def _half_edges(faces):
    """(source, destination, opposite corner) of the 3·M half-edges, zero-length ones dropped."""
    faces = np.asarray(faces, dtype=np.int64)
    src = faces[:, [0, 1, 2]].ravel()
    dst = faces[:, [1, 2, 0]].ravel()
    opp = faces[:, [2, 0, 1]].ravel()
    keep = src != dst
    return src[keep], dst[keep], opp[keep]


def one_ring(faces, n_vertices):
    """Compressed one-ring table: the neighbours of vertex i are ``neighbours[offsets[i]:offsets[i+1]]``.

    A neighbour is a vertex sharing an edge with i; each is listed once, in increasing order,
    and i itself is not listed. Vertices on no face have an empty ring.
    Returns ``offsets`` (N+1,) and ``neighbours`` (K,), both int64.
    """
    src, dst, _ = _half_edges(faces)
    n = np.int64(n_vertices)
    key = np.unique(np.concatenate([src * n + dst, dst * n + src]))  # sorted by (source, dest)
    owner = key // n
    offsets = np.searchsorted(owner, np.arange(n + 1, dtype=np.int64)).astype(np.int64)
    return offsets, (key % n).astype(np.int64)


def interior_edges(faces, n_vertices):
    """Edges shared by exactly two faces, with the corner opposite the edge in each face.

    Returns ``edges`` (E, 2) with ``edges[:, 0] < edges[:, 1]``, sorted, and ``opposite`` (E, 2).
    ``opposite[:, 0]`` is the third corner of a face that runs i → j (so the triangle
    (i, j, opposite[0]) carries the mesh orientation); if neither face runs i → j (an
    inconsistently oriented pair) it is the third corner of the face listed first.
    Boundary edges (one face) and non-manifold edges (three or more) are left out.
    """
    src, dst, opp = _half_edges(faces)
    n = np.int64(n_vertices)
    lo, hi = np.minimum(src, dst), np.maximum(src, dst)
    key = lo * n + hi
    backward = src > dst
    order = np.lexsort((backward, key))  # by edge, then the i → j half-edge first
    key, lo, hi, opp = key[order], lo[order], hi[order], opp[order]
    _, start, count = np.unique(key, return_index=True, return_counts=True)
    first = start[count == 2]
    edges = np.stack([lo[first], hi[first]], axis=1)
    opposite = np.stack([opp[first], opp[first + 1]], axis=1)
    return edges, opposite
