"""USD caches written as ``.usda`` text: the cloth and its colliders, animated, in one file.

The layout (OpenUSD's UsdGeom schemas, as Houdini, Maya, Blender and Omniverse read them):
the stage's ``timeCodesPerSecond`` and ``framesPerSecond`` are the run's fps, time code k
is frame k (t = k / fps), ``upAxis`` the axis against gravity (Y or Z), ``metersPerUnit`` 1;
``/clothtool/cloth`` is a ``Mesh`` of triangles (``faceVertexCounts``, ``faceVertexIndices``)
whose ``points`` are time-sampled at every written frame, with the pattern's texture
coordinates per corner as the ``faceVarying`` primvar ``st`` and one ``GeomSubset`` per panel
(OBJ group or material, family ``panel``); each collider is a ``Mesh`` of its own under
``/clothtool/colliders``, its points sampled at the same time codes. Points are float32
(``point3f``), written with 9 significant digits, which read back as the same float32.

:class:`UsdaWriter` streams the samples to hidden files beside the target and, on
:meth:`~UsdaWriter.close`, writes the stage under a temporary name and renames it: the file
appears complete, with the frames written so far, or not at all. No USD library is needed
to write it; ``pxr`` (usd-core) reads it.
"""

import os
import re
import shutil

import numpy as np

from clothtool.io.atomic import atomic_path, remove_quietly, temporary_name

FAMILY = "panel"


class UsdaWriter:
    """A USD cache at ``path``: a cloth of ``faces`` (M, 3), ``corner_uv`` (M, 3, 2) or None,
    ``panels`` {name: triangle indices}, at ``fps``, ``up`` 'Y' or 'Z', and ``colliders``
    [(name, faces (F, 3))] whose positions come with each frame."""

    def __init__(self, path, faces, corner_uv=None, panels=None, *, fps, up="Y", colliders=()):
        self.path = os.fspath(path)
        self.faces = np.asarray(faces, np.int64)
        self.corner_uv = corner_uv
        self.panels = {k: np.asarray(v, np.int64) for k, v in (panels or {}).items() if len(v)}
        self.fps, self.up = float(fps), up
        self.colliders = [(name, np.asarray(f, np.int64)) for name, f in colliders]
        self.codes = []
        base = temporary_name(self.path)
        self._paths = [base + f".samples{k}" for k in range(1 + len(self.colliders))]
        self._files = [open(p, "w", encoding="ascii") for p in self._paths]

    def add(self, code, positions, collider_positions=()):
        """Append the samples at time code ``code`` (the frame number): the cloth's
        ``positions`` (N, 3) and each collider's (V_c, 3)."""
        if self.codes and not code > self.codes[-1]:
            raise ValueError(f"time codes must increase: {code} after {self.codes[-1]}")
        if len(collider_positions) != len(self.colliders):
            raise ValueError(f"{len(self.colliders)} colliders, {len(collider_positions)} given")
        for fh, x in zip(self._files, [positions, *collider_positions]):
            fh.write(f"            {_number(code)}: [{_tuples(x, 3)}],\n")
        self.codes.append(code)

    def close(self, ok=True):
        """Write the stage (when ``ok`` and it has samples) and remove the samples' files."""
        if self._files[0].closed:
            return
        try:
            for fh in self._files:
                fh.close()
            if ok and self.codes:
                with atomic_path(self.path) as tmp, open(tmp, "w", encoding="ascii") as out:
                    self._write(out)
        finally:
            for p in self._paths:
                remove_quietly(p)

    def _write(self, out):
        out.write(f'#usda 1.0\n(\n    defaultPrim = "clothtool"\n'
                  f"    startTimeCode = {_number(self.codes[0])}\n"
                  f"    endTimeCode = {_number(self.codes[-1])}\n"
                  f"    timeCodesPerSecond = {_number(self.fps)}\n"
                  f"    framesPerSecond = {_number(self.fps)}\n"
                  f'    upAxis = "{self.up}"\n    metersPerUnit = 1\n)\n\n'
                  'def Xform "clothtool"\n{\n')
        self._mesh(out, "cloth", self.faces, self._paths[0], self.corner_uv, self.panels)
        if self.colliders:
            out.write('    def Xform "colliders"\n    {\n')
            for (name, faces), samples in zip(self.colliders, self._paths[1:]):
                self._mesh(out, name, faces, samples, indent="    ")
            out.write("    }\n")
        out.write("}\n")

    def _mesh(self, out, name, faces, samples, corner_uv=None, panels=None, indent=""):
        pad = "    " + indent
        out.write(f'{pad}def Mesh "{prim_name(name)}"\n{pad}{{\n'
                  f"{pad}    uniform bool doubleSided = 1\n"
                  f'{pad}    uniform token subdivisionScheme = "none"\n'
                  f'{pad}    uniform token orientation = "rightHanded"\n'
                  f"{pad}    int[] faceVertexCounts = [{', '.join(['3'] * len(faces))}]\n"
                  f"{pad}    int[] faceVertexIndices = [{', '.join(map(str, faces.ravel().tolist()))}]\n")
        if corner_uv is not None:
            out.write(f"{pad}    texCoord2f[] primvars:st = [{_tuples(corner_uv.reshape(-1, 2), 2)}] (\n"
                      f'{pad}        interpolation = "faceVarying"\n{pad}    )\n')
        out.write(f"{pad}    point3f[] points.timeSamples = {{\n")
        with open(samples, encoding="ascii") as fh:
            shutil.copyfileobj(fh, out, 1 << 20)
        out.write(f"{pad}    }}\n")
        for panel, tri in (panels or {}).items():
            out.write(f'\n{pad}    def GeomSubset "{prim_name(panel)}"\n{pad}    {{\n'
                      f'{pad}        uniform token elementType = "face"\n'
                      f'{pad}        uniform token familyName = "{FAMILY}"\n'
                      f"{pad}        int[] indices = [{', '.join(map(str, tri.tolist()))}]\n"
                      f"{pad}    }}\n")
        out.write(f"{pad}}}\n")


def prim_name(name):
    """A USD prim name (an identifier) for ``name``: other characters as ``_``, and a leading
    ``_`` before a digit."""
    out = re.sub(r"[^A-Za-z0-9_]", "_", str(name)) or "_"
    return "_" + out if out[0].isdigit() else out


def _tuples(rows, width):
    """'(a, b, c), …' of the float32 values of ``rows`` (K, width), 9 significant digits."""
    values = np.asarray(rows, np.float32).astype(np.float64).ravel().tolist()
    if not values:
        return ""
    one = "(" + ", ".join(["%.9g"] * width) + ")"
    return ", ".join([one] * (len(values) // width)) % tuple(values)


def _number(value):
    value = float(value)
    return str(int(value)) if value.is_integer() else repr(value)
