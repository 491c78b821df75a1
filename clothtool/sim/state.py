"""What changes during a run: positions, velocities, time, the previous step, the contact memory.

A :class:`State` is everything an integrator reads from one step to the next, so a
copy of it taken between steps resumes the run exactly (same model, same config).
"""

from dataclasses import dataclass, field, fields

import numpy as np


@dataclass
class State:
    x: np.ndarray  # (N, 3) positions, m
    v: np.ndarray  # (N, 3) velocities, m/s
    time: float = 0.0
    # contact memory: vertices whose contact pulled at the last step are released at the next
    released: np.ndarray = field(default=None)  # (N,) bool
    # positions and velocities before the last step (BDF2's second history point, VBD's last
    # acceleration (v − v_prev)/h); None at start
    x_prev: np.ndarray | None = None
    v_prev: np.ndarray | None = None

    def __post_init__(self):
        if self.released is None:
            self.released = np.zeros(len(self.x), dtype=np.bool_)

    def copy(self):
        """A deep copy (arrays copied), to save a state and resume from it later."""
        return State(**{f.name: _copy(getattr(self, f.name)) for f in fields(self)})


def _copy(value):
    return value.copy() if isinstance(value, np.ndarray) else value
