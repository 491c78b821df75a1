"""Exact intersection test of triangle meshes: does any edge cross a triangle?

Two triangles that share no vertex intersect exactly when an edge of one meets
the other (closed sets: touching counts). Segment pq meets triangle abc when p
and q are not strictly on one side of the plane abc and the line pq passes on
the same side of the three edges: the signs of orient3d(p, q, a, b),
orient3d(p, q, b, c), orient3d(p, q, c, a) do not differ (Möller–Trumbore
in predicate form); when p, q, a, b, c are coplanar it is the 2D test in the
plane. The signs come from Shewchuk's orient3d with his static error bound
(1997, "Adaptive precision floating-point arithmetic and fast robust geometric
predicates", errboundA): a sign the bound cannot certify (near-coplanar points)
is decided again in exact rational arithmetic, so the answer is exact for the
floating-point input. Pairs sharing a vertex are not tested (as in IPC).
"""

from fractions import Fraction

import numpy as np

from clothtool.contact.broadphase import box_pairs, element_boxes, mesh_edges, vertex_boxes
from clothtool.numba_setup import njit, njit_inner

ERRBOUND_A = (7.0 + 56.0 * 2.0**-53) * 2.0**-53
CCW_ERRBOUND_A = (3.0 + 16.0 * 2.0**-53) * 2.0**-53
NO, YES, UNSURE = 0, 1, 2


@njit(cache=True, inline="always")
def _certain_sign(det, bound):
    """+1 or −1 when |det| exceeds its rounding-error bound, else 0 (undecided)."""
    if det > bound:
        return 1
    if -det > bound:
        return -1
    return 0


@njit(cache=True)
def orient3d(a, b, c, d):
    """Sign of det[a − d; b − d; c − d] (+1, −1), or 0 when rounding could have changed it."""
    adx, bdx, cdx = a[0] - d[0], b[0] - d[0], c[0] - d[0]
    ady, bdy, cdy = a[1] - d[1], b[1] - d[1], c[1] - d[1]
    adz, bdz, cdz = a[2] - d[2], b[2] - d[2], c[2] - d[2]
    bdxcdy, cdxbdy = bdx * cdy, cdx * bdy
    cdxady, adxcdy = cdx * ady, adx * cdy
    adxbdy, bdxady = adx * bdy, bdx * ady
    det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady)
    permanent = ((abs(bdxcdy) + abs(cdxbdy)) * abs(adz) + (abs(cdxady) + abs(adxcdy)) * abs(bdz)
                 + (abs(adxbdy) + abs(bdxady)) * abs(cdz))
    return _certain_sign(det, ERRBOUND_A * permanent)


@njit_inner(cache=True)
def orient2d(a, b, c, i, j):
    """Sign of the 2D orientation of a, b, c in coordinates (i, j), or 0 when uncertain
    (Shewchuk's ccwerrboundA)."""
    left = (a[i] - c[i]) * (b[j] - c[j])
    right = (a[j] - c[j]) * (b[i] - c[i])
    det = left - right
    return _certain_sign(det, CCW_ERRBOUND_A * (abs(left) + abs(right)))


@njit_inner(cache=True)
def _separated_in_projection(p, q, a, b, c):
    """True when the projections of pq and abc onto a coordinate plane are certainly apart
    (a separating axis among the edge normals of both): then so are pq and abc."""
    e1, e2 = b - a, c - a
    n0 = abs(e1[1] * e2[2] - e1[2] * e2[1])
    n1 = abs(e1[2] * e2[0] - e1[0] * e2[2])
    n2 = abs(e1[0] * e2[1] - e1[1] * e2[0])
    i, j = (1, 2) if n0 >= n1 and n0 >= n2 else ((2, 0) if n1 >= n2 else (0, 1))
    for u, v, w in ((a, b, c), (b, c, a), (c, a, b)):
        side = orient2d(u, v, w, i, j)
        if side != 0 and orient2d(u, v, p, i, j) == -side and orient2d(u, v, q, i, j) == -side:
            return True
    sa = orient2d(p, q, a, i, j)
    return sa != 0 and orient2d(p, q, b, i, j) == sa and orient2d(p, q, c, i, j) == sa


@njit(cache=True)
def segment_triangle(p, q, a, b, c):
    """NO or YES when the filtered signs decide whether segment pq meets triangle abc, else UNSURE."""
    s1, s2 = orient3d(a, b, c, p), orient3d(a, b, c, q)
    if s1 != 0 and s1 == s2:
        return NO
    t1, t2, t3 = orient3d(p, q, a, b), orient3d(p, q, b, c), orient3d(p, q, c, a)
    if t1 * t2 < 0 or t2 * t3 < 0 or t3 * t1 < 0:
        return NO
    if s1 * s2 < 0 and t1 != 0 and t1 == t2 and t2 == t3:
        return YES
    if _separated_in_projection(p, q, a, b, c):  # near-coplanar but apart
        return NO
    return UNSURE


