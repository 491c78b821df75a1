"""The ``clothtool`` command line: parse arguments, call the library, report.

Every command body imports its heavy modules (numba, h5py) lazily so that
``clothtool --help`` starts fast. Errors become one line on stderr and an exit
code: 0 done, 2 bad input or usage, 3 numerical failure, 130 interrupted.
"""

import contextlib
import sys
import traceback

import click

try:  # click ≥ 8.2 raises this (a UsageError) for a bare command that has no_args_is_help
    from click.exceptions import NoArgsIsHelpError
except ImportError:  # pragma: no cover
    class NoArgsIsHelpError(Exception):
        pass

from clothtool import __version__, interrupt
from clothtool.errors import ClothtoolError, InputError

OPTIONS = {"fields": "--fields", "dtype": "--dtype", "compression": "--compression",
           "pairs": "--pairs", "reference": "--reference", "uv_scale": "--uv-scale",
           "vertex_average": "--vertex-average", "kabsch": "--kabsch", "pair": "--pair",
           "field": "--field", "component": "--component", "color_range": "--range",
           "overrides": "--set", "fps": "--fps", "dpi": "--dpi", "kes": "--kes",
           "target": "--fit-drape"}
"""Library keyword argument → the option that sets it, for the messages of InputError."""

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
            message = exc.format(OPTIONS) if isinstance(exc, InputError) else str(exc)
            _fail(ctx, f"error: {message}", exc.exit_code, exc)
        except NoArgsIsHelpError:
            raise
        except click.UsageError as exc:
            _fail(ctx, _usage_message(exc), 2, exc)
        except KeyboardInterrupt as exc:
            _fail(ctx, "interrupted", 130, exc)
        except OSError as exc:  # an input or output the library did not anticipate
            where = f"{exc.filename}: " if exc.filename else ""
            _fail(ctx, f"error: {where}{exc.strerror or exc}", 2, exc)
        except MemoryError as exc:  # the input asks for more than this machine has
            _fail(ctx, f"error: out of memory: {exc}", 2, exc)
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


QUIET = click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary.")
SET = click.option("--set", "settings", multiple=True, metavar="KEY=VALUE",
                   help="Override one config key, e.g. --set material.stretch=1e5 (repeatable; "
                        "in every simulation of a command that runs several).")


def simulation_options(folder, *, required=True, scope="", rounds=False):
    """The options of every command that runs simulations (sweep, fabric, fit), defined once:
    ``-o DIR`` (``folder``: what the folder holds; ``required``), ``--set``, ``-j`` and
    ``--slurm`` (``scope``: the option they serve, e.g. ``"--fit-drape: "``; ``rounds``: the
    command runs rounds of simulations, each waiting for the one before)."""
    options = (
        click.option("-o", "--output", required=required, default=None,
                     type=click.Path(file_okay=False), help=folder),
        SET,
        click.option("-j", "--jobs", default=1, show_default=True, type=int,
                     help=f"{scope}Simulations at a time on this machine (worker processes)."),
        click.option("--slurm", is_flag=True,
                     help=f"{scope}Write a Slurm job-array script instead of running; print its "
                          "sbatch line" + ("; rerun the command once the array has ended, to go "
                                           "on to the next round." if rounds else ".")),
    )

    def apply(command):
        for option in reversed(options):
            command = option(command)
        return command
    return apply


@contextlib.contextmanager
def runs_bar(quiet, slurm, desc):
    """A progress bar on stderr counting simulations (None when quiet, on Slurm or not a
    terminal); tqdm's monitor thread is off, since the local pool forks its workers."""
    if not _progress_enabled(quiet) or slurm:
        yield None
        return
    from tqdm import tqdm

    tqdm.monitor_interval = 0
    bar = tqdm(desc=desc, unit="run", file=sys.stderr)  # no total: bool(bar) raises, test `is None`
    try:
        yield bar
    finally:
        bar.close()


