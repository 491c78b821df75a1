"""The kernel plan shared by the triangle and the tetrahedron kernels."""

import numpy as np
import pytest

from clothtool.analysis import deformation2d, tet
from clothtool.fields import FIELDS_TET
from clothtool.analysis.kernel_plan import Slots


def test_slots_must_match_the_registry():
    names = tuple(f.name for f in FIELDS_TET)
    with pytest.raises(ImportError, match="volume_ratio"):
        Slots("tet", names[:-2] + names[-1:], FIELDS_TET, {})
    with pytest.raises(ImportError, match="extra"):
        Slots("tet", (*names, "extra"), FIELDS_TET, {})
    assert Slots("tet", names[::-1], FIELDS_TET, {}).index["F"] == len(names) - 1


@pytest.mark.parametrize("module, fields, needs", [
    (deformation2d, ("flags", "stretch", "F"), deformation2d.NEED_PRINCIPAL | deformation2d.NEED_POLAR),
    (deformation2d, ("area_ratio", "strain"), deformation2d.NEED_C),
    (tet, ("flags", "directions", "volume_ratio"), tet.NEED_POLAR | tet.NEED_C),
    (tet, ("F", "strain"), tet.NEED_C),
    (tet, ("F", "flags"), 0),
])
def test_plan_packs_the_requested_fields(module, fields, needs):
    m = 5
    plan = module.KernelPlan(m, fields)
    assert plan.needs == needs
    assert set(plan.fields) == set(fields)
    out, out_flags, views = plan.allocate(np.float32)
    assert out.dtype == np.float32 and out_flags.dtype == np.uint8
    float_fields = [f for f in module.SLOTS.fields if f.name in fields and not f.integer]
    assert len(out) == plan.float_size == sum(m * f.size for f in float_fields)
    assert len(out_flags) == plan.flags_size == (m if "flags" in fields else 0)
    offset = 0
    for f in float_fields:  # slot order, one after the other
        view = views[f.name]
        assert view.shape == (m, *f.shape) and view.flags.c_contiguous
        assert np.shares_memory(view, out)
        assert plan.starts[module.SLOTS.index[f.name]] == offset
        offset += m * f.size
    skipped = [s for s, name in enumerate(module.SLOTS.names) if name not in fields]
    assert (plan.starts[skipped] == -1).all()
    with pytest.raises(ValueError, match="volume_ratio" if module is deformation2d else "area_ratio"):
        module.KernelPlan(m, ("volume_ratio" if module is deformation2d else "area_ratio",))


def test_flagged_tetrahedron_is_nan_in_the_requested_fields_only():
    x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]])
    tets = np.array([[1, 2, 3, 0], [0, 1, 4, 2]])  # the second is flat
    r = tet.analyze_tet_pair(x, 1.5 * x, tets, fields=("stretch", "U", "flags"))
    assert set(r) == {"stretch", "U", "flags"}
    np.testing.assert_allclose(r["stretch"][0], 1.5)
    assert np.isnan(r["stretch"][1]).all() and np.isnan(r["U"][1]).all()
    assert r["flags"][1] & tet.FLAG_REFERENCE_DEGENERATE
