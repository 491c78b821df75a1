"""The error types clothtool raises on purpose.

The CLI turns each into one line on stderr and an exit code (spec §6):
:class:`InputError` → 2 (bad input, usage, unusable output path),
:class:`NumericalError` → 3 (a simulation that blew up). Library callers catch
:class:`ClothtoolError` to handle both.
"""


class ClothtoolError(Exception):
    """Base class; ``exit_code`` is what the CLI exits with."""

    exit_code = 1


class InputError(ClothtoolError, ValueError):
    """Bad input file, config, option or output path. The message names the culprit."""

    exit_code = 2


class NumericalError(ClothtoolError, ArithmeticError):
    """A computation produced non-finite or exploding values (exit code 3)."""

    exit_code = 3