def _analyze_epilog():
    from clothtool.fields import help_table

    return (ANALYZE_EXAMPLES + "\b\nFields (--fields, comma separated; all = the default table, "
            "extended = every 2D field):\n" + help_table() + ANALYZE_READING)


ANALYZE_EXAMPLES = """\b
Examples:
  clothtool analyze frames/ -o out.h5
      pairs (0,1), (1,2), ... of all *.ply in frames/, natural order
  clothtool analyze 'cap/*.ply' -o out.h5 --reference first --fields stretch,area_ratio
      every frame against the first, only two fields stored
  clothtool analyze sim/ -o out.h5 --reference uv --uv-scale 0.5
      rest shape from the texture coordinates (Baraff-Witkin): per corner
      (PLY texcoord, OBJ vt; right on both sides of a uv seam) or per vertex (s,t / u,v)
  clothtool analyze frames/ -o out.h5 --reference rest.ply --dtype float64
  clothtool analyze frames/ -o part1.h5 --pairs 100:200
      only pairs 100..199; join the parts with `clothtool merge`
  clothtool analyze frames/ -o out.h5 --kabsch --fields stretch,angle,residual,dihedral_change
      with the 3D variant: per-vertex ring rotation, residual and bending
  clothtool analyze volume/ -o out.h5 --fields stretch,volume_ratio,flags
      a tetrahedral sequence (.vtu, .vtk, .msh or TetGen .node frames): /tet/... fields

"""

ANALYZE_READING = """

\b
Read the result with h5py:  h5py.File('out.h5')['face/stretch'][k]  (pair k)
Open out.xdmf (written beside out.h5) in ParaView for the deformed mesh over time.

""" + EXIT_CODES_HELP


@main.command(epilog=_analyze_epilog())
@click.argument("inputs", nargs=-1, required=True, metavar="FRAMES...")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="HDF5 file to write (written under a temporary name, renamed when complete).")
@click.option("--reference", default="previous", show_default=True, metavar="previous|first|uv|PATH",
              help="Rest state of each pair: the previous frame, the first frame, the texture "
                   "coordinates, or a PLY or OBJ mesh (a tetrahedral mesh for tetrahedra).")
@click.option("--uv-scale", default=1.0, show_default=True, type=float,
              help="Metres per uv unit for --reference uv.")
@click.option("--fields", default="all", show_default=True, metavar="NAMES",
              help="Comma-separated fields to compute and store (list below).")
@click.option("--dtype", type=click.Choice(["float32", "float64"]), default="float32",
              show_default=True, help="Storage type of float fields (computation is float64).")
@click.option("--compression", default="none", show_default=True, metavar="none|gzip[=LEVEL]",
              help="HDF5 compression of the field datasets (gzip is readable by MATLAB and ParaView).")
@click.option("--vertex-average", default="", metavar="NAMES",
              help="Face fields to also store per vertex (area-weighted average over the "
                   "incident triangles) as /vertex/NAME_avg, e.g. stretch,area_ratio.")
@click.option("--pairs", "pair_slice", default=None, metavar="START:STOP",
              help="Compute only pairs START..STOP-1 (for splitting a sequence over machines).")
@click.option("--kabsch", is_flag=True,
              help="Add the 3D variant: Kabsch rotation of each vertex's one-ring, the 3×3 face "
                   "gradient with its polar split, the dihedral-angle change per edge.")
