"""Base mesh: a coarse spherical triangulation whose cells cover equal surface areas."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from meshfit import errors
from meshfit._kernels import frozen
from meshfit._kernels import shrinkwrap as _k
from meshfit.mesh import Mesh
from meshfit.shrinkwrap import _topo
from meshfit.shrinkwrap.sphere import SphereMap, spherical_orientation

__all__ = ["BaseMesh", "BaseOptions", "base_mesh", "cell_areas", "icosahedron", "octahedron"]


def icosahedron() -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Regular icosahedron inscribed in the unit sphere, faces oriented outward.

    Returns
    -------
    vertices : (12, 3) float64
    faces : (20, 3) int64
    """
    g = (1 + 5**0.5) / 2
    v = []
    for a in (-1, 1):
        for b in (-g, g):
            v += [(0, a, b), (a, b, 0), (b, 0, a)]
    v = np.asarray(v, dtype=np.float64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v, _outward_hull(v)


def _outward_hull(v: NDArray[np.float64]) -> NDArray[np.int64]:
    """Triangles of the convex hull of unit vectors ``v``, counter-clockwise from outside."""
    f = ConvexHull(v).simplices.astype(np.int64)
    flip = spherical_orientation(v, f) < 0
    f[flip] = f[flip][:, ::-1]
    return f


def octahedron() -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Regular octahedron inscribed in the unit sphere, faces oriented outward.

    Returns
    -------
    vertices : (6, 3) float64
    faces : (8, 3) int64
    """
    v = np.vstack([np.eye(3), -np.eye(3)])
    return v, _outward_hull(v)


#: starting polyhedra of `base_mesh`: name -> (builder, face count)
STARTS = {"icosahedron": (icosahedron, 20), "octahedron": (octahedron, 8)}


@dataclass(frozen=True)
class BaseOptions:
    """Options of :func:`base_mesh` (all have defaults); checked on construction.

    Attributes
    ----------
    max_faces : int
        Face budget (default 100); at least the face count of ``start``.
    target_ratio : float
        Stop splitting once ``max/min`` cell area is at most this (default 2).
    min_faces : int
        Keep splitting until the base has at least this many faces (default 20: the
        icosahedron; more base faces give finer levels for the same level count).
    start_subdivisions : int
        1-to-4 splits of the starting polyhedron before the relaxation (default 0; 1 turns
        the icosahedron into the 80-face geodesic polyhedron).
    start : {"icosahedron", "octahedron"}
        The polyhedron relaxed and split (default the icosahedron, 20 faces, as in the
        paper; the octahedron's 8 faces allow coarser bases, e.g. for automatic layouts of
        fewer than 60 patches).
    iterations : int
        Relaxation steps after the start and after every split (default 20).
    alpha : float
        Damping factor of eq. 1, in (0, 1] (default 0.5).
    seed : int
        Seed of the random rotation of the starting polyhedron and of the sampling
        (default 0).
    relaxation : {"equalize", "umbrella"}
        ``"umbrella"``: eq. 1 with density = summed adjacent cell areas, as in the paper.
        Its fixed point balances ``A_c`` times cell size rather than ``A_c`` alone, so on
        strongly distorted sphere maps it stalls far from equal areas (cells differing in
        area many times over). ``"equalize"`` (default): a damped per-vertex Gauss-Newton
        step on the squared deviation of each adjacent cell's area from their mean, same
        flip guard.
    samples : int
        Cell areas are estimated from at most this many input faces (sphere centroids,
        area-weighted; default 60,000).

    Raises
    ------
    InputError
        Unknown ``start`` or ``relaxation``, ``max_faces`` below the start's face count,
        ``alpha`` outside (0, 1].
    """

    max_faces: int = 100
    target_ratio: float = 2.0
    min_faces: int = 20
    start_subdivisions: int = 0
    start: str = "icosahedron"
    iterations: int = 20
    alpha: float = 0.5
    seed: int = 0
    relaxation: str = "equalize"
    samples: int = 60_000

    def __post_init__(self) -> None:
        if self.start not in STARTS:
            raise errors.InputError(
                f"start must be one of {', '.join(map(repr, STARTS))}, got {self.start!r}"
            )
        start_faces = STARTS[self.start][1]
        if self.max_faces < start_faces:
            raise errors.InputError(
                f"max_faces must be at least {start_faces} (an {self.start}), got {self.max_faces}"
            )
        if not 0 < self.alpha <= 1:
            raise errors.InputError(f"alpha must be in (0, 1], got {self.alpha}")
        if self.relaxation not in ("equalize", "umbrella"):
            raise errors.InputError(
                f"relaxation must be 'equalize' or 'umbrella', got {self.relaxation!r}"
            )


def _face_centroids_on_sphere(smap: SphereMap) -> NDArray[np.float64]:
    c = smap.sphere[smap.mesh.faces].sum(axis=1)
    return np.ascontiguousarray(c / np.linalg.norm(c, axis=1, keepdims=True))


def cell_areas(
    sphere: NDArray[np.float64],
    faces: NDArray[np.int64],
    points: NDArray[np.float64],
    weights: NDArray[np.float64],
    start: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Sum of ``weights`` of the ``points`` falling in each spherical triangle.

    Parameters
    ----------
    sphere : (nv, 3) float64
        Vertices of a flip-free spherical triangulation.
    faces : (nf, 3) int64
    points : (n, 3) float64
        Unit vectors (the sphere images of the input faces' centroids).
    weights : (n,) float64
        Their surface areas.
    start : (n,) int64, optional
        Faces to start the point location from (the previous cells).

    Returns
    -------
    area : (nf,) float64
    cell : (n,) int64
        Triangle holding each point.
    """
    s = np.ascontiguousarray(sphere, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if start is None:
        cell, _ = _k.locate_sphere_brute(s, f, points)
    else:
        fn = _topo.face_neighbors(f)
        steps = 8 * int(np.sqrt(len(f))) + 64
        cell, _, found = _k.locate_sphere(*frozen(s, f, fn), start, points, steps)
        if not found.all():
            bad = np.flatnonzero(~found)
            cell[bad], _ = _k.locate_sphere_brute(s, f, points[bad])
    return np.bincount(cell, weights=weights, minlength=len(f)), cell


@dataclass(frozen=True, eq=False)
class BaseMesh:
    """Result of :func:`base_mesh`.

    Attributes
    ----------
    sphere : (nv, 3) float64
        Vertices of the spherical polyhedron ``P*`` (unit vectors).
    faces : (nf, 3) int64
    mesh : Mesh
        ``M0 = F(P*)``: the base mesh on the input surface.
    cell_area : (nf,) float64
        Surface area of the input covered by each spherical cell, model units squared.
    area_ratio : float
        ``max / min`` of ``cell_area`` (``inf`` when a cell is empty).
    splits : int
        Edges bisected by the split heuristic.
    iterations : int
        Relaxation steps run in total.
    """

    sphere: NDArray[np.float64]
    faces: NDArray[np.int64]
    mesh: Mesh
    cell_area: NDArray[np.float64]
    area_ratio: float
    splits: int
    iterations: int


def _relax(s, faces, area, alpha):
    """One density-weighted umbrella step on the sphere (eq. 1, density = summed adjacent
    cell areas); moves that would flip a triangle are undone."""
    n = len(s)
    dens = np.bincount(faces.reshape(-1), weights=np.repeat(area, 3), minlength=n)
    adj = _topo.adjacency(faces, n)
    num = adj @ (s * dens[:, None])
    den = adj @ dens
    tgt = num / np.maximum(den, 1e-300)[:, None]
    new = (1 - alpha) * s + alpha * tgt
    new /= np.linalg.norm(new, axis=1, keepdims=True)
    return _guard(s, new, faces)


def _guard(s, new, faces):
    """Undo the moves of the corners of triangles that ``new`` would flip."""
    for _ in range(50):
        bad = spherical_orientation(new, faces) <= 0
        if not bad.any():
            return new
        back = np.unique(faces[bad])
        new[back] = s[back]
    return s


def _equalize(s, faces, area, alpha):
    """One damped Gauss-Newton step per vertex (Jacobi) toward equal cell areas.

    Cell ``c`` holds surface area ``A_c`` over the flat spherical triangle area ``a_c``
    (density ``rho_c = A_c / a_c``); moving corner ``p`` by ``delta`` changes ``A_c`` by about
    ``rho_c grad_p(a_c) . delta``. Each vertex takes the least-squares move (in the tangent
    plane) that brings its adjacent cells to their mean, damped by ``alpha`` and clamped to a
    quarter of its shortest edge; moves that flip a triangle are undone.
    """
    n = len(s)
    p = s[faces]
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    sa = 0.5 * np.linalg.norm(nrm, axis=1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    rho = area / sa
    fl = faces.reshape(-1)
    cnt = np.bincount(fl, minlength=n)
    local = np.bincount(fl, weights=np.repeat(area, 3), minlength=n) / np.maximum(cnt, 1)
    m = np.zeros((n, 3, 3))
    b = np.zeros((n, 3))
    emin = np.full(n, np.inf)
    for k in range(3):
        v = faces[:, k]
        g = rho[:, None] * 0.5 * np.cross(nrm, p[:, (k + 2) % 3] - p[:, (k + 1) % 3])
        r = area - local[v]
        np.add.at(m, v, g[:, :, None] * g[:, None, :])
        np.add.at(b, v, g * r[:, None])
        el = np.linalg.norm(p[:, (k + 1) % 3] - p[:, k], axis=1)
        np.minimum.at(emin, v, el)
        np.minimum.at(emin, faces[:, (k + 1) % 3], el)
    tr = np.trace(m, axis1=1, axis2=2)
    m += (s[:, :, None] * s[:, None, :] + 1e-6 * np.eye(3)) * tr[:, None, None]
    m[tr <= 0.0] = np.eye(3)  # (no gradient at the vertex, b is 0 there: it stays)
    d = -np.linalg.solve(m, b[:, :, None])[:, :, 0] * alpha
    ln = np.linalg.norm(d, axis=1)
    cap = 0.25 * emin
    d *= np.minimum(1.0, cap / np.maximum(ln, 1e-300))[:, None]
    new = s + d
    new /= np.linalg.norm(new, axis=1, keepdims=True)
    return _guard(s, new, faces)


#: the base-mesh relaxation at one face count stops after this many steps without a new best
_STALL = 8


def _split(s, faces, area):
    """Bisect the edge whose two adjacent cells hold the largest summed area."""
    edges, fe = _topo.unique_edges(faces)
    esum = np.bincount(fe.reshape(-1), weights=np.repeat(area, 3), minlength=len(edges))
    e = int(np.argmax(esum))
    a, b = edges[e]
    m = s[a] + s[b]
    s = np.vstack([s, m / np.linalg.norm(m)])
    iv = len(s) - 1
    out = []
    for tri in faces:
        t = list(tri)
        if a in t and b in t:
            k = t.index(a)
            if t[(k + 1) % 3] == b:  # edge a -> b
                c = t[(k + 2) % 3]
                out += [[a, iv, c], [iv, b, c]]
            else:  # edge b -> a
                c = t[(k + 1) % 3]
                out += [[a, c, iv], [iv, c, b]]
        else:
            out.append(t)
    return s, np.asarray(out, dtype=np.int64)


def base_mesh(
    smap: SphereMap,
    options: BaseOptions | None = None,
    *,
    progress: Callable[[str, float], None] | None = None,
) -> BaseMesh:
    """Build the base mesh ``M0`` by relaxing and splitting an icosahedron (or an
    octahedron) on the sphere.

    Each spherical cell gets the summed area of the input triangles whose sphere centroid
    it contains; a density-weighted umbrella relaxation (eq. 1 with density = sum of the
    adjacent cells' areas, projected back onto the sphere after each step) equalizes the
    cells, and while ``max/min`` stays above ``target_ratio`` the edge with the largest summed
    area of its two cells is bisected (two cells become four). The configuration with the
    smallest ratio seen within ``max_faces`` is returned.

    Parameters
    ----------
    smap : SphereMap
    options : BaseOptions, optional
        Default ``BaseOptions()``: the settings live in one frozen dataclass, checked when
        it is made, so a caller (e.g. :func:`shrink_wrap`) can pass them on whole.
    progress : callable(stage, fraction), keyword-only, optional

    Returns
    -------
    BaseMesh

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6 and eq. 1.
    """
    o = options if options is not None else BaseOptions()
    max_faces = o.max_faces
    target_ratio = o.target_ratio
    min_faces = o.min_faces
    iterations = o.iterations
    alpha = o.alpha
    seed = o.seed
    samples = o.samples
    build = STARTS[o.start][0]
    step = _equalize if o.relaxation == "equalize" else _relax
    v, f = build()
    for _ in range(o.start_subdivisions):
        f, e = _topo.subdivide(f, len(v))
        mid = v[e[:, 0]] + v[e[:, 1]]
        v = np.vstack([v, mid / np.linalg.norm(mid, axis=1, keepdims=True)])
    v = Rotation.random(random_state=seed).apply(v)
    pts = _face_centroids_on_sphere(smap)
    w = smap.mesh.face_areas
    if len(w) > samples:
        pick = np.random.default_rng(seed).choice(len(w), samples, replace=False)
        pts = np.ascontiguousarray(pts[pick])
        w = w[pick] * (w.sum() / w[pick].sum())
    area, cell = cell_areas(v, f, pts, w)
    best = None
    total_it = 0
    splits = 0
    while True:
        stage = None  # best configuration at this face count
        since = 0
        for _ in range(iterations):
            v = step(v, f, area, alpha)
            area, cell = cell_areas(v, f, pts, w, cell)
            total_it += 1
            ratio = float(area.max() / area.min()) if area.min() > 0 else np.inf
            since += 1
            if stage is None or ratio < stage[0]:
                stage = (ratio, v.copy(), f.copy(), area.copy(), splits, cell.copy())
                since = 0
            if since >= _STALL or ratio <= target_ratio:
                break
        if len(f) >= min_faces and (best is None or stage[0] < best[0]):
            best = stage
        if progress:
            progress("base mesh", min(1.0, len(f) / max_faces))
        if (best is not None and best[0] <= target_ratio) or len(f) + 2 > max_faces:
            break
        _, v, f, area, _, cell = stage  # split the best configuration of this face count
        v, f = _split(v, f, area)
        splits += 1
        area, cell = cell_areas(v, f, pts, w)
    if best is None:
        best = stage
    _, v, f, _, splits, _ = best
    area, _ = cell_areas(v, f, _face_centroids_on_sphere(smap), smap.mesh.face_areas)
    ratio = float(area.max() / area.min()) if area.min() > 0 else np.inf
    m0 = Mesh(smap.evaluate(v), f, name=f"{smap.mesh.name}-M0" if smap.mesh.name else "M0")
    return BaseMesh(v, f, m0, area, ratio, splits, total_it)
