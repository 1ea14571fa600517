"""Spring mesh relaxation: arc-length and fairness forces, moves walked on the patch (sec. 5.5)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from meshfit import tol
from meshfit._kernels import frozen
from meshfit._kernels import springs as _k
from meshfit.errors import InputError
from meshfit.springs.grid import FREE, dilate_grid
from meshfit.springs.state import State

__all__ = [
    "Sweeps",
    "even_lines_in_map",
    "folded_cells",
    "relax",
    "repair_folds",
    "unfold_in_map",
    "untangle",
    "untangle_in_charts",
]

#: walk steps never cross more faces than this (a relaxation step is about one spring long)
_MAX_FACES = 10_000
#: fold repair: trial directions per point, and the cosine between a grid triangle's normal
#: and its corners' surface normals below which a triangle counts as nearly folded
REPAIR_DIRECTIONS = 16
REPAIR_MARGIN = 0.3
#: trial places of a side point of a folded cell (`slide_side_points`), as fractions of the
#: way to the neighbouring side point before (negative) or after it
SLIDE_FRACTIONS = tuple(float(f) for f in np.linspace(-0.9, 0.9, 19) if abs(f) > 1e-9)
#: a sliding side point may take the side points within this many places along, by amounts
#: tapering linearly to zero (stopping at patch corners and feature-curve ends), so that the
#: side's spacing changes by a fraction of the slide per interval instead of all of it at once
#: (a longer taper unfolds no more cells, and the stitched fit of a near-triangular patch
#: can then face away from its grid at a node)
SLIDE_TAPER = 2
#: a side point closer than this fraction of its side's median spacing to a neighbouring side
#: point is slid apart (`unpinch_side_points`; a higher ratio slides points of sides that
#: are not pinched, and the grid can then miss the surface by more)
PINCH_RATIO = 0.4
#: untangling in a chart (`untangle_in_charts`): grid steps around a folded cell that may
#: move, Gauss-Seidel rounds, the largest angle between the window's surface normals and
#: their mean for which its tangent plane is a usable chart, and the least signed area of a
#: cell triangle aimed at, as a fraction of the squared grid spacing
CHART_REACH = 3
CHART_ROUNDS = 30
CHART_MAX_SPREAD = 60.0
CHART_GOAL = 0.05
#: evening grid lines in the planar map (`even_lines_in_map`): points per grid interval at
#: which a line's path in the square is sampled on the surface to measure its arc length
#: (enough to resolve pleats of the surface: denser sampling changes the evened grids no
#: more than two runs at the same density differ, and costs time)
LINE_SAMPLES = 8

#: `relax` sweeps a free point again only while it or one of its four neighbours moved more
#: than this many times the convergence tolerance (``eps``) of its spring lengths in the
#: sweep before: this trades time against quality (a higher factor skips more sweeps, and
#: patches that met the quality bounds begin to break them)
LAZY_MOVES = 2.0


def _curve_step(state: State, X: np.ndarray, w_arc: float, w_fair: float) -> float:
    """Move the curve points along their feature curves (eq. 5.14-5.17); returns the root-mean-
    square move relative to the local spring length."""
    nu, nv = state.nu, state.nv
    Xg = X.reshape(nu, nv, 3)
    moves = []
    for lines, idx, svals, along_u in (
        (state.u_feat, state.u_lines, state.s_u, False),
        (state.v_feat, state.v_lines, state.s_v, True),
    ):
        other = state.v_lines if not along_u else state.u_lines
        for line, c, s in zip(lines, idx, svals, strict=True):
            n_along = nv if not along_u else nu
            movable = np.ones(n_along, dtype=bool)
            movable[[0, -1]] = False
            movable[other] = False  # anchors
            k = np.flatnonzero(movable)
            if k.size == 0:
                continue
            if not along_u:  # u feature: column c, neighbours across are columns c -/+ 1
                P, A, B = Xg[c, k], Xg[c - 1, k], Xg[c + 1, k]
                prev, nxt = Xg[c, k - 1], Xg[c, k + 1]
            else:
                P, A, B = Xg[k, c], Xg[k, c - 1], Xg[k, c + 1]
                prev, nxt = Xg[k - 1, c], Xg[k + 1, c]
            fa, fb = A - P, B - P
            la = np.linalg.norm(fa, axis=1)
            lb = np.linalg.norm(fb, axis=1)
            T = line.tangent_at(s[k])
            fair = fa / np.maximum(la, 1e-300)[:, None] + fb / np.maximum(lb, 1e-300)[:, None]
            fair = np.einsum("ij,ij->i", fair, T)  # eq. 5.15-5.16
            h = 0.5 * (la + lb)
            # eq. 5.14 with the spacing measured as chords between the grid points along
            # the curve (as the free points' springs are): where a painted feature curve
            # wiggles, equal arc lengths along it give unequal grid spacing
            arc = np.linalg.norm(nxt - P, axis=1) - np.linalg.norm(P - prev, axis=1)
            ds = 0.25 * (w_arc * arc + w_fair * fair * h)
            new = np.clip(s[k] + ds, s[k - 1], s[k + 1])
            # Gauss-Seidel would use new neighbours; Jacobi with clipping keeps the order
            span = np.maximum(s[k + 1] - s[k - 1], 1e-300)
            moves.append(np.abs(new - s[k]) / span * 2.0)
            s[k] = new
    if not moves:
        return 0.0
    m = np.concatenate(moves)
    return float(np.sqrt(np.mean(m * m)))


@dataclass(frozen=True)
class Sweeps:
    """The schedule of one :func:`relax` call.

    Attributes
    ----------
    max_iter : int
        Gauss-Seidel sweeps allowed.
    ramp : int
        Sweeps over which the fairness weight grows from 0 to ``fairness``.
    fairness : float
        Final weight of the fairness force in [0, 1]; the arc-length force gets the rest.
    omega : float
        Over-relaxation factor, in (0, 2).
    start : int
        Sweep of the schedule to start from (``start >= ramp``: final weights at once;
        default 0).
    eps : float
        Stop when the root-mean-square move is below this share of the spring lengths
        (default ``tol.SPRING_CONVERGED``).
    """

    max_iter: int
    ramp: int
    fairness: float
    omega: float
    start: int = 0
    eps: float = tol.SPRING_CONVERGED


def relax(
    state: State,
    sweeps: Sweeps,
    *,
    tangent: bool = True,
    guard: bool = True,
    fold: bool = False,
    only: np.ndarray | None = None,
) -> tuple[int, float]:
    """Relax the spring mesh of ``state`` at its current level, in place.

    Free points move by the weighted sum (eq. 5.4) of the arc-length force (eq. 5.1) and the
    fairness force (sec. 5.5.2), walked on the patch mesh (so they never leave it); curve
    points slide along their feature curve (eq. 5.17); boundary points and anchors stay.
    The fairness weight ramps from 0 to ``sweeps.fairness`` over ``sweeps.ramp`` sweeps (arc
    length first), counted from sweep ``sweeps.start`` of the schedule (see :class:`Sweeps`).
    Sweeps stop when the root-mean-square move is below ``sweeps.eps`` of the spring lengths. With
    ``tangent`` the spring vectors are turned into each point's tangent plane keeping their
    lengths (see `meshfit._kernels.springs.spring_force`), else they are Euclidean. With
    ``guard`` a move that folds more triangles of the point's cells than before is halved
    (up to three times) or dropped. ``only`` ((nu, nv) bool) limits the moving free points
    to those it marks. With ``fold`` a spring vector to a neighbour across a fold (normals
    more than 90 degrees apart) follows the grid line instead of the chord turned into the
    tangent plane (see `meshfit._kernels.springs.spring_force`). Without feature curves, a
    sweep after the first moves only the points near a move of more than `LAZY_MOVES` times
    ``sweeps.eps`` in the sweep before (the rest have settled).

    Returns
    -------
    (int, float)
        Sweeps done and the largest relative move of the last sweep.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.5.1-5.5.3, eq. 5.1 and 5.4; sec. 5.11.3, eq. 5.14-5.17.
    """
    mesh = state.mesh
    max_iter, ramp, fairness, omega = sweeps.max_iter, sweeps.ramp, sweeps.fairness, sweeps.omega
    start, eps = sweeps.start, sweeps.eps
    movable = state.free()
    if only is not None:
        movable &= np.asarray(only, dtype=bool).ravel()
    args = (mesh.vertices, mesh.faces, mesh.face_neighbors)
    alpha = np.ones(state.nu * state.nv)
    prev = np.zeros((state.nu * state.nv, 3))
    if not state.u_feat and not state.v_feat:
        done, _worst, rms = _k.relax_sweeps(
            *args,
            state.face,
            state.bary,
            state.nu,
            state.nv,
            movable,
            tangent,
            guard,
            alpha,
            prev,
            max_iter,
            start,
            ramp,
            fairness,
            omega,
            eps,
            tol.BARY_EPS,
            _MAX_FACES,
            LAZY_MOVES * eps,
            fold,
        )
        return int(done), float(rms)
    done, worst = 0, np.inf
    for it in range(max_iter):
        _, _w1, w1 = _k.relax_sweeps(
            *args,
            state.face,
            state.bary,
            state.nu,
            state.nv,
            movable,
            tangent,
            guard,
            alpha,
            prev,
            1,
            start + it,
            ramp,
            fairness,
            omega,
            eps,
            tol.BARY_EPS,
            _MAX_FACES,
            0.0,  # one sweep a call: nothing to skip
            fold,
        )
        t = min(1.0, (start + it) / ramp) if ramp > 0 else 1.0
        X = _k.grid_xyz(mesh.vertices, mesh.faces, state.face, state.bary)
        w2 = _curve_step(state, X, 1.0 - fairness * t, fairness * t)
        state.set_feature_points()
        done = it + 1
        worst = max(float(w1), w2)
        if start + it + 1 >= ramp and worst < eps:
            break
    return done, worst


def folded_cells(state: State) -> np.ndarray:
    """(nu - 1, nv - 1) bool: cells with a triangle whose normal points against the surface
    normals at its corners (the `grid_metrics` fold test)."""
    return grid_folds(state.mesh, state.face, state.bary, state.nu, state.nv)


def grid_folds(mesh, face: np.ndarray, bary: np.ndarray, nu: int, nv: int) -> np.ndarray:
    """`folded_cells` of a ``nu`` x ``nv`` grid of surface points of ``mesh`` (``face``
    (nu * nv,) int64, ``bary`` (nu * nv, 3) float64), whatever holds them."""
    return _k.folded_cells(*frozen(mesh.vertices, mesh.faces, face, bary), nu, nv)


def untangle(
    state: State,
    *,
    rounds: int,
    sweeps: int,
    reach: int,
    tangent: bool = True,
    guard: bool = True,
    fold: bool = False,
) -> int:
    """Smooth the free points around folded cells with the fairness force alone, in place.

    The fairness force moves a point to the centroid of its neighbours (a discrete harmonic
    map), which unfolds cells that the arc-length force folded where Euclidean springs pull
    across a bump or into a hollow (sec. 5.5.3, fig. 5.5). Points within ``reach`` cells of
    a fold move; up to ``rounds`` rounds of ``sweeps`` sweeps. ``fold``: spring vectors
    across a fold of the surface follow the grid line (see `relax`). Returns the folded
    cells left.
    """
    mesh = state.mesh
    folds = folded_cells(state)
    for _ in range(rounds):
        if not folds.any():
            break
        near = _near_folds(state, folds, reach)
        n = state.nu * state.nv
        _k.relax_sweeps(
            mesh.vertices, mesh.faces, mesh.face_neighbors, state.face, state.bary,
            state.nu, state.nv, near.ravel(), tangent, guard, np.ones(n), np.zeros((n, 3)),
            sweeps, 1, 1, 1.0, 1.0, 0.0, tol.BARY_EPS, _MAX_FACES, 0.0, fold,
        )  # fmt: skip
        folds = folded_cells(state)
    return int(folds.sum())


def repair_folds(state: State, *, rounds: int = 8) -> int:
    """Unfold the folded cells of the spring mesh by local moves of their free corners, in
    place; returns the folded cells left.

    Each free corner of a folded cell goes to the best of a set of trial places around it
    (the centroid of its neighbours, and steps in its tangent plane), walked on the patch:
    fewest folded triangles in its four cells, then the triangles' normals closest to the
    surface normals. Where a side bends sharply between two grid points, the point next to
    it must step past the chord between them; the relaxation forces, which pull it toward
    its neighbours, do not take it there (see `meshfit._kernels.springs.repair_folds`).
    """
    if not folded_cells(state).any():
        return 0
    mesh = state.mesh
    movable = state.free()
    _k.repair_folds(
        mesh.vertices, mesh.faces, mesh.face_neighbors, state.face, state.bary,
        state.nu, state.nv, movable, int(rounds), REPAIR_DIRECTIONS, REPAIR_MARGIN,
        tol.BARY_EPS, _MAX_FACES,
    )  # fmt: skip
    return int(folded_cells(state).sum())


def slide_side_points(state: State) -> int:
    """Slide the side points of folded cells along their sides, in place; returns the folded
    cells left.

    A side cut along mesh edges can step sideways or back over a stretch as short as the grid
    spacing; when two consecutive side points fall on the two legs of such a step, the chord
    between them points into the patch and the cell beside it folds wherever its free
    corners go (the fold repair moves only free points). Each side point of a folded cell
    (not a patch corner, not the end of a feature curve) tries places along its side between
    its two neighbouring side points (`SLIDE_FRACTIONS`), alone or taking the side points
    within `SLIDE_TAPER` places along by amounts tapering to zero (the side's spacing then
    changes over several intervals instead of one). Of the trials that fold the fewest cells
    beside the moved points it keeps the one whose shortest cell edge there is longest (a
    side point slid right under its interior neighbour leaves a sliver cell that no fold
    test sees). The static resampling of the next level starts afresh.

    The taper unfolds cells that a slide of one point leaves folded, and evens the
    arc lengths of the patch's grid; the choice among the trials keeps slides of one point
    from leaving a very short interval beside a very long one on a side.

    Parameters
    ----------
    state : State
        The spring mesh being built (``face (nu nv,) int64``, ``bary (nu nv, 3) float64``),
        changed in place.

    Returns
    -------
    int
        Folded cells left.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.6 (boundary points resampled statically along the
       patch's sides) and sec. 5.5.3, fig. 5.5 (folded spring cells).
    """
    folds = folded_cells(state)
    if not folds.any():
        return 0
    count = int(folds.sum())
    idx, movable, ends = _side_slots(state)
    i, j = np.nonzero(folds)
    cells = np.stack([idx[i, j], idx[i + 1, j], idx[i, j + 1], idx[i + 1, j + 1]], axis=1)
    todo = [movable[g] for g in dict.fromkeys(cells.ravel().tolist()) if g in movable]
    for name, k in todo:
        here, after, _ = _slide(state, idx, ends, name, k, pinched=False)
        count -= here - after
        if count == 0:
            break
    return count


def unpinch_side_points(state: State, ratio: float | None = None) -> int:
    """Slide side points that sit much closer to a neighbouring side point than the side's
    median spacing, in place (as :func:`slide_side_points` slides those of folded cells);
    returns how many were moved.

    Where a side steps back over a stretch about as short as the grid spacing, points at
    equal arc lengths fall on the two legs of the step, nearly on top of each other: the
    boundary iso-curve's spacing has a gap and a near-zero interval beside each other. A
    side point whose shorter chord to a neighbour is below ``ratio`` (default
    `PINCH_RATIO`) of its side's median chord tries the same places as a fold's side point,
    and takes the one whose shortest cell edge beside the moved points is longest, if that
    is longer than now and folds no more cells there. A point that cannot be improved is not
    tried again on the same level.

    Parameters
    ----------
    state : State
        The spring mesh being built (``face (nu nv,) int64``, ``bary (nu nv, 3) float64``),
        changed in place.
    ratio : float, optional
        Shorter chord over the side's median chord below which a side point is pinched
        (default `PINCH_RATIO`).

    Returns
    -------
    int
        Side points moved.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.6 (boundary points resampled statically along the
       patch's sides) and sec. 5.1 (arc-length distortion along iso-curves).
    """
    ratio = PINCH_RATIO if ratio is None else float(ratio)
    mesh = state.mesh
    # a slide moves points of its own side only: every side's chords can be read first
    pinched = _k.pinched_side_points(
        mesh.vertices, mesh.faces, state.face, state.bary, state.nu, state.nv, ratio
    )
    if not len(pinched):
        return 0
    idx, movable, ends = _side_slots(state)
    lines = _side_lines(idx)
    names = list(lines)
    moved = 0
    tried = state.pinch_tried()
    for side, k in pinched.tolist():
        name = names[side]
        if (name, k) in tried or int(lines[name][k]) not in movable:
            continue
        ok = _slide(state, idx, ends, name, k, pinched=True)[2]
        moved += ok
        if not ok:  # not again on this level
            tried.add((name, k))
    return moved


def _side_lines(idx: np.ndarray) -> dict[str, np.ndarray]:
    """Flat grid indices of the points of each side, in order."""
    return {"bottom": idx[:, 0], "top": idx[:, -1], "left": idx[0, :], "right": idx[-1, :]}


def _side_slots(state: State):
    """The grid's flat index array, the side points that may slide (flat index -> (side,
    place along it): not patch corners, not feature-curve ends) and each side's places that
    never move."""
    nu, nv = state.nu, state.nv
    idx = np.arange(nu * nv).reshape(nu, nv)
    fixed = {"u": set(state.u_lines.tolist()), "v": set(state.v_lines.tolist())}
    movable, ends = {}, {}
    for name, pts in _side_lines(idx).items():
        keep = fixed["u" if name in ("bottom", "top") else "v"]
        ends[name] = np.array(sorted({0, len(pts) - 1} | keep))
        for k in range(1, len(pts) - 1):
            if k not in keep:
                movable[int(pts[k])] = (name, k)
    return idx, movable, ends


def _slide(state: State, idx, ends, name: str, k: int, *, pinched: bool) -> tuple[int, int, bool]:
    """Try the places of side point ``k`` of side ``name`` (alone or with its neighbours by
    tapering amounts) and keep the best: for a fold's side point (``pinched`` False) the
    trial folding the fewest cells beside the moved points, fewer than now, of those the
    one whose shortest cell edge there is longest; for a pinched point (trying only places
    away from its nearer neighbour), the trial with the longest shortest edge, if longer
    than now and folding no more cells. Returns the folded cells beside the moved points
    before and after, and whether the points moved."""
    from meshfit.springs.init import chain_points

    mesh = state.mesh
    pos = state.slid_positions(name)
    e = ends[name]
    lo, hi = int(e[e < k].max()), int(e[e > k].min())
    left, right = min(SLIDE_TAPER + 1, k - lo), min(SLIDE_TAPER + 1, hi - k)
    js = np.arange(k - left + 1, k + right)
    w = 1.0 - np.abs(js - k) / np.where(js < k, left, right)
    win = _side_window(idx, name, k - left, k + right)
    rows, cols = win.shape
    sub = win.ravel()
    chain, arc = state.sides.chains[name], state.sides.arcs[name]
    gs = _side_points(idx, name, js)
    fracs = np.array(SLIDE_FRACTIONS)
    if pinched:  # away from the nearer neighbour
        near = _side_points(idx, name, np.array([k - 1, k, k + 1]))
        X = _xyz(mesh, state.face[near], state.bary[near])
        nearer_next = np.linalg.norm(X[2] - X[1]) < np.linalg.norm(X[1] - X[0])
        fracs = fracs[fracs < 0] if nearer_next else fracs[fracs > 0]
    # every trial's places at once: (trials, len(js)) arc lengths along the side
    step = np.where(fracs > 0, pos[k + 1] - pos[k], pos[k - 1] - pos[k]) * np.abs(fracs)
    weights = np.stack([w, (js == k).astype(np.float64)])
    trials = (pos[js][None, None, :] + step[:, None, None] * weights[None, :, :]).reshape(
        -1, js.size
    )
    pts = chain_points(mesh, chain, arc, trials.ravel(), state.sides.edge_faces[name])
    faces = pts.face.reshape(trials.shape)
    barys = pts.bary.reshape(*trials.shape, 3)
    # the window's folds and shortest chord as it is (entry 0) and for every trial
    place = {int(g): i for i, g in enumerate(sub.tolist())}
    at = np.array([place[int(g)] for g in gs], dtype=np.int64)
    folds, short = _k.window_trials(
        mesh.vertices, mesh.faces, state.face[sub], state.bary[sub], rows, cols, at, faces, barys
    )
    here = int(folds[0])
    best = (here, -float(short[0]) if pinched else 0.0)
    best_t = None
    for t in range(trials.shape[0]):
        c = int(folds[t + 1])
        if c > here or (c == here and not pinched):
            continue
        # fewest folds; of those, the trial whose shortest cell edge is longest (a side
        # point slid right under its interior neighbour leaves a sliver cell)
        score = (c, -float(short[t + 1]))
        if (best_t is None and not pinched) or score < best:
            best, best_t = score, t
    if best_t is not None:
        state.face[gs], state.bary[gs] = faces[best_t], barys[best_t]
        pos[js] = trials[best_t]
    return here, best[0], best_t is not None


def _side_window(idx: np.ndarray, name: str, a: int, b: int) -> np.ndarray:
    """The grid points of the cells beside side points ``a..b`` of side ``name`` (two grid
    lines deep)."""
    nu, nv = idx.shape
    return {
        "bottom": lambda: idx[a : b + 1, :2],
        "top": lambda: idx[a : b + 1, nv - 2 :],
        "left": lambda: idx[:2, a : b + 1],
        "right": lambda: idx[nu - 2 :, a : b + 1],
    }[name]()


def _side_points(idx: np.ndarray, name: str, js: np.ndarray) -> np.ndarray:
    """Flat grid indices of the points ``js`` along side ``name``."""
    if name in ("bottom", "top"):
        return idx[js, 0 if name == "bottom" else -1]
    return idx[0 if name == "left" else -1, js]


def _xyz(mesh, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Positions of face points (arrays known to be valid)."""
    return np.einsum("ij,ijk->ik", bary, mesh.vertices[mesh.faces[face]])