@QUIET
def analyze(inputs, output, reference, uv_scale, fields, dtype, compression, vertex_average,
            pair_slice, kabsch, quiet):
    """Per-triangle deformation of a PLY or OBJ sequence (per tetrahedron of a
    tetrahedral one), written to HDF5.

    FRAMES is a folder of .ply or .obj files, a glob, or a list of files; they are
    taken in natural order (f2.ply before f10.ply) and analysed in pairs. For
    each triangle: the deformation gradient F in the triangle's tangent frame,
    C = FᵀF, the polar split F = R·U, principal stretches and directions, the
    area ratio J and the Green strain E = (C − I)/2.

    Tetrahedral frames (.vtu, .vtk, .msh, or TetGen .node with a shared or own
    .ele) give the same fields per tetrahedron in 3D, with J = det F the volume
    ratio and the invertible polar split (λ3 < 0 for an inverted tetrahedron).
    """
    from clothtool.analysis.sequence import analyze_sequence

    summary = analyze_sequence(
        list(inputs), output, reference=reference, uv_scale=uv_scale,
        fields=fields, dtype=dtype, compression=compression, kabsch=kabsch,
        progress=_progress_enabled(quiet), command=" ".join(["clothtool", *sys.argv[1:]]),
        pairs=pair_slice, vertex_average=vertex_average,
    )
    if not quiet:
        from clothtool.io.xdmf import xdmf_path

        click.echo(summary.describe())
        click.echo(f"  for ParaView: {xdmf_path(output)}; overview: clothtool info {output}")



INFO_EPILOG = """\b
Examples:
  clothtool info out.h5
  clothtool info out.h5 --csv | awk -F, 'NR > 1 && $5 > 1.05'      pairs with λ1 median > 1.05

\b
CSV columns: pair,reference,deformed, lambda1|lambda2|area_ratio _p5,_p50,_p95, compressed,stretched
(fractions of triangles with λ2 < 1, λ1 > 1), flagged and per-flag counts.

""" + EXIT_CODES_HELP


@main.command(epilog=INFO_EPILOG)
@click.argument("result", type=click.Path(dir_okay=False))
@click.option("--csv", "as_csv", is_flag=True, help="Print only the per-pair summary, as CSV.")
def info(result, as_csv):
    """What is in an analysis result, and a per-pair summary of its stretches."""
    from clothtool.results.info import describe, summary_csv

    click.echo(summary_csv(result) if as_csv else describe(result), nl=not as_csv)


EXPORT_EPILOG = """\b
Examples:
  clothtool export out.h5 --pair 10 -o pair10.ply                 λ1 (stretch component 0)
  clothtool export out.h5 --pair 10 --field stretch --component 1 -o lambda2.ply
  clothtool export out.h5 --field area_ratio --range 0.9:1.1 -o J.ply
  clothtool export out.h5 --field stretch_avg -o smooth.ply       a /vertex field

\b
Components are row-major: stretch 0 = λ1, 1 = λ2; 2×2 tensors 0 = xx, 1 = xy, 2 = yx, 3 = yy.

""" + EXIT_CODES_HELP


@main.command(epilog=EXPORT_EPILOG)
@click.argument("result", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="PLY file to write.")
@click.option("--pair", default=0, show_default=True, type=int,
              help="Pair index (as in /pairs and `clothtool info`).")
@click.option("--field", default="stretch", show_default=True,
              help="A /face or /vertex dataset of the result.")
@click.option("--component", default=0, show_default=True, type=int,
              help="Component of a field with several (row-major).")
@click.option("--range", "color_range", default=None, metavar="LO:HI",
              help="Values mapped to the ends of the colour scale [default: the pair's min:max].")
@click.option("--vertex-colors/--no-vertex-colors", default=True, show_default=True,
              help="Also colour the vertices (area-weighted average of a face field), for Blender.")
@click.option("--ascii", is_flag=True, help="Write ascii PLY instead of binary.")
def export(result, output, pair, field, component, color_range, vertex_colors, ascii):
    """The deformed mesh of one pair as a PLY coloured by a field (viridis).

    The field is written as a face (or vertex) property and as red/green/blue
    colours, which MeshLab and Blender display directly.
    """
    from clothtool.results.export import export_ply, parse_range

    name, (lo, hi) = export_ply(result, output, pair=pair, field=field, component=component,
                                color_range=parse_range(color_range), vertex_colors=vertex_colors,
                                binary=not ascii)
    click.echo(f"wrote {output}: pair {pair}, {name} coloured over [{lo:.6g}, {hi:.6g}]")



