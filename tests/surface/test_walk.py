"""Walking face points (MovePointOnSurface), attraction (CurveAttract) and MovePointOnCurve."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import tol
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.surface import (
    attract_points,
    curve_arc_lengths,
    move_along_curve,
    random_surface_points,
    walk_points,
)
from meshfit.types import SurfaceCurve, SurfacePoints

from ..conftest import CLOSED_REAL, analytic_mesh, any_mesh, real_mesh
from ..reference import walk as reference

ANALYTIC = ("icosphere", "plane", "cylinder", "torus")
CLOSED_ANALYTIC = ("icosphere", "torus")


# ------------------------------------------------------------------------- helpers


def tangent_steps(
    mesh: Mesh, points: SurfacePoints, rng: np.random.Generator, lo: float, hi: float
) -> np.ndarray:
    """Random directions in each start face's plane, lengths uniform in [lo, hi] mean edges."""
    d = rng.normal(size=(len(points), 3))
    n = mesh.face_normals[points.face]
    d -= np.einsum("ij,ij->i", d, n)[:, None] * n
    d /= np.linalg.norm(d, axis=1)[:, None]
    return d * (rng.uniform(lo, hi, len(points)) * mesh.mean_edge_length)[:, None]


def projected_length(mesh: Mesh, points: SurfacePoints, step: np.ndarray) -> np.ndarray:
    n = mesh.face_normals[points.face]
    return np.linalg.norm(step - np.einsum("ij,ij->i", step, n)[:, None] * n, axis=1)


def on_boundary_edge(mesh: Mesh, points: SurfacePoints) -> np.ndarray:
    """(n,) bool: the point's coordinate opposite a boundary edge of its face is exactly 0."""
    out = np.zeros(len(points), dtype=bool)
    for k in range(3):
        out |= (mesh.face_neighbors[points.face, k] < 0) & (points.bary[:, (k + 2) % 3] == 0.0)
    return out


def assert_valid_points(mesh: Mesh, points: SurfacePoints) -> None:
    """Barycentrics >= 0 summing to 1, positions on the surface."""
    assert (points.bary >= 0.0).all()
    assert_allclose(points.bary.sum(axis=1), 1.0, rtol=0, atol=tol.BARY_EPS)
    assert ((points.face >= 0) & (points.face < mesh.n_faces)).all()
    gap = mesh.closest_points(mesh.xyz(points)).distance
    assert (gap <= tol.ON_SURFACE * mesh.bbox_diagonal).all()


def point_at(face: int, bary) -> SurfacePoints:
    return SurfacePoints(np.array([face]), np.array([bary], dtype=float))


# ------------------------------------------------------------------ walk vs oracle


@pytest.mark.parametrize("name", CLOSED_REAL + ANALYTIC)
def test_walk_matches_oracle(name, rng):
    mesh = any_mesh(name)
    start = random_surface_points(mesh, 150, rng)
    step = tangent_steps(mesh, start, rng, 0.5, 5.0)

    got = walk_points(mesh, start, step)
    want = reference.walk_points(mesh, start, step)

    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    assert_allclose(mesh.xyz(got.end), mesh.xyz(want.end), rtol=0, atol=atol)
    assert_allclose(got.length, want.length, rtol=0, atol=atol)
    assert_array_equal(got.hit_boundary, want.hit_boundary)
    assert not got.capped.any()
    assert_valid_points(mesh, got.end)
    if mesh.is_closed:  # closed: walks never stop early, so length == |projected step|
        assert not got.hit_boundary.any()
        assert_allclose(got.length, projected_length(mesh, start, step), rtol=1e-12)
    else:
        free = ~got.hit_boundary
        assert_allclose(
            got.length[free], projected_length(mesh, start[free], step[free]), rtol=1e-12
        )
        assert (got.length[~free] < projected_length(mesh, start[~free], step[~free])).all()
        assert on_boundary_edge(mesh, got.end[~free]).all()


@pytest.mark.parametrize("name", ["spot", "torus"])
def test_long_walks_match_oracle(name, rng):
    """Walks over ~20-60 mean edge lengths (hundreds of faces) stay on the oracle's path."""
    mesh = any_mesh(name)
    start = random_surface_points(mesh, 30, rng)
    step = tangent_steps(mesh, start, rng, 20.0, 60.0)
    got = walk_points(mesh, start, step)
    want = reference.walk_points(mesh, start, step)
    # rounding grows with the number of unfoldings; 1e-9 of the diagonal still holds
    assert_allclose(
        mesh.xyz(got.end), mesh.xyz(want.end), rtol=0, atol=tol.TEST_ATOL * mesh.bbox_diagonal
    )
    assert_allclose(got.length, projected_length(mesh, start, step), rtol=1e-12)


