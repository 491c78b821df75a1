"""benchmarks/references.py: a stored reference is read back only under its own key (the run's
config and the simulator's source); otherwise, and under ``--full``, it is solved again."""

import numpy as np

from benchmarks import references


def test_a_reference_is_read_back_only_under_its_key(tmp_path, monkeypatch):
    monkeypatch.setattr(references, "FOLDER", tmp_path)
    monkeypatch.setattr(references, "FULL", False)
    solved = []

    def solve(value):
        def compute():
            solved.append(value)
            return {"x": np.full((2, 3), value), "seconds": 0.5}
        return compute

    data, cached = references.stored("plate", {"steps": 64}, solve(1.0))
    assert (cached, solved) == (False, [1.0])
    assert data["x"].tolist() == [[1.0] * 3] * 2 and float(data["seconds"]) == 0.5
    data, cached = references.stored("plate", {"steps": 64}, solve(2.0))
    assert (cached, solved) == (True, [1.0]) and data["x"].tolist() == [[1.0] * 3] * 2
    data, cached = references.stored("plate", {"steps": 128}, solve(3.0))  # another config
    assert (cached, solved, data["x"][0, 0]) == (False, [1.0, 3.0], 3.0)
    monkeypatch.setattr(references, "source_digest", lambda: b"another simulator")
    data, cached = references.stored("plate", {"steps": 128}, solve(4.0))
    assert (cached, solved, data["x"][0, 0]) == (False, [1.0, 3.0, 4.0], 4.0)
    monkeypatch.setattr(references, "FULL", True)  # --full solves it whatever the file holds
    data, cached = references.stored("plate", {"steps": 128}, solve(5.0))
    assert (cached, solved, data["x"][0, 0]) == (False, [1.0, 3.0, 4.0, 5.0], 5.0)
    monkeypatch.setattr(references, "FULL", False)
    assert references.stored("plate", {"steps": 128}, solve(6.0))[1] is True
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plate.npz"]


def test_the_key_follows_the_simulator_source_not_the_analysis():
    """The digest covers clothtool/sim/ and clothtool/contact/ and the top-level modules."""
    root = references.ROOT / "clothtool"
    covered = {p for pattern in references.SIMULATOR for p in root.glob(pattern)}
    assert root / "sim" / "model" / "config.py" in covered
    assert root / "contact" / "barrier.py" in covered
    assert root / "fabrics.csv" in covered
    assert not any(p.is_relative_to(root / "analysis") for p in covered)
