"""Quality of a spring mesh (or of any grid on a patch): uniformity, shape, folds, fidelity."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._kernels.springs import grid_spacing
from meshfit.mesh import Mesh
from meshfit.springs.grid import SpringMesh, grid_triangles

__all__ = ["QUALITY_BOUNDS", "grid_metrics", "out_of_bounds", "spring_metrics"]

#: quality a spring mesh is held to (the bounds the test layouts are checked against):
#: arc-length coefficient of variation along every iso-curve piece, median cell aspect ratio,
#: folded cells, and the two-sided largest distance to the patch over the whole model's
#: bounding-box diagonal
QUALITY_BOUNDS: dict[str, float] = {
    "arc_cv_max": 0.15,
    "aspect_median": 1.5,
    "folded": 0,
    "fidelity_max": 5e-4,
}


def _cv(d: NDArray[np.float64]) -> float:
    m = d.mean()
    return float(d.std() / m) if m > 0 else 0.0


def spacing(
    X: NDArray[np.float64], u_lines: ArrayLike = (), v_lines: ArrayLike = ()
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Spacing figures of :func:`grid_metrics` for a grid ``X (nu, nv, 3)``: the coefficient
    of variation of the point spacing along each iso-curve piece inside one section
    (flattened, u pieces first), and each cell's aspect ratio ``(nu - 1, nv - 1)``."""
    nu, nv = X.shape[:2]
    X = np.ascontiguousarray(X, dtype=np.float64)
    return grid_spacing(X, _section_ends(nu, u_lines), _section_ends(nv, v_lines))


def _section_ends(n: int, lines: ArrayLike) -> NDArray[np.int64]:
    """(s + 1,) int64: the grid indices where the sections of ``n`` points along one
    direction begin and end: 0, the feature lines ``lines`` (s - 1,), n - 1."""
    inner = np.asarray(lines, dtype=np.int64).reshape(-1)
    return np.concatenate([[0], inner, [n - 1]]).astype(np.int64)


def grid_metrics(
    mesh: Mesh,
    xyz: ArrayLike,
    normals: ArrayLike,
    *,
    u_lines: ArrayLike = (),
    v_lines: ArrayLike = (),
    fidelity: bool = True,
    scale: float | None = None,
) -> dict[str, float | int]:
    """Quality metrics of an ``(nu, nv)`` grid of points on a patch surface.

    Parameters
    ----------
    mesh : Mesh
        The patch surface.
    xyz : (nu, nv, 3) float64
        Grid positions, model units.
    normals : (nu, nv, 3) float64
        Unit surface normal at each grid point (of the face it lies in).
    u_lines, v_lines : (a,) int64, (b,) int64
        Columns / rows that follow feature curves: arc-length uniformity is measured per
        section between them (sec. 5.10.3).
    fidelity : bool
        Also measure the two-sided distance between the grid triangulation and ``mesh``.
    scale : float, optional
        Length the fidelity distances are divided by, model units (e.g. the whole model's
        bounding-box diagonal); default ``mesh.bbox_diagonal``.

    Returns
    -------
    dict
        ``arc_cv_max`` / ``arc_cv_mean``: coefficient of variation of the point spacing along
        each iso-curve piece inside one section (max / mean over pieces); ``aspect_median``
        / ``aspect_max``: cell aspect ratio (longer over shorter mean side, >= 1);
        ``area_cv``: coefficient of variation of cell areas; ``area_ratio``: largest over
        smallest cell area; ``folded``: cells with a triangle whose normal points against
        the surface normal; ``fidelity_max`` / ``fidelity_rms``: two-sided distance between
        the grid triangulation and ``mesh`` (grid triangle centroids and edge mid-points to
        the surface, mesh vertices to the triangulation) over ``scale``.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.1-5.2 (arc length, aspect ratio, fairness) and
       sec. 5.13 (fidelity of the resampling).
    """
    X = np.asarray(xyz, dtype=np.float64)
    N = np.asarray(normals, dtype=np.float64)
    nu, nv = X.shape[:2]
    cv, aspect = spacing(X, u_lines, v_lines)
    p00, p10, p11, p01 = X[:-1, :-1], X[1:, :-1], X[1:, 1:], X[:-1, 1:]
    area = 0.5 * np.linalg.norm(np.cross(p11 - p00, p01 - p10), axis=2)
    n1 = np.cross(p10 - p00, p11 - p00)
    n2 = np.cross(p11 - p00, p01 - p00)
    s1 = N[:-1, :-1] + N[1:, :-1] + N[1:, 1:]
    s2 = N[:-1, :-1] + N[1:, 1:] + N[:-1, 1:]
    folded = (np.einsum("ijk,ijk->ij", n1, s1) <= 0) | (np.einsum("ijk,ijk->ij", n2, s2) <= 0)
    out: dict[str, float | int] = {
        "nu": int(nu),
        "nv": int(nv),
        "arc_cv_max": float(cv.max()) if cv.size else 0.0,
        "arc_cv_mean": float(cv.mean()) if cv.size else 0.0,
        "aspect_median": float(np.median(aspect)),
        "aspect_max": float(np.max(aspect)),
        "area_cv": _cv(area.ravel()),
        "area_ratio": float(area.max() / area.min()) if area.min() > 0 else float("inf"),
        "folded": int(folded.sum()),
    }
    if fidelity:
        diag = mesh.bbox_diagonal if scale is None else float(scale)
        out.update(_fidelity(mesh, X.reshape(-1, 3), grid_triangles(nu, nv), diag))
    return out


def _fidelity(
    mesh: Mesh, P: NDArray[np.float64], T: NDArray[np.int64], diag: float
) -> dict[str, float]:
    import igl

    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    samples = np.concatenate([(a + b + c) / 3.0, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)])
    d1, _, _ = igl.point_mesh_squared_distance(samples, mesh.vertices, mesh.faces)
    d2, _, _ = igl.point_mesh_squared_distance(np.ascontiguousarray(mesh.vertices), P, T)
    d = np.sqrt(np.concatenate([d1, d2]))
    return {
        "fidelity_max": float(d.max() / diag),
        "fidelity_rms": float(np.sqrt(np.mean(d * d)) / diag),
    }


def out_of_bounds(metrics: dict, bounds: dict | None = None) -> list[str]:
    """Names of the metrics above their quality bound.

    Parameters
    ----------
    metrics : dict
        A :func:`grid_metrics` dict (or a row holding some of its keys).
    bounds : dict of str to float, optional
        Upper bounds per metric (default `QUALITY_BOUNDS`); a metric missing from
        ``metrics`` is skipped.

    Returns
    -------
    list of str
        In the order of ``bounds``.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.1-5.2 (arc length, aspect ratio) and sec. 5.5.3
       (folded spring cells).
    """
    bounds = QUALITY_BOUNDS if bounds is None else bounds
    return [k for k, b in bounds.items() if k in metrics and metrics[k] > b]


def spring_metrics(
    mesh: Mesh, spring: SpringMesh, *, fidelity: bool = True, scale: float | None = None
) -> dict:
    """:func:`grid_metrics` of a spring mesh on its patch mesh (normals of the points' faces)."""
    normals = mesh.face_normals[spring.points.face].reshape(*spring.shape, 3)
    return grid_metrics(
        mesh,
        spring.xyz,
        normals,
        u_lines=spring.u_lines,
        v_lines=spring.v_lines,
        fidelity=fidelity,
        scale=scale,
    )
