"""The app's controller on spot: painting by clicks, snapping, editing, undo/redo, autosave,
layout status, layout files and previews."""

from __future__ import annotations

import base64
import json

import numpy as np
import pytest

from meshfit import tol
from meshfit.curves import check_sampling, curve_length
from meshfit.errors import InputError, LayoutError
from meshfit.layout import check_layout_topology, load_layout
from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints
from meshfit.ui.picking import pick_point
from meshfit.ui.state import SESSION_VERSION, Session, _sp_from_json
from tests.conftest import analytic_mesh, real_mesh
from tests.fuzz import peak_within
from tests.ui.helpers import SPOT_LAYOUT, click_ray, paint_quad, side_picks


@pytest.fixture(scope="module")
def spot():
    return real_mesh("spot")


@pytest.fixture(scope="module")
def painted(spot):
    """A session with one patch's four sides painted by clicks (not modified by tests)."""
    s = Session(spot)
    paint_quad(s)
    return s


def _copy(session: Session, tmp_path=None) -> Session:
    s = Session(session.mesh, autosave=None if tmp_path is None else tmp_path / "auto.json")
    s.state = session.state
    return s


# ------------------------------------------------------------------------------ picking
def test_pick_point_hits_the_clicked_point(spot):
    x = spot.vertices[123]
    hit = pick_point(spot, *click_ray(spot, x))
    assert hit is not None and len(hit) == 1
    np.testing.assert_allclose(spot.xyz(hit)[0], x, atol=1e-9 * spot.bbox_diagonal)


def test_pick_point_misses_and_bad_rays(spot):
    far = spot.bbox[1] + spot.bbox_diagonal
    assert pick_point(spot, far, far - spot.bbox[0]) is None  # pointing away from the mesh
    with pytest.raises(InputError, match="bad click ray"):
        pick_point(spot, [0, 0, 0], [0, 0, 0])
    with pytest.raises(InputError, match="3-d origin"):
        pick_point(spot, [0, 0], [1, 0, 0])


# ------------------------------------------------------------------------------ painting
def test_paint_closed_quad_by_clicks(painted, spot):
    s = painted
    assert len(s.curves) == 4 and len(s.corners) == 4
    assert s.state.stroke is None
    ends = [pc.ends for pc in s.curves]
    assert ends == [(0, 1), (1, 2), (2, 3), (3, 0)]  # each side starts where the last ended
    for pc in s.curves:
        assert pc.kind == "boundary"
        assert check_sampling(spot, pc.curve).size == 0
        xyz = spot.xyz(pc.curve.points)
        cxyz = spot.xyz(s.corners)
        np.testing.assert_allclose(xyz[0], cxyz[pc.ends[0]], atol=1e-12)
        np.testing.assert_allclose(xyz[-1], cxyz[pc.ends[1]], atol=1e-12)
    st = s.status()
    # a closed quad on a sphere-like mesh: inside and outside are both four-sided disks
    assert st.error == "" and len(st.regions) == 2 and st.complete
    assert all(len(r.sides) == 4 for r in st.regions)
    assert sorted(len(r.faces) for r in st.regions)[0] > 0
    layout = s.layout()
    assert layout.n_patches == 2
    check_layout_topology(spot, layout)


def test_click_that_misses_changes_nothing(spot):
    s = Session(spot)
    far = spot.bbox[1] + spot.bbox_diagonal
    assert s.click(far, far - spot.bbox[0]) == "missed"
    assert not s.can_undo and s.state.stroke is None


