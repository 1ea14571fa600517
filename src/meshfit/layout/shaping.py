"""Base-mesh vertices moved on the sphere so that the automatic layout's patches are well shaped.

The area-equalised base mesh (:func:`meshfit.shrinkwrap.base_mesh`) gives every base triangle
about the same surface area, but where the sphere map stretches one way more than the other
(a neck, the rim of a hollow) a triangle of equal area can be a sliver on the surface, and so
are the three quads it is split into. Their spring meshes then fold and space unevenly
(patches with a small fraction of the area of a square of their perimeter,
:attr:`meshfit.layout.Patch.bulge`). :func:`shape_base` moves the base vertices over the
sphere to make the quads' images close to squares of equal area, which removes most of
those slivers and folds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["BaseShape", "quad_cost", "quad_images", "shape_base"]

#: rounds of trial moves, trial directions per vertex and round, the first trial step as a
#: fraction of the mean base-edge arc, and its decay per round
SHAPE_ROUNDS = 30
SHAPE_DIRECTIONS = 8
SHAPE_STEP = 0.25
SHAPE_DECAY = 0.85
#: weight of the area term (squared log of each quad's area over the mean) against the shape
#: term (see `quad_cost`)
SHAPE_AREA_WEIGHT = 1.0


@dataclass(frozen=True)
class BaseShape:
    """Result of :func:`shape_base`.

    Attributes
    ----------
    sphere : (nv, 3) float64
        The moved base vertices (unit vectors).
    cost_before, cost_after : float
        Summed `quad_cost` of all quads (NaN when the map gives the quads no area: then
        nothing is moved).
    worst_before, worst_after : float
        Largest quad shape term (see `quad_cost`; 1 for a square).
    moves : int
        Accepted vertex moves.
    """

    sphere: NDArray[np.float64]
    cost_before: float
    cost_after: float
    worst_before: float
    worst_after: float
    moves: int


def _unit(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def quad_images(smap, sphere: NDArray[np.float64], tris: NDArray[np.int64]) -> NDArray:
    """Surface positions of the three quads of each spherical triangle.

    Quad ``i`` of triangle ``(a, b, c)`` runs from its corner ``i`` through the mid-point of
    the edge after it, the centroid and the mid-point of the edge before it (mid-points and
    centroid as normalised means on the sphere), each point mapped to the surface by the
    sphere map.

    Parameters
    ----------
    smap : meshfit.shrinkwrap.SphereMap
        Parameterization over the unit sphere (``locate`` and ``mesh.xyz`` are used).
    sphere : (nv, 3) float64
        Unit vectors of the base vertices.
    tris : (k, 3) int64
        Spherical triangles, counter-clockwise seen from outside.

    Returns
    -------
    (k, 3, 4, 3) float64
        Corner positions of each triangle's quads, model units.

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6 (the base mesh and its images).
    """
    tris = np.asarray(tris, dtype=np.int64)
    return _quads(smap, sphere[tris[..., 0]], sphere[tris[..., 1]], sphere[tris[..., 2]])[0]


def _quads(smap, a: NDArray, b: NDArray, c: NDArray, start: NDArray | None = None):
    """`quad_images` of triangles given by their corners ``a``, ``b``, ``c`` (..., 3), and the
    faces ``(..., 7)`` of the seven points mapped (corners, mid-points, centroid); ``start``
    (..., 7) are faces to start locating them from (points near those of an earlier call)."""
    pts = np.stack([a, b, c, _unit(a + b), _unit(b + c), _unit(c + a), _unit(a + b + c)], axis=-2)
    lead = pts.shape[:-2]
    where = smap.locate(pts.reshape(-1, 3), start=None if start is None else start.reshape(-1))
    X = smap.mesh.xyz(where).reshape(*lead, 7, 3)
    A, B, C, mab, mbc, mca, g = (X[..., i, :] for i in range(7))
    Q = np.stack(
        [
            np.stack([A, mab, g, mca], axis=-2),
            np.stack([B, mbc, g, mab], axis=-2),
            np.stack([C, mca, g, mbc], axis=-2),
        ],
        axis=-3,
    )
    return Q, np.array(where.face).reshape(*lead, 7)


def _shape_and_area(Q: NDArray) -> tuple[NDArray, NDArray]:
    """Shape term and area of quads ``Q (..., 4, 3)``.

    The shape term is the mean over the four corners of ``(|e1|^2 + |e2|^2) / (2 |e1 x e2|)``
    for the corner's two sides ``e1``, ``e2`` (the condition number of the corner's frame: 1
    for a square, growing without bound for a sliver, a kite or a corner near 180 degrees);
    the area is half the diagonals' cross product.
    """
    e1 = np.roll(Q, -1, axis=-2) - Q
    e2 = np.roll(Q, 1, axis=-2) - Q
    tiny = np.finfo(np.float64).tiny
    frame = (e1**2).sum(axis=-1) + (e2**2).sum(axis=-1)
    twice = 2.0 * np.linalg.norm(np.cross(e1, e2), axis=-1)
    shape = (frame / np.maximum(twice, tiny)).mean(axis=-1)
    d1 = Q[..., 2, :] - Q[..., 0, :]
    d2 = Q[..., 3, :] - Q[..., 1, :]
    area = 0.5 * np.linalg.norm(np.cross(d1, d2), axis=-1)
    return shape, area


def quad_cost(Q: NDArray, mean_area: float, area_weight: float = SHAPE_AREA_WEIGHT) -> NDArray:
    """Cost of each triangle's three quads, summed per triangle.

    Per quad ``shape - 1 + area_weight * log(area / mean_area)^2``: 0 for a square of the
    mean area; a sliver's shape term grows without bound (see `_shape_and_area`).

    Parameters
    ----------
    Q : (..., 3, 4, 3) float64
        Quad corners (:func:`quad_images`).
    mean_area : float
        Target quad area, model units squared.
    area_weight : float
        Weight of the area term (default `SHAPE_AREA_WEIGHT`).

    Returns
    -------
    (...,) float64
    """
    shape, area = _shape_and_area(Q)
    tiny = np.finfo(np.float64).tiny
    log_area = np.log(np.maximum(area, tiny) / mean_area)
    return (shape - 1.0 + area_weight * log_area**2).sum(axis=-1)


def _oriented(sphere: NDArray, tris: NDArray) -> NDArray[np.bool_]:
    """Whether each spherical triangle is counter-clockwise seen from outside."""
    a, b, c = sphere[tris[..., 0]], sphere[tris[..., 1]], sphere[tris[..., 2]]
    return np.einsum("...i,...i->...", np.cross(a, b), c) > 0.0


def shape_base(
    smap,
    sphere: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    rounds: int = SHAPE_ROUNDS,
    directions: int = SHAPE_DIRECTIONS,
    step: float = SHAPE_STEP,
    seed: int = 0,
) -> BaseShape:
    """Move base vertices over the sphere so that their quads are square on the surface.

    Each round tries, for every vertex at once, ``directions`` moves of one length along
    evenly turned tangent directions (a random offset per round), and scores each by the
    summed `quad_cost` of the vertex's triangles (their three quads mapped to the surface
    by ``smap``). Moves that lower the cost and flip no spherical triangle are applied, best
    first, to vertices that share no triangle with a vertex already moved this round. The
    trial length starts at ``step`` times the mean base-edge arc and shrinks by
    `SHAPE_DECAY` per round.

    Parameters
    ----------
    smap : meshfit.shrinkwrap.SphereMap
        Parameterization of the surface over the unit sphere (``locate`` and ``mesh.xyz``
        are used).
    sphere : (nv, 3) float64
        Base vertices (unit vectors).
    faces : (nf, 3) int64
        Base triangles, counter-clockwise seen from outside.
    rounds, directions : int, keyword-only
        Rounds of trial moves (default 30) and trial directions per vertex (default 8).
    step : float, keyword-only
        First trial length over the mean base-edge arc (default 0.25).
    seed : int, keyword-only
        Seed of the directions' offsets.

    Returns
    -------
    BaseShape
        The moved vertices and the cost before and after.

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6 (the base mesh, there relaxed
       for equal areas only).
    """
    S = np.array(sphere, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    nv, nf = S.shape[0], F.shape[0]
    rng = np.random.default_rng(seed)
    Q, at = _quads(smap, S[F[:, 0]], S[F[:, 1]], S[F[:, 2]])  # at: faces of the 7 points
    shape0, area = _shape_and_area(Q)
    mean_area = float(area.mean())
    if not (mean_area > 0.0 and np.isfinite(shape0).all()):
        # a map that collapses the quads (no area to balance): nothing to improve
        worst = float(shape0.max()) if np.isfinite(shape0).all() else float("inf")
        return BaseShape(S, float("nan"), float("nan"), worst, worst, 0)
    cost = quad_cost(Q, mean_area)
    before = float(cost.sum())
    worst_before = float(shape0.max())
    # incidence: row r = (vertex, triangle) pairs, and the slot of the vertex in the triangle
    inc_v = F.ravel()
    inc_t = np.repeat(np.arange(nf), 3)
    slot = np.tile(np.arange(3), nf)
    vert_tris: list[list[int]] = [[] for _ in range(nv)]
    for v, t in zip(inc_v.tolist(), inc_t.tolist(), strict=True):
        vert_tris[v].append(t)
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    arc = float(np.arccos(np.clip((S[edges[:, 0]] * S[edges[:, 1]]).sum(axis=1), -1, 1)).mean())
    length = step * arc
    moves = 0
    for _ in range(int(rounds)):
        helper = np.where(np.abs(S[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        t1 = _unit(np.cross(S, helper))
        t2 = np.cross(S, t1)
        ang = rng.uniform(0.0, 2.0 * np.pi) + np.arange(directions) * (2.0 * np.pi / directions)
        turn = np.cos(ang)[None, :, None] * t1[:, None] + np.sin(ang)[None, :, None] * t2[:, None]
        cand = _unit(S[:, None, :] + length * turn)  # (nv, K, 3)
        # each (vertex, triangle) pair with the vertex at each candidate: (r, K, 3) corners
        tri = S[F[inc_t]]  # (r, 3, 3)
        trial = np.repeat(tri[:, None], directions, axis=1)  # (r, K, 3, 3)
        trial[np.arange(len(inc_v)), :, slot] = cand[inc_v]
        a, b, c = trial[..., 0, :], trial[..., 1, :], trial[..., 2, :]
        ok = np.einsum("...i,...i->...", np.cross(a, b), c) > 0.0  # (r, K)
        # the trial points are located starting from the faces of the points they move from
        Qt, _ = _quads(smap, a, b, c, start=np.repeat(at[inc_t][:, None], directions, axis=1))
        new_cost = quad_cost(Qt, mean_area)  # (r, K)
        gain_rows = cost[inc_t][:, None] - new_cost
        gain_rows = np.where(ok, gain_rows, -np.inf)
        gain = np.zeros((nv, directions))
        np.add.at(gain, inc_v, gain_rows)
        best = gain.argmax(axis=1)
        best_gain = gain[np.arange(nv), best]
        order = np.argsort(-best_gain, kind="stable")
        touched = np.zeros(nf, dtype=bool)
        moved = 0
        for v in order.tolist():
            if not best_gain[v] > 0.0:
                break
            ts = vert_tris[v]
            if touched[ts].any():
                continue
            S[v] = cand[v, best[v]]
            touched[ts] = True
            moved += 1
        if moved:
            hit = np.flatnonzero(touched)
            Qh, at[hit] = _quads(smap, *(S[F[hit, k]] for k in range(3)), start=at[hit])
            cost[hit] = quad_cost(Qh, mean_area)
            moves += moved
        length *= SHAPE_DECAY
    Q = quad_images(smap, S, F)
    after = float(quad_cost(Q, mean_area).sum())
    assert _oriented(S, F).all(), "a base triangle flipped"
    return BaseShape(S, before, after, worst_before, float(_shape_and_area(Q)[0].max()), moves)
