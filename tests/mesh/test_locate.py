"""Closest points, first ray hits and barycentric coordinates, against analytic answers on the
icosphere and brute force over every face of spot."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import errors, tol
from meshfit.mesh import closest_points, ray_first_hit
from meshfit.mesh.locate import barycentric
from meshfit.surface import random_surface_points
from meshfit.types import SurfacePoints

from .. import shapes
from ..conftest import analytic_mesh, real_mesh


# ------------------------------------------------------------------ oracles (slow, obvious)
def closest_on_triangles(p, a, b, c):
    """Closest point to ``p (3,)`` on each triangle ``a, b, c (m, 3)`` (Ericson, RTCD 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    out = np.empty_like(a)
    done = np.zeros(a.shape[0], dtype=bool)

    def put(mask, value):
        m = mask & ~done
        out[m] = value[m]
        done[m] = True

    with np.errstate(divide="ignore", invalid="ignore"):
        put((d1 <= 0) & (d2 <= 0), a)
        put((d3 >= 0) & (d4 <= d3), b)
        put((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[:, None] * ab)
        put((d6 >= 0) & (d5 <= d6), c)
        put((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[:, None] * ac)
        put(
            (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),
            b + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (c - b),
        )
        denom = 1.0 / (va + vb + vc)
        put(np.ones_like(done), a + (vb * denom)[:, None] * ab + (vc * denom)[:, None] * ac)
    return out


def brute_closest(mesh, q):
    p = mesh.vertices[mesh.faces]
    dist = np.empty(q.shape[0])
    face = np.empty(q.shape[0], dtype=np.int64)
    xyz = np.empty_like(q)
    for i, x in enumerate(q):
        c = closest_on_triangles(x, p[:, 0], p[:, 1], p[:, 2])
        d = np.linalg.norm(c - x, axis=1)
        face[i] = int(np.argmin(d))
        dist[i], xyz[i] = d[face[i]], c[face[i]]
    return dist, face, xyz


def brute_first_hit(mesh, o, d):
    """Moeller-Trumbore over all faces: smallest t >= 0 per ray (inf when none)."""
    p = mesh.vertices[mesh.faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    t_best = np.full(o.shape[0], np.inf)
    for i in range(o.shape[0]):
        h = np.cross(d[i], e2)
        det = (e1 * h).sum(1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = o[i] - p[:, 0]
            u = inv * (s * h).sum(1)
            qv = np.cross(s, e1)
            v = inv * (qv @ d[i])
            t = inv * (e2 * qv).sum(1)
        ok = (np.abs(det) > 1e-300) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0)
        if ok.any():
            t_best[i] = t[ok].min()
    return t_best


def unit(rng, n):
    x = rng.normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


# ------------------------------------------------------------------------ closest points
def test_closest_points_on_icosphere_match_the_sphere(rng):
    mesh = analytic_mesh("icosphere")  # radius 1, 1280 faces
    # the polyhedron lies between the sphere and the sphere shrunk to the smallest
    # face-plane distance d_min: every distance is within 1 - d_min of the sphere's
    d_min = np.abs(np.einsum("ij,ij->i", mesh.face_normals, mesh.vertices[mesh.faces[:, 0]])).min()
    gap = 1.0 - d_min
    u = unit(rng, 300)
    s = rng.uniform(0.3, 2.5, size=(300, 1))
    q = u * s
    got = closest_points(mesh, q)
    assert_allclose(got.distance, np.abs(s[:, 0] - 1.0), atol=gap)
    # the closest point is near the radial projection and on the returned face
    assert_allclose(got.xyz, u, atol=np.sqrt(2 * gap) + gap)
    assert_allclose(got.xyz, mesh.xyz(got.points), atol=tol.TEST_ATOL * mesh.bbox_diagonal)
    assert_allclose(
        np.linalg.norm(got.xyz - q, axis=1), got.distance, atol=tol.TEST_ATOL * mesh.bbox_diagonal
    )


def test_closest_points_of_surface_points_are_themselves(rng):
    mesh = analytic_mesh("icosphere")
    sp = random_surface_points(mesh, 200, rng)
    got = closest_points(mesh, mesh.xyz(sp))
    assert_allclose(got.distance, 0.0, atol=tol.ON_SURFACE * mesh.bbox_diagonal)
    assert_allclose(got.xyz, mesh.xyz(sp), atol=tol.TEST_ATOL * mesh.bbox_diagonal)


def test_closest_points_against_brute_force_on_spot(spot, rng):
    lo, hi = spot.bbox
    q = rng.uniform(lo - 0.2, hi + 0.2, size=(60, 3))
    got = closest_points(spot, q)
    dist, face, xyz = brute_closest(spot, q)
    atol = tol.TEST_ATOL * spot.bbox_diagonal
    assert_allclose(got.distance, dist, atol=atol)
    assert_allclose(got.xyz, xyz, atol=1e-7 * spot.bbox_diagonal)  # unique nearest points
    assert_allclose(spot.xyz(got.points), got.xyz, atol=atol)
    # the returned face is a closest face (ties only where faces meet)
    p = spot.vertices[spot.faces[got.points.face]]
    on_face = np.array(
        [
            closest_on_triangles(x, a[None], b[None], c[None])[0]
            for x, a, b, c in zip(q, p[:, 0], p[:, 1], p[:, 2], strict=True)
        ]
    )
    assert_allclose(np.linalg.norm(on_face - q, axis=1), dist, atol=atol)
    assert (face >= 0).all()


def test_closest_points_bary_valid(spot, rng):
    q = rng.normal(size=(100, 3))
    got = closest_points(spot, q).points
    assert isinstance(got, SurfacePoints)
    assert_allclose(got.bary.sum(axis=1), 1.0, atol=1e-12)
    assert (got.bary >= 0).all()
    assert ((got.face >= 0) & (got.face < spot.n_faces)).all()


def test_closest_points_shapes_and_errors(spot):
    one = closest_points(spot, [0.0, 0.0, 0.0])  # a single (3,) point becomes (1, 3)
    assert one.xyz.shape == (1, 3)
    assert one.distance.shape == (1,)
    none = closest_points(spot, np.zeros((0, 3)))
    assert len(none.points) == 0
    assert none.xyz.shape == (0, 3)
    with pytest.raises(errors.InputError, match="row 1"):
        closest_points(spot, [[0, 0, 0], [np.nan, 0, 0]])
    with pytest.raises(errors.InputError, match=r"shape \(n, 3\)"):
        closest_points(spot, np.zeros((4, 2)))
    # the method on Mesh delegates
    assert_array_equal(
        spot.closest_points([[0.1, 0.2, 0.3]]).points.face,
        closest_points(spot, [[0.1, 0.2, 0.3]]).points.face,
    )


# ---------------------------------------------------------------------------- ray hits
def test_rays_into_the_icosphere_hit_its_near_side(rng):
    mesh = analytic_mesh("icosphere")
    u = unit(rng, 200)
    origins = 3.0 * u
    hits = ray_first_hit(mesh, origins, -u)  # unit directions towards the centre
    assert hits.hit.all()
    # the first hit is on the near side: t is 3 minus the hit's distance from the centre
    xyz = mesh.xyz(hits.points)
    assert_allclose(hits.t, 3.0 - np.linalg.norm(xyz, axis=1), atol=1e-12)
    assert ((hits.t >= 2.0) & (hits.t <= 2.0 + 0.01)).all()
    assert_allclose(xyz, origins + hits.t[:, None] * -u, atol=tol.TEST_ATOL * mesh.bbox_diagonal)
    assert_allclose(hits.bary.sum(axis=1), 1.0, atol=1e-12)
    assert (hits.bary >= 0).all()


def test_rays_pointing_away_miss():
    mesh = analytic_mesh("icosphere")
    rng = np.random.default_rng(3)
    u = unit(rng, 50)
    hits = ray_first_hit(mesh, 3.0 * u, u)  # origin outside, pointing away
    assert not hits.hit.any()
    assert np.isinf(hits.t).all()
    assert_array_equal(hits.face, -1)
    assert_array_equal(hits.bary, 0.0)
    assert len(hits.points) == 0


def test_rays_from_inside_hit_once_at_radius_one():
    mesh = analytic_mesh("icosphere")
    rng = np.random.default_rng(4)
    u = unit(rng, 100)
    hits = ray_first_hit(mesh, np.zeros((100, 3)), 2.0 * u)  # directions of length 2
    assert hits.hit.all()
    # t is in units of |direction|: the hit is at distance 2 t, just inside the unit sphere
    assert ((2.0 * hits.t > 0.99) & (2.0 * hits.t <= 1.0 + 1e-12)).all()
    assert_allclose(mesh.xyz(hits.points), 2.0 * hits.t[:, None] * u, atol=1e-12)


def test_ray_hits_against_brute_force_on_spot(spot, rng):
    lo, hi = spot.bbox
    n = 80
    origins = rng.uniform(lo, hi, size=(n, 3))
    directions = unit(rng, n) * rng.uniform(0.5, 2.0, size=(n, 1))
    hits = ray_first_hit(spot, origins, directions)
    want = brute_first_hit(spot, origins, directions)
    assert_array_equal(hits.hit, np.isfinite(want))
    assert 0 < hits.hit.sum() < n  # both hits and misses occur
    assert_allclose(hits.t[hits.hit], want[hits.hit], rtol=1e-9)
    xyz = spot.xyz(hits.points)
    on_ray = origins[hits.hit] + hits.t[hits.hit, None] * directions[hits.hit]
    assert_allclose(xyz, on_ray, atol=tol.TEST_ATOL * spot.bbox_diagonal)
    assert_allclose(hits.bary[hits.hit].sum(axis=1), 1.0, atol=1e-12)


def test_ray_direction_broadcasts_and_is_checked(spot):
    o = np.array([[0.0, 0.0, 5.0], [0.1, 0.0, 5.0]])
    hits = ray_first_hit(spot, o, [0.0, 0.0, -1.0])
    assert hits.hit.shape == (2,)
    with pytest.raises(errors.InputError, match="directions must have 2 rows"):
        ray_first_hit(spot, o, np.zeros((3, 3)))
    empty = ray_first_hit(spot, np.zeros((0, 3)), np.zeros((0, 3)))
    assert empty.hit.shape == (0,)
    assert_array_equal(spot.ray_first_hit(o, [0.0, 0.0, -1.0]).t, hits.t)


# ------------------------------------------------------------------------- barycentric
@pytest.mark.parametrize("name", ["spot", "torus", "plane"])
def test_barycentric_round_trip(name, rng):
    mesh = real_mesh(name) if name == "spot" else analytic_mesh(name)
    face = rng.integers(0, mesh.n_faces, size=500)
    bary = rng.dirichlet([1.0, 1.0, 1.0], size=500)
    xyz = mesh.xyz(SurfacePoints(face, bary))
    assert_allclose(barycentric(mesh, face, xyz), bary, atol=1e-9)


def test_barycentric_projects_and_extrapolates():
    mesh = shapes.plane(4)
    face = np.array([0, 0])
    p = mesh.vertices[mesh.faces[0]]
    # off the plane (projected) and outside the triangle (negative coordinate, not clipped)
    q = np.array([p.mean(axis=0) + np.array([0, 0, 0.7]), p[0] + 2.0 * (p[1] - p[0])])
    b = barycentric(mesh, face, q)
    assert_allclose(b[0], [1 / 3, 1 / 3, 1 / 3], atol=1e-12)
    assert_allclose(b[1], [-1.0, 2.0, 0.0], atol=1e-12)
    assert_allclose(b.sum(axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4])
def test_rays_hit_whatever_the_model_scale(scale, rng):
    """libigl's ray-triangle test has an absolute epsilon: tiny faces must still be hit."""
    from meshfit.mesh import Mesh

    ico = shapes.icosphere(5)  # 20,480 faces
    mesh = Mesh(ico.vertices * scale, ico.faces)
    d = rng.normal(size=(500, 3)) * scale
    hits = ray_first_hit(mesh, np.zeros((500, 3)), d)
    assert hits.hit.all()
    radius = np.linalg.norm(hits.t[:, None] * d, axis=1)
    assert_allclose(radius, scale, rtol=1e-3)  # inside the sphere, on the chords of its faces


def test_rays_from_the_centre_of_igea_hit():
    mesh = real_mesh("igea")
    d = np.random.default_rng(0).normal(size=(300, 3))
    hits = ray_first_hit(mesh, np.repeat(mesh.vertices.mean(0)[None], 300, 0), d)
    assert hits.hit.mean() > 0.99


def test_a_ray_tree_alive_at_exit_is_freed_before_libigl_is_torn_down():
    # a mesh whose igl.AABB tree outlives the main thread (held by a daemon thread, as the web
    # app's session is) made nanobind report the tree as leaked at interpreter exit
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent(
        """
        import threading, time
        import numpy as np
        from meshfit.mesh import Mesh
        V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
        F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        m = Mesh(V, F)
        hit = m.ray_first_hit(np.array([[0.2, 0.2, 5.0]]), np.array([[0, 0, -1.0]]))
        assert hit.face[0] >= 0
        threading.Thread(target=lambda mesh: time.sleep(60), args=(m,), daemon=True).start()
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert "leaked" not in out.stderr, out.stderr


def test_triangle_distances_are_the_same_in_any_query_order(spot, rng):
    """`query_order` is only a speed-up: any permutation of the queries gives the same
    distances, and anything but a permutation of the points' indices is refused (the
    kernel indexes with it)."""
    from meshfit.mesh.locate import query_order, triangle_distances

    Q = spot.vertices + rng.normal(scale=1e-2 * spot.bbox_diagonal, size=spot.vertices.shape)
    d0, _ = triangle_distances(Q, spot.vertices, spot.faces)
    for order in (query_order(Q), rng.permutation(len(Q)), np.arange(len(Q))[::-1]):
        d, _ = triangle_distances(Q, spot.vertices, spot.faces, qorder=order)
        assert_array_equal(d, d0)  # (a tie may name another triangle: f is not compared)
    assert sorted(query_order(Q).tolist()) == list(range(len(Q)))
    bad = query_order(Q)
    bad[bad == 0] = -1  # every other index once: still not a permutation
    for order in (np.arange(len(Q) - 1), bad, np.zeros(len(Q), dtype=np.int64), Q[:, 0]):
        with pytest.raises(errors.InputError, match="qorder must be a permutation"):
            triangle_distances(Q, spot.vertices, spot.faces, qorder=order)
