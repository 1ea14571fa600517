"""Headless renders: the rasteriser kernel against its oracle, framing, depth, colours, PNG."""

from __future__ import annotations

import numpy as np
import png
import pytest

from meshfit._kernels import render as kernel
from meshfit.errors import InputError
from meshfit.render import (
    Camera,
    camera_frame,
    heat_colors,
    patch_colors,
    project,
    render,
    write_png_rgb,
)

from .conftest import real_mesh
from .reference import render as oracle


def _random_scene(rng, m=12, size=24):
    P = rng.uniform(-4, size + 4, size=(m, 3, 3))
    P[:, :, 2] = rng.uniform(-1, 1, size=(m, 3))
    color = rng.uniform(0, 1, size=(m, 3, 3))
    shade = rng.uniform(0.2, 1, size=(m, 3))
    uv = rng.uniform(0, 3, size=(m, 3, 2))
    return P, color, shade, uv


@pytest.mark.parametrize("checker", [0.0, 2.0])
def test_kernel_matches_oracle(rng, checker):
    P, color, shade, uv = _random_scene(rng)
    out = []
    for fn in (kernel.raster, oracle.raster):
        image = np.ones((24, 24, 3))
        depth = np.full((24, 24), -np.inf)
        fn(P, color, shade, uv, checker, image, depth)
        out.append((image, depth))
    np.testing.assert_allclose(out[0][0], out[1][0], atol=1e-12)
    np.testing.assert_allclose(out[0][1], out[1][1], atol=1e-12)


def test_kernel_matches_oracle_on_triangles_smaller_than_a_pixel(rng):
    # a dense mesh drawn small: most triangles cover no pixel centre, some cover one, and
    # corners on pixel centres and half-pixel lines exercise the bounding box's ends
    m, size = 400, 16
    base = rng.uniform(-1, size + 1, size=(m, 1, 3))
    P = base + rng.uniform(-0.7, 0.7, size=(m, 3, 3))
    P[::7, 0, :2] = np.floor(P[::7, 0, :2]) + 0.5  # a corner exactly on a pixel centre
    P[::11, 1, 0] = np.floor(P[::11, 1, 0])  # a corner on a pixel edge
    P[:, :, 2] = rng.uniform(-1, 1, size=(m, 3))
    color = rng.uniform(0, 1, size=(m, 3, 3))
    shade = rng.uniform(0.2, 1, size=(m, 3))
    uv = rng.uniform(0, 3, size=(m, 3, 2))
    out = []
    for fn in (kernel.raster, oracle.raster):
        image = np.ones((size, size, 3))
        depth = np.full((size, size), -np.inf)
        fn(P, color, shade, uv, 2.0, image, depth)
        out.append((image, depth))
    assert np.isfinite(out[1][1]).sum() > size  # some pixels are drawn
    np.testing.assert_allclose(out[0][0], out[1][0], atol=1e-12)
    np.testing.assert_allclose(out[0][1], out[1][1], atol=1e-12)


@pytest.mark.parametrize("flat", [False, True])
@pytest.mark.parametrize("colours", ["face", "vertex", "none"])
def test_mesh_kernel_matches_the_gathered_oracle(rng, flat, colours):
    n, m, size = 30, 40, 32
    V = rng.normal(size=(n, 3))
    X = rng.uniform(-4, size + 4, size=(n, 3))
    F = rng.integers(0, n, size=(m, 3))
    view = np.array([0.0, 0.6, 0.8])
    fc = rng.uniform(0, 1, (m, 3)) if colours == "face" else np.zeros((0, 3))
    vc = rng.uniform(0, 1, (n, 3)) if colours == "vertex" else np.zeros((0, 3))
    uv = rng.uniform(0, 3, (n, 2))
    args = (V, X, F, view, 0.25, flat, fc, vc, uv, 2.0)
    out = []
    for draw in ("kernel", "oracle"):
        image = np.ones((size, size, 3))
        depth = np.full((size, size), -np.inf)
        if draw == "kernel":
            kernel.raster_mesh(*args, image, depth)
        else:
            oracle.raster(*oracle.mesh_inputs(*args), image, depth)
        out.append((image, depth))
    assert np.isfinite(out[1][1]).any()
    np.testing.assert_allclose(out[0][0], out[1][0], atol=1e-12)
    np.testing.assert_allclose(out[0][1], out[1][1], rtol=1e-12)


def _square(z=0.0):
    V = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], dtype=float)
    V[:, 1] = z
    return V, np.array([[0, 1, 2], [0, 2, 3]])


def test_square_fills_the_frame_and_keeps_colours():
    V, F = _square()
    cam = Camera(size=(50, 50), view=(0, 1, 0))
    img = render(V, F, camera=cam, vertex_colors=np.full((4, 3), 0.5))
    covered = (img != 255).any(axis=2)
    # the square seen head-on fills the frame less the 6% margin on each side
    assert covered[3:47, 3:47].all()
    assert not covered[:2].any() and not covered[:, :2].any()
    assert (np.abs(img[covered].astype(int) - 128) <= 1).all()  # lit head-on: the colour
    face = render(V, F, camera=cam, face_colors=[[1, 0, 0], [0, 0, 1]], shading="flat")
    colours = {tuple(c) for c in face.reshape(-1, 3).tolist()}
    assert {(255, 0, 0), (0, 0, 255)} <= colours


