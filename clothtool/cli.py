"""The ``clothtool`` command line: parse arguments, call the library, report.

Every command body imports its heavy modules (numba, h5py) lazily so that
``clothtool --help`` starts fast. Errors become one line on stderr and an exit
code (spec §6): 0 done, 2 bad input or usage, 3 numerical failure, 130 interrupted.
"""

import sys
import traceback

import click

try:  # click ≥ 8.2 raises this (a UsageError) for a bare command that has no_args_is_help
    from click.exceptions import NoArgsIsHelpError
except ImportError:  # pragma: no cover
    class NoArgsIsHelpError(Exception):
        pass

from clothtool import __version__, interrupt
from clothtool.errors import ClothtoolError

EXIT_CODES_HELP = """\b
Exit codes: 0 done, 2 bad input, usage or unusable output path,
            3 numerical failure (a simulation that blew up), 130 interrupted,
            1 internal error (a bug; --debug shows the traceback)."""


class ClothtoolGroup(click.Group):
    """A click group that turns every failure into one line on stderr and an exit code."""

    def parse_args(self, ctx, args):
        try:
            return super().parse_args(ctx, args)
        except NoArgsIsHelpError:
            raise  # bare ``clothtool`` shows the help
        except click.UsageError as exc:
            _fail(ctx, _usage_message(exc), 2, exc)

    def invoke(self, ctx):
        # SIGTERM is handled like Ctrl-C so that temporary outputs are cleaned up.
        interrupt.install()
        try:
            return super().invoke(ctx)
        except ClothtoolError as exc:
            _fail(ctx, f"error: {exc}", exc.exit_code, exc)
        except NoArgsIsHelpError:
            raise
        except click.UsageError as exc:
            _fail(ctx, _usage_message(exc), 2, exc)
        except KeyboardInterrupt as exc:
            _fail(ctx, "interrupted", 130, exc)
        except OSError as exc:  # an input or output the library did not anticipate
            where = f"{exc.filename}: " if exc.filename else ""
            _fail(ctx, f"error: {where}{exc.strerror or exc}", 2, exc)
        except (click.exceptions.Exit, click.exceptions.Abort):
            raise
        except Exception as exc:  # a bug: still one line, the traceback with --debug
            if _caused_by_interrupt(exc):  # Ctrl-C inside a numba kernel surfaces as SystemError
                _fail(ctx, "interrupted", 130, exc)
            _fail(ctx, f"internal error: {type(exc).__name__}: {exc} "
                       "(run with --debug for the traceback and please report it)", 1, exc)


def _caused_by_interrupt(exc):
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _usage_message(exc):
    command = exc.ctx.command_path if exc.ctx is not None else "clothtool"
    return f"error: {exc.format_message()} (see '{command} --help')"


def _fail(ctx, message, code, exc):
    if ctx.find_root().params.get("debug") or "--debug" in sys.argv[1:]:
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    click.echo(f"clothtool: {' '.join(message.split())}", err=True)
    ctx.exit(code)


@click.group(cls=ClothtoolGroup, epilog=EXIT_CODES_HELP)
@click.version_option(__version__, prog_name="clothtool")
@click.option("--debug", is_flag=True, help="Show the full traceback on errors.")
def main(debug):
    """Measure and produce cloth deformation.

    \b
      clothtool analyze frames/ -o out.h5      per-triangle deformation of a PLY sequence
      clothtool simulate config.yaml           write such a sequence with an implicit solver

    Run `clothtool COMMAND --help` for the options and examples of each command.
    """


def _progress_enabled(quiet):
    return not quiet and sys.stderr.isatty()


ANALYZE_EPILOG = """\b
Examples:
  clothtool analyze frames/ -o out.h5
      pairs (0,1), (1,2), ... of all *.ply in frames/, natural order
  clothtool analyze 'cap/*.ply' -o out.h5 --reference first --fields stretch,area_ratio
      every frame against the first, only two fields stored
  clothtool analyze sim/ -o out.h5 --reference uv --uv-scale 0.5
      rest shape from the s,t / u,v texture coordinates (Baraff-Witkin)
  clothtool analyze frames/ -o out.h5 --reference rest.ply --dtype float64

\b
Fields (--fields, comma separated; default all):
  F C U R strain stretch directions area_ratio flags
Read the result with h5py:  h5py.File('out.h5')['face/stretch'][k]  (pair k)

""" + EXIT_CODES_HELP


@main.command(epilog=ANALYZE_EPILOG)
@click.argument("inputs", nargs=-1, required=True, metavar="FRAMES...")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="HDF5 file to write (written under a temporary name, renamed when complete).")
@click.option("--reference", default="previous", show_default=True, metavar="previous|first|uv|PATH",
              help="Rest state of each pair: the previous frame, the first frame, the texture "
                   "coordinates, or a PLY mesh.")
@click.option("--uv-scale", default=1.0, show_default=True, type=float,
              help="Metres per uv unit for --reference uv.")
@click.option("--fields", default="all", show_default=True, metavar="NAMES",
              help="Comma-separated face fields to compute and store.")
@click.option("--dtype", type=click.Choice(["float32", "float64"]), default="float32",
              show_default=True, help="Storage type of float fields (computation is float64).")
@click.option("--compression", default="none", show_default=True, metavar="none|gzip[=LEVEL]",
              help="HDF5 compression of the field datasets (gzip is readable by MATLAB and ParaView).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary.")
def analyze(inputs, output, reference, uv_scale, fields, dtype, compression, quiet):
    """Per-triangle deformation of a PLY sequence, written to HDF5.

    FRAMES is a folder of .ply files, a glob, or a list of files; they are
    taken in natural order (f2.ply before f10.ply) and analysed in pairs. For
    each triangle: the deformation gradient F in the triangle's tangent frame,
    C = FᵀF, the polar split F = R·U, principal stretches and directions, the
    area ratio J and the Green strain E = (C − I)/2.
    """
    from clothtool.analysis.sequence import analyze_sequence

    summary = analyze_sequence(
        list(inputs), output, reference=reference, uv_scale=uv_scale,
        fields=fields, dtype=dtype, compression=compression,
        progress=_progress_enabled(quiet), command=" ".join(["clothtool", *sys.argv[1:]]),
    )
    if not quiet:
        click.echo(summary.describe())


if __name__ == "__main__":  # pragma: no cover
    main()
