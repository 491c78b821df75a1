"""Process-wide numba settings, applied before the first kernel runs.

Threading layer: numba prefers TBB, then OpenMP, then its own 'workqueue'. OpenMP
workers spin while they wait; on a 2-core machine shared with the HDF5 writer
thread (and with other jobs under ``make -j`` or Slurm) that spinning costs more
CPU than it saves (measured on the 100k-triangle analyze benchmark: 3.0 s of user
time with OpenMP against 2.0 s with workqueue). So clothtool asks for workqueue
unless the user chose a layer with ``NUMBA_THREADING_LAYER``.
"""

import os

import numba

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"
