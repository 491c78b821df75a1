"""The registry of analysis fields: one entry per stored dataset kind.

Everything else is derived from :data:`REGISTRY`: which names ``fields=`` accepts, what the
2D and tet kernels compute (:mod:`clothtool.analysis.kernel_plan`), the HDF5 layout
(``/<group>/<name>``, shape (P, count, *shape)), the ParaView attributes, the vertex
averages, the ``/summary`` columns and the field list of ``clothtool analyze --help``.

Pure Python (no numpy, numba or h5py), so that ``clothtool --help`` stays fast.

Adding a 2D field: one :class:`Field` here (``kernel="2d"``) and its writer in
:mod:`clothtool.analysis.deformation2d`; a field of tetrahedral sequences (``kernel="tet"``,
group ``tet``): one :class:`Field` and its writer in :mod:`clothtool.analysis.tet`.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class Field:
    """One stored field.

    ``group``: ``face``, ``vertex``, ``edge`` or ``tet`` (the HDF5 group and what it counts);
    ``shape``: per element; ``kernel``: ``2d`` (the tangent-frame kernel), the 3D variant's
    ``kabsch``, ``face3d``, ``dihedral``, or ``tet`` (tetrahedral sequences); ``needs``: shared
    per-element quantities of the 2D or tet kernel it is computed from (``C``: FᵀF, ``polar``:
    F = R·U, ``principal``: λk and vk of the 2D kernel; the tet kernel's polar split gives
    those too);
    ``averageable``: has a vertex average ``/vertex/<name>_avg``; ``summary``: the
    ``/summary`` quantities computed from it; ``extended``: only when named (or with
    ``extended``), not in ``all``.
    """

    name: str
    group: str
    shape: tuple
    kernel: str
    definition: str
    needs: tuple = ()
    averageable: bool = False
    summary: tuple = ()
    integer: bool = False
    extended: bool = False

    @property
    def key(self):
        """``group/name``: its path in the result."""
        return f"{self.group}/{self.name}"

    @property
    def size(self):
        """Numbers per element: prod(shape)."""
        n = 1
        for s in self.shape:
            n *= s
        return n


REGISTRY = (
    Field("F", "face", (2, 2), "2d", "D_d·D_r⁻¹: reference tangent coordinates → deformed "
          "tangent coordinates", averageable=True),
    Field("C", "face", (2, 2), "2d", "FᵀF, right Cauchy–Green, in the reference tangent frame",
          needs=("C",), averageable=True),
    Field("U", "face", (2, 2), "2d", "stretch of the polar split F = R·U, symmetric positive "
          "definite", needs=("polar",), averageable=True),
    Field("R", "face", (2, 2), "2d", "rotation of the polar split F = R·U (a reflection against "
          "a flipped uv triangle)", needs=("polar",), averageable=True),
    Field("strain", "face", (2, 2), "2d", "Green–Lagrange E = (C − I)/2 (tensor shear, not "
          "engineering shear)", needs=("C",), averageable=True),
    Field("stretch", "face", (2,), "2d", "principal stretches λ1 ≥ λ2 (eigenvalues of U)",
          needs=("principal",), averageable=True, summary=("lambda1", "lambda2")),
    Field("directions", "face", (2, 3), "2d", "unit principal directions in the reference "
          "configuration, row k for λk, sign free", needs=("principal",)),
    Field("area_ratio", "face", (), "2d", "λ1·λ2 = |det F| = deformed area / reference area",
          averageable=True, summary=("area_ratio",)),
    Field("flags", "face", (), "2d", "bit 0 reference degenerate, bit 1 deformed degenerate, "
          "bit 2 non-finite input, bit 3 uv triangle flipped", integer=True, summary=("flags",)),
    Field("thickness", "face", (), "2d", "thickness stretch λ3 = 1/(λ1λ2) of an incompressible "
          "sheet", averageable=True, extended=True),
    Field("almansi", "face", (2, 2), "2d", "Euler–Almansi e = (I − B⁻¹)/2, B = F·Fᵀ, in the "
          "deformed tangent frame", averageable=True, extended=True),
    Field("hencky", "face", (2, 2), "2d", "logarithmic strain ln U = Σ ln λk vk vkᵀ, reference "
          "tangent frame", needs=("principal",), averageable=True, extended=True),
    Field("engineering", "face", (2, 2), "2d", "Biot strain U − I, reference tangent frame",
          needs=("polar",), averageable=True, extended=True),
    Field("principal_strain", "face", (2,), "2d", "Green principal strains (λk² − 1)/2, major "
          "first", needs=("principal",), averageable=True, extended=True),
    Field("max_shear", "face", (), "2d", "(E1 − E2)/2 of the Green principal strains (tensor "
          "shear)", needs=("principal",), averageable=True, extended=True),
    Field("von_mises", "face", (), "2d", "equivalent true strain √(2/3 Σ εk²), εk = ln λk, "
          "ε3 = −(ε1 + ε2)", needs=("principal",), averageable=True, extended=True),
    Field("directions_deformed", "face", (2, 3), "2d", "unit principal directions in the "
          "deformed configuration (R·vk = F·vk/λk), row k for λk, sign free",
          needs=("principal",), extended=True),
    # The 3D variant (analyze --kabsch): clothtool.analysis.variant3d.
    Field("rotation", "vertex", (3, 3), "kabsch", "Kabsch rotation R of the vertex's one-ring, "
          "a proper rotation, det R = +1"),
    Field("angle", "vertex", (), "kabsch", "rotation angle of R, radians in [0, π]"),
    Field("residual", "vertex", (), "kabsch", "√(mean ‖R p − q‖²) over the ring, in length "
          "units: the part of the motion no rotation explains (stretch plus bending)"),
    Field("flags", "vertex", (), "kabsch", "bit 0 reference ring degenerate, bit 1 deformed "
          "ring degenerate, bit 2 non-finite input, bit 3 rotation ambiguous; where any bit is "
          "set the three fields above are NaN", integer=True),
    Field("F3", "face", (3, 3), "face3d", "F3 = [e1′ e2′ n′] [e1 e2 n]⁻¹, the full-rank "
          "deformation gradient that also maps the reference unit normal to the deformed one"),
    Field("R3", "face", (3, 3), "face3d", "rotation of the polar split F3 = R3·U3, proper"),
    Field("U3", "face", (3, 3), "face3d", "stretch of the polar split F3 = R3·U3, symmetric "
          "positive definite, in the reference configuration"),
    Field("stretch3", "face", (3,), "face3d", "the eigenvalues of U3, descending"),
    Field("directions3", "face", (3, 3), "face3d", "the unit eigenvectors of U3 as rows, row k "
          "belongs to stretch3[k], in the reference configuration (sign free)"),
    Field("dihedral_change", "edge", (), "dihedral", "θ_deformed − θ_reference per interior "
          "edge, radians, wrapped to (−π, π]"),
    Field("flags", "edge", (), "dihedral", "bit 0/1 a triangle of the edge is degenerate in the "
          "reference/deformed frame, bit 2 non-finite; then the change is NaN", integer=True),
    # Tetrahedral sequences: clothtool.analysis.tet.
    Field("F", "tet", (3, 3), "tet", "G·D_r⁻¹, D = [p1 − p4, p2 − p4, p3 − p4]"),
    Field("C", "tet", (3, 3), "tet", "FᵀF, right Cauchy–Green", needs=("C",)),
    Field("U", "tet", (3, 3), "tet", "stretch of the polar split F = R·U, symmetric; one "
          "negative eigenvalue for an inverted tetrahedron (Irving, Teran & Fedkiw 2004, "
          "\"Invertible finite elements for robust simulation of large deformation\")",
          needs=("polar",)),
    Field("R", "tet", (3, 3), "tet", "rotation of the polar split F = R·U, always proper "
          "(det R = +1)", needs=("polar",)),
    Field("strain", "tet", (3, 3), "tet", "Green–Lagrange E = (C − I)/2", needs=("C",)),
    Field("stretch", "tet", (3,), "tet", "principal stretches λ1 ≥ λ2 ≥ λ3 (eigenvalues of U; "
          "λ3 < 0 if inverted)", needs=("polar",), summary=("lambda1", "lambda2", "lambda3")),
    Field("directions", "tet", (3, 3), "tet", "unit principal directions in the reference "
          "configuration, row k for λk, sign free", needs=("polar",)),
    Field("volume_ratio", "tet", (), "tet", "J = det F = deformed volume / reference volume "
          "(negative when inverted)",
          summary=("volume_ratio",)),
    Field("flags", "tet", (), "tet", "bit 0 reference degenerate, bit 1 deformed degenerate, "
          "bit 2 non-finite input, bit 4 (16) inverted", integer=True, summary=("flags",)),
)

BY_KEY = {f.key: f for f in REGISTRY}
FIELDS_2D = tuple(f for f in REGISTRY if f.kernel == "2d")
DEFAULT_2D = tuple(f.name for f in FIELDS_2D if not f.extended)
"""The 2D fields of ``fields='all'``."""
NAMES_2D = tuple(f.name for f in FIELDS_2D)
FIELDS_TET = tuple(f for f in REGISTRY if f.kernel == "tet")
NAMES_TET = tuple(f.name for f in FIELDS_TET)
"""The fields of a tetrahedral sequence (all of them by default)."""
NAMES_3D = tuple(dict.fromkeys(f.name for f in REGISTRY if f.kernel not in ("2d", "tet")
                               and f.name != "flags"))
"""Names that only the 3D variant (``kabsch=True``) stores; ``flags`` selects those of every group."""
AVERAGEABLE = tuple(f.name for f in FIELDS_2D if f.averageable)


def field(name, group="face"):
    """The registry entry of ``/<group>/<name>``."""
    return BY_KEY[f"{group}/{name}"]


def parse_fields(fields, kabsch=False, tets=False):
    """'all', 'extended', a comma-separated string or an iterable of names → tuple of names in
    registry order. 'all' is the default table (with ``kabsch``, and the 3D variant's fields);
    'extended' adds the fields that are only computed when asked for. ``tets``: the names of
    a tetrahedral sequence instead."""
    from clothtool.errors import InputError

    if tets:
        known = default = NAMES_TET
    else:
        known = NAMES_2D + NAMES_3D if kabsch else NAMES_2D
        default = DEFAULT_2D + NAMES_3D if kabsch else DEFAULT_2D
    if fields is None or fields == "all":
        return default
    names = [f.strip() for f in fields.split(",")] if isinstance(fields, str) else list(fields)
    names = [n for n in names if n]
    if "all" in names or "extended" in names:
        names += [n for n in (known if "extended" in names else default)]
    names = [n for n in names if n not in ("all", "extended")]
    unknown = [n for n in names if n not in known]
    if unknown and unknown[0] in NAMES_3D:
        raise InputError(f"{unknown[0]!r} belongs to the 3D variant; add {{kabsch}}",
                         keyword="fields", mentions={"kabsch": "kabsch=True"})
    if unknown and tets:
        raise InputError(f"unknown field {unknown[0]!r} for tetrahedra; choose from all, "
                         f"{', '.join(known)}", keyword="fields")
    if unknown or not names:
        raise InputError((f"unknown field {unknown[0]!r}" if unknown else "empty")
                         + f"; choose from all, extended, {', '.join(known)}", keyword="fields")
    return tuple(n for n in known if n in names)


def help_table(width=76):
    """The field list of ``clothtool analyze --help``: one line per 2D field, then the 3D
    variant's names by group."""
    rows = []
    pad = max(len(f.name) for f in FIELDS_2D) + 2
    for f in FIELDS_2D:
        shape = "×".join(map(str, f.shape)) or ("uint8" if f.integer else "scalar")
        extra = " (only when named)" if f.extended else ""
        rows.append(f"  {f.name:<{pad}}{shape:<7}{f.definition}{extra}")
    groups = {}
    for f in REGISTRY:
        if f.kernel not in ("2d", "tet") and f.name != "flags":
            groups.setdefault(f.group, []).append(f.name)
    rows.append("  with --kabsch also: " + "; ".join(
        f"{' '.join(names)} (per {group}, /{group}/...)" for group, names in groups.items()))
    rows.append("  flags then also selects /vertex/flags and /edge/flags")
    rows.append("  tetrahedral frames (.vtu .vtk .msh .node): " + " ".join(NAMES_TET)
                + " (per tetrahedron, /tet/..., 3×3; λ1 ≥ λ2 ≥ λ3, J = det F)")
    return "\n".join(_wrap(r, width) for r in rows)


def _wrap(row, width):
    """A row broken at spaces to ``width`` characters, continuation lines indented."""
    import textwrap

    indent = " " * 4 if row.startswith(("  with", "  tetrahedral")) else " " * 21
    return "\n".join(textwrap.wrap(row, width, subsequent_indent=indent,
                                   break_long_words=False, drop_whitespace=True)) or row
