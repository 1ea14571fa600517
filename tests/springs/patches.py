"""Synthetic four-sided patches with known spring meshes: plane, quarter cylinder, sphere cap."""

from __future__ import annotations

import numpy as np

from meshfit.layout.patch import Patch
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints


def _grid_faces(n: int, m: int, rng) -> np.ndarray:
    idx = np.arange((n + 1) * (m + 1)).reshape(n + 1, m + 1)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[1:, :-1].ravel(),
        idx[1:, 1:].ravel(),
        idx[:-1, 1:].ravel(),
    )
    flip = rng.random(a.size) < 0.5
    f1 = np.where(flip[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    f2 = np.where(flip[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    return np.concatenate([f1, f2])


def param_patch(fn, n: int = 24, m: int = 24, *, jitter: float = 0.25, seed: int = 0) -> Patch:
    """Patch of the map ``fn(s, t) -> (k, 3)`` over ``[0, 1]^2``, triangulated irregularly.

    Corner 0 is (0, 0), corner 1 (1, 0), corner 2 (1, 1), corner 3 (0, 1); the map must be
    oriented so that (dS/ds) x (dS/dt) is the outward normal.
    """
    rng = np.random.default_rng(seed)
    s, t = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, m + 1), indexing="ij")
    inner = (s > 0) & (s < 1) & (t > 0) & (t < 1)
    s = s + np.where(inner, rng.uniform(-jitter / n, jitter / n, s.shape), 0)
    t = t + np.where(inner, rng.uniform(-jitter / m, jitter / m, t.shape), 0)
    verts = fn(s.ravel(), t.ravel())
    mesh = Mesh(verts, _grid_faces(n, m, rng), name="param_patch")
    idx = np.arange((n + 1) * (m + 1)).reshape(n + 1, m + 1)
    corners = np.array([idx[0, 0], idx[-1, 0], idx[-1, -1], idx[0, -1]])
    sides = (idx[:, 0], idx[-1, :], idx[::-1, -1], idx[0, ::-1])
    vs = SurfacePoints(*_vertex_points(mesh))
    return Patch(0, mesh, corners, sides, np.arange(mesh.n_faces), vs)


def _vertex_points(mesh: Mesh):
    indptr, vf = mesh.vertex_faces
    face = vf[indptr[:-1]]
    bary = (mesh.faces[face] == np.arange(mesh.n_vertices)[:, None]).astype(float)
    return face, bary


def plane_map(width: float = 2.0, height: float = 1.0):
    def fn(s, t):
        return np.stack([width * s, height * t, np.zeros_like(s)], axis=1)

    return fn


def cylinder_map(radius: float = 1.0, height: float = 1.5, angle: float = np.pi / 2):
    """Quarter cylinder about z; s runs around (outward normal), t along the axis."""

    def fn(s, t):
        a = angle * s
        return np.stack([radius * np.cos(a), radius * np.sin(a), height * t], axis=1)

    return fn


def cap_map(radius: float = 1.0, half: float = 0.6):
    """A quad on a sphere: the gnomonic square [-half, half]^2 projected onto the sphere."""

    def fn(s, t):
        x = (2 * s - 1) * half
        y = (2 * t - 1) * half
        p = np.stack([x, y, np.ones_like(x)], axis=1)
        return radius * p / np.linalg.norm(p, axis=1, keepdims=True)

    return fn


def with_features(patch: Patch, fn, us=(), vs=(), n: int = 400) -> Patch:
    """The patch with feature curves ``s = c`` (for c in us) and ``t = c`` (for c in vs),
    painted as dense face-point polylines found by closest points."""
    from meshfit.surface import closest_surface_points

    feats, fsides = [], []
    r = np.linspace(0.0, 1.0, n)
    for c in us:
        pts = closest_surface_points(patch.mesh, fn(np.full(n, c), r))
        feats.append(SurfaceCurve(pts, closed=False, kind="feature"))
        fsides.append((0, 2))
    for c in vs:
        pts = closest_surface_points(patch.mesh, fn(r[::-1], np.full(n, c)))
        feats.append(SurfaceCurve(pts, closed=False, kind="feature"))
        fsides.append((1, 3))
    return Patch(
        patch.index,
        patch.mesh,
        patch.corners,
        patch.sides,
        patch.face_parent,
        patch.vertex_source,
        tuple(feats),
        tuple(fsides),
    )
