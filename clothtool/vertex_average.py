"""Per-vertex versions of face fields: averages over the incident triangles, weighted by
their rest area, for smooth colour maps.

    v_i = Σ_{t ∋ i} A_t f_t / Σ_{t ∋ i} A_t,   A_t = rest area = ½ |det D_r| = ½ / |det D_r⁻¹|

Triangles whose value is NaN (flagged) or whose rest area is not finite take no part;
a vertex with no such triangle gets NaN. Tensors are averaged component by component.
"""

import numpy as np

from clothtool.fields import AVERAGEABLE
from clothtool.errors import InputError

SUFFIX = "_avg"  # /vertex/<field>_avg


def parse_vertex_average(names):
    """'stretch,area_ratio', an iterable of names, or None/'' → tuple in canonical order."""
    if not names:
        return ()
    names = [n.strip() for n in names.split(",")] if isinstance(names, str) else list(names)
    for n in names:
        if n not in AVERAGEABLE:
            raise InputError(f"no vertex average of {n!r}; choose from {', '.join(AVERAGEABLE)}",
                             keyword="vertex_average")
    return tuple(n for n in AVERAGEABLE if n in names)


def rest_areas(dinv):
    """Rest area of each triangle from D_r⁻¹ (M, 2, 2): ½ / |det D_r⁻¹| (NaN where degenerate)."""
    det = dinv[:, 0, 0] * dinv[:, 1, 1] - dinv[:, 0, 1] * dinv[:, 1, 0]
    with np.errstate(divide="ignore"):
        return 0.5 / np.abs(det)


class VertexAverager:
    """Area-weighted averages of face values onto the vertices of a fixed triangle mesh."""

    def __init__(self, faces, n_vertices):
        import scipy.sparse

        m = len(faces)
        rows = np.asarray(faces).ravel()
        cols = np.repeat(np.arange(m), 3)
        self.incidence = scipy.sparse.csr_matrix((np.ones(3 * m), (rows, cols)),
                                                 shape=(n_vertices, m))

    def __call__(self, values, areas):
        """(N, …) averages of face ``values`` (M, …) with weights ``areas`` (M,)."""
        flat = np.asarray(values, np.float64).reshape(len(values), -1)
        valid = np.isfinite(flat) & np.isfinite(areas)[:, None]
        w = np.where(valid, np.nan_to_num(areas, nan=0.0, posinf=0.0)[:, None], 0.0)
        num = self.incidence @ (w * np.where(valid, flat, 0.0))
        den = self.incidence @ w
        with np.errstate(invalid="ignore", divide="ignore"):
            out = np.where(den > 0, num / den, np.nan)
        return out.reshape(-1, *np.shape(values)[1:])