def test_corner_snapping_and_curve_split(painted, spot):
    s = _copy(painted)
    r = tol.length(spot, tol.UI_SNAP_RADIUS, scale="bbox_diagonal")
    corner = spot.xyz(s.corners)[2]
    # a pick a little away from corner 2 starts at corner 2
    near = spot.closest_points((corner + np.array([0.3 * r, 0.0, 0.0]))[None]).points
    assert s.add_pick(near) == "started"
    assert s.state.stroke.start_corner == 2 and len(s.corners) == 4
    s.cancel_curve()
    # a pick on the middle of curve 0 splits it there: a new corner, one more curve
    c0 = s.curves[0].curve
    mid = c0.points[len(c0) // 2]
    n0 = len(c0)
    assert s.add_pick(mid) == "started"
    assert len(s.corners) == 5 and len(s.curves) == 5
    assert s.curves[0].ends == (0, 4) and s.curves[4].ends == (4, 1)
    assert len(s.curves[0].curve) + len(s.curves[4].curve) == n0 + 1
    assert s.state.stroke.start_corner == 4


def test_stroke_cannot_close_on_itself(spot):
    s = Session(spot)
    picks = side_picks(spot)[0]
    s.click(*click_ray(spot, picks[0]))
    s.click(*click_ray(spot, picks[2]))
    with pytest.raises(InputError, match="cannot end at the corner it starts"):
        s.click(*click_ray(spot, picks[0]))
    with pytest.raises(InputError, match="being painted"):
        s.add_pick(SurfacePoints.at_vertices(spot.faces, [5]), kind="feature")


def test_feature_curve_snaps_to_boundary_curves(painted, spot):
    s = _copy(painted)
    a = s.curves[0].curve
    b = s.curves[2].curve
    pa = a.points[len(a) // 2]
    pb = b.points[len(b) // 2]
    assert s.add_pick(pa, kind="feature") == "started"
    assert s.add_pick(pb, kind="feature") == "finished"
    feat = s.curves[-1]
    assert feat.ends is None and feat.kind == "feature"
    np.testing.assert_allclose(spot.xyz(feat.curve.points[0]), spot.xyz(pa))
    np.testing.assert_allclose(spot.xyz(feat.curve.points[len(feat.curve) - 1]), spot.xyz(pb))
    assert len(s.corners) == 4  # features make no corners
    assert s.status().complete  # features do not change the regions
    layout = s.layout()
    assert sum(len(f) for f in layout.features) == 1


def test_delete_curve_prunes_corners(painted):
    s = _copy(painted)
    s.delete_curve(1)
    assert len(s.curves) == 3 and len(s.corners) == 4  # every corner still used
    s.delete_curve(0)
    assert len(s.corners) == 3  # corner 1 was only used by curves 0 and 1
    ends = {c for pc in s.curves for c in pc.ends}
    assert ends == {0, 1, 2}
    with pytest.raises(InputError, match="no curve 7"):
        s.delete_curve(7)


# ------------------------------------------------------------------------------ undo / redo
def test_undo_redo_every_edit(painted):
    s = _copy(painted)
    before = s.state
    s.smooth_curve(0, max_iter=20)
    s.delete_curve(3)
    assert len(s.curves) == 3
    assert s.undo() and len(s.curves) == 4
    assert s.undo() and s.state is before
    assert s.redo() and s.redo() and len(s.curves) == 3
    assert not s.redo()
    s.undo()
    s.delete_curve(0)  # a new edit clears the redo stack
    assert not s.can_redo


def test_undo_back_to_empty(spot):
    s = Session(spot)
    said = paint_quad(s)
    steps = sum(w != "missed" for w in said)
    for _ in range(steps):
        assert s.undo()
    assert not s.undo()
    assert len(s.curves) == 0 and len(s.corners) == 0 and s.state.stroke is None


# ------------------------------------------------------------------------------ editing
def test_smooth_curve_keeps_ends_and_shortens(painted, spot):
    s = _copy(painted)
    c = s.curves[1].curve
    it = s.smooth_curve(1, w_fair=1.0, max_iter=200)
    d = s.curves[1].curve
    assert it > 0 and len(d) == len(c)
    np.testing.assert_array_equal(d.points.face[[0, -1]], c.points.face[[0, -1]])
    assert curve_length(spot, d) <= curve_length(spot, c) * (1 + 1e-9)
    assert s.status().complete


def test_snake_step_moves_a_little(painted):
    s = _copy(painted)
    c = s.curves[1].curve
    move = s.snake_step(1)
    assert move >= 0.0
    assert s.curves[1].curve is not c and s.can_undo


def test_edit_curve_moves_only_the_section(painted, spot):
    s = _copy(painted)
    c = s.curves[1].curve
    n = len(c)
    e, sec = n // 2, 6
    x = spot.xyz(c.points)
    side = np.cross(spot.face_normals[c.points.face[e]], x[e + 1] - x[e - 1])
    target = x[e] + 0.02 * spot.bbox_diagonal * side / np.linalg.norm(side)
    s.edit_curve(1, edit_index=e, section=sec, target=target)
    d = s.curves[1].curve
    y = spot.xyz(d.points)
    assert np.linalg.norm(y[e] - target) < np.linalg.norm(x[e] - target)
    outside = np.r_[0 : e - sec, e + sec + 1 : n]
    np.testing.assert_array_equal(d.points.face[outside], c.points.face[outside])
    np.testing.assert_array_equal(d.points.bary[outside], c.points.bary[outside])
    hit = s.nearest_sample(y[e])
    assert hit == (1, e)


def test_space_curve_control_point_drag(painted, spot):
    s = _copy(painted)
    sp = s.fit_space_curve(1, n_control=6)
    assert s.curves[1].space is sp
    c = s.curves[1].curve
    s.move_control_point(1, 2, sp.control_points[2] + [0.0, 0.0, 0.02 * spot.bbox_diagonal])
    d = s.curves[1].curve
    assert s.curves[1].space is not sp
    np.testing.assert_array_equal(d.points.face[[0, -1]], c.points.face[[0, -1]])
    assert check_sampling(spot, d).size == 0
    assert not np.array_equal(spot.xyz(d.points)[len(d) // 2], spot.xyz(c.points)[len(c) // 2])
    s.smooth_curve(1, max_iter=5)  # a snake edit drops the stale space curve
    with pytest.raises(InputError, match="no space curve"):
        s.move_control_point(1, 0, [0, 0, 0])


def test_color_attraction_changes_the_relaxation(painted, spot):
    plain = _copy(painted)
    plain.smooth_curve(1, max_iter=30)
    pulled = _copy(painted)
    pulled.set_color_attraction(enabled=True, weight=2.0, field="luminance")
    pulled.smooth_curve(1, max_iter=30)
    a, b = plain.curves[1].curve, pulled.curves[1].curve
    assert not np.array_equal(spot.xyz(a.points), spot.xyz(b.points))
    with pytest.raises(InputError):
        pulled.set_color_attraction(enabled=True, weight=-1.0)


def test_color_attraction_needs_colours():
    s = Session(analytic_mesh("icosphere"))
    with pytest.raises(InputError):
        s.set_color_attraction(enabled=True, field="red")
    s.set_color_attraction(enabled=True, field="mean_curvature")  # any scalar field works
    assert s.color.enabled


# ------------------------------------------------------------------------------ status
def test_status_of_an_open_network_names_the_problem(painted):
    s = _copy(painted)
    s.delete_curve(3)
    st = s.status()
    assert not st.complete
    assert st.error == "" and len(st.regions) == 1
    assert "boundary loop" in st.regions[0].reason or "side" in st.regions[0].reason
    with pytest.raises(LayoutError, match="do not make a layout yet"):
        s.layout()
    assert Session(s.mesh).status().error == "no boundary curves painted yet"


def test_status_reports_crossing_curves(painted, spot):
    s = _copy(painted)
    # a curve from the middle of side 0 across to the middle of side 2 ... and beyond it
    a, b = s.curves[0].curve, s.curves[2].curve
    xa = spot.xyz(a.points)[len(a) // 2]
    xb = spot.xyz(b.points)[len(b) // 2]
    s.add_pick(spot.closest_points((xa + 0.3 * (xa - xb))[None]).points)
    s.add_pick(spot.closest_points((xb + 0.3 * (xb - xa))[None]).points)
    s.finish_curve()
    st = s.status()
    assert not st.complete
    assert "cross" in st.error or any(not r.valid for r in st.regions)


def _test_layout_status(name: str):
    """The status of a test layout (examples/layouts) loaded for editing, and its extracted
    patches."""
    from meshfit.layout import extract_patches

    from ..conftest import ROOT

    mesh = real_mesh(name)
    layout = load_layout(ROOT / "examples" / "layouts" / f"{name}.json", mesh)
    s = Session(mesh)
    s.set_layout(layout)
    st = s.status()
    assert st.complete
    return st, extract_patches(mesh, layout)


def test_status_measures_how_each_region_bulges():
    # the nefertiti test layout: the region over neck, shoulders and base balloons out of its
    # sides (as Patch.bulge measures the extracted patch), every other region is flat-ish
    from meshfit.ui.app import _region_text

    st, patches = _test_layout_status("nefertiti")
    bulges = sorted(r.bulge for r in st.regions)
    np.testing.assert_allclose(bulges, sorted(p.bulge for p in patches), rtol=1e-9)
    bust = max(st.regions, key=lambda r: r.bulge)
    assert bust.bulge > 10 and bulges[-2] < 1.5
    assert "bulging" in _region_text(bust) and st.as_dict()["regions"][0]["bulge"] > 0
    assert _region_text(min(st.regions, key=lambda r: r.bulge)) == "patch"


# ------------------------------------------------------------------------------ files
def test_autosave_every_change_and_restore(painted, tmp_path, spot):
    path = tmp_path / "auto.json"
    s = Session(spot, autosave=path)
    x = side_picks(spot)[0]
    s.click(*click_ray(spot, x[0]))
    assert s.flush()
    doc = json.loads(path.read_text())
    assert doc["meshfit_ui_session"] == SESSION_VERSION and doc["stroke"] is not None
    s.state = painted.state
    s.smooth_curve(2, max_iter=10)  # a change writes the file
    assert s.flush() and not s.save_errors
    t = Session(spot)
    t.restore(path)
    assert len(t.curves) == 4
    for a, b in zip(s.curves, t.curves, strict=True):
        np.testing.assert_array_equal(a.curve.points.face, b.curve.points.face)
        np.testing.assert_array_equal(a.curve.points.bary, b.curve.points.bary)
        assert a.ends == b.ends
    assert t.status().complete


def test_background_and_synchronous_autosave_agree(painted, tmp_path, spot):
    a = Session(spot, autosave=tmp_path / "a.json")
    b = Session(spot, autosave=tmp_path / "b.json", background_save=False)
    for s in (a, b):
        s.state = painted.state
        s.snake_step(0)  # the same deterministic edit from the same state
        s.delete_curve(3)
        s.undo()
    assert a.flush()
    text = (tmp_path / "a.json").read_text()
    assert text == (tmp_path / "b.json").read_text() == a.to_json()
    assert json.loads(text)["curves"][3]["ends"] == [3, 0]


def _as_version_1(doc: dict) -> dict:
    """A session document rewritten in the version-1 encoding (decimal lists)."""

    def lists(d: dict) -> dict:
        sp = _sp_from_json(d, "test")
        return {k: v for k, v in d.items() if k != "n"} | {
            "face": sp.face.tolist(),
            "bary": sp.bary.tolist(),
        }

    out = dict(doc, meshfit_ui_session=1, corners=lists(doc["corners"]))
    out["curves"] = [lists(c) for c in doc["curves"]]
    if doc["stroke"] is not None:
        st = doc["stroke"]
        out["stroke"] = dict(st, picks=lists(st["picks"]), pieces=[lists(q) for q in st["pieces"]])
    return out


def test_session_file_keeps_points_exactly_and_reads_version_1(painted, tmp_path, spot):
    s = _copy(painted, tmp_path)
    s.smooth_curve(1, max_iter=5)  # barycentrics with every digit used
    s.add_pick(SurfacePoints.at_vertices(spot.faces, [7]))  # a stroke too
    assert s.flush() and not s.save_errors
    doc = json.loads(s.autosave_path.read_text())
    assert isinstance(doc["curves"][0]["face"], str)  # base64, not decimal lists
    old = tmp_path / "v1.json"
    old.write_text(json.dumps(_as_version_1(doc)))
    for path in (s.autosave_path, old):
        t = Session(spot)
        t.restore(path)
        assert len(t.curves) == len(s.curves)
        for a, b in zip(s.curves, t.curves, strict=True):
            np.testing.assert_array_equal(a.curve.points.face, b.curve.points.face)
            np.testing.assert_array_equal(a.curve.points.bary, b.curve.points.bary)
            assert a.ends == b.ends and a.kind == b.kind
        np.testing.assert_array_equal(t.corners.bary, s.corners.bary)
        np.testing.assert_array_equal(t.state.stroke.picks.face, s.state.stroke.picks.face)
        assert t.state.stroke.start_corner == s.state.stroke.start_corner


@pytest.mark.parametrize(
    "change, match",
    [
        ({"face": "not base64!"}, "bad face points"),
        ({"n": 5}, "file says 5"),
        ({"bary": base64.b64encode(b"\0" * 20).decode()}, "whole number"),
        ({"bary": base64.b64encode(b"\0" * 48).decode()}, "barycentric values"),
    ],
)
def test_restore_refuses_bad_point_arrays(painted, tmp_path, spot, change, match):
    s = _copy(painted, tmp_path)
    doc = json.loads(s.to_json())
    doc["curves"][0] |= change
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=match):
        Session(spot).restore(bad)


def test_restore_refuses_bad_files(tmp_path, spot):
    s = Session(spot)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="not a readable session"):
        s.restore(bad)
    bad.write_text(json.dumps({"meshfit_ui_session": 99}))
    with pytest.raises(InputError, match="version"):
        s.restore(bad)
    other = Session(real_mesh("igea").__class__(spot.vertices * 2, spot.faces))
    other.autosave_path = tmp_path / "other.json"
    other.add_pick(SurfacePoints.at_vertices(spot.faces, [3]))
    other.flush()
    with pytest.raises(InputError, match="another mesh"):
        s.restore(tmp_path / "other.json")


def test_save_and_load_layout(painted, tmp_path, spot):
    path = painted.save_layout(tmp_path / "quad.json")
    layout = load_layout(path, spot)
    assert layout == painted.layout()
    s = Session(spot)
    s.load_layout(path)
    assert len(s.curves) == 4 and s.status().complete
    again = s.layout()
    np.testing.assert_array_equal(again.corners.face, layout.corners.face)
    np.testing.assert_array_equal(again.curve_ends, layout.curve_ends)
    assert sorted(map(sorted, again.patch_curves.tolist())) == sorted(
        map(sorted, layout.patch_curves.tolist())
    )


def test_example_layout_and_previews(spot):
    s = Session(spot)
    s.load_layout(SPOT_LAYOUT)
    st = s.status()
    assert st.complete and len(st.regions) == 24
    grid0 = s.spring_preview(4, level=0)
    grid1 = s.spring_preview(4, level=1)
    assert grid1.shape[0] > grid0.shape[0] and grid1.shape[1] > grid0.shape[1]
    coarse = s.fit_patch(4, controls=(4, 4))
    fine = s.fit_patch(4, controls=(8, 8))
    assert coarse.surface.control_points.shape == (4, 4, 3)
    assert fine.surface.control_points.shape[:2] == (min(8, grid1.shape[0]), min(8, grid1.shape[1]))
    assert fine.rms <= coarse.rms + 1e-12
    assert fine.error.shape == grid1.shape
    img = s.displacement_image(4)
    assert img.dtype == np.uint8 and img.shape == (*grid1.shape, 3)
    with pytest.raises(InputError, match="no patch 99"):
        s.spring_preview(99)


def test_auto_layout(spot):
    s = Session(spot)
    s.auto_layout()
    assert s.status().complete and s.can_undo
    s.undo()
    assert len(s.curves) == 0


def test_auto_layout_of_an_open_mesh_of_genus_one():
    from ..shapes import tori

    mesh = tori(1, edge=0.15)
    keep = mesh.vertices[mesh.faces].mean(axis=1)[:, 2] < 0.2  # the top cut open
    used, inverse = np.unique(mesh.faces[keep], return_inverse=True)
    s = Session(Mesh(mesh.vertices[used], inverse.reshape(-1, 3), name="open_torus"))
    s.auto_layout()
    assert s.status().complete


def test_actions_need_a_mesh():
    s = Session()
    with pytest.raises(InputError, match="no mesh is open"):
        s.click([0, 0, 1], [0, 0, -1])


def test_status_measures_how_each_region_tapers():
    # spot's test layout: the four head regions are near-triangular (as Patch.taper measures
    # the extracted patches)
    from meshfit.layout.patch import TAPERED
    from meshfit.ui.app import _region_text

    st, patches = _test_layout_status("spot")
    tapers = sorted(r.taper for r in st.regions)
    np.testing.assert_allclose(tapers, sorted(p.taper for p in patches), rtol=1e-9)
    assert sum(t > TAPERED for t in tapers) == 4
    worst = max(st.regions, key=lambda r: r.taper)
    assert "tapered" in _region_text(worst) and st.as_dict()["regions"][0]["taper"] >= 1.0
    assert _region_text(min(st.regions, key=lambda r: r.taper)) == "patch"


def _mutations(doc, draw):
    """A copy of the JSON ``doc`` with one value somewhere replaced by another type, one key
    dropped, or a list cut."""
    import copy

    from hypothesis import strategies as st

    out = copy.deepcopy(doc)
    node = out
    for _ in range(draw(st.integers(0, 4))):
        kids = list(node.items()) if isinstance(node, dict) else list(enumerate(node))
        kids = [(k, v) for k, v in kids if isinstance(v, (dict, list)) and v]
        if not kids:
            break
        node = draw(st.sampled_from(kids))[1]
    keys = list(node) if isinstance(node, dict) else list(range(len(node)))
    if not keys:
        return out
    key = draw(st.sampled_from(keys))
    op = draw(st.sampled_from(["type", "drop", "cut"]))
    if op == "type":
        node[key] = draw(st.sampled_from([None, True, -1, 2**40, 0.5, "x", [], {}, [[1]]]))
    elif op == "drop" and isinstance(node, dict):
        del node[key]
    elif isinstance(node[key], (list, str)):
        node[key] = node[key][: len(node[key]) // 2]
    return out


def test_damaged_session_files_raise_only_input_errors(painted, spot, tmp_path):
    """Random damage to a valid session file (a key dropped, a value of another type, a
    list cut short, anywhere in it): it restores or raises InputError, nothing else."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    doc = json.loads(_copy(painted).to_json())
    bad = tmp_path / "bad.json"

    @settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck))
    @given(data=st.data())
    def run(data):
        bad.write_text(json.dumps(_mutations(doc, data.draw)))
        with peak_within(bad.stat().st_size):
            try:
                Session(spot).restore(bad)
            except InputError:
                pass

    run()


def test_random_bytes_as_a_session_file_raise_only_input_errors(spot, tmp_path):
    from hypothesis import given, settings
    from hypothesis import strategies as st

    bad = tmp_path / "bad.json"

    @settings(max_examples=100, deadline=None)
    @given(raw=st.binary(max_size=4096))
    def run(raw):
        bad.write_bytes(raw)
        with peak_within(len(raw)), pytest.raises(InputError):
            Session(spot).restore(bad)

    run()
