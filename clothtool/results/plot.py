"""``clothtool plot``: one figure that shows a result at a glance (matplotlib, optional extra).

Four panels: (1) the 5th/50th/95th percentiles of the principal stretches λ1, λ2 and
(2) of the area ratio λ1λ2 against the deformed frame, from ``/summary``; (3) histograms of
λ1, λ2 and the area ratio over the triangles of the pairs (at most :data:`HISTOGRAM_PAIRS` pairs, evenly
spaced); (4) one field of one pair drawn on its deformed mesh in 3D (:mod:`view3d`), with the
run's colliders at the frame's time when its scene is given. A tetrahedral result shows λ3
too, the volume ratio, and its boundary surface in panel 4.
"""

import os

import numpy as np

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path
from clothtool.results.export import field_values
from clothtool.io.result import open_result, read_summary
from clothtool.results.frame_times import frame_times
from clothtool.results.view3d import (COLLIDER_RGB, draw_meshes, layout, light_direction, lit,
                                      push_back, setup_axes)

HISTOGRAM_PAIRS = 100
FIELD_AMBIENT = 0.65  # the field's colours lit softly: shape visible, colours still readable


def pyplot(command="plot"):
    """matplotlib's pyplot on the headless Agg backend; ``command`` names who needs it."""
    try:
        import matplotlib
    except ImportError:
        raise InputError(f"clothtool {command} needs matplotlib: "
                         "pip install 'clothtool[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _band(ax, t, summary, name, label, color):
    ax.fill_between(t, summary[f"{name}_p5"], summary[f"{name}_p95"], color=color, alpha=0.25,
                    lw=0, label=f"{label} 5–95 %")
    ax.plot(t, summary[f"{name}_p50"], color=color, lw=1.5, label=f"{label} median")


def _histogram_data(h5, group, ratio):
    """λ1, λ2 (λ3), J (finite values) of up to HISTOGRAM_PAIRS evenly spaced pairs, and the
    count; ``ratio``: the dataset of J in ``group``."""
    n = len(h5["pairs"])
    picks = np.unique(np.linspace(0, n - 1, min(n, HISTOGRAM_PAIRS)).round().astype(int))
    out = {}
    if "stretch" in h5.get(group, {}):
        s = np.concatenate([h5[f"{group}/stretch"][p] for p in picks])
        for k in range(s.shape[1]):
            out[f"λ{k + 1}"] = s[:, k]
    if ratio in h5.get(group, {}):
        out[ratio.replace("_", " ")] = np.concatenate([h5[f"{group}/{ratio}"][p] for p in picks])
    return {k: v[np.isfinite(v)] for k, v in out.items()}, len(picks)


def _image_format(output):
    """The image format named by the extension of ``output`` (png without one)."""
    from matplotlib.backend_bases import FigureCanvasBase

    fmt = os.path.splitext(os.fspath(output))[1][1:].lower() or "png"
    known = FigureCanvasBase.get_supported_filetypes()
    if fmt not in known:
        raise InputError(f"{output}: unknown image format {fmt!r}; use one of "
                         f"{', '.join(sorted(known))}")
    return fmt


def _draw_field_3d(ax, x, faces, values, scene, frame_path):
    """The deformed mesh ``x`` in 3D with its face ``values`` in viridis (NaN grey), lit
    softly; the colliders of ``scene`` at the frame's time. Returns the colour mapping."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    finite = values[np.isfinite(values)]
    vmin, vmax = (finite.min(), finite.max()) if finite.size else (0.0, 1.0)
    mapping = ScalarMappable(Normalize(vmin, vmax if vmax > vmin else vmin + 1e-12),
                             colormaps["viridis"].with_extremes(bad="0.5"))
    times = frame_times([frame_path], scene.fps) if scene is not None else [0.0]
    cloth, colliders, (centre, half) = layout(x[None], scene, times)
    light = light_direction()
    rgb = mapping.to_rgba(np.ma.masked_invalid(values))[:, :3]
    meshes = [(cloth[0], faces, lit(cloth[0], faces, rgb, light, ambient=FIELD_AMBIENT))]
    meshes += [(push_back(v, f), f, lit(v, f, COLLIDER_RGB, light)) for v, f in colliders[0]]
    draw_meshes(ax, meshes)
    setup_axes(ax, centre, half)
    return mapping


def plot_result(h5_path, output, *, pair=None, field=None, component=0, dpi=120, scene=None):
    """Draw the overview figure of the result ``h5_path`` into ``output`` (format from its
    extension). ``pair``: the pair of the map (default: the largest 95th percentile of λ1);
    ``field``: the mapped dataset (default: stretch, else area_ratio); ``scene``: the run's
    scene (:class:`clothtool.sim.scene.RunScene`: colliders at the deformed frame's time,
    up), or None (y up). Returns the pair drawn."""
    from clothtool.io.h5 import check_output_path

    plt = pyplot()
    check_output_path(output)
    fmt = _image_format(output)
    with open_result(h5_path) as h5:
        summary = read_summary(h5)
        tets = "tets" in h5["mesh"]
        group, ratio = ("tet", "volume_ratio") if tets else ("face", "area_ratio")
        field = field or ("stretch" if "stretch" in h5.get(group, {}) else ratio)
        if pair is None:
            pair = int(summary["pair"][np.nanargmax(summary["lambda1_p95"])])
        values, where, name = field_values(h5, pair, field, component)
        offset = int(h5.attrs.get("pair_offset", 0))
        frame = int(h5["pairs"][pair - offset][1])
        x = h5["frame_vertices"][frame].astype(np.float64)
        frame_path = h5["frames"][frame].decode()
        if where == "tet":  # its boundary surface, each triangle with its tetrahedron's value
            from clothtool.io.tetmesh import boundary_faces

            faces, owner = boundary_faces(h5["mesh/vertices"][:], h5["mesh/tets"][:])
            values, where = values[owner], "face"
        else:
            faces = h5["mesh/faces"][:]
        hist, n_hist = _histogram_data(h5, group, ratio)
        n_pairs = len(h5["pairs"])

    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5), constrained_layout=True)
    t = summary["deformed"]
    ax = axes[0, 0]
    _band(ax, t, summary, "lambda1", "λ1", "tab:red")
    _band(ax, t, summary, "lambda2", "λ2", "tab:blue")
    if tets:
        _band(ax, t, summary, "lambda3", "λ3", "tab:purple")
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set(xlabel="deformed frame", ylabel="principal stretch", title="Principal stretches per pair")
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    _band(ax, t, summary, ratio, ratio.replace("_", " "), "tab:green")
    ax.axhline(1.0, color="k", lw=0.6)
    ratio_label = ("volume ratio det F", "Volume ratio") if tets else ("area ratio λ1·λ2",
                                                                      "Area ratio")
    ax.set(xlabel="deformed frame", ylabel=ratio_label[0], title=f"{ratio_label[1]} per pair")
    ax.legend(fontsize=8)

    ax = axes[1, 0]
    if hist:
        lo = min(v.min() for v in hist.values() if v.size)
        hi = max(v.max() for v in hist.values() if v.size)
        bins = np.linspace(lo, hi if hi > lo else lo + 1e-6, 60)
        colors = {"λ1": "tab:red", "λ2": "tab:blue", "λ3": "tab:purple", "area ratio": "tab:green",
                  "volume ratio": "tab:green"}
        for label, v in hist.items():
            ax.hist(v, bins=bins, histtype="step", lw=1.5, color=colors[label], label=label)
        ax.set_yscale("log")
        ax.xaxis.set_major_locator(plt.MaxNLocator(5))
        ax.legend(fontsize=8)
    ax.set(xlabel="value", ylabel="tetrahedra" if tets else "triangles",
           title=f"Histogram over {'all' if n_hist == n_pairs else n_hist} of {n_pairs} pairs")

    axes[1, 1].remove()
    ax = fig.add_subplot(2, 2, 4, projection="3d")
    mappable = _draw_field_3d(ax, x, faces, values if where == "face" else values[faces].mean(axis=1),
                              scene, frame_path)
    label = f"λ{component + 1}" if field == "stretch" else name
    fig.colorbar(mappable, ax=ax, shrink=0.8, label=label)
    shown = " with the colliders" if scene is not None and scene.colliders is not None else ""
    ax.set_title(f"{label} of pair {pair} (frame {frame}){shown}")
    fig.suptitle(str(h5_path))
    with atomic_path(output) as tmp:  # the temporary name has no extension: say the format
        fig.savefig(tmp, dpi=dpi, format=fmt)
    plt.close(fig)
    return pair
