"""Surface snakes: relaxation on analytic shapes, coarse-to-fine, editing, errors."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import tol
from meshfit.curves import curve_length, paint_curve
from meshfit.curves.snake import (
    SNAKE_MOVE_TOL,
    SnakeOptions,
    _pairs_ok,
    edit_snake,
    relax_snake,
    snake_forces,
)
from meshfit.errors import InputError
from meshfit.types import SurfaceCurve, SurfacePoints

from .. import shapes
from ..reference import snake as reference

SPHERE = shapes.icosphere(4, 1.0)


def curve_from_polyline(mesh, xyz, *, closed=False, rounds=40) -> SurfaceCurve:
    """Closest surface points of a 3-D polyline, densified until the sampling rule holds."""
    pts = mesh.closest_points(np.asarray(xyz, dtype=float)).points
    face, bary = np.array(pts.face), np.array(pts.bary)
    for _ in range(rounds):
        ok = _pairs_ok(mesh.faces, face, closed)
        if ok.all():
            break
        x = mesh.xyz(SurfacePoints(face, bary))
        bad = np.flatnonzero(~ok)
        mid = mesh.closest_points(0.5 * (x[bad] + x[(bad + 1) % len(face)])).points
        face = np.insert(face, bad + 1, mid.face)
        bary = np.insert(bary, bad + 1, mid.bary, axis=0)
    curve = SurfaceCurve(SurfacePoints(face, bary), closed)
    assert _pairs_ok(mesh.faces, curve.points.face, closed).all()
    return curve


def zigzag_arc(angle=1.5, n=40, amp=0.15) -> SurfaceCurve:
    """Crude zig-zag between (1, 0, 0) and (cos a, sin a, 0) on the unit icosphere."""
    t = np.linspace(0.0, angle, n)
    z = amp * np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    z[0] = z[-1] = 0.0
    return curve_from_polyline(SPHERE, np.stack([np.cos(t), np.sin(t), z], axis=1))


def circle(z0, n=200) -> SurfaceCurve:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = np.sqrt(1 - z0**2)
    return curve_from_polyline(
        SPHERE, np.stack([r * np.cos(t), r * np.sin(t), np.full(n, z0)], 1), closed=True
    )


def seg_lengths(mesh, curve):
    x = mesh.xyz(curve.points)
    if curve.closed:
        x = np.vstack([x, x[:1]])
    return np.linalg.norm(np.diff(x, axis=0), axis=1)


def on_surface(mesh, curve):
    d = mesh.closest_points(mesh.xyz(curve.points)).distance
    assert d.max() <= tol.ON_SURFACE * mesh.bbox_diagonal


@pytest.fixture(scope="module")
def fair_result():
    return zigzag_arc(), relax_snake(SPHERE, zigzag_arc(), SnakeOptions(max_iter=20_000))


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("levels", [1, 2, 4])
def test_forces_match_oracle(closed, levels, rng):
    x = rng.normal(size=(37, 3))
    kw = dict(w_fair=0.7, w_curv=1.3, w_arc=0.4, levels=levels)
    assert_allclose(
        snake_forces(x, closed=closed, **kw),
        reference.snake_forces(x, closed=closed, **kw),
        atol=1e-12,
    )


def test_fairness_snake_becomes_the_geodesic(fair_result):
    start, res = fair_result
    assert res.converged
    x = SPHERE.xyz(res.curve.points)
    geodesic = np.arccos(np.clip(x[0] @ x[-1], -1, 1))
    assert abs(seg_lengths(SPHERE, res.curve).sum() / geodesic - 1) < 0.005
    # every sample is near the great circle z = 0
    assert np.abs(x[:, 2]).max() < 0.01
    # ends fixed, bitwise
    assert_array_equal(res.curve.points.face[[0, -1]], start.points.face[[0, -1]])
    assert_array_equal(res.curve.points.bary[[0, -1]], start.points.bary[[0, -1]])
    on_surface(SPHERE, res.curve)
    assert np.isfinite(res.curve.points.bary).all() and np.isfinite(res.max_move).all()
    assert _pairs_ok(SPHERE.faces, res.curve.points.face, False).all()


def test_spacing_is_even(fair_result):
    _, res = fair_result
    seg = seg_lengths(SPHERE, res.curve)
    assert seg.std() / seg.mean() <= 0.05


def test_curvature_weight_gives_smooth_curve_on_surface():
    start = zigzag_arc()
    res = relax_snake(SPHERE, start, SnakeOptions(w_fair=0.2, w_curv=1.0, max_iter=20_000))
    on_surface(SPHERE, res.curve)
    x = SPHERE.xyz(res.curve.points)
    d = np.diff(x, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", d[1:], d[:-1]), -1, 1))
    d0 = np.diff(SPHERE.xyz(start.points), axis=0)
    d0 /= np.linalg.norm(d0, axis=1, keepdims=True)
    turn0 = np.arccos(np.clip(np.einsum("ij,ij->i", d0[1:], d0[:-1]), -1, 1))
    assert turn.max() < 0.1 * turn0.max()
    assert np.abs(x[:, 2]).max() < 0.02
    assert _pairs_ok(SPHERE.faces, res.curve.points.face, False).all()


def test_closed_small_circle_shrinks_and_stays_round():
    start = circle(0.5)
    res = relax_snake(SPHERE, start, SnakeOptions(max_iter=150))
    assert not res.converged  # curve shortening on the sphere: a small circle keeps shrinking
    x = SPHERE.xyz(res.curve.points)
    assert seg_lengths(SPHERE, res.curve).sum() < 0.97 * seg_lengths(SPHERE, start).sum()
    rho = np.linalg.norm(x[:, :2], axis=1)
    assert rho.std() / rho.mean() < 0.01  # still a circle about the z axis
    assert x[:, 2].mean() > 0.5  # moved toward the pole
    assert _pairs_ok(SPHERE.faces, res.curve.points.face, True).all()


def test_closed_great_circle_keeps_its_shape():
    # a great circle is a geodesic: an equilibrium of the membrane snake (an unstable one,
    # as nearby small circles are shorter, so use single-resolution forces, which do not
    # amplify the polyhedral perturbations as the long coarse-level chords do)
    start = circle(0.0)
    res = relax_snake(SPHERE, start, SnakeOptions(levels=1, max_iter=2000))
    assert res.converged
    x = SPHERE.xyz(res.curve.points)
    assert abs(seg_lengths(SPHERE, res.curve).sum() / seg_lengths(SPHERE, start).sum() - 1) < 0.005
    assert np.abs(x[:, 2]).max() < 0.01


def test_coarse_to_fine_needs_fewer_iterations(fair_result):
    _, multi = fair_result
    single = relax_snake(SPHERE, zigzag_arc(), SnakeOptions(levels=1, max_iter=20_000))
    assert multi.converged and single.converged
    assert multi.iterations < 0.6 * single.iterations


def test_fixed_points_never_move():
    start = zigzag_arc()
    fixed = [0, 10, 20, len(start) - 1]
    res = relax_snake(SPHERE, start, SnakeOptions(max_iter=50), fixed=fixed)
    assert_array_equal(res.curve.points.face[fixed], start.points.face[fixed])
    assert_array_equal(res.curve.points.bary[fixed], start.points.bary[fixed])


@pytest.fixture(scope="module")
def great_arc():
    return relax_snake(SPHERE, zigzag_arc(angle=2.0, n=60), SnakeOptions(max_iter=20_000)).curve


def test_edit_moves_only_the_section(great_arc):
    n = len(great_arc)
    e, half = n // 2, n // 6
    res = edit_snake(SPHERE, great_arc, edit_index=e, section=half, force=[0, 0, 0.2])
    inside = np.zeros(n, bool)
    inside[e - half + 1 : e + half] = True
    assert_array_equal(res.curve.points.face[~inside], great_arc.points.face[~inside])
    assert_array_equal(res.curve.points.bary[~inside], great_arc.points.bary[~inside])
    x0, x1 = SPHERE.xyz(great_arc.points), SPHERE.xyz(res.curve.points)
    assert 0.15 < x1[e, 2] < 0.25  # pulled up by about the force
    moved = np.linalg.norm(x1 - x0, axis=1)
    assert (moved[inside] > 0).mean() > 0.9
    # the section is a smooth tent: heights fall off monotonically from the edit point
    z = x1[e - half : e + half + 1, 2]
    assert (np.diff(z[: half + 1]) > -1e-12).all() and (np.diff(z[half:]) < 1e-12).all()
    on_surface(SPHERE, res.curve)
    assert np.isfinite(x1).all()


def test_edit_toward_a_target(great_arc):
    n = len(great_arc)
    e = n // 2
    target = SPHERE.xyz(great_arc.points)[e] + [0, 0, 0.1]
    res = edit_snake(SPHERE, great_arc, edit_index=e, section=n // 5, target=target)
    xe = SPHERE.xyz(res.curve.points)[e]
    t = target / np.linalg.norm(target)
    assert np.linalg.norm(xe - t) < SPHERE.mean_edge_length


def test_external_force_array_pulls_the_curve(great_arc):
    ext = np.zeros((len(great_arc), 3))
    ext[:, 2] = 0.05
    res = relax_snake(SPHERE, great_arc, SnakeOptions(max_iter=300), external=ext)
    assert SPHERE.xyz(res.curve.points)[1:-1, 2].mean() > 0.02


def test_errors(great_arc):
    n = len(great_arc)
    nan = np.zeros((n, 3))
    nan[3, 1] = np.nan
    with pytest.raises(InputError, match="not finite at curve point 3"):
        relax_snake(SPHERE, great_arc, external=nan)
    with pytest.raises(InputError, match="not finite at curve point 3"):
        relax_snake(SPHERE, great_arc, external=lambda c: nan)
    with pytest.raises(InputError, match="shape"):
        relax_snake(SPHERE, great_arc, external=np.zeros((n - 1, 3)))
    with pytest.raises(InputError, match="out of range"):
        relax_snake(SPHERE, great_arc, fixed=[n])
    with pytest.raises(InputError, match="options must be SnakeOptions"):
        relax_snake(SPHERE, great_arc, {"max_iter": 5})
    with pytest.raises(InputError, match="options must be SnakeOptions"):
        edit_snake(SPHERE, great_arc, options={}, edit_index=5, section=3, force=[0, 0, 1])
    with pytest.raises(InputError, match="exactly one"):
        edit_snake(SPHERE, great_arc, edit_index=5, section=3)
    with pytest.raises(InputError, match="force is not finite"):
        edit_snake(SPHERE, great_arc, edit_index=5, section=3, force=[np.nan, 0, 0])
    with pytest.raises(InputError, match="edit_index"):
        edit_snake(SPHERE, great_arc, edit_index=n, section=3, force=[0, 0, 1])
    with pytest.raises(InputError, match="end of the curve"):
        edit_snake(SPHERE, great_arc, edit_index=0, section=3, force=[0, 0, 1])
    with pytest.raises(InputError, match="SurfaceCurve"):
        relax_snake(SPHERE, great_arc.points)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("w_fair", -0.1),
        ("w_curv", np.nan),
        ("w_arc", np.inf),
        ("w_fair", "heavy"),
        ("step", 0.0),
        ("step", -0.25),
        ("step", 1.5),
        ("tol_move", -1e-4),
        ("max_iter", -1),
        ("max_iter", 2.5),
        ("max_iter", True),
        ("levels", 0),
        ("levels", 1.0),
    ],
)
def test_options_refuse_nonsense(field, value):
    with pytest.raises(InputError, match=field):
        SnakeOptions(**{field: value})


def test_options_defaults_and_conversion():
    o = SnakeOptions()
    assert (o.w_fair, o.w_curv, o.w_arc, o.levels) == (1.0, 0.0, 1.0, None)
    assert (o.step, o.max_iter, o.tol_move) == (0.25, 5000, SNAKE_MOVE_TOL)
    o = SnakeOptions(w_fair=1, levels=np.int64(2), max_iter=np.int32(7))
    assert type(o.w_fair) is float and type(o.levels) is int and type(o.max_iter) is int
    with pytest.raises(AttributeError):
        o.step = 0.5  # type: ignore[misc]


def test_options_positional_or_keyword_and_default(great_arc):
    """``options`` as third argument, as keyword, or omitted (the defaults) is one call."""
    o = SnakeOptions(max_iter=30)
    a = relax_snake(SPHERE, great_arc, o)
    b = relax_snake(SPHERE, great_arc, options=o)
    assert_array_equal(a.curve.points.face, b.curve.points.face)
    assert_array_equal(a.curve.points.bary, b.curve.points.bary)
    d, e = relax_snake(SPHERE, great_arc), relax_snake(SPHERE, great_arc, SnakeOptions())
    assert_array_equal(d.curve.points.bary, e.curve.points.bary)
    assert_array_equal(d.max_move, e.max_move)
    n = len(great_arc)
    kw = dict(edit_index=n // 2, section=n // 6, force=[0, 0, 0.1])
    f = edit_snake(SPHERE, great_arc, SnakeOptions(), **kw)
    g = edit_snake(SPHERE, great_arc, **kw)
    assert_array_equal(f.curve.points.bary, g.curve.points.bary)
    assert_array_equal(f.max_move, g.max_move)


def test_converges_on_a_bumpy_scan():
    """Forces projected on the interpolated vertex normal's plane: no jitter at creases."""
    from meshfit.demo import demo_mesh

    mesh = demo_mesh(20_000)
    top, bottom = int(mesh.vertices[:, 2].argmax()), int(mesh.vertices[:, 2].argmin())
    curve = paint_curve(mesh, [top, bottom])
    res = relax_snake(mesh, curve, SnakeOptions(max_iter=5000))
    assert res.converged
    assert curve_length(mesh, res.curve) < curve_length(mesh, curve)
    on_surface(mesh, res.curve)