def test_plane_walk_is_straight_line_in_3d(rng):
    """On the flat unit square: start + step, or the first crossing of the square's border."""
    mesh = analytic_mesh("plane")
    start = random_surface_points(mesh, 400, rng)
    step = np.zeros((400, 3))
    step[:, :2] = rng.uniform(-0.6, 0.6, (400, 2))
    got = walk_points(mesh, start, step)
    p = mesh.xyz(start)[:, :2]
    d = step[:, :2]
    # parameter where the segment leaves [0, 1]^2
    with np.errstate(divide="ignore", invalid="ignore"):
        t_hi = np.where(d > 0, (1.0 - p) / d, np.where(d < 0, -p / d, np.inf))
    t = np.minimum(1.0, t_hi.min(axis=1))
    leaves = t_hi.min(axis=1) < 1.0
    want = np.zeros((400, 3))
    want[:, :2] = p + t[:, None] * d
    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    assert_allclose(mesh.xyz(got.end), want, rtol=0, atol=atol)
    assert_array_equal(got.hit_boundary, leaves)
    assert_allclose(got.length, t * np.linalg.norm(d, axis=1), rtol=0, atol=atol)
    assert leaves.any() and (~leaves).any()


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(0.0, 1.0),
    y=st.floats(0.0, 1.0),
    dx=st.floats(-0.3, 0.3),
    dy=st.floats(-0.3, 0.3),
    dz=st.floats(-1.0, 1.0),
)
def test_plane_walk_property(x, y, dx, dy, dz):
    """Any start, any step (normal part dropped) on the flat square gives the straight line.

    Steps within a relative 1e-6 of parallel to the square's sides (but not exactly
    parallel) are left out: from a point on the border, whether such a step runs along the
    border or leaves at once is decided at rounding level.
    """
    assume(all(c == 0.0 or abs(c) > 1e-6 * np.hypot(dx, dy) for c in (dx, dy)))
    mesh = analytic_mesh("plane")
    start = mesh.closest_points(np.array([[x, y, 0.0]])).points
    got = walk_points(mesh, start, np.array([[dx, dy, dz]]))
    p = mesh.xyz(start)[0, :2]
    d = np.array([dx, dy])
    t = 1.0
    if np.hypot(dx, dy) <= tol.WALK_EPS * mesh.mean_edge_length:  # too short to move
        t = 0.0
    for j in range(2):
        if d[j] > 0 and t > 0:
            t = min(t, (1.0 - p[j]) / d[j])
        elif d[j] < 0 and t > 0:
            t = min(t, -p[j] / d[j])
    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    assert_allclose(mesh.xyz(got.end)[0, :2], p + t * d, rtol=0, atol=atol)
    assert_allclose(mesh.xyz(got.end)[0, 2], 0.0, atol=atol)
    assert_allclose(got.length[0], t * np.hypot(dx, dy), rtol=0, atol=atol)
    assert got.end.bary.min() >= 0.0
    if got.hit_boundary[0]:
        assert on_boundary_edge(mesh, got.end)[0]


# ------------------------------------------------------------------------ boundary


def test_bunny_walks_into_holes_stop_on_the_boundary_edge(bunny):
    """From a boundary face's centroid straight at its boundary edge: the foot of the
    perpendicular, exactly on that edge."""
    mesh = bunny
    f, k = np.nonzero(mesh.face_neighbors < 0)
    V, F = mesh.vertices, mesh.faces
    a, c = V[F[f, k]], V[F[f, (k + 1) % 3]]
    g = V[F[f]].mean(axis=1)
    e = c - a
    mu = np.einsum("ij,ij->i", g - a, e) / np.einsum("ij,ij->i", e, e)
    keep = np.flatnonzero((mu > 0.05) & (mu < 0.95))[::2]
    f, k, a, e, mu, g = f[keep], k[keep], a[keep], e[keep], mu[keep], g[keep]
    foot = a + mu[:, None] * e
    out = foot - g
    dist = np.linalg.norm(out, axis=1)
    step = out / dist[:, None] * 3.0 * mesh.mean_edge_length
    start = SurfacePoints(f, np.full((f.size, 3), 1.0 / 3.0))

    got = walk_points(mesh, start, step)

    assert got.hit_boundary.all()
    assert_array_equal(got.end.face, f)
    assert (got.end.bary[np.arange(f.size), (k + 2) % 3] == 0.0).all()
    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    assert_allclose(mesh.xyz(got.end), foot, rtol=0, atol=atol)
    assert_allclose(got.length, dist, rtol=0, atol=atol)
    assert len(mesh.boundary_loops) == 5 and f.size > 50


