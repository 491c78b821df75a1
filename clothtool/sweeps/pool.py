"""Runs on this machine: one pool process that imports clothtool, numpy, numba and the
simulator once, and ``jobs`` workers forked from it, each running one run after another
as the pool hands them out, so a run costs its simulation and not a Python start-up.

    the caller (writes the manifest) ── socket ── pool process (fresh interpreter, own session)
                                                   ├── worker (fork): run, run, …
                                                   └── worker (fork): run, run, …

The caller starts the pool process before it expands the sweep (:class:`Pool`), so the
imports (about 1 s of CPU on the benchmark machine: numba, scipy, the simulator's modules)
run while the runs' configs are checked and the folder is written, and run once for all
workers: a worker is a copy-on-write fork of a process that has imported them and has
started no thread (numba's threads start with its first parallel kernel, in the workers).
Each worker still loads from numba's on-disk cache the compiled kernels its first run calls.
A sweep is one batch of runs (:meth:`Pool.run`); ``clothtool fit`` hands the same pool a batch
per round, and the workers stay from one batch to the next, their kernels loaded.

Only the caller writes the manifest; a worker writes its runs' ``status.json``. A worker
that dies (killed, out of memory) fails its run with a message naming the signal or exit
code, and the pool forks another. Ctrl-C or SIGTERM to the caller: it SIGTERMs the pool
process, which SIGTERMs its workers (each run then cleans up as ``clothtool simulate``
does and is left not done) and exits, and the caller re-raises. The pool has its own
session, so a terminal's Ctrl-C reaches the caller alone and the stop always goes down
the tree in that order. If the pool process itself dies, the caller stops its workers
(the pool's process group) and raises :class:`PoolError`: the runs not finished are not
done, and running the sweep again resumes them. POSIX only (fork, sessions).
"""

import contextlib
import importlib
import multiprocessing
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from multiprocessing.connection import Connection, wait
from pathlib import Path

from clothtool import interrupt
from clothtool.errors import ClothtoolError, InputError

# what every run imports (clothtool.sim.api imports the others when a run starts)
PRELOAD = ("tqdm", "clothtool.sweeps.run", "clothtool.sim.api", "clothtool.sim.model.builder",
           "clothtool.sim.solve.integrator",
           "clothtool.sim.model.methods", "clothtool.sim.model.model", "clothtool.sim.output")
ANALYSIS_PRELOAD = ("clothtool.analysis.sequence",)
STOP_WAIT_S = 10.0  # how long a stopped process may take to clean up before SIGKILL


class PoolError(ClothtoolError):
    """The pool process died; the runs it had not finished are left not done."""


def available():
    """Can this platform run the pool (fork and sessions)?"""
    return hasattr(os, "fork") and hasattr(os, "killpg")


