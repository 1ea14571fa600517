"""Every exporter declares the model's unit from one table; the coordinates never change."""

from __future__ import annotations

import numpy as np
import pytest

from meshfit.errors import InputError
from meshfit.export import export_3dm, export_iges
from meshfit.export.units import UNITS, unit
from tests.bspline.grids import random_surface
from tests.export.iges_reader import entity_128_surface, read_entities, read_global, read_sections


@pytest.fixture(scope="module")
def surface():
    return random_surface(np.random.default_rng(5), 5, 4)


def test_the_unit_table():
    assert list(UNITS) == ["mm", "cm", "m", "in", "ft"]
    assert unit("MM") is unit("mm") and unit("mm").meters == 1e-3
    assert unit("in").meters == 0.0254
    assert unit("ft").meters == pytest.approx(12 * unit("in").meters, rel=1e-15)
    with pytest.raises(InputError, match=r"one of \('mm', 'cm', 'm', 'in', 'ft'\)"):
        unit("furlong")


@pytest.mark.parametrize("name", list(UNITS))
def test_iges_declares_the_unit(surface, tmp_path, name):
    path = export_iges(tmp_path / "u.igs", surface, units=name)
    g = read_global(read_sections(path))
    u = unit(name)
    assert (int(g[13]), g[14]) == (u.iges_flag, f"{len(u.iges_name)}H{u.iges_name}")
    (e,) = read_entities(path)
    np.testing.assert_array_equal(
        entity_128_surface(e["params"]).control_points, surface.control_points
    )


def test_iges_default_is_millimetres(surface, tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = export_iges(tmp_path / "a" / "u.igs", surface)
    b = export_iges(tmp_path / "b" / "u.igs", surface, units="MM")
    ga, gb = read_global(read_sections(a)), read_global(read_sections(b))
    assert (ga[13], ga[14]) == ("2", "2HMM")
    dates = (17, 24)  # the file's and the model's time stamps
    assert [x for k, x in enumerate(ga) if k not in dates] == [
        x for k, x in enumerate(gb) if k not in dates
    ]
    assert [x for x in a.read_text().splitlines() if x[72] in "DP"] == [
        x for x in b.read_text().splitlines() if x[72] in "DP"
    ]


@pytest.mark.parametrize("name", list(UNITS))
def test_3dm_declares_the_unit(surface, tmp_path, name):
    import rhino3dm

    path = export_3dm(tmp_path / "u.3dm", surface, units=name)
    model = rhino3dm.File3dm.Read(str(path))
    assert model.Settings.ModelUnitSystem == getattr(rhino3dm.UnitSystem, unit(name).rhino_name)
    g = model.Objects[0].Geometry
    got = np.array([[g.Points.GetControlPoint(i, j).X for j in range(4)] for i in range(5)])
    np.testing.assert_array_equal(got, surface.control_points[:, :, 0])
