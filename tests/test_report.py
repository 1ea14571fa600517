"""The fit report: renders of every stage and from fixed viewpoints, patch labels, the 3D
view's model and its drawing in a real browser, values beyond bounds, displacement images,
tables.

The browser test opens the page from ``file://`` in Debian's chromium (Playwright, the
network off) and saves screenshots in ``$MESHFIT_TEST_ARTIFACTS/report`` (else
``<pytest's temporary folder>/artifacts/report``).
"""

from __future__ import annotations

import base64
import copy
import os
import re
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import png
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from meshfit.errors import RenderError
from meshfit.pipeline import FitOptions
from meshfit.render import PALETTE
from meshfit.report import VIEW_NAMES, blender_renders, report_images, write_html
from meshfit.report_bounds import OPPOSED_NORMALS_DEG, beyond_bounds
from meshfit.report_view import STATIC_FILES, deviation_glb, fixed_views, near_max
from tests.fitting import run_fit

from .conftest import ROOT, real_mesh


def _read(path):
    w, h, rows, _ = png.Reader(bytes=path.read_bytes()).asRGB8()
    return np.vstack([np.asarray(r, np.uint8) for r in rows]).reshape(h, w, 3)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    opts = FitOptions(controls=(6, 6), spring_level=1, formats=(), image_size=160)
    summary = run_fit(
        real_mesh("spot"), out, layout=ROOT / "examples/layouts/spot.json", options=opts
    )
    return out, summary


def _page(summary):
    return summary["report_page"]


def test_report_lists_every_image(report):
    out, summary = report
    text = (out / "report.html").read_text()
    srcs = re.findall(r"<img src='([^']+)'", text)
    assert srcs == report_images(summary["patches_total"])
    for s in srcs:
        assert (out / s).is_file()
    # the 3D view's scripts, all beside the page (nothing from the network)
    scripts = re.findall(r"<script src='([^']+)'", text)
    assert scripts == ["report/three.min.js", "report/model.js", "report/viewer.js"]
    assert all((out / f).is_file() for f in scripts)
    assert "http" not in "".join(scripts)
    # tables of errors, timings and patches
    for word in ("spline only", "displaced", "springs", "fit parametric rms"):
        assert word in text
    assert summary["outputs"]["report"] == ["report.html"]
    assert not summary["stages"]["report"]["cached"]


def test_static_assets_ship_with_the_package(report):
    out, _ = report
    static = resources.files("meshfit") / "report_static"
    for name in STATIC_FILES:
        data = (static / name).read_bytes()
        assert data and (out / "report" / name).read_bytes() == data
    bundle = (static / "three.min.js").read_text()
    # a classic script (a page from file:// cannot import modules) setting one global
    assert bundle.startswith("var MeshfitThree=")
    assert not re.search(r"^\s*(import|export)\s", bundle, re.M)
    assert "MIT" in (static / "three.LICENSE.txt").read_text()


def test_model_renders_show_the_model(report):
    out, _ = report
    layout = _read(out / "report/layout_front.png")
    assert layout.shape == (120, 120, 3)  # the fixed viewpoints: half the size, at least 120
    model = (layout != 255).any(axis=2)
    assert 0.1 < model.mean() < 0.9
    # the layout render shows many patch colours, the spline render grey only
    colours = {tuple(c) for c in layout[model].tolist()}
    assert len(colours) > 24
    spline = _read(out / "report/spline.png")
    assert spline.shape == (160, 160, 3)
    px = spline[(spline != 255).any(axis=2)].astype(int)
    assert (np.ptp(px, axis=1) <= 1).all()
    # the spring checkerboard alternates light and dark squares of each patch colour
    springs = _read(out / "report/springs.png")
    assert len({tuple(c) for c in springs.reshape(-1, 3).tolist()}) > 50
    # both heat maps run from blue (near the input) to red (far), from every viewpoint
    for kind in ("spline", "displaced"):
        for v in VIEW_NAMES:
            heat = _read(out / f"report/error_{kind}_{v}.png").astype(int)
            assert (heat[..., 2] - heat[..., 0] > 100).any(), (kind, v)
            assert (heat[..., 0] - heat[..., 2] > 100).any(), (kind, v)
    # four different viewpoints: no two images of a row alike
    rows = [_read(out / f"report/layout_{v}.png") for v in VIEW_NAMES]
    assert all((a != b).any() for i, a in enumerate(rows) for b in rows[i + 1 :])


