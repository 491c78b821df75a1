"""The Cusick drape coefficient against the mesh: what depends on it, and whether it converges.

    python -m benchmarks drape_mesh            # the defaults' convergence and spread
    python -m benchmarks --full drape_mesh     # and every variant of the study

Writes ``bench-results/drape_mesh.csv`` (one row per run; a rerun skips the runs the file has)
and ``bench-results/drape_mesh.md``, and the tables of docs/simulate.md between their
markers. The Cusick test (:func:`clothtool.sim.textile.cusick_drape`: a 30 cm disc clamped on
an 18 cm pedestal, 3 s at 60 fps, damping 0.05 s) of one fabric (``FABRIC``), on four meshes
of the disc (a polar mesh of rings, a grid inside its boundary ring and two Poisson-disc
Delaunay meshes, :func:`clothtool.sim.textile.disc`) at 12, 8, 6 and 4 mm: the drape
coefficient and the number of folds of every run, each spacing's spread across the meshes
and each mesh's change from one spacing to the next.

The variants (``--full``): the static finish with the projected Hessian alone
(``exact_finish=False``, which stalls short of rest on some 6 and 4 mm discs), the plate
without its correction (``plate_correction: false``),
``bend_model: dihedral``, ``membrane_model: nodal`` and ``edge`` (each also with the plate's
correction), and the disc resting on the pedestal as
a barrier collider (its centre pinned) instead of clamped, with friction 0.5, with friction
0 and with the contact distance (``collision_margin``) halved.
"""

import csv
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import full_or, markdown_table, write_doc_table

FABRIC = {"density": 0.2, "stretch": 5000.0, "shear": 50.0, "bending_length": 0.025}
MESHES = (("polar", 1), ("grid", 1), ("poisson", 1), ("poisson", 2))
SPACINGS = (0.012, 0.008, 0.006, 0.004)
SECONDS = 3.0
DEFAULTS = "defaults"
VARIANTS = {DEFAULTS: {},
            "projected finish": {"exact_finish": False},
            "plate_correction: false": {"plate_correction": False},
            "plate_correction: true": {"plate_correction": True},
            "bend_model: dihedral": {"bend_model": "dihedral"},
            "membrane_model: nodal": {"membrane_model": "nodal"},
            "membrane_model: nodal, plate_correction: true": {"membrane_model": "nodal",
                                                              "plate_correction": True},
            "membrane_model: edge": {"membrane_model": "edge"},
            "membrane_model: edge, plate_correction: true": {"membrane_model": "edge",
                                                             "plate_correction": True},
            "on a support, friction 0.5": {"support": (0.5, 0.002)},
            "on a support, friction 0": {"support": (0.0, 0.002)},
            "on a support, friction 0.5, contact distance 1 mm": {"support": (0.5, 0.001)}}
STUDY = full_or(tuple(VARIANTS), (DEFAULTS,))
COLUMNS = ("variant", "mesh", "seed", "spacing mm", "vertices", "drape coefficient %", "folds",
           "Newton", "PCG", "finish Newton", "finish residual", "largest speed mm/s", "wall s")


def run_one(variant, kind, seed, spacing):
    """One row: the Cusick test of FABRIC with the variant's keys on one mesh."""
    from clothtool.sim.textile import CUSICK, CUSICK_DAMPING, cusick_drape, disc, drape_folds

    keys = dict(VARIANTS[variant])
    support = keys.pop("support", None)
    exact = keys.pop("exact_finish", True)
    material = {**FABRIC, "damping": CUSICK_DAMPING, **keys}
    started = time.perf_counter()
    if support is None:
        counts = {}
        dc, state, _ = cusick_drape(material, spacing, kind, seed=seed, seconds=SECONDS,
                                    counts=counts, exact_finish=exact)
        uv, _ = disc(CUSICK[0], spacing, kind, seed=seed, clamp=CUSICK[1])
    else:
        dc, state, uv, counts = support_drape(material, spacing, kind, seed, *support)
    return {"variant": variant, "mesh": kind, "seed": seed, "spacing mm": round(1000 * spacing, 3),
            "vertices": len(uv), "drape coefficient %": round(100 * dc, 2),
            "folds": drape_folds(state.x, uv, CUSICK[0]), "Newton": counts.get("newton", ""),
            "PCG": counts.get("pcg", ""), "finish Newton": counts.get("finish", ""),
            "finish residual": f"{counts['residual']:.2g}" if "residual" in counts else "",
            "largest speed mm/s": round(1000 * float(np.abs(state.v).max()), 3),
            "wall s": round(time.perf_counter() - started, 1)}


