"""The three map kinds a fit offers (vector, scalar, bump) end to end: made, rebuilt, shaded,
written and read; invariant under rigid motions and scalings."""

import json

import numpy as np
import OpenEXR
import png
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from meshfit import tol
from meshfit.bspline import fit_bspline, grid_parameters
from meshfit.displacement import (
    KINDS,
    DisplacementMap,
    bump_map,
    bump_normals,
    canonical_kind,
    displacement_map,
    grid_normals,
    read_exr,
    read_png,
    reconstruct,
    resample_map,
    shading_normals,
)
from meshfit.errors import ImageFileError, InputError
from meshfit.mesh import triangle_distances
from meshfit.springs.grid import grid_triangles
from tests.bspline.grids import random_surface

F32 = 2.0**-24  # float32 unit round-off


def _grid(rng, n=33, m=29, shift=0.4):
    """Detail along the normal of a smooth surface, sampled at parameters moved along the
    surface by up to ``shift`` grid cells (a spring grid is not sampled at the fitted
    spline's parameters), and the spline fitted to it."""
    base = random_surface(rng)
    U, V = np.meshgrid(grid_parameters(n), grid_parameters(m), indexing="ij")
    Uw = np.clip(U + shift / (n - 1) * np.sin(6 * np.pi * V), 0, 1)
    Vw = np.clip(V + shift / (m - 1) * np.cos(4 * np.pi * U), 0, 1)
    h = 0.01 * np.sin(20 * Uw) * np.cos(15 * Vw) + 0.004 * np.sin(45 * Uw + 30 * Vw)
    X = base.evaluate(Uw, Vw) + h[..., None] * base.normals(Uw, Vw)
    return X, fit_bspline(X, controls=(7, 8))


def _diag(X):
    return float(np.linalg.norm(np.ptp(X.reshape(-1, 3), axis=0)))


def _to_grid_surface(P, X):
    """Distance from each point ``P (..., 3)`` to the triangulated grid ``X``."""
    d, _ = triangle_distances(P.reshape(-1, 3), X.reshape(-1, 3), grid_triangles(*X.shape[:2]))
    return d.reshape(P.shape[:-1])


def _two_sided(R, X, margin=2):
    """Largest and root-mean-square distance between two grids' surfaces, both ways, from
    the points at least ``margin`` rows inside each (a patch's border is its neighbour's
    business)."""
    k = slice(margin, -margin)
    d = np.r_[_to_grid_surface(R[k, k], X).ravel(), _to_grid_surface(X[k, k], R).ravel()]
    return d.max(), np.sqrt(np.mean(d**2))


def test_kind_names_and_the_former_normal_kind():
    assert tuple(KINDS) == ("vector", "scalar", "magnitude", "bump")
    assert canonical_kind("normal") == "scalar"
    m = DisplacementMap(np.zeros((3, 4)), "normal")  # maps made under the former name
    assert m.kind == "scalar" and m.channels == 1
    with pytest.raises(InputError, match="kind must be one of"):
        canonical_kind("height")
    X, s = _grid(np.random.default_rng(0))
    a = displacement_map(s, X, kind="normal")
    np.testing.assert_array_equal(a.values, displacement_map(s, X, kind="scalar").values)
    b = displacement_map(s, X, kind="bump")
    np.testing.assert_array_equal(b.values, bump_map(s, X).values)


def test_every_kind_rebuilds_within_its_bound(rng):
    X, s = _grid(rng)
    h, w = X.shape[:2]
    diag = _diag(X)
    U, V = np.meshgrid(grid_parameters(h), grid_parameters(w), indexing="ij")
    S = s.evaluate(U, V)
    N = s.normals(U, V)
    d = X - S
    d_tan = np.linalg.norm(d - (d * N).sum(-1)[..., None] * N, axis=-1)
    # vector: the grid itself
    assert_allclose(reconstruct(s, displacement_map(s, X)), X, rtol=0, atol=1e-15 * diag)
    # scalar: on the grid's surface where the normal's line meets it nearby, else d . N,
    # which misses the grid point by the tangential part of d
    sc = displacement_map(s, X, kind="scalar")
    R = reconstruct(s, sc)
    assert_allclose(R, S + sc.values * N, rtol=0, atol=1e-15 * diag)
    dist = _to_grid_surface(R, X)
    assert (dist <= d_tan + tol.TEST_ATOL * diag).all()
    inner = dist[2:-2, 2:-2]
    assert np.median(inner) <= tol.TEST_ATOL * diag  # interior lines meet the grid
    assert (inner <= tol.TEST_ATOL * diag).mean() > 0.95
    # bump: shading only, the geometry is the spline's
    bm = displacement_map(s, X, kind="bump")
    for shape in ((h, w), (2 * h - 1, w + 4)):
        want = s.evaluate_grid(*(grid_parameters(n) for n in shape))
        np.testing.assert_array_equal(reconstruct(s, bm, shape=shape), want)
    assert_allclose(bump_normals(s, bm), grid_normals(X), atol=1e-13)


