"""Seams: panels that lie apart in the file, sewn together and then welded.

``mesh.seams`` pairs two boundary polylines of the garment, vertex a[i] with b[i]. Each
side must be a chain of boundary edges; the two sides must run opposite ways around their
panels (as the two half-edges of one edge of an oriented surface do, so the sewn garment
keeps one orientation) and have the same rest length in the pattern within
``mesh.seam_tolerance`` (relative), or the seam would be sewn under strain.

Sewing is the :class:`~clothtool.sim.energies.terms.Stitch` term W = ½ Σ k_i ‖x_{a_i} − x_{b_i}‖² in the
incremental potential, so it goes through the same Newton steps, CCD and self-collision
barrier as everything else and stays intersection-free; k_i = ``mesh.sewing.stiffness`` ×
the seam length around pair i (the mean of its sides' half-edges), so a seam pulls with the
same force per metre at any resolution. Once every pair is within ``mesh.sewing.weld`` (by
default the self-collision thickness: as close as the barrier lets two surfaces come), the
pairs are welded: each group of sewn vertices becomes one vertex at their mean position and
velocity, each triangle keeps its own corners' rest shape (its pattern), and the garment is
finalized again without stitches. The weld is made only when that welded garment's start
passes the contact's start check (no crossing, no pair inside the barrier's wall): each
pair's jump to its mean moves a vertex up to half the weld distance, farther than the wall's
depth that the barrier can press cloth to, so a fold pressed against the seam could be carried
through; a weld that fails the check waits (sewing goes on) and, still failing at
``sewing.time``, stops the run naming the check. Welding rather than keeping stiff stitches:
a stitch held by the barrier stays a thickness open (1–2 mm), its pairs cost barrier terms for the rest of
the run, and no hinge bends across it; the welded seam is closed (0 mm) and bends like cloth.
"""

import numpy as np

from clothtool.errors import InputError, NumericalError
from clothtool.sim.model.mesh import RestMesh


WELD = 1.25  # default weld distance in self-collision thicknesses: the barrier reaches a little
# beyond the thickness, so a stitch held off by it rests just outside; a quarter more welds it


def add_config_seams(builder, mesh_spec, scene):
    """Check ``mesh.seams`` against the mesh and add its stitches to the builder. A seam the
    file has closed already (its pairs welded at the start, ``mesh.weld_closed``) is
    satisfied: it is checked, not sewn, and listed in ``builder.listed_closed``."""
    if not mesh_spec.seams:
        return
    mesh = builder.mesh if builder.file_mesh is None else builder.file_mesh  # the file's vertices
    if mesh.corner_uv is None and mesh.uv is None:
        raise InputError(f"{mesh.path}: mesh.seams need the panels' rest pattern (texture "
                         "coordinates: OBJ vt, PLY face texcoord or s t)")
    pairs, stiffness, lines = [], [], None
    for k, seam in enumerate(mesh_spec.seams):
        key, sides = f"mesh.seams[{k}]", []
        for side, given in (("a", seam.a), ("b", seam.b)):
            if isinstance(given, str):
                if lines is None:
                    lines = _line_groups(mesh)
                given = group_side(mesh, lines, given, forward=side == "a",
                                   key=f"{key}.{side}")
            sides.append(given)
        if len(sides[0]) != len(sides[1]):
            raise InputError(f"{mesh.path}: {key}: a has {len(sides[0])} vertices and b "
                             f"{len(sides[1])}; a[i] is sewn to b[i]")
        a, b, length = check_seam(mesh, *sides, mesh_spec.seam_tolerance, key)
        a, b = builder.to_model(a), builder.to_model(b)
        apart = a != b  # pairs welded at the start (mesh.weld_closed) are sewn already
        if not apart.all():
            builder.listed_closed.append((key, seam.a, seam.b, int((~apart).sum()), len(a)))
        pairs.append(np.stack([a[apart], b[apart]], axis=1))
        stiffness.append(mesh_spec.sewing.stiffness * length[apart])
    if not sum(len(p) for p in pairs):
        return  # every seam closed in the file: nothing to sew
    builder.add_stitches(np.concatenate(pairs), np.concatenate(stiffness))
    x = builder.mesh.positions
    builder.stitch_gap0 = np.linalg.norm(x[builder.stitches[:, 0]] - x[builder.stitches[:, 1]],
                                         axis=1)
    builder.sewing = mesh_spec.sewing
    builder.weld_distance = (mesh_spec.sewing.weld if mesh_spec.sewing.weld is not None
                             else WELD * scene.self_collision.thickness)
    check_apart(builder.mesh, "lay them out apart before sewing")