def test_fixed_views_go_round_the_model():
    views = fixed_views([1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    assert [v.name for v in views] == list(VIEW_NAMES)
    d = np.array([v.view for v in views])
    assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert (d[:, 1] < 0).all()  # each looks down on the model
    flat = d * [1, 0, 1]
    assert_allclose(flat[0] @ flat[2], -(flat[0] @ flat[0]))  # front and back are opposite
    assert_allclose(flat[0] @ flat[1], 0.0, atol=1e-12)  # a quarter turn apart


def test_patch_numbers_sit_on_their_patches(report):
    out, summary = report
    labels = _page(summary)["labels"]
    assert sorted(labels) == [f"layout_{v}" for v in sorted(VIEW_NAMES)]
    hits = total = 0
    for name, tags in labels.items():
        img = _read(out / f"report/{name}.png").astype(float)
        h, w = img.shape[:2]
        for p, x, y in tags:
            total += 1
            c = img[int(y * h / 100), int(x * w / 100)]
            want = PALETTE[p % len(PALETTE)] * 255
            # flat shading scales the patch's colour: the pixel is parallel to it
            cos = c @ want / (np.linalg.norm(c) * np.linalg.norm(want))
            hits += cos > 0.995
    assert total >= summary["patches_total"]
    assert hits >= 0.9 * total, (hits, total)
    # every patch is numbered from some viewpoint, or named as out of sight
    seen = {p for tags in labels.values() for p, _, _ in tags}
    text = (out / "report.html").read_text()
    hidden = sorted(set(range(summary["patches_total"])) - seen)
    assert len(hidden) < summary["patches_total"] // 4
    if hidden:
        assert f"patches {', '.join(map(str, hidden))}." in text
    # the numbers are printed over the layout images
    assert text.count("class='tag'") == sum(len(t) for t in labels.values())


def test_the_model_is_the_displaced_surface_with_its_deviation(report):
    out, summary = report
    script = (out / "report/model.js").read_text()
    b64 = re.fullmatch(r'window\.MESHFIT_MODEL = "([A-Za-z0-9+/=]+)";\n', script).group(1)
    glb = base64.b64decode(b64)
    scene = trimesh.load(trimesh.util.wrap_as_stream(glb), file_type="glb", process=False)
    n = summary["patches_total"]
    assert sorted(scene.geometry) == sorted(f"patch {p}" for p in range(n))
    diag = summary["mesh"]["bbox_diagonal"]
    dev = []
    for g in scene.geometry.values():
        assert g.visual.kind == "vertex" and g.visual.vertex_colors.shape == (len(g.vertices), 4)
        dev.append(np.asarray(g.vertex_attributes["_DEVIATION"]).reshape(-1))
    # the displaced surface's texels (in float32): each within its distance to the input
    V = np.vstack([g.vertices for g in scene.geometry.values()])
    far = real_mesh("spot").closest_points(V).distance.max()
    assert far <= summary["errors"]["displaced"]["to_input_max"] * diag + 1e-6 * diag
    dev = np.concatenate(dev)
    page = _page(summary)
    # percent of the diagonal; the thinned grids keep the largest value
    assert_allclose(dev.max(), 100 * page["error_max"]["displaced"], rtol=1e-6)
    # the scan's distance to the displaced surface, so at most its Hausdorff distance
    assert 0 < page["error_max"]["displaced"] <= summary["errors"]["displaced"]["hausdorff"]
    assert 0 < page["error_scale"]["displaced"] <= page["error_max"]["displaced"]


def test_the_heat_map_reads_the_errors_own_scan_distances(report):
    """The displaced surface's heat map reuses the errors stage's distance of every scan
    vertex to the displaced surface (no second search): the array kept is the one a
    search over the fit's displaced grids finds."""
    from meshfit import load_fit
    from meshfit.mesh.locate import grid_tree, triangle_distances
    from meshfit.report import _grid_soup

    out, summary = report
    (npz,) = (out / ".meshfit").glob("errors-*.npz")
    with np.load(npz) as z:
        kept = z["input_to_displaced"]
    mesh = real_mesh("spot")
    disp = [p.displaced() for p in load_fit(out, mesh=mesh).patches]
    Vd, Fd, _, _ = _grid_soup(disp)
    tree = grid_tree(Vd, Fd, [d.shape[:2] for d in disp])
    want, _ = triangle_distances(mesh.vertices, Vd, Fd, tree=tree)
    assert kept.shape == (mesh.n_vertices,)
    assert_allclose(kept, want, rtol=0, atol=1e-12 * summary["mesh"]["bbox_diagonal"])


def test_figures_come_from_every_grid_vertex_and_renders_from_fewer(report, tmp_path):
    """The renders draw the grids thinned to the image's pixels; the figures on the page
    are still those of every vertex of the grids, whatever the thinning."""
    import meshfit.report as rep
    from meshfit import load_fit

    out, summary = report
    disp = [p.displaced() for p in load_fit(out, mesh=real_mesh("spot")).patches]
    drawn: list[int] = []
    real = rep.render
    with pytest.MonkeyPatch.context() as m:
        m.setattr(rep, "RENDER_POINTS_PER_PIXEL", 0.05)  # (this fit's grids are small)
        m.setattr(rep, "render", lambda V, F, **k: drawn.append(len(V)) or real(V, F, **k))
        step = rep._render_step(disp, 160 * 160)
        opts = FitOptions(controls=(6, 6), spring_level=1, formats=(), image_size=160)
        again = run_fit(
            real_mesh("spot"), tmp_path, layout=ROOT / "examples/layouts/spot.json", options=opts
        )
    thinned = sum(g.shape[0] * g.shape[1] for g in rep._thinned(disp, step)[0])
    assert step > 1 and thinned in drawn
    assert sum(d.shape[0] * d.shape[1] for d in disp) not in drawn
    for key in ("error_max", "error_scale"):
        assert _page(again)[key] == _page(summary)[key]


@given(
    shape=st.tuples(st.integers(2, 40), st.integers(2, 40)),
    step=st.integers(1, 9),
    seed=st.integers(0, 2**16),
)
@settings(max_examples=60, deadline=None)
def test_thinned_grids_keep_their_sides_and_their_peaks(shape, step, seed):
    from meshfit.report import _thinned

    rng = np.random.default_rng(seed)
    grids = [rng.normal(size=(*shape, 3)), rng.normal(size=(shape[1], shape[0], 3))]
    values = rng.random(2 * shape[0] * shape[1])
    thin, kept = _thinned(grids, step, values)
    base = 0
    for G, T in zip(grids, thin, strict=True):
        for i, j in [(0, 0), (0, -1), (-1, 0), (-1, -1)]:  # its corners, so patches meet
            assert_allclose(T[i, j], G[i, j])
        n, m = T.shape[0] * T.shape[1], G.shape[0] * G.shape[1]
        # every value lies within the pooling of a kept vertex: the peak survives
        assert kept[:n].max() == values[base : base + m].max()
        kept, base = kept[n:], base + m
    assert kept.size == 0


def test_glb_colours_follow_the_deviation():
    u, v = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 7), indexing="ij")
    grid = np.stack([u, v, np.zeros_like(u)], axis=-1)
    dev = 2.0 * u  # 0 to 2 percent across the grid
    scene = trimesh.load(
        trimesh.util.wrap_as_stream(deviation_glb([grid], [dev], vmax=1.0)),
        file_type="glb",
        process=False,
    )
    (g,) = scene.geometry.values()
    assert len(g.vertices) == 63 and len(g.faces) == 2 * 8 * 6
    got = np.asarray(g.vertex_attributes["_DEVIATION"]).reshape(-1)
    assert_allclose(got, 2.0 * g.vertices[:, 0], atol=1e-6)
    red = g.visual.vertex_colors[got >= 1.0]
    blue = g.visual.vertex_colors[got == 0.0]
    assert (red[:, 0] > 150).all() and (red[:, 2] < 10).all()  # beyond vmax: red
    assert (blue[:, 2] > blue[:, 0]).all()
    # thinned to a vertex budget, the boundaries and the peak are kept
    peak = np.zeros((41, 41))
    peak[21, 19] = 5.0
    g41 = np.stack([*np.meshgrid(np.arange(41.0), np.arange(41.0), indexing="ij"),
                    np.zeros((41, 41))], axis=-1)  # fmt: skip
    scene = trimesh.load(
        trimesh.util.wrap_as_stream(deviation_glb([g41], [peak], vmax=1.0, max_vertices=200)),
        file_type="glb",
        process=False,
    )
    (g,) = scene.geometry.values()
    assert len(g.vertices) <= 200 * 1.3
    assert g.vertices[:, 0].max() == 40 and g.vertices[:, 1].max() == 40
    assert np.asarray(g.vertex_attributes["_DEVIATION"]).reshape(-1).max() == 5.0


