"""Parameter sweeps: many simulations of one base config, run on a local process pool
or as a Slurm job array, resumable, gathered into one table.

    import clothtool
    result = clothtool.sweep("base.yaml", "runs", grid={"material.stretch": [1e3, 1e4, 1e5]},
                             jobs=2, analyze=True)
    report = clothtool.sweep_report("runs")    # report.csv + report.h5 in runs/

Modules: :mod:`~clothtool.sweeps.spec` (grid, zip, random → runs),
:mod:`~clothtool.sweeps.layout` (the folder: record, manifest, run configs, statuses),
:mod:`~clothtool.sweeps.run` (one run), :mod:`~clothtool.sweeps.pool` (local processes),
:mod:`~clothtool.sweeps.slurm` (job-array script, task), :mod:`~clothtool.sweeps.report`
(table, HDF5 series, plots), :mod:`~clothtool.sweeps.api` (:func:`sweep`).
"""

from clothtool.sweeps.api import SweepResult, sweep
from clothtool.sweeps.report import sweep_report

__all__ = ["SweepResult", "sweep", "sweep_report"]
