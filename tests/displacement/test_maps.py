import numpy as np
import OpenEXR
import png
import pytest
from numpy.testing import assert_allclose

from meshfit.bspline import fit_bspline, grid_parameters
from meshfit.displacement import (
    DisplacementMap,
    bump_map,
    bump_normals,
    displacement_map,
    read_exr,
    read_png,
    reconstruct,
    resample_map,
    sample_bilinear,
    vector_values,
)
from meshfit.displacement.io import to_image, write_png
from meshfit.errors import ImageFileError, InputError
from tests.bspline.grids import random_surface, scan_grid

F32 = 2.0**-24  # float32 unit round-off


def _scale(X):
    return float(np.abs(X).max())


@pytest.fixture(scope="module", params=["igea", "nefertiti"])
def fitted(request):
    X = scan_grid(request.param)
    return X, fit_bspline(X, controls=(10, 9))


def _analytic(rng):
    s = random_surface(rng)
    u, v = grid_parameters(33), grid_parameters(29)
    U, V = np.meshgrid(u, v, indexing="ij")
    bumps = 0.01 * np.sin(20 * U)[..., None] * np.cos(15 * V)[..., None]
    X = s.evaluate_grid(u, v) + bumps * s.normals(U, V) + 0.003 * rng.normal(size=(33, 29, 3))
    return X, fit_bspline(X, controls=(7, 9))


def test_vector_map_reproduces_grid_to_float64(fitted):
    X, s = fitted
    d = displacement_map(s, X)
    assert d.values.shape == (*X.shape[:2], 3)
    assert d.image.dtype == np.float32
    assert_allclose(reconstruct(s, d), X, rtol=0, atol=4 * np.finfo(float).eps * _scale(X))


def test_vector_map_reproduces_grid_analytic(rng):
    X, s = _analytic(rng)
    assert_allclose(reconstruct(s, displacement_map(s, X)), X, rtol=0, atol=1e-15 * 8)


def test_components_are_frame_dot_products(rng):
    X, s = _analytic(rng)
    d = displacement_map(s, X)
    U, V = np.meshgrid(grid_parameters(33), grid_parameters(29), indexing="ij")
    T, _, N = s.frames(U, V)
    D = X - s.evaluate(U, V)
    assert_allclose(d.values[..., 0], (D * T).sum(-1), atol=1e-15)
    assert_allclose(d.values[..., 2], (D * N).sum(-1), atol=1e-15)
    n = displacement_map(s, X, kind="scalar", scalar="component")
    m = displacement_map(s, X, kind="magnitude")
    assert_allclose(n.values[..., 0], d.values[..., 2])
    assert_allclose(m.values[..., 0], np.linalg.norm(D, axis=-1), atol=1e-15)


def test_scalar_maps_with_base(rng):
    X, s = _analytic(rng)
    d = displacement_map(s, X)
    m = displacement_map(s, X, kind="magnitude")
    n = displacement_map(s, X, kind="scalar", scalar="component")
    assert_allclose(reconstruct(s, m, base=d), X, atol=1e-14)
    assert_allclose(reconstruct(s, n, base=d), X, atol=1e-14)
    with pytest.raises(InputError, match="base"):
        reconstruct(s, m)
    # scalar map alone: displacement along N only
    S = s.evaluate_grid(grid_parameters(33), grid_parameters(29))
    U, V = np.meshgrid(grid_parameters(33), grid_parameters(29), indexing="ij")
    assert_allclose(reconstruct(s, n), S + n.values * s.normals(U, V), atol=1e-14)


def test_doubling_normal_component_map_doubles_normal_component(rng):
    """The thesis' image game: editing the grey (normal component) map moves only the normal
    part of the vector map it is applied to."""
    X, s = _analytic(rng)
    d = displacement_map(s, X)
    n = displacement_map(s, X, kind="scalar", scalar="component")
    twice = DisplacementMap(2 * n.values, "scalar")
    got = displacement_map(s, reconstruct(s, twice, base=d))
    assert_allclose(got.values[..., :2], d.values[..., :2], atol=1e-13)
    assert_allclose(got.values[..., 2], 2 * d.values[..., 2], atol=1e-13)
    # scaling a magnitude map scales the vectors along their directions
    m = displacement_map(s, X, kind="magnitude")
    half = DisplacementMap(0.5 * m.values, "magnitude")
    assert_allclose(vector_values(half, d), 0.5 * d.values, atol=1e-15)


