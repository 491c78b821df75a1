"""Pictures of a run: ``clothtool render`` (PNG frames and a movie, with the run's colliders at
each frame's time), ``clothtool plot``'s 3D mesh panel with colliders, and the pieces under
them: the colliders as surfaces (known geometry), frame times, the 3D view's basis and light."""

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

import clothtool
from clothtool.cli import main
from clothtool.io.ply import write_ply
from clothtool.results.frame_times import frame_times
from clothtool.results.view3d import display_basis, lit, push_back, view_direction
from clothtool.sim.scene import capsule_mesh, plane_patch, run_scene, subdivide

plt = pytest.importorskip("matplotlib.pyplot")
Image = pytest.importorskip("PIL.Image")

FRAMES = 4
CLOTH = np.array([0.80, 0.33, 0.22])


def body_frames(folder, k=3):
    """An animated mesh collider: a closed tetrahedron-shaped box moving +x, k frames."""
    folder.mkdir()
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) * 0.2 + [-0.1, -0.9, -0.1]
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    for j in range(k):
        write_ply(folder / f"body_{j}.ply", x + [0.1 * j, 0, 0], faces)
    return x, faces


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A sheet above every kind of collider, simulated for FRAMES frames (every 2nd written)."""
    root = tmp_path_factory.mktemp("render")
    body_frames(root / "body")
    config = {"mesh": {"grid": {"nx": 8, "ny": 8, "width": 0.8, "height": 0.8, "plane": "xz"}},
              "material": {"stretch": 1000.0, "shear": 100.0},
              "scene": {"colliders": [
                  {"sphere": {"center": [0, -0.3, 0], "radius": 0.2}},
                  {"capsule": {"a": [-0.3, -0.5, 0.3], "b": [0.3, -0.5, 0.3], "radius": 0.05}},
                  {"box": {"center": [0.3, -0.55, -0.3], "size": [0.1, 0.1, 0.1]}},
                  {"plane": {"point": [0, -1.0, 0], "normal": [0, 1, 0]}},
                  {"mesh": {"frames": "body", "fps": 30}}]},
              "solver": {"newton_iterations": 6, "newton_tolerance": 2e-2, "tolerance": 1e-2},
              "time": {"frames": 2 * FRAMES, "fps": 30},
              "output": {"every": 2, "format": ["ply", "obj"]}}
    (root / "scene.yaml").write_text(yaml.safe_dump(config))
    clothtool.simulate(root / "scene.yaml", output_dir=root / "out", progress=False)
    return root


def render(*args):
    return CliRunner().invoke(main, ["render", *map(str, args)])


def pixels_near(image, rgb, tolerance=0.12):
    """Fraction of pixels whose colour is within ``tolerance`` of a shade of ``rgb``."""
    px = image[..., :3].reshape(-1, 3)
    scale = (px @ rgb) / (rgb @ rgb)
    return float(np.mean(np.abs(px - scale[:, None] * rgb).max(axis=1) < tolerance * (scale > 0.3)))


def test_render_writes_every_frame_and_a_movie(run, tmp_path):
    out = tmp_path / "pics"
    result = render(run / "out", "-o", out, "--config", run / "scene.yaml")
    assert result.exit_code == 0, result.output
    assert f"{FRAMES + 1} PNG frames in {out}/" in result.output
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == [f"frame_{k:05d}.png" for k in range(FRAMES + 1)]
    movie = out / "movie.gif" if (out / "movie.gif").exists() else out / "movie.mp4"
    assert movie.is_file() and not list(out.glob(".*"))
    image = plt.imread(out / "frame_00004.png")
    assert image.shape[:2] == (480, 640)
    assert pixels_near(image, CLOTH) > 0.01  # the cloth
    grey = np.array([0.72, 0.74, 0.78])
    with_colliders = pixels_near(image, grey, 0.03)
    assert with_colliders > 0.05  # the plane patch, sphere, capsule, box, body
    if movie.suffix == ".gif":
        gif = Image.open(movie)
        assert gif.n_frames == FRAMES + 1
        assert gif.info["duration"] in (60, 66, 67)  # frames 2/30 s apart: 15 fps

    beside = tmp_path / "beside"  # no --config: the config.yaml simulate wrote beside the frames
    assert render(run / "out", "-o", beside, "--no-movie", "-q").exit_code == 0
    assert not list(beside.glob("movie.*"))
    assert pixels_near(plt.imread(beside / "frame_00004.png"), grey, 0.03) > 0.05

    bare = tmp_path / "bare"  # no config given and none beside the frames: the cloth only
    frames = tmp_path / "frames"
    frames.mkdir()
    for ply in (run / "out").glob("frame_*.ply"):
        (frames / ply.name).write_bytes(ply.read_bytes())
    assert render(frames, "-o", bare, "--no-movie", "-q").exit_code == 0
    assert pixels_near(plt.imread(bare / "frame_00004.png"), grey, 0.03) < 0.2 * with_colliders


def test_render_writes_an_mp4_through_ffmpeg(run, tmp_path):
    import shutil
    import subprocess

    if shutil.which("ffmpeg") is None or shutil.which("ffprobe") is None:
        pytest.skip("ffmpeg is not installed: apt-get install -y --no-install-recommends ffmpeg")
    out = tmp_path / "pics"
    result = render(run / "out", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == \
        [f"frame_{k:05d}.png" for k in range(FRAMES + 1)] + ["movie.mp4"]
    probe = subprocess.run(
        ["ffprobe", "-v", "error", "-select_streams", "v:0", "-count_frames", "-show_entries",
         "stream=codec_name,width,height,nb_read_frames,avg_frame_rate,pix_fmt", "-of", "json",
         str(out / "movie.mp4")], capture_output=True, text=True, check=True)
    import json

    stream = json.loads(probe.stdout)["streams"][0]
    assert stream["codec_name"] == "h264" and stream["pix_fmt"] == "yuv420p"
    assert (stream["width"], stream["height"]) == (640, 480)
    assert int(stream["nb_read_frames"]) == FRAMES + 1
    assert stream["avg_frame_rate"] == "15/1"  # frames 2/30 s apart


def test_render_of_obj_frames_uses_the_runs_times(run, tmp_path):
    times = frame_times(sorted((run / "out" / "obj").glob("*.obj")), fps=1000.0)
    np.testing.assert_allclose(times, np.arange(0, 2 * FRAMES + 1, 2) / 30)  # stats.csv, one up
    assert render(run / "out" / "obj", "-o", tmp_path / "o", "--no-movie", "-q").exit_code == 0
    assert len(list((tmp_path / "o").glob("*.png"))) == FRAMES + 1


def test_a_rerun_replaces_the_earlier_pictures(run, tmp_path):
    out = tmp_path / "pics"
    assert render(run / "out", "-o", out, "-q").exit_code == 0
    (out / "mine.png").write_bytes(b"x")
    frames = sorted((run / "out").glob("frame_*.ply"))[:2]
    assert render(*frames, "-o", out, "-q").exit_code == 0
    assert sorted(p.name for p in out.iterdir() if p.suffix == ".png") == \
        ["frame_00000.png", "frame_00001.png", "mine.png"]


def test_frame_times_without_stats(tmp_path):
    names = [tmp_path / "frame_00000.ply", tmp_path / "frame_00010.ply", tmp_path / "x.ply"]
    np.testing.assert_allclose(frame_times(names, 20.0), [0.0, 0.5, 0.1])


def test_bad_input_is_one_line_and_writes_nothing(run, tmp_path):
    (tmp_path / "file").write_text("")
    (tmp_path / "broken").mkdir()
    for k in range(3):
        (tmp_path / "broken" / f"frame_{k:05d}.ply").write_bytes(
            (run / "out" / f"frame_{2 * k:05d}.ply").read_bytes()[:-8 if k == 2 else None])
    bad_config = tmp_path / "bad.yaml"
    bad_config.write_text("mesh: {grid: {}}\nscene: {colliders: [{sphere: {radius: -1}}]}\n")
    cases = [((tmp_path / "none", "-o", tmp_path / "o1"), "none: no such file or folder"),
             ((run / "out", "-o", tmp_path / "file"), "file' is a file"),
             ((run / "out", "-o", tmp_path / "o2", "--fps", "0"), "--fps: must be > 0, got 0"),
             ((tmp_path / "broken", "-o", tmp_path / "o3"), "frame_00002.ply"),
             ((run / "out", "-o", tmp_path / "o4", "--config", bad_config),
              "scene.colliders[0].sphere.radius must be > 0")]
    for args, message in cases:
        result = render(*args)
        assert result.exit_code == 2, result.output
        assert result.output.count("\n") == 1 and message in result.output, result.output
        out = args[2]
        assert out.name == "file" or not out.exists() or not list(out.iterdir())


def test_plot_draws_the_pair_in_3d_with_the_colliders(run, tmp_path):
    clothtool.analyze_sequence(run / "out", tmp_path / "a.h5", reference="uv")
    for name, extra in (("with", ["--colliders", run / "scene.yaml"]), ("without", [])):
        result = CliRunner().invoke(main, ["plot", str(tmp_path / "a.h5"), "-o",
                                           str(tmp_path / f"{name}.png"), *map(str, extra)])
        assert result.exit_code == 0, result.output
    panel = [plt.imread(tmp_path / f"{n}.png") for n in ("with", "without")]
    grey = np.array([0.72, 0.74, 0.78])
    quarter = [p[p.shape[0] // 2:, p.shape[1] // 2:] for p in panel]
    assert pixels_near(quarter[0], grey, 0.03) > 0.05 > pixels_near(quarter[1], grey, 0.03)


# ------------------------------------------------------------------ the pieces


def distance_to_segment(p, a, b):
    d = b - a
    s = np.clip(((p - a) @ d) / max(d @ d, 1e-300), 0, 1)
    return np.linalg.norm(p - (a + s[:, None] * d), axis=1)


@pytest.mark.parametrize("a, b", [([0, 0, 0], [0, 0, 0]), ([0, 0, 0], [1, 2, 2]),
                                  ([1, 1, 1], [3, 1, 1])])
def test_capsule_and_sphere_surfaces_are_at_the_radius(a, b):
    a, b = np.array(a, float), np.array(b, float)
    v, f = capsule_mesh(a, b, 0.3)
    np.testing.assert_allclose(distance_to_segment(v, a, b), 0.3, atol=1e-12)
    assert f.min() == 0 and f.max() == len(v) - 1
    # closed and facing out: the signed volume (divergence theorem) is the capsule's
    # π r² L + 4/3 π r³ less the inscribed polygons' shortfall (2.8 % at 12 × 24)
    volume = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
    exact = np.pi * 0.3 ** 2 * np.linalg.norm(b - a) + 4 / 3 * np.pi * 0.3 ** 3
    assert 0.97 < volume / exact < 1.0


def test_plane_patch_lies_in_the_plane_about_the_nearest_point():
    v, f = plane_patch(np.array([0, 1.0, 0]), np.array([0, 2.0, 0]), np.array([3, 5, -1]), 0.5)
    np.testing.assert_allclose(v[:, 1], 1.0)
    np.testing.assert_allclose(v.mean(axis=0), [3, 1, -1])
    np.testing.assert_allclose(np.abs(v - [3, 1, -1]).max(axis=0), [0.5, 0, 0.5])
    assert f.shape == (2, 3)


@pytest.mark.parametrize("n", [1, 2, 5])
def test_subdivide_keeps_the_area_and_orientation(n):
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 3]], float)
    f = np.array([[0, 1, 2], [0, 3, 1]])
    sv, sf = subdivide(v, f, n)
    assert len(sf) == 2 * n * n

    def normals(x, t):
        return np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]])
    big, small = normals(v, f), normals(sv, sf)
    np.testing.assert_allclose(small.reshape(2, n * n, 3).sum(axis=1), big, atol=1e-12)
    np.testing.assert_allclose(small, np.repeat(big, n * n, axis=0) / n ** 2, atol=1e-12)


def test_scene_surfaces_follow_the_motion_and_the_frames(tmp_path):
    x, faces = body_frames(tmp_path / "body", k=2)
    config = {"mesh": {"grid": {}}, "time": {"fps": 10},
              "scene": {"gravity": [0, 0, -9.81], "colliders": [
                  {"sphere": {"center": [0, 0, 0], "radius": 0.1,
                              "motion": {"translate": {"velocity": [1, 0, 0], "until": 1.0}}}},
                  {"mesh": {"frames": str(tmp_path / "body"), "fps": 10}}]}}
    scene = run_scene(config)
    assert scene.fps == 10 and np.allclose(scene.up, [0, 0, 1])
    sphere, body = scene.surfaces(0.05, np.zeros(3), 1.0)
    assert sphere.key == "scene.colliders[0].sphere" and body.key == "scene.colliders[1].mesh"
    np.testing.assert_allclose(sphere.vertices.mean(axis=0), [0.05, 0, 0], atol=1e-12)
    np.testing.assert_allclose(body.vertices, x + [0.05, 0, 0])  # halfway between the frames
    np.testing.assert_array_equal(body.faces, faces)
    assert scene.surfaces(2.0, np.zeros(3), 1.0)[0].vertices.mean(axis=0)[0] == pytest.approx(1.0)


def test_run_scene_finds_a_sweep_runs_config(tmp_path):
    assert run_scene(None, tmp_path) is None
    (tmp_path / "config.yaml").write_text("mesh: {grid: {}}\ntime: {fps: 48}\n")
    assert run_scene(None, tmp_path).fps == 48
    assert run_scene({"mesh": {"grid": {}}}, tmp_path).fps == 30


@pytest.mark.parametrize("up", [[0, 1, 0], [0, 0, 1], [1, 0, 0], [0.3, -0.5, 0.8]])
def test_display_basis_is_a_rotation_taking_up_to_z(up):
    b = display_basis(up)
    np.testing.assert_allclose(b @ b.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(b) == pytest.approx(1.0)
    np.testing.assert_allclose(b @ (np.array(up) / np.linalg.norm(up)), [0, 0, 1], atol=1e-12)
    if up == [0, 1, 0]:
        np.testing.assert_allclose(b, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)


def test_lambert_shading_and_push_back():
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = np.array([[0, 1, 2], [0, 2, 1], [0, 3, 1]])  # normal +z, −z (two-sided), −y
    rgba = lit(x, faces, np.array([1.0, 0.5, 0.0]), np.array([0.0, 0.0, 1.0]), ambient=0.2)
    np.testing.assert_allclose(rgba[:2, :3], [[1, 0.5, 0]] * 2)
    np.testing.assert_allclose(rgba[2, :3], [0.2, 0.1, 0])  # edge-on to the light: ambient
    moved = push_back(x, faces)
    shift = moved - x
    np.testing.assert_allclose(shift, shift[0] + 0 * shift)  # one translation
    np.testing.assert_allclose(shift[0] / np.linalg.norm(shift[0]), view_direction())
    assert np.linalg.norm(shift[0]) == pytest.approx(1.0)  # the median edge: 1 (of 1, 1, √2)
