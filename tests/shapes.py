"""Analytic test shapes with known answers (sphere, plane, cylinder, torus)."""

from __future__ import annotations

import numpy as np

from meshfit.mesh import Mesh


def icosphere(subdivisions: int = 3, radius: float = 1.0) -> Mesh:
    """Closed genus-0 sphere of ``20 * 4**subdivisions`` faces."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return Mesh(np.asarray(s.vertices), np.asarray(s.faces), name=f"icosphere{subdivisions}")


def plane(n: int = 20, size: float = 1.0, *, jitter: float = 0.3, seed: int = 0) -> Mesh:
    """Irregularly triangulated flat square ``[0, size]^2`` in z = 0 (a disk, one boundary loop)."""
    rng = np.random.default_rng(seed)
    h = size / n
    u, v = np.meshgrid(np.arange(n + 1) * h, np.arange(n + 1) * h, indexing="ij")
    xy = np.stack([u.ravel(), v.ravel()], axis=1)
    inner = ((u > 0) & (u < size - 1e-12) & (v > 0) & (v < size - 1e-12)).ravel()
    xy[inner] += rng.uniform(-jitter * h, jitter * h, size=(int(inner.sum()), 2))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[1:, :-1].ravel(),
        idx[1:, 1:].ravel(),
        idx[:-1, 1:].ravel(),
    )
    flip = rng.random(a.size) < 0.5
    f1 = np.where(flip[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    f2 = np.where(flip[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    faces = np.concatenate([f1, f2])
    verts = np.concatenate([xy, np.zeros((xy.shape[0], 1))], axis=1)
    return Mesh(verts, faces, name=f"plane{n}")


def cylinder(
    n_around: int = 32, n_along: int = 16, radius: float = 1.0, height: float = 2.0
) -> Mesh:
    """Open tube (two boundary loops), axis z, outward normals."""
    t = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    z = np.linspace(0, height, n_along + 1)
    T, Z = np.meshgrid(t, z, indexing="ij")
    verts = np.stack([radius * np.cos(T).ravel(), radius * np.sin(T).ravel(), Z.ravel()], axis=1)
    idx = np.arange(n_around * (n_along + 1)).reshape(n_around, n_along + 1)
    nxt = np.roll(idx, -1, axis=0)
    a, b, c, d = idx[:, :-1].ravel(), nxt[:, :-1].ravel(), nxt[:, 1:].ravel(), idx[:, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return Mesh(verts, faces, name="cylinder")


def torus(n_major: int = 48, n_minor: int = 24, major: float = 1.0, minor: float = 0.35) -> Mesh:
    """Closed genus-1 torus."""
    u = np.linspace(0, 2 * np.pi, n_major, endpoint=False)
    v = np.linspace(0, 2 * np.pi, n_minor, endpoint=False)
    U, V = np.meshgrid(u, v, indexing="ij")
    r = major + minor * np.cos(V)
    verts = np.stack(
        [(r * np.cos(U)).ravel(), (r * np.sin(U)).ravel(), (minor * np.sin(V)).ravel()], 1
    )
    idx = np.arange(n_major * n_minor).reshape(n_major, n_minor)
    nu = np.roll(idx, -1, axis=0)
    nv = np.roll(idx, -1, axis=1)
    nuv = np.roll(nu, -1, axis=1)
    faces = np.concatenate(
        [
            np.stack([idx.ravel(), nu.ravel(), nuv.ravel()], 1),
            np.stack([idx.ravel(), nuv.ravel(), nv.ravel()], 1),
        ]
    )
    return Mesh(verts, faces, name="torus")
