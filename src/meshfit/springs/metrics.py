"""Quality of a spring mesh (or of any grid on a patch): uniformity, shape, folds, fidelity."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._kernels.springs import grid_spacing
from meshfit.mesh import Mesh
from meshfit.springs.grid import SpringMesh, grid_triangles

__all__ = ["QUALITY_BOUNDS", "grid_metrics", "out_of_bounds", "spring_metrics", "worst_places"]

#: quality a spring mesh is held to (`out_of_bounds` reports the patches that miss one):
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
    places: bool = False,
) -> dict:
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
    places : bool, keyword-only
        Also say where the worst figures are (``"places"``: see :func:`worst_places`),
        from the same spacings, fold tests and distances.

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
        the surface, mesh vertices to the triangulation) over ``scale``; with ``places``,
        ``places`` (a dict, see :func:`worst_places`).

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
    folded = _folded(X, N)
    out: dict = {
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
    dist = None
    if fidelity:
        diag = mesh.bbox_diagonal if scale is None else float(scale)
        dist = _distances(mesh, X.reshape(-1, 3), grid_triangles(nu, nv))
        out.update(_fidelity_figures(dist[1], diag))
    if places:
        out["places"] = _places(X, cv, folded, u_lines, v_lines, dist, diag if fidelity else 1.0)
    return out


def _folded(X: NDArray[np.float64], N: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(nu - 1, nv - 1) bool: cells of the grid ``X (nu, nv, 3)`` with a triangle whose
    normal points against the summed unit normals ``N (nu, nv, 3)`` at its corners."""
    p00, p10, p11, p01 = X[:-1, :-1], X[1:, :-1], X[1:, 1:], X[:-1, 1:]
    n1 = np.cross(p10 - p00, p11 - p00)
    n2 = np.cross(p11 - p00, p01 - p00)
    s1 = N[:-1, :-1] + N[1:, :-1] + N[1:, 1:]
    s2 = N[:-1, :-1] + N[1:, 1:] + N[:-1, 1:]
    return (np.einsum("ijk,ijk->ij", n1, s1) <= 0) | (np.einsum("ijk,ijk->ij", n2, s2) <= 0)


def _distances(
    mesh: Mesh, P: NDArray[np.float64], T: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """The two-sided distance samples between the triangulation ``P``, ``T`` and ``mesh``:
    the sample points (grid triangle centroids and edge mid-points, then the mesh
    vertices), their distances to the other surface, and how many are grid samples."""
    import igl

    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    samples = np.concatenate([(a + b + c) / 3.0, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)])
    d1, _, _ = igl.point_mesh_squared_distance(samples, mesh.vertices, mesh.faces)
    d2, _, _ = igl.point_mesh_squared_distance(np.ascontiguousarray(mesh.vertices), P, T)
    points = np.concatenate([samples, mesh.vertices])
    return points, np.sqrt(np.concatenate([d1, d2])), len(samples)


def _fidelity(
    mesh: Mesh, P: NDArray[np.float64], T: NDArray[np.int64], diag: float
) -> dict[str, float]:
    return _fidelity_figures(_distances(mesh, P, T)[1], diag)


def _fidelity_figures(d: NDArray[np.float64], diag: float) -> dict[str, float]:
    """``fidelity_max`` and ``fidelity_rms`` of the two-sided distances ``d`` over ``diag``."""
    return {
        "fidelity_max": float(d.max() / diag),
        "fidelity_rms": float(np.sqrt(np.mean(d * d)) / diag),
    }


#: grid lines from a side within which `worst_places` calls a place "side" (from two sides:
#: "corner")
NEAR_SIDE = 2


def _place(i: int, j: int, nu: int, nv: int) -> str:
    """Where grid point ``(i, j)`` lies: "corner", "side" or "interior" (`NEAR_SIDE`)."""
    near_i = min(i, nu - 1 - i) <= NEAR_SIDE
    near_j = min(j, nv - 1 - j) <= NEAR_SIDE
    return "corner" if near_i and near_j else "side" if near_i or near_j else "interior"


