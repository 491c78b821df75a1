"""``clothtool render``: a simulated sequence as PNG frames and a short movie, headless.

Each frame shows the cloth (and, given the run's scene, its colliders at the frame's time)
in 3D (:mod:`clothtool.results.view3d`), with one camera for the whole sequence that holds
every frame's cloth, at the frame's time (:func:`~clothtool.results.frame_times.frame_times`).
The movie is an MP4 through ffmpeg when matplotlib finds it, else an animated GIF
(matplotlib's PillowWriter), at the frames' own rate. Every frame is read and every collider
placed before anything is written; PNGs and the movie appear complete or not at all.
"""

import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path, finish
from clothtool.io.frames import FrameReader, discover_frames, is_tet_path
from clothtool.results.frame_times import frame_times
from clothtool.results.plot import pyplot
from clothtool.results.view3d import (CLOTH_RGB, COLLIDER_RGB, draw_meshes, layout,
                                      light_direction, lit, push_back, setup_axes)

PNG = re.compile(r"frame_\d{5,}\.png")
MOVIES = ("movie.mp4", "movie.gif")
DEFAULT_FPS = 30.0


@dataclass
class RenderResult:
    output_dir: Path
    frames: int
    movie: Path | None
    seconds_per_frame: float

    def describe(self):
        movie = f", movie {self.movie}" if self.movie else ""
        return (f"{self.frames} PNG frames in {self.output_dir}/{movie} "
                f"({1000 * self.seconds_per_frame:.0f} ms/frame)")


def render_sequence(frames, output_dir, *, scene=None, fps=None, dpi=100, size=(6.4, 4.8),
                    movie=True, progress=False):
    """Draw every frame of ``frames`` (a folder, glob or list of PLY/OBJ files) into
    ``output_dir``/frame_NNNNN.png (NNNNN: the frame's index in the sequence), and the
    movie. ``scene``: a run's scene (:class:`clothtool.sim.scene.RunScene`: colliders, fps,
    up) or None (cloth only, y up); ``fps``: the frame rate of frames without
    ``stats.csv`` times (default the scene's, else 30). Returns a :class:`RenderResult`."""
    import time

    from tqdm import tqdm

    if fps is not None and not fps > 0:
        raise InputError(f"must be > 0, got {fps:g}", keyword="fps")
    if not dpi > 0:
        raise InputError(f"must be > 0, got {dpi}", keyword="dpi")
    paths = discover_frames(frames)
    if is_tet_path(paths[0]):
        raise InputError(f"{paths[0]}: render draws triangle meshes (PLY or OBJ frames), "
                         "not tetrahedra")
    out = _output_folder(output_dir)
    plt = pyplot("render")
    reader = FrameReader(paths)
    positions = np.stack([reader.positions(k) for k in range(len(paths))])
    faces = reader.faces
    times = frame_times(paths, fps or (scene.fps if scene is not None else DEFAULT_FPS))
    cloth, colliders, (centre, half) = layout(positions, scene, times)
    light = light_direction()

    _remove_earlier_render(out)
    fig = plt.figure(figsize=size, dpi=dpi)
    ax = fig.add_axes([0, 0, 1, 1], projection="3d")
    setup_axes(ax, centre, half)
    label = fig.text(0.02, 0.96, "", fontsize=10, va="top")
    writer, movie_path, movie_tmp = _movie_writer(out, _movie_fps(times)) if movie else (None,) * 3
    started = time.perf_counter()
    ok = False
    try:
        if writer is not None:
            writer.setup(fig, movie_tmp, dpi)
        for k in tqdm(range(len(paths)), desc="render", unit="frame", file=sys.stderr,
                      disable=not progress):
            meshes = [(cloth[k], faces, lit(cloth[k], faces, CLOTH_RGB, light))]
            meshes += [(push_back(x, f), f, lit(x, f, COLLIDER_RGB, light)) for x, f in colliders[k]]
            collection = draw_meshes(ax, meshes)
            label.set_text(f"t = {times[k]:.3f} s")
            with atomic_path(out / f"frame_{k:05d}.png") as tmp:
                fig.savefig(tmp, dpi=dpi, format="png")
            if writer is not None:
                writer.grab_frame()
            collection.remove()
        if writer is not None:
            writer.finish()
        ok = True
    finally:
        plt.close(fig)
        if writer is not None:
            finish([(movie_tmp, movie_path)], ok)
    return RenderResult(out, len(paths), movie_path,
                        (time.perf_counter() - started) / len(paths))


def _output_folder(output_dir):
    out = Path(output_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create the output folder: {exc.strerror}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"{out}: output folder is not writable")
    return out


def _remove_earlier_render(out):
    for old in out.iterdir():
        if PNG.fullmatch(old.name) or old.name in MOVIES:
            old.unlink()


def _movie_fps(times):
    """Frames per second of the movie: one over the frames' median spacing in time."""
    steps = np.diff(times)
    steps = steps[steps > 0]
    return float(1.0 / np.median(steps)) if len(steps) else DEFAULT_FPS


def _movie_writer(out, fps):
    """(writer, final path, temporary path): MP4 through ffmpeg when available, else GIF."""
    from matplotlib import animation

    if animation.writers.is_available("ffmpeg"):
        writer, name = animation.FFMpegWriter(
            fps=fps, extra_args=["-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2"]), \
            "movie.mp4"
    else:
        writer, name = animation.PillowWriter(fps=fps), "movie.gif"
    final = out / name
    # the writers choose the container by the file's extension: the temporary name keeps it
    return writer, final, out / f".{name}.tmp-{os.getpid()}{final.suffix}"