MERGE_EPILOG = """\b
Examples:
  clothtool analyze frames/ -o part0.h5 --pairs 0:500      # on one machine
  clothtool analyze frames/ -o part1.h5 --pairs 500:1000   # on another
  clothtool merge part*.h5 -o all.h5                       # equal to one run over 0:1000
  clothtool merge part0.h5 -o first.h5 --allow-partial     # only pairs 0:500

""" + EXIT_CODES_HELP


@main.command(epilog=MERGE_EPILOG)
@click.argument("parts", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="HDF5 file to write (an XDMF is written beside it).")
@click.option("--allow-partial", is_flag=True,
              help="Accept parts that cover only some of the analysis' pairs (still consecutive).")
def merge(parts, output, allow_partial):
    """Join results computed in slices (analyze --pairs) into one result.

    PARTS are slices of the same analysis, in any order; together they must cover
    every pair of the analysis, consecutively, without gap or overlap (with
    --allow-partial: consecutive pairs only).
    """
    from clothtool.results.merge import merge_results

    offset, n = merge_results(list(parts), output, command=" ".join(["clothtool", *sys.argv[1:]]),
                              allow_partial=allow_partial)
    click.echo(f"wrote {output}: pairs {offset}:{offset + n} from {len(parts)} parts")



PLOT_EPILOG = """\b
Examples:
  clothtool plot out.h5 -o fig.png
  clothtool plot out.h5 -o fig.pdf --pair 12 --field area_ratio

Needs matplotlib: pip install 'clothtool[plot]'

""" + EXIT_CODES_HELP


@main.command(epilog=PLOT_EPILOG)
@click.argument("result", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Image to write (.png, .pdf, .svg).")
@click.option("--pair", default=None, type=int,
              help="Pair of the mesh map [default: the one with the largest λ1 95th percentile].")
@click.option("--field", default=None, help="Field of the mesh map [default: stretch].")
@click.option("--component", default=0, show_default=True, type=int,
              help="Component of the mapped field (stretch: 0 = λ1, 1 = λ2).")
@click.option("--dpi", default=120, show_default=True, type=int, help="Resolution of raster images.")
@click.option("--config", "--colliders", "config", default=None, type=click.Path(dir_okay=False),
              help="The simulation config of the run: draws its colliders at the pair's frame.")
def plot(result, output, pair, field, component, dpi, config):
    """An overview figure: stretch and area-ratio percentiles over the sequence, histograms,
    and one pair's field drawn on the deformed mesh in 3D (with the run's colliders when
    --config names its simulation config)."""
    from clothtool.results.plot import plot_result
    from clothtool.sim.scene import run_scene

    drawn = plot_result(result, output, pair=pair, field=field, component=component, dpi=dpi,
                        scene=run_scene(config))
    click.echo(f"wrote {output} (mesh map: pair {drawn})")


RENDER_EPILOG = """\b
Examples:
  clothtool render demo-out/drape -o demo-out/drape-render
      the cloth and the body it falls on (from the config.yaml simulate wrote beside the
      frames): frame_00000.png ... and movie.mp4 (or movie.gif)
  clothtool render runs/run_0003 -o pictures/      a sweep's run: its config.yaml is used
  clothtool render frames/ -o pics/ --config scene.yaml   frames from elsewhere, with a scene
  clothtool render 'out/obj/*.obj' -o pics/ --fps 60 --no-movie

\b
The movie is an MP4 when ffmpeg is on PATH, else an animated GIF. Frame times come
from the run's stats.csv (else frame number / --fps). Needs matplotlib.

""" + EXIT_CODES_HELP


@main.command(epilog=RENDER_EPILOG)
@click.argument("frames", nargs=-1, required=True, metavar="FRAMES...")
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False),
              help="Folder of the pictures: frame_NNNNN.png and movie.mp4 or movie.gif.")