def _line_groups(mesh):
    from clothtool.io.obj_groups import line_groups

    if mesh.path is None or not str(mesh.path).lower().endswith(".obj"):
        raise InputError(f"{mesh.path or 'mesh'}: a seam side by group name needs mesh.obj")
    return line_groups(mesh.path)


def group_side(mesh, lines, name, *, forward, key):
    """The vertex list of the seam side named by OBJ group ``name``: the group's boundary
    edges (its ``l`` segments, and those of its triangles' edges on the mesh boundary) in
    their order along one open polyline, running along its panel's boundary (``forward``,
    side a) or against it (side b), so that a[i] and b[i] meet as an oriented surface's
    two half-edges do."""
    edges = boundary_edges(mesh.faces)
    own = lines.get(name, np.zeros((0, 2), np.int64))
    faces = (mesh.groups or {}).get(name)
    if faces is not None:
        inside = np.zeros(len(mesh.faces), bool)
        inside[faces] = True
        own = np.concatenate([own, np.array([e for e, t in edges.items() if inside[t]],
                                            np.int64).reshape(-1, 2)])
    where = f"{mesh.path}: {key}"
    if name not in lines and faces is None:
        known = sorted(set(lines) | set(mesh.groups or {}))
        raise InputError(f"{where}: no group {name!r} in the OBJ (its groups: "
                         f"{', '.join(known) or 'none'})")
    chain = _polyline(np.unique(np.sort(own, axis=1), axis=0))
    if chain is None:
        raise InputError(f"{where}: group {name!r}'s boundary edges are not one open polyline")
    p, q = chain[0], chain[1]
    if (p, q) not in edges and (q, p) not in edges:
        raise InputError(f"{where}: group {name!r}: vertices {p} and {q} are not a boundary "
                         "edge of the mesh")
    along = (p, q) in edges
    return chain if along == forward else chain[::-1]


def _polyline(edges):
    """The vertices of the undirected ``edges`` (K, 2) in order along one open polyline, or
    None when they are not one (empty, a loop, branched or in pieces)."""
    if len(edges) == 0:
        return None
    ids, degree = np.unique(edges, return_counts=True)
    ends = ids[degree == 1]
    if len(ends) != 2 or degree.max() > 2:
        return None
    neighbours = {int(v): [] for v in ids}
    for i, j in edges:
        neighbours[int(i)].append(int(j))
        neighbours[int(j)].append(int(i))
    chain, previous = [int(ends[0])], None
    while len(chain) <= len(edges):
        step = [v for v in neighbours[chain[-1]] if v != previous]
        if not step:
            break
        previous = chain[-1]
        chain.append(step[0])
    return chain if len(chain) == len(edges) + 1 else None


def boundary_edges(faces):
    """{(i, j): triangle} of the boundary half-edges i → j (edges of one triangle)."""
    half = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    tri = np.tile(np.arange(len(faces)), 3)
    key = np.sort(half, axis=1)
    _, inverse, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = count[inverse.ravel()] == 1
    return {(int(i), int(j)): int(t) for (i, j), t in zip(half[once], tri[once])}


