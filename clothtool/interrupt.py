"""Ctrl-C and SIGTERM: stop soon, clean up, never publish a partial result.

The CLI calls :func:`install`: both signals then raise ``KeyboardInterrupt`` (exit
code 130) *and* are remembered, because Python drops an exception raised where it
cannot propagate (a ``__del__``, a weakref callback during garbage collection). Long
loops call :func:`check`, and an atomic output is never renamed into place once a
signal has arrived, so a dropped interrupt still stops the run and leaves no output.
"""

import contextlib
import signal
import sys

_SIGNALS = {signal.SIGINT, signal.SIGTERM}
_received = []  # signal numbers seen by the handler installed by install()


def _handler(signum, frame):
    _received.append(signum)
    raise KeyboardInterrupt


def _quiet(hook):
    """An unraisable hook that stays silent about a dropped interrupt (it is remembered)."""
    def quiet(unraisable):
        if not (unraisable.exc_type and issubclass(unraisable.exc_type, KeyboardInterrupt)):
            hook(unraisable)
    quiet.clothtool = True
    return quiet


def install():
    """Make SIGTERM behave like Ctrl-C, and remember both. SIGINT is left alone when the
    parent ignores it (a background job in a script)."""
    signal.signal(signal.SIGTERM, _handler)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _handler)
    if not getattr(sys.unraisablehook, "clothtool", False):
        sys.unraisablehook = _quiet(sys.unraisablehook)


def check():
    """Raise ``KeyboardInterrupt`` if a signal arrived whose exception was dropped."""
    if _received:
        raise KeyboardInterrupt


@contextlib.contextmanager
def deferred():
    """Hold back SIGINT and SIGTERM during the block (POSIX; no-op elsewhere): a signal
    that arrives meanwhile is delivered when the block ends."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        yield
        return
    old = mask(signal.SIG_BLOCK, _SIGNALS)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, old)
