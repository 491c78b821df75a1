"""Files that appear complete or not at all: a temporary name in the target folder,
renamed over the target on success, removed on any failure, Ctrl-C or SIGTERM.

The cleanup runs with SIGINT and SIGTERM held back, so a second Ctrl-C cannot
interrupt it half-way; a signal that arrives meanwhile is delivered right after
(and still ends the program with exit code 130).
"""

import contextlib
import os
import signal

_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def temporary_name(path):
    """A hidden name beside ``path``, unique to this process: ``.NAME.tmp-PID``."""
    folder, name = os.path.split(os.path.abspath(os.fspath(path)))
    return os.path.join(folder, f".{name}.tmp-{os.getpid()}")


@contextlib.contextmanager
def deferred_signals():
    """Hold back SIGINT and SIGTERM for the duration of the block (POSIX; no-op elsewhere)."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        yield
        return
    old = mask(signal.SIG_BLOCK, _SIGNALS)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, old)


def remove_quietly(path):
    with contextlib.suppress(FileNotFoundError):
        os.remove(path)


def finish(tmp, path, ok, close=None):
    """End an atomic write: call ``close()``, then rename ``tmp`` to ``path`` if ``ok``
    and closing worked; otherwise remove ``tmp``. Closing errors after a failure are
    ignored (the first error is the one worth reporting)."""
    with deferred_signals():
        try:
            if close is not None:
                try:
                    close()
                except Exception:
                    if ok:
                        raise
            if ok:
                os.replace(tmp, path)
        finally:
            remove_quietly(tmp)


@contextlib.contextmanager
def atomic_path(path):
    """``with atomic_path(p) as tmp:`` write ``tmp``; it becomes ``p`` only if the block completes."""
    tmp = temporary_name(path)
    try:
        yield tmp
    except BaseException:
        finish(tmp, path, ok=False)
        raise
    finish(tmp, path, ok=True)