def test_bunny_walks_toward_hole_centres_match_oracle(bunny, rng):
    """Starts around each of the bunny's holes, aimed at the hole's centre."""
    mesh = bunny
    indptr, vf = mesh.vertex_faces
    faces, targets = [], []
    for loop in mesh.boundary_loops:
        ring = np.unique(np.concatenate([vf[indptr[v] : indptr[v + 1]] for v in loop]))
        pick = rng.choice(ring, size=min(40, ring.size), replace=False)
        faces.append(pick)
        targets.append(np.repeat(mesh.vertices[loop].mean(axis=0)[None], pick.size, axis=0))
    face = np.concatenate(faces)
    r = rng.random((face.size, 3)) + 0.05
    start = SurfacePoints(face, r / r.sum(axis=1, keepdims=True))
    to = np.concatenate(targets) - mesh.xyz(start)
    step = to / np.linalg.norm(to, axis=1)[:, None] * 6.0 * mesh.mean_edge_length

    got = walk_points(mesh, start, step)
    want = reference.walk_points(mesh, start, step)

    assert_allclose(
        mesh.xyz(got.end), mesh.xyz(want.end), rtol=0, atol=tol.TEST_ATOL * mesh.bbox_diagonal
    )
    assert_array_equal(got.hit_boundary, want.hit_boundary)
    assert got.hit_boundary.mean() > 0.5
    assert on_boundary_edge(mesh, got.end[got.hit_boundary]).all()
    assert_valid_points(mesh, got.end)


# ------------------------------------------------------------------- degenerate use


def test_zero_steps_are_noops(spot, rng):
    start = random_surface_points(spot, 50, rng)
    got = walk_points(spot, start, np.zeros((50, 3)))
    assert_array_equal(got.end.face, start.face)
    assert_array_equal(got.end.bary, start.bary)
    assert (got.length == 0).all() and not got.hit_boundary.any() and not got.capped.any()
    normal_only = spot.face_normals[start.face] * spot.mean_edge_length
    got = walk_points(spot, start, normal_only)  # nothing left after projection
    assert_allclose(
        spot.xyz(got.end), spot.xyz(start), rtol=0, atol=tol.TEST_ATOL * spot.bbox_diagonal
    )


def test_normal_component_is_dropped(spot, rng):
    start = random_surface_points(spot, 50, rng)
    step = tangent_steps(spot, start, rng, 1.0, 3.0)
    tilted = step + rng.normal(size=(50, 1)) * spot.face_normals[start.face]
    a = walk_points(spot, start, step)
    b = walk_points(spot, start, tilted)
    assert_allclose(
        spot.xyz(a.end), spot.xyz(b.end), rtol=0, atol=tol.TEST_ATOL * spot.bbox_diagonal
    )


def test_single_step_vector_broadcasts(spot, rng):
    start = random_surface_points(spot, 5, rng)
    a = walk_points(spot, start, [0.01, 0.02, 0.0])
    b = walk_points(spot, start, np.tile([0.01, 0.02, 0.0], (5, 1)))
    assert_array_equal(a.end.bary, b.end.bary)


def test_iteration_cap_is_reported(spot, rng):
    start = random_surface_points(spot, 40, rng)
    step = tangent_steps(spot, start, rng, 10.0, 12.0)
    got = walk_points(spot, start, step, max_faces=3)
    want = reference.walk_points(spot, start, step, max_faces=3)
    assert got.capped.all()
    assert_array_equal(got.capped, want.capped)
    assert (got.length < projected_length(spot, start, step)).all()
    assert_allclose(
        spot.xyz(got.end), spot.xyz(want.end), rtol=0, atol=tol.TEST_ATOL * spot.bbox_diagonal
    )
    assert_valid_points(spot, got.end)


def test_empty_input(spot):
    got = walk_points(
        spot, SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3))), np.zeros((0, 3))
    )
    assert len(got.end) == 0 and got.length.shape == (0,)


