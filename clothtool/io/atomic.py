"""Files that appear complete or not at all: a temporary name in the target folder,
renamed over the target on success, removed on any failure, Ctrl-C or SIGTERM.

The cleanup runs with SIGINT and SIGTERM held back, so a second Ctrl-C cannot
interrupt it half-way, and nothing is renamed into place once a signal has arrived
(see :mod:`clothtool.interrupt`).
"""

import contextlib
import os

from clothtool import interrupt


def temporary_name(path):
    """A hidden name beside ``path``, unique to this process: ``.NAME.tmp-PID``."""
    folder, name = os.path.split(os.path.abspath(os.fspath(path)))
    return os.path.join(folder, f".{name}.tmp-{os.getpid()}")


def remove_quietly(path):
    with contextlib.suppress(FileNotFoundError):
        os.remove(path)


def finish(renames, ok, close=None):
    """End an atomic write: call ``close()``, then, if ``ok`` and closing worked, rename
    each (temporary, final) path of ``renames`` in order; otherwise remove the temporary
    files. Closing errors after a failure are ignored (the first error is the one worth
    reporting)."""
    with interrupt.deferred():
        try:
            if close is not None:
                try:
                    close()
                except Exception:
                    if ok:
                        raise
            if ok:
                interrupt.check()
                for tmp, path in renames:
                    os.replace(tmp, path)
        finally:
            for tmp, _ in renames:
                remove_quietly(tmp)


@contextlib.contextmanager
def atomic_path(path):
    """``with atomic_path(p) as tmp:`` write ``tmp``; it becomes ``p`` only if the block completes."""
    tmp = temporary_name(path)
    try:
        yield tmp
    except BaseException:
        finish([(tmp, path)], ok=False)
        raise
    finish([(tmp, path)], ok=True)
