"""Generate the strip sample of `clothtool fit`: sample_data/strip.yaml and sample_data/strip/.

A fabric strip 10 cm × 2.5 cm (a cantilever test's specimen), clamped flat at one end (two
rows of vertices held), released horizontal under gravity: it falls, swings and settles.
sample_data/strip/strip.ply is its mesh (a 5 mm criss-cross grid, 126 vertices, texture
coordinates = the flat pattern); sample_data/strip/capture/ the "captured" sequence: the strip
simulated at TRUE (bend 1e-4 N·m, damping 0.02 s) for 1.5 s at 30 fps, with Gaussian noise of
NOISE (0.3 mm) on every coordinate of every frame (numpy's default_rng(SEED));
sample_data/strip.yaml the setup with a first guess GUESS three times off (bend 3e-4, damping
0.006), which `clothtool fit` corrects. The overhang is 2.7 bending lengths
(c = (B/(ρg))^(1/3) = 3.7 cm), as in the cantilever test, where the droop measures the bending;
a strip many bending lengths long hangs nearly straight down whatever its bending.

    clothtool fit sample_data/strip.yaml --target sample_data/strip/capture \\
          --range material.bend=1e-6:1e-3:log --range material.damping=1e-3:0.1:log -o fit/

    python scripts/make_strip_capture.py sample_data
"""

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from clothtool.io.frames import discover_frames, read_mesh
from clothtool.io.ply import write_ply
from clothtool.sim.api import simulate
from clothtool.sim.textile import strip

LENGTH, WIDTH, SPACING = 0.1, 0.025, 0.005  # m
FPS, SECONDS = 30, 1.5
TRUE = {"bend": 1.0e-4, "damping": 0.02}
GUESS = {"bend": 3.0e-4, "damping": 0.006}
NOISE, SEED = 3.0e-4, 1


def write_scene(folder, name="strip", kind="grid", spacing=SPACING, material=GUESS):
    """``folder/name/name.ply`` (the flat strip, xy plane, its uv the pattern) and
    ``folder/name.yaml`` (the setup: clamp pinned, gravity −z, ``material``); returns the
    config's path."""
    folder = Path(folder)
    uv, faces, held = strip(LENGTH, WIDTH, spacing, kind)
    (folder / name).mkdir(parents=True, exist_ok=True)
    write_ply(folder / name / f"{name}.ply", np.concatenate([uv, np.zeros((len(uv), 1))], axis=1),
              faces, vertex_properties={"s": uv[:, 0].copy(), "t": uv[:, 1].copy()})
    config = {"mesh": {"ply": f"{name}/{name}.ply"},
              # frozen βK damping resists the strip's swing, so the capture tells its β apart
              # from the bend (a rigid turn feels none of the default strain damping)
              "material": {"density": 0.2, "stretch": 5000.0, "shear": 50.0,
                           "damping_model": "frozen", **material},
              "scene": {"gravity": [0.0, 0.0, -9.81], "pins": [int(v) for v in held]},
              "time": {"fps": FPS, "frames": int(SECONDS * FPS)},
              "output": {"dir": f"../demo-out/{name}"}}
    path = folder / f"{name}.yaml"
    path.write_text(f"# A {100 * LENGTH:g} cm × {100 * WIDTH:g} cm strip clamped at one end, "
                    "released horizontal (the capture of clothtool fit's worked example).\n"
                    "# clothtool fit sample_data/strip.yaml --target sample_data/strip/capture "
                    "--range material.bend=1e-6:1e-3:log --range material.damping=1e-3:0.1:log "
                    "-o fit/\n" + yaml.safe_dump(config, sort_keys=False))
    return path


def write_capture(config, folder, values, noise=NOISE, seed=SEED, overrides=()):
    """``config`` simulated with ``values`` ({material key: value}), Gaussian ``noise`` (m) on
    every coordinate, as PLY frames in ``folder``."""
    folder = Path(folder)
    with tempfile.TemporaryDirectory() as tmp:
        simulate(config, output_dir=tmp, progress=False,
                 overrides=[f"material.{k}={v}" for k, v in values.items()] + list(overrides))
        rng = np.random.default_rng(seed)
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        for path in discover_frames(tmp):
            mesh = read_mesh(path)
            write_ply(folder / Path(path).name,
                      mesh.vertices + rng.normal(0.0, noise, mesh.vertices.shape), mesh.faces)
    return folder


if __name__ == "__main__":
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "sample_data")
    config = write_scene(root)
    write_capture(config, root / "strip" / "capture", TRUE)
    print(f"wrote {config} and {root / 'strip'}/")