@click.option("--config", default=None, type=click.Path(dir_okay=False),
              help="The simulation config of the run: draws its colliders, with gravity down "
                   "[default: config.yaml beside the frames, if there is one].")
@click.option("--fps", default=None, type=float,
              help="Frames per second of frames without stats.csv times [default: the config's, else 30].")
@click.option("--dpi", default=100, show_default=True, type=int,
              help="Pixels per inch of the 6.4 × 4.8 inch pictures.")
@click.option("--movie/--no-movie", default=True, show_default=True, help="Also write the movie.")
@QUIET
def render(frames, output, config, fps, dpi, movie, quiet):
    """Pictures of a simulated sequence: each frame's cloth (and the run's colliders)
    in 3D as a PNG, and a short movie of them.

    FRAMES is a run's folder of PLY or OBJ frames, a glob, or a list of files.
    """
    from pathlib import Path

    from clothtool.results.render import render_sequence
    from clothtool.sim.scene import run_scene

    first = Path(frames[0])
    scene = run_scene(config, frames_dir=first if first.is_dir() else None)
    result = render_sequence(list(frames), output, scene=scene, fps=fps, dpi=dpi, movie=movie,
                             progress=_progress_enabled(quiet))
    if not quiet:
        click.echo(result.describe())



@main.command("init-config")
def init_config():
    """Print a commented default simulation config.

    \b
      clothtool init-config > config.yaml
      clothtool simulate config.yaml
    """
    from clothtool.config_tools import DEFAULT_CONFIG

    click.echo(DEFAULT_CONFIG, nl=False)


FABRIC_EPILOG = """\b
Examples:
  clothtool fabric --list
      the measured fabrics (material.preset)
  clothtool fabric --preset 11oz-black-denim
      a preset's material block, in SI and in a lab's units
  clothtool fabric --kes B=0.16,0.20 --kes W=38 --kes G=0.9 --kes EMT=4.1,7.5
      KES-F values (warp, weft) as a material block
  clothtool fabric sheet.yaml --drape
      a config's material in a lab's units, with its simulated Cusick drape
  clothtool fabric sheet.yaml --fit-drape 55 -o fit/ -j 2
      the bending length whose simulated Cusick test drapes 55 %

""" + EXIT_CODES_HELP


@main.command(epilog=FABRIC_EPILOG)
@click.argument("config", required=False, type=click.Path(dir_okay=False))
@click.option("--preset", default=None, metavar="NAME", help="A measured fabric (see --list).")
@click.option("--kes", multiple=True, metavar="NAME=VALUE",
              help="A KES-F value: B (gf·cm²/cm), G (gf/cm·deg), EMT (%), W (mg/cm²); "
                   "B and EMT may be WARP,WEFT.")
@click.option("--drape", is_flag=True,
              help="Also simulate its Cusick drape test (about 15-60 s) and print the drape "
                   "coefficient.")
@click.option("--fit-drape", "target", type=float, default=None, metavar="PERCENT",
              help="Fit the bending to this measured Cusick drape coefficient (sweeps of the "
                   "drape test into -o DIR; at most 10 simulations).")
@simulation_options("The folder of --fit-drape's sweeps.", required=False, scope="--fit-drape: ",
                    rounds=True)