class Pool:
    """The caller's side of the pool: starts the pool process at once (it imports while the
    caller plans); :meth:`run` hands it a batch of runs, :meth:`close` stops it."""

    def __init__(self, analysis, jobs):
        if not available():
            raise InputError("runs at a time on this machine need a POSIX system (fork); "
                             "give 1, or run the sweep on Slurm", keyword="jobs", value=jobs)
        package_dir = str(Path(__file__).resolve().parents[2])  # this clothtool, not another
        code = (f"import sys; sys.path.insert(0, {package_dir!r}); "
                "from clothtool.sweeps.pool import serve; serve(int(sys.argv[1])); "
                "import os; os._exit(0)")  # nothing left to flush: skip the interpreter's teardown
        env = dict(os.environ)
        # one numba thread per worker: the workers already fill the cores (unless the user chose)
        env.setdefault("NUMBA_NUM_THREADS", "1")
        ours, theirs = socket.socketpair()
        with ours, theirs:
            self.process = subprocess.Popen(
                [sys.executable, "-c", code, str(theirs.fileno())], pass_fds=[theirs.fileno()],
                stdin=subprocess.DEVNULL, env=env, start_new_session=True)
            self.conn = Connection(ours.detach())
        self.conn.send((analysis, jobs))
        self.started = False  # runs handed to it
        self.busy = False  # a batch is running

    def run(self, root, runs, methods, on_done):
        """Run ``runs`` (ids) of the sweep in ``root``; ``methods``: the ``solver.method`` names
        they use (their modules are imported before the workers fork). ``on_done(run, status)``
        as each run ends."""
        self.started = self.busy = True
        try:
            self.conn.send((str(root), list(runs), sorted(methods)))
        except OSError:  # it died since the last batch
            raise self._died() from None
        while True:
            try:
                message = self.conn.recv()
            except (EOFError, OSError):
                raise self._died() from None
            if message is None:
                break
            on_done(*message)
        self.busy = False

    def close(self):
        """Stop the pool process and its workers if they still run (and wait for them): between
        batches it is told to end; during one, or before any, it is signalled."""
        if self.process.poll() is None and self.started and not self.busy:
            with contextlib.suppress(OSError):
                self.conn.send(None)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(timeout=2 * STOP_WAIT_S)
        if self.process.poll() is None:
            with interrupt.deferred():
                # before any run it has no worker and has written nothing
                self.process.send_signal(signal.SIGTERM if self.started else signal.SIGKILL)
            try:
                self.process.wait(timeout=2 * STOP_WAIT_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._stop_group()
        self.conn.close()

    def _died(self):
        code = self.process.wait()
        self._stop_group()
        return PoolError(f"the process that runs the sweep's workers died ({_how(code)}); the "
                         "runs it had not finished are not done: run the sweep again to resume")

    def _stop_group(self):
        """SIGTERM what is left of the pool's process group (workers whose pool died), wait
        for it to end; SIGKILL what lingers."""
        group = self.process.pid
        for signum in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(group, signum)
            except (ProcessLookupError, PermissionError):
                return
            deadline = time.monotonic() + STOP_WAIT_S
            while time.monotonic() < deadline:
                try:
                    os.killpg(group, 0)
                except (ProcessLookupError, PermissionError):
                    return
                time.sleep(0.02)


# ---------------------------------------------------------------------- the pool process


def serve(fd):
    """The pool process's main: import what the runs need, then for each batch of runs the
    caller sends, fork the workers and hand the runs out, sending each run's status to the
    caller and None when the batch is done; None from the caller ends it."""
    caller = Connection(fd)
    _stop_on_first_signal()
    workers = []
    try:
        analysis, jobs = caller.recv()
        for name in PRELOAD + (ANALYSIS_PRELOAD if analysis is not None else ()):
            importlib.import_module(name)
        from tqdm import tqdm

        # tqdm's default lock is a multiprocessing semaphore (made even for a disabled bar):
        # a worker stopped by a signal would leak it, and the resource tracker would say so
        tqdm.set_lock(threading.RLock())
        from clothtool.sim.model.methods import METHODS

        while (message := caller.recv()) is not None:
            root, runs, methods = message
            for name in methods:
                METHODS[name].load()
            _hand_out_runs(caller, root, analysis, jobs, runs, workers)
            caller.send(None)
        _end(workers)
    except (KeyboardInterrupt, EOFError, OSError):
        pass  # stopped by the caller, or the caller is gone
    finally:
        _stop(workers)


def _stop_on_first_signal():
    """SIGINT and SIGTERM raise KeyboardInterrupt (:func:`clothtool.interrupt.install`) the
    first time, then both are ignored: the pool's stop (and a worker's clean-up) must not
    be interrupted by a second signal. (Ignored by a Python function: with SIG_IGN, a
    signal already pending is reported as "ignored due to race condition".) The workers
    inherit these handlers with the fork."""
    interrupt.install()
    for signum in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(signum)
        if callable(handler):
            signal.signal(signum, _once(handler))


def _once(handler):
    def first(signum, frame):
        signal.signal(signal.SIGINT, _ignore)
        signal.signal(signal.SIGTERM, _ignore)
        handler(signum, frame)
    return first


def _ignore(signum, frame):
    pass


def _worker(conn, caller, analysis):
    """A worker's main loop: receive (sweep folder, run id), run it, send back (run, status);
    None ends it."""
    caller.close()  # the pool's connection to the caller: only the pool holds it
    try:
        from clothtool.sweeps.run import run_one

        while (message := conn.recv()) is not None:
            root, run = message
            conn.send((run, run_one(root, run, analysis)))
    except (KeyboardInterrupt, EOFError, BrokenPipeError):
        return  # the pool is stopping; nothing of this run was published


class _Worker:
    def __init__(self, caller, analysis):
        ctx = multiprocessing.get_context("fork")
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker, args=(child, caller, analysis), daemon=True)
        self.process.start()
        child.close()
        self.run = None  # the run it is busy with


def _hand_out_runs(caller, root, analysis, jobs, runs, workers):
    """One batch: the runs of the sweep in ``root`` on the ``workers`` (forked as needed, up
    to ``jobs``; they stay for the next batch, their kernels loaded)."""
    pending = list(reversed(runs))
    while len(workers) < min(jobs, len(runs)):
        workers.append(_Worker(caller, analysis))
    for w in workers:
        _hand_out(w, root, pending)
    while any(w.run is not None for w in workers):
        busy = [w for w in workers if w.run is not None]
        ready = wait([caller] + [w.conn for w in busy] + [w.process.sentinel for w in busy])
        if caller in ready:
            caller.recv()  # the caller sends nothing while runs run: it is gone (EOFError)
        for w in busy:
            if w.conn not in ready and w.process.sentinel not in ready:
                continue
            try:
                message = w.conn.recv() if w.conn.poll() else None
            except (EOFError, OSError):  # it died while we looked
                message = None
            if message is not None:
                w.run = None
                caller.send(message)
                _hand_out(w, root, pending)
            elif not w.process.is_alive():
                run, w.run = w.run, None
                w.process.join()
                caller.send((run, _died(root, run, w.process.exitcode)))
                workers.remove(w)
                if pending:
                    fresh = _Worker(caller, analysis)
                    workers.append(fresh)
                    _hand_out(fresh, root, pending)


def _hand_out(worker, root, pending):
    if pending:
        worker.run = pending.pop()
        with contextlib.suppress(OSError):  # it just died: its sentinel tells, and fails the run
            worker.conn.send((root, worker.run))


def _end(workers):
    """The caller has no more batches: each worker ends after its loop."""
    for w in workers:
        with contextlib.suppress(OSError):
            w.conn.send(None)
    for w in workers:
        w.process.join()
    workers.clear()


def _how(exitcode):
    return (f"killed by signal {signal.Signals(-exitcode).name}" if exitcode is not None
            and exitcode < 0 else f"exit code {exitcode}")


def _died(root, run, exitcode):
    from clothtool.sweeps.layout import SweepFolder

    status = {"status": "failed", "exit_code": 1,
              "error": f"the worker process running this run died ({_how(exitcode)})"}
    SweepFolder(root).write_status(run, status)
    return status


def _stop(workers):
    """SIGTERM every worker (each cleans up its run), then wait; SIGKILL what lingers."""
    with interrupt.deferred():
        for w in workers:
            if w.process.is_alive():
                w.process.terminate()
    for w in workers:
        w.process.join(timeout=STOP_WAIT_S)
        if w.process.is_alive():
            w.process.kill()
            w.process.join()