@pytest.mark.parametrize("name", ["icosphere", "plane"])
def test_walks_through_vertices_never_lose_a_point(name, rng):
    """Steps aimed exactly at vertices, starting at vertices, and running along edges."""
    mesh = analytic_mesh(name)
    V, F = mesh.vertices, mesh.faces
    mel = mesh.mean_edge_length
    face = rng.integers(0, mesh.n_faces, 300)
    corner = rng.integers(0, 3, 300)
    r = rng.random((300, 3)) + 0.05
    # 1. from inside a face through one of its corners, 2 mean edges beyond
    inner = SurfacePoints(face, r / r.sum(axis=1, keepdims=True))
    to = V[F[face, corner]] - mesh.xyz(inner)
    through = to * (1.0 + 2.0 * mel / np.linalg.norm(to, axis=1))[:, None]
    # 2. from a corner, in a random in-plane direction
    at_vertex = SurfacePoints(face, np.eye(3)[corner])
    random_dir = tangent_steps(mesh, at_vertex, rng, 1.0, 3.0)
    # 3. from a corner along one of the face's edges, past its far end
    along = (V[F[face, (corner + 1) % 3]] - V[F[face, corner]]) * 2.5
    starts = SurfacePoints.concatenate([inner, at_vertex, at_vertex])
    steps = np.concatenate([through, random_dir, along])

    got = walk_points(mesh, starts, steps)

    assert not got.capped.any()
    assert_valid_points(mesh, got.end)
    want_len = projected_length(mesh, starts, steps)
    free = ~got.hit_boundary
    assert_allclose(got.length[free], want_len[free], rtol=1e-12)
    if mesh.is_closed:
        assert free.all()
    else:  # flat: whichever side of a vertex the walk passes, the 3-D line is the same
        x0 = mesh.xyz(starts)
        ok = free & (np.abs((x0 + steps)[:, :2] - 0.5) < 0.5).all(axis=1)
        assert ok.sum() > 300
        assert_allclose(
            mesh.xyz(got.end)[ok], (x0 + steps)[ok], rtol=0, atol=tol.TEST_ATOL * mesh.bbox_diagonal
        )


def test_walk_rejects_bad_input(spot):
    start = random_surface_points(spot, 4, 0)
    with pytest.raises(InputError, match="step must have 4 rows"):
        walk_points(spot, start, np.zeros((3, 3)))
    step = np.zeros((4, 3))
    step[2, 1] = np.nan
    with pytest.raises(InputError, match="row 2"):
        walk_points(spot, start, step)
    with pytest.raises(InputError, match=r"start\[1\] is on face"):
        walk_points(
            spot, SurfacePoints([0, spot.n_faces], np.full((2, 3), 1 / 3)), np.zeros((2, 3))
        )
    with pytest.raises(InputError, match="max_faces"):
        walk_points(spot, start, np.zeros((4, 3)), max_faces=0)
    with pytest.raises(InputError, match="SurfacePoints"):
        walk_points(spot, np.zeros((4, 3)), np.zeros((4, 3)))


# ---------------------------------------------------------------------- attraction


