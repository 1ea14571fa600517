"""The session's fit actions without a browser: continuity per curve, the whole fit with
progress and cancel, one-patch re-fits, the map brush and exports in any format."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit.displacement import reconstruct
from meshfit.errors import InputError
from meshfit.ui.fitting import (
    FitCancelled,
    deviation_colors,
    deviation_percent,
    patch_colors,
)
from meshfit.ui.fitview import grid_lines
from meshfit.ui.state import Session
from tests.conftest import real_mesh
from tests.ui.helpers import SPOT_LAYOUT


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    s = Session(real_mesh("spot"), autosave=tmp_path_factory.mktemp("fit") / "s.json")
    s.load_layout(SPOT_LAYOUT)
    return s


@pytest.fixture(scope="module")
def fitted(session):
    stages: list[str] = []
    session.set_curve_continuity(0, "C0")
    result = session.fit_model(
        progress=lambda st, d, n: stages.append(st) if st not in stages else None
    )
    return result, stages


def test_continuity_per_curve_and_default(session):
    n = len(session.state.boundary_ids)
    assert not session.creases().any() and session.creases().shape == (n,)
    session.set_curve_continuity(3, "C0")
    assert session.curve_continuity(3) == "C0" and session.creases()[3]
    assert session.undo() and not session.creases()[3]  # undoable like any edit
    session.set_default_continuity("C0")
    assert session.creases().all()
    session.set_curve_continuity(3, "G1")
    assert session.creases().sum() == n - 1 and not session.creases()[3]
    assert session.layout().creases.sum() == n - 1  # the layout the fit gets carries them
    session.set_default_continuity("G1")
    session.set_curve_continuity(3, "default")
    assert not session.creases().any()
    with pytest.raises(InputError, match="C0 or G1"):
        session.set_default_continuity("G2")
    with pytest.raises(InputError, match="C0, G1 or default"):
        session.set_curve_continuity(3, "C2")


def test_continuity_survives_the_session_file(session, tmp_path):
    session.set_curve_continuity(5, "C0")
    path = tmp_path / "again.json"
    path.write_text(session.to_json())
    other = Session(session.mesh)
    other.restore(path)
    assert other.curves[5].continuity == "C0" and other.curves[4].continuity is None
    session.set_curve_continuity(5, None)


def test_fit_model_uses_the_chosen_continuity(fitted, session):
    result, stages = fitted
    assert stages[:3] == ["validate", "layout", "cut"] and "springs" in stages
    cont = {(b.a, b.b): b.continuity for b in result.network.boundaries}
    assert "C0" in cont.values() and "G1" in cont.values()
    assert sum(c == "C0" for c in cont.values()) == 1  # curve 0 only
    assert session.result is result


def test_fit_cancel_keeps_the_last_result(fitted, session):
    cancel = threading.Event()
    cancel.set()
    with pytest.raises(FitCancelled, match="cancelled at stage validate"):
        session.fit_model(cancel=cancel)
    assert session.result is fitted[0]


def test_refit_one_patch_leaves_the_others(fitted, session):
    before = session.result
    after = session.refit_patch(3, controls=(6, 5))
    assert after.patches[3].surface.control_points.shape[:2] == (6, 5)
    assert all(after.patches[p] is before.patches[p] for p in range(len(before.patches)) if p != 3)
    whole = session.refit_all(controls=(8, 8))
    assert {p.surface.control_points.shape[:2] for p in whole.patches} == {(8, 8)}


def test_brush_raises_the_displaced_surface(fitted, session):
    result = session.result
    mesh = session.mesh
    diag = mesh.bbox_diagonal
    grid = result.patches[2].displaced()
    centre = grid[grid.shape[0] // 2, grid.shape[1] // 2]
    new = session.brush_map(2, centre, radius=0.02 * diag, amount=0.01 * diag)
    # (the rebuild may give the map more texels to match its neighbours': compare the
    # surfaces at the same parameters)
    pf = new.patches[2]
    moved = reconstruct(pf.surface, pf.displacement, shape=grid.shape[:2])
    lift = np.linalg.norm(moved - grid, axis=2)
    assert_allclose(lift.max(), 0.01 * diag, rtol=0.1)  # the dab's height at its centre
    # and little elsewhere (the rebuild closes the seams the re-fits above opened)
    assert np.median(lift) < 0.05 * lift.max()
    assert new.summary["rebuilt"]  # seams closed again
    with pytest.raises(InputError, match="radius > 0"):
        session.brush_map(2, centre, radius=0.0, amount=1.0)
    # after a patch is re-fitted alone at other counts the seams cannot be closed: the
    # brush still moves the surface (its own reconstruction), without the rebuild
    odd = session.refit_patch(2, controls=(5, 7))
    again = session.brush_map(2, centre, radius=0.02 * diag, amount=-0.01 * diag)
    assert again.summary is odd.summary  # (a rebuild makes a new summary)
    down = np.linalg.norm(again.patches[2].displaced() - odd.patches[2].displaced(), axis=2)
    assert_allclose(down.max(), 0.01 * diag, rtol=0.1)


def test_export_fit_any_format(fitted, session, tmp_path):
    files = session.export_fit(tmp_path, formats=("3dm", "iges", "glb", "png"), units="cm")
    suffixes = {p.suffix for p in files}
    assert {".3dm", ".igs", ".glb", ".png"} <= suffixes
    assert all(p.is_file() for p in files)
    assert ",10,2HCM," in (tmp_path / "spot.igs").read_text()  # IGES unit flag 10: cm
    with pytest.raises(InputError, match="at least one format"):
        session.export_fit(tmp_path, formats=())
    with pytest.raises(InputError, match="units"):
        session.export_fit(tmp_path, formats=("obj",), units="furlong")


def test_deviation_of_the_scan_itself_is_zero():
    mesh = real_mesh("spot")
    d = deviation_percent(mesh, mesh.vertices[:50])
    assert_allclose(d, 0.0, atol=1e-9)
    off = np.array(mesh.vertices[:5])
    off[:, 0] += 0.01 * mesh.bbox_diagonal  # 1 % of the diagonal away, at most
    d = deviation_percent(mesh, off)
    assert (d > 0).all() and (d <= 1.0 + 1e-9).all()


def test_colours_distinct_and_ramp_ends():
    c = patch_colors(60)
    assert len({tuple(x) for x in c}) == 60
    ramp = deviation_colors(np.array([0.0, 0.5, 1.0, 9.0]), 1.0)
    assert tuple(ramp[0]) == (40, 60, 220) and tuple(ramp[2]) == tuple(ramp[3]) == (230, 50, 40)


def test_fine_grids_are_thinned_to_lines():
    u, v = np.meshgrid(np.linspace(0, 1, 129), np.linspace(0, 1, 97), indexing="ij")
    grid = np.stack([u, v, 0 * u], axis=2)
    seg = grid_lines(grid, max_lines=24)
    xs = np.unique(seg[:, :, 0].round(9))
    ys = np.unique(seg[:, :, 1].round(9))
    rows = np.unique(seg[np.isclose(seg[:, 0, 0], seg[:, 1, 0]), 0, 0].round(9))
    assert len(rows) <= 24 and {0.0, 1.0} <= set(rows.tolist())  # border kept
    assert len(xs) == 129 and len(ys) == 97  # lines still follow every grid point
    small = grid_lines(grid[:5, :4])
    assert len(small) == 5 * 3 + 4 * 4  # a coarse level is drawn whole


def test_crease_curves_of_a_layout_start_at_c0():
    from dataclasses import replace

    from tests.ui.helpers import spot_layout

    lay = spot_layout()
    mask = np.zeros(len(lay.curves), bool)
    mask[[1, 7]] = True
    s = Session(real_mesh("spot"))
    s.set_layout(replace(lay, creases=mask))  # as the automatic layout marks creases
    got = [s.curves[i].continuity for i in s.state.boundary_ids]
    assert got == ["C0" if m else None for m in mask]
    assert_allclose(s.creases(), mask)
