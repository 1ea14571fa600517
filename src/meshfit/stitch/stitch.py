"""C0 / G1 stitching of B-spline patch networks, displacement seams, and seam measures."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit.bspline import BSplineSurface
from meshfit.displacement import DisplacementMap
from meshfit.errors import InputError
from meshfit.stitch.network import Network, SharedBoundary, side_row

__all__ = [
    "SeamReport",
    "displacement_seam_gaps",
    "seam_report",
    "stitch_displacements",
    "stitch_surfaces",
]


def _side_params(side: str, t: NDArray) -> tuple[NDArray, NDArray]:
    z, o = np.zeros_like(t), np.ones_like(t)
    return {"u0": (z, t), "u1": (o, t), "v0": (t, z), "v1": (t, o)}[side]


def _check(surfaces: Sequence[BSplineSurface], network: Network) -> list[BSplineSurface]:
    surfaces = list(surfaces)
    if len(surfaces) != network.n_patches:
        raise InputError(f"{len(surfaces)} surfaces for a network of {network.n_patches} patches")
    for k, b in enumerate(network.boundaries):
        na = side_row(surfaces[b.a].control_points, b.side_a).shape[0]
        nb = side_row(surfaces[b.b].control_points, b.side_b).shape[0]
        if na != nb:
            raise InputError(
                f"boundary {k} (patch {b.a} side {b.side_a} / patch {b.b} side {b.side_b}) has "
                f"{na} and {nb} control points: make the counts consistent (control_classes)"
            )
        for s in (surfaces[b.a], surfaces[b.b]):
            if not s.is_uniform:
                raise InputError("stitching needs clamped uniform knots on every patch")
    return surfaces


def _corner_geometry(shapes, offs, slot):
    """Flat indices around one patch corner: corner, neighbour along u, along v, diagonal;
    and the sides running along u (v fixed) and along v (u fixed) from that corner."""
    k, i, j = slot
    mu, mv = shapes[k]
    ii, jj = i % mu, j % mv
    su, sv = (1 if i == 0 else -1), (1 if j == 0 else -1)

    def at(a: int, c: int) -> int:
        return int(offs[k] + a * mv + c)

    side_along_u = "v0" if j == 0 else "v1"
    side_along_v = "u0" if i == 0 else "u1"
    return (
        at(ii, jj),
        at(ii + su, jj),
        at(ii, jj + sv),
        at(ii + su, jj + sv),
        su * sv,
        side_along_u,
        side_along_v,
    )


def _corner_spokes(shapes, offs, slots, bound_of) -> dict:
    spokes: dict[int, list] = {}
    for sl in slots:
        _, nu_, nv_, _, _, side_u, side_v = _corner_geometry(shapes, offs, sl)
        for side, q in ((side_u, nu_), (side_v, nv_)):
            bi = bound_of.get((sl[0], side))
            if bi is not None:
                spokes.setdefault(bi, []).append((sl, q))
    return spokes


def _stitch_corner(P, shapes, offs, corner_slot, slots, bound_of, boundaries, lam, exact4) -> None:
    """G1 at one network corner (in place on the flat control array ``P``).

    Valence 2 on the network border (one shared boundary): the corner moves onto the line of
    its two neighbours along the border sides, in the boundary's spacing ratio, so that
    boundary is G1 to its ends. Valence 4 with four G1 boundaries (``exact4``; their rows
    are then equally spaced, ratio 1): the four spoke points (the corner's neighbours along
    the boundaries) are made pairwise symmetric about the corner and the four diagonal
    points the least change that puts each spoke point at the midpoint of its two
    diagonals: every row of every boundary is then collinear and equally spaced (exact G1).
    Any other corner whose shared boundaries are all G1: the mean-tangent-plane rule of the
    thesis (see :func:`_project_corner`).
    """
    geo = {sl: _corner_geometry(shapes, offs, sl) for sl in slots}
    spokes: dict[int, list] = {}
    for sl in slots:
        c, nu_, nv_, _, _, side_u, side_v = geo[sl]
        for side, q in ((side_u, nu_), (side_v, nv_)):
            bi = bound_of.get((sl[0], side))
            if bi is not None:
                spokes.setdefault(bi, []).append((sl, q))
    if not spokes or any(boundaries[bi].continuity != "G1" for bi in spokes):
        return
    shared = {bi: v for bi, v in spokes.items() if len(v) == 2}
    c_idx = [geo[sl][0] for sl in slots]
    if len(slots) == 2 and len(spokes) == 1 and len(shared) == 1:
        # the two border neighbours: along the side that is not the shared one
        (bi,) = shared
        other = {}
        for sl in slots:
            _, nu_, nv_, _, _, side_u, side_v = geo[sl]
            other[sl[0]] = nv_ if bound_of.get((sl[0], side_u)) == bi else nu_
        b = boundaries[bi]
        lb = (lam or {}).get(bi, 1.0)
        P[c_idx] = (P[other[b.a]] + lb * P[other[b.b]]) / (1.0 + lb)
        return None
    if exact4 and len(slots) == 4 and len(shared) == 4 and len(spokes) == 4:
        # cyclic order of spokes and patches around the corner
        order_s, order_p = [], []
        sl = slots[0]
        bi = bound_of[(sl[0], geo[sl][5])]
        for _ in range(4):
            order_s.append(bi)
            order_p.append(sl)
            _, _, _, _, _, side_u, side_v = geo[sl]
            nxt = (
                bound_of[(sl[0], side_v)]
                if bound_of[(sl[0], side_u)] == bi
                else bound_of[(sl[0], side_u)]
            )
            sl = next(x for x, _ in shared[nxt] if x != sl)
            bi = nxt
        if sorted(order_s) != sorted(shared) or len(set(order_p)) != 4:
            return _project_corner(P, geo, slots, corner_slot, shared, boundaries, lam)
        c = P[c_idx[0]]
        q_idx = [[q for _, q in shared[bi]] for bi in order_s]  # both copies of each spoke
        q = np.array([P[ix[0]] for ix in q_idx])
        for s0, s1 in ((0, 2), (1, 3)):
            half = 0.5 * (q[s0] - q[s1])
            q[s0], q[s1] = c + half, c - half
        for ix, val in zip(q_idx, q, strict=True):
            P[ix] = val
        # patch order_p[s] lies between spokes order_s[s] and order_s[s+1]:
        # spoke s + 1 is the midpoint of diagonals s and s + 1
        r_idx = [geo[sl][3] for sl in order_p]
        r = P[r_idx]
        A = np.zeros((4, 4))
        for s_ in range(4):
            A[s_, (s_ - 1) % 4] = 0.5
            A[s_, s_] = 0.5
        target = q  # spoke s = mid(diag s-1, diag s)
        r_new = r + np.linalg.pinv(A) @ (target - A @ r)
        P[r_idx] = r_new
        return None
    return _project_corner(P, geo, slots, corner_slot, spokes, boundaries, lam)


def _cell_normal(P, g) -> NDArray:
    """Normal of a patch's corner control cell from its diagonals (robust to a sheared cell
    whose two edges at the corner are nearly parallel)."""
    c, nu_, nv_, diag, sign, _, _ = g
    return np.cross(P[diag] - P[c], P[nv_] - P[nu_]) * sign


def _corner_normals(P, geo, slots) -> list:
    out = []
    for sl in slots:
        n = _cell_normal(P, geo[sl])
        ln = np.linalg.norm(n)
        out.append(n / ln if ln > 0 else np.zeros(3))
    return out


def _folded(P, geo, slots, ref) -> bool:
    """True when a patch corner (its corner quad or its diagonal point) turned over
    compared with the normals ``ref`` from before the corner rule."""
    for sl, n0 in zip(slots, ref, strict=True):
        c, nu_, nv_, diag, sign, _, _ = geo[sl]
        n = np.cross(P[nu_] - P[c], P[nv_] - P[c]) * sign
        if n @ n0 <= 0:
            return True
        # the diagonal point stays inside the corner's wedge
        d = P[diag] - P[c]
        if np.cross(P[nu_] - P[c], d) @ n * sign < 0 or np.cross(d, P[nv_] - P[c]) @ n * sign < 0:
            return True
    return False


def _rotation(n_from: NDArray, n_to: NDArray) -> NDArray:
    """Smallest rotation taking unit vector ``n_from`` to ``n_to`` (Rodrigues)."""
    v = np.cross(n_from, n_to)
    c = float(n_from @ n_to)
    sv = float(np.linalg.norm(v))
    if sv < 1e-15:
        return np.eye(3) if c > 0 else -np.eye(3)
    k = v / sv
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sv * K + (1 - c) * (K @ K)


def _project_corner(P, geo, slots, corner_slot, spokes=None, boundaries=(), lam=None) -> None:
    """Mean-tangent-plane rule at a corner: each patch's corner neighbours are turned about
    the corner by the smallest rotation taking that patch's corner normal to the mean normal
    (so no patch corner folds), the diagonal points are put in the plane, and each shared
    spoke point is placed on its row-1 line between the two diagonal points (in the
    boundary's spacing ratio), which keeps that row collinear."""
    c0 = P[corner_slot[slots[0]]].copy()
    normals = []
    for sl in slots:
        n = _cell_normal(P, geo[sl])
        ln = np.linalg.norm(n)
        normals.append(n / ln if ln > 0 else None)
    good = [n for n in normals if n is not None]
    if not good:
        return
    normal = np.sum(good, axis=0)
    ln = np.linalg.norm(normal)
    if ln == 0:
        return
    normal /= ln
    moved: dict[int, list] = {}
    for sl, n in zip(slots, normals, strict=True):
        _, nu_, nv_, diag, _, _, _ = geo[sl]
        R = np.eye(3) if n is None else _rotation(n, normal)
        for ix in (nu_, nv_, diag):
            moved.setdefault(ix, []).append(c0 + R @ (P[ix] - c0))
    for ix, vals in moved.items():
        p = np.mean(vals, axis=0)
        P[ix] = p - ((p - c0) @ normal) * normal
    # shared spokes back on their row-1 lines between the (now planar) diagonal points,
    # or (without spacing ratios) at the mean of their two turned copies
    for bi, pairs in (spokes or {}).items():
        if len(pairs) != 2:
            continue
        if lam is None or bi not in lam:
            val = 0.5 * (P[pairs[0][1]] + P[pairs[1][1]])
            P[pairs[0][1]] = val
            P[pairs[1][1]] = val
            continue
        b = boundaries[bi]
        diag = {sl[0]: geo[sl][3] for sl, _ in pairs}
        q = pairs[0][1]
        val = (P[diag[b.a]] + lam[bi] * P[diag[b.b]]) / (1.0 + lam[bi])
        for _, qi in pairs:
            P[qi] = val
        del q


def _slot_rows(shapes, b: SharedBoundary, depth: int):
    """Flat control-slot indices of a boundary's rows on both patches, aligned."""
    offs = np.concatenate([[0], np.cumsum([mu * mv for mu, mv in shapes])])
    ia = side_row(np.arange(shapes[b.a][0] * shapes[b.a][1]).reshape(shapes[b.a]), b.side_a, depth)
    ib = side_row(np.arange(shapes[b.b][0] * shapes[b.b][1]).reshape(shapes[b.b]), b.side_b, depth)
    if b.reversed:
        ib = ib[::-1]
    return ia + offs[b.a], ib + offs[b.b]


def stitch_surfaces(surfaces: Sequence[BSplineSurface], network: Network) -> list[BSplineSurface]:
    """Make a network of patches C0 or G1 across its shared boundaries.

    Parameters
    ----------
    surfaces : sequence of BSplineSurface
        One per patch, clamped uniform knots, counts consistent along shared boundaries
        (see :func:`meshfit.stitch.control_classes`).
    network : Network
        Shared boundaries, each with its continuity (``C0`` or ``G1``), and corners.

    Returns
    -------
    list of BSplineSurface
        New surfaces; only boundary and corner control points move.

    Notes
    -----
    Following the thesis (sec. 8.1.3):

    1. C0: every class of coincident boundary control points (a shared boundary row on two
       patches; at a corner, the corner point of every patch meeting there, of any valence)
       is replaced by its mean.
    2. G1 along a boundary: each shared boundary control point away from the ends is moved
       onto the segment between the two tangent control points beside it, so tangent,
       boundary and tangent points are collinear; the thesis spaces them equally, here they
       keep the ratio of the two patches' mean spacings across the boundary (equal when the
       patches are alike), one ratio per boundary, so the cross-boundary derivatives of the
       two patches are parallel wherever only such rows act (beyond the first knot span
       from each end) and patches of different sizes move less.
    3. G1 at a corner whose shared boundaries are all G1: the corner's neighbours
       ``P[1,0], P[0,1], P[1,1]`` of every patch meeting there are projected onto the plane
       through the corner point whose normal is the mean of the patches' corner normals (the
       average tangent plane); every patch then has that tangent plane at the corner.
       Each patch's corner fan is turned (not projected) onto the plane so no corner
       folds, and shared spoke points go back onto their row-1 lines. Two cases go further
       and make the rows at the corner collinear and equally spaced as well (G1 to the very
       end of the boundary): a border corner of valence 2 (the corner moves to the midpoint
       of its border neighbours) and an interior corner of valence 4 (spoke points made
       symmetric about the corner, diagonal points the least change that keeps each spoke
       point the midpoint of its diagonals). At valence 3 or 5+ that is impossible in
       general and the normal may still turn within the first knot span of the corner.
       A corner rule that would turn a patch corner over is abandoned and that corner is
       left C0 (its boundaries stay G1 beyond the first knot span).
    """
    surfaces = _check(surfaces, network)
    shapes = [s.shape for s in surfaces]
    P = np.concatenate([s.control_points.reshape(-1, 3) for s in surfaces])
    offs = np.concatenate([[0], np.cumsum([mu * mv for mu, mv in shapes])])

    # 1. C0: union-find over boundary slots
    parent = np.arange(P.shape[0])

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for b in network.boundaries:
        ia, ib = _slot_rows(shapes, b, 0)
        for x, y in zip(ia, ib, strict=True):
            rx, ry = find(int(x)), find(int(y))
            if rx != ry:
                parent[rx] = ry
    corner_slot = {}
    for c, slots in enumerate(network.corners):
        for k, i, j in slots:
            mu, mv = shapes[k]
            s = offs[k] + (i % mu) * mv + (j % mv)
            corner_slot[(k, i, j)] = int(s)
        first = corner_slot[slots[0]]
        for sl in slots[1:]:
            rx, ry = find(corner_slot[sl]), find(first)
            if rx != ry:
                parent[rx] = ry
        del c
    roots = np.array([find(x) for x in range(P.shape[0])])
    sums = np.zeros_like(P)
    np.add.at(sums, roots, P)
    cnt = np.bincount(roots, minlength=P.shape[0]).astype(float)
    P = sums[roots] / cnt[roots][:, None]

    # 2. G1 along boundaries: tangent, boundary and tangent points collinear, in the ratio of
    # the two patches' spacings across the boundary (constant along it: exact G1)
    bound_of = {}
    for bi, b in enumerate(network.boundaries):
        bound_of[(b.a, b.side_a)] = bi
        bound_of[(b.b, b.side_b)] = bi
    lam = {}
    for bi, b in enumerate(network.boundaries):
        if b.continuity == "G1":
            ia, ib = _slot_rows(shapes, b, 0)
            ta, tb = _slot_rows(shapes, b, 1)
            da = np.linalg.norm(P[ia] - P[ta], axis=1).mean()
            db = np.linalg.norm(P[tb] - P[ib], axis=1).mean()
            lam[bi] = float(da / db) if db > 0 and da > 0 else 1.0
    exact4 = []
    for slots in network.corners:
        spokes = _corner_spokes(shapes, offs, slots, bound_of)
        if (
            len(slots) == 4
            and len(spokes) == 4
            and all(len(v) == 2 and bi in lam for bi, v in spokes.items())
        ):
            exact4.append(slots)
            for bi in spokes:
                lam[bi] = 1.0
    for bi, b in enumerate(network.boundaries):
        if bi not in lam:
            continue
        ia, ib = _slot_rows(shapes, b, 0)
        ta, tb = _slot_rows(shapes, b, 1)
        c = (P[ta[1:-1]] + lam[bi] * P[tb[1:-1]]) / (1.0 + lam[bi])
        P[ia[1:-1]] = c
        P[ib[1:-1]] = c

    # 3. G1 at corners, each rule checked for folds (a patch corner turned over)
    for slots in network.corners:
        geo = {sl: _corner_geometry(shapes, offs, sl) for sl in slots}
        touched = np.unique([ix for sl in slots for ix in geo[sl][:4]])
        before = P[touched].copy()
        ref = _corner_normals(P, geo, slots)
        attempts = [
            (any(slots == e for e in exact4), True),  # exact valence-4 / valence-2 / plane
            (False, True),  # plane rule with spoke rows
        ]
        for use4, spoke_rows in attempts:
            P[touched] = before
            _stitch_corner(
                P,
                shapes,
                offs,
                corner_slot,
                slots,
                bound_of,
                network.boundaries,
                lam if spoke_rows else None,
                use4,
            )
            if not _folded(P, geo, slots, ref):
                break
        else:
            P[touched] = before  # leave this corner C0 rather than fold a patch
    return [
        s.with_control_points(P[offs[k] : offs[k + 1]].reshape(*shapes[k], 3))
        for k, s in enumerate(surfaces)
    ]


@dataclass(frozen=True)
class SeamReport:
    """Position gaps and normal-angle jumps along every shared boundary.

    Attributes
    ----------
    gap : (n_boundaries,) float64
        Largest distance between the two patches' boundary curves at equal boundary
        parameters, model units.
    angle_deg : (n_boundaries,) float64
        Largest angle between the two patches' normals, degrees, away from the corners
        (beyond one knot span of the boundary's ends).
    angle_corner_deg : (n_boundaries,) float64
        Largest angle within one knot span of the ends (corner zones), degrees.
    corner_point_deg : (n_corners,) float64
        Largest angle between the normals of the patches meeting at each network corner, at
        the corner point itself, degrees (0 for a corner of one patch).
    """

    gap: NDArray[np.float64]
    angle_deg: NDArray[np.float64]
    angle_corner_deg: NDArray[np.float64]
    corner_point_deg: NDArray[np.float64]

    def summary(self) -> dict[str, float]:
        def mx(a):
            return float(a.max()) if a.size else 0.0

        return {
            "gap_max": mx(self.gap),
            "angle_max_deg": mx(self.angle_deg),
            "angle_corner_max_deg": mx(self.angle_corner_deg),
            "corner_point_max_deg": mx(self.corner_point_deg),
        }


def seam_report(
    surfaces: Sequence[BSplineSurface], network: Network, *, samples: int = 201
) -> SeamReport:
    """Measure every shared boundary: position gap and normal jump (thesis sec. 8.1.1, fig.
    8.1), the figures before and after :func:`stitch_surfaces`.

    ``samples`` boundary parameters ``t = k / (samples - 1)`` per boundary.
    """
    surfaces = list(surfaces)
    t = np.linspace(0.0, 1.0, samples)
    gaps, ang, angc = [], [], []
    for b in network.boundaries:
        ua, va = _side_params(b.side_a, t)
        tb = t[::-1] if b.reversed else t
        ub, vb = _side_params(b.side_b, tb)
        sa, sb = surfaces[b.a], surfaces[b.b]
        gaps.append(float(np.linalg.norm(sa.evaluate(ua, va) - sb.evaluate(ub, vb), axis=1).max()))
        cos = (sa.normals(ua, va) * sb.normals(ub, vb)).sum(axis=1)
        a = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        n_along = sa.shape[1] if b.side_a[0] == "u" else sa.shape[0]
        span = 1.0 / (n_along - 3)
        inner = (t > span) & (t < 1 - span)
        ang.append(float(a[inner].max()) if inner.any() else 0.0)
        angc.append(float(a[~inner].max()) if (~inner).any() else 0.0)
    corner = []
    for slots in network.corners:
        ns = [
            surfaces[k].normals(np.array([float(i == -1)]), np.array([float(j == -1)]))[0]
            for k, i, j in slots
        ]
        worst = 0.0
        for x in range(len(ns)):
            for y in range(x + 1, len(ns)):
                c = float(np.clip(ns[x] @ ns[y], -1.0, 1.0))
                worst = max(worst, float(np.degrees(np.arccos(c))))
        corner.append(worst)
    return SeamReport(np.array(gaps), np.array(ang), np.array(angc), np.array(corner))


def _row_world(surface: BSplineSurface, dmap: DisplacementMap, side: str):
    """World-space displacement vectors of a map's boundary row and the frames there."""
    h, w = dmap.shape
    n = w if side[0] == "u" else h
    t = np.linspace(0.0, 1.0, n)
    u, v = _side_params(side, t)
    T, B, N = surface.frames(u, v)
    comp = side_row(dmap.values, side)
    world = comp[:, :1] * T + comp[:, 1:2] * B + comp[:, 2:] * N
    return t, world, (T, B, N)


def _set_row(values: NDArray, side: str, world: NDArray, frames) -> None:
    T, B, N = frames
    comp = np.stack([(world * T).sum(1), (world * B).sum(1), (world * N).sum(1)], axis=1)
    side_row(values, side)[...] = comp


def _interp_rows(t_from: NDArray, rows: NDArray, t_to: NDArray) -> NDArray:
    return np.stack([np.interp(t_to, t_from, rows[:, c]) for c in range(3)], axis=1)


def stitch_displacements(
    surfaces: Sequence[BSplineSurface],
    maps: Sequence[DisplacementMap],
    network: Network,
) -> list[DisplacementMap]:
    """Make displaced patches crack-free across shared boundaries (thesis sec. 8.2).

    Parameters
    ----------
    surfaces : sequence of BSplineSurface
        The stitched surfaces (C0 at least: shared boundary curves identical).
    maps : sequence of DisplacementMap
        One ``vector`` map per patch, any resolutions.
    network : Network

    Returns
    -------
    list of DisplacementMap
        Maps whose boundary texels agree in model space: at every network corner the
        corner texels take the mean of their model-space vectors; along a shared boundary the
        coarser row takes the mean of both rows' piecewise-linear displacement at its texels
        and the finer row is the coarser one's linear interpolation. With nested resolutions
        (``n_fine - 1`` a multiple of ``n_coarse - 1``, as spring-mesh subdivision gives) the
        two reconstructions coincide along the seam at every resolution
        (:func:`meshfit.displacement.reconstruct` filters model-space vectors); otherwise the
        seam is closed at the coarse texels and off by the interpolation error between them.
    """
    surfaces = _check(surfaces, network)
    maps = list(maps)
    if len(maps) != len(surfaces):
        raise InputError(f"{len(maps)} maps for {len(surfaces)} surfaces")
    for k, m in enumerate(maps):
        if not isinstance(m, DisplacementMap) or m.kind != "vector":
            raise InputError(f"maps[{k}] must be a vector displacement map")
    vals = [m.values.copy() for m in maps]
    # corners: mean model-space vector of the corner texels
    for slots in network.corners:
        if len(slots) < 2:
            continue
        worlds, frames = [], []
        for k, i, j in slots:
            s = surfaces[k]
            u, v = float(i == -1), float(j == -1)
            T, B, N = s.frames(np.array([u]), np.array([v]))
            c = vals[k][i, j]
            worlds.append(c[0] * T[0] + c[1] * B[0] + c[2] * N[0])
            frames.append((T[0], B[0], N[0]))
        mean = np.mean(worlds, axis=0)
        for (k, i, j), (T, B, N) in zip(slots, frames, strict=True):
            vals[k][i, j] = [mean @ T, mean @ B, mean @ N]
    for b in network.boundaries:
        cur = [DisplacementMap(vals[b.a]), DisplacementMap(vals[b.b])]
        ta, wa, fa = _row_world(surfaces[b.a], cur[0], b.side_a)
        tb, wb, fb = _row_world(surfaces[b.b], cur[1], b.side_b)
        if b.reversed:
            wb, fb = wb[::-1], tuple(f[::-1] for f in fb)
        if len(ta) <= len(tb):
            coarse_t, coarse_w, fine_t, fine_w = ta, wa, tb, wb
        else:
            coarse_t, coarse_w, fine_t, fine_w = tb, wb, ta, wa
        avg = 0.5 * (coarse_w + _interp_rows(fine_t, fine_w, coarse_t))
        fine_new = _interp_rows(coarse_t, avg, fine_t)
        new_a = avg if len(ta) <= len(tb) else fine_new
        new_b = fine_new if len(ta) <= len(tb) else avg
        _set_row(vals[b.a], b.side_a, new_a, fa)
        if b.reversed:
            new_b, fb = new_b[::-1], tuple(f[::-1] for f in fb)
        _set_row(vals[b.b], b.side_b, new_b, fb)
    return [DisplacementMap(v, "vector") for v in vals]


def displacement_seam_gaps(
    surfaces: Sequence[BSplineSurface],
    maps: Sequence[DisplacementMap],
    network: Network,
    *,
    samples: int = 401,
) -> NDArray[np.float64]:
    """Largest gap between displaced boundaries per shared boundary, model units.

    The displaced boundary of a patch at boundary parameter t is the spline point plus the
    linear interpolation of its boundary texels' model-space vectors (what
    :func:`meshfit.displacement.reconstruct` produces along a boundary at any resolution).
    """
    t = np.linspace(0.0, 1.0, samples)
    out = []
    for b in network.boundaries:
        pts = []
        for k, side, rev in ((b.a, b.side_a, False), (b.b, b.side_b, b.reversed)):
            tt = t[::-1] if rev else t
            u, v = _side_params(side, tt)
            tr, wr, _ = _row_world(surfaces[k], maps[k], side)
            pts.append(surfaces[k].evaluate(u, v) + _interp_rows(tr, wr, tt))
        out.append(float(np.linalg.norm(pts[0] - pts[1], axis=1).max()))
    return np.array(out)