def test_attract_on_icosphere_reaches_global_closest_point(rng):
    """Convex mesh, targets outside it, starts on the same side: the local minimum the walk
    reaches is the global closest point (checked against a brute-force search)."""
    mesh = analytic_mesh("icosphere")
    direction = rng.normal(size=(60, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    targets = direction * rng.uniform(1.02, 1.6, (60, 1))
    # starts within ~50 degrees of the target direction
    pool = random_surface_points(mesh, 2000, rng)
    xyz = mesh.xyz(pool)
    starts = [int(np.flatnonzero(xyz @ d > 0.65)[0]) for d in direction]
    start = pool[np.array(starts)]

    got = attract_points(mesh, start, targets)

    want = [reference.closest_point_bruteforce(mesh, t) for t in targets]
    atol = 1e-8 * mesh.bbox_diagonal  # the walk stops within ATTRACT_EPS steps of the minimum
    assert_allclose(mesh.xyz(got.end), np.array([w[0] for w in want]), rtol=0, atol=atol)
    assert_allclose(got.distance, [w[1] for w in want], rtol=0, atol=atol)
    assert got.converged.all() and not got.hit_boundary.any()
    assert_valid_points(mesh, got.end)


@pytest.mark.parametrize("name", ["spot", "igea"])
def test_attract_surface_point_targets_come_back(name, rng):
    mesh = real_mesh(name)
    target = random_surface_points(mesh, 60, rng)
    start = walk_points(mesh, target, tangent_steps(mesh, target, rng, 0.5, 2.0)).end
    got = attract_points(mesh, start, mesh.xyz(target))
    assert got.converged.all()
    assert_allclose(
        mesh.xyz(got.end), mesh.xyz(target), rtol=0, atol=tol.TEST_ATOL * mesh.bbox_diagonal
    )
    assert (got.distance <= tol.TEST_ATOL * mesh.bbox_diagonal).all()
    same = attract_points(mesh, target, mesh.xyz(target))  # already there
    assert_array_equal(same.end.face, target.face)
    assert same.converged.all()


@pytest.mark.parametrize("name", ["spot", "nefertiti"])
def test_attract_ends_at_a_local_minimum(name, rng):
    """Targets off the surface: no small walk from the result gets closer to the target."""
    mesh = real_mesh(name)
    mel = mesh.mean_edge_length
    base = random_surface_points(mesh, 40, rng)
    targets = (
        mesh.xyz(base)
        + rng.uniform(-0.5, 0.5, (40, 1)) * mel * mesh.face_normals[base.face]
        + rng.normal(size=(40, 3)) * 0.2 * mel
    )
    start = walk_points(mesh, base, tangent_steps(mesh, base, rng, 1.0, 3.0)).end
    got = attract_points(mesh, start, targets)
    assert got.converged.all()
    assert_allclose(got.distance, np.linalg.norm(mesh.xyz(got.end) - targets, axis=1))
    for _ in range(8):
        probe = walk_points(mesh, got.end, tangent_steps(mesh, got.end, rng, 1e-4, 1e-3))
        d = np.linalg.norm(mesh.xyz(probe.end) - targets, axis=1)
        assert (d >= got.distance - 1e-13 * mesh.bbox_diagonal).all()


def test_attract_on_plane_is_the_analytic_projection(rng):
    mesh = analytic_mesh("plane")
    start = random_surface_points(mesh, 200, rng)
    targets = np.column_stack([rng.uniform(-0.4, 1.4, (200, 2)), rng.uniform(-1, 1, 200)])
    got = attract_points(mesh, start, targets)
    want = np.column_stack([np.clip(targets[:, :2], 0.0, 1.0), np.zeros(200)])
    assert_allclose(mesh.xyz(got.end), want, rtol=0, atol=tol.TEST_ATOL * mesh.bbox_diagonal)
    outside = (np.abs(targets[:, :2] - 0.5) > 0.5).any(axis=1)
    assert_array_equal(got.hit_boundary, outside)
    assert got.converged.all()
    assert outside.sum() > 50 and (~outside).sum() > 50


def test_attract_reports_iteration_cap(spot, rng):
    start = random_surface_points(spot, 20, rng)
    far = -spot.xyz(start)  # across the model: many steps needed
    got = attract_points(spot, start, far, max_iter=1)
    assert (got.iterations == 1).all()
    assert not got.converged.all()
    assert_valid_points(spot, got.end)


def test_attract_rejects_bad_input(spot):
    start = random_surface_points(spot, 3, 0)
    with pytest.raises(InputError, match="targets must have 3 rows"):
        attract_points(spot, start, np.zeros((2, 3)))
    with pytest.raises(InputError, match="row 0"):
        attract_points(spot, start, np.full((3, 3), np.inf))
    with pytest.raises(InputError, match="max_iter"):
        attract_points(spot, start, np.zeros((3, 3)), max_iter=0)


# --------------------------------------------------------------------------- curves


def face_walk_curve(mesh: Mesh, n: int, rng: np.random.Generator) -> SurfacePoints:
    """Random face points on a random walk over edge-adjacent faces."""
    face = [int(rng.integers(mesh.n_faces))]
    while len(face) < n:
        nb = mesh.face_neighbors[face[-1]]
        nb = nb[(nb >= 0) & ~np.isin(nb, face[-3:])]
        face.append(int(rng.choice(nb)) if nb.size else face[-1])
    r = rng.random((n, 3)) + 0.02
    return SurfacePoints(np.array(face), r / r.sum(axis=1, keepdims=True))


def vertex_fan_curve(mesh: Mesh, vertex: int, rng: np.random.Generator) -> SurfacePoints:
    """One random point in each face around an interior vertex, in cyclic order."""
    indptr, vf = mesh.vertex_faces
    fan = set(vf[indptr[vertex] : indptr[vertex + 1]].tolist())
    order = [min(fan)]
    while len(order) < len(fan):
        nxt = [g for g in mesh.face_neighbors[order[-1]] if g in fan and g not in order]
        order.append(nxt[0])
    r = rng.random((len(order), 3)) + 0.05
    return SurfacePoints(np.array(order), r / r.sum(axis=1, keepdims=True))


def reference_arc(mesh: Mesh, curve: SurfacePoints, closed: bool) -> np.ndarray:
    m = len(curve)
    seg = [
        reference.curve_length(
            mesh, (curve.face[i], curve.bary[i]), (curve.face[(i + 1) % m], curve.bary[(i + 1) % m])
        )
        for i in range(m if closed else m - 1)
    ]
    return np.concatenate([[0.0], np.cumsum(seg)])


@pytest.mark.parametrize("name", ["spot", "torus"])
def test_curve_arc_lengths_and_points_match_oracle(name, rng):
    mesh = any_mesh(name)
    curve = face_walk_curve(mesh, 60, rng)
    arc = curve_arc_lengths(mesh, curve)
    assert_allclose(arc, reference_arc(mesh, curve, False), rtol=1e-12)
    s = rng.uniform(0, arc[-1], 200)
    got = move_along_curve(mesh, curve, s, 0.0)
    want = []
    for si, seg in zip(s, got.segment, strict=True):
        p = (curve.face[seg], curve.bary[seg])
        q = (curve.face[seg + 1], curve.bary[seg + 1])
        want.append(reference.curve_point(mesh, p, q, si - arc[seg]))
    assert_allclose(
        mesh.xyz(got.points), np.array(want), rtol=0, atol=tol.TEST_ATOL * mesh.bbox_diagonal
    )
    assert ((arc[got.segment] <= s) & (s <= arc[got.segment + 1])).all()
    assert_valid_points(mesh, got.points)


def test_curve_segments_are_straight_walks(spot, rng):
    """Walking from point i toward i+1 (unfolded) by the segment's length lands on i+1."""
    curve = face_walk_curve(spot, 80, rng)
    arc = curve_arc_lengths(spot, curve)
    i = np.arange(len(curve) - 1)
    straight = np.array(
        [
            reference.curve_segment(
                spot, (curve.face[j], curve.bary[j]), (curve.face[j + 1], curve.bary[j + 1])
            )[3]
            for j in i
        ]
    )
    seg_len = np.diff(arc)
    i = i[straight & (seg_len > 1e-3 * spot.mean_edge_length)]
    near = move_along_curve(spot, curve, arc[i], 1e-3 * seg_len[i])  # a little way along
    direction = spot.xyz(near.points) - spot.xyz(curve[i])
    direction *= (seg_len[i] / np.linalg.norm(direction, axis=1))[:, None]
    walked = walk_points(spot, curve[i], direction)
    assert_allclose(
        spot.xyz(walked.end),
        spot.xyz(curve[i + 1]),
        rtol=0,
        atol=tol.TEST_ATOL * spot.bbox_diagonal,
    )
    assert (~straight).any() and i.size > 40  # both kinds of segment occur


def test_move_along_curve_preserves_arc_length(spot, rng):
    curve = face_walk_curve(spot, 40, rng)
    arc = curve_arc_lengths(spot, curve)
    s = rng.uniform(0.3, 0.7, 100) * arc[-1]
    d = rng.uniform(-0.3, 0.3, 100) * arc[-1]
    there = move_along_curve(spot, curve, s, d)
    assert_allclose(there.position, s + d)
    assert not there.clamped.any()
    back = move_along_curve(spot, curve, there.position, -d)
    assert_allclose(back.position, s, rtol=0, atol=1e-12 * arc[-1])
    direct = move_along_curve(spot, curve, s, 0.0)
    assert_allclose(
        spot.xyz(back.points),
        spot.xyz(direct.points),
        rtol=0,
        atol=tol.TEST_ATOL * spot.bbox_diagonal,
    )


def test_move_along_open_curve_clamps_at_the_ends(spot, rng):
    curve = face_walk_curve(spot, 20, rng)
    arc = curve_arc_lengths(spot, curve)
    got = move_along_curve(
        spot, curve, [0.5 * arc[-1], 0.5 * arc[-1], arc[-1], 0.0], [arc[-1], -arc[-1], 0.0, 0.0]
    )
    assert_array_equal(got.clamped, [True, True, False, False])
    assert_array_equal(got.position, [arc[-1], 0.0, arc[-1], 0.0])
    assert_array_equal(got.points.face, curve.face[[-1, 0, -1, 0]])
    assert_array_equal(got.points.bary, curve.bary[[-1, 0, -1, 0]])
    assert_array_equal(got.segment, [18, 0, 18, 0])


def test_move_along_curve_lands_exactly_on_curve_points(spot, rng):
    curve = face_walk_curve(spot, 30, rng)
    arc = curve_arc_lengths(spot, curve)
    got = move_along_curve(spot, curve, arc, 0.0)
    assert_array_equal(got.points.face, curve.face)
    assert_array_equal(got.points.bary, curve.bary)
    # approaching a curve point from below converges onto it (fraction -> 1)
    below = move_along_curve(spot, curve, arc[1:] * (1 - 1e-15), 0.0)
    assert_allclose(
        spot.xyz(below.points), spot.xyz(curve[1:]), rtol=0, atol=tol.TEST_ATOL * spot.bbox_diagonal
    )


def test_move_along_closed_curve_wraps(spot, rng):
    vertex = int(spot.faces[100, 0])
    curve = SurfaceCurve(vertex_fan_curve(spot, vertex, rng), closed=True)
    m = len(curve)
    arc = curve_arc_lengths(spot, curve)
    assert arc.shape == (m + 1,)
    assert_allclose(arc, reference_arc(spot, curve.points, True), rtol=1e-12)
    total = arc[-1]
    got = move_along_curve(
        spot, curve, [total - 0.1 * total, 0.2 * total, 0.0], [0.3 * total, -0.5 * total, 3 * total]
    )
    assert_allclose(got.position, [0.2 * total, 0.7 * total, 0.0], rtol=0, atol=1e-12 * total)
    assert not got.clamped.any()
    direct = move_along_curve(spot, curve, got.position, 0.0)
    assert_allclose(
        spot.xyz(got.points),
        spot.xyz(direct.points),
        rtol=0,
        atol=tol.TEST_ATOL * spot.bbox_diagonal,
    )
    last = move_along_curve(spot, curve, arc[m - 1] + 0.5 * (total - arc[m - 1]), 0.0)
    assert last.segment[0] == m - 1  # the closing segment runs from point m - 1 to point 0
    with pytest.raises(InputError, match="contradicts"):
        curve_arc_lengths(spot, curve, closed=False)


def test_curve_through_a_vertex_shared_by_non_adjacent_faces(spot):
    """A curve point at a vertex may be stored in any face of the vertex's fan."""
    v = int(spot.faces[7, 0])
    indptr, vf = spot.vertex_faces
    fan = vf[indptr[v] : indptr[v + 1]]
    far = next(g for g in fan if g != 7 and g not in spot.face_neighbors[7])
    at_v = point_at(7, [1.0, 0.0, 0.0])
    inside = point_at(int(far), [1 / 3, 1 / 3, 1 / 3])
    curve = SurfacePoints.concatenate([at_v, inside])
    arc = curve_arc_lengths(spot, curve)
    assert_allclose(arc[-1], np.linalg.norm(spot.xyz(inside) - spot.vertices[v]))
    # an interior point of face 7: the segment is routed through the shared vertex
    p = point_at(7, [0.2, 0.3, 0.5])
    arc = curve_arc_lengths(spot, SurfacePoints.concatenate([p, inside]))
    via = np.linalg.norm(spot.xyz(p) - spot.vertices[v])
    assert_allclose(arc[-1], via + np.linalg.norm(spot.xyz(inside) - spot.vertices[v]))
    half = move_along_curve(spot, SurfacePoints.concatenate([p, inside]), [via], [0.0])
    assert_allclose(
        spot.xyz(half.points), spot.vertices[v][None], atol=tol.TEST_ATOL * spot.bbox_diagonal
    )
    far_away = int(np.argmax(np.linalg.norm(spot.vertices - spot.vertices[v], axis=1)))
    with pytest.raises(InputError, match="neither the same, adjacent nor sharing a vertex"):
        curve_arc_lengths(
            spot, SurfacePoints.concatenate([p, SurfacePoints.at_vertices(spot.faces, [far_away])])
        )


def test_move_along_curve_rejects_bad_input(spot, rng):
    curve = face_walk_curve(spot, 5, rng)
    arc = curve_arc_lengths(spot, curve)
    with pytest.raises(InputError, match="outside the curve"):
        move_along_curve(spot, curve, [arc[-1] * 1.5], [0.0])
    with pytest.raises(InputError, match=r"distance must have shape \(2,\)"):
        move_along_curve(spot, curve, [0.0, 0.1], [0.0, 0.1, 0.2])
    with pytest.raises(InputError, match=r"position\[1\] is not finite"):
        move_along_curve(spot, curve, [0.0, np.nan], 0.0)
    with pytest.raises(InputError, match="no points"):
        curve_arc_lengths(spot, SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3))))


