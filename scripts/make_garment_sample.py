"""Generate the garment sample in sample_data/garment/: a walking mannequin and a two-panel skirt.

- body/frame_KK.obj: the mannequin, an OBJ sequence at BODY_FPS frames per second over
  DURATION s (y up, metres, facing +z). A union of closed surfaces: an ellipsoid torso, a
  sphere head, capsule legs and arms. It stands still while the skirt is sewn (STILL s), then
  walks: the legs swing about the hips by ±LEG_SWING (one stride a second), the arms against
  them, the torso turns about the vertical by ±TURN. The collider reader interpolates linearly
  between frames, so BODY_FPS = 10 is enough for the 30 fps simulation and keeps the files small.
- skirt.obj: the pattern, two trapezoid panels ``g front`` (facing +z) and ``g back`` (facing
  −z), their per-corner ``vt`` in centimetres of the pattern (``mesh.uv_scale: 0.01``), each TOP
  cm wide at the waist and BOTTOM cm at the hem, LENGTH cm long. They are laid out wrapped
  around the body, as pattern software arranges panels on an avatar: each row of a panel on an
  arc around the torso's waist ellipse, offset outward so that the arc is as long as the row
  (the waist row 6 mm off the body), flaring out to FLARE m and below that taking up the rest of
  its width in FOLDS folds per panel; the arcs stop SIDE_GAP short of each other at the sides,
  which sewing closes, and the sewn waist (2 × TOP = 87 cm around) fits the body's (85 cm).
  Their side edges are also ``l`` polylines in the groups ``front_left``, ``front_right``,
  ``back_left`` and ``back_right``: the seams, named.
- ../garment.yaml (beside the folder): the scene. The side seams (``mesh.seams``), sewn with
  gravity off while the body stands, the body as an animated mesh collider with friction,
  self-collision, the waistband (the top rows of both panels) attached to the body, OBJ frames
  and an MDD cache beside the PLY frames.

    python scripts/make_garment_sample.py sample_data/garment
"""

import os
import sys

import numpy as np

from clothtool.contact.shapes import capsule
from clothtool.io.caches.obj_writer import write_obj

BODY_FPS, DURATION, STILL, RAMP = 10, 1.5, 0.4, 0.3  # frames/s, s, s standing, s to full stride
LEG_SWING, ARM_SWING, TURN, STRIDE = np.radians(20.0), np.radians(12.0), np.radians(8.0), 1.0
TORSO_CENTER, TORSO_AXES = np.array([0.0, 1.10, 0.0]), np.array([0.16, 0.33, 0.11])
HEAD_CENTER, HEAD_RADIUS = np.array([0.0, 1.55, 0.0]), 0.10
HIP, LEG_LENGTH, LEG_RADIUS = np.array([0.085, 0.86, 0.0]), 0.76, 0.065
SHOULDER, ARM_LENGTH, ARM_RADIUS, ARM_OUT = np.array([0.19, 1.36, 0.0]), 0.55, 0.045, np.radians(50)
WAIST_Y, SIDE_GAP, TOP, BOTTOM, LENGTH, NX, NY = 1.12, 0.01, 43.5, 70.0, 45.0, 19, 13
FLARE, FOLDS = 0.04, 4  # m the skirt stands out from the waist at most, folds per panel


def ellipsoid(center, axes, around=28, rings=14):
    """A closed ellipsoid: a uv sphere (poles on y, ``rings`` bands) scaled by ``axes``;
    faces counter-clockwise seen from outside."""
    phi = np.linspace(0.0, np.pi, rings + 1)[1:-1]  # from the top pole down
    theta = np.linspace(0.0, 2.0 * np.pi, around, endpoint=False)
    p, t = np.meshgrid(phi, theta, indexing="ij")
    ring = np.stack([np.sin(p) * np.sin(t), np.cos(p), np.sin(p) * np.cos(t)], -1).reshape(-1, 3)
    x = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]])
    last = len(x) - 1
    at = lambda k, j: 1 + k * around + j % around  # noqa: E731
    faces = []
    for j in range(around):
        faces += [[0, at(0, j), at(0, j + 1)], [last, at(rings - 2, j + 1), at(rings - 2, j)]]
        faces += [f for k in range(rings - 2) for f in
                  ([at(k, j), at(k + 1, j), at(k + 1, j + 1)], [at(k, j), at(k + 1, j + 1), at(k, j + 1)])]
    return x * axes + center, np.array(faces, np.int64)