def test_resampling_with_the_surface_filters_model_space_vectors(fitted):
    X, s = fitted
    d = displacement_map(s, X)
    h, w = d.shape
    for shape in ((h + 8, w + 5), (h - 7, w + 3), (h, w)):
        r = resample_map(d, shape, surface=s)
        assert r.shape == shape and r.kind == "vector"
        # read at its own resolution: the old map read at that resolution
        assert_allclose(reconstruct(s, r), reconstruct(s, d, shape=shape), atol=1e-12 * _scale(X))
    # frame components filtered as channels are a different (frame-dependent) surface
    plain = resample_map(d, (h + 8, w + 5))
    assert np.abs(reconstruct(s, plain) - reconstruct(s, d, shape=(h + 8, w + 5))).max() > 1e-9
    # a scalar map is resampled as values, with or without the surface
    n = displacement_map(s, X, kind="scalar")
    np.testing.assert_array_equal(
        resample_map(n, (h + 8, w + 5), surface=s).values, resample_map(n, (h + 8, w + 5)).values
    )
    with pytest.raises(InputError, match="2 x 2"):
        resample_map(d, (1, w), surface=s)


def test_reconstruction_at_other_resolutions_is_bilinear(fitted):
    X, s = fitted
    d = displacement_map(s, X)
    h, w = d.shape
    fine = reconstruct(s, d, shape=(2 * h - 1, 2 * w - 1))
    assert_allclose(fine[::2, ::2], X, atol=1e-12 * _scale(X))
    # midpoints carry the mean of the neighbouring displacements
    up = resample_map(d, (2 * h - 1, 2 * w - 1))
    assert_allclose(up.values[1::2, ::2], 0.5 * (d.values[:-1] + d.values[1:]), atol=1e-15)
    uv = np.random.default_rng(3).uniform(0, 1, (20, 2))
    i, j = (uv[:, 0] * (h - 1)).astype(int), (uv[:, 1] * (w - 1)).astype(int)
    fx, fy = uv[:, 0] * (h - 1) - i, uv[:, 1] * (w - 1) - j
    V = d.values
    want = (
        (1 - fx)[:, None] * (1 - fy)[:, None] * V[i, j]
        + fx[:, None] * (1 - fy)[:, None] * V[i + 1, j]
        + (1 - fx)[:, None] * fy[:, None] * V[i, j + 1]
        + (fx * fy)[:, None] * V[i + 1, j + 1]
    )
    assert_allclose(sample_bilinear(V, uv[:, 0], uv[:, 1]), want, atol=1e-15)
    coarse = reconstruct(s, d, shape=(7, 5))
    assert coarse.shape == (7, 5, 3)
    assert_allclose(coarse[[0, -1]][:, [0, -1]], X[[0, -1]][:, [0, -1]], atol=1e-12 * _scale(X))


def test_exr_round_trip_to_float32(fitted, tmp_path):
    X, s = fitted
    d = displacement_map(s, X)
    d.to_exr(tmp_path / "d.exr")
    e = DisplacementMap.from_exr(tmp_path / "d.exr")
    assert e.kind == "vector"
    np.testing.assert_array_equal(e.image, d.image)
    # rebuilt from the file: within float32 rounding of the displacement, plus float64 noise
    err = np.linalg.norm(reconstruct(s, e) - X, axis=-1)
    bound = np.sqrt(3) * F32 * np.linalg.norm(d.values, axis=-1) + 8 * np.finfo(float).eps * _scale(
        X
    )
    assert (err <= bound).all()
    n = displacement_map(s, X, kind="scalar")
    n.to_exr(tmp_path / "n.exr")
    np.testing.assert_array_equal(read_exr(tmp_path / "n.exr").image, n.image)


