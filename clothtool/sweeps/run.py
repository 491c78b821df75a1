"""One run of a sweep, in whichever process runs it (a local pool worker or a Slurm
task): simulate its ``config.yaml`` into its folder, analyse the frames on request,
then write its ``status.json``.

A clothtool error (bad config, a blow-up) or any other exception of the run becomes a
``failed`` status carrying the one-line message and the exit code the CLI would give
(2, 3, or 1 for an internal error); Ctrl-C and SIGTERM are not caught, so an
interrupted run is left without a status, i.e. not done.
"""

import time

from clothtool.errors import ClothtoolError, InputError
from clothtool.sweeps.layout import CONFIG, SweepFolder

ANALYSIS = "analysis.h5"


def run_one(root, run, analysis=None):
    """Run ``run`` of the sweep in ``root``; returns its status record (also written)."""
    from clothtool.sim.api import simulate

    folder = SweepFolder(root)
    run_dir = folder.run_dir(run)
    folder.clear_status(run)
    started = time.perf_counter()
    try:
        result = simulate(run_dir / CONFIG, output_dir=run_dir, progress=False)
        status = {"status": "done", "frames": result.frames_written}
        if analysis is not None:
            from clothtool.analysis.sequence import analyze_sequence

            analyze_sequence(str(run_dir), str(run_dir / ANALYSIS), progress=False,
                             command=f"clothtool sweep --analyze ({run})", **analysis)
    except ClothtoolError as exc:
        message = exc.format() if isinstance(exc, InputError) else str(exc)
        status = {"status": "failed", "error": " ".join(message.split()),
                  "exit_code": exc.exit_code}
    except (KeyboardInterrupt, SystemExit):
        raise
    except Exception as exc:  # a bug: the sweep goes on, the manifest names it
        status = {"status": "failed", "exit_code": 1,
                  "error": " ".join(f"internal error: {type(exc).__name__}: {exc}".split())}
    status["seconds"] = round(time.perf_counter() - started, 6)
    folder.write_status(run, status)
    return status