def _exact_orient3d(a, b, c, d):
    """Sign of det[a − d; b − d; c − d] in rational arithmetic (floats convert exactly)."""
    a, b, c, d = ([Fraction(float(v)) for v in p] for p in (a, b, c, d))
    ad = [a[i] - d[i] for i in range(3)]
    bd = [b[i] - d[i] for i in range(3)]
    cd = [c[i] - d[i] for i in range(3)]
    det = (ad[2] * (bd[0] * cd[1] - cd[0] * bd[1]) + bd[2] * (cd[0] * ad[1] - ad[0] * cd[1])
           + cd[2] * (ad[0] * bd[1] - bd[0] * ad[1]))
    return (det > 0) - (det < 0)


def _orient2d(a, b, c):
    det = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return (det > 0) - (det < 0)


def _on_segment(a, b, p):
    """p collinear with a, b: is it within their box?"""
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


def _segments_meet_2d(p, q, a, b):
    o1, o2, o3, o4 = _orient2d(p, q, a), _orient2d(p, q, b), _orient2d(a, b, p), _orient2d(a, b, q)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return ((o1 == 0 and _on_segment(p, q, a)) or (o2 == 0 and _on_segment(p, q, b))
            or (o3 == 0 and _on_segment(a, b, p)) or (o4 == 0 and _on_segment(a, b, q)))


def _inside_2d(p, a, b, c):
    s = (_orient2d(a, b, p), _orient2d(b, c, p), _orient2d(c, a, p))
    return not (min(s) < 0 < max(s))


def exact_segment_triangle(p, q, a, b, c):
    """Does segment pq meet the closed triangle abc? Exact for float input."""
    s1, s2 = _exact_orient3d(a, b, c, p), _exact_orient3d(a, b, c, q)
    if s1 * s2 > 0:
        return False
    if s1 == 0 and s2 == 0:  # coplanar: drop the axis of the largest normal component
        pts = [[Fraction(float(v)) for v in pt] for pt in (p, q, a, b, c)]
        e1 = [pts[3][i] - pts[2][i] for i in range(3)]
        e2 = [pts[4][i] - pts[2][i] for i in range(3)]
        n = [abs(e1[1] * e2[2] - e1[2] * e2[1]), abs(e1[2] * e2[0] - e1[0] * e2[2]),
             abs(e1[0] * e2[1] - e1[1] * e2[0])]
        drop = n.index(max(n))
        keep = [i for i in range(3) if i != drop]
        p2, q2, a2, b2, c2 = ([pt[i] for i in keep] for pt in pts)
        if max(n) == 0:  # a degenerate triangle: its three edges as segments
            return any(_segments_meet_2d(p2, q2, u, v) for u, v in ((a2, b2), (b2, c2), (c2, a2)))
        return (_inside_2d(p2, a2, b2, c2) or _inside_2d(q2, a2, b2, c2)
                or any(_segments_meet_2d(p2, q2, u, v) for u, v in ((a2, b2), (b2, c2), (c2, a2))))
    t = (_exact_orient3d(p, q, a, b), _exact_orient3d(p, q, b, c), _exact_orient3d(p, q, c, a))
    return not (min(t) < 0 < max(t))


@njit(cache=True)
def _edge_face_candidates(x, edges, faces, obstacle):
    """Edge–face pairs whose boxes touch, filtered, with their filtered verdict (K,)."""
    vlo, vhi = vertex_boxes(x, np.zeros_like(x), np.zeros(x.shape[0]))
    elo, ehi = element_boxes(vlo, vhi, edges)
    flo, fhi = element_boxes(vlo, vhi, faces)
    pairs = box_pairs(elo, ehi, edges, flo, fhi, faces, 0.0, obstacle, True, False)
    verdict = np.empty(pairs.shape[0], dtype=np.int64)
    for k in range(pairs.shape[0]):
        e, f = edges[pairs[k, 0]], faces[pairs[k, 1]]
        verdict[k] = segment_triangle(x[e[0]], x[e[1]], x[f[0]], x[f[1]], x[f[2]])
    return pairs, verdict


def intersecting_pairs(x, faces, obstacle=None, edges=None):
    """(K, 2) array of (edge, face) index pairs that intersect, exactly.

    x: (N, 3) vertices of the cloth and colliders; faces: (M, 3); obstacle: (N,) bool,
    True for collider vertices (pairs of two collider elements are not tested);
    edges: (E, 2), by default every edge of the faces once.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    edges = mesh_edges(faces) if edges is None else np.ascontiguousarray(edges, dtype=np.int64)
    obstacle = (np.zeros(len(x), dtype=np.bool_) if obstacle is None
                else np.ascontiguousarray(obstacle, dtype=np.bool_))
    pairs, verdict = _edge_face_candidates(x, edges, faces, obstacle)
    hit = verdict == YES
    for k in np.flatnonzero(verdict == UNSURE):
        e, f = edges[pairs[k, 0]], faces[pairs[k, 1]]
        hit[k] = exact_segment_triangle(x[e[0]], x[e[1]], x[f[0]], x[f[1]], x[f[2]])
    return pairs[hit]


def has_intersections(x, faces, obstacle=None, edges=None):
    """True when some edge meets some triangle it shares no vertex with (exact)."""
    return len(intersecting_pairs(x, faces, obstacle, edges)) > 0
