"""The error types clothtool raises on purpose.

The CLI turns each into one line on stderr and an exit code:
:class:`InputError` → 2 (bad input, usage, unusable output path),
:class:`NumericalError` → 3 (a simulation that blew up). Library callers catch
:class:`ClothtoolError` to handle both.
"""


class ClothtoolError(Exception):
    """Base class; ``exit_code`` is what the CLI exits with."""

    exit_code = 1


class InputError(ClothtoolError, ValueError):
    """Bad input file, config, option or output path. The message names the culprit.

    An error about a keyword argument carries it as ``keyword`` (and the offending ``value``,
    if the message shows it): ``InputError("no pairs in this slice", keyword="pairs",
    value="5:3")`` reads ``pairs=5:3: no pairs in this slice``; the CLI shows the same
    ``detail`` under its own option name (``--pairs 5:3: …``). ``mentions`` maps other
    keywords the detail names, as ``{keyword}`` placeholders, to their library spelling
    (``{"kabsch": "kabsch=True"}``)."""

    exit_code = 2

    def __init__(self, message, keyword=None, value=None, mentions=None):
        self.detail, self.keyword, self.value = message, keyword, value
        self.mentions = dict(mentions or {})
        super().__init__(self.format())

    def format(self, names=None):
        """The message with keywords spelled by ``names`` (keyword → option name, as the
        CLI's flags), or as keyword arguments without it."""
        detail = self.detail
        if self.mentions:
            detail = detail.format(**{k: names[k] if names else v for k, v in self.mentions.items()})
        if not self.keyword:
            return detail
        if names is None:
            head = f"{self.keyword}={'' if self.value is None else self.value}"
        else:
            name = names[self.keyword]
            head = name if self.value is None else f"{name} {self.value}"
        return f"{head}: {detail}"


class NumericalError(ClothtoolError, ArithmeticError):
    """A computation produced non-finite or exploding values (exit code 3)."""

    exit_code = 3
