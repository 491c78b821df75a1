"""What changes during a run: positions, velocities, time and the previous step.

A :class:`State` is everything an integrator reads from one step to the next, so a
copy of it taken between steps resumes the run exactly (same model, same config).
"""

from dataclasses import dataclass, fields

import numpy as np


@dataclass
class State:
    x: np.ndarray  # (N, 3) positions, m
    v: np.ndarray  # (N, 3) velocities, m/s
    time: float = 0.0
    # positions and velocities before the last step (BDF2's second history point, VBD's last
    # acceleration (v − v_prev)/h); None at start
    x_prev: np.ndarray | None = None
    v_prev: np.ndarray | None = None

    def copy(self):
        """A deep copy (arrays copied), to save a state and resume from it later."""
        return State(**{f.name: _copy(getattr(self, f.name)) for f in fields(self)})


def _copy(value):
    return value.copy() if isinstance(value, np.ndarray) else value
