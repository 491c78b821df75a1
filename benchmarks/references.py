"""Converged reference runs, kept in the repository so that a fresh clone does not solve them
again: most of ``methods``' and ``accuracy``' time went into them.

Each is one file, ``benchmarks/references/<slot>.npz``, under a key that hashes its run's
config and the simulator's source (:func:`source_digest`). :func:`stored` reads it when the key
matches, else runs it and writes the file; ``--full`` runs it whatever the file holds and
rewrites it. A run that rewrites one leaves a changed file in the checkout: commit it with the
docs' tables that run measured.
"""

import hashlib
import json
import pathlib

import numpy as np

from benchmarks.common import FULL

ROOT = pathlib.Path(__file__).resolve().parents[1]
FOLDER = pathlib.Path(__file__).with_name("references")
# What an in-memory run of a grid scene executes: the simulator, the contact kernels and the
# package's top-level modules (errors, vec3, geometry, the fabric table …); not analysis/,
# io/, results/ or sweeps/, whose changes leave the references as they are.
SIMULATOR = ("sim/**/*.py", "contact/**/*.py", "*.py", "*.csv")


def source_digest():
    """sha256 of the simulator's source (the files of SIMULATOR under clothtool/, in path
    order)."""
    digest = hashlib.sha256()
    paths = {p for pattern in SIMULATOR for p in (ROOT / "clothtool").glob(pattern)}
    for path in sorted(paths):
        digest.update(str(path.relative_to(ROOT)).encode())
        digest.update(path.read_bytes())
    return digest.digest()


def key(config):
    """The key of a reference run: ``config`` (JSON-able: the run's config and whatever else
    decides its result) and the simulator's source, hashed."""
    return hashlib.sha256(json.dumps(config, sort_keys=True).encode()
                          + source_digest()).hexdigest()[:16]


def stored(slot, config, compute):
    """``(arrays, cached)``: the reference ``slot`` of the run ``config`` — read from its file
    when the file holds ``config``'s key (``cached`` True), else ``compute()`` (a dict of
    arrays or numbers) written there (``cached`` False). ``--full`` always computes it."""
    path = FOLDER / f"{slot}.npz"
    k = key(config)
    if not FULL and path.exists():
        with np.load(path) as data:
            if str(data["key"]) == k:
                return {name: data[name] for name in data.files if name != "key"}, True
    arrays = {name: np.asarray(value) for name, value in compute().items()}
    FOLDER.mkdir(exist_ok=True)
    np.savez(path, key=np.array(k), **arrays)
    print(f"  benchmarks/references/{slot}.npz written (commit it with the tables it measured)")
    return arrays, False