def _near_folds(state: State, folds: np.ndarray, reach: int) -> np.ndarray:
    """(nu, nv) bool: free points within ``reach`` grid steps of a corner of a folded cell."""
    near = np.zeros((state.nu, state.nv), dtype=bool)
    near[:-1, :-1] |= folds
    near[1:, :-1] |= folds
    near[:-1, 1:] |= folds
    near[1:, 1:] |= folds
    if reach > 0:
        near = dilate_grid(near, reach)
    return near & state.free().reshape(state.nu, state.nv)


def unfold_in_map(state: State, pmap, *, reach: int = 2, sweeps: int = 40) -> int:
    """Re-place the free points around folded cells harmonically in the planar map, in place;
    returns the folded cells left.

    The points within ``reach`` grid steps of a folded cell take the mean of their four
    neighbours' parameters in `meshfit.springs.planar.PlanarMap` (``sweeps`` red-black
    Gauss-Seidel sweeps, the other points fixed) and go to the images of those parameters.
    The map is a bijection of the patch onto the square, so a tangle of several points,
    which no single move undoes, comes out as an untangled grid patch in the map;
    `repair_folds` then handles the cells still folded on the surface (a triangle spanning
    a sharp bend). Nothing changes if the surface would have more folded cells than before.
    """
    folds = folded_cells(state)
    if not folds.any() or pmap is None:
        return int(folds.sum())
    nu, nv = state.nu, state.nv
    win = _near_folds(state, folds, reach)
    uv = np.ascontiguousarray(pmap.uv_of(state.face, state.bary).reshape(nu, nv, 2))
    ii, jj = np.nonzero(win)
    # red-black Gauss-Seidel: each colour's neighbours are the other colour's
    _k.red_black_mean(uv, ii.astype(np.int64), jj.astype(np.int64), int(sweeps))
    flat = (ii * nv + jj).astype(np.int64)
    old_face, old_bary = state.face[flat].copy(), state.bary[flat].copy()
    pts = pmap.locate(uv[ii, jj])
    state.face[flat] = pts.face
    state.bary[flat] = pts.bary
    left = int(folded_cells(state).sum())
    if left > folds.sum():  # worse on the surface than before: keep the old points
        state.face[flat], state.bary[flat] = old_face, old_bary
        return int(folds.sum())
    return left