@pytest.mark.parametrize("shift", [0.0, 0.4, 1.0])
def test_scalar_ray_rebuilds_the_grid_closer_than_the_normal_component(shift):
    """The measurement behind ``scalar="ray"``: the two-sided distance between the rebuilt
    and the original grid's surfaces, at the map's resolution and at twice it."""
    X, s = _grid(np.random.default_rng(11), n=41, m=37, shift=shift)
    ray = displacement_map(s, X, kind="scalar")
    comp = displacement_map(s, X, kind="scalar", scalar="component")
    fine = (2 * X.shape[0] - 1, 2 * X.shape[1] - 1)
    for shape in (None, fine):
        r_max, r_rms = _two_sided(reconstruct(s, ray, shape=shape), X)
        c_max, c_rms = _two_sided(reconstruct(s, comp, shape=shape), X)
        assert r_rms < c_rms
        assert r_max <= 1.25 * c_max


def test_scalar_map_reads_along_the_normal_at_any_resolution(rng):
    X, s = _grid(rng)
    sc = displacement_map(s, X, kind="scalar")
    shape = (50, 23)
    u, v = grid_parameters(shape[0]), grid_parameters(shape[1])
    U, V = np.meshgrid(u, v, indexing="ij")
    up = resample_map(sc, shape)
    want = s.evaluate(U, V) + up.values * s.normals(U, V)
    assert_allclose(reconstruct(s, sc, shape=shape), want, atol=1e-15 * _diag(X))
    # so a resampled scalar map read at its own resolution is the old one read there
    assert_allclose(reconstruct(s, up), reconstruct(s, sc, shape=shape), atol=1e-15 * _diag(X))


def test_bump_normals_at_any_resolution(rng):
    X, s = _grid(rng)
    h, w = X.shape[:2]
    b = bump_map(s, X)
    fine = bump_normals(s, b, shape=(2 * h - 1, 2 * w - 1))
    assert_allclose(np.linalg.norm(fine, axis=-1), 1.0, atol=1e-15)
    assert_allclose(fine[::2, ::2], grid_normals(X), atol=1e-13)
    # between texels: the normalised mean of the two texels' model-space normals
    n = grid_normals(X)
    mid = n[:-1] + n[1:]
    assert_allclose(fine[1::2, ::2], mid / np.linalg.norm(mid, axis=-1, keepdims=True), atol=1e-13)
    # resampled with the surface: read at its own resolution it gives the same normals
    r = resample_map(b, (h + 6, w - 5), surface=s)
    assert r.kind == "bump"
    assert_allclose(bump_normals(s, r), bump_normals(s, b, shape=(h + 6, w - 5)), atol=1e-13)
    # shading normals of each kind
    assert_allclose(shading_normals(s, b, shape=(h + 6, w - 5)), bump_normals(s, r), atol=1e-13)
    assert_allclose(shading_normals(s, displacement_map(s, X)), grid_normals(X), atol=1e-12)
    U, V = np.meshgrid(grid_parameters(9), grid_parameters(7), indexing="ij")
    assert_allclose(shading_normals(s, shape=(9, 7)), s.normals(U, V), atol=1e-15)
    with pytest.raises(InputError, match="shape"):
        shading_normals(s)


@pytest.mark.parametrize("kind", ["vector", "scalar", "bump", "magnitude"])
def test_every_kind_round_trips_through_exr_and_png(kind, rng, tmp_path):
    X, s = _grid(rng)
    m = displacement_map(s, X, kind=kind)
    m.to_exr(tmp_path / "m.exr")
    e = read_exr(tmp_path / "m.exr")
    assert e.kind == kind
    np.testing.assert_array_equal(e.image, m.image)  # float32, exactly
    with OpenEXR.File(str(tmp_path / "m.exr")) as f:
        assert set(f.channels()) == ({"Y"} if KINDS[kind] == 1 else {"RGB"})
        assert f.header()["meshfit_kind"] == kind
    m.to_png(tmp_path / "m.png")
    p = read_png(tmp_path / "m.png")
    assert p.kind == kind
    info = png.Reader(bytes=(tmp_path / "m.png").read_bytes()).read()[3]
    assert info["bitdepth"] == 16 and info["greyscale"] == (KINDS[kind] == 1)
    if kind == "bump":  # over [-1, 1], then normalised: within a step of the unit vectors
        assert np.abs(p.values - m.values).max() <= 2 * 2 / 65535
    else:
        step = (m.values.max() - m.values.min()) / 65535
        assert np.abs(p.values - m.values).max() <= 0.5 * step * (1 + 1e-9)
    if kind == "scalar":  # rebuilt from the PNG: within half a step along the normal
        err = np.linalg.norm(reconstruct(s, p) - reconstruct(s, m), axis=-1)
        assert err.max() <= 0.5 * step * (1 + 1e-9)


