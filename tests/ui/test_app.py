"""The viser glue without a browser: event handlers called with the events viser would pass."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from meshfit.ui.app import App
from meshfit.ui.files import FilePolicy
from meshfit.ui.state import Session
from tests.conftest import real_mesh
from tests.ui.helpers import click_ray, side_picks


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    a = App(Session(real_mesh("spot")), FilePolicy(tmp_path_factory.mktemp("glue")), port=0)
    yield a
    a.stop()


def _click(app, xyz):
    o, d = click_ray(app.session.mesh, xyz)
    app._on_click(SimpleNamespace(ray_origin=tuple(o), ray_direction=tuple(d)))
    return app.messages[-1]


def _drag_end(position):
    return SimpleNamespace(phase="end", target=SimpleNamespace(position=tuple(position)))


def test_clicks_paint_and_edit(app):
    s = app.session
    picks = side_picks(s.mesh)[0]
    assert "started" in _click(app, picks[0])
    for x in picks[1:]:
        _click(app, x)
    app.gui_mode.value = "feature"  # a stroke of the other kind is refused, not a crash
    assert _click(app, picks[1]).startswith("**refused:**")
    app.gui_mode.value = "boundary"
    assert s.finish_curve() == 0
    # edit mode: a click on the curve picks an edit point, a drag of its handle pulls it
    app.gui_mode.value = "edit"
    c = s.curves[0].curve
    e = len(c) // 2
    x = s.mesh.xyz(c.points[e])[0]
    assert "edit point" in _click(app, x)
    assert app.selected == 0 and app.edit_point is not None
    app._edit_drag(
        _drag_end(x + 0.01 * s.mesh.bbox_diagonal * s.mesh.face_normals[c.points.face[e]])
    )
    assert "edited" in app.messages[-1]
    assert s.curves[0].curve is not c
    assert "view mode" not in app.messages[-1]
    app.gui_mode.value = "view"
    assert "view mode" in _click(app, x)
    app.gui_mode.value = "boundary"


def test_control_vertex_drag(app):
    s = app.session
    app.selected = 0
    app._on_curve_action("space")
    assert "space curve with 8 control vertices" in app.messages[-1]
    sp = s.curves[0].space
    old = s.curves[0].curve
    app._control_drag(3)(_drag_end(sp.control_points[3] + [0.0, 0.02, 0.0]))
    assert s.curves[0].curve is not old and s.curves[0].space is not sp
    app._control_drag(3)(SimpleNamespace(phase="move", target=None))  # only drag ends edit


def test_smooth_step_delete_undo_buttons(app):
    s = app.session
    app.selected = 0
    app._on_curve_action("smooth")
    assert "smoothed" in app.messages[-1]
    app._on_curve_action("step")
    assert "one snake step" in app.messages[-1]
    n = len(s.curves)
    app._on_delete()
    assert len(s.curves) == n - 1 and "deleted" in app.messages[-1]
    assert s.undo() and len(s.curves) == n


def test_colour_controls_and_refusals(app):
    s = app.session
    app.gui_color.value = True
    app._on_color()
    assert s.color.enabled and s.color.field == "luminance"
    app.gui_color.value = False
    app._on_color()
    assert not s.color.enabled
    app.gui_layout_path.value = "../elsewhere.json"
    app._on_save()
    assert "outside the allowed folder" in app.messages[-1]


def test_region_colouring_and_status(app):
    app._show_status()
    st = app.session.status()
    assert not st.complete and len(st.regions) == 1  # one open curve: one region, no patch
    assert st.regions[0].reason in app.gui_status.content
    app.gui_regions.value = True
    app.redraw(mesh=True)
    assert len(app._nodes["/mesh"]) == len(st.regions)  # one coloured mesh per region
    app.gui_regions.value = False
    app.redraw(mesh=True)
    assert len(app._nodes["/mesh"]) == 1


def test_spring_levels_run_pause_continue(app):
    from tests.ui.helpers import SPOT_LAYOUT

    s = app.session
    s.load_layout(SPOT_LAYOUT)
    app.gui_patch.value = 4
    app.gui_level.value = 2
    app._on_pause()  # paused before the run: the run waits at level 0
    assert "paused" in app.messages[-1]
    app._on_run_levels()
    app._levels_thread.join(timeout=0.5)
    assert app._levels_thread.is_alive() and app.preview_level == -1
    app._on_pause()
    assert "continue" in app.messages[-1]
    app._levels_thread.join(timeout=120)
    assert not app._levels_thread.is_alive()
    assert app.preview_level == 2
    assert "spring mesh level 2" in app.messages[-1]
    app._on_fit()
    assert "8 x 8 controls" in app.gui_fitinfo.content
    assert app.gui_image.image.shape[2] == 3


def test_share_tunnel_is_refused(app):
    # the handler of a client's ShareUrlRequest calls server.request_share_url()
    assert app.server.request_share_url() is None
    assert "sharing through a public tunnel is turned off" in app.messages[-1]


def test_a_finished_curve_is_selected(app):
    s = app.session
    app.gui_mode.value = "boundary"
    picks = side_picks(s.mesh)[1]
    for x in picks[:3]:
        _click(app, x)
    app._on_finish()
    i = len(s.curves) - 1
    assert app.selected == i and app.messages[-1] == f"curve {i} finished and selected"
    app._on_curve_action("smooth")  # the edit buttons act on it at once
    assert app.messages[-1].startswith(f"curve {i} smoothed")
    app.selected = None


def test_status_is_concise(app):
    from meshfit.ui.app import _status_text
    from meshfit.ui.network import NetworkStatus, RegionStatus

    def region(k: int, reason: str = "") -> RegionStatus:
        return RegionStatus(k, not reason, reason, (), np.zeros(0, np.int64), 1.0, 1.0, 1.0)

    ok = NetworkStatus([region(k) for k in range(40)])
    assert _status_text(ok) == "**40 of 40 regions are four-sided patches**"
    bad = NetworkStatus([region(k, "not a disk" if k % 4 == 0 else "") for k in range(40)])
    lines = _status_text(bad).splitlines()
    assert lines[0] == "**30 of 40 regions are four-sided patches**"
    assert lines[2:10] == [f"- region {k}: **not a disk**" for k in range(0, 32, 4)]
    assert lines[10] == "- and 2 more regions with a problem" and len(lines) == 11


def test_the_first_click_of_a_curve_shows(app):
    s = app.session
    app.gui_mode.value = "feature"
    assert "started" in _click(app, side_picks(s.mesh)[2][1])
    (dots,) = [h for h in app._nodes["/curves"] if h.name == "/curves/picks"]
    assert dots.points.shape == (1, 3)  # one dot before there is any line
    s.cancel_curve()
    app.redraw()
    assert not [h for h in app._nodes["/curves"] if h.name == "/curves/picks"]
    app.gui_mode.value = "boundary"