def check_seam(mesh, a, b, tolerance, key):
    """(a, b, length (S,)): the checked sides of one seam and the seam length around each
    pair; an InputError naming the file and the seam otherwise."""
    where = f"{mesh.path}: {key}" if mesh.path is not None else key
    n = len(mesh.positions)
    a, b = np.asarray(a, np.int64), np.asarray(b, np.int64)
    for side, ids in (("a", a), ("b", b)):
        out = np.flatnonzero(ids >= n)
        if len(out):
            raise InputError(f"{where}.{side}[{out[0]}]: vertex {int(ids[out[0]])} out of range "
                             f"(the mesh has {n} vertices)")
    if len(a) < 2:
        raise InputError(f"{where}: a seam needs at least 2 vertices on each side")
    both = np.concatenate([a, b])
    values, counts = np.unique(both, return_counts=True)
    if np.any(counts > 1):
        raise InputError(f"{where}: vertex {int(values[np.argmax(counts > 1)])} appears twice "
                         "(the two sides of a seam are different vertices)")
    edges = boundary_edges(mesh.faces)
    signs, lengths = [], []
    for side, ids in (("a", a), ("b", b)):
        sign, seg = 0, np.empty(len(ids) - 1)
        for i in range(len(ids) - 1):
            p, q = int(ids[i]), int(ids[i + 1])
            forward, backward = (p, q) in edges, (q, p) in edges
            if not (forward or backward):
                raise InputError(f"{where}.{side}: vertices {p} and {q} (items {i} and {i + 1}) "
                                 "are not a boundary edge of the mesh")
            s = 1 if forward else -1
            if sign and s != sign:
                raise InputError(f"{where}.{side}: the polyline turns back at item {i} (a side "
                                 "runs one way along the boundary)")
            sign = s
            tri = edges[(p, q) if forward else (q, p)]
            seg[i] = _rest_edge_length(mesh, tri, p, q)
        signs.append(sign)
        lengths.append(seg)
    if signs[0] == signs[1]:
        raise InputError(f"{where}: a and b run the same way around their panels; the two sides "
                         "of a seam run opposite ways (reverse b)")
    la, lb = float(lengths[0].sum()), float(lengths[1].sum())
    if abs(la - lb) > tolerance * max(la, lb):
        raise InputError(f"{where}: side a is {la:.6g} m long and b {lb:.6g} m in the pattern, "
                         f"{abs(la - lb) / max(la, lb):.3g} apart (mesh.seam_tolerance "
                         f"{tolerance:g})")
    seg = 0.5 * (lengths[0] + lengths[1])  # the seam length around each pair: half of each
    around = np.zeros(len(a))
    around[:-1] += 0.5 * seg
    around[1:] += 0.5 * seg
    return a, b, around


def _rest_edge_length(mesh, tri, p, q):
    """Rest (pattern) length of the edge p–q of triangle tri."""
    face = mesh.faces[tri]
    if mesh.corner_uv is not None:
        uv = mesh.corner_uv[tri]
        d = uv[int(np.argmax(face == q))] - uv[int(np.argmax(face == p))]
    elif mesh.uv is not None:
        d = mesh.uv[q] - mesh.uv[p]
    else:
        d = mesh.rest3d[q] - mesh.rest3d[p]
    return float(np.sqrt(d @ d))


def check_apart(mesh, hint):
    """InputError when two panels cross each other in the file (they must start apart),
    naming the pair, then ``hint``."""
    from clothtool.contact.intersect import intersecting_pairs
    from clothtool.contact.broadphase import mesh_edges

    edges = mesh_edges(mesh.faces)
    crossing = intersecting_pairs(mesh.positions, mesh.faces, None, edges)
    if len(crossing) == 0:
        return
    edge, face = edges[crossing[0][0]], int(crossing[0][1])
    tri = int(np.flatnonzero(np.isin(mesh.faces, edge).sum(axis=1) == 2)[0])
    raise InputError(f"{mesh.path or 'mesh'}: the panels overlap at the start: triangle {tri} "
                     f"crosses triangle {face}; {hint}")


def seam_gap(model, x):
    """The largest distance between sewn pairs at positions x (0 without stitches)."""
    if model.stitches is None:
        return 0.0
    return float(model.stitches.gaps(x).max())


def sewn(model, x, builder):
    """Are the seams within the weld distance at positions x?"""
    return model.stitches is not None and seam_gap(model, x) <= builder.weld_distance


LAG, CLOSE = 0.1, 0.5  # the goal gap: held for LAG × sewing.time, then closed in CLOSE × it
RAISE, MOST = 2.0, 2.0 ** 24  # a pair behind its goal: its stiffness × RAISE, up to MOST × its own


def goal_gaps(builder, t):
    """(S,) the gap each stitch pair should be within at time t: its gap at the start, held
    for LAG × ``sewing.time`` and then closing at a constant rate to 0 at (LAG + CLOSE) ×
    ``sewing.time`` (never below the weld distance)."""
    T = builder.sewing.time
    left = np.clip(1.0 - (t - LAG * T) / (CLOSE * T), 0.0, 1.0)
    return np.maximum(builder.stitch_gap0 * left, builder.weld_distance)


def tighten(model, x, t, builder):
    """Raise the stiffness of the stitch pairs behind their goal gap (:func:`goal_gaps`) by
    RAISE (up to MOST × their own): a seam closes on schedule whatever the panels' stiffness,
    unless contact holds it open. The builder's largest stiffness N/m per metre of seam after
    the raise, or None when none was behind."""
    behind = model.stitches.gaps(x) > goal_gaps(builder, t)
    k, k0 = builder.stitch_stiffness, builder.stitch_stiffness0
    behind &= k < MOST * k0
    if not behind.any():
        return None
    k[behind] = np.minimum(k[behind] * RAISE, MOST * k0[behind])
    return float((k / k0).max()) * builder.sewing.stiffness


