"""Gridded samples of real scans and exact spline data, shared by the fit, map and export tests."""

from __future__ import annotations

from functools import cache

import numpy as np

from meshfit.bspline import BSplineSurface
from meshfit.mesh import Mesh
from tests.conftest import real_mesh

#: (mesh, view axis, view sign, window centre as a fraction of the bbox, window half-size)
VIEWS = {
    "igea": (2, 1.0, (0.5, 0.55), 0.18),
    "nefertiti": (2, 1.0, (0.5, 0.6), 0.15),
}


@cache
def scan_grid(name: str, nu: int = 60, nv: int = 50) -> np.ndarray:
    """Grid of points ray-cast from a plane onto a real scan: ``(nu, nv, 3) float64``.

    Rays run along the view axis from outside the bounding box towards the mesh; the window
    is a square of the bbox (a height-field-like region of the face). Oriented so that
    ``S_u x S_v`` points towards the viewer (outwards).
    """
    mesh = real_mesh(name)
    # ray_first_hit misses every ray on igea (bbox ~0.1 units; libigl's ray test seems to use
    # an absolute epsilon), so rays are cast on a copy scaled to ~100 units and scaled back
    scale = 1000.0 / mesh.bbox_diagonal
    mesh = Mesh(mesh.vertices * scale, mesh.faces)
    axis, sign, (cu, cv), half = VIEWS[name]
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    a, b = [k for k in range(3) if k != axis]
    ext = hi - lo
    su = lo[a] + ext[a] * (cu + half * np.linspace(-1, 1, nu))
    sv = lo[b] + ext[b] * (cv + half * np.linspace(-1, 1, nv))
    U, V = np.meshgrid(su, sv, indexing="ij")
    origins = np.zeros((nu * nv, 3))
    origins[:, a], origins[:, b] = U.ravel(), V.ravel()
    origins[:, axis] = hi[axis] + 0.1 * ext[axis] if sign > 0 else lo[axis] - 0.1 * ext[axis]
    d = np.zeros(3)
    d[axis] = -sign
    hits = mesh.ray_first_hit(origins, np.repeat(d[None], nu * nv, axis=0))
    assert hits.hit.all(), f"{name}: {int((~hits.hit).sum())} rays missed"
    X = (origins + hits.t[:, None] * d).reshape(nu, nv, 3) / scale
    n = np.cross(X[1:, :-1] - X[:-1, :-1], X[:-1, 1:] - X[:-1, :-1]).sum(axis=(0, 1))
    if n[axis] * sign < 0:
        X = X[:, ::-1]
    X = np.ascontiguousarray(X)
    X.flags.writeable = False
    return X


def random_surface(rng: np.random.Generator, mu: int = 7, mv: int = 9) -> BSplineSurface:
    """A wavy but regular spline over the unit square (height field plus a random wobble)."""
    iu, iv = np.meshgrid(np.linspace(0, 1, mu), np.linspace(0, 1.3, mv), indexing="ij")
    P = np.stack([iu, iv, 0.2 * np.sin(3 * iu) * np.cos(2 * iv)], axis=-1)
    P += 0.03 * rng.normal(size=P.shape)
    return BSplineSurface(P)