def test_near_max_takes_the_largest_nearby_value():
    sources = np.array([[0.0, 0, 0], [0.1, 0, 0], [10.0, 0, 0]])
    values = np.array([1.0, 3.0, 7.0])
    got = near_max(np.array([[0.05, 0, 0], [9.9, 0, 0]]), sources, values)
    assert got.tolist() == [7.0, 7.0]  # three sources: each target sees all (k = 6)
    line = np.zeros((100, 3))
    line[:, 0] = np.arange(100.0)
    spike = np.zeros(100)
    spike[50] = 1.0
    got = near_max(np.array([[50.2, 0, 0], [52.9, 0, 0], [90.0, 0, 0]]), line, spike)
    assert got.tolist() == [1.0, 1.0, 0.0]  # its six nearest reach the spike, or not


def test_values_beyond_the_bounds_stand_out_with_the_reason(report, tmp_path):
    _, summary = report
    bad = copy.deepcopy(summary)
    bad["seams"]["spline_normal_jump_max_deg"] = 179.0
    bad["patches"][2]["folded"] = 3
    bad["errors"]["displaced"]["hausdorff"] = 0.05
    flags = beyond_bounds(bad)
    got = {(f.section, f.row, f.key) for f in flags}
    assert ("seams", None, "spline_normal_jump_max_deg") in got
    assert ("patches", 2, "folded") in got
    assert ("errors.displaced", None, "hausdorff") in got
    jump = next(f for f in flags if f.key == "spline_normal_jump_max_deg")
    assert jump.value > OPPOSED_NORMALS_DEG and "flipped or folded" in jump.reason
    write_html(tmp_path, bad)
    text = (tmp_path / "report.html").read_text()
    alarm = re.search(r"<div class='alarm'>(.*?)</div>", text, re.S).group(1)
    assert "spline normal jump max deg = 179" in alarm and "flipped or folded" in alarm
    assert "patch 2: folded = 3" in alarm
    # the table cells are marked and point to their reasons
    cells = re.findall(r"<td class='beyond'[^>]*>([^<]*)<a href='#beyond-(\d+)'>", text)
    assert ("179 ", str(1 + [f.key for f in flags].index("spline_normal_jump_max_deg"))) in cells
    assert any(c.startswith("3 ") for c, _ in cells)
    # a sound summary: no mark, and the page says so
    good = copy.deepcopy(summary)
    good["seams"]["spline_normal_jump_max_deg"] = 0.5
    good["errors"]["displaced"]["hausdorff"] = 0.001
    for row in good["patches"]:
        row.update(folded=0, aspect_max=2.0, input_distance_max=0.001,
                   corner_angles=[90.0] * 4)  # fmt: skip
    assert beyond_bounds(good) == []
    write_html(tmp_path, good)
    text = (tmp_path / "report.html").read_text()
    assert "class='beyond'" not in text and "within the report's bounds" in text