def test_points_on_vertices_keep_the_pair_rule():
    # a painted boundary curve of the nefertiti test layout passes through mesh vertices;
    # point 59 of curve 38 lies on a vertex, written in a face that shares no vertex with
    # point 58's face (the layout accepts the pair: some face around the vertex does). The
    # snake writes such points in a face around the vertex that keeps the pair rule, so it
    # guards those segments too (unguarded, 3 steps took point 59 to a face sharing nothing)
    from meshfit.layout import load_layout
    from meshfit.mesh import load_mesh

    from ..conftest import ROOT, mesh_path

    mesh = load_mesh(mesh_path("nefertiti"))
    curve = load_layout(ROOT / "examples" / "layouts" / "nefertiti.json", mesh).curves[38]
    assert not _pairs_ok(mesh.faces, curve.points.face, False).all()
    for steps in (1, 3, 5):
        opts = SnakeOptions(levels=1, max_iter=steps, tol_move=0.0)
        out = relax_snake(mesh, curve, opts).curve
        assert _pairs_ok(mesh.faces, out.points.face, False).all(), steps
        on_surface(mesh, out)
    # written in another face, the point is where it was
    res = relax_snake(mesh, curve, SnakeOptions(max_iter=0))
    assert_allclose(mesh.xyz(res.curve.points), mesh.xyz(curve.points), rtol=0, atol=1e-12)