def check_sewing(model, x, t, builder, frame):
    """NumericalError when the sewing has run ``mesh.sewing.time`` without closing."""
    if model.stitches is None or t < builder.sewing.time:
        return
    gaps = model.stitches.gaps(x)
    s = int(np.argmax(gaps))
    a, b = model.stitches.elements[s]
    raise NumericalError(f"simulation failed at frame {frame}: mesh.seams did not close in "
                         f"mesh.sewing.time ({builder.sewing.time:g} s): vertices {int(a)} and "
                         f"{int(b)} are {gaps[s]:.3g} m apart (mesh.sewing.weld "
                         f"{builder.weld_distance:g} m) with the stitch stiffness raised to "
                         f"{stitch_level(builder):.3g} N/m per metre of seam (unless contact holds "
                         "them apart, a longer mesh.sewing.time closes them)")


def sewing_gap_text(model, x):
    """'vertices a and b are d mm apart' of the farthest stitch pair."""
    gaps = model.stitches.gaps(x)
    s = int(np.argmax(gaps))
    a, b = model.stitches.elements[s]
    return f"vertices {int(a)} and {int(b)} are {1e3 * gaps[s]:.3g} mm apart"


def stitch_level(builder):
    """The largest stitch stiffness now, in N/m per metre of seam."""
    return float((builder.stitch_stiffness / builder.stitch_stiffness0).max()) \
        * builder.sewing.stiffness


def weld(builder, model, state):
    """The welded garment's (mesh, t = 0 positions, file vertex map, pinned vertices, pin
    motions) and the state on it: each group of sewn vertices one vertex at
    their mean position and velocity (see the module)."""
    mesh, n = builder.mesh, len(builder.mesh.positions)
    root = np.arange(n)
    for a, b in model.stitches.elements:  # union-find: the smallest index of each group
        ra, rb = _find(root, a), _find(root, b)
        root[max(ra, rb)] = min(ra, rb)
    root = np.array([_find(root, v) for v in range(n)])
    keep, new = np.unique(root, return_inverse=True)
    count = np.bincount(new, minlength=len(keep)).astype(np.float64)[:, None]

    def merge(values):
        out = np.zeros((len(keep),) + values.shape[1:])
        np.add.at(out, new, values)
        return out / count

    origin = builder.origin if builder.origin is not None else mesh.positions
    x = merge(state.x)
    corner = mesh.corner_uv if mesh.corner_uv is not None else mesh.uv[mesh.faces]
    welded = RestMesh(x.copy(), new[mesh.faces], None, None, x.copy(), corner, mesh.groups,
                      mesh.path)
    file_vertex = new if builder.file_vertex is None else new[builder.file_vertex]
    pinned = np.unique(new[builder.pinned])
    motions = [type(m)(np.unique(new[m.vertices]), m.motion) for m in builder.pin_motions]
    state.x, state.v = x, merge(state.v)
    if state.x_prev is not None:
        state.x_prev, state.v_prev = merge(state.x_prev), merge(state.v_prev)
    return (welded, merge(origin), file_vertex, pinned, motions), state


def _find(root, v):
    while root[v] != v:
        root[v] = root[root[v]]
        v = root[v]
    return v


def _apart(points, tolerance):
    """True when no two of ``points`` (K, 3) lie within ``tolerance`` of each other, shown
    without the KD-tree (a single sheet's rim, the common case, then imports none of scipy's
    sparse and spatial modules: about 0.3 s of CPU): every pair closer than a reach a little
    over ``tolerance`` (a margin over either side's rounding) is within it along the widest
    axis, so a sort along that axis and the squared distances of those candidates decide.
    False when some pair is within the reach, or the candidates are too many to list (the
    KD-tree then decides)."""
    extent = points.max(axis=0) - points.min(axis=0)
    axis = int(np.argmax(extent))
    reach = tolerance * (1.0 + 1e-6) + 8.0 * np.finfo(float).eps * float(np.abs(points).max())
    p = points[np.argsort(points[:, axis], kind="stable")]
    key = p[:, axis]
    after = np.searchsorted(key, key + reach, side="right") - np.arange(len(p)) - 1
    total = int(after.sum())
    if total > 50 * len(p) + 100000:
        return False
    i = np.repeat(np.arange(len(p)), after)
    j = i + 1 + np.arange(total) - np.repeat(np.cumsum(after) - after, after)
    d = p[i] - p[j]
    return not np.any(np.einsum("ij,ij->i", d, d) <= reach * reach)


