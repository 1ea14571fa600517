"""`resample_patch`: a patch resampled into a spring mesh, coarse to fine (sec. 5.3-5.11)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from meshfit import tol
from meshfit._kernels import springs as _k
from meshfit._threads import map_threads, n_workers
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.springs.features import FeatureLine, Sides, intersect_lines, prepare_features
from meshfit.springs.grid import SpringMesh, dilate_grid, grid_triangles
from meshfit.springs.init import chain_arc, chain_edge_faces, closest_approach, dijkstra_paths
from meshfit.springs.metrics import QUALITY_BOUNDS, _fidelity, _section_ends, spring_metrics
from meshfit.springs.planar import PlanarMap, square_map
from meshfit.springs.relax import (
    Sweeps,
    even_lines_in_map,
    folded_cells,
    grid_folds,
    relax,
    repair_folds,
    slide_side_points,
    unfold_in_map,
    unpinch_side_points,
    untangle,
    untangle_in_charts,
)
from meshfit.springs.state import State
from meshfit.springs.subdivide import subdivide

__all__ = ["SpringResult", "resample_patch", "resample_patches"]

#: level 0 gets this many times ``max_iter`` sweeps ...
COARSE_SWEEPS = 5
#: ... and converges to this fraction of tol.SPRING_CONVERGED ...
COARSE_EPS = 0.01
#: ... with Gauss-Seidel over-relaxed by this factor (its points travel far)
COARSE_OMEGA = 1.7
#: default ``polish`` of :func:`resample_patch`: arc-length sweeps on the coarse levels
POLISH_SWEEPS = 10
#: multiple of ``polish`` swept on the final level (above level 0)
FINAL_POLISH = 3
#: the final level's polish (tried when a grid line's spacing has a coefficient of
#: variation above `POLISH_CV_GOAL`) moves only the grid lines whose coefficient exceeds
#: this, and the points within `POLISH_REACH` lines of them
POLISH_LINE_CV = 0.1
POLISH_REACH = 2
#: ... and is kept only if it brings every line's coefficient of variation within this (on
#: a patch whose spacing the sweeps cannot even out, e.g. a pleat, they would only cost
#: fairness, and the stitched corners of such a patch meet less well)
POLISH_CV_GOAL = 0.15
#: ... which a level with a line above this does not reach (the sweeps are not tried: on
#: such patches they spend time for nothing)
POLISH_CV_HOPELESS = 0.3
#: ``rescue`` of :func:`resample_patch`: a final spring mesh that misses a vertex of its patch
#: by more than this many mean grid spacings is made again from the area-balanced map ...
RESCUE_SPACINGS = 1.0
#: ... and the new one is kept when it misses by at most this fraction as much and folds no
#: more cells
RESCUE_GAIN = 0.5
#: a kept grid that still misses its patch by more than ``RESCUE_SPACINGS`` is made again up
#: to this many levels finer (four times the points each), each finer grid kept when it misses
#: by at most ``RESCUE_GAIN`` as much (as a distance) with no larger share of folded cells: a
#: horn or an ear inside one patch needs more grid lines than the patch has vertices across
#: it ...
RESCUE_LEVELS = 2
#: ... while the grid has at most this many points per vertex of its patch ...
RESCUE_DENSITY = 16.0
#: ... and at most this many points (each finer level costs about four times the time and
#: memory of the last)
RESCUE_MAX_POINTS = 250_000
#: rows-then-columns passes of the rescue's evening of the final level
#: (`even_lines_in_map`): one pass can leave a folded cell that a round-off perturbation of
#: the mesh decides, so the result is not stable; two passes are (a third changes little)
EVEN_ROUNDS = 2


@dataclass(frozen=True, eq=False)
class SpringResult:
    """Result of :func:`resample_patch`.

    Attributes
    ----------
    levels : list of SpringMesh
        The relaxed spring mesh at every level, coarsest first (coarse previews).
    metrics : list of dict
        :func:`meshfit.springs.grid_metrics` of each level (empty dicts when not asked for).
    sweeps : list of int
        Relaxation sweeps used at each level.
    seconds : dict
        Wall time of ``init``, ``relax``, ``subdivide`` (summed over levels) and ``metrics``
        of the kept result, ``total`` (with a rescue's), and ``rescue`` when one was tried.
    rescued : bool
        The levels come from the rescue of :func:`resample_patch` (area-balanced map, light
        relaxation; or, with ``evened``, the relaxed grid with its final level's lines
        evened out in the map).
    finer : int
        Levels beyond the vertex-count rule's final level that the rescue or the
        ``tolerance`` of :func:`resample_patch` added (0 when none was kept).
    fairness : float or None
        Final fairness weight the levels were relaxed with: the ``fairness`` asked for, or 0
        where ``fairness_fallback`` took over (None when not recorded).
    remade : bool
        Level 0 was remade by ``fairness_fallback`` (arc-length force alone or rebalanced
        intervals).
    final_arc : bool
        The final level broke a quality bound and was relaxed once more with the arc-length
        force alone, which broke fewer bounds or left its grid lines more evenly spaced
        (``fairness_fallback``); its coarser levels keep ``fairness``.
    evened : bool
        The rescue evened out the final level's grid lines along their paths in the planar
        map (:func:`meshfit.springs.relax.even_lines_in_map`).
    distance : float or None
        With a ``tolerance``: the final level's two-sided largest distance to the patch
        (``fidelity_max`` of :func:`meshfit.springs.grid_metrics`, a fraction of ``scale``);
        above the tolerance when the point caps stopped the refinement. None otherwise.
    """

    levels: list[SpringMesh]
    metrics: list[dict]
    sweeps: list[int]
    seconds: dict[str, float] = field(default_factory=dict)
    rescued: bool = False
    finer: int = 0
    fairness: float | None = None
    remade: bool = False
    distance: float | None = None
    final_arc: bool = False
    evened: bool = False

    @property
    def final(self) -> SpringMesh:
        """The finest level."""
        return self.levels[-1]


def _sides(patch) -> Sides:
    mesh = patch.mesh
    chains = {
        "bottom": np.asarray(patch.sides[0]),
        "right": np.asarray(patch.sides[1]),
        "top": np.asarray(patch.sides[2])[::-1].copy(),
        "left": np.asarray(patch.sides[3])[::-1].copy(),
    }
    return Sides(
        chains,
        {k: chain_arc(mesh, c) for k, c in chains.items()},
        dict(zip(chains, chain_edge_faces(mesh, list(chains.values())), strict=True)),
    )


def _split_counts(spacing: float, breaks: list[float]) -> list[int]:
    """Intervals per section for a target spacing, at least 1 each."""
    lengths = np.diff(np.asarray(breaks, dtype=np.float64))
    return [max(1, round(float(length) / spacing)) for length in lengths]


def _as_counts(value, n: int, name: str) -> list[int] | None:
    if value is None:
        return None
    counts = [int(c) for c in value]
    if len(counts) != n or min(counts) < 1:
        raise InputError(
            f"{name} needs {n} positive interval counts (one per section), got {value!r}"
        )
    return counts


def _nearest_vertex(mesh: Mesh, face: int, bary: np.ndarray) -> int:
    return int(mesh.faces[face, int(np.argmax(bary))])


def _initialize(state: State) -> None:
    """Level-0 spring points: intersections of Dijkstra iso-curves and feature curves (sec. 5.4,
    sec. 5.11.2)."""
    mesh = state.mesh
    nu, nv = state.nu, state.nv
    state.face = np.zeros(nu * nv, dtype=np.int64)
    state.bary = np.zeros((nu * nv, 3))
    state.set_boundary()
    idx = np.arange(nu * nv).reshape(nu, nv)
    ucol = dict(zip(state.u_lines.tolist(), state.u_feat, strict=True))
    vrow = dict(zip(state.v_lines.tolist(), state.v_feat, strict=True))

    def ends(a, b):
        return (
            _nearest_vertex(mesh, state.face[a], state.bary[a]),
            _nearest_vertex(mesh, state.face[b], state.bary[b]),
        )

    ucols = [i for i in range(1, nu - 1) if i not in ucol]
    vrows = [j for j in range(1, nv - 1) if j not in vrow]
    paths = dijkstra_paths(
        mesh,
        [ends(idx[i, 0], idx[i, -1]) for i in ucols] + [ends(idx[0, j], idx[-1, j]) for j in vrows],
    )
    upath = dict(zip(ucols, paths[: len(ucols)], strict=True))
    vpath = dict(zip(vrows, paths[len(ucols) :], strict=True))
    state.s_u = [np.linspace(0.0, ln.total, nv) for ln in state.u_feat]
    state.s_v = [np.linspace(0.0, ln.total, nu) for ln in state.v_feat]
    su = dict(zip(ucol, state.s_u, strict=True))
    sv = dict(zip(vrow, state.s_v, strict=True))
    V = mesh.vertices
    # position of each vertex along each u path (-1: not on it); paths are loop-free
    upos = np.full((nu, mesh.n_vertices), -1, dtype=np.int64)
    for i, path in upath.items():
        upos[i, path] = np.arange(len(path))
    seats: list[tuple[int, int]] = []  # (grid point, mesh vertex) of path crossings
    for i in range(1, nu - 1):
        for j in range(1, nv - 1):
            fu: FeatureLine | None = ucol.get(i)
            fv: FeatureLine | None = vrow.get(j)
            if fu is not None and fv is not None:
                s, seg, t, _ = intersect_lines(mesh, fu, fv.xyz, fv.vertices)
                su[i][j] = s
                sv[j][i] = fv.position_of(min(seg, len(fv.arc) - 2), t)
            elif fu is not None:
                p = vpath[j]
                su[i][j] = intersect_lines(mesh, fu, V[p], p)[0]
            elif fv is not None:
                p = upath[i]
                sv[j][i] = intersect_lines(mesh, fv, V[p], p)[0]
            else:
                pu, pv = upath[i], vpath[j]
                iv = np.flatnonzero(upos[i, pv] >= 0)  # shared vertices, along pv
                iu = upos[i, pv[iv]]
                common = pv[iv]
                if common.size:
                    cost = np.abs(iu / max(len(pu) - 1, 1) - j / (nv - 1)) + np.abs(
                        iv / max(len(pv) - 1, 1) - i / (nu - 1)
                    )
                    v = int(common[np.argmin(cost)])
                else:
                    k, t, _, _, _ = closest_approach(V[pu], V[pv])
                    v = int(pu[k + (1 if t > 0.5 else 0)]) if len(pu) > 1 else int(pu[0])
                seats.append((idx[i, j], v))
    if seats:
        pts, verts = np.array(seats, dtype=np.int64).T
        vfp, vf = mesh.vertex_faces
        faces = vf[vfp[verts]]
        state.face[pts] = faces
        state.bary[pts] = (mesh.faces[faces] == verts[:, None]).astype(np.float64)
    for s in [*state.s_u, *state.s_v]:
        np.maximum.accumulate(s, out=s)  # keep the order along each feature curve
    state.set_feature_points()


def grid_parameters(state: State) -> np.ndarray:
    """(nu, nv, 2) unit-square parameters of the grid points: along each side the static
    resampling's arc-length fractions, inside blended linearly between opposite sides."""
    frac = {}
    for name in ("bottom", "top", "left", "right"):
        length = state.breaks[name][-1]
        pos = state.side_positions(name)
        frac[name] = pos / length if length > 0 else np.linspace(0.0, 1.0, len(pos))
    s = np.linspace(0.0, 1.0, state.nu)[:, None]
    t = np.linspace(0.0, 1.0, state.nv)[None, :]
    u = (1.0 - t) * frac["bottom"][:, None] + t * frac["top"][:, None]
    v = (1.0 - s) * frac["left"][None, :] + s * frac["right"][None, :]
    return np.stack([u, v], axis=2)


def _initialize_map(state: State, pmap: PlanarMap) -> None:
    """Level-0 spring points: images of the regular parameter grid under the planar map
    (free points), the static side resampling and the feature curves (sec. 5.11.1)."""
    nu, nv = state.nu, state.nv
    state.face = np.zeros(nu * nv, dtype=np.int64)
    state.bary = np.zeros((nu * nv, 3))
    uv = grid_parameters(state).reshape(-1, 2)
    free = state.free()
    pts = pmap.locate(uv[free])
    state.face[free] = pts.face
    state.bary[free] = pts.bary
    state.set_boundary()
    state.s_u = [np.linspace(0.0, ln.total, nv) for ln in state.u_feat]
    state.s_v = [np.linspace(0.0, ln.total, nu) for ln in state.v_feat]
    state.set_feature_points()


def _repair(state: State, pmap, left: int | None = None) -> None:
    """Fold repair: free points re-placed in the planar map, then moved one by one; side
    points of cells still folded slid along their sides, and the free points moved again;
    last, the free points around each cell still folded moved together in a chart. Done
    again, up to `REPAIR_PASSES` times in all, while each pass leaves fewer folded cells
    (a pass moves the points around a fold it cannot undo, which can free the next).
    ``left``: the folded cells of ``state`` when the caller has just counted them."""
    if left is None:
        left = int(folded_cells(state).sum())
    for _ in range(REPAIR_PASSES):
        unfold_in_map(state, pmap)
        now = repair_folds(state)
        if now and slide_side_points(state):
            now = repair_folds(state)
        if now:
            now = untangle_in_charts(state)
        if not now or now >= left:
            break
        left = now


#: most passes of the fold repair (`_repair`)
REPAIR_PASSES = 3


#: most points of a grid at a level asked for (``level`` without ``max_points``): 2,000 x
#: 2,000; each level has four times the points of the last, and a level well past the
#: vertex count exhausts the memory (tens of millions of points a few levels past it)
LEVEL_MAX_POINTS = 4_000_000


def _final_level(
    n_level0: tuple[int, int], n_vertices: int, level, max_points, patch: int = 0
) -> int:
    mu, mv = n_level0

    def count(k):
        return (mu * 2**k + 1) * (mv * 2**k + 1)

    if level is not None:
        if isinstance(level, bool) or int(level) != level or level < 0:
            raise InputError(f"level must be a non-negative integer, got {level!r}")
        k = int(level)
        if max_points is None and count(k) > LEVEL_MAX_POINTS:
            top = 0
            while count(top + 1) <= LEVEL_MAX_POINTS:
                top += 1
            raise InputError(
                f"level {k} gives patch {patch} ({n_vertices:,} vertices) a "
                f"{mu * 2**k + 1} x {mv * 2**k + 1} grid, {count(k):,} points; at most "
                f"{LEVEL_MAX_POINTS:,} are made at a level asked for: ask for level {top} or "
                "less"
            )
    else:
        # the level whose point count is closest (by ratio) to the patch's vertex count:
        # "spring points comparable to the number of mesh vertices" (sec. 5.6)
        k = 0
        while count(k + 1) <= n_vertices or count(k + 1) / n_vertices < n_vertices / count(k):
            k += 1
    if max_points is not None:
        if int(max_points) < count(0):
            raise InputError(f"max_points={max_points} is below the level-0 grid ({count(0)})")
        while k > 0 and count(k) > max_points:
            k -= 1
    return k


def _level0_sections(patch, sides: Sides, init_intervals: int, sections_u=None, sections_v=None):
    """Feature curves, section breaks and level-0 interval counts of a patch.

    Returns
    -------
    us, vs : list
        The patch's feature curves across u and v (:func:`prepare_features`).
    breaks : dict of str to list of float
        Arc length along each side at its ends and where feature curves meet it.
    counts_u, counts_v : list of int
        Level-0 intervals per section: ``sections_u`` / ``sections_v`` when given, else
        ``init_intervals`` along the shorter direction and the other in proportion, at least
        one per section (Krishnamurthy 2000, sec. 5.4: counts from the patch's aspect ratio).
    """
    us, vs, eb, et, el, er = prepare_features(
        patch.mesh, sides, patch.features, patch.feature_sides, patch.index
    )
    breaks = {
        "bottom": [0.0, *eb, float(sides.arcs["bottom"][-1])],
        "top": [0.0, *et, float(sides.arcs["top"][-1])],
        "left": [0.0, *el, float(sides.arcs["left"][-1])],
        "right": [0.0, *er, float(sides.arcs["right"][-1])],
    }
    len_u = 0.5 * (sides.arcs["bottom"][-1] + sides.arcs["top"][-1])
    len_v = 0.5 * (sides.arcs["left"][-1] + sides.arcs["right"][-1])
    spacing = min(len_u, len_v) / int(init_intervals)
    mid_u = [0.5 * (a + b) for a, b in zip(breaks["bottom"], breaks["top"], strict=True)]
    mid_v = [0.5 * (a + b) for a, b in zip(breaks["left"], breaks["right"], strict=True)]
    if not us:
        mid_u = [0.0, len_u]
    if not vs:
        mid_v = [0.0, len_v]
    counts_u = _as_counts(sections_u, len(us) + 1, "sections_u") or _split_counts(spacing, mid_u)
    counts_v = _as_counts(sections_v, len(vs) + 1, "sections_v") or _split_counts(spacing, mid_v)
    return us, vs, breaks, counts_u, counts_v


#: a polished coarse level is kept only if its median cell aspect ratio stays within this
#: bound (or does not grow) and no more of its cells fold
POLISH_ASPECT = 1.4


def _broken_bounds(state: State) -> int:
    """How many of the arc-length, aspect-ratio and fold bounds of
    :data:`meshfit.springs.QUALITY_BOUNDS` the current level breaks (0-3)."""
    return _bounds_and_cv(state)[0]


def _bounds_and_cv(state: State) -> tuple[int, float]:
    """The quality bounds the current level breaks (`_broken_bounds`) and its largest
    arc-length coefficient of variation over the grid lines."""
    folded, aspect, col, row = _shape(state)
    cv = float(max(col.max(initial=0.0), row.max(initial=0.0)))
    broken = (
        int(cv > QUALITY_BOUNDS["arc_cv_max"])
        + int(aspect > QUALITY_BOUNDS["aspect_median"])
        + int(folded > QUALITY_BOUNDS["folded"])
    )
    return broken, cv


def _relax_again(first: tuple[int, float]) -> bool:
    """Whether a final level whose first relaxation gives ``first`` (`_bounds_and_cv`) is
    relaxed once more with the arc-length force alone: when it breaks a bound."""
    return first[0] > 0


def _rebalanced(state: State) -> tuple[list[int], list[int]]:
    """Level-0 intervals per section that make the current grid's cells square on average:
    the direction with more intervals scaled by the ratio of the mean spacings across and
    along it (at least one interval per section)."""
    X = _k.grid_xyz(state.mesh.vertices, state.mesh.faces, state.face, state.bary)
    X = X.reshape(state.nu, state.nv, 3)
    du = float(np.linalg.norm(np.diff(X, axis=0), axis=2).mean())  # along u (rows' index)
    dv = float(np.linalg.norm(np.diff(X, axis=1), axis=2).mean())
    cu, cv = list(state.counts_u), list(state.counts_v)
    if du <= 0.0 or dv <= 0.0:
        return cu, cv
    if sum(cv) >= sum(cu):
        cv = [max(1, round(c * dv / du)) for c in cv]
    else:
        cu = [max(1, round(c * du / dv)) for c in cu]
    return cu, cv


def _polish_factor(k: int, final: int) -> int:
    """Multiple of ``polish`` swept on level ``k`` (of ``final``): `COARSE_SWEEPS` on level
    0, 2 on level 1, `FINAL_POLISH` on a final level above 0 (its new points start
    unevenly)."""
    if k == 0:
        return COARSE_SWEEPS
    return FINAL_POLISH if k == final else 2


def _line_cvs(
    mesh: Mesh, face: np.ndarray, bary: np.ndarray, shape, u_lines, v_lines, ends=None
) -> tuple[np.ndarray, np.ndarray, float]:
    """The largest arc-length coefficient of variation along each grid column (nv,) and
    row (nu,) over its sections, as :func:`meshfit.springs.spring_metrics` counts them, and
    the median cell aspect ratio, of the grid of face points ``face``, ``bary`` (row-major,
    ``shape = (nu, nv)``). ``ends``: the section ends along u and v of ``u_lines`` and
    ``v_lines`` when the caller keeps them (:func:`meshfit.springs.metrics._section_ends`)."""
    nu, nv = shape
    if ends is None:
        ends = (_section_ends(nu, u_lines), _section_ends(nv, v_lines))
    col, row, aspect = _k.line_spacing(
        mesh.vertices,
        mesh.faces,
        np.ascontiguousarray(face, dtype=np.int64),
        np.ascontiguousarray(bary, dtype=np.float64),
        nu,
        nv,
        *ends,
    )
    return col, row, float(aspect)


def _shape(state: State) -> tuple[int, float, np.ndarray, np.ndarray]:
    """Folded cells and median cell aspect ratio of the current level, and the columns' and
    rows' arc-length coefficients of variation (`_line_cvs`)."""
    mesh, nu, nv = state.mesh, state.nu, state.nv
    col, row, aspect = _line_cvs(
        mesh, state.face, state.bary, (nu, nv), None, None, ends=state._kind()[2:]
    )
    folded = grid_folds(mesh, state.face, state.bary, nu, nv)
    return int(folded.sum()), aspect, col, row


def _uneven_lines(col: np.ndarray, row: np.ndarray, cv: float, reach: int) -> np.ndarray:
    """(nu, nv) bool: the points of the grid columns and rows whose spacing's coefficient of
    variation (``col`` (nv,), ``row`` (nu,), see `_line_cvs`) exceeds ``cv``, and those within
    ``reach`` steps of them."""
    out = np.zeros((row.size, col.size), dtype=bool)
    out[:, col > cv] = True
    out[row > cv, :] = True
    if reach > 0 and out.any():
        out = dilate_grid(out, reach)
    return out


def _polish(
    state: State,
    sweeps: int,
    omega: float,
    forces: str,
    guard: bool,
    lines: bool = False,
    fold: bool = False,
) -> tuple[bool, int]:
    """Sweeps of the arc-length force alone on the current level, kept only when they fold
    no more cells and leave the median cell aspect ratio within :data:`POLISH_ASPECT` (or
    no higher than before); returns whether they were kept, and the folded cells of the level
    as it is left. With ``lines`` only the grid
    lines spaced unevenly (coefficient of variation above :data:`POLISH_LINE_CV`) and their
    neighbours within :data:`POLISH_REACH` lines move, and the sweeps are kept only if every
    line's coefficient of variation ends within :data:`POLISH_CV_GOAL`; they are tried only
    when some line is above that goal and none above :data:`POLISH_CV_HOPELESS`.
    """
    before = _shape(state)
    only = None
    if lines:
        worst = max(before[2].max(), before[3].max())
        if not POLISH_CV_GOAL < worst <= POLISH_CV_HOPELESS:
            return False, before[0]
        only = _uneven_lines(before[2], before[3], POLISH_LINE_CV, POLISH_REACH)
    saved = (
        state.face.copy(),
        state.bary.copy(),
        [a.copy() for a in state.s_u],
        [a.copy() for a in state.s_v],
    )
    schedule = Sweeps(max_iter=sweeps, ramp=0, fairness=0.0, omega=omega, eps=tol.SPRING_POLISHED)
    relax(state, schedule, tangent=forces == "tangent", guard=guard, only=only, fold=fold)
    after = _shape(state)
    ok = after[0] <= before[0] and after[1] <= max(POLISH_ASPECT, before[1])
    if lines:  # an uneven level the sweeps cannot even out (a pleat) keeps its fairness
        ok = ok and max(after[2].max(), after[3].max()) <= POLISH_CV_GOAL
    if not ok:
        state.face, state.bary = saved[0], saved[1]
        state.s_u, state.s_v = saved[2], saved[3]
    return ok, (after if ok else before)[0]


@dataclass(frozen=True)
class SpringOptions:
    """Options of :func:`resample_patch` (all have defaults; frozen, so one value can be
    shared by every patch and sent to other processes).

    Attributes
    ----------
    level : int, optional
        Final level to reach; default from the vertex-count rule. A level whose grid would
        have more than `LEVEL_MAX_POINTS` points raises InputError (unless ``max_points``
        is given).
    max_points : int, optional
        Upper bound on the final grid's point count: the final level is lowered to meet it.
    sections_u, sections_v : sequence of int, optional
        Level-0 intervals of each section between u (v) feature curves, one more entry than
        there are u (v) feature curves; default in proportion to the sections' lengths.
    init_intervals : int
        Level-0 intervals along the shorter direction (default 8: on coarser grids the
        Euclidean springs pull iso-curves tight across bumps and hollows, which finer levels
        cannot undo).
    fairness : float
        Final weight of the fairness force, in [0, 1]; the arc-length force gets
        ``1 - fairness`` (default 0.5).
    max_iter : int
        Relaxation sweeps allowed per level (default 10: new points start near their places;
        level 0 gets five times as many, over-relaxed).
    ramp : int
        Sweeps of level 0 over which the fairness weight grows from 0 (default 8); later
        levels start from points already in place and use the final weights.
    omega : float
        Over-relaxation factor of the Gauss-Seidel sweeps, in (0, 2) (default 1; level 0
        uses 1.7 times it).
    n_fair : int
        Local fairness moves after each FindMidPoint guess (default 2).
    forces : {"tangent", "euclidean"}
        Spring vectors between neighbours: turned into the moving point's tangent plane
        keeping their length (default; a first-order stand-in for the geodesic forces of
        sec. 5.5.3, which keeps grid lines from being pulled across bulges), or Euclidean
        (sec. 5.5).
    init : {"map", "dijkstra"}
        Level-0 points: the planar map's images of the regular parameter grid (default; a
        patch with feature curves in both directions falls back to "dijkstra", whose anchors
        are the curves' intersections), or the crossings of Dijkstra iso-curves (sec. 5.4),
        relaxed with the arc-length force first.
    midpoints : {"map", "findmid"}
        New points of a subdivision: the planar map's image of the mean parameter of their
        neighbours (default), or FindMidPoint (sec. 5.6).
    side_spacing : {"chord", "arc"}
        Static resampling of the sides: equal chords within each section while the grid
        spacing is at least `meshfit.springs.state.CHORD_MIN_EDGES` side edges, equal arc
        lengths on finer levels (default "chord": where a side bends, equal arc lengths give
        uneven boundary iso-curves and sheared cells next to the side; on finer levels equal
        chords would follow the zigzag of the side's edges and cut its corners), or equal
        arc lengths on every level ("arc", sec. 5.6).
    guard : bool
        Halve (up to three times) or drop a relaxation move that would fold more triangles
        of the moving point's four cells than before (default True).
    follow_folds : bool
        A spring vector from a point to a neighbour across a fold of the surface (their
        faces' normals more than 90 degrees apart, the other neighbour on the grid line not
        across) points along the grid line, away from that other neighbour, keeping its
        length, instead of the chord turned into the point's tangent plane (default False).
        Across a curled rim (an ear, a horn, a pleat) the turned chord can point anywhere,
        often back along the line, and the grid lines stop at the rim: the grid then misses
        what lies beyond it; following the line lets the grid cross the rim. Patches whose
        grids cross no such fold are unchanged. Not the default: elsewhere it can stretch
        cells or loosen the arc-length spacing slightly, and with ``rescue`` on (as the
        fit has it) the patches it helps are mostly those the rescue already handles.
    fairness_fallback : bool
        When level 0 breaks one of the arc-length, aspect-ratio or fold bounds of
        :data:`meshfit.springs.QUALITY_BOUNDS`, make it again with the arc-length force alone
        (fairness 0), then (without ``sections_u`` / ``sections_v``) with the intervals of the
        longer direction scaled so the cells are square on average, with ``fairness`` and
        with 0, until one breaks no bound. The remake breaking the fewest bounds is compared
        with the first level 0 once more on level 1 (bounds broken there first, then on
        level 0) and replaces it if it does better; the kept one is resampled to the final
        level (default True; ``fairness`` and ``remade`` of the result tell what was used).
        A patch that misses part of its surface (``rescue``) is rescued from the grid made
        without remakes. On tapered patches the fairness force bunches the grid lines toward
        the narrow side, which the arc-length-only remakes avoid; levels 0 and 1 are small,
        so the tries cost little. A final level above 0 that still breaks a bound is
        relaxed once more from its subdivided points with the arc-length force alone, and
        that relaxation is kept when it breaks fewer bounds or, as many, leaves a lower
        largest arc-length coefficient of variation (``final_arc`` of the result): where
        the grid steps over a pleat or a bulge the fairness force holds the grid lines
        apart across it. It costs a second relaxation of those final levels.
    untangle_rounds : int
        After each subdivision and each level's relaxation, rounds of fairness-only sweeps
        around folded cells (default 3; 0 turns it off).
    polish : int
        Sweeps of the arc-length force alone (guarded) after the relaxation of level 0
        (``polish`` times `COARSE_SWEEPS`) and of level 1 (``2 * polish``) when they are not
        the final level, and of the final level above 0 when a grid line's spacing has a
        coefficient of variation above ``POLISH_CV_GOAL`` (0.15) and none above
        ``POLISH_CV_HOPELESS`` (0.3) (``FINAL_POLISH * polish``, moving only the grid lines
        whose coefficient exceeds ``POLISH_LINE_CV`` (0.1) and the points within
        ``POLISH_REACH`` (2) lines of them);
        each stops once the moves fall below `meshfit.tol.SPRING_POLISHED` (default
        ``POLISH_SWEEPS`` = 10; 0: none). The final sweeps are kept only if they bring
        every line within ``POLISH_CV_GOAL`` (0.15). The fairness force's equilibrium
        spaces grid lines unevenly on curved patches; the coarse sweeps even the spacing out
        before subdivision, the final ones where the new points of the last subdivision
        left it uneven. A polished level is kept only where no more of its cells fold and
        its median cell aspect ratio stays within ``POLISH_ASPECT`` (1.4) or does not grow:
        on bulging and near-triangular patches the even spacing stretches the cells. Thanks
        to the early stop, the polish costs little where the spacing is already even.
    repair : bool
        After each subdivision and each level's relaxation, re-place the free points around
        folded cells harmonically in the planar map (`meshfit.springs.relax.unfold_in_map`,
        when there is a map), then move the free corners of cells still folded to fold-free
        places nearby (`meshfit.springs.relax.repair_folds`), then slide the side points of
        cells still folded along their sides and move the free corners again
        (`meshfit.springs.relax.slide_side_points`), and slide apart side points that
        nearly coincide with a neighbour where a side steps back
        (`meshfit.springs.relax.unpinch_side_points`; default True).
    rescue : bool
        Where a vertex of the patch lies more than ``RESCUE_SPACINGS`` (1) mean grid
        spacings from the final spring mesh, make the spring mesh again from the
        area-balanced map (:func:`meshfit.springs.planar.square_map` with ``balanced``)
        with the arc-length force alone, one sweep per level (five on level 0), and keep it
        when it misses by at most ``RESCUE_GAIN`` (half) as much and folds no more cells
        (with ``init`` and ``midpoints`` "map"; default False: the relaxation of the
        thesis; :func:`meshfit.fit` turns it on). A pleat or a bulge squeezed
        into a sliver of the square gets almost no grid points, and the full relaxation
        pulls grid lines away from it. The price: a rescued grid is less fair, and stitched
        fits with few controls meet less well at its corners. Without ``level``, a kept
        grid that still misses by more than ``RESCUE_SPACINGS`` is made the same way up to
        ``RESCUE_LEVELS`` (2) levels finer (at most ``RESCUE_DENSITY`` (16) points per
        patch vertex and ``RESCUE_MAX_POINTS`` in all); a finer grid is kept when it misses
        by at most ``RESCUE_GAIN`` as much, as a distance, with no larger share of folded
        cells (``finer`` of the result): a horn or an ear inside one patch needs more grid
        lines than the patch has vertices across it. Where neither a remake nor a finer
        grid is kept, the relaxed grid's final level has its grid lines evened out along
        their paths in the planar map (:func:`meshfit.springs.relax.even_lines_in_map`,
        ``EVEN_ROUNDS`` (2) passes, folds repaired), kept by the same rule (``evened`` of
        the result; the coarser levels and the fairness stay): a bulge that the map
        squeezes into a corner of the square folds the remakes' cells and is missed as
        much by finer grids.
    tolerance : float, optional
        Largest two-sided distance wanted between the final grid's triangulation and the
        patch, as a fraction of ``scale`` (the ``fidelity_max`` of
        :func:`meshfit.springs.grid_metrics`): while the final level misses it, the patch
        is resampled one level finer, up to ``TOLERANCE_LEVELS`` (3) levels beyond the
        vertex-count rule, ``RESCUE_DENSITY`` (16) points per patch vertex,
        ``RESCUE_MAX_POINTS`` and ``max_points`` (``finer`` and ``distance`` of the result
        tell how far it went); a finer grid with a larger share of folded cells is not
        kept, and ends the refinement. Each finer try relaxes every level again (the
        coarser levels come out the same). Not with ``level`` or ``rescue``. At the
        vertex-count level a grid of a scan misses by about as much as the scan's detail
        between two grid points; a tolerance below that takes a level or two more.
    metrics, fidelity : bool
        Compute :func:`meshfit.springs.grid_metrics` of every level (with the fidelity
        distances).
    scale : float, optional
        Length the fidelity distances are divided by (e.g. the whole model's bounding-box
        diagonal); default the patch mesh's.
    """

    level: int | None = None
    max_points: int | None = None
    sections_u: tuple[int, ...] | None = None
    sections_v: tuple[int, ...] | None = None
    init_intervals: int = 8
    fairness: float = 0.5
    max_iter: int = 10
    ramp: int = 8
    omega: float = 1.0
    n_fair: int = 2
    untangle_rounds: int = 3
    repair: bool = True
    polish: int = POLISH_SWEEPS
    forces: str = "tangent"
    init: str = "map"
    midpoints: str = "map"
    side_spacing: str = "chord"
    guard: bool = True
    follow_folds: bool = False
    fairness_fallback: bool = True
    rescue: bool = False
    tolerance: float | None = None
    metrics: bool = True
    fidelity: bool = True
    scale: float | None = None

    def __post_init__(self) -> None:
        for name in ("sections_u", "sections_v"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, tuple(int(x) for x in value))


def _checked_options(options: SpringOptions | None) -> SpringOptions:
    """``options`` (default ``SpringOptions()``) once its values pass the checks of
    :func:`resample_patch`; raises InputError naming the first bad one."""
    o = options if options is not None else SpringOptions()
    if not isinstance(o, SpringOptions):
        raise InputError(f"options must be SpringOptions, got {type(o).__name__}")
    if not 0.0 <= o.fairness <= 1.0:
        raise InputError(f"fairness must be in [0, 1], got {o.fairness}")
    if o.forces not in ("tangent", "euclidean"):
        raise InputError(f"forces must be 'tangent' or 'euclidean', got {o.forces!r}")
    if o.init not in ("map", "dijkstra"):
        raise InputError(f"init must be 'map' or 'dijkstra', got {o.init!r}")
    if o.side_spacing not in ("chord", "arc"):
        raise InputError(f"side_spacing must be 'chord' or 'arc', got {o.side_spacing!r}")
    if o.midpoints not in ("map", "findmid"):
        raise InputError(f"midpoints must be 'map' or 'findmid', got {o.midpoints!r}")
    polish = o.polish
    if isinstance(polish, bool) or int(polish) != polish or polish < 0:
        raise InputError(f"polish must be a non-negative integer, got {polish!r}")
    if not 0.0 < o.omega < 2.0:
        raise InputError(f"omega must be in (0, 2), got {o.omega}")
    if int(o.init_intervals) < 1:
        raise InputError(f"init_intervals must be >= 1, got {o.init_intervals}")
    if o.tolerance is not None:
        _check_tolerance(o)
    _check_level(o)
    return o


def check_spring_options(options: SpringOptions) -> SpringOptions:
    """``options`` once its values pass the checks :func:`resample_patch` makes before any
    patch (for callers that validate every option before any work).

    Parameters
    ----------
    options : SpringOptions

    Returns
    -------
    SpringOptions
        ``options`` itself.

    Raises
    ------
    meshfit.errors.InputError
        Naming the first bad value: a weight or a mode out of range, a negative or
        fractional ``level``, a ``level`` whose grids would pass `LEVEL_MAX_POINTS` even for
        a one-cell patch, ``max_points`` below 4.
    """
    return _checked_options(options)


def _check_level(o: SpringOptions) -> None:
    """``level`` a non-negative integer that does not give even a one-cell level-0 grid more
    than `LEVEL_MAX_POINTS` points (without ``max_points``); ``max_points`` at least 4."""
    level, most = o.level, o.max_points
    if level is not None:
        if isinstance(level, bool) or int(level) != level or level < 0:
            raise InputError(f"level must be a non-negative integer, got {level!r}")
        if most is None and (2 ** int(level) + 1) ** 2 > LEVEL_MAX_POINTS:
            top = 0
            while (2 ** (top + 1) + 1) ** 2 <= LEVEL_MAX_POINTS:
                top += 1
            raise InputError(
                f"level {level} gives every patch more than {LEVEL_MAX_POINTS:,} grid points: "
                f"ask for level {top} or less"
            )
    if most is not None and (isinstance(most, bool) or int(most) != most or most < 4):
        raise InputError(f"max_points must be an integer >= 4, got {most!r}")


def _check_tolerance(o: SpringOptions) -> None:
    """A ``tolerance`` is a positive number and leaves ``level`` and ``rescue`` unset."""
    tolerance = o.tolerance
    try:
        positive = not isinstance(tolerance, bool) and 0.0 < float(tolerance) < np.inf
    except (TypeError, ValueError):
        positive = False
    if not positive:
        raise InputError(f"tolerance must be a positive number, got {tolerance!r}")
    if o.level is not None or o.rescue:
        raise InputError("tolerance chooses the final level: not with level or rescue")


def _check_patch(patch) -> None:
    from meshfit.layout.patch import Patch

    if not isinstance(patch, Patch):
        raise InputError(
            f"patch must be a meshfit.layout.Patch (from extract_patches), got "
            f"{type(patch).__name__}"
        )


def resample_patch(
    patch,
    options: SpringOptions | None = None,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> SpringResult:
    """Resample a four-sided patch into a spring mesh, coarse to fine.

    Level 0 starts from the images of a regular parameter grid under a mean-value map of the
    patch onto the unit square (fold-free: the map is a bijection), or from Dijkstra
    iso-curves between points at equal arc-length fractions of opposite sides (sec. 5.4);
    ``init_intervals`` intervals along the shorter direction, the other direction in
    proportion to the patch's aspect ratio. Each level is relaxed (arc-length force eq. 5.1
    and fairness force sec. 5.5.2, weighted per eq. 5.4, moves walked inside the patch),
    then subdivided, its new points placed by the planar map (the image of their
    neighbours' mean parameter) or by FindMidPoint (sec. 5.6), the sides resampled
    statically. Subdivision stops at the level whose spring point count is closest to the
    patch's vertex count (or at ``level``; never above ``max_points``).

    Parameters
    ----------
    patch : meshfit.layout.Patch
        A four-sided disk patch; its feature curves become iso-curves of the spring mesh.
    options : SpringOptions, optional
        Default ``SpringOptions()``: the level from the vertex-count rule, the relaxation
        of the thesis with this module's guards and remakes.
    progress : callable(done, total), keyword-only, optional
        Called after each level (with a ``tolerance``, again from the first level for each
        finer try, ``total`` counting its levels).

    Returns
    -------
    SpringResult
        Every level's spring mesh, metrics, sweep counts and timings.

    Raises
    ------
    meshfit.errors.FeatureCurveError
        A feature curve does not run side to side, or two of one direction cross.
    meshfit.errors.InputError
        Bad option values; a ``level`` whose grid would exceed `LEVEL_MAX_POINTS` points.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 5.3-5.8 (spring mesh), sec. 5.10-5.11 (feature curves).
    """
    o = _checked_options(options)
    _check_patch(patch)
    sides = _sides(patch)

    def run(
        balanced: bool,
        fairness: float,
        max_iter: int,
        polish: int,
        progress,
        finer: int = 0,
        fallback: bool = o.fairness_fallback,
        even: bool = False,
    ) -> SpringResult:
        """The coarse-to-fine resampling with these settings (the rest from ``o``)."""
        settings = _RunSettings(balanced, fairness, max_iter, polish, finer, fallback, even)
        return _Resampling(patch, sides, o, settings).result(progress)

    res = run(False, o.fairness, o.max_iter, o.polish, progress)
    if o.tolerance is not None:
        return _to_tolerance(
            patch.mesh, res, float(o.tolerance), o.scale, o.max_points,
            lambda extra: run(False, o.fairness, o.max_iter, o.polish, progress, extra),
        )  # fmt: skip
    if not (o.rescue and o.init == "map" and o.midpoints == "map"):
        return res
    return _rescue(patch.mesh, res, o, run)


@dataclass(frozen=True)
class _RunSettings:
    """What one run of `_Resampling` takes besides the options: the map (area-balanced or
    not), the relaxation's fairness weight, sweeps and polish, ``finer`` levels beyond the
    vertex-count rule's, the level-0 remakes (``fallback``) and, with ``even``, the final
    level's grid lines evened out in the map."""

    balanced: bool
    fairness: float
    max_iter: int
    polish: int
    finer: int = 0
    fallback: bool = True
    even: bool = False


class _Resampling:
    """One coarse-to-fine resampling of a patch (:func:`resample_patch` with one set of
    `_RunSettings`): level 0 (remade where it breaks a quality bound), then each finer level
    subdivided, relaxed, polished and repaired."""

    def __init__(self, patch, sides: Sides, o: SpringOptions, run: _RunSettings) -> None:
        self.t0 = time.perf_counter()
        self.patch, self.mesh, self.sides, self.o, self.run = patch, patch.mesh, sides, o, run
        self.us, self.vs, self.breaks, self.counts_u, self.counts_v = _level0_sections(
            patch, sides, o.init_intervals, o.sections_u, o.sections_v
        )
        maps = "map" in (o.init, o.midpoints)
        self.pmap = square_map(self.mesh, sides, balanced=run.balanced) if maps else None
        self.mapped = o.init == "map" and not (self.us and self.vs)
        self.seconds = {
            "init": time.perf_counter() - self.t0, "relax": 0.0, "subdivide": 0.0, "metrics": 0.0
        }  # fmt: skip

    def final_level(self, cu: list[int], cv: list[int]) -> int:
        o = self.o
        return self.run.finer + _final_level(
            (sum(cu), sum(cv)), self.mesh.n_vertices, o.level, o.max_points, self.patch.index
        )

    def settle(self, state: State, reach: int, sweeps: int, folds: int | None = None) -> None:
        """Untangling rounds around folded cells (``reach`` rings), then the fold repair and
        the sliding apart of pinched side points. ``folds``: the folded cells of ``state``
        when the caller has just counted them (0: the untangling is skipped)."""
        o = self.o
        left = None
        if o.untangle_rounds and folds == 0:
            left = 0
        elif o.untangle_rounds:
            left = untangle(
                state,
                rounds=o.untangle_rounds,
                sweeps=sweeps,
                reach=reach,
                tangent=o.forces == "tangent",
                guard=o.guard,
                fold=o.follow_folds,
            )
        if o.repair:
            if left != 0:  # (with no folded cell left the repair has nothing to do)
                _repair(state, self.pmap, left)
            unpinch_side_points(state)

    def level_step(self, state: State, k: int, fairness: float, final: int) -> int:
        """Relaxation, polish and fold repair of level ``k``; the sweeps done."""
        o, max_iter, polish = self.o, self.run.max_iter, self.run.polish
        # level 0 starts from graph paths and must travel far: it is relaxed to a tighter
        # tolerance with more sweeps (it is small); later levels only settle new points
        schedule = Sweeps(
            max_iter=max_iter if k else max_iter * COARSE_SWEEPS,
            ramp=o.ramp,
            fairness=fairness,
            omega=o.omega if k else min(1.9, o.omega * COARSE_OMEGA),
            # a graph-path start is pulled into place by the arc-length force first; a mapped
            # start is already spread out and gets the final weights at once
            start=0 if k == 0 and not self.mapped else o.ramp,
            eps=tol.SPRING_CONVERGED * (1.0 if k else COARSE_EPS),
        )
        done, _ = relax(
            state, schedule, tangent=o.forces == "tangent", guard=o.guard, fold=o.follow_folds
        )
        folds = None
        if polish and ((k <= 1 and k < final) or 0 < k == final):  # arc-length sweeps
            n = int(polish) * _polish_factor(k, final)
            folds = _polish(
                state, n, o.omega, o.forces, o.guard, lines=k == final, fold=o.follow_folds
            )[1]
        self.settle(state, 2, max_iter, folds)
        return done

    def advance(
        self, state: State, k: int, fairness: float, final: int, again: bool = False
    ) -> tuple[State, int, dict]:
        """Subdivide to level ``k`` and relax it: the state kept, the sweeps done and
        what else was done (``final_arc``, ``evened``). With ``again`` a level that
        breaks a quality bound is relaxed once more from its subdivided points with the
        arc-length force alone, kept when it breaks fewer bounds or as many with a lower
        largest arc-length coefficient of variation. With ``even`` of the run the grid
        lines of the final level are then evened out in the planar map
        (`even_lines_in_map`) and its folds repaired (a rescue weighs the result)."""
        max_iter = self.run.max_iter
        t = time.perf_counter()
        pmap = self.pmap if self.o.midpoints == "map" else None
        subdivide(state, n_fair=self.o.n_fair, pmap=pmap)
        self.settle(state, 1, max_iter)  # mid-points placed across a fold: smooth them out
        self.seconds["subdivide"] += time.perf_counter() - t
        t = time.perf_counter()
        trial = state.copy() if again and fairness > 0.0 else None
        done = self.level_step(state, k, fairness, final)
        kept = {"final_arc": False, "evened": False}
        score = _bounds_and_cv(state) if trial is not None else None
        if trial is not None and _relax_again(score):
            done_again = self.level_step(trial, k, 0.0, final)
            trial_score = _bounds_and_cv(trial)
            if trial_score < score:
                state, done, score = trial, done_again, trial_score
                kept["final_arc"] = True
        if self.run.even and k == final and even_lines_in_map(state, self.pmap, rounds=EVEN_ROUNDS):
            self.settle(state, 2, max_iter)  # rows and columns evened apart: folds
            kept["evened"] = True
        self.seconds["relax"] += time.perf_counter() - t
        return state, done, kept

    def start(self, cu: list[int], cv: list[int], f: float) -> dict:
        """Level 0 with these intervals and fairness weight, as a candidate: its state,
        weight, final level, sweeps and snapshots per level done, and bounds broken."""
        t = time.perf_counter()
        state = State(
            self.mesh, self.patch.index, self.sides, self.us, self.vs, self.breaks, cu, cv
        )
        state.chords = self.o.side_spacing == "chord"
        if self.mapped:
            _initialize_map(state, self.pmap)
        else:
            _initialize(state)
        final = self.final_level(cu, cv)
        self.seconds["init"] += time.perf_counter() - t
        t = time.perf_counter()
        done = self.level_step(state, 0, f, final)
        self.seconds["relax"] += time.perf_counter() - t
        broken = [_broken_bounds(state)] if self.run.fallback else [0]
        return {"state": state, "fair": f, "final": final, "done": [done],
                "snaps": [state.snapshot()], "broken": broken}  # fmt: skip

    def remakes(self, best: dict) -> list[tuple[list[int], list[int], float]]:
        """Intervals and fairness weights a level 0 that breaks a quality bound is made
        again with: the arc-length force alone, then intervals rebalanced to square cells
        (with the weight asked for, then alone) where no sections were given."""
        fairness = self.run.fairness
        tries = [] if fairness == 0.0 else [(self.counts_u, self.counts_v, 0.0)]
        if self.o.sections_u is None and self.o.sections_v is None:
            cu, cv = _rebalanced(best["state"])
            if (cu, cv) != (self.counts_u, self.counts_v):
                tries += [(cu, cv, f) for f in dict.fromkeys((fairness, 0.0))]
        return tries

    def remade(self, best: dict) -> tuple[dict, bool]:
        """The level-0 candidate kept, and whether it is a remake. The first remake that
        breaks the fewest bounds is weighed against ``best`` once more on level 1 (where a
        level 0 that looked better can turn worse), and kept if better there."""
        if not best["broken"][0]:
            return best, False
        alt = None
        for cu, cv, f in self.remakes(best):
            c = self.start(cu, cv, f)
            if c["broken"][0] < (alt or best)["broken"][0]:
                alt = c
                if not c["broken"][0]:
                    break
        if alt is None:
            return best, False
        if min(best["final"], alt["final"]) >= 1:
            for c in (best, alt):
                c["done"].append(self.advance(c["state"], 1, c["fair"], c["final"])[1])
                c["snaps"].append(c["state"].snapshot())
                c["broken"].insert(0, _broken_bounds(c["state"]))
        if alt["broken"] < best["broken"]:  # level 1 first, then level 0
            return alt, True
        return best, False

    def result(self, progress) -> SpringResult:
        """Every level from 0 to the final one, with metrics, sweeps and timings."""
        o = self.o
        best, remade = self.remade(self.start(self.counts_u, self.counts_v, self.run.fairness))
        state, fairness, final = best["state"], best["fair"], best["final"]
        levels, mets, sweeps = [], [], []
        kept = {"final_arc": False, "evened": False}
        for k in range(final + 1):
            if k < len(best["snaps"]):
                snap, done = best["snaps"][k], best["done"][k]
            else:
                again = self.run.fallback and k == final
                state, done, kept = self.advance(state, k, fairness, final, again=again)
                snap = state.snapshot()
            sweeps.append(done)
            levels.append(snap)
            t = time.perf_counter()
            mets.append(
                spring_metrics(self.mesh, snap, fidelity=o.fidelity, scale=o.scale)
                if o.metrics
                else {}
            )
            self.seconds["metrics"] += time.perf_counter() - t
            if progress is not None:
                progress(k + 1, final + 1)
        seconds = {**self.seconds, "total": time.perf_counter() - self.t0}
        return SpringResult(levels, mets, sweeps, seconds, fairness=fairness, remade=remade, **kept)


def _rescue(mesh: Mesh, res: SpringResult, o: SpringOptions, run) -> SpringResult:
    """The ``rescue`` of :func:`resample_patch` for its first result ``res``; ``run`` makes
    a resampling with other settings (the arguments of the ``run`` there)."""
    t = time.perf_counter()
    first = res.seconds["total"]
    kept, finer = res, 0
    # most grids miss no vertex (`_misses` settles that without exact distances); the rest
    # may be remade, as below
    if _misses(mesh, res.final):
        if res.remade:
            # the rescue weighs its remakes against the grid of the thesis's relaxation (a
            # remade level 0 misses less but keeps the rescue from a finer, closer grid)
            res = run(False, o.fairness, o.max_iter, o.polish, None, fallback=False)
        # area-balanced map, arc length only, one sweep per level
        kept, miss = _rescued(mesh, res, lambda: run(True, 0.0, 1, 0, None, fallback=False))
        kept, miss, finer = _rescue_finer(mesh, res, kept, miss, o, run)
        if kept is res:
            # neither remake nor a finer grid kept (they fold cells, or miss as much): the
            # same grid with its final level's lines evened out along their paths in the map
            # (the coarser levels and the fairness kept; evened from the grid without the
            # fallback's arc-length retry, which can leave a folded cell the evening keeps)
            kept, miss = _rescued(
                mesh,
                res,
                lambda: run(
                    False, o.fairness, o.max_iter, o.polish, None, fallback=False, even=True
                ),
            )
    spent = time.perf_counter() - t
    seconds = {**kept.seconds, "rescue": spent, "total": first + spent}
    return replace(kept, seconds=seconds, finer=finer)


def _rescue_finer(
    mesh: Mesh, res: SpringResult, kept: SpringResult, miss, o: SpringOptions, run
) -> tuple[SpringResult, tuple[float, float], int]:
    """A grid still missing its patch made again up to `RESCUE_LEVELS` levels finer (a
    protrusion inside the patch needs more grid lines), each kept when it misses by at most
    `RESCUE_GAIN` as much and folds no larger share of cells: the grid kept, its miss and
    the levels added."""
    finer = 0
    for extra in range(1, RESCUE_LEVELS + 1 if o.level is None else 1):
        if miss[0] <= RESCUE_SPACINGS:
            break
        if _points_at(res.final.shape, extra) > _point_cap(mesh, o.max_points):
            break
        cand, c_miss = _rescued(
            mesh,
            run(False, o.fairness, o.max_iter, o.polish, None, extra, fallback=False),
            lambda e=extra: run(True, 0.0, 1, 0, None, e, fallback=False),
        )
        if c_miss[1] <= RESCUE_GAIN * miss[1] and _fold_share(mesh, cand) <= _fold_share(
            mesh, kept
        ):
            kept, miss, finer = cand, c_miss, extra
    return kept, miss, finer


def resample_patches(
    patches: Sequence,
    options: SpringOptions | None = None,
    *,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[SpringResult]:
    """:func:`resample_patch` of every patch of a layout, on threads; results in order.

    The relaxation, subdivision and planar-map kernels release the GIL, so the patches of
    a layout resample in parallel (``benchmarks/springs.py`` measures it). Each patch's grid
    is the same whatever the number of workers (a patch is resampled by one thread, from
    its own mesh).

    Parameters
    ----------
    patches : sequence of meshfit.layout.Patch
        Four-sided disk patches (e.g. :func:`meshfit.layout.extract_patches`).
    workers : int, keyword-only, optional
        Threads (default: every core); 1 resamples the patches one after the other.
    progress : callable(done, total), keyword-only, optional
        Called after each patch, in the calling thread.
    options : SpringOptions, optional
        The options of every patch (default ``SpringOptions()``).

    Returns
    -------
    list of SpringResult
        One per patch, in the order of ``patches``.

    Raises
    ------
    meshfit.errors.InputError
        ``workers`` is not an integer >= 1, or an option value is bad (raised from the patch
        that met it; the patches not yet started are dropped).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.3 (each patch resampled on its own) and sec. 5.13
       (the spring meshes of a whole model's patches).
    """
    count = n_workers(workers)
    patches = list(patches)
    # larger patches first, so the last one to start is small
    cost = [float(p.mesh.n_vertices) for p in patches]
    return map_threads(
        lambda p: resample_patch(p, options), patches, count, cost=cost, progress=progress
    )


def _rescued(
    mesh: Mesh, res: SpringResult, remake: Callable[[], SpringResult]
) -> tuple[SpringResult, tuple[float, float]]:
    """``res``, or its ``remake`` (marked rescued) where ``res`` misses a vertex of its patch
    by more than ``RESCUE_SPACINGS`` grid spacings and the remake misses by at most
    ``RESCUE_GAIN`` as much with no more folded cells; with the kept one's `_miss`."""
    miss = _miss(mesh, res.final)
    if miss[0] > RESCUE_SPACINGS:
        # the grid misses part of its patch (a pleat or a bulge the map squeezes, which the
        # relaxation pulls the grid lines away from)
        alt = remake()
        alt_miss = _miss(mesh, alt.final)
        if alt_miss[0] <= RESCUE_GAIN * miss[0] and _folds(mesh, alt) <= _folds(mesh, res):
            return replace(alt, rescued=True), alt_miss
    return res, miss


#: most levels a ``tolerance`` adds beyond the vertex-count rule's final level
TOLERANCE_LEVELS = 3


def _to_tolerance(
    mesh: Mesh, res: SpringResult, tolerance: float, scale, max_points, finer_run
) -> SpringResult:
    """``res`` or the first of its finer remakes (``finer_run(extra)``) whose final grid is
    within ``tolerance`` of the patch (see ``tolerance`` of :func:`resample_patch`)."""
    t = time.perf_counter()
    first = res.seconds["total"]
    diag = mesh.bbox_diagonal if scale is None else float(scale)
    cap = _point_cap(mesh, max_points)

    def distance(r: SpringResult) -> float:
        if "fidelity_max" in r.metrics[-1]:  # measured by the run already (same scale)
            return float(r.metrics[-1]["fidelity_max"])
        nu, nv = r.final.shape
        P = r.final.xyz.reshape(-1, 3)
        return _fidelity(mesh, P, grid_triangles(nu, nv), diag)["fidelity_max"]

    dist, finer = distance(res), 0
    for extra in range(1, TOLERANCE_LEVELS + 1):
        if dist <= tolerance or _points_at(res.final.shape, 1) > cap:
            break
        cand = finer_run(extra)
        if _fold_share(mesh, cand) > _fold_share(mesh, res):  # finer, but folded
            break
        res, finer, dist = cand, extra, distance(cand)
    spent = time.perf_counter() - t
    seconds = {**res.seconds, "tolerance": spent, "total": first + spent}
    return replace(res, seconds=seconds, finer=finer, distance=dist)


def _point_cap(mesh: Mesh, max_points: int | None) -> int:
    """Most points a finer grid of the rescue or the tolerance may have: `RESCUE_DENSITY`
    per patch vertex, `RESCUE_MAX_POINTS` and ``max_points``."""
    cap = min(RESCUE_DENSITY * mesh.n_vertices, RESCUE_MAX_POINTS)
    return cap if max_points is None else min(cap, int(max_points))


def _points_at(shape: tuple[int, int], extra: int) -> int:
    """Points of a grid of ``shape`` subdivided ``extra`` more times."""
    return ((shape[0] - 1) * 2**extra + 1) * ((shape[1] - 1) * 2**extra + 1)


def _fold_share(mesh: Mesh, res: SpringResult) -> float:
    """Folded cells of a result's final level over its cell count."""
    nu, nv = res.final.shape
    return _folds(mesh, res) / ((nu - 1) * (nv - 1))


def _miss(mesh: Mesh, spring: SpringMesh) -> tuple[float, float]:
    """Largest distance from a vertex of ``mesh`` to the triangulated spring mesh: over the
    spring mesh's mean grid spacing, and as a length."""
    from meshfit.mesh.locate import triangle_distances

    h, P, T, tree = _spacing_and_soup(spring)
    d, _ = triangle_distances(mesh.vertices, P, T, tree=tree)
    worst = float(d.max())
    return (worst / h if h > 0 else 0.0), worst


def _misses(mesh: Mesh, spring: SpringMesh) -> bool:
    """``_miss(mesh, spring)[0] > RESCUE_SPACINGS``, with exact distances only for the
    vertices that have no triangle within ``tol.WITHIN_MARGIN`` (relative) inside that
    limit."""
    from meshfit.mesh.locate import triangle_distances, triangles_within

    h, P, T, tree = _spacing_and_soup(spring)
    if not h > 0:
        return False
    limit = RESCUE_SPACINGS * h * (1.0 - tol.WITHIN_MARGIN)
    near = triangles_within(mesh.vertices, P, T, limit, tree=tree)
    if near.all():
        return False
    d, _ = triangle_distances(mesh.vertices[~near], P, T, tree=tree)
    return float(d.max()) / h > RESCUE_SPACINGS


def _spacing_and_soup(spring: SpringMesh):
    """A spring mesh's mean grid spacing, its points and triangles, and their tree."""
    from meshfit.mesh.locate import grid_tree
    from meshfit.springs.grid import grid_triangles

    X = spring.xyz
    nu, nv = X.shape[:2]
    h = 0.5 * (
        np.linalg.norm(np.diff(X, axis=0), axis=2).mean()
        + np.linalg.norm(np.diff(X, axis=1), axis=2).mean()
    )
    P = np.ascontiguousarray(X.reshape(-1, 3))
    T = grid_triangles(nu, nv)
    return h, P, T, grid_tree(P, T, [(nu, nv)])


def _folds(mesh: Mesh, res: SpringResult) -> int:
    """Folded cells of a result's final level (the `grid_metrics` test)."""
    f = res.final
    nu, nv = f.shape
    return int(grid_folds(mesh, f.points.face, f.points.bary, nu, nv).sum())
