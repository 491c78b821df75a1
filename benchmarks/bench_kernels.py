"""The per-triangle 2D kernel against numpy routes: throughput and accuracy (issues 2 and 5).

For 100k triangles, in one run: clothtool's closed-form numba kernel (serial and all
cores), numpy ``eigh`` of C (λ = √w, U = V·diag(λ)·Vᵀ, R = F·U⁻¹) and numpy ``svd``
of F. Accuracy is measured against the same closed-form formulas evaluated in
extended precision (np.longdouble, 64-bit mantissa), in three regimes: moderate
deformation, near-isotropic (λ1 ≈ λ2) and strongly anisotropic (λ2/λ1 ≈ 1e-6), and
for float32 and float64 storage of clothtool's results. The summary (throughput, and each
route's worst error over the regimes) is README.md's ``kernels`` table.
"""

import pathlib

import numba
import numpy as np

from benchmarks.common import markdown_table, median_seconds, write_csv, write_doc_table
from clothtool.analysis.deformation2d import (KernelPlan, deformation_fields,
                                              reference_from_positions)

M = 100_000


def triangles(regime, rng):
    """(reference, deformed, faces) of M independent triangles in a regime."""
    ref = rng.normal(size=(M, 3, 3))
    A = np.eye(3) + 0.3 * rng.normal(size=(M, 3, 3))
    if regime == "near-isotropic":
        A = np.eye(3) * rng.uniform(0.5, 2.0, (M, 1, 1)) + 1e-7 * rng.normal(size=(M, 3, 3))
    elif regime == "anisotropic":
        A = np.eye(3)[None].repeat(M, 0)
        A[:, 0, 0] = 1e-6
    dfm = np.einsum("mij,mkj->mki", A, ref)
    faces = np.arange(3 * M).reshape(M, 3)
    return ref.reshape(-1, 3), dfm.reshape(-1, 3), faces


def tangent_F(x_ref, x_def, faces, dtype):
    def frame(x):
        x = x.astype(dtype)
        e1 = x[faces[:, 1]] - x[faces[:, 0]]
        e2 = x[faces[:, 2]] - x[faces[:, 0]]
        a = np.sqrt((e1 * e1).sum(1))
        t1 = e1 / a[:, None]
        b = (t1 * e2).sum(1)
        n = np.cross(e1, e2)
        c = np.sqrt((n * n).sum(1)) / a
        D = np.zeros((len(faces), 2, 2), dtype)
        D[:, 0, 0], D[:, 0, 1], D[:, 1, 1] = a, b, c
        return D
    Dr, Dd = frame(x_ref), frame(x_def)
    inv = np.zeros_like(Dr)
    inv[:, 0, 0] = 1 / Dr[:, 0, 0]
    inv[:, 0, 1] = -Dr[:, 0, 1] / (Dr[:, 0, 0] * Dr[:, 1, 1])
    inv[:, 1, 1] = 1 / Dr[:, 1, 1]
    return np.einsum("mij,mjk->mik", Dd, inv)


def closed_form_numpy(F):
    """The kernel's formulas, vectorised, in F's dtype (longdouble for the reference)."""
    f00, f01, f10, f11 = F[:, 0, 0], F[:, 0, 1], F[:, 1, 0], F[:, 1, 1]
    c, s = f00 + f11, f10 - f01
    h = np.sqrt(c * c + s * s)
    c, s = c / h, s / h
    u00 = c * f00 + s * f10
    u01 = 0.5 * ((c * f01 + s * f11) + (-s * f00 + c * f10))
    u11 = -s * f01 + c * f11
    half = 0.5 * (u00 - u11)
    lam1 = 0.5 * (u00 + u11) + np.sqrt(half * half + u01 * u01)
    lam2 = np.abs(f00 * f11 - f01 * f10) / lam1
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    U = np.stack([np.stack([u00, u01], -1), np.stack([u01, u11], -1)], -2)
    return np.stack([lam1, lam2], -1), R, U


