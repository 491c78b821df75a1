"""The textile lab's tests as the simulator meets them: specimens and their known answers.

Specimens are flat patterns (uv in metres, counter-clockwise triangles) on a regular grid,
a grid turned 45°, or an irregular (Delaunay) mesh:

- :func:`strip`: a strip along +u from a clamp, for the cantilever test (ASTM D1388) and
  the hanging strip; :func:`disc`: the Cusick drape test's disc (BS 5058).

Known answers:

- :func:`elastica_tip_drop`: a strip clamped flat, k_b θ'' = −ρg(L − s) cos θ, θ(0) = 0,
  θ'(L) = 0 (scipy's ``solve_bvp``); tip drop ∫₀ᴸ sin θ ds; ρgL⁴/(8k_b) for small drops;
- :func:`bias_modulus`: the small-strain tensile stiffness (N/m) at 45° to warp and weft of
  the stretch and shear energy k_u/2 ε_uu² + k_v/2 ε_vv² + k_h/2 (2ε_uv)²:
  1/(1/(2K) + 1/(4k_h)), K = 2k_u k_v/(k_u + k_v) (uniaxial stress, free contraction);
  a strip hanging under its own weight lengthens by ρgL²/(2k) for the stiffness k along it;
- :func:`drape_coefficient`: (A_shadow − A_pedestal)/(A_disc − A_pedestal); :func:`drape_error`
  its discretisation error at a mesh size, :func:`drape_folds` the folds of a draped disc.

The tests on a material (the config's ``material`` keys): :func:`cusick_drape` simulates the
drape tester, :func:`cantilever_bending_length` the cantilever and reads its bending length.
"""

import numpy as np

from clothtool.geometry import grid_triangles
from clothtool.sim.model.config import STANDARD_GRAVITY

JITTER = 0.35  # a ``jittered`` strip's vertices move by up to this fraction of the spacing


def elastica_tip_drop(length, bend, density, gravity=STANDARD_GRAVITY):
    """Vertical tip drop (m) of a cantilever of ``length`` m clamped flat (large deflections)."""
    from scipy.integrate import solve_bvp

    q = density * gravity / bend
    s = np.linspace(0.0, length, 201)

    def rhs(s, y):
        return np.vstack([y[1], -q * (length - s) * np.cos(y[0])])

    def ends(a, b):
        return np.array([a[0], b[1]])

    sol = solve_bvp(rhs, ends, s, np.zeros((2, len(s))), tol=1e-10, max_nodes=100000)
    if not sol.success:
        raise ArithmeticError(f"elastica: {sol.message}")
    fine = np.linspace(0.0, length, 20001)
    return float(np.trapezoid(np.sin(sol.sol(fine)[0]), fine))


def bias_modulus(stretch_u, stretch_v, shear):
    """Small-strain stiffness (N/m) of a strip cut at 45° to warp (u) and weft (v)."""
    k = 2.0 * stretch_u * stretch_v / (stretch_u + stretch_v)
    return 1.0 / (1.0 / (2.0 * k) + 1.0 / (4.0 * shear))


