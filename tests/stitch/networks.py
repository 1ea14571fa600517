"""Synthetic patch networks: grids sampled from one smooth surface split into patches."""

from __future__ import annotations

import numpy as np


def split_grid(X: np.ndarray, cuts_u: list[int], cuts_v: list[int]) -> list[np.ndarray]:
    """Blocks of a grid cut at the given rows / columns; neighbours share their cut row."""
    bu = [0, *cuts_u, X.shape[0] - 1]
    bv = [0, *cuts_v, X.shape[1] - 1]
    return [
        np.ascontiguousarray(X[bu[a] : bu[a + 1] + 1, bv[b] : bv[b + 1] + 1])
        for a in range(len(bu) - 1)
        for b in range(len(bv) - 1)
    ]


def height_field(n: int = 61) -> np.ndarray:
    """A bumpy height field over [0, 2] x [0, 2], normals up: ``(n, n, 3)``."""
    x = np.linspace(0, 2, n)
    U, V = np.meshgrid(x, x, indexing="ij")
    Z = 0.3 * np.sin(1.7 * U) * np.cos(1.3 * V) + 0.05 * np.sin(7 * U + 3 * V)
    return np.stack([U, V, Z], axis=-1)


def _radius(p: np.ndarray) -> np.ndarray:
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    return 1.0 + 0.08 * np.sin(3 * x) * np.cos(2 * y) + 0.05 * z**2


def cube_sphere(n: int = 33, resolutions: dict[int, int] | None = None) -> list[np.ndarray]:
    """Six outward-oriented grids on a bumpy sphere (cube faces projected): valence-3 corners,
    boundaries running both ways. ``resolutions`` gives per-face grid sizes (default n)."""
    grids = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            e1 = np.zeros(3)
            e2 = np.zeros(3)
            e1[(axis + 1) % 3] = 1.0
            e2[(axis + 2) % 3] = 1.0
            if sign < 0:
                e1, e2 = e2, e1  # keep e1 x e2 = sign * e_axis (outward)
            m = (resolutions or {}).get(len(grids), n)
            s = np.linspace(-1, 1, m)
            U, V = np.meshgrid(s, s, indexing="ij")
            c = np.zeros(3)
            c[axis] = sign
            p = c + U[..., None] * e1 + V[..., None] * e2
            d = p / np.linalg.norm(p, axis=-1, keepdims=True)
            grids.append(d * _radius(d)[..., None])
    return grids


def roof(n: int = 61) -> np.ndarray:
    """A bumpy roof over [0, 2] x [0, 2], normals up, with a crease (ridge) along x = 1
    (grid row ``(n - 1) / 2``): ``(n, n, 3)``."""
    x = np.linspace(0, 2, n)
    U, V = np.meshgrid(x, x, indexing="ij")
    Z = 0.5 - 0.35 * np.abs(U - 1.0) + 0.1 * np.sin(1.3 * V) + 0.01 * np.sin(9 * U + 7 * V)
    return np.stack([U, V, Z], axis=-1)
