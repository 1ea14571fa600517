"""Multi-level shrink wrapping: subdivision-connectivity meshes M0..Mm fitted to the input."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from meshfit import errors, tol
from meshfit.mesh import Mesh
from meshfit.shrinkwrap import _topo
from meshfit.shrinkwrap.base import STARTS, BaseMesh, BaseOptions, base_mesh, cell_areas
from meshfit.shrinkwrap.sphere import (
    VOXEL_REMOVED,
    SphereMap,
    sphere_map,
    spherical_orientation,
    triangle_quality,
)
from meshfit.types import SurfacePoints

__all__ = ["WrapLevel", "WrapResult", "level_metrics", "shrink_wrap"]


@dataclass(frozen=True, eq=False)
class WrapLevel:
    """One refinement level ``M_i`` of the wrap.

    Attributes
    ----------
    level : int
    vertices : (n_i, 3) float64
        Positions on the input surface, model units. Vertex ``j < n_{i-1}`` descends from
        vertex ``j`` of the previous level; vertex ``n_{i-1} + e`` was inserted on edge ``e``
        (rows of ``unique_edges`` of the previous faces).
    faces : (4^i nf0, 3) int64
    sphere : (n_i, 3) float64
        Parameter values ``F^-1(vertices)`` on the unit sphere.
    points : SurfacePoints
        The vertices as face points of the input mesh.
    phase : str
        ``"base"``, ``"parameter"`` (relaxed on the sphere) or ``"surface"`` (relaxed in space
        and projected onto the input).
    iterations : int
    density : str
        Densities used in the relaxation: ``"area"``, ``"edge"`` or ``"-"``.
    tightness : float
        95th percentile of the distance of face centroids to the input over the mean edge
        length (the switching rule's figure).
    ray_fraction : float
        Surface phase: fraction of the projections of the level's relaxation that took the
        first ray hit along the normal (the rest took the closest point); ``nan`` for the
        base and parameter-phase levels, which do not project.
    """

    level: int
    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    sphere: NDArray[np.float64]
    points: SurfacePoints
    phase: str
    iterations: int
    density: str
    tightness: float
    ray_fraction: float = float("nan")

    @cached_property
    def mesh(self) -> Mesh:
        """The level as a :class:`Mesh` (validated on first use)."""
        return Mesh(self.vertices, self.faces, name=f"M{self.level}")


@dataclass(frozen=True, eq=False)
class WrapResult:
    """Result of :func:`shrink_wrap`.

    Attributes
    ----------
    sphere_map : SphereMap
    base : BaseMesh
    levels : list of WrapLevel
        ``M0 .. Mm``.
    switch_level : int
        First level relaxed on the surface (``levels + 1`` if none).
    seconds : dict
        Wall time per stage.
    """

    sphere_map: SphereMap
    base: BaseMesh
    levels: list[WrapLevel]
    switch_level: int
    seconds: dict = field(default_factory=dict)

    @property
    def meshes(self) -> list[Mesh]:
        """``M0 .. Mm`` as meshes."""
        return [lv.mesh for lv in self.levels]


#: the switching rule's tightness is estimated from at most this many face centroids
_TIGHTNESS_SAMPLES = 20_000


def _tightness(mesh: Mesh, x: NDArray, faces: NDArray) -> float:
    if len(faces) > _TIGHTNESS_SAMPLES:  # a fixed, evenly spread subset of the faces
        faces = faces[:: len(faces) // _TIGHTNESS_SAMPLES]
    c = x[faces].mean(axis=1)
    d = mesh.closest_points(c).distance
    e, _ = _topo.unique_edges(faces)
    mel = np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1).mean()
    return float(np.quantile(d, 0.95) / mel)


def _guard(old, new, faces):
    """Indices of vertices whose move must be undone so no spherical triangle flips, and the
    guarded positions."""
    back = np.zeros(len(old), dtype=bool)
    for _ in range(50):
        bad = spherical_orientation(new, faces) <= 0
        if not bad.any():
            return new, back
        v = np.unique(faces[bad])
        back[v] = True
        new[v] = old[v]
    return old.copy(), np.ones(len(old), dtype=bool)


def _edge_density(x, edges, n):
    ln = np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1)
    s = np.bincount(edges.reshape(-1), weights=np.repeat(ln, 2), minlength=n)
    c = np.bincount(edges.reshape(-1), minlength=n)
    return s / np.maximum(c, 1)


def _area_density(s, faces, centroids, weights, cell):
    """Per vertex: the summed sampling weight of the input triangles in its adjacent cells
    (eq. 1's density with the surface metric, sec. 7); a vertex whose cells are all empty gets
    ``tol.SHRINKWRAP_DENSITY_FLOOR`` times the largest density."""
    area, cell = cell_areas(s, faces, centroids, weights, cell)
    d = np.bincount(faces.reshape(-1), weights=np.repeat(area, 3), minlength=len(s))
    return np.maximum(d, tol.SHRINKWRAP_DENSITY_FLOOR * d.max()), cell


def _param_relax(smap, s, loc, faces, iterations, alpha, density, centroids, weights, cell):
    """Density-weighted umbrella steps on the sphere (sec. 7): densities are summed adjacent
    cell weights while the cells are large against the input triangles, then mean surface
    edge lengths."""
    mesh = smap.mesh
    n = len(s)
    adj = _topo.adjacency(faces, n)
    edges, _ = _topo.unique_edges(faces)
    for _ in range(iterations):
        if density == "area":
            d, cell = _area_density(s, faces, centroids, weights, cell)
        else:
            d = _edge_density(mesh.xyz(loc), edges, n)
        tgt = (adj @ (s * d[:, None])) / (adj @ d)[:, None]
        new = (1 - alpha) * s + alpha * tgt
        new /= np.linalg.norm(new, axis=1, keepdims=True)
        new, _ = _guard(s, new, faces)
        s = new
        loc = smap.locate(s, start=loc.face)
    return s, loc, cell, float("nan")


def _vertex_normals(x, faces):
    fn = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    flat = faces.reshape(-1)
    vn = np.stack(
        [np.bincount(flat, weights=np.repeat(fn[:, j], 3), minlength=len(x)) for j in range(3)],
        axis=1,
    )
    return vn / np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)


def _project(mesh: Mesh, x, nrm, mel):
    """Ray along the normal, first hit; closest point when the ray misses or lands far.

    One ray per point, started ``tol.SHRINKWRAP_RAY_BACKOFF`` mean edge lengths behind it,
    finds the surface on either side of a point that is already close to it."""
    cp = mesh.closest_points(x)
    back = tol.SHRINKWRAP_RAY_BACKOFF * mel
    hits = mesh.ray_first_hit(x - back * nrm, nrm)
    dist = np.abs(hits.t - back)
    ok = hits.hit & (
        dist <= tol.SHRINKWRAP_RAY_TRUST * cp.distance + tol.SHRINKWRAP_RAY_SLACK * mel
    )
    face = np.where(ok, hits.face, cp.points.face)
    bary = np.where(ok[:, None], hits.bary, cp.points.bary)
    return SurfacePoints(face, bary), float(ok.mean())


def _surface_relax(smap, s, loc, faces, iterations, alpha0, density, centroids, weights, cell):
    """Alternate the umbrella operator in space (eq. 1; densities: summed adjacent cell
    weights or mean edge lengths, as in the parameter phase) with projection onto the input
    (sec. 4); the damping fades linearly to 0; moves that would flip a triangle in the
    parameter domain are undone."""
    mesh = smap.mesh
    n = len(s)
    adj = _topo.adjacency(faces, n)
    edges, _ = _topo.unique_edges(faces)
    x = mesh.xyz(loc)
    rays = []
    for it in range(iterations):
        alpha = alpha0 * (1.0 - it / iterations)
        if density == "area":
            d, cell = _area_density(s, faces, centroids, weights, cell)
        else:
            d = _edge_density(x, edges, n)
        tgt = (adj @ (x * d[:, None])) / (adj @ d)[:, None]
        y = (1 - alpha) * x + alpha * tgt
        mel = float(np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1).mean())
        new_loc, ray = _project(mesh, y, _vertex_normals(x, faces), mel)
        rays.append(ray)
        new_s = smap.inverse(new_loc)
        new_s, back = _guard(s, new_s, faces)
        face = np.where(back, loc.face, new_loc.face)
        bary = np.where(back[:, None], loc.bary, new_loc.bary)
        loc = SurfacePoints(face, bary)
        s = new_s
        x = mesh.xyz(loc)
    return s, loc, cell, float(np.mean(rays)) if rays else float("nan")


#: step lengths tried, in turn, by the thin-triangle clean-up (fractions of the umbrella step)
_CLEAN_STEPS = (1.0, 0.5, 0.25, 0.125)
#: the clean-up stops after this many rounds without a larger minimum angle
_CLEAN_STALL = 5


def _fix_thin(smap, s, loc, faces, min_angle, rounds):
    """Local clean-up of thin triangles (sec. 4's relaxing force, restricted): the corners of
    triangles with an angle below ``min_angle`` (radians) take uniform umbrella steps in
    their tangent plane and are projected back onto the input, flip-guarded like the
    surface phase. Stops after ``_CLEAN_STALL`` rounds without progress and returns the
    configuration with the largest minimum angle seen."""
    mesh = smap.mesh
    n = len(s)
    adj = _topo.adjacency(faces, n)
    edges, _ = _topo.unique_edges(faces)
    val = np.asarray(adj.sum(axis=1)).ravel()
    x = mesh.xyz(loc)
    best = None
    since = 0
    for _ in range(rounds + 1):
        ang, _ = triangle_quality(x, faces)
        since += 1
        if best is None or ang.min() > best[0]:
            best = (ang.min(), s, loc)
            since = 0
        thin = ang < min_angle
        if not thin.any() or since >= _CLEAN_STALL:
            break
        sel = np.zeros(n, dtype=bool)
        sel[faces[thin]] = True
        nrm = _vertex_normals(x, faces)
        step = (adj @ x) / val[:, None] - x
        step -= (step * nrm).sum(axis=1, keepdims=True) * nrm
        mel = float(np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1).mean())
        face = loc.face.copy()
        bary = loc.bary.copy()
        for scale in _CLEAN_STEPS:  # a move that flips is retried shorter
            idx = np.flatnonzero(sel)
            if len(idx) == 0:
                break
            new_loc, _ = _project(mesh, x[idx] + scale * step[idx], nrm[idx], mel)
            new_s = s.copy()
            new_s[idx] = smap.inverse(new_loc)
            new_s, back = _guard(s, new_s, faces)
            k = ~back[idx]
            face[idx[k]] = new_loc.face[k]
            bary[idx[k]] = new_loc.bary[k]
            s = new_s
            sel[idx[k]] = False
        loc = SurfacePoints(face, bary)
        x = mesh.xyz(loc)
    return best[1], best[2]


#: most faces of a wrap's finest level: every level has four times the faces of the last,
#: and the levels are kept (peak memory of the order of a kilobyte a finest face, so this
#: bound keeps a wrap within a few gigabytes)
WRAP_MAX_FACES = 8_000_000


def _check_level_faces(base_faces: int, levels: int, fewest: bool = False) -> None:
    """InputError when ``levels`` splits of ``base_faces`` (``fewest``: of at least that
    many) exceed `WRAP_MAX_FACES`."""
    if base_faces * 4**levels > WRAP_MAX_FACES:
        top = 0
        while base_faces * 4 ** (top + 1) <= WRAP_MAX_FACES:
            top += 1
        raise errors.InputError(
            f"{levels} levels over {'at least ' if fewest else ''}{base_faces} base faces make "
            f"{'at least ' if fewest else ''}{base_faces * 4**levels:,} faces; at most "
            f"{WRAP_MAX_FACES:,} are made: ask for {top} levels or fewer"
        )


@dataclass(frozen=True)
class WrapOptions:
    """Options of :func:`shrink_wrap` and :func:`meshfit.wrap` (all have defaults).

    Attributes
    ----------
    base_faces : int
        Face budget of the base mesh (default 100): :func:`shrink_wrap` without
        ``base_options`` builds the base with ``BaseOptions(max_faces=base_faces)``. Given
        base options carry their own ``max_faces``; a ``base_faces`` other than the default
        must then agree with it (InputError otherwise, rather than one silently winning).
    sphere_method : {"tutte"}
        Construction of the sphere map when ``smap`` is omitted (see :func:`sphere_map`;
        ``"voxel"``, the paper's distance-field flow, is refused with the reason).
    sphere_max_aspect : float, optional
        Aspect-ratio bound of the spherical triangles when ``smap`` is omitted
        (``sphere_map(max_aspect=...)``; default ``None``: no bound).
    sphere_stretch : int
        Rounds of stretch-minimizing reweighting of the sphere map when ``smap`` is omitted
        (``sphere_map(stretch_iterations=...)``; default 0). The default map squeezes
        protrusions, and the wrap then misses their tips; the reweighted map gives them
        their share of the sphere, at the price of less even triangles (smaller angles,
        more triangles facing against the input), and on shapes without protrusions it
        can do worse. Not the default for that reason.
    parameter_iterations, surface_iterations : int
        Relaxation steps per level in each phase (defaults 6 and 4).
    alpha : float
        Damping factor of eq. 1, in (0, 1] (default 0.5).
    count_weight : float
        Each input triangle weighs its area plus this times the mean triangle area in the
        density estimate (default 3; 0: surface area only, as in the paper).
    min_cell_faces : float
        Area densities while the input has at least this many triangles per cell of the
        level (default 2), edge-length densities afterwards.
    switch_tightness : float
        Tightness threshold of the switching rule (default 0.1).
    switch_min_angle_deg : float
        Also switch when the parameter phase leaves a triangle with a smaller angle, degrees
        (default 10): the surface metric then has to take over.
    min_switch_level : int
        No switch before this level (default 2).
    clean_min_angle_deg, clean_rounds : float, int
        After the surface phase of each level, the corners of triangles with an angle below
        ``clean_min_angle_deg`` (default 10) take up to ``clean_rounds`` (default 20; 0: off)
        uniform umbrella steps in their tangent planes, projected back onto the input and
        flip-guarded; the configuration with the largest minimum angle is kept (slivers are
        lifted without moving the surface).
    """

    base_faces: int = 100
    sphere_method: str = "tutte"
    sphere_max_aspect: float | None = None
    sphere_stretch: int = 0
    parameter_iterations: int = 6
    surface_iterations: int = 4
    alpha: float = 0.5
    count_weight: float = 3.0
    min_cell_faces: float = 2.0
    switch_tightness: float = 0.1
    switch_min_angle_deg: float = 10.0
    min_switch_level: int = 2
    clean_min_angle_deg: float = 10.0
    clean_rounds: int = 20

    def __post_init__(self) -> None:
        if self.sphere_method == "voxel":
            raise errors.InputError(f"sphere_method: {VOXEL_REMOVED}")
        if self.sphere_method != "tutte":
            raise errors.InputError(f"sphere_method must be 'tutte', got {self.sphere_method!r}")


def _base_options(o: WrapOptions, given: BaseOptions | None) -> BaseOptions:
    """The base mesh's options: ``given``, or ``o.base_faces`` as the budget when omitted.

    ``WrapOptions.base_faces`` and ``BaseOptions.max_faces`` name the same budget; a
    non-default ``base_faces`` that disagrees with given base options is an InputError, so
    neither setting is dropped without notice.
    """
    if given is None:
        return BaseOptions(max_faces=o.base_faces)
    if not isinstance(given, BaseOptions):
        raise errors.InputError(f"base_options must be a BaseOptions, got {type(given).__name__}")
    if o.base_faces != WrapOptions.base_faces and o.base_faces != given.max_faces:
        raise errors.InputError(
            f"WrapOptions(base_faces={o.base_faces}) disagrees with "
            f"BaseOptions(max_faces={given.max_faces}): set the budget in one of them"
        )
    return given


def shrink_wrap(
    mesh: Mesh,
    options: WrapOptions | None = None,
    *,
    levels: int = 5,
    smap: SphereMap | None = None,
    base: BaseMesh | None = None,
    base_options: BaseOptions | None = None,
    progress: Callable[[str, float], None] | None = None,
) -> WrapResult:
    """Remesh a closed genus-0 mesh with subdivision connectivity by shrink wrapping.

    Starting from the base mesh, each level is a 1-to-4 split of the previous one (new
    vertices at the normalised midpoints of the parameter-domain edges, mapped by ``F``)
    followed by relaxation:

    - **parameter phase** (low levels): density-weighted umbrella steps (eq. 1) applied to the
      pre-images on the sphere, positions ``F(p*)`` always on the input (sec. 7);
    - **surface phase**: eq. 1 in space with damping fading from ``alpha`` to 0, alternated
      with projection onto the input along the vertex normals (first hit on the AABB tree of
      one ray per vertex started a little behind it; closest point when the ray misses or
      lands more than ``tol.SHRINKWRAP_RAY_TRUST`` times farther than the closest point) (sec. 4).

    Densities of eq. 1, in both phases: while the input has at least ``min_cell_faces``
    triangles per cell of ``M_i``, the summed weight of the input triangles in the vertex's
    adjacent cells (the paper's area density, sec. 7), each triangle weighing its area plus
    ``count_weight`` times the mean triangle area; afterwards (cells too small to estimate
    areas) the mean surface edge length at each neighbour, as in eq. 1. The count term makes
    the wrap follow the input's own sampling: scans and decimated models are finely
    triangulated at their creases, where a wrap with uniform surface density cuts corners
    (``benchmarks/wrap.py`` measures both). A vertex
    whose cells are all empty gets a tiny density (``tol.SHRINKWRAP_DENSITY_FLOOR``).

    Switching rule: after the parameter phase of level ``i >= min_switch_level``, if the 95th
    percentile of the distance from the face centroids of ``M_i`` to the input is at most
    ``switch_tightness`` times the mean edge length of ``M_i`` (normal rays then meet the
    surface near their start), or if ``M_i`` has a triangle with an angle below
    ``switch_min_angle_deg`` (the sphere metric no longer approximates the surface metric
    well enough), all later levels use the surface phase. Every move that would
    flip a triangle in the parameter domain is undone, so each ``M_i`` stays a bijective
    image of the sphere.

    Parameters
    ----------
    mesh : Mesh
        Closed, connected genus-0 surface.
    options : WrapOptions, optional
        Default ``WrapOptions()``.
    levels : int
        Number of refinement levels ``m`` (default 5). InputError when the finest level
        would have more than `WRAP_MAX_FACES` faces.
    smap, base : optional
        A sphere map / base mesh computed before (recomputed when omitted).
    base_options : BaseOptions, optional
        Options of :func:`base_mesh` (e.g. ``BaseOptions(start_subdivisions=1)``); default
        ``BaseOptions(max_faces=options.base_faces)``. When given, its ``max_faces`` is the
        face budget, and a non-default ``options.base_faces`` that differs from it is an
        InputError. Unused when ``base`` is given.
    progress : callable(stage, fraction), optional

    Returns
    -------
    WrapResult

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 4 (eq. 1), sec. 7.
    """
    o = options if options is not None else WrapOptions()
    sphere_method = o.sphere_method
    sphere_max_aspect = o.sphere_max_aspect
    sphere_stretch = o.sphere_stretch
    parameter_iterations = o.parameter_iterations
    surface_iterations = o.surface_iterations
    alpha = o.alpha
    count_weight = o.count_weight
    min_cell_faces = o.min_cell_faces
    switch_tightness = o.switch_tightness
    switch_min_angle_deg = o.switch_min_angle_deg
    min_switch_level = o.min_switch_level
    clean_min_angle_deg = o.clean_min_angle_deg
    clean_rounds = o.clean_rounds
    if levels < 0:
        raise errors.InputError(f"levels must be >= 0, got {levels}")
    fewest = min(n for _, n in STARTS.values())
    if smap is None and base is None and mesh.n_faces < fewest:
        raise errors.InputError(
            f"{mesh.name or 'the mesh'} has {mesh.n_faces} faces: a wrap's base mesh is a "
            f"simplification of it with at least {fewest} (an octahedron); subdivide it first"
        )
    _check_level_faces(fewest, levels, fewest=True)
    if not 0 < alpha <= 1:
        raise errors.InputError(f"alpha must be in (0, 1], got {alpha}")
    if count_weight < 0:
        raise errors.InputError(f"count_weight must be >= 0, got {count_weight}")
    if base is None:  # checked before the sphere map is made
        base_options = _base_options(o, base_options)
    secs: dict[str, float] = {}
    t0 = time.perf_counter()
    if smap is None:
        smap = sphere_map(
            mesh,
            method=sphere_method,
            max_aspect=sphere_max_aspect,
            stretch_iterations=sphere_stretch,
            progress=progress,
        )
    secs["sphere_map"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if base is None:
        base = base_mesh(smap, base_options, progress=progress)
    secs["base_mesh"] = time.perf_counter() - t0
    _check_level_faces(len(base.faces), levels)
    s = np.array(base.sphere)
    faces = np.array(base.faces)
    loc = smap.locate(s)
    c = smap.sphere[mesh.faces].sum(axis=1)
    centroids = np.ascontiguousarray(c / np.linalg.norm(c, axis=1, keepdims=True))
    weights = mesh.face_areas + count_weight * mesh.face_areas.mean()
    _, cell = cell_areas(s, faces, centroids, weights)
    out = [
        WrapLevel(
            0, mesh.xyz(loc), faces, s, loc, "base", 0, "-", _tightness(mesh, mesh.xyz(loc), faces)
        )
    ]
    phase = "parameter"
    switch = levels + 1
    for lev in range(1, levels + 1):
        t0 = time.perf_counter()
        n = len(s)
        faces, edges = _topo.subdivide(faces, n)
        mid = s[edges[:, 0]] + s[edges[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        s = np.vstack([s, mid])
        ml = smap.locate(mid, start=loc.face[edges[:, 0]])
        loc = SurfacePoints(np.r_[loc.face, ml.face], np.vstack([loc.bary, ml.bary]))
        cell = 4 * cell + 3  # the centre child: the walk starts there
        used = "area" if mesh.n_faces >= min_cell_faces * len(faces) else "edge"
        relax = _param_relax if phase == "parameter" else _surface_relax
        its = parameter_iterations if phase == "parameter" else surface_iterations
        s, loc, cell, ray = relax(smap, s, loc, faces, its, alpha, used, centroids, weights, cell)
        if phase == "surface" and clean_rounds > 0:
            s, loc = _fix_thin(smap, s, loc, faces, np.radians(clean_min_angle_deg), clean_rounds)
        x = mesh.xyz(loc)
        tight = _tightness(mesh, x, faces)
        out.append(WrapLevel(lev, x, faces, s, loc, phase, its, used, tight, ray))
        thin = np.degrees(triangle_quality(x, faces)[0].min()) < switch_min_angle_deg
        if phase == "parameter" and lev >= min_switch_level and (tight <= switch_tightness or thin):
            phase = "surface"
            switch = lev + 1
        secs[f"level_{lev}"] = time.perf_counter() - t0
        if progress:
            progress("shrink wrap", lev / max(levels, 1))
    return WrapResult(smap, base, out, switch, secs)


def level_metrics(mesh: Mesh, level: WrapLevel) -> dict:
    """Quality and distance figures of one level.

    Returns
    -------
    dict
        ``faces``, ``vertices``, ``flips`` (parameter-domain triangles with
        ``det <= 0``: the level is no longer a bijective image of the sphere),
        ``normal_flips`` (triangles whose normal points against the input's face normal at
        the closest point to their centroid: folds in space; a triangle bridging a sheet
        thinner than itself may count too), ``min_angle_deg``, ``min_angle_p01_deg`` (1st
        percentile), ``max_aspect``, ``mean_aspect``, ``rms`` and ``hausdorff`` (symmetric,
        as fractions of the input's bbox diagonal; the wrap is sampled at vertices and face
        centroids, the input at its vertices), ``rms_to_input``, ``rms_from_input``,
        ``tightness`` and ``ray_fraction`` (see :class:`WrapLevel`; ``None`` when the level
        did not project).
    """
    import igl

    x, f = level.vertices, level.faces
    ang, asp = triangle_quality(x, f)
    flips = int((spherical_orientation(level.sphere, f) <= 0).sum())
    diag = mesh.bbox_diagonal
    q = np.vstack([x, x[f].mean(axis=1)])
    cp = mesh.closest_points(q)
    d1 = cp.distance
    wn = np.cross(x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]])
    against = np.einsum("ij,ij->i", wn, mesh.face_normals[cp.points.face[len(x) :]]) < 0
    tree = igl.AABB()
    xc = np.ascontiguousarray(x)
    fc = np.ascontiguousarray(f)
    tree.init(xc, fc)
    sqd, _, _ = tree.squared_distance(xc, fc, np.ascontiguousarray(mesh.vertices))
    d2 = np.sqrt(np.maximum(np.asarray(sqd), 0.0))
    r1 = float(np.sqrt(np.mean(d1**2)) / diag)
    r2 = float(np.sqrt(np.mean(d2**2)) / diag)
    fin = np.isfinite(asp)
    return {
        "level": level.level,
        "phase": level.phase,
        "faces": len(f),
        "vertices": len(x),
        "flips": flips,
        "normal_flips": int(against.sum()),
        "min_angle_deg": float(np.degrees(ang.min())),
        "min_angle_p01_deg": float(np.degrees(np.quantile(ang, 0.01))),
        "max_aspect": float(asp[fin].max()) if fin.any() else float("inf"),
        "mean_aspect": float(asp[fin].mean()) if fin.any() else float("inf"),
        "rms": max(r1, r2),
        "rms_to_input": r1,
        "rms_from_input": r2,
        "hausdorff": float(max(d1.max(), d2.max()) / diag),
        "tightness": level.tightness,
        "ray_fraction": None if np.isnan(level.ray_fraction) else level.ray_fraction,
    }


def wrap_report(
    result: WrapResult,
    *,
    schemes: tuple[str, ...] = ("loop", "butterfly"),
    fractions: tuple[float, ...] = (0.01, 0.03, 0.1),
) -> dict:
    """The metrics of a wrap as a JSON-ready dict.

    Keys: ``input`` (name, faces, bbox diagonal), ``sphere_map`` (method, flips, max aspect,
    notes), ``base`` (faces, max / min cell surface area and their ratio, splits),
    ``switch_level``, ``levels`` (one :func:`level_metrics` dict per level: flips in the parameter
    domain and in space, min angle, aspect, RMS and Hausdorff as fractions of the bbox
    diagonal, share of ray hits in the projections), ``reconstruction`` (per
    scheme: RMS vertex error of the finest level decoded from the stream cut to its first
    1 %, 3 %, 10 % of bytes, "0%" the base mesh alone; fractions of the bbox diagonal), ``seconds``.
    """
    from meshfit.shrinkwrap.stream import encode_stream, reconstruction_errors

    mesh = result.sphere_map.mesh
    diag = mesh.bbox_diagonal
    b = result.base
    top = result.levels[-1]
    rec = {}
    for sch in schemes:
        st = encode_stream(top.vertices, b.faces, len(b.sphere), top.level, scheme=sch)
        errs = reconstruction_errors(st, top.vertices, (0.0, *fractions))
        rec[sch] = {
            "coefficients": st.n_coefficients,
            "bytes": len(st.to_bytes()),
            **{k: v / diag for k, v in errs.items()},
        }
    sm = result.sphere_map
    return {
        "input": {
            "name": mesh.name,
            "faces": mesh.n_faces,
            "vertices": mesh.n_vertices,
            "bbox_diagonal": diag,
        },
        "sphere_map": {
            "method": sm.method,
            "flips": sm.flips,
            "min_det": sm.min_det,
            "max_aspect": sm.max_aspect,
            "notes": list(sm.notes),
        },
        "base": {
            "faces": len(b.faces),
            "vertices": len(b.sphere),
            "cell_area_max": float(b.cell_area.max()),
            "cell_area_min": float(b.cell_area.min()),
            "cell_area_ratio": b.area_ratio,
            "splits": b.splits,
        },
        "switch_level": result.switch_level,
        "levels": [level_metrics(mesh, lv) for lv in result.levels],
        "reconstruction": rec,
        "seconds": {k: round(v, 3) for k, v in result.seconds.items()},
    }