def limb(start, direction, length, radius, around=14, rings=3):
    """A closed capsule from ``start`` along the unit ``direction``, ``length`` between its
    cap centres."""
    x, faces = capsule(radius=radius, half_length=0.5 * length, around=around, rings=rings)
    x[:, 0] -= 0.5 * length  # the +x cap centre at the origin, the body along −x
    d = -np.asarray(direction, float)
    d /= np.linalg.norm(d)
    e = np.cross(d, [0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.cross(d, [1.0, 0.0, 0.0])
    e /= np.linalg.norm(e)
    frame = np.stack([d, e, np.cross(d, e)])  # rows: where x, y, z go (right-handed)
    return x @ frame + start, faces


def turn_y(points, angle):
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def swing(angle, out=0.0, side=1.0):
    """The unit direction of a limb hanging down, turned ``out`` from the vertical toward
    side·x and then swung forward (toward +z) by ``angle``."""
    down = np.array([side * np.sin(out), -np.cos(out), 0.0])
    c, s = np.cos(angle), np.sin(angle)
    return np.array([down[0], c * down[1], -s * down[1]])


def body(t):
    """(x, faces) of the mannequin at time t."""
    ramp = np.clip((t - STILL) / RAMP, 0.0, 1.0)
    ramp = ramp * ramp * (3.0 - 2.0 * ramp)  # smoothstep: starts and reaches the stride gently
    phase = np.sin(2.0 * np.pi * STRIDE * max(t - STILL, 0.0)) * ramp
    parts = [ellipsoid(TORSO_CENTER, TORSO_AXES),
             ellipsoid(HEAD_CENTER, np.full(3, HEAD_RADIUS), around=16, rings=8)]
    for side in (1.0, -1.0):
        hip, shoulder = HIP * [side, 1, 1], SHOULDER * [side, 1, 1]
        parts.append(limb(hip, swing(side * LEG_SWING * phase), LEG_LENGTH, LEG_RADIUS))
        parts.append(limb(shoulder, swing(-side * ARM_SWING * phase, ARM_OUT, side), ARM_LENGTH,
                          ARM_RADIUS))
    xs, fs, n = [], [], 0
    for x, f in parts:
        xs.append(x)
        fs.append(f + n)
        n += len(x)
    x = turn_y(np.concatenate(xs), TURN * phase)
    return x, np.concatenate(fs)


def panel():
    """(pattern uv (V, 2) cm, faces): a trapezoid, NX across and NY down, row NY−1 the waist."""
    i, j = np.meshgrid(np.arange(NX), np.arange(NY))
    s, h = i.ravel() / (NX - 1), j.ravel() / (NY - 1)
    width = BOTTOM + (TOP - BOTTOM) * h
    uv = np.stack([(s - 0.5) * width, h * LENGTH], axis=1)
    faces = []
    for b in range(NY - 1):
        for a in range(NX - 1):
            v = b * NX + a
            faces += [(v, v + 1, v + NX + 1), (v, v + NX + 1, v + NX)] if (a < (NX - 1) // 2) \
                else [(v, v + 1, v + NX), (v + 1, v + NX + 1, v + NX)]
    return uv, np.array(faces, np.int64)


def arc(offset, wave=0.0, width=None, samples=2001):
    """The arc around the torso at the waist, ``offset`` m out from its ellipse plus ``wave`` m
    × sin(FOLDS π s), s from 0 to 1 along it (FOLDS folds, none at the ends), stopping where
    the front and back arcs are SIDE_GAP apart: (points (samples, 2) x, z from one side to the
    other, its length); with ``width``, the NX points at arc lengths 0 … width."""
    ax, az = TORSO_AXES[[0, 2]] * np.sqrt(1.0 - ((WAIST_Y - TORSO_CENTER[1]) / TORSO_AXES[1]) ** 2)
    end = np.arccos(0.5 * SIDE_GAP / (az + offset))
    phi = np.linspace(-end, end, samples)
    r = offset + wave * np.sin(FOLDS * np.pi * np.linspace(0.0, 1.0, samples))
    p = np.stack([(ax + r) * np.sin(phi), (az + r) * np.cos(phi)], axis=1)
    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    if width is None:
        return p, along[-1]
    s = np.linspace(0.0, along[-1], NX)
    return np.stack([np.interp(s, along, p[:, 0]), np.interp(s, along, p[:, 1])], axis=1), along[-1]


def bisect(length, lo, hi):
    """The x in [lo, hi] where the increasing length(x) is 0 (60 halvings)."""
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if length(mid) < 0.0 else (lo, mid)
    return hi


def wrapped(uv):
    """(V, 3) the panel laid around the body (see the module): row by row, the offset whose arc
    is the row's width, up to FLARE; beyond it the folds' depth that makes up the width; each
    row below the last by its pattern distance."""
    out, y, last = np.zeros((len(uv), 3)), WAIST_Y, None
    for j in range(NY - 1, -1, -1):  # from the waist down
        width = 0.01 * (uv[j * NX + NX - 1, 0] - uv[j * NX, 0])
        offset = min(bisect(lambda d: arc(d)[1] - width, -0.05, 0.5), FLARE)
        wave = bisect(lambda w: arc(offset, w)[1] - width, 0.0, 0.2) if offset == FLARE else 0.0
        if last is not None:
            step = 0.01 * LENGTH / (NY - 1)
            y -= np.sqrt(step * step - (offset - last) ** 2)
        last = offset
        xz, _ = arc(offset, wave, width)
        out[j * NX:(j + 1) * NX] = np.column_stack([xz[:, 0], np.full(NX, y), xz[:, 1]])
    return out


def skirt():
    """(positions, faces, corner uv, groups, seams {name: vertices}, waist vertices)."""
    uv, faces = panel()
    n = len(uv)
    front = wrapped(uv)
    back = front * [-1.0, 1.0, -1.0]  # turned half round: faces −z
    rows = np.arange(NY) * NX
    seams = {"front_left": rows, "back_left": n + rows + NX - 1,
             "front_right": rows + NX - 1, "back_right": n + rows}
    waist = np.concatenate([rows[-1] + np.arange(NX), n + rows[-1] + np.arange(NX)])
    corner = uv[faces]
    return (np.concatenate([front, back]), np.concatenate([faces, faces + n]),
            np.concatenate([corner, corner]), (["front", "back"], np.repeat([0, 1], len(faces))),
            seams, waist)


SCENE = """\
# A two-panel skirt sewn onto a walking mannequin (scripts/make_garment_sample.py writes this
# file and {folder}/). The panels are laid out wrapped around the hips, their sides 1 cm
# apart; with gravity off their side seams are sewn and welded while the body stands still,
# then the waistband is attached to the body and the skirt hangs and swings as the body walks.
# clothtool simulate sample_data/{folder}.yaml -o demo-out/{folder}
mesh:
  obj: {folder}/skirt.obj
  uv_scale: 0.01          # the pattern's vt are in centimetres
  seams:                  # front's left side to back's left side, and the right sides: OBJ
                          # groups of l polylines (or lists of vertex indices)
{seams}
  sewing: {{stiffness: 1000.0, time: 1.0}}
material: {{density: 0.15, stretch: 3000.0, shear: 50.0, bend: 5.0e-6, damping: 0.02}}
scene:
  gravity: [0, -9.81, 0]
  colliders:
    - mesh: {{frames: {folder}/body, fps: {fps}, friction: 0.3}}
  self_collision: {{thickness: 0.002, friction: 0.2}}
  attach: {{vertices: {waist}, to: 0}}
solver: {{newton_iterations: 8, newton_tolerance: 2.0e-2, tolerance: 1.0e-2}}
time: {{fps: 30, frames: {frames}}}
output: {{dir: ../demo-out/{folder}, format: [ply, obj, mdd]}}
"""
FRAMES = 45  # simulated frames at 30 fps: 1.5 s


def list_text(ids):
    return "[" + ", ".join(str(int(v)) for v in ids) + "]"


def seam_lines(seams):
    """The side seams by the names of the skirt's ``l`` groups (their vertex lists would do)."""
    return "\n".join(f"    - {{a: {a}, b: {b}}}" for a, b in
                     (("front_left", "back_left"), ("front_right", "back_right")))


def write_body_frame(path, x, faces):
    """A compact OBJ frame: positions to 0.1 mm, which is all a collider needs here."""
    with open(path, "w") as fh:
        np.savetxt(fh, x, fmt="v %.4f %.4f %.4f")
        np.savetxt(fh, faces + 1, fmt="f %d %d %d")


def main(out_dir):
    os.makedirs(os.path.join(out_dir, "body"), exist_ok=True)
    frames = int(round(DURATION * BODY_FPS))
    for k in range(frames + 1):
        x, faces = body(k / BODY_FPS)
        write_body_frame(os.path.join(out_dir, "body", f"frame_{k:03d}.obj"), x, faces)
    x, faces, corner, groups, seams, waist = skirt()
    path = os.path.join(out_dir, "skirt.obj")
    write_obj(path, x, faces, corner_uv=corner, groups=groups)
    with open(path, "a") as fh:
        for name, ids in seams.items():
            fh.write(f"g {name}\nl " + " ".join(str(v + 1) for v in ids) + "\n")
    folder = os.path.basename(os.path.normpath(out_dir))
    with open(os.path.join(os.path.dirname(os.path.normpath(out_dir)) or ".",
                           f"{folder}.yaml"), "w") as fh:
        fh.write(SCENE.format(folder=folder, fps=BODY_FPS, frames=FRAMES,
                              seams=seam_lines(seams), waist=list_text(waist)))
    print(f"{out_dir}: {frames + 1} body frames of {len(body(0.0)[1])} triangles; skirt "
          f"{len(x)} vertices, {len(faces)} triangles")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join("sample_data", "garment"))