def drape_coefficient(x, faces, pedestal_radius, disc_radius, centre, up=(0.0, 0.0, 1.0),
                      pixels=1024):
    """Cusick drape coefficient of a draped disc: its shadow seen along ``up`` around the
    pedestal's ``centre`` (rasterised on a pixels² grid over the disc's radius), less the
    pedestal, over the annulus of the flat disc."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    a = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    b = np.cross(up, a)
    centre = np.asarray(centre, np.float64)
    p = np.stack([(x - centre) @ a, (x - centre) @ b], axis=1)
    shadow = _rasterise(p, faces, disc_radius, pixels)
    pedestal = np.pi * pedestal_radius ** 2
    return (shadow - pedestal) / (np.pi * disc_radius ** 2 - pedestal)


def _rasterise(p, faces, radius, pixels):
    """Area (m²) of the union of the 2D triangles, on a pixels² grid over [−r, r]²."""
    cell = 2.0 * radius / pixels
    centres = -radius + cell * (np.arange(pixels) + 0.5)
    covered = np.zeros((pixels, pixels), np.bool_)
    for tri in p[faces]:
        lo = np.floor((tri.min(axis=0) + radius) / cell).astype(int).clip(0, pixels - 1)
        hi = np.ceil((tri.max(axis=0) + radius) / cell).astype(int).clip(0, pixels - 1)
        gx, gy = np.meshgrid(centres[lo[0]:hi[0] + 1], centres[lo[1]:hi[1] + 1], indexing="ij")
        d = []
        for k in range(3):  # the side of edge k each pixel centre is on
            ex, ey = tri[(k + 1) % 3] - tri[k]
            d.append(ex * (gy - tri[k][1]) - ey * (gx - tri[k][0]))
        inside = ((d[0] >= 0) & (d[1] >= 0) & (d[2] >= 0)) | ((d[0] <= 0) & (d[1] <= 0) & (d[2] <= 0))
        covered[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1] |= inside
    return covered.sum() * cell * cell


def cusick_drape(material, spacing=0.01, kind="grid", *, seconds=3.0, fps=60, seed=1,
                 counts=None, exact_finish=True):
    """(drape coefficient, final state, faces) of the Cusick test (BS 5058: a 30 cm disc on an
    18 cm pedestal) of ``material`` (a mapping of ``material`` keys), simulated for
    ``seconds`` at ``fps`` (implicit, BDF2, PCG tolerance 1e-3) from the flat disc with a
    6-fold ripple of 2 mm at the rim, which seeds the folds alike on every mesh, then brought
    to rest (:func:`clothtool.sim.solve.statics.static_equilibrium` from where the run ends:
    after 3 s a 12 mm disc still creeps, 0.6 points above its rest). The disc (:func:`disc`
    of ``kind``, ``spacing`` and ``seed``) is clamped at the pedestal's radius on every mesh:
    its rings at 9 cm ± spacing/2 and every vertex within them pinned. ``exact_finish``: the
    static finish tries the membrane's exact Hessian first (``exact_hessian`` there: with
    the projected one alone, Newton is linear where the folds compress triangles and stalls
    short of rest on some 6 and 4 mm discs). ``counts``: a dict that gets the
    run's Newton and PCG iterations (``newton``, ``pcg``) and the finish's Newton steps and
    last residual (``finish``, ``residual``); the state's x is at rest, its v the run's last."""
    import tempfile

    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.methods import make_integrator
    from clothtool.sim.solve.statics import static_equilibrium

    radius, pedestal = CUSICK
    uv, faces = disc(radius, spacing, kind, seed=seed, clamp=pedestal)
    edge = pedestal + spacing / 2  # the outer pinned ring
    r, phi = np.hypot(uv[:, 0], uv[:, 1]), np.arctan2(uv[:, 1], uv[:, 0])
    with tempfile.TemporaryDirectory() as tmp:
        model = specimen_model(uv, faces, np.flatnonzero(r <= edge + 1e-9 * radius), material,
                               tmp)
    solver = load_config({"mesh": {"grid": {}}, "solver": {"tolerance": 1e-3}}).solver
    integrator = make_integrator(model, solver, 1.0 / fps)
    state = model.initial_state()
    state.x[:, 2] = -0.002 * np.clip(r - edge, 0.0, None) / (radius - edge) * np.cos(6 * phi)
    newton = pcg = 0
    for _ in range(int(round(seconds * fps))):
        result = integrator.step(state)
        newton += result.newton_iterations
        pcg += result.cg_iterations
    # to 1e-3 of the largest vertex weight (the coefficient then stands within 0.01 points)
    finish = {}
    state.x[:] = static_equilibrium(model, state.x, tolerance=1e-3, load_steps=1,
                                    max_iterations=5000, exact_hessian=exact_finish,
                                    counts=finish)
    if counts is not None:
        counts.update(newton=newton, pcg=pcg, finish=finish["newton"],
                      residual=finish["residual"])
    return drape_coefficient(state.x, faces, pedestal, radius, (0.0, 0.0, 0.0)), state, faces


def drape_error(material, spacing, coefficient, kind="grid", *, seed=1):
    """The discretisation error of a Cusick ``coefficient`` simulated at ``spacing`` (on a
    ``kind`` disc), estimated as its change from a disc √2 coarser: with an error c h² the
    coefficient at √2 h is off by 2c h², so the change is the error at h (Richardson). A
    fraction, ≥ 0; one more simulation, about a third of the first's cost."""
    coarse = cusick_drape(material, np.sqrt(2.0) * spacing, kind, seed=seed)[0]
    return abs(coefficient - coarse)


def drape_folds(x, uv, radius):
    """Folds of a draped disc: the local maxima of the rim's reach from the axis (the rim's
    vertices in order of angle) above its median."""
    r, phi = np.hypot(uv[:, 0], uv[:, 1]), np.arctan2(uv[:, 1], uv[:, 0])
    rim = np.flatnonzero(r >= radius * (1 - 1e-9))
    reach = np.hypot(x[rim, 0], x[rim, 1])[np.argsort(phi[rim])]
    return int(np.sum((reach > np.roll(reach, 1)) & (reach >= np.roll(reach, -1))
                      & (reach > np.median(reach))))