def untangle_in_charts(state: State, *, reach: int | None = None, rounds: int | None = None) -> int:
    """Unfold the folded cells left by the other repairs by moving all the free points around
    each one together in a tangent-plane chart, in place; returns the folded cells left.

    Around a folded cell, the points within ``reach`` grid steps (default `CHART_REACH`) are
    projected onto the mean tangent plane of their faces. Each free one in turn goes to the
    place within one grid spacing that maximizes the least signed area of the fold-test
    triangles it is a corner of (a small linear program solved exactly,
    `meshfit._kernels.springs.maxmin_point`), for up to ``rounds`` rounds (default
    `CHART_ROUNDS`) or until every such triangle has `CHART_GOAL` of the squared spacing;
    the points then go to the surface points closest to their chart places lifted to their
    old heights. The moves are kept only if the patch has fewer folded cells.

    Where a side turns sharply (an inner corner of a patch, far over 180 degrees), the
    grid must fan around the corner: the neighbours of the corner's cells must all move,
    and neither the forces nor `repair_folds`, which moves one point at a time to a few trial
    places, find that. Windows whose surface normals spread by more than
    `CHART_MAX_SPREAD` degrees are skipped: there the tangent plane is no chart.

    Parameters
    ----------
    state : State
        Building state of one level; ``state.face`` (n,) int64 and ``state.bary`` (n, 3)
        float64 of the free points change in place.
    reach : int, keyword-only, optional
        Grid steps around a folded cell whose free points move (default `CHART_REACH`).
    rounds : int, keyword-only, optional
        Gauss-Seidel rounds per window (default `CHART_ROUNDS`).

    Returns
    -------
    int
        Folded cells left (the `folded_cells` test).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.5.3 (folds of the spring mesh and their repair).
    """
    reach = CHART_REACH if reach is None else int(reach)
    rounds = CHART_ROUNDS if rounds is None else int(rounds)
    folds = folded_cells(state)
    left = int(folds.sum())
    if not left:
        return 0
    mesh = state.mesh
    nu, nv = state.nu, state.nv
    movable = state.kind() == FREE
    tried = set()
    while left:
        todo = [tuple(c) for c in np.argwhere(folds).tolist() if tuple(c) not in tried]
        if not todo:
            break
        fi, fj = todo[0]
        tried.add((fi, fj))
        # the points within reach move; one more ring stays put around them, so that every
        # cell a moving point is a corner of is in the window
        i0, i1 = max(fi - reach - 1, 0), min(fi + 2 + reach, nu - 1)
        j0, j1 = max(fj - reach - 1, 0), min(fj + 2 + reach, nv - 1)
        idx = np.arange(nu * nv).reshape(nu, nv)[i0 : i1 + 1, j0 : j1 + 1]
        flat = idx.ravel()
        inner = np.zeros(idx.shape, dtype=bool)
        inner[1:-1, 1:-1] = True
        var = movable.ravel()[flat] & inner.ravel()
        if not var.any():
            continue
        X = _xyz(mesh, state.face[flat], state.bary[flat])
        normals = mesh.face_normals[state.face[flat]]
        n = normals.sum(axis=0)
        n /= max(np.linalg.norm(n), 1e-300)
        if np.degrees(np.arccos(np.clip(normals @ n, -1.0, 1.0))).max() > CHART_MAX_SPREAD:
            continue
        e1 = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        origin = X.mean(axis=0)
        Y = np.ascontiguousarray(np.stack([(X - origin) @ e1, (X - origin) @ e2], axis=1))
        Yg = Y.reshape(*idx.shape, 2)
        h = float(
            np.median(
                np.concatenate(
                    [
                        np.linalg.norm(np.diff(Yg, axis=0), axis=2).ravel(),
                        np.linalg.norm(np.diff(Yg, axis=1), axis=2).ravel(),
                    ]
                )
            )
        )
        if not h > 0.0:
            continue
        _k.chart_untangle(Y, idx.shape[0], idx.shape[1], var, h, rounds, 2.0 * CHART_GOAL * h * h)
        moved = flat[var]
        height = (X[var] - origin) @ n
        lifted = origin + Y[var, :1] * e1 + Y[var, 1:] * e2 + height[:, None] * n
        near = mesh.closest_points(lifted).points
        old_face, old_bary = state.face[moved].copy(), state.bary[moved].copy()
        state.face[moved], state.bary[moved] = near.face, near.bary
        after = folded_cells(state)
        if int(after.sum()) < left:
            folds, left = after, int(after.sum())
        else:
            state.face[moved], state.bary[moved] = old_face, old_bary
    return left


