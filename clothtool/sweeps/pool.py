"""Runs on this machine: ``jobs`` worker processes, each importing clothtool (numpy,
numba and the compiled-kernel cache) once and then running one run after another as
the parent hands them out, so a run costs its simulation and not a Python start-up.

Only the parent writes the manifest; a worker writes its runs' ``status.json``. A
worker that dies (killed, out of memory) fails its run with a message naming the
signal or exit code, and another worker takes its place. Ctrl-C or SIGTERM to the
parent stops the workers with SIGTERM (each run then cleans up as ``clothtool
simulate`` does and is left not done) before the parent re-raises.
"""

import contextlib
import multiprocessing
import os
import signal
import threading
from multiprocessing.connection import wait

from clothtool import interrupt


def _worker(conn, root, analysis, threads):
    """A pool worker's main loop: receive a run id, run it, send back (run, status)."""
    if threads is not None:  # before numba is imported
        os.environ["NUMBA_NUM_THREADS"] = threads
    try:
        interrupt.install()
        for signum in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(signum)
            if callable(handler):
                signal.signal(signum, _once(handler))
        from tqdm import tqdm

        # tqdm's default lock is a multiprocessing semaphore (made even for a disabled bar):
        # a worker stopped by a signal would leak it, and the resource tracker would say so
        tqdm.set_lock(threading.RLock())
        from clothtool.sweeps.run import run_one

        while True:
            run = conn.recv()
            if run is None:
                return
            conn.send((run, run_one(root, run, analysis)))
    except (KeyboardInterrupt, EOFError, BrokenPipeError):
        return  # the parent is stopping the sweep; nothing of this run was published


def _once(handler):
    """``handler`` for the first SIGINT or SIGTERM, then both ignored: Ctrl-C reaches the
    workers and the parent's SIGTERM follows it, and the second must not interrupt the
    first one's clean-up. (Ignored by a Python function: with SIG_IGN, a signal already
    pending is reported as "ignored due to race condition".)"""
    def first(signum, frame):
        signal.signal(signal.SIGINT, _ignore)
        signal.signal(signal.SIGTERM, _ignore)
        handler(signum, frame)
    return first


def _ignore(signum, frame):
    pass


def _context():
    """Workers start from a fresh interpreter (forkserver; spawn where there is none), not
    as forks of the caller: a notebook that already ran numba's thread pool cannot fork
    safely."""
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


class _Worker:
    def __init__(self, ctx, root, analysis, threads):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker, args=(child, root, analysis, threads),
                                   daemon=True)
        self.process.start()
        child.close()
        self.run = None  # the run it is busy with


def run_pool(root, runs, analysis, jobs, on_done):
    """Run ``runs`` (ids) of the sweep in ``root`` on ``jobs`` processes; ``on_done(run,
    status)`` is called in the parent as each ends. One job runs in this process."""
    if jobs <= 1:
        from clothtool.sweeps.run import run_one

        for run in runs:
            on_done(run, run_one(root, run, analysis))
        return
    ctx = _context()
    pending = list(reversed(runs))
    workers = []
    # one numba thread per worker: the workers already fill the cores (unless the user chose)
    threads = None if "NUMBA_NUM_THREADS" in os.environ else "1"
    try:
        for _ in range(min(jobs, len(runs))):
            workers.append(_Worker(ctx, root, analysis, threads))
        for w in workers:
            _hand_out(w, pending)
        while any(w.run is not None for w in workers):
            busy = [w for w in workers if w.run is not None]
            ready = wait([w.conn for w in busy] + [w.process.sentinel for w in busy])
            for w in busy:
                if w.conn not in ready and w.process.sentinel not in ready:
                    continue
                try:
                    message = w.conn.recv() if w.conn.poll() else None
                except (EOFError, OSError):  # it died while we looked
                    message = None
                if message is not None:
                    run, status = message
                    w.run = None
                    on_done(run, status)
                    _hand_out(w, pending)
                elif not w.process.is_alive():
                    run, w.run = w.run, None
                    w.process.join()
                    on_done(run, _died(root, run, w.process.exitcode))
                    workers.remove(w)
                    if pending:
                        fresh = _Worker(ctx, root, analysis, threads)
                        workers.append(fresh)
                        _hand_out(fresh, pending)
        for w in workers:
            with contextlib.suppress(OSError):
                w.conn.send(None)
        for w in workers:
            w.process.join()
    except BaseException:
        _stop(workers)
        raise


def _hand_out(worker, pending):
    if pending:
        worker.run = pending.pop()
        with contextlib.suppress(OSError):  # it just died: its sentinel tells, and fails the run
            worker.conn.send(worker.run)


def _died(root, run, exitcode):
    from clothtool.sweeps.layout import SweepFolder

    how = (f"killed by signal {signal.Signals(-exitcode).name}" if exitcode is not None
           and exitcode < 0 else f"exit code {exitcode}")
    status = {"status": "failed", "exit_code": 1,
              "error": f"the worker process running this run died ({how})"}
    SweepFolder(root).write_status(run, status)
    return status


def _stop(workers):
    """SIGTERM every worker (each cleans up its run), then wait; SIGKILL what lingers."""
    with interrupt.deferred():
        for w in workers:
            if w.process.is_alive():
                w.process.terminate()
        for w in workers:
            w.process.join(timeout=10)
            if w.process.is_alive():
                w.process.kill()
                w.process.join()