def test_displacement_images_each_on_their_own_scale(report):
    out, summary = report
    text = (out / "report.html").read_text()
    scales = _page(summary)["map_scales"]
    assert len(scales) == summary["patches_total"] and min(scales) > 0
    assert len(set(np.round(scales, 9))) > 1  # not one shared scale
    for p, scale in enumerate(scales):
        img = _read(out / f"report/map_{p:03d}.png").astype(int)
        assert max(img.shape[:2]) >= 128
        assert abs(float(np.median(img)) - 128) < 20  # mid-grey is no displacement
        assert np.abs(img - 128).max() >= 126  # the largest value reaches full scale
        assert f"patch {p}: &plusmn;{100 * scale:.3g}%</figcaption>" in text


CHROMIUM = Path("/usr/bin/chromium")


@pytest.fixture(scope="module")
def shots(tmp_path_factory) -> Path:
    base = os.environ.get("MESHFIT_TEST_ARTIFACTS")
    root = Path(base) if base else tmp_path_factory.getbasetemp() / "artifacts"
    out = root / "report"
    out.mkdir(parents=True, exist_ok=True)
    return out


# the pixels of the 3D view that differ from its white background, read back in the page
_DRAWN = """() => {
  const gl = document.querySelector('#view3d canvas');
  const c = document.createElement('canvas');
  c.width = gl.width; c.height = gl.height;
  const ctx = c.getContext('2d');
  ctx.drawImage(gl, 0, 0);
  const d = ctx.getImageData(0, 0, c.width, c.height).data;
  let drawn = 0, blue = 0;
  for (let i = 0; i < d.length; i += 4) {
    if (d[i] < 250 || d[i + 1] < 250 || d[i + 2] < 250) drawn++;
    if (d[i + 2] > d[i] + 60) blue++;
  }
  return [drawn, blue, d.length / 4];
}"""


