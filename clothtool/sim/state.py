"""What changes during a run: positions, velocities, time."""

from dataclasses import dataclass

import numpy as np


@dataclass
class State:
    x: np.ndarray  # (N, 3) positions, m
    v: np.ndarray  # (N, 3) velocities, m/s
    time: float = 0.0