def weld_closed_seams(mesh, tolerance):
    """(mesh, file_vertex, found) of a garment whose seams are already closed in the file (each
    panel with its own vertices along a seam, at the same positions, as pattern software
    exports a sewn garment): boundary vertices of different panels (connected pieces of the
    mesh) within ``tolerance`` m of each other are welded into one vertex at their mean
    position; each triangle keeps its own corners' rest shape. ``file_vertex`` (N_file,) is
    the welded vertex of each vertex of the file, ``found`` a list of (panel, panel, vertices,
    length m) per pair of panels welded. Nothing to weld: (mesh, None, [])."""
    n = len(mesh.positions)
    edges = boundary_edges(mesh.faces)
    rim = np.unique(np.array(list(edges), np.int64).reshape(-1, 2))
    if len(rim) < 2 or _apart(mesh.positions[rim], tolerance):
        return mesh, None, []
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    close = cKDTree(mesh.positions[rim]).query_pairs(tolerance, output_type="ndarray")
    if len(close) == 0:
        return mesh, None, []
    f = mesh.faces
    graph = coo_matrix((np.ones(3 * len(f)), (f.ravel(), np.roll(f, 1, axis=1).ravel())),
                       shape=(n, n))
    _, panel = connected_components(graph, directed=False)
    pairs = rim[close]
    same = np.flatnonzero(panel[pairs[:, 0]] == panel[pairs[:, 1]])
    if len(same):
        i, j = (int(v) for v in pairs[same[0]])
        d = float(np.linalg.norm(mesh.positions[i] - mesh.positions[j]))
        raise InputError(f"mesh.weld_tolerance: {tolerance:g} m would weld vertices {i} and {j} "
                         f"of one panel ({_panel_name(mesh, panel, panel[i])}), {d:.3g} m apart; "
                         "lower it, or set mesh.weld_closed: false")
    root = np.arange(n)
    for a, b in pairs:
        ra, rb = _find(root, a), _find(root, b)
        root[max(ra, rb)] = min(ra, rb)
    root = np.array([_find(root, v) for v in range(n)])
    keep, new = np.unique(root, return_inverse=True)
    count = np.bincount(new, minlength=len(keep)).astype(np.float64)[:, None]
    x = np.zeros((len(keep), 3))
    np.add.at(x, new, mesh.positions)
    x /= count
    corner = mesh.corner_uv if mesh.corner_uv is not None else (
        mesh.uv[f] if mesh.uv is not None else None)
    rest = x.copy() if corner is not None else None
    if rest is None:  # a mesh resting in its own shape: the welded vertices' mean rest position
        rest = np.zeros((len(keep), 3))
        np.add.at(rest, new, mesh.rest3d)
        rest /= count
    welded = RestMesh(x, new[f], None, None, rest, corner, mesh.groups, mesh.path)
    members = {}  # each weld's panels
    for v in np.flatnonzero(root != np.arange(n)):
        members.setdefault(int(root[v]), set()).update((int(panel[v]), int(panel[root[v]])))
    seams = {}  # (panel, other panel): [vertices of the first, length of its welded edges m]
    for v, r in enumerate(root):
        for q in members.get(int(r), ()):
            if q != panel[v]:
                seams.setdefault((int(panel[v]), q), [0, 0.0])[0] += 1
    for i, j in edges:
        for q in members.get(int(root[i]), set()) & members.get(int(root[j]), set()):
            if q != panel[i]:
                seams[(int(panel[i]), q)][1] += float(np.linalg.norm(mesh.positions[j]
                                                                     - mesh.positions[i]))
    found = [(_panel_name(mesh, panel, p), _panel_name(mesh, panel, q), count, length)
             for (p, q), (count, length) in sorted(seams.items()) if p < q]
    return welded, new, found


def _panel_name(mesh, panel, p):
    """An OBJ group holding panel p's triangles (the smallest), or 'panel p'."""
    tri = np.flatnonzero(panel[mesh.faces[:, 0]] == p)
    names = [(len(t), name) for name, t in (mesh.groups or {}).items()
             if len(t) and np.isin(tri, t).all()]
    return min(names)[1] if names else f"panel {p}"