def test_walk_kernel_does_not_divide_by_zero_in_a_zero_area_face():
    """A sliver left by cutting (collinear corners) must not raise inside the kernel."""
    from meshfit._kernels import walk as kernels

    V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0]])
    F = np.array([[0, 1, 2], [0, 3, 1]], dtype=np.int64)  # face 0 has zero area
    FN = np.array([[1, -1, -1], [-1, -1, 0]], dtype=np.int64)
    face = np.array([0], dtype=np.int64)
    bary = np.array([[0.25, 0.5, 0.25]])
    step = np.array([[0.0, 0.1, 0.0]])
    _, out_bary, *_ = kernels.walk_points(V, F, FN, face, bary, step, 100, 1e-12, 1e-12)
    assert np.isfinite(out_bary).all()
    assert_allclose(out_bary.sum(axis=1), 1.0)


@pytest.mark.parametrize("name", ["spot", "igea"])
def test_attraction_cutting_hopeless_walks_short_changes_nothing(name):
    """Attraction gives up a walking step once it cannot end closer than the point already
    is; the result is the same as following every step to its end."""
    from meshfit.surface import greedy_path, path_to_surface_points
    from tests.reference import curves as ref_curves

    mesh = real_mesh(name)
    v = mesh.vertices
    a, b = int(np.argmin(v[:, 1])), int(np.argmax(v[:, 0]))
    pts = path_to_surface_points(mesh, greedy_path(mesh, a, b).vertices, per_edge=1)
    pts = pts[:: max(1, len(pts) // 120)]
    x = mesh.xyz(pts)
    t = np.linspace(0.0, 1.0, len(pts))[:, None]
    targets = x[0] + t * (x[-1] - x[0])  # far under the surface: long, rejected steps
    got = attract_points(mesh, pts, targets)
    for i in range(len(pts)):
        f, bary, dist, it = ref_curves.attract_uncut(mesh, pts.face[i], pts.bary[i], targets[i])
        assert got.end.face[i] == f
        assert_array_equal(got.end.bary[i], bary)
        assert got.distance[i] == dist
        assert got.iterations[i] == it


@pytest.mark.parametrize("name", ["spot", "bunny", "plane"])
def test_move_in_face_is_the_walk_when_it_stays_in_its_face(name, rng):
    """`_move_in_face` (the spring relaxation's short cut) gives the walk's barycentrics bit
    for bit when the walk ends in its start face, and declines every other walk."""
    from meshfit._kernels import walk as kernels

    mesh = any_mesh(name)
    V, F, FN = mesh.vertices, mesh.faces, mesh.face_neighbors
    start = random_surface_points(mesh, 400, rng)
    bary = start.bary.copy()
    bary[:100, 0] = 0.0  # on an edge, and (next) on a vertex: the walk's edge cases
    bary[50:100, 1] = 0.0
    bary[:100] /= bary[:100].sum(axis=1)[:, None]
    step = tangent_steps(mesh, start, rng, 0.01, 1.0)
    stayed = declined = 0
    for i in range(len(start)):
        f = int(start.face[i])
        u = np.empty(3)
        length = kernels._start_direction(V, F, f, step[i], u)
        ok, *b = kernels._move_in_face(V, F, f, *bary[i], *u, length, tol.BARY_EPS)
        walked = bary[i].copy()
        g, rest, status, crossed = kernels._walk_one(
            V, F, FN, f, walked, u, length, 100, tol.BARY_EPS
        )
        if ok:
            stayed += 1
            assert (g, rest, status, crossed) == (f, 0.0, kernels.DONE, 0)
            assert_array_equal(np.array(b), walked)
        else:
            declined += 1
            assert crossed > 0 or status != kernels.DONE
    assert stayed > 50 and declined > 50  # both branches taken