def even_lines_in_map(state: State, pmap, *, rounds: int = 1, samples: int | None = None) -> bool:
    """Move the free points along their grid lines, in the planar map, to equal arc lengths
    on the surface, rows then columns, ``rounds`` times, in place; returns whether it moved
    them (not with feature curves or without a map).

    Each interior grid line is a polyline in the unit square through its points'
    parameters; sampled at ``samples`` (default `LINE_SAMPLES`) points per interval and
    lifted onto the patch, it gives the line's arc length on the surface, and its interior
    points go to equal fractions of it (the ends stay). A pleat or a bulge that the map
    squeezes into a sliver between two grid points has a long arc there: the points move
    into it, where the relaxation's local moves, pulled by both neighbours, do not go.
    Rows and columns are evened one after the other, so cells may fold: the caller repairs
    and weighs the result.

    Parameters
    ----------
    state : State
        The spring mesh being built (``face (nu nv,) int64``, ``bary (nu nv, 3) float64``),
        changed in place.
    pmap : PlanarMap or None
        The patch's map onto the unit square (`meshfit.springs.planar.square_map`).
    rounds : int, keyword-only
        Rows-then-columns passes (default 1).
    samples : int, keyword-only, optional
        Points per grid interval on the lines' paths (default `LINE_SAMPLES`).

    Returns
    -------
    bool
        Whether the points moved.

    Raises
    ------
    meshfit.errors.InputError
        ``rounds`` below 0 or ``samples`` below 1.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.5.1 (the arc-length force: equal spacing along each
       iso-curve) and sec. 5.5.3 (Euclidean springs cut across bulges and hollows).
    """
    samples = LINE_SAMPLES if samples is None else samples
    for name, value, least in (("rounds", rounds, 0), ("samples", samples, 1)):
        if isinstance(value, bool) or int(value) != value or value < least:
            raise InputError(
                f"even_lines_in_map: {name} must be an integer >= {least}, got {value!r}"
            )
    if pmap is None or state.u_feat or state.v_feat or min(state.nu, state.nv) < 3:
        return False
    nu, nv = state.nu, state.nv
    uv = pmap.uv_of(state.face, state.bary).reshape(nu, nv, 2)
    for _ in range(int(rounds)):
        _even_lines(pmap, uv, int(samples))  # the lines along u (rows i = 0 .. nu - 1)
        _even_lines(pmap, uv.transpose(1, 0, 2), int(samples))
    free = state.free()
    pts = pmap.locate(uv.reshape(-1, 2)[free])
    state.face[free] = pts.face
    state.bary[free] = pts.bary
    return True


