"""Distances between a fit and its input, as fractions of the input's bbox diagonal.

Two-sided: every reconstruction vertex to the input triangles and every input vertex to the
reconstruction's triangles (a grid soup), so a part of the input the fit misses counts as
much as a part the fit invents.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._kernels.geometry import label_corner_max
from meshfit.mesh import Mesh
from meshfit.mesh.locate import grid_tree, triangle_distances, triangles_within
from meshfit.springs import grid_triangles


def surface_distance(
    mesh: Mesh, V: NDArray[np.float64], F: NDArray[np.int64], tree, known=None, order=None
) -> tuple[NDArray, NDArray]:
    """Two-sided distances: reconstruction vertices to the input, input vertices to the
    reconstruction (a triangle soup ``V, F`` and its tree). ``known`` (per vertex of ``V``,
    optional): an upper bound of each one's distance to the input; where it is below
    ``tol.KNOWN_DISTANCE`` of the diagonal it is the distance (no search). ``order``
    (optional): :func:`meshfit.mesh.locate.query_order` of the input's vertices, when they
    are searched in several soups."""
    todo = np.arange(V.shape[0])
    to_input = np.zeros(V.shape[0])
    if known is not None:
        near = known <= tol.KNOWN_DISTANCE * mesh.bbox_diagonal
        to_input[near] = known[near]
        todo = np.flatnonzero(~near)
    if todo.size:
        to_input[todo], _ = triangle_distances(
            V[todo], mesh.vertices, mesh.faces, tree=mesh.triangle_tree
        )
    from_input, _ = triangle_distances(mesh.vertices, V, F, tree=tree, qorder=order)
    return to_input, from_input


def error_figures(
    mesh: Mesh, V, F, tree, known=None, order=None
) -> tuple[dict[str, float], NDArray[np.float64], NDArray[np.float64]]:
    """Error figures over the bbox diagonal, each reconstruction vertex's distance to the
    input and each input vertex's distance to the reconstruction (``known``, ``order``: see
    `surface_distance`)."""
    a, b = surface_distance(mesh, V, F, tree, known, order)
    return figures(a, b, mesh.bbox_diagonal), a, b


def figures(to_input: NDArray, from_input: NDArray, diag: float) -> dict[str, float]:
    """The error figures of two-sided distances (reconstruction vertices to the input, input
    vertices to the reconstruction) over the diagonal ``diag``."""
    both = np.concatenate([to_input, from_input])
    return {
        "rms": float(np.sqrt(np.mean(both**2)) / diag),
        "hausdorff": float(both.max() / diag),
        "mean": float(both.mean() / diag),
        "to_input_max": float(to_input.max() / diag),
        "from_input_max": float(from_input.max() / diag),
    }


def texel_grids(surfaces: list, shapes: list[tuple[int, ...]]) -> list[NDArray[np.float64]]:
    """Each spline on a regular grid of its parameter square (``shapes[p]`` starts with the
    grid's rows and columns: its spring grid's for the spline-only surface, its map's for
    a displaced one), laid out as the displaced grids are."""
    return [
        s.evaluate_grid(np.linspace(0.0, 1.0, sh[0]), np.linspace(0.0, 1.0, sh[1]))
        for s, sh in zip(surfaces, shapes, strict=True)
    ]


def spline_errors(mesh: Mesh, grids: list[NDArray[np.float64]], faces=None, order=None):
    """Error figures of the spline grids (`texel_grids`) against the input, and each grid
    vertex's distance to the input (``faces``: see `soup`; ``order``: see
    `surface_distance`)."""
    V, F = soup(grids, faces)
    tree = grid_tree(V, F, [g.shape[:2] for g in grids])
    fig, to_input, _ = error_figures(mesh, V, F, tree, order=order)
    return fig, to_input


def early_spline(mesh: Mesh, surfaces: list, shapes: list[tuple[int, ...]]):
    """The spline grids of ``shapes`` (`texel_grids`: the spring grids') and
    `spline_errors` of them."""
    grids = texel_grids(surfaces, shapes)
    return (grids, *spline_errors(mesh, grids))


def per_patch_max(
    mesh: Mesh, face_patch: NDArray[np.int64] | None, value: NDArray, n: int
) -> list[float | None]:
    """Largest ``value`` (one per input vertex) over each patch's input vertices (a vertex on
    a patch boundary counts for every patch of its faces); None without the face labels."""
    if face_patch is None or len(face_patch) != mesh.n_faces:
        return [None] * n
    worst = label_corner_max(
        np.ascontiguousarray(mesh.faces, dtype=np.int64),
        np.ascontiguousarray(face_patch, dtype=np.int64),
        np.ascontiguousarray(value, dtype=np.float64),
        int(n),
    )
    return np.maximum(worst, 0.0).tolist()


def soup(arrays: list[NDArray[np.float64]], faces=None) -> tuple[NDArray, NDArray]:
    """Grids ``(nu, nv, 3)`` as one triangle soup: stacked vertices and faces (``faces``:
    `soup_faces` of the grids' shapes, made once for several soups of one layout)."""
    F = soup_faces([X.shape[:2] for X in arrays]) if faces is None else faces
    return np.vstack([X.reshape(-1, 3) for X in arrays]), F


def soup_faces(shapes: list[tuple[int, int]]) -> NDArray[np.int64]:
    """The triangles of `soup` for grids of these ``(nu, nv)`` shapes: each grid's
    :func:`meshfit.springs.grid_triangles`, offset by the points before it, written in place
    into one array (a soup of a large fit has tens of millions of triangles: no per-grid
    copies and no stacking)."""
    sizes = [(int(nu), int(nv)) for nu, nv in shapes]
    F = np.empty((sum(2 * (nu - 1) * (nv - 1) for nu, nv in sizes), 3), dtype=np.int64)
    t = base = 0
    for nu, nv in sizes:
        n = 2 * (nu - 1) * (nv - 1)
        grid_triangles(nu, nv, base=base, out=F[t : t + n])
        t += n
        base += nu * nv
    return F


def grid_boxes(grids: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Each grid's bounding box, ``(n, 2, 3)``: its lowest and highest corner."""
    out = np.empty((len(grids), 2, 3))
    for q, g in enumerate(grids):
        pts = g.reshape(-1, 3)
        out[q, 0], out[q, 1] = pts.min(axis=0), pts.max(axis=0)
    return out


def nearest_grid_distances(
    points: NDArray[np.float64],
    p: int,
    boxes: NDArray[np.float64],
    grid: Callable[[int], NDArray[np.float64]],
) -> NDArray[np.float64]:
    """Each point's distance to the soup of all grids (`soup`), searching only grid ``p``
    and the grids that may hold a nearer point.

    The distance to grid ``p`` bounds each point's distance from above; another grid can be
    nearer only where its bounding box (``boxes``, `grid_boxes` of all grids) is within the
    largest bound of the points' box, and then only for the points that have one of its
    triangles within that bound (a yes-or-no search), which alone are searched again. The
    minimum is taken over the same triangles as a search of the whole soup, so the
    distances are equal to it; only grid ``p`` and its neighbours are read (``grid(q)``
    gives grid ``q``), which splits the search of a scan's vertices patch by patch.
    """
    X = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    if X.shape[0] == 0:
        return np.empty(0)
    own = grid(p)
    V, F = soup([own])
    d, _ = triangle_distances(X, V, F, tree=grid_tree(V, F, [own.shape[:2]]))
    # a box's distance is computed with a rounding of the coordinates' size: boxes within
    # that much more than a point's bound are searched too, so no nearer grid is missed
    reach = d + 4.0 * np.spacing(max(np.abs(boxes).max(), np.abs(X).max()))
    lo, hi = X.min(axis=0), X.max(axis=0)
    gap = np.linalg.norm(
        np.maximum(np.maximum(boxes[:, 0] - hi, lo - boxes[:, 1]), 0.0), axis=1
    )  # from the points' box to each grid's: below every point's own
    near = [int(q) for q in np.flatnonzero(gap < reach.max()) if q != p]
    if near:
        grids = [grid(q) for q in near]
        V, F = soup(grids)
        tree = grid_tree(V, F, [g.shape[:2] for g in grids])
        # a yes-or-no search first: most points have no other grid within the largest bound
        idx = np.flatnonzero(triangles_within(X, V, F, float(reach.max()), tree=tree))
        if idx.size:
            other, _ = triangle_distances(X[idx], V, F, tree=tree)
            d[idx] = np.minimum(d[idx], other)
    return d