def test_png_round_trip_within_half_a_step(fitted, tmp_path):
    X, s = fitted
    for kind in ("scalar", "magnitude", "vector"):
        m = displacement_map(s, X, kind=kind)
        m.to_png(tmp_path / f"{kind}.png")
        r = read_png(tmp_path / f"{kind}.png")
        step = (m.values.max() - m.values.min()) / 65535
        assert r.kind == kind
        assert np.abs(r.values - m.values).max() <= 0.5 * step * (1 + 1e-9)
    info = png.Reader(bytes=(tmp_path / "scalar.png").read_bytes()).read()[3]
    assert info["bitdepth"] == 16 and info["greyscale"]


def test_edited_images_rebuild_geometry(fitted, tmp_path):
    """Scaling, lossy compression, compositing and 8-bit re-saving all come back to geometry."""
    X, s = fitted
    d = displacement_map(s, X)
    spline_only = np.linalg.norm(reconstruct(s, DisplacementMap(0 * d.values)) - X, axis=-1)
    # 1. scaled: a half-resolution image, rebuilt at full resolution
    half = resample_map(d, ((d.shape[0] + 1) // 2, (d.shape[1] + 1) // 2))
    half.to_exr(tmp_path / "half.exr")
    got = reconstruct(s, read_exr(tmp_path / "half.exr"), shape=d.shape)
    err = np.linalg.norm(got - X, axis=-1)
    assert np.sqrt(np.mean(err**2)) < 0.8 * np.sqrt(np.mean(spline_only**2))
    # 2. lossy compression (PXR24 keeps 15 mantissa bits)
    d.to_exr(tmp_path / "pxr.exr", compression="pxr24")
    lossy = read_exr(tmp_path / "pxr.exr")
    assert not np.array_equal(lossy.image, d.image)
    err = np.linalg.norm(reconstruct(s, lossy) - X, axis=-1)
    assert (
        err <= np.sqrt(3) * 2.0**-15 * np.linalg.norm(d.values, axis=-1) + 1e-12 * _scale(X)
    ).all()
    # 3. compositing: erase the detail in a rectangle, keep it elsewhere
    vals = d.values.copy()
    vals[5:15, 10:20] = 0
    DisplacementMap(vals, "vector").to_exr(tmp_path / "erased.exr")
    got = reconstruct(s, read_exr(tmp_path / "erased.exr"))
    S = s.evaluate_grid(grid_parameters(d.shape[0]), grid_parameters(d.shape[1]))
    assert_allclose(got[5:15, 10:20], S[5:15, 10:20], atol=1e-12 * _scale(X))
    keep = np.ones(d.shape, bool)
    keep[5:15, 10:20] = False
    assert (np.linalg.norm(got - X, axis=-1)[keep] <= 1e-6 * np.abs(d.values).max()).all()
    # 4. a grey map re-saved by an editor as 8-bit RGB without metadata
    n = displacement_map(s, X, kind="scalar", scalar="component")
    lo, hi = float(n.values.min()), float(n.values.max())
    q8 = np.rint((n.values[..., 0] - lo) / (hi - lo) * 255).astype(np.uint8)
    rgb = to_image(np.repeat(q8[..., None], 3, axis=2))  # x along u, y up along v
    with open(tmp_path / "edit.png", "wb") as fh:
        png.Writer(rgb.shape[1], rgb.shape[0], bitdepth=8, greyscale=False).write(
            fh, rgb.reshape(rgb.shape[0], -1).tolist()
        )
    with pytest.raises(ImageFileError, match="metadata"):
        read_png(tmp_path / "edit.png")
    r = read_png(tmp_path / "edit.png", kind="scalar", value_range=(lo, hi))
    assert np.abs(r.values - n.values).max() <= 0.5 * (hi - lo) / 255 * (1 + 1e-9)
    got = reconstruct(s, r, base=d)
    assert (np.linalg.norm(got - X, axis=-1) <= 0.5 * (hi - lo) / 255 * (1 + 1e-9)).all()


def test_bump_map(rng, tmp_path):
    X, s = _analytic(rng)
    U, V = np.meshgrid(grid_parameters(33), grid_parameters(29), indexing="ij")
    on = s.evaluate(U, V)
    flat = bump_map(s, on, normals=s.normals(U, V))
    assert_allclose(flat.values, np.broadcast_to([0, 0, 1.0], flat.values.shape), atol=1e-14)
    # normals of the bumpy grid come back in world space
    b = bump_map(s, X)
    from meshfit.displacement import grid_normals

    assert_allclose(bump_normals(s, b), grid_normals(X), atol=1e-13)
    assert_allclose(np.linalg.norm(b.values, axis=-1), 1.0, atol=1e-14)
    # finite differences of the spline's own samples give nearly its normals
    approx = bump_map(s, on)
    assert np.degrees(np.arccos(np.clip(approx.values[2:-2, 2:-2, 2], -1, 1))).max() < 2.0
    b.to_png(tmp_path / "bump.png")
    r = read_png(tmp_path / "bump.png")
    assert r.kind == "bump"
    assert np.abs(r.values - b.values).max() <= 2 / 65535
    b.to_exr(tmp_path / "bump.exr")
    np.testing.assert_array_equal(read_exr(tmp_path / "bump.exr").image, b.image)


def test_bad_maps_and_files(tmp_path, rng):
    with pytest.raises(InputError, match="kind"):
        DisplacementMap(np.zeros((4, 4, 3)), "height")
    with pytest.raises(InputError, match="shape"):
        DisplacementMap(np.zeros((4, 4, 3)), "scalar")
    with pytest.raises(InputError, match=r"texel \[1, 2\]"):
        v = np.zeros((4, 4, 3))
        v[1, 2, 0] = np.nan
        DisplacementMap(v)
    with pytest.raises(ImageFileError, match="no such file"):
        read_exr(tmp_path / "missing.exr")
    (tmp_path / "junk.exr").write_bytes(b"not an image")
    with pytest.raises(ImageFileError, match="OpenEXR"):
        read_exr(tmp_path / "junk.exr")
    (tmp_path / "junk.png").write_bytes(b"not an image")
    with pytest.raises(ImageFileError, match="PNG"):
        read_png(tmp_path / "junk.png")
    X, s = _analytic(rng)
    with pytest.raises(InputError, match="scalar must be"):
        displacement_map(s, X, kind="scalar", scalar="closest")
    with pytest.raises(InputError, match="needs a bump map"):
        bump_normals(s, displacement_map(s, X))


@pytest.mark.parametrize("fmt", ["exr", "png"])
def test_map_images_are_in_texture_orientation(tmp_path, fmt):
    # texel [i, j] at (u_i, v_j): image x runs along u, image y along v, row 0 at v = 1
    h, w = 5, 3
    u, v = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    d = DisplacementMap(np.stack([u, v, u * 10 + v], axis=-1).astype(float), "vector")
    path = tmp_path / f"ramp.{fmt}"
    if fmt == "exr":
        d.to_exr(path)
        with OpenEXR.File(str(path)) as f:
            img = np.asarray(f.channels()["RGB"].pixels, dtype=float)
        back = read_exr(path)
    else:
        write_png(d, path, value_range=(0.0, 50.0))
        _, _, rows, _ = png.Reader(bytes=path.read_bytes()).asDirect()
        img = np.vstack([np.asarray(r, float) for r in rows]).reshape(w, h, 3) / 65535 * 50
        back = read_png(path)
    assert img.shape == (w, h, 3)  # w rows (v), h columns (u); channels T, N, B
    assert_allclose(img[0, :, 0], np.arange(h), atol=1e-3)  # u grows to the right
    assert_allclose(img[:, 0, 2], np.arange(w)[::-1], atol=1e-3)  # v grows upwards
    assert_allclose(back.values, d.values, atol=1e-3)


def test_map_images_of_format_2_keep_rows_along_u(tmp_path):
    vals = np.arange(5 * 3, dtype=np.float32).reshape(5, 3, 1)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    header |= {"meshfit_map": "2", "meshfit_kind": "scalar"}
    with OpenEXR.File(header, {"Y": np.ascontiguousarray(vals[:, :, 0])}) as f:
        f.write(str(tmp_path / "old.exr"))
    assert_allclose(read_exr(tmp_path / "old.exr").values, vals)


def _vector_ramp(h: int = 5, w: int = 3) -> DisplacementMap:
    """A vector map whose components tell each other apart: T = i, B = 10 + j, N = -(i + j)."""
    i, j = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    return DisplacementMap(np.stack([i, 10.0 + j, -(i + j)], axis=-1).astype(float), "vector")


def _raw_exr(path) -> tuple[dict, np.ndarray]:
    with OpenEXR.File(str(path)) as f:
        return dict(f.header()), np.asarray(f.channels()["RGB"].pixels, dtype=np.float64)


def test_vector_map_files_hold_tangent_normal_bitangent(tmp_path):
    # Blender's tangent-space Vector Displacement node (and Maya, Mudbox) read R along the
    # tangent, G along the normal, B along the bitangent
    d = _vector_ramp()
    d.to_exr(tmp_path / "v.exr")
    header, img = _raw_exr(tmp_path / "v.exr")
    assert header["meshfit_map"] == "3"
    T, B, N = (to_image(d.image[:, :, k]) for k in range(3))
    np.testing.assert_array_equal(img[:, :, 0], T)
    np.testing.assert_array_equal(img[:, :, 1], N)
    np.testing.assert_array_equal(img[:, :, 2], B)
    back = read_exr(tmp_path / "v.exr")
    assert back.kind == "vector"
    np.testing.assert_array_equal(back.values, d.values)  # in memory: T, B, N again
    # PNG alike
    write_png(d, tmp_path / "v.png", value_range=(-10.0, 20.0))
    _, _, rows, _ = png.Reader(bytes=(tmp_path / "v.png").read_bytes()).asDirect()
    q = np.vstack([np.asarray(r, float) for r in rows]).reshape(3, 5, 3) / 65535 * 30 - 10
    assert_allclose(q[:, :, 1], N, atol=1e-3)
    assert_allclose(q[:, :, 2], B, atol=1e-3)
    assert_allclose(read_png(tmp_path / "v.png").values, d.values, atol=1e-3)
    # an image that lost its metadata, read as a vector map: today's order
    with OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": img.astype(np.float32)}) as f:
        f.write(str(tmp_path / "bare.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "bare.exr", kind="vector").values, d.values)
    # bump maps keep the normal-map order: R = T, G = B, B = N
    bump = DisplacementMap(np.broadcast_to([0.6, 0.0, 0.8], (5, 3, 3)), "bump")
    bump.to_exr(tmp_path / "b.exr")
    _, img = _raw_exr(tmp_path / "b.exr")
    np.testing.assert_array_equal(img, to_image(bump.image))


def test_vector_map_files_of_format_2_read_as_written(tmp_path):
    d = _vector_ramp()
    # format 2: RGB = T, B, N, image rows along u
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    header |= {"meshfit_map": "2", "meshfit_kind": "vector"}
    with OpenEXR.File(header, {"RGB": np.ascontiguousarray(d.image)}) as f:
        f.write(str(tmp_path / "old.exr"))
    old = read_exr(tmp_path / "old.exr")
    assert old.kind == "vector"
    np.testing.assert_array_equal(old.values, d.values)


@pytest.mark.parametrize("seed", range(3))
def test_grid_normals_are_the_per_point_normals(seed):
    """The facing test of a finer map reads the spline's normals on the texel grid by
    banded products (`_grid_normals`); they are `points_and_frames`' normals, evaluated
    point by point, to round-off."""
    from meshfit.bspline import BSplineSurface
    from meshfit.displacement.maps import _grid_normals

    rng = np.random.default_rng(seed)
    s = BSplineSurface(rng.normal(size=(9, 11, 3)))
    h, w = 57, 73
    u, v = np.meshgrid(grid_parameters(h), grid_parameters(w), indexing="ij")
    want = s.points_and_frames(u, v)[3]
    got = _grid_normals(s, h, w)
    assert got.shape == want.shape
    assert_allclose(got, want, rtol=0, atol=1e-12)
    assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=1e-14)