def support_drape(material, spacing, kind, seed, friction, margin, fps=60):
    """The Cusick disc (not clamped: no pedestal rings) resting on the pedestal, a barrier
    collider (a closed cylinder of 256 sides, its top ``margin`` below the disc) with Coulomb
    ``friction``, its centre vertex pinned; (coefficient, state, uv, counts)."""
    from clothtool.io.ply import write_ply
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config
    from clothtool.sim.model.methods import make_integrator
    from clothtool.sim.textile import CUSICK, disc, drape_coefficient

    radius, pedestal = CUSICK
    uv, faces = disc(radius, spacing, kind, seed=seed)
    r, phi = np.hypot(uv[:, 0], uv[:, 1]), np.arctan2(uv[:, 1], uv[:, 0])
    with tempfile.TemporaryDirectory() as tmp:
        write_ply(Path(tmp) / "disc.ply", np.concatenate([uv, np.zeros((len(uv), 1))], axis=1),
                  faces, vertex_properties={"s": uv[:, 0].copy(), "t": uv[:, 1].copy()})
        write_ply(Path(tmp) / "pedestal.ply", *cylinder(pedestal, -0.05, -margin))
        config = load_config({
            "mesh": {"ply": str(Path(tmp) / "disc.ply")}, "material": dict(material),
            "scene": {"gravity": [0.0, 0.0, -9.81], "pins": [int(np.argmin(r))],
                      "colliders": [{"mesh": {"ply": str(Path(tmp) / "pedestal.ply"),
                                              "friction": friction}}],
                      "collision_margin": margin},
            "solver": {"tolerance": 1e-3}})
        model = build_model(config)
    integrator = make_integrator(model, config.solver, 1.0 / fps)
    state = model.initial_state()
    state.x[:, 2] = -0.002 * np.clip(r - pedestal, 0.0, None) / (radius - pedestal) * np.cos(6 * phi)
    counts = {"newton": 0, "pcg": 0}
    for _ in range(int(round(SECONDS * fps))):
        result = integrator.step(state)
        counts["newton"] += result.newton_iterations
        counts["pcg"] += result.cg_iterations
    return drape_coefficient(state.x, faces, pedestal, radius, (0.0, 0.0, 0.0)), state, uv, counts


def cylinder(radius, bottom, top, sides=256):
    """(vertices, faces) of a closed cylinder about z, outward-facing triangles."""
    phi = 2 * np.pi * np.arange(sides) / sides
    ring = radius * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    v = np.concatenate([np.column_stack([ring, np.full(sides, bottom)]),
                        np.column_stack([ring, np.full(sides, top)]),
                        [[0.0, 0.0, bottom], [0.0, 0.0, top]]])
    i = np.arange(sides)
    j = (i + 1) % sides
    side = np.concatenate([np.stack([i, j, sides + j], 1), np.stack([i, sides + j, sides + i], 1)])
    caps = np.concatenate([np.stack([np.full(sides, 2 * sides), j, i], 1),
                           np.stack([np.full(sides, 2 * sides + 1), sides + i, sides + j], 1)])
    return v, np.concatenate([side, caps])


def study(path, variants=STUDY, meshes=MESHES, spacings=SPACINGS):
    """Run every (variant, mesh, spacing) the CSV at ``path`` lacks, appending each row as it
    ends; returns every row of the file."""
    done = read_rows(path)
    have = {(r["variant"], r["mesh"], int(r["seed"]), float(r["spacing mm"])) for r in done}
    for variant in variants:
        for spacing in sorted(spacings, reverse=True):  # coarse first: the cheap answers
            for kind, seed in meshes:
                if (variant, kind, seed, round(1000 * spacing, 3)) in have:
                    continue
                row = run_one(variant, kind, seed, spacing)
                print("  drape_mesh", row, flush=True)
                new = not os.path.exists(path)
                with open(path, "a", newline="") as fh:
                    writer = csv.DictWriter(fh, fieldnames=COLUMNS)
                    if new:
                        writer.writeheader()
                    writer.writerow(row)
                done.append({k: str(v) for k, v in row.items()})
    return done


def read_rows(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def summary(rows, variant):
    """Per spacing: each mesh's coefficient (folds), the spread, and each mesh's change from
    the next coarser spacing; the 12 mm error against each mesh's 4 mm run."""
    mine = [r for r in rows if r["variant"] == variant]
    label = {(k, s): f"{k} {s}" if k == "poisson" else k for k, s in MESHES}
    out = []
    prev = {}
    for spacing in sorted({float(r["spacing mm"]) for r in mine}, reverse=True):
        row = {"spacing mm": f"{spacing:g}"}
        values = []
        for kind, seed in MESHES:
            hit = [r for r in mine if r["mesh"] == kind and int(r["seed"]) == seed
                   and float(r["spacing mm"]) == spacing]
            if not hit:
                continue
            dc = float(hit[0]["drape coefficient %"])
            change = f" ({dc - prev[kind, seed]:+.2f})" if (kind, seed) in prev else ""
            row[label[kind, seed]] = f"{dc:.2f} % · {hit[0]['folds']} folds{change}"
            prev[kind, seed] = dc
            values.append(dc)
        if len(values) > 1:
            row["spread points"] = f"{max(values) - min(values):.2f}"
        out.append(row)
    columns = ["spacing mm"] + [label[m] for m in MESHES] + ["spread points"]
    return out, columns


def run(out_dir):
    out_dir = Path(out_dir)
    started = time.perf_counter()
    path = out_dir / "drape_mesh.csv"
    rows = study(path)
    sections = []
    for variant in STUDY:
        table, columns = summary(rows, variant)
        sections.append(f"### {variant}\n\n" + markdown_table(table, columns))
        if variant == DEFAULTS:
            write_doc_table("docs/simulate.md", "drape-mesh", markdown_table(table, columns),
                            "drape_mesh")
    (out_dir / "drape_mesh.md").write_text(
        "## Cusick drape against the mesh\n\n`python -m benchmarks drape_mesh` (every run: "
        "drape_mesh.csv); each cell: drape coefficient · folds (change from the coarser "
        "spacing)\n\n" + "\n".join(sections))
    print(f"  drape_mesh benchmark in {time.perf_counter() - started:.0f} s")