def test_files_of_the_former_normal_kind_read_as_scalar(tmp_path, rng):
    X, s = _grid(rng)
    m = displacement_map(s, X, kind="scalar")
    img = np.ascontiguousarray(m.image[:, :, 0])
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    header |= {"meshfit_map": "1", "meshfit_kind": "normal"}
    with OpenEXR.File(header, {"Y": img}) as f:
        f.write(str(tmp_path / "old.exr"))
    old = read_exr(tmp_path / "old.exr")
    assert old.kind == "scalar"
    np.testing.assert_array_equal(old.image, m.image)
    # a format-1 PNG: kind "normal" in its text chunk
    m.to_png(tmp_path / "new.png")
    chunks = list(png.Reader(bytes=(tmp_path / "new.png").read_bytes()).chunks())
    for k, (ctype, data) in enumerate(chunks):
        if ctype == b"tEXt":
            meta = json.loads(data[len(b"meshfit\x00") :]) | {"meshfit_map": 1, "kind": "normal"}
            chunks[k] = (ctype, b"meshfit\x00" + json.dumps(meta).encode("latin-1"))
    with open(tmp_path / "old.png", "wb") as fh:
        png.write_chunks(fh, chunks)
    assert read_png(tmp_path / "old.png").kind == "scalar"
    # a grey map an editor re-saved as RGB EXR without metadata: the mean of its channels
    with OpenEXR.File(header, {"RGB": np.repeat(img[..., None], 3, axis=2)}) as f:
        f.write(str(tmp_path / "rgb.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "rgb.exr", kind="scalar").image, m.image)
    with pytest.raises(ImageFileError, match="unknown map kind"):
        read_exr(tmp_path / "old.exr", kind="height")


def _rotation(q):
    q = np.asarray(q, dtype=np.float64)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array(
        [
            [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d],
        ]
    )


_GRID = _grid(np.random.default_rng(5), n=17, m=15, shift=0.6)
_MAPS = {k: displacement_map(_GRID[1], _GRID[0], kind=k) for k in KINDS}


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    q=st.tuples(*[st.floats(-1, 1) for _ in range(4)]).filter(lambda q: np.linalg.norm(q) > 0.1),
    shift=st.tuples(*[st.floats(-100, 100) for _ in range(3)]),
    scale=st.floats(1e-3, 1e3),
)
# a small grid far from the origin (once past a tolerance of the grid's size alone)
@example(q=(0.0, 0.0, 0.0, 1.0), shift=(0.0, 0.0, 89.79159560010618), scale=0.001)
def test_maps_follow_rigid_motions_and_scalings(q, shift, scale):
    """In the spline's own frame a rigid motion changes no component and a scaling by c
    multiplies lengths by c: vector, scalar and magnitude maps scale, bump maps stay."""
    X, s = _GRID
    R = _rotation(q)
    move = lambda P: scale * P @ R.T + np.asarray(shift)  # noqa: E731
    X2, s2 = move(X), s.with_control_points(move(s.control_points))
    size = scale * _diag(X)
    # coordinates round off relative to their own magnitude: a grid moved far from the
    # origin for its size carries that much more error, in lengths and in their ratios
    reach = size + float(np.abs(shift).max())
    for kind, m in _MAPS.items():
        got = displacement_map(s2, X2, kind=kind)
        want = m.values if kind == "bump" else scale * m.values
        unit = reach / size if kind == "bump" else reach
        assert_allclose(got.values, want, rtol=0, atol=tol.TEST_ATOL * unit)
        rebuilt = reconstruct(s2, got, base=displacement_map(s2, X2))
        want = move(reconstruct(s, m, base=_MAPS["vector"]))
        assert_allclose(rebuilt, want, atol=tol.TEST_ATOL * reach)