def worst_places(
    mesh: Mesh, spring: SpringMesh, *, fidelity: bool = True, scale: float | None = None
) -> dict:
    """Where a spring mesh's worst quality figures are: what to look at (or paint again)
    when a patch misses a bound of `QUALITY_BOUNDS`.

    Each place has its grid indices, its position and a ``"place"``: ``"corner"`` or
    ``"side"`` within `NEAR_SIDE` grid lines of two sides or of one (a painted side or
    corner that bends, steps back or meets another at a sharp angle), else
    ``"interior"`` (a bulge, a pleat or scan detail inside the patch). The same as
    ``spring_metrics(mesh, spring, places=True)["places"]``, which also gives the metrics
    from one distance computation.

    Parameters
    ----------
    mesh : Mesh
        The patch surface the spring mesh lies on.
    spring : SpringMesh
        The spring mesh.
    fidelity : bool, keyword-only
        Also find the largest two-sided distance (as :func:`grid_metrics` measures it).
    scale : float, keyword-only, optional
        Length the distance is divided by (default ``mesh.bbox_diagonal``).

    Returns
    -------
    dict
        ``"arc_cv"``: the iso-curve piece with the largest arc-length coefficient of
        variation (``"cv"``; ``"along"``: ``"u"`` for a piece of constant ``j`` running
        along ``i``, else ``"v"``) and on it the interval farthest from the piece's mean
        spacing (``"points"``: its two grid points ``[i, j]``; ``"ratio"``: its length over
        the mean; ``"xyz"``: its mid-point); ``"folded"``: per folded cell its lower grid
        corner ``"cell"`` ``[i, j]`` and centre ``"xyz"``; with ``fidelity``,
        ``"fidelity"``: the largest distance (``"distance"``, over ``scale``), whether it
        is a point of the patch far from the grid (``"from": "patch"``) or of the grid
        far from the patch (``"grid"``), that point (``"xyz"``) and the grid point nearest
        to it (``"grid_point"``). Lists and floats only (JSON-ready).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.1-5.2 (arc length, aspect ratio), sec. 5.5.3
       (folded spring cells) and sec. 5.13 (fidelity of the resampling).
    """
    return spring_metrics(mesh, spring, fidelity=fidelity, scale=scale, places=True)["places"]


def _places(X, cv, folded, u_lines, v_lines, dist, diag: float) -> dict:
    """`worst_places` from a grid ``X (nu, nv, 3)``'s spacing CVs (`spacing`), folded cells
    (`_folded`) and, unless None, two-sided distances (`_distances`) over ``diag``."""
    nu, nv = X.shape[:2]
    ends_u = _section_ends(nu, u_lines)
    ends_v = _section_ends(nv, v_lines)
    k = int(np.argmax(cv))
    if k < (len(ends_u) - 1) * nv:  # a piece of column j between u ends
        sec, j = divmod(k, nv)
        lo, hi = int(ends_u[sec]), int(ends_u[sec + 1])
        pts = np.array([[i, j] for i in range(lo, hi + 1)])
        along = "u"
    else:
        sec, i = divmod(k - (len(ends_u) - 1) * nv, nu)
        lo, hi = int(ends_v[sec]), int(ends_v[sec + 1])
        pts = np.array([[i, j] for j in range(lo, hi + 1)])
        along = "v"
    P = X[pts[:, 0], pts[:, 1]]
    d = np.linalg.norm(np.diff(P, axis=0), axis=1)
    ratio = d / d.mean() if d.mean() > 0 else np.ones_like(d)
    m = int(np.argmax(np.abs(ratio - 1.0)))
    a, b = pts[m], pts[m + 1]
    out: dict = {
        "arc_cv": {
            "cv": float(cv[k]),
            "along": along,
            "points": [a.tolist(), b.tolist()],
            "ratio": float(ratio[m]),
            "xyz": (0.5 * (P[m] + P[m + 1])).tolist(),
            "place": _place(int(a[0]), int(a[1]), nu, nv),
        },
        "folded": [
            {
                "cell": [int(ci), int(cj)],
                "xyz": X[ci : ci + 2, cj : cj + 2].reshape(-1, 3).mean(axis=0).tolist(),
                "place": _place(int(ci), int(cj), nu, nv),
            }
            for ci, cj in np.argwhere(folded)
        ],
    }
    if dist is not None:
        points, dists, n_grid = dist
        w = int(np.argmax(dists))
        g = int(np.argmin(np.linalg.norm(X.reshape(-1, 3) - points[w], axis=1)))
        gi, gj = divmod(g, nv)
        out["fidelity"] = {
            "distance": float(dists[w] / diag),
            "from": "grid" if w < n_grid else "patch",
            "xyz": points[w].tolist(),
            "grid_point": [gi, gj],
            "place": _place(gi, gj, nu, nv),
        }
    return out


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
    mesh: Mesh,
    spring: SpringMesh,
    *,
    fidelity: bool = True,
    scale: float | None = None,
    places: bool = False,
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
        places=places,
    )
