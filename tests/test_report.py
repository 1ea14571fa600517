"""The fit report: renders of every stage, displacement images, tables."""

from __future__ import annotations

import re
import sys

import numpy as np
import png
import pytest
from numpy.testing import assert_allclose

from meshfit.errors import RenderError
from meshfit.pipeline import FitOptions
from meshfit.report import REPORT_IMAGES, blender_renders
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


def test_report_lists_every_image(report):
    out, summary = report
    text = (out / "report.html").read_text()
    srcs = re.findall(r"src='([^']+)'", text)
    stems = [s for s, _ in REPORT_IMAGES]
    assert [f"report/{s}.png" for s in stems] == srcs[: len(stems)]
    assert len(srcs) == len(stems) + summary["patches_total"]
    for s in srcs:
        assert (out / s).is_file()
    # tables of errors, timings and patches
    for word in ("spline only", "displaced", "springs", "fit parametric rms"):
        assert word in text
    assert summary["outputs"]["report"] == ["report.html"]
    assert not summary["stages"]["report"]["cached"]


def test_model_renders_show_the_model(report):
    out, _ = report
    layout = _read(out / "report/layout.png")
    assert layout.shape == (160, 160, 3)
    model = (layout != 255).any(axis=2)
    assert 0.1 < model.mean() < 0.9
    # the layout render shows many patch colours, the spline render grey only
    colours = {tuple(c) for c in layout[model].tolist()}
    assert len(colours) > 24
    spline = _read(out / "report/spline.png")
    px = spline[(spline != 255).any(axis=2)].astype(int)
    assert (np.ptp(px, axis=1) <= 1).all()
    # the spring checkerboard alternates light and dark squares of each patch colour
    springs = _read(out / "report/springs.png")
    assert len({tuple(c) for c in springs.reshape(-1, 3).tolist()}) > 50
    # the heat map runs from blue (near the input) to red (far)
    heat = _read(out / "report/error.png").astype(int)
    assert (heat[..., 2] - heat[..., 0] > 100).any() and (heat[..., 0] - heat[..., 2] > 100).any()


def test_displacement_images_are_centred_on_grey(report):
    out, summary = report
    img = _read(out / "report/map_000.png")
    assert max(img.shape[:2]) >= 128
    assert abs(float(np.median(img)) - 128) < 20
    assert summary["map_scale"] > 0


def test_resume_keeps_the_images(report, tmp_path):
    import shutil

    out, _ = report
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    before = (copy / "report/layout.png").stat().st_mtime_ns
    opts = FitOptions(controls=(6, 6), spring_level=1, formats=(), image_size=160)
    again = run_fit(
        real_mesh("spot"),
        copy,
        layout=ROOT / "examples/layouts/spot.json",
        options=opts,
        resume=True,
    )
    assert again["work_done"] == []
    assert (copy / "report/layout.png").stat().st_mtime_ns == before
    assert (copy / "report.html").is_file()


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
