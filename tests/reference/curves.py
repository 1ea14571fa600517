"""Slow, obviously-correct oracles for `meshfit.curves`.

The B-spline basis here is the textbook Cox-de Boor recursion, one function value at a time,
with the convention 0 / 0 = 0; the right end of the domain belongs to the last non-empty
knot span (so the basis sums to one on the closed interval).
"""

from __future__ import annotations

import numpy as np


def _n(i: int, p: int, t: float, U: np.ndarray) -> float:
    if p == 0:
        last = U[-1]
        if U[i] <= t < U[i + 1]:
            return 1.0
        # t at the right end: the last span with U[i] < U[i + 1] holds it
        if t == last and U[i] < U[i + 1] == last:
            return 1.0
        return 0.0
    a = 0.0 if U[i + p] == U[i] else (t - U[i]) / (U[i + p] - U[i]) * _n(i, p - 1, t, U)
    b = (
        0.0
        if U[i + p + 1] == U[i + 1]
        else (U[i + p + 1] - t) / (U[i + p + 1] - U[i + 1]) * _n(i + 1, p - 1, t, U)
    )
    return a + b


def bspline_basis(t, knots, degree: int = 3) -> np.ndarray:
    """(n, k) matrix of B-spline basis values N_i,degree(t_j), k = len(knots) - degree - 1."""
    U = np.asarray(knots, dtype=float)
    k = U.size - degree - 1
    t = np.atleast_1d(np.asarray(t, dtype=float))
    return np.array([[_n(i, degree, float(tj), U) for i in range(k)] for tj in t])


def attract_chain(mesh, points, targets):
    """CurveAttract by continuation, one point at a time with the public ``attract_points``:
    point i starts from the nearer (to its target) of its own position and point i - 1's
    result. Returns ``(face (n,), bary (n, 3))``."""
    from meshfit.surface import attract_points
    from meshfit.types import SurfacePoints

    faces, barys = [], []
    for i in range(len(points)):
        start = points[i]
        if i > 0:
            prev = SurfacePoints(np.array([faces[-1]]), barys[-1][None])
            own = np.sum((targets[i] - mesh.xyz(start)[0]) ** 2)
            if np.sum((targets[i] - mesh.xyz(prev)[0]) ** 2) < own:
                start = prev
        end = attract_points(mesh, start, targets[i][None]).end
        faces.append(int(end.face[0]))
        barys.append(end.bary[0].copy())
    return np.array(faces), np.array(barys)
