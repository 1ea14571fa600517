"""The web app in a real browser (Debian chromium, headless, Playwright): painting by clicks,
editing, previews, layout files, fit export, refused uploads and paths.

The tests share one app and one page and run in file order (each builds on the state the
previous one left). Server-side state is read from the app object in this process.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests.conftest import mesh_path
from tests.ui.browser import (
    canvas_pixels,
    changed,
    choose,
    click_canvas,
    press,
    screen_of,
    settle,
    type_into,
)
from tests.ui.conftest import wait_for

pytestmark = pytest.mark.browser

#: screen points on spot's back (the app frames the mesh from +z in a 1000 x 700 view)
QUAD = [(465, 330), (535, 330), (535, 430), (465, 430)]


# ------------------------------------------------------------------------------ tests
def test_paint_closed_curves_by_clicks(page, app):
    before = canvas_pixels(page)
    s = app.session
    for k in range(4):
        a, b = QUAD[k], QUAD[(k + 1) % 4]
        assert "started" in click_canvas(page, app, a)
        said = click_canvas(page, app, b)
        if k < 3:
            assert "added" in said
            press(page, app, "Finish curve", until=lambda k=k: len(s.curves) == k + 1)
        else:
            assert "finished" in said  # the last click lands on the first corner
    assert len(s.curves) == 4 and len(s.corners) == 4
    press(page, app, "Check layout")
    assert "2 of 2 regions are four-sided patches" in app.gui_status.content
    settle(page)
    assert changed(before, canvas_pixels(page)) > 1e-3  # the curves are drawn


def test_edit_point_pull_and_drag_update_the_view(page, app):
    s = app.session
    choose(page, app.gui_mode, "Click mode", "edit")
    c0 = s.curves[0].curve
    mid = screen_of(app, s.mesh.xyz(c0.points[len(c0) // 2])[0])
    said = click_canvas(page, app, mid)
    assert "edit point" in said and app.selected is not None
    i = app.selected
    old = s.curves[i].curve
    settle(page)
    before = canvas_pixels(page)
    said = click_canvas(page, app, (mid[0], mid[1] - 30))  # pull it up the screen
    assert "edited" in said, said
    assert s.curves[i].curve is not old
    settle(page)
    assert changed(before, canvas_pixels(page)) > 1e-4
    press(page, app, "Undo", until=lambda: s.curves[i].curve is old)
    # drag the edit point's handle (the up arrow of its transform gizmo) up the screen
    settle(page)
    before = canvas_pixels(page)
    e = app.edit_point
    x = s.mesh.xyz(old.points[e])[0]
    handle = screen_of(app, x + 0.75 * 0.05 * s.mesh.bbox_diagonal * np.array([0.0, 1.0, 0.0]))
    n = len(app.messages)
    page.mouse.move(*handle)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(handle[0], handle[1] - 3 * k)
        time.sleep(0.03)
    page.mouse.up()
    wait_for(lambda: len(app.messages) > n, what="the edit from the drag")
    assert f"edited at point {e}" in app.messages[-1], app.messages[-1]
    assert s.curves[i].curve is not old
    settle(page)
    assert changed(before, canvas_pixels(page)) > 1e-4
    press(page, app, "Undo", until=lambda: s.curves[i].curve is old)
    choose(page, app.gui_mode, "Click mode", "boundary")


def test_save_and_reload_layout(page, app, workdir):
    s = app.session
    type_into(page, app.gui_layout_path, "Layout file", "quad.json")
    said = press(page, app, "Save layout")
    assert "layout saved" in said, said
    assert (workdir / "quad.json").is_file()
    press(page, app, "Undo", until=lambda: len(s.curves) == 3)
    press(page, app, "Load layout", until=lambda: len(s.curves) == 4)
    assert s.status().complete


def test_previews_update_live(page, app):
    s = app.session
    said = press(page, app, "Spring mesh")
    assert "spring mesh level 0" in said, said
    said = press(page, app, "Fit B-spline")
    assert "8 x 8 controls" in said, said
    settle(page)
    before = canvas_pixels(page)
    type_into(page, app.gui_cu, "Controls u", "4")
    wait_for(lambda: "4 x 8 controls" in app.messages[-1], what="the re-fit at 4 x 8")
    fit = s.fit_patch(0, controls=(4, 8))
    assert fit.surface.control_points.shape[:2] == (4, 8)
    settle(page)
    assert changed(before, canvas_pixels(page)) > 1e-4


def test_run_fit_exports(page, app, workdir):
    type_into(page, app.gui_export, "Export folder", "fit")
    # with no fit yet, Export fits first: on a first run that compiles every fit kernel
    said = press(page, app, "Export", timeout=600.0)
    assert "exported" in said, said
    assert (workdir / "fit" / "layout.json").is_file()
    assert any((workdir / "fit").rglob("*.obj")) or any((workdir / "fit").rglob("*.usd*"))


def test_refused_uploads(page, app):
    upload = page.locator("input[type=file]").first
    app.policy.max_upload = 10_000
    try:
        n = len(app.messages)
        upload.set_input_files(
            files=[
                {
                    "name": "spot.ply",
                    "mimeType": "application/octet-stream",
                    "buffer": mesh_path("spot").read_bytes(),
                }
            ]
        )
        wait_for(lambda: len(app.messages) > n, what="the upload reply")
        assert "the limit is 10,000 bytes" in app.messages[-1]
    finally:
        app.policy.max_upload = 200 * 1024 * 1024
    n = len(app.messages)
    upload.set_input_files(
        files=[
            {
                "name": "broken.ply",
                "mimeType": "application/octet-stream",
                "buffer": b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
            }
        ]
    )
    wait_for(lambda: len(app.messages) > n, what="the upload reply")
    assert app.messages[-1].startswith("**refused:**")
    assert app.session.mesh.name == "spot.ply"  # still the same mesh


def test_paths_outside_the_workdir_are_refused(page, app):
    type_into(page, app.gui_layout_path, "Layout file", "../outside.json")
    said = press(page, app, "Save layout")
    assert "outside the allowed folder" in said, said
    type_into(page, app.gui_layout_path, "Layout file", "/etc/passwd")
    said = press(page, app, "Load layout")
    assert "only .json" in said, said


def test_upload_opens_a_mesh(page, app):
    n = len(app.messages)
    page.locator("input[type=file]").first.set_input_files(
        files=[
            {
                "name": "spot-copy.ply",
                "mimeType": "application/octet-stream",
                "buffer": mesh_path("spot").read_bytes(),
            }
        ]
    )
    wait_for(lambda: len(app.messages) > n, what="the upload reply")
    assert app.messages[-1].startswith("opened spot-copy.ply: 2930 vertices")
    assert app.session.mesh.name == "spot-copy.ply" and len(app.session.curves) == 0
    assert not app.session.can_undo  # a new mesh starts a new history