@click.option("--list", "show_list", is_flag=True, help="List the measured fabrics and exit.")
def fabric(config, preset, kes, settings, drape, target, output, jobs, slurm, show_list):
    """Print a material block (SI) and what it is in a lab's units (KES-F, ASTM D1388)."""
    from clothtool import fabrics
    from clothtool.sim import lab_sheet

    if show_list:
        click.echo("\n".join(fabrics.listing()))
        return
    material = lab_sheet.material_of(config, preset=preset, kes=kes, overrides=settings)
    if target is not None:
        from clothtool.sweeps.drape_fit import fit_drape

        if output is None:
            raise click.UsageError("--fit-drape needs -o DIR (the sweeps' folder)")
        fit = fit_drape(material, target / 100.0, output, jobs=jobs, slurm=slurm)
        click.echo(lab_sheet.fit_report(material, fit))
        return
    click.echo(lab_sheet.report(material, lab_sheet.simulated_drape(material) if drape else None))


SIMULATE_EPILOG = """\b
Examples:
  clothtool simulate sample_data/hanging_sheet.yaml
      frames and stats.csv into the config's output.dir
  clothtool simulate sheet.yaml -o runs/stiff --set material.stretch=1e5
      another output folder (relative to the current folder), one key changed

\b
Output: DIR/frame_00000.ply (initial state) ... one binary PLY per frame with
the rest coordinates as s,t (analyze it with --reference uv), and DIR/stats.csv.
Config keys and units: see the README, section Simulation.

""" + EXIT_CODES_HELP


@main.command(epilog=SIMULATE_EPILOG)
@click.argument("config", type=click.Path(dir_okay=False))
@click.option("-o", "--output", type=click.Path(),
              help="Output folder, overriding output.dir (relative to the current folder).")
@SET
@QUIET
def simulate(config, output, settings, quiet):
    """Simulate cloth with an implicit Baraff-Witkin solver; write PLY frames.

    CONFIG is a YAML file (mesh, material, scene, solver, time, output).
    """
    from clothtool.sim.api import simulate as run

    result = run(config, output_dir=output, overrides=list(settings),
                 progress=_progress_enabled(quiet),
                 log=None if quiet else (lambda line: click.echo(line, err=True)))
    if not quiet:
        click.echo(result.describe())


# ---------------------------------------------------------------- parameter sweeps (docs/sweep.md)

OPTIONS.update({"grid": "--grid", "zip": "--zip", "random": "--random", "ranges": "--range",
                "seed": "--seed", "jobs": "--jobs", "per_task": "--per-task", "plot": "--plot",
                "against": "--against", "settings": "--set"})

SWEEP_EPILOG = """\b
Examples:
  clothtool sweep base.yaml -o runs/ --grid material.stretch=1e3,1e4,1e5 \\
        --grid material.bend=1e-5,1e-4 --jobs 2          6 runs, 2 at a time
  clothtool sweep base.yaml -o runs/ --zip material.stretch=1e3,1e4 --zip material.shear=10,100
  clothtool sweep base.yaml -o data/ --random 1000 --seed 0 \\
        --range material.stretch=1e3:1e5:log --range material.damping=0:0.05 --slurm --per-task 10
  clothtool sweep-report runs/ --plot max_stretch --against material.stretch

\b
Rerun the same command to resume: done runs are skipped (failed ones too, unless
--retry-failed). runs/manifest.csv lists every run, its parameters and status.

""" + EXIT_CODES_HELP


@main.command(epilog=SWEEP_EPILOG)
@click.argument("base", type=click.Path(dir_okay=False))
@simulation_options("Sweep folder: run_NNNN/ per run, manifest.csv (a rerun resumes it).")
@click.option("--grid", multiple=True, metavar="KEY=V1,V2,...",
              help="Values of one config key; the runs are the product of all --grid lists.")
@click.option("--zip", "zipped", multiple=True, metavar="KEY=V1,V2,...",
              help="Values taken together, element by element, across all --zip lists.")
@click.option("--random", type=int, default=None, metavar="N",
              help="N random samples of the --range keys (needs --seed).")
@click.option("--range", "ranges", multiple=True, metavar="KEY=LO:HI[:log|:int]",
              help="A range a --random sweep draws from: uniform, log-uniform or integer.")