def cantilever_bending_length(material, direction="warp", divisions=20, width=0.025):
    """The bending length c (m) the simulated cantilever of ``material`` shows, cut along warp
    (u) or weft (v): a strip of overhang 2c₀ (c₀ = (B/(ρg))^(1/3) of its own ``bend`` in that
    direction) clamped flat, brought to static equilibrium; the rigidity k whose elastica
    drops its tip as far, c = (k/(ρg))^(1/3)."""
    import tempfile

    from scipy.optimize import brentq

    from clothtool.sim.model.config import STANDARD_GRAVITY, load_config
    from clothtool.sim.solve.statics import static_equilibrium

    m = load_config({"mesh": {"grid": {"nx": 2, "ny": 2}}, "material": dict(material)}).material
    bend = m.bend if isinstance(m.bend, tuple) else (m.bend, m.bend)
    rho_g = m.density * STANDARD_GRAVITY
    length = 2.0 * (bend[0 if direction == "warp" else 1] / rho_g) ** (1.0 / 3.0)
    uv, faces, held = strip(length, width, length / divisions)
    if direction == "weft":  # the strip's axis along v
        uv = uv @ np.array([[0.0, 1.0], [-1.0, 0.0]])
    with tempfile.TemporaryDirectory() as tmp:
        x = static_equilibrium(specimen_model(uv, faces, held, material, tmp))
    tip = np.flatnonzero(np.abs(uv).max(axis=1) >= length - 1e-9 * length)
    drop = -x[tip, 2].mean()
    k = brentq(lambda k: elastica_tip_drop(length, k, m.density) - drop,
               rho_g * (length / 3.0) ** 3, rho_g * length ** 3, rtol=1e-10)  # c in [2/3, 2] c₀
    return (k / rho_g) ** (1.0 / 3.0)


# ---------------------------------------------------------------------------- specimens

CUSICK = (0.15, 0.09)  # m: the disc's and the pedestal's radius (BS 5058)
CUSICK_DAMPING = 0.05  # s: the drape tests' damping, so that the disc comes to rest in 3 s


def specimen_model(uv, faces, pinned, material, folder, gravity=(0.0, 0.0, -STANDARD_GRAVITY)):
    """A :class:`~clothtool.sim.model.model.Model` of the pattern laid flat in the xy plane (its uv as
    the rest shape, written as ``folder/specimen.ply``), ``pinned`` vertex indices held,
    ``gravity`` (m/s², default down along z); ``material``: the config's material section."""
    from pathlib import Path

    from clothtool.io.ply import write_ply
    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.builder import build_model

    path = Path(folder) / "specimen.ply"
    positions = np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)
    write_ply(path, positions, faces, vertex_properties={"s": uv[:, 0].copy(), "t": uv[:, 1].copy()})
    # the lab tests keep the damping they were calibrated with unless told otherwise: frozen
    # βK brings the Cusick disc to rest in 3 s (with strain damping it rests with a drape
    # coefficient 0.3–0.4 points lower: another of its nearby equilibria)
    config = load_config({"mesh": {"ply": str(path)},
                          "material": {"damping_model": "frozen", **dict(material)},
                          "scene": {"gravity": [float(g) for g in gravity],
                                    "pins": [int(v) for v in pinned]}})
    return build_model(config)