def test_the_3d_view_draws_offline_from_the_file(report, shots):
    """Debian's chromium opens the page from file:// with the network off: the three.js
    bundle and the model load from beside the page and the WebGL canvas shows the model."""
    from playwright.sync_api import sync_playwright

    from tests.ui.conftest import CHROMIUM_ARGS

    out, _ = report
    assert CHROMIUM.exists(), f"the report's browser test needs Debian's chromium at {CHROMIUM}"
    requests: list[str] = []
    errors: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            context = browser.new_context(viewport={"width": 1100, "height": 900}, offline=True)
            page = context.new_page()
            page.on("request", lambda r: requests.append(r.url))
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto((out / "report.html").as_uri())
            page.wait_for_selector("#view3d[data-state='ready']", timeout=60_000)
            view = page.locator("#view3d")
            view.scroll_into_view_if_needed()
            view.screenshot(path=str(shots / "view3d_front.png"))
            drawn, blue, total = page.evaluate(_DRAWN)
            # another fixed viewpoint draws another picture
            page.get_by_role("button", name="back").click()
            view.screenshot(path=str(shots / "view3d_back.png"))
            back = page.evaluate(_DRAWN)
            # the page saves the model it shows as a GLB file
            with page.expect_download() as saving:
                page.get_by_role("button", name="save model.glb").click()
            saved = Path(saving.value.path()).read_bytes()
            assert saving.value.suggested_filename == "model.glb"
            page.screenshot(path=str(shots / "report_page.png"), full_page=True)
            page.emulate_media(media="print")
            page.screenshot(path=str(shots / "report_print.png"), full_page=True)
            printed = view.is_visible()
        finally:
            browser.close()
    assert not errors
    assert all(u.startswith("file://") for u in requests), requests
    assert 0.05 * total < drawn < 0.95 * total  # the model, framed: not empty, not all
    assert blue > 0.2 * drawn  # coloured by the deviation (mostly near: blue)
    assert back[0] > 0.05 * total and back != [drawn, blue, total]
    assert not printed  # the printout shows the fixed viewpoints instead
    script = (out / "report/model.js").read_text()
    assert saved[:4] == b"glTF" and base64.b64encode(saved).decode() in script