def numpy_eigh(F):
    C = np.transpose(F, (0, 2, 1)) @ F
    w, V = np.linalg.eigh(C)
    lam = np.sqrt(np.clip(w, 0, None))[:, ::-1]
    U = V @ (np.sqrt(np.clip(w, 0, None))[:, :, None] * np.transpose(V, (0, 2, 1)))
    R = F @ np.linalg.inv(U)
    return lam, R, U


def numpy_svd(F):
    W, S, Vt = np.linalg.svd(F)
    return S, W @ Vt, np.transpose(Vt, (0, 2, 1)) @ (S[:, :, None] * Vt)


def clothtool_kernel(x_ref, x_def, faces, dtype):
    ref = reference_from_positions(x_ref, faces, 1e-8)
    plan = KernelPlan(len(faces), ("stretch", "R", "U"))
    out, out_flags, views = plan.allocate(dtype)
    deformation_fields(x_def, faces, *ref, 1e-8, plan.starts, plan.needs, out, out_flags)
    return views["stretch"], views["R"], views["U"]


def rel_error(value, ref):
    """max |value − ref| / max(|ref|, tiny), per field."""
    value = np.asarray(value, np.longdouble)
    return float(np.nanmax(np.abs(value - ref) / np.maximum(np.abs(ref), 1e-300)))


def run(out_dir):
    out_dir = pathlib.Path(out_dir)
    rng = np.random.default_rng(7)
    rows = []
    for regime in ("moderate", "near-isotropic", "anisotropic"):
        x_ref, x_def, faces = triangles(regime, rng)
        F64 = tangent_F(x_ref, x_def, faces, np.float64)
        lam_ref, R_ref, U_ref = closed_form_numpy(tangent_F(x_ref, x_def, faces, np.longdouble))
        routes = {
            "clothtool closed form (numba, float64 out)": lambda: clothtool_kernel(x_ref, x_def, faces, np.float64),
            "clothtool closed form (numba, float32 out)": lambda: clothtool_kernel(x_ref, x_def, faces, np.float32),
            "numpy eigh of C": lambda: numpy_eigh(F64),
            "numpy svd of F": lambda: numpy_svd(F64),
        }
        threads = numba.get_num_threads()
        for name, fn in routes.items():
            lam, R, U = fn()
            row = {"regime": regime, "method": name,
                   "stretch_rel_err": rel_error(lam, lam_ref),
                   "lambda2_rel_err": rel_error(lam[:, 1], lam_ref[:, 1]),
                   "R_abs_err": float(np.nanmax(np.abs(np.asarray(R, np.longdouble) - R_ref))),
                   "U_err_over_lambda1": float(np.nanmax(
                       np.abs(np.asarray(U, np.longdouble) - U_ref) / lam_ref[:, :1, None]))}
            if regime == "moderate":
                seconds = median_seconds(fn)
                row["triangles_per_s"] = M / seconds
                if name.startswith("clothtool") and threads > 1:
                    numba.set_num_threads(1)
                    row["triangles_per_s_1_thread"] = M / median_seconds(fn)
                    numba.set_num_threads(threads)
            rows.append(row)
    columns = ["regime", "method", "triangles_per_s", "triangles_per_s_1_thread", "stretch_rel_err",
               "lambda2_rel_err", "R_abs_err", "U_err_over_lambda1"]
    write_csv(out_dir / "kernels.csv", rows, columns)
    with open(out_dir / "kernels.md", "w") as fh:
        fh.write(f"## 2D kernel: {M} triangles, throughput and error against an extended-precision "
                 "(np.longdouble) evaluation\n\n")
        fh.write("Throughput: median of 7, kernel only (clothtool: rest state + all of stretch, R, U; "
                 "numpy: from a precomputed F). Errors: max over triangles; U's entrywise error "
                 "is divided by the triangle's λ1.\n\n")
        fh.write(markdown_table(rows, columns))
    print((out_dir / "kernels.md").read_text())
    summary = []
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        summary.append({"route": method, **mine[0],
                        **{c: max(r[c] for r in mine) for c in columns[4:]}})
    write_doc_table("README.md", "kernels", markdown_table(summary, ["route"] + columns[2:]),
                    "kernels")


if __name__ == "__main__":
    run(pathlib.Path("bench-results"))