@click.option("--seed", type=int, default=None, help="Seed of a --random sweep.")
@click.option("--per-task", default=1, show_default=True, type=int,
              help="Runs per Slurm array task.")
@click.option("--analyze", is_flag=True,
              help="Also analyse each run against its rest pattern (--reference uv).")
@click.option("--fields", default="stretch,area_ratio,flags", show_default=True, metavar="NAMES",
              help="Fields the --analyze results store (as analyze --fields).")
@click.option("--retry-failed", is_flag=True, help="Rerun the runs that failed before.")
@QUIET
def sweep(base, output, grid, zipped, random, ranges, seed, settings, jobs, slurm, per_task,
          analyze, fields, retry_failed, quiet):
    """Run a simulation for each combination of config values (a parameter sweep).

    BASE is a simulation config; each run gets a folder with its resolved config,
    frames and stats.csv. A run that fails is recorded with its error and the sweep
    goes on (exit code 3 when any run failed). Gather the results with sweep-report.
    """
    from clothtool.sweeps.api import sweep as run_sweep

    with runs_bar(quiet, slurm, "sweep") as bar:
        result = run_sweep(base, output, grid=list(grid), zip=list(zipped), random=random,
                           ranges=list(ranges), seed=seed, settings=list(settings), jobs=jobs,
                           slurm=slurm, per_task=per_task, analyze=analyze, fields=fields,
                           retry_failed=retry_failed, on_done=None if bar is None else (lambda r, s: bar.update()))
    if not quiet or slurm:
        click.echo(result.describe())
    if result.failed and not slurm:
        click.get_current_context().exit(3)


FIT_EPILOG = """\b
Examples:
  clothtool fit sample_data/strip.yaml --target sample_data/strip/capture \\
        --range material.bend=1e-6:1e-3:log --range material.damping=1e-3:0.1:log -o fit/
      the bending and damping that make the strip fall as the capture did
  clothtool fit sheet.yaml --target 'scan/*.ply' --range material.stretch=1e3:1e5:log \\
        -o fit/ -j 2        a scan, compared surface to surface; 2 simulations at a time
  clothtool fit sheet.yaml --target cap/ --range material.bend.0=1e-6:1e-4:log \\
        --range material.bend.1=1e-6:1e-4:log -o fit/ --slurm      warp and weft, on Slurm

\b
Rerun the same command to resume (an interruption, or a round left to Slurm).
Writes DIR/fit.yaml (the config with the fitted values: clothtool simulate DIR/fit.yaml),
DIR/fit.csv (a row per simulation), DIR/fit.png, DIR/runs/ (each round a sweep).

""" + EXIT_CODES_HELP

OPTIONS.update({"capture": "--target", "compare": "--compare", "outliers": "--outliers",
                "max_simulations": "--max-simulations", "scan": "--scan"})


@main.command(epilog=FIT_EPILOG)
@click.argument("config", type=click.Path(dir_okay=False))
@click.option("--target", required=True, multiple=True, metavar="FRAMES",
              help="The capture: a folder, glob or list of PLY/OBJ frames (repeatable); frame 0 "
                   "the initial state, frame k the config's output frame k.")
@click.option("--range", "ranges", required=True, multiple=True, metavar="KEY=LO:HI[:log]",
              help="A numeric config key to fit and its range (repeatable); log: in log space.")
@simulation_options("Fit folder: fit.yaml, fit.csv, fit.png, runs/ (a rerun resumes it).",
                    rounds=True)
@click.option("--compare", type=click.Choice(["auto", "vertex", "surface"]), default="auto",
              show_default=True, help="Vertex for vertex (the capture has the config's mesh) or "
                                      "each captured vertex to the simulated surface; auto: "
                                      "vertex for vertex when the meshes match.")
@click.option("--outliers", type=float, default=None, metavar="DIST",
              help="Metres beyond which a residual counts less and less (Cauchy loss): stray "
                   "points of a scan do not pull the fit.")