def test_resume_keeps_the_images(report, tmp_path):
    import shutil

    out, summary = report
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "report.html").unlink()
    before = (copy / "report/layout_front.png").stat().st_mtime_ns
    opts = FitOptions(controls=(6, 6), spring_level=1, formats=(), image_size=160)
    again = run_fit(
        real_mesh("spot"),
        copy,
        layout=ROOT / "examples/layouts/spot.json",
        options=opts,
        resume=True,
    )
    assert again["work_done"] == []
    assert (copy / "report/layout_front.png").stat().st_mtime_ns == before
    # the page is written again with what the renders measured (scales, labels, the model)
    assert again["report_page"] == summary["report_page"]
    text = (copy / "report.html").read_text()
    assert text.count("class='tag'") == (out / "report.html").read_text().count("class='tag'")
    assert "<script src='report/model.js'></script>" in text


def test_model_view_is_upright():
    from meshfit.report import model_view

    rng = np.random.default_rng(0)
    # y-up by default: a body about as long (z) as it is tall (y), like spot, is seen from
    # the side, not stood on its end
    body = rng.normal(size=(500, 3)) * [0.3, 0.55, 0.6]
    view, up = model_view(body)
    assert_allclose(up, [0.0, 1.0, 0.0])
    assert abs(view @ up) < 1e-9
    assert abs(view[0]) > abs(view[2])  # along the narrow horizontal axis (x), not the long one
    # z-up where the model is much taller along z than along y (a bust scanned z-up)
    bust = rng.normal(size=(500, 3)) * [0.5, 0.7, 1.0]
    assert_allclose(model_view(bust)[1], [0.0, 0.0, 1.0])
    # degenerate spreads still give a horizontal view
    for pts in (np.zeros((4, 3)), np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])):
        view, up = model_view(pts)
        assert np.isfinite(view).all() and np.linalg.norm(view) > 0 and abs(view @ up) < 1e-9


def test_blender_renders_fail_with_the_reason(tmp_path):
    """Each way Blender's Python can fail is a RenderError saying which (the renders with
    Blender itself: tests/export/test_blender.py); no image is left behind."""
    args = {"size": 16, "view": (1.0, 0.0, 0.0)}
    with pytest.raises(RenderError, match="no Blender Python at"):
        blender_renders(tmp_path, "fit.usdc", python=tmp_path / "missing", **args)
    with pytest.raises(RenderError, match=r"fit.usdc .* failed \(exit 1\)(.|\n)*'bpy'"):
        blender_renders(tmp_path, "fit.usdc", python=sys.executable, **args)
    slow = tmp_path / "python"
    slow.write_text("#!/bin/sh\nexec sleep 30\n")
    slow.chmod(0o755)
    with pytest.raises(RenderError, match=r"took longer than 0\.5 s"):
        blender_renders(tmp_path, "fit.usdc", python=slow, timeout=0.5, **args)
    assert not list(tmp_path.rglob("*.png"))
