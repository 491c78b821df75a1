"""``clothtool plot``: one figure that shows a result at a glance (matplotlib, optional extra).

Four panels: (1) the 5th/50th/95th percentiles of the principal stretches λ1, λ2 and
(2) of the area ratio λ1λ2 against the deformed frame, from ``/summary``; (3) histograms of
λ1, λ2 and the area ratio over the triangles of the pairs (at most :data:`HISTOGRAM_PAIRS` pairs, evenly
spaced); (4) one field of one pair drawn on its deformed mesh, projected on the mesh's
best-fit plane (the two leading right-singular vectors of the centred positions). A
tetrahedral result shows λ3 too, the volume ratio, and its boundary surface in panel 4.
"""

import os

import numpy as np

from clothtool.errors import InputError
from clothtool.io.atomic import atomic_path
from clothtool.results.export import field_values
from clothtool.io.result import open_result, read_summary

HISTOGRAM_PAIRS = 100
MISSING = "clothtool plot needs matplotlib: pip install 'clothtool[plot]'"


def pyplot():
    try:
        import matplotlib
    except ImportError:
        raise InputError(MISSING) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def best_fit_projection(x):
    """(N, 2) coordinates of points ``x`` (N, 3) in their best-fit plane (least squares)."""
    centred = x - x.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axes = vt[:2] * np.sign(vt[:2].sum(axis=1, keepdims=True) + 1e-300)  # deterministic signs
    return centred @ axes.T


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


def plot_result(h5_path, output, *, pair=None, field=None, component=0, dpi=120):
    """Draw the overview figure of the result ``h5_path`` into ``output`` (format from its
    extension). ``pair``: the pair of the map (default: the largest 95th percentile of λ1);
    ``field``: the mapped dataset (default: stretch, else area_ratio). Returns the pair drawn."""
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

    ax = axes[1, 1]
    uv = best_fit_projection(x)
    finite = values[np.isfinite(values)]
    vmin, vmax = (finite.min(), finite.max()) if finite.size else (0.0, 1.0)
    if where == "face":
        from matplotlib.collections import PolyCollection

        from matplotlib import colormaps

        shapes = PolyCollection(uv[faces], cmap=colormaps["viridis"].with_extremes(bad="0.5"),
                                edgecolors="face", linewidths=0.2)
        shapes.set_array(np.ma.masked_invalid(values))
        shapes.set_clim(vmin, vmax)
        ax.add_collection(shapes)
        mappable = shapes
    else:
        mappable = ax.tripcolor(uv[:, 0], uv[:, 1], faces, np.nan_to_num(values, nan=vmin),
                                shading="gouraud", cmap="viridis", vmin=vmin, vmax=vmax)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_axis_off()
    label = f"λ{component + 1}" if field == "stretch" else name
    fig.colorbar(mappable, ax=ax, shrink=0.8, label=label)
    ax.set_title(f"{label} of pair {pair} (frame {frame}), best-fit plane view")
    fig.suptitle(str(h5_path))
    with atomic_path(output) as tmp:  # the temporary name has no extension: say the format
        fig.savefig(tmp, dpi=dpi, format=fmt)
    plt.close(fig)
    return pair