@click.option("--register/--no-register", default=True, show_default=True,
              help="Move the capture rigidly so that its frame 0 lies nearest the config's "
                   "initial state (a capture in another frame, or slightly off).")
@click.option("--scan", default=0, show_default=True, type=int, metavar="N",
              help="First simulate N values of each key across its range (N^keys simulations, "
                   "one round) and start from the nearest to the capture (keys with local "
                   "minima, such as friction).")
@click.option("--max-simulations", default=40, show_default=True, type=int,
              help="Stop after this many simulations with the best so far.")
@click.option("--compare-strain", is_flag=True,
              help="Also analyse the capture and the fit (against their first frames) and "
                   "report the per-triangle stretch difference.")
@QUIET
def fit(config, target, ranges, output, settings, jobs, slurm, compare, outliers, register,
        scan, max_simulations, compare_strain, quiet):
    """Fit material values so that the simulation of CONFIG moves as a captured sequence
    did (scipy's trust-region least squares, finite-difference Jacobian in log space).

    CONFIG reproduces the capture's setup (mesh, pins, colliders, fps, frames). The report
    gives each fitted value with its uncertainty (from the Jacobian at the fit), the RMS and
    largest distance, and the values the capture cannot tell apart.
    """
    from clothtool.sweeps.motion_fit import fit as run_fit

    with runs_bar(quiet, slurm, "fit") as bar:
        result = run_fit(config, list(target), list(ranges), output, settings=list(settings),
                         compare=compare, outliers=outliers, register=register, scan=scan,
                         jobs=jobs, slurm=slurm,
                         max_simulations=max_simulations, compare_strain=compare_strain,
                         on_done=None if bar is None else (lambda r, s: bar.update()),
                         log=None if quiet else (
                             (lambda line: bar.write(line, file=sys.stderr)) if bar is not None
                             else (lambda line: click.echo(line, err=True))))
    if not quiet or slurm:
        click.echo(result.describe())


@main.command("sweep-report")
@click.argument("runs", type=click.Path(file_okay=False))
@click.option("--plot", multiple=True, metavar="METRIC",
              help="Draw METRIC (a table column, e.g. max_stretch) against a parameter.")
@click.option("--against", default=None, metavar="KEY",
              help="The parameter of --plot's x axis [default: the sweep's first].")
@click.option("--format", "plot_format", type=click.Choice(["png", "pdf", "svg"]), default="png",
              show_default=True, help="Format of the plots.")
def sweep_report(runs, plot, against, plot_format):
    """Gather a sweep into one table: RUNS/report.csv and RUNS/report.h5 (per-frame series).

    One row per run: parameters, status and error, ms/frame, max stretch, final
    energies, min separation, and with --analyze the strain percentiles.
    """
    from clothtool.sweeps.report import sweep_report as gather

    click.echo(gather(runs, plot=plot, against=against, plot_format=plot_format).describe())


@main.command("sweep-task", hidden=True)
@click.argument("runs", type=click.Path(file_okay=False))
@click.argument("ids", nargs=-1, required=True)
def sweep_task(runs, ids):
    """One Slurm array task of a sweep: run the named runs that are not done yet."""
    from clothtool.sweeps.slurm import run_task

    for run, status in run_task(runs, list(ids)).items():
        click.echo(f"{run}: {status['status']}" + (f": {status['error']}" if "error" in status
                                                   else f" in {status['seconds']:.2f} s"))


def run():
    """The ``clothtool`` console script: :func:`main`, then a fast exit.

    Finalising the interpreter with numba and LLVM loaded collects garbage for about
    0.2 s (a third of a small analysis); ``gc.freeze()`` moves every object to the
    permanent generation so that the final collections skip them. Outputs are closed
    by then, and the operating system frees the memory.
    """
    import gc

    try:
        main()
    finally:
        gc.freeze()


if __name__ == "__main__":  # pragma: no cover
    run()
