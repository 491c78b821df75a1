"""Opening an input file: its errors as one-line :class:`~clothtool.errors.InputError`s that
name the file."""

import contextlib
import os

from clothtool.errors import InputError


@contextlib.contextmanager
def reading(path, what):
    """``open(path, "rb")``; a folder, a missing or unreadable file (also while reading in
    the block) is an InputError naming ``path`` (``what``: "a PLY file")."""
    try:
        with open(path, "rb") as fh:
            yield fh
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, not {what}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None


def read_bytes(path, what):
    """The bytes of the file ``path``, with the errors of :func:`reading`."""
    path = os.fspath(path)
    with reading(path, what) as fh:
        return fh.read()
