"""MDD point caches: every vertex's position at each time sample, in one file.

The format of LightWave's MDD, as Blender's Mesh Cache modifier, 3ds Max's Point Cache and
Houdini read it: big-endian; int32 sample count K, int32 point count N, float32 times[K]
(seconds), then K blocks of N float32 x y z. Positions are in the base mesh's own
coordinates and its vertex order (the cache holds no faces or uv: those come from the base
mesh, e.g. an OBJ of the first frame).

:class:`MddWriter` streams the samples to a hidden file beside the target and, on
:meth:`~MddWriter.close`, writes the header, the times and the samples under a temporary
name and renames it: the cache appears complete, with the samples written so far, or not
at all.
"""

import os
import shutil

import numpy as np

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path, remove_quietly, temporary_name
from clothtool.io.files import read_bytes

HEADER = np.dtype(">i4")
VALUE = np.dtype(">f4")


class MddWriter:
    """Collects the samples of an MDD cache of ``n_points`` points at ``path``."""

    def __init__(self, path, n_points):
        self.path, self.n_points = os.fspath(path), int(n_points)
        self.times = []
        self._data_path = temporary_name(self.path) + ".samples"
        self._data = open(self._data_path, "wb")

    def add(self, time, positions):
        """Append the sample of ``positions`` (N, 3) at ``time`` seconds."""
        positions = np.asarray(positions)
        if positions.shape != (self.n_points, 3):
            raise ValueError(f"positions must be ({self.n_points}, 3), got {positions.shape}")
        if self.times and not time > self.times[-1]:
            raise ValueError(f"sample times must increase: {time} after {self.times[-1]}")
        self._data.write(positions.astype(VALUE).tobytes())
        self.times.append(float(time))

    def close(self, ok=True):
        """Write the cache (when ``ok`` and it has samples) and remove the samples' file."""
        if self._data.closed:
            return
        try:
            self._data.close()
            if ok and self.times:
                with atomic_path(self.path) as tmp, open(tmp, "wb") as out:
                    out.write(np.array([len(self.times), self.n_points], HEADER).tobytes())
                    out.write(np.array(self.times, VALUE).tobytes())
                    with open(self._data_path, "rb") as samples:
                        shutil.copyfileobj(samples, out, 1 << 20)
        finally:
            remove_quietly(self._data_path)


def read_mdd(path):
    """(times (K,) float32 seconds, positions (K, N, 3) float32) of an MDD file."""
    path = os.fspath(path)
    data = read_bytes(path, "an MDD file")
    if len(data) < 8:
        raise InputError(f"{path}: {len(data)} bytes, too short for an MDD header")
    k, n = (int(v) for v in np.frombuffer(data, HEADER, 2))
    if k < 0 or n < 0 or len(data) != 8 + 4 * k + 12 * k * n:
        raise InputError(f"{path}: {len(data)} bytes, but the header says {k} samples of "
                         f"{n} points ({8 + 4 * k + 12 * k * n} bytes)")
    times = np.frombuffer(data, VALUE, k, 8).astype(np.float32)
    positions = np.frombuffer(data, VALUE, 3 * k * n, 8 + 4 * k).astype(np.float32)
    return times, positions.reshape(k, n, 3)