def _even_lines(pmap, uv: np.ndarray, samples: int) -> None:
    """Move the interior points of the interior lines ``uv[:, j]`` (uv (n, m, 2), a view
    changed in place) to equal surface arc lengths along their paths in the square."""
    mesh = pmap.mesh
    n, m = uv.shape[:2]
    t = np.arange(samples) / samples
    a, b = uv[:-1, 1:-1], uv[1:, 1:-1]  # (n - 1, m - 2, 2) interval ends
    dense = a[:, None] * (1.0 - t)[None, :, None, None] + b[:, None] * t[None, :, None, None]
    dense = np.concatenate([dense.reshape(-1, m - 2, 2), uv[-1:, 1:-1]], axis=0)
    k = dense.shape[0]
    pts = pmap.locate(dense.reshape(-1, 2))
    X = _k.grid_xyz(mesh.vertices, mesh.faces, pts.face, pts.bary).reshape(k, m - 2, 3)
    seg = np.linalg.norm(np.diff(X, axis=0), axis=2)  # (k - 1, m - 2)
    arc = np.concatenate([np.zeros((1, m - 2)), np.cumsum(seg, axis=0)], axis=0)
    for c in range(m - 2):
        total = arc[-1, c]
        if not total > 0.0:
            continue
        want = total * np.arange(1, n - 1) / (n - 1)
        at = np.clip(np.searchsorted(arc[:, c], want, side="right") - 1, 0, k - 2)
        f = np.clip((want - arc[at, c]) / np.maximum(seg[at, c], 1e-300), 0.0, 1.0)[:, None]
        uv[1:-1, c + 1] = dense[at, c] * (1.0 - f) + dense[at + 1, c] * f