def strip(length, width, spacing, kind="grid", *, clamp=True, seed=0):
    """A strip along +u of ``length`` m beyond its clamp, ``width`` m wide (v in ±width/2).

    ``kind``: ``grid`` (clothtool's criss-cross grid, its lines along u and v), ``across``
    (the same grid with u and v swapped: the strip runs along the grid's second axis),
    ``jittered`` (the grid with each vertex off the outline and the clamp moved by up to
    JITTER of the spacing, uniformly at random over that disc),
    ``rot45`` (a square lattice turned 45°, Delaunay-triangulated) or ``delaunay`` (jittered
    points, Delaunay). With ``clamp`` the strip starts at u = −spacing/2 and the vertices with
    u ≤ spacing/2 are the clamp (two rows on a grid): the clamp line, where the strip leaves
    it flat, is u = 0, halfway between the rows (a second-order clamp: with the line on the
    outer row the strip would be spacing/2 longer). Without it the strip spans [0, length].
    ``spacing`` is rounded so that whole intervals fit.
    Returns (uv (N, 2), faces (M, 3), clamped vertex indices).
    """
    n = max(int(round(length / spacing)), 1)
    spacing = length / (n + 0.5) if clamp else length / n  # rows at ±spacing/2 and on to the tip
    start = -spacing / 2 if clamp else 0.0
    if kind in ("grid", "across", "jittered"):
        n_along = n + 2 if clamp else n + 1
        n_across = max(int(round(width / spacing)), 1) + 1
        a = np.linspace(start, length, n_along)
        b = np.linspace(-width / 2, width / 2, n_across)
        if kind in ("grid", "jittered"):
            uv, faces = _criss_cross(a, b)
        else:
            uv, faces = _criss_cross(b, a)
            uv = uv[:, ::-1].copy()
            faces = faces[:, ::-1].copy()
        if kind == "jittered":
            tol = 1e-9 * spacing
            inner = ((uv[:, 0] > (spacing / 2 if clamp else 0.0) + tol) & (uv[:, 0] < length - tol)
                     & (np.abs(uv[:, 1]) < width / 2 - tol))
            rng = np.random.default_rng(seed)
            r = JITTER * spacing * np.sqrt(rng.uniform(0.0, 1.0, int(inner.sum())))
            phi = rng.uniform(0.0, 2.0 * np.pi, int(inner.sum()))
            uv[inner] += r[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    else:
        uv, faces = _delaunay_strip(start, length, width, spacing, kind, seed,
                                    spacing / 2 if clamp else None)
    held = np.flatnonzero(uv[:, 0] <= spacing / 2 + 1e-9 * spacing) if clamp else np.zeros(0, np.int64)
    return uv, faces, held.astype(np.int64)


def disc(radius, spacing, kind="grid", *, seed=0, clamp=None):
    """A disc of ``radius`` m centred on the origin: ``grid`` (a square grid clipped to the
    circle, with a ring of boundary points), ``rot45`` (the same grid turned 45°),
    ``delaunay`` (the grid's points jittered by up to 0.3 of the spacing), ``poisson``
    (Poisson-disc points, no two closer than 0.8 of the spacing, Bridson's dart throwing with
    ``seed``) or ``polar`` (concentric rings about ``spacing`` apart, each with points
    ``spacing`` apart along it, every other ring turned by half a step); Delaunay triangles.

    ``clamp`` r_c (m): two more rings, at r_c ± spacing/2, so that pinning every vertex within
    r_c + spacing/2 clamps the disc at r_c whatever the mesh (the plate leaves a clamp flat
    halfway between its two outer pinned rows, as :func:`strip`'s clamp).
    Returns (uv (N, 2), faces (M, 3))."""
    rings = [radius] if clamp is None else [clamp - spacing / 2, clamp + spacing / 2, radius]
    if kind == "polar":
        return _polar_disc(radius, spacing, rings)
    rng = np.random.default_rng(seed)
    if kind == "poisson":
        pts = _poisson_disc(radius, 0.8 * spacing, rng)
    else:
        m = int(np.ceil(radius / spacing)) + 1
        g = spacing * np.arange(-m, m + 1)
        gx, gy = np.meshgrid(g, g)
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        if kind == "rot45":
            c = np.sqrt(0.5)
            pts = pts @ np.array([[c, -c], [c, c]])
        elif kind == "delaunay":
            pts = pts + rng.uniform(-0.3, 0.3, pts.shape) * spacing
        elif kind != "grid":
            raise ValueError(f"disc kind {kind!r}")
    r = np.hypot(pts[:, 0], pts[:, 1])
    keep = r < radius - 0.4 * spacing
    for ring in rings[:-1]:
        keep &= np.abs(r - ring) > 0.4 * spacing
    return _delaunay(np.concatenate([pts[keep]] + [_ring(q, spacing) for q in rings]), spacing)


def _ring(radius, spacing, turn=0.0, count=np.ceil):
    """Points about ``spacing`` apart around a circle (``count`` of 2πr/spacing of them),
    turned by ``turn`` of a step."""
    n = int(count(2 * np.pi * radius / spacing - 1e-9))
    phi = 2 * np.pi * (np.arange(n) + turn) / n
    return radius * np.stack([np.cos(phi), np.sin(phi)], axis=1)


def _polar_disc(radius, spacing, rings):
    """The centre and rings through each radius of ``rings`` (ascending), with rings evenly
    about ``spacing`` apart between them, every other one turned by half a step."""
    radii, inner = [], 0.0
    for outer in rings:
        k = max(int(round((outer - inner) / spacing)), 1)
        radii += [inner + (outer - inner) * (j + 1) / k for j in range(k)]
        inner = outer
    pts = [_ring(r, spacing, 0.5 * ((j + 1) % 2), np.round) for j, r in enumerate(radii)]
    return _delaunay(np.concatenate([np.zeros((1, 2))] + pts), spacing)


def _poisson_disc(radius, distance, rng, tries=30):
    """Points in the disc of ``radius`` no two closer than ``distance``, as many as dart
    throwing fits (Bridson 2007, "Fast Poisson disk sampling in arbitrary dimensions")."""
    cell = distance / np.sqrt(2.0)
    m = int(np.ceil(2 * radius / cell)) + 1
    grid = -np.ones((m, m), np.int64)
    pts = [np.zeros(2)]
    grid[int(radius / cell), int(radius / cell)] = 0
    active = [0]
    while active:
        i = active[rng.integers(len(active))]
        a = rng.uniform(0.0, 2 * np.pi, tries)
        d = distance * np.sqrt(rng.uniform(1.0, 4.0, tries))
        for c in pts[i] + d[:, None] * np.stack([np.cos(a), np.sin(a)], axis=1):
            if np.hypot(*c) >= radius:
                continue
            gx, gy = int((c[0] + radius) / cell), int((c[1] + radius) / cell)
            near = grid[max(gx - 2, 0):gx + 3, max(gy - 2, 0):gy + 3]
            near = near[near >= 0]
            if len(near) and np.min(np.hypot(*(np.asarray(pts)[near] - c).T)) < distance:
                continue
            grid[gx, gy] = len(pts)
            active.append(len(pts))
            pts.append(c)
            break
        else:
            active.remove(i)
    return np.asarray(pts)


def _criss_cross(a, b):
    """Grid over a × b (vertex j·len(a) + i at (a_i, b_j)), quads split by alternating diagonals
    as :func:`clothtool.sim.model.mesh.grid_mesh` does."""
    aa, bb = np.meshgrid(a, b)
    return np.stack([aa.ravel(), bb.ravel()], axis=1), grid_triangles(len(a), len(b))


def _delaunay_strip(start, length, width, spacing, kind, seed, clamp_line):
    """Points on the outline (and on the clamp line), a turned lattice or jittered points inside."""
    rng = np.random.default_rng(seed)
    na = int(round((length - start) / spacing))
    nb = max(int(round(width / spacing)), 1)
    a_line = np.linspace(start, length, na + 1)
    b_line = np.linspace(-width / 2, width / 2, nb + 1)[1:-1]
    lines = [np.stack([a_line, np.full_like(a_line, v)], 1) for v in (-width / 2, width / 2)]
    ends = [start, length] + ([clamp_line] if clamp_line is not None else [])
    lines += [np.stack([np.full_like(b_line, u), b_line], 1) for u in ends]
    if kind == "rot45":
        s = spacing * np.sqrt(0.5)
        m = np.arange(-int((length - start + width) / s) - 2, int((length - start + width) / s) + 3)
        ga, gb = np.meshgrid(m, m)
        keep = (ga + gb) % 2 == 0
        inner = np.stack([start + s * (ga[keep] + 0.5), s * gb[keep]], axis=1)
        margin = 0.3 * s
    elif kind == "delaunay":
        ga, gb = np.meshgrid(np.arange(start + spacing / 2, length, spacing),
                             np.arange(-width / 2 + spacing / 2, width / 2, spacing))
        inner = np.stack([ga.ravel(), gb.ravel()], 1)
        inner = inner + rng.uniform(-0.3, 0.3, inner.shape) * spacing
        margin = 0.2 * spacing
    else:
        raise ValueError(f"strip kind {kind!r}")
    ok = ((inner[:, 0] > start + margin) & (inner[:, 0] < length - margin)
          & (np.abs(inner[:, 1]) < width / 2 - margin))
    if clamp_line is not None:  # the clamp is its two lines, as on a grid: nothing between
        ok &= inner[:, 0] > clamp_line + margin
    return _delaunay(np.concatenate(lines + [inner[ok]]), spacing)


def _delaunay(points, spacing):
    """Counter-clockwise Delaunay triangles of the points, without zero-area ones."""
    from scipy.spatial import Delaunay

    faces = Delaunay(points).simplices.astype(np.int64)
    e1 = points[faces[:, 1]] - points[faces[:, 0]]
    e2 = points[faces[:, 2]] - points[faces[:, 0]]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    faces = faces[np.abs(det) > 1e-8 * spacing * spacing]
    det = det[np.abs(det) > 1e-8 * spacing * spacing]
    faces[det < 0] = faces[det < 0][:, [0, 2, 1]]
    return points, faces