def test_nearer_surface_hides_the_farther():
    V1, F1 = _square(0.0)
    V2, F2 = _square(-1.0)  # nearer to a camera looking along +y (it sits at smaller y)
    V = np.vstack([V1, V2 * [0.5, 1, 0.5]])
    F = np.vstack([F1, F2 + 4])
    cols = np.vstack([np.tile([1.0, 0, 0], (4, 1)), np.tile([0, 0, 1.0], (4, 1))])
    cam = Camera(size=(40, 40), view=(0, 1, 0), bounds=V1)
    img = render(V, F, camera=cam, vertex_colors=cols)
    assert tuple(img[20, 20]) == (0, 0, 255)
    assert tuple(img[5, 5]) == (255, 0, 0)


def test_checkerboard_alternates():
    V, F = _square()
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    img = render(V, F, camera=Camera(size=(80, 80), view=(0, 1, 0)), uv=uv, checker=2.0)
    a, b = img[25, 25, 0], img[25, 55, 0]
    assert a != b and img[55, 55, 0] == a


def test_real_mesh_render_and_png(tmp_path):
    mesh = real_mesh("spot")
    cam = Camera(size=(64, 48), view=(1, 0, 0), up=(0, 1, 0))
    img = render(mesh.vertices, mesh.faces, camera=cam)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    covered = (img < 250).any(axis=2).mean()
    assert 0.1 < covered < 0.9
    path = write_png_rgb(tmp_path / "spot.png", img)
    w, h, rows, _ = png.Reader(bytes=path.read_bytes()).asRGB8()
    back = np.vstack([np.asarray(r, np.uint8) for r in rows]).reshape(h, w, 3)
    np.testing.assert_array_equal(back, img)


def test_helpers_and_errors():
    R = camera_frame((0, 0, -1))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    h = heat_colors([0.0, 1.0, 2.0], vmax=1.0)
    np.testing.assert_allclose(h[1], h[2])
    assert patch_colors([-1])[0].tolist() == [0.6, 0.6, 0.6]
    V, F = _square()
    with pytest.raises(InputError):
        render(V, F + 10)
    with pytest.raises(InputError):
        render(V, F, shading="phong")
    with pytest.raises(InputError):
        render(V, F, camera={"size": (50, 50)})
    with pytest.raises(InputError):
        write_png_rgb("x.png", np.zeros((4, 4, 3)))


def test_camera_normalises_and_validates():
    cam = Camera(size=(64.9, 48), view=np.array([1, 0, 0]), up=[0, 1, 0], bounds=np.eye(3)[:2])
    assert cam.size == (64, 48) and cam.view == (1.0, 0.0, 0.0) and cam.up == (0.0, 1.0, 0.0)
    assert cam.bounds == ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    assert all(type(x) is float for x in cam.view + cam.up + cam.bounds[0])
    assert hash(cam) == hash(Camera((64, 48), (1, 0, 0), (0, 1, 0), ((1, 0, 0), (0, 1, 0))))
    assert Camera(bounds=np.zeros((0, 3))).bounds == ()
    # a view along up is drawn (camera_frame takes another up), not refused
    V, F = _square()
    assert render(V, F, camera=Camera(size=(8, 8), view=(0, 0, 1))).shape == (8, 8, 3)
    bad = [
        {"size": (0, 50)},
        {"size": (50,)},
        {"size": "big"},
        {"view": (0, 0, 0)},
        {"view": (0, np.nan, 1)},
        {"view": (1, 0)},
        {"up": (0.0, 0.0, 0.0)},
        {"bounds": [[0, 0]]},
        {"bounds": [[0, 0, np.inf]]},
    ]
    for kw in bad:
        with pytest.raises(InputError):
            Camera(**kw)


def test_project_places_points_where_render_draws_them():
    V1, F1 = _square(0.0)
    V2, F2 = _square(-1.0)  # nearer, half the size
    V = np.vstack([V1, V2 * [0.5, 1, 0.5]])
    F = np.vstack([F1, F2 + 4])
    cam = Camera(size=(40, 40), view=(0, 1, 0), bounds=V1)
    depth = np.empty((40, 40))
    render(V, F, camera=cam, depth_out=depth)
    X = project(V, cam)
    # the big square's corners at the margins, the small one's halfway in
    np.testing.assert_allclose(np.sort(X[:4, 0]), [2.4, 2.4, 37.6, 37.6])
    np.testing.assert_allclose(np.sort(X[4:, 0]), [11.2, 11.2, 28.8, 28.8])
    # depth towards the viewer: the nearer square (y = -1) is 1 unit nearer
    np.testing.assert_allclose(X[:4, 2] - X[4:, 2], -1.0)
    assert depth[20, 20] == X[4, 2] and depth[4, 4] == X[0, 2]
    assert np.isneginf(depth[0, 0])  # nothing drawn in the margin
