"""C0 / G1 stitching of B-spline patch networks, displacement seams, and seam measures."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._unionfind import DisjointSets
from meshfit.bspline import BSplineSurface
from meshfit.bspline.basis import DEGREE, basis_local
from meshfit.displacement import DisplacementMap
from meshfit.errors import InputError
from meshfit.stitch.network import Network, SharedBoundary, side_row, texel_shapes

__all__ = [
    "MAP_KINDS",
    "SeamReport",
    "bump_seam_angles",
    "displacement_seam_gaps",
    "match_map_shapes",
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


def _border_corner(P, shapes, offs, slots, bound_of, boundaries, lam) -> bool:
    """G1 at a border corner of valence 2 (one shared G1 boundary), in place: the corner
    moves onto the line of its two neighbours along the border sides, in the boundary's
    spacing ratio, so row 0 of the boundary is collinear like the others and the boundary is
    G1 to its end. Returns whether it was applied (False if it would fold a patch corner)."""
    geo = {sl: _corner_geometry(shapes, offs, sl) for sl in slots}
    ((bi, _),) = _corner_spokes(shapes, offs, slots, bound_of).items()
    other = {}
    for sl in slots:
        _, nu_, nv_, _, _, side_u, _ = geo[sl]
        other[sl[0]] = nv_ if bound_of.get((sl[0], side_u)) == bi else nu_
    b = boundaries[bi]
    c_idx = [geo[sl][0] for sl in slots]
    before = P[c_idx].copy()
    ref = [_cell_normal(P, geo[sl]) for sl in slots]
    P[c_idx] = (P[other[b.a]] + lam[bi] * P[other[b.b]]) / (1.0 + lam[bi])
    if _folded(P, geo, slots, ref):
        P[c_idx] = before
        return False
    return True


def _cell_normal(P, g) -> NDArray:
    """Normal of a patch's corner control cell from its diagonals."""
    c, nu_, nv_, diag, sign, _, _ = g
    return np.cross(P[diag] - P[c], P[nv_] - P[nu_]) * sign


def _folded(P, geo, slots, ref) -> bool:
    """True when a patch corner (its corner quad or its diagonal point) turned over
    compared with the normals ``ref`` from before the corner rule."""
    for sl, n0 in zip(slots, ref, strict=True):
        c, nu_, nv_, diag, sign, _, _ = geo[sl]
        n = np.cross(P[nu_] - P[c], P[nv_] - P[c]) * sign
        if n @ n0 <= 0:
            return True
        d = P[diag] - P[c]
        if np.cross(P[nu_] - P[c], d) @ n * sign < 0 or np.cross(d, P[nv_] - P[c]) @ n * sign < 0:
            return True
    return False


@dataclass
class _Wedge:
    """One patch's corner at a network corner: its two spokes in counter-clockwise order
    about the patch normal, and its diagonal (twist) control point."""

    slot: tuple[int, int, int]
    first: tuple
    second: tuple
    diag: int


def _spoke_key(bound_of, k: int, side: str) -> tuple:
    bi = bound_of.get((k, side))
    return ("b", bi) if bi is not None else ("p", k, side)


def _corner_fan(shapes, offs, slots, bound_of):
    """The patch corners at one network corner in counter-clockwise order.

    Returns ``(corner_index, wedges, spoke_index, cycle)`` or None when the corner is not a
    simple fan (a patch meeting itself, inconsistent orientations): ``wedges`` in order, each
    wedge's ``second`` spoke the next one's ``first``; ``spoke_index`` maps each spoke to its
    flat control indices (two for a shared boundary); ``cycle`` is True for an interior
    corner (the fan closes), False on the network border.
    """
    if len({sl[0] for sl in slots}) != len(slots):
        return None
    wedges, spoke_index, corner = [], {}, []
    for sl in slots:
        c, nu_, nv_, diag, sign, side_u, side_v = _corner_geometry(shapes, offs, sl)
        ku, kv = _spoke_key(bound_of, sl[0], side_u), _spoke_key(bound_of, sl[0], side_v)
        spoke_index.setdefault(ku, []).append(nu_)
        spoke_index.setdefault(kv, []).append(nv_)
        corner.append(c)
        # S_u x S_v at the corner is sign * (e_u x e_v): counter-clockwise from e_u to e_v
        # when sign > 0
        wedges.append(_Wedge(sl, ku, kv, diag) if sign > 0 else _Wedge(sl, kv, ku, diag))
    by_first = {w.first: w for w in wedges}
    seconds = {w.second for w in wedges}
    if len(by_first) != len(wedges) or len(seconds) != len(wedges):
        return None
    if any(len(ix) > 2 for ix in spoke_index.values()):
        return None
    starts = [w for w in wedges if w.first not in seconds]
    if len(starts) > 1:
        return None
    w = starts[0] if starts else wedges[0]
    order = []
    while w is not None and len(order) <= len(wedges):
        order.append(w)
        w = by_first.get(w.second)
        if w is order[0]:
            break
    if len(order) != len(wedges) or len({id(x) for x in order}) != len(order):
        return None
    return corner, order, spoke_index, not starts


def _cross2(a: NDArray, b: NDArray) -> NDArray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _fan_folded(spokes: dict, wedges: list, diags: NDArray, min_sin: float = 0.0) -> bool:
    """True when a flat fan turns a patch corner over (the wedge from its first to its second
    spoke not counter-clockwise, or the diagonal point outside the wedge)."""
    for w, d in zip(wedges, diags, strict=True):
        a, b = spokes[w.first], spokes[w.second]
        # np.linalg.norm of a vector is sqrt(x . x): the same, without its dispatch
        la, lb, ld = math.sqrt(a.dot(a)), math.sqrt(b.dot(b)), math.sqrt(d.dot(d))
        if min(la, lb, ld) == 0:
            return True
        if _cross2(a, b) <= min_sin * la * lb:
            return True
        if _cross2(a, d) <= 0 or _cross2(d, b) <= 0:
            return True
    return False


def _flat_angles(theta: NDArray, cycle: bool) -> NDArray | None:
    """Wedge angles of the flat fan: the patches' own corner angles scaled to a full turn
    (interior corner) and kept within ``[CORNER_MIN_ANGLE, pi - CORNER_MIN_ANGLE]``."""
    lo, hi = tol.STITCH_CORNER_MIN_ANGLE, np.pi - tol.STITCH_CORNER_MIN_ANGLE
    n = len(theta)
    if cycle and not n * lo < 2 * np.pi < n * hi:
        return None
    th = np.clip(theta, lo, hi)
    if not cycle:
        total = min(th.sum(), 2 * np.pi - lo)
        return np.clip(th * total / th.sum(), lo, hi)
    fixed = np.zeros(n, dtype=bool)
    for _ in range(n + 1):  # scale the free angles to the remainder, clamp, repeat
        free = 2 * np.pi - th[fixed].sum()
        th[~fixed] *= free / th[~fixed].sum()
        out = (th < lo) | (th > hi)
        if not out.any():
            return th
        th = np.clip(th, lo, hi)
        fixed |= out
    return None


def _null_space(hard: NDArray) -> NDArray:
    """Orthonormal basis (columns) of the null space of ``hard`` (rows: constraints)."""
    _, sv, vt = np.linalg.svd(hard)
    rank = int((sv > 1e-12 * sv.max()).sum())
    return vt[rank:].T


def _solve_fan(
    x0: NDArray, hard: NDArray, soft, scale: float, iters: int = 30, Z: NDArray | None = None
) -> NDArray:
    """The fan nearest ``x0`` on the linear constraints ``hard @ x = 0``, then Gauss-Newton
    steps within them that drive the soft residuals ``soft(x) -> (r, J)`` towards zero with
    a small pull back to ``x0`` (weight ``tol.STITCH_FAN_PULL``, lengths over ``scale``).
    ``Z``: ``_null_space(hard)`` when the caller has it (one corner's many trials)."""
    if hard.size:
        x = x0 - np.linalg.lstsq(hard, hard @ x0, rcond=None)[0]
        if Z is None:
            Z = _null_space(hard)
    else:
        x, Z = x0.copy(), np.eye(x0.size)
    if soft is None or Z.shape[1] == 0:
        return x
    w = tol.STITCH_FAN_PULL
    for _ in range(iters):
        r, J = soft(x)
        res = np.concatenate([w * (x - x0) / scale, r])
        jac = np.vstack([w * Z / scale, J @ Z])
        step = np.linalg.lstsq(jac, -res, rcond=None)[0]
        x = x + Z @ step
        if np.abs(Z @ step).max() <= 1e-15 * scale:
            break
    return x


def _row2_slots(shapes, offs, keys, spoke_index, boundaries) -> list[tuple[int, ...]]:
    """The control slots `_flatten_row2` moves at one corner: per shared boundary there with
    at least 6 control points, its row-2 boundary point and both tangent points."""
    out = []
    for k in keys:
        if k[0] != "b":
            continue
        b = boundaries[k[1]]
        ia, ib = _slot_rows(shapes, offs, b, 0)
        ta, tb = _slot_rows(shapes, offs, b, 1)
        n = len(ia)
        if n < 6:
            continue
        q = 2 if spoke_index[k][0] in (ia[1], ib[1]) else n - 3
        out.append((int(ia[q]), int(ib[q]), int(ta[q]), int(tb[q])))
    return out


def _flatten_row2(P, c0, normal, row2: list[tuple[int, ...]]) -> None:
    """Row 2 from the corner of every shared boundary there (boundary point and both tangent
    points, `_row2_slots`) translated along ``normal`` so its boundary point lies in the
    corner's tangent plane: the boundary curves leave the corner without normal curvature,
    which is what turns the two patches' tangent planes apart within the first knot span
    when row 0 cannot be collinear. Rows stay collinear (a common translation), so G1 beyond
    the first span is kept; boundaries with fewer than 6 control points are left alone (row
    2 is the other end's too)."""
    for slots in row2:
        off = -((P[slots[0]] - c0) @ normal) * normal
        for ix in slots:
            P[ix] += off


def _g1_corner(P, shapes, offs, slots, bound_of, boundaries, lam, surfaces, exact: bool):  # noqa: C901 (one corner's constraint system, built in order; to split)
    """G1 at one network corner of valence >= 3 (or a border corner of valence >= 3), in
    place on the flat control array ``P``; returns whether it was applied.

    1. Tangent plane: normal ``N`` the sum of the patches' corner normals
       ``sign (e_u x e_v) / (|e_u| |e_v|)`` (spokes ``e``: the corner's neighbours along the
       boundaries; a sheared corner, whose normal is unreliable, weighs less).
    2. Flat fan: the spokes are laid out in that plane around the corner in the patches'
       cyclic order, each keeping its length, the wedge angles the patches' own corner angles
       scaled to a full turn (kept within ``tol.STITCH_CORNER_MIN_ANGLE`` of 0 and pi), the
       fan turned about ``N`` to fit the old spokes best (where row 0 cannot be collinear:
       the turn, among that one and ``_FAN_TURNS`` others evenly over a full turn and then
       a golden-section search around the best, with the smallest normal jump over the
       first knot span of the corner's boundaries; the rows
       beyond the corner ring stay, and the turn decides how much the first span twists
       between them); each diagonal point keeps its
       coordinates in its wedge's spoke basis (clamped inside the wedge). No patch corner
       folds: every wedge is counter-clockwise about ``N``, as every patch's own normal.
    3. Constraints, solved together as the least change from the flat fan (Gauss-Newton,
       minimum-norm steps), in the plane:
       - row 1 of every shared G1 boundary collinear in the boundary's ratio: the spoke along
         the boundary is ``(d_a + lam d_b) / (1 + lam)`` of the two diagonal points;
       - row 0, with ``e_a, e_b`` the two patches' other spokes: ``e_a + lam e_b`` parallel to
         the boundary's spoke (``exact``: equal to 0, the valence-4 case with lam = 1, which
         makes every row at the corner collinear and G1 exact to the boundary's end). Row 0
         cannot be collinear at other valences; parallel to the boundary it leaves the two
         patches' cross-boundary derivatives in the tangent plane of the boundary curve's
         first control leg, so the normal jump within the first knot span is of the order
         of the boundary's normal curvature there times the row-0 defect.
    If the constraints fold a patch corner, only the row-1 constraints are kept; if they
    fold too (or the corner is not a simple fan) nothing is changed. Folds are judged in
    the tangent plane only: a patch whose surface turns by a right angle or more within two
    knot spans of the corner (a near-triangular patch at a narrow end) still gets the
    rule (a plane checked against the patch's normal two knot spans in left such a corner
    C0, with a large normal jump).

    At an interior corner a second family of flat fans is tried as well: equal wedges, each
    diagonal point in the middle of its wedge. Where row 0 cannot be collinear the family
    with the smaller corner-zone jump wins (the patches' own angles on a tie); at an exact
    corner the equal fan is used only where every own fan folds. Where the patches' corner
    angles are far from a full turn in sum (a cone point of the surface, such as a sharp tip
    where three patches meet), the own fans collapse under the constraints and only the
    equal fan gives a corner rule.
    """
    fan = _corner_fan(shapes, offs, slots, bound_of)
    if fan is None:
        return False
    corner, wedges, spoke_index, cycle = fan
    c0 = P[corner[0]].copy()
    keys = list(dict.fromkeys(k for w in wedges for k in (w.first, w.second)))
    e3 = {k: P[spoke_index[k][0]] - c0 for k in keys}
    if any(np.linalg.norm(e3[k]) == 0 for k in keys):
        return False
    unit = {k: v / np.linalg.norm(v) for k, v in e3.items()}
    # the tangent plane: mean unit normal of the patches over their first knot span at the
    # corner (the corner normals alone follow the fitted spokes, which a rough boundary tilts)
    normal = np.zeros(3)
    for k, i, j in slots:
        mu, mv = shapes[k]
        su_ = np.linspace(0.0, 1.0 / (mu - 3), 6)
        sv_ = np.linspace(0.0, 1.0 / (mv - 3), 6)
        U, V = np.meshgrid(su_ if i == 0 else 1 - su_, sv_ if j == 0 else 1 - sv_, indexing="ij")
        normal += surfaces[k].normals(U, V).reshape(-1, 3).mean(axis=0)
    if np.linalg.norm(normal) <= tol.BSPLINE_DEGENERATE:
        return False
    normal /= np.linalg.norm(normal)
    theta = np.array([np.arccos(np.clip(unit[w.first] @ unit[w.second], -1, 1)) for w in wedges])
    flat = _flat_angles(theta, cycle)
    if flat is None:
        return False
    # in-plane basis and the flat fan, turned to fit the old spokes
    x_ax = np.cross(normal, [1.0, 0.0, 0.0])
    if np.linalg.norm(x_ax) < 0.5:
        x_ax = np.cross(normal, [0.0, 1.0, 0.0])
    x_ax /= np.linalg.norm(x_ax)
    y_ax = np.cross(normal, x_ax)
    length = {k: float(np.linalg.norm(e3[k])) for k in keys}
    proj = {k: np.array([e3[k] @ x_ax, e3[k] @ y_ax]) for k in keys}
    beta = {k: np.arctan2(p[1], p[0]) for k, p in proj.items()}

    def spoke_angles(wedge_angles: NDArray) -> tuple[dict, float]:
        """Angle of every spoke in the fan, and the turn that fits the old spokes best."""
        phi = {wedges[0].first: 0.0}
        for w, t in zip(wedges, wedge_angles, strict=True):
            phi.setdefault(w.second, phi[w.first] + t)
        wsum = np.array([0.0, 0.0])
        for k in keys:
            wgt = length[k] * float(np.linalg.norm(proj[k]))
            wsum += wgt * np.array([np.cos(beta[k] - phi[k]), np.sin(beta[k] - phi[k])])
        return phi, float(np.arctan2(wsum[1], wsum[0]))

    phi, psi = spoke_angles(flat)
    # the last resort at an interior corner: equal wedges (where the patches' own corner
    # angles, far from a full turn in sum, give a fan the constraints collapse)
    even = spoke_angles(np.full(len(wedges), 2 * np.pi / len(wedges))) if cycle else None
    # unknowns: spokes (in ``keys`` order) then diagonals, 2 coordinates each
    ks = {k: n for n, k in enumerate(keys)}
    nd = len(keys)
    wi = {w.slot[0]: n for n, w in enumerate(wedges)}
    rows1, rows0 = [], []
    for k in keys:
        if k[0] != "b":
            continue
        b = boundaries[k[1]]
        wa = next(w for w in wedges if w.slot[0] == b.a)
        wb = next(w for w in wedges if w.slot[0] == b.b)
        lb = lam[k[1]]
        rows1.append((ks[k], nd + wi[b.a], nd + wi[b.b], lb))
        other_a = wa.second if wa.first == k else wa.first
        other_b = wb.second if wb.first == k else wb.first
        rows0.append((ks[k], ks[other_a], ks[other_b], lb))

    nx = 2 * (nd + len(wedges))
    scale = float(np.mean(list(length.values())))
    hard = []
    for sp, da, db, lb in rows1:  # row 1 collinear in the boundary's ratio
        for c in range(2):
            row = np.zeros(nx)
            row[2 * sp + c] = 1.0
            row[2 * da + c] -= 1.0 / (1.0 + lb)
            row[2 * db + c] -= lb / (1.0 + lb)
            hard.append(row)
    if exact:  # row 0 collinear too: e_a + lam e_b = 0
        for _, ea, eb, lb in rows0:
            for c in range(2):
                row = np.zeros(nx)
                row[2 * ea + c] += 1.0
                row[2 * eb + c] += lb
                hard.append(row)
    hard = np.array(hard).reshape(-1, nx)
    null = _null_space(hard) if hard.size else None
    row2 = [] if exact else _row2_slots(shapes, offs, keys, spoke_index, boundaries)
    r0 = np.array([(sp, ea, eb) for sp, ea, eb, _ in rows0], dtype=np.int64).reshape(-1, 3)
    r0_lam = np.array([lb for *_, lb in rows0], dtype=np.float64)
    r0_at = np.arange(len(rows0))
    r0_distinct = all(len({sp, ea, eb}) == 3 for sp, ea, eb in r0.tolist())

    def soft(x):
        """Row 0: (e_a + lam e_b) x e_s = 0 per boundary, over scale**2 (all boundaries at
        once; the rows' entries summed in the order spokes a, b, s where they share one)."""
        X = x.reshape(-1, 2)
        sp, ea, eb, lb = r0[:, 0], r0[:, 1], r0[:, 2], r0_lam
        wv, sv = X[ea] + lb[:, None] * X[eb], X[sp]
        J = np.zeros((len(r0_at), nx))
        for cols, vals in (
            (2 * ea, sv[:, 1]),
            (2 * ea + 1, -sv[:, 0]),
            (2 * eb, lb * sv[:, 1]),
            (2 * eb + 1, -lb * sv[:, 0]),
            (2 * sp, -wv[:, 1]),
            (2 * sp + 1, wv[:, 0]),
        ):
            if r0_distinct:  # no two terms of a row in one column: as 0.0 + v (no -0.0)
                J[r0_at, cols] = vals + 0.0
            else:
                np.add.at(J, (r0_at, cols), vals)
        return _cross2(wv, sv) / scale**2, J / scale**2

    wedge_ab: dict[int, NDArray] = {}  # each diagonal point in its wedge's spoke basis

    def diagonal_coords(n: int, w) -> NDArray:
        if n not in wedge_ab:
            A = np.stack([e3[w.first], e3[w.second]], axis=1)
            ab = np.linalg.lstsq(A, P[w.diag] - c0, rcond=None)[0]
            floor = 0.05 * float(np.abs(ab).sum())
            wedge_ab[n] = np.maximum(ab, floor) if floor > 0 else np.array([0.5, 0.5])
        return wedge_ab[n]

    def flat_fan(equal: bool, rot: float, angles: dict):
        ln = dict(length)
        if equal:  # a symmetric start when the patches' own spokes fold the fan
            mean = float(np.mean(list(length.values())))
            ln = dict.fromkeys(keys, mean)
        s2 = {k: ln[k] * np.array([np.cos(angles[k] + rot), np.sin(angles[k] + rot)]) for k in keys}
        d2 = []
        for n, w in enumerate(wedges):
            if angles is not phi:  # the equal fan: each diagonal point at its wedge's middle
                d2.append(s2[w.first] + s2[w.second])
                continue
            ab = diagonal_coords(n, w)  # P is only written once the corner is decided
            d2.append(ab[0] * s2[w.first] + ab[1] * s2[w.second])
        return s2, np.array(d2)

    own = [
        (equal, with_row0, phi, psi)
        for equal, with_row0 in ((False, True), (True, True), (False, False), (True, False))
    ]
    equal_fan = [] if even is None else [(True, True, *even), (True, False, *even)]

    solved: dict[tuple, NDArray | None] = {}

    def solve(equal: bool, with_row0: bool, angles: dict, fit: float) -> NDArray | None:
        """The constrained fan of one try at its fitted turn (None where it folds). The
        constraints, the pull to the flat fan and the fold tests are all invariant under a
        turn of the plane, so a fan turned by ``rot`` solves to this one turned by ``rot``:
        it is solved once per try, not once per turn."""
        key = (equal, with_row0, angles is phi)
        if key not in solved:
            s2, d2 = flat_fan(equal, fit, angles)
            X = None
            if not _fan_folded(s2, wedges, d2):
                x0 = np.concatenate([np.array([s2[k] for k in keys]).ravel(), d2.ravel()])
                pull = soft if with_row0 and not exact else None
                X = _solve_fan(x0, hard, pull, scale, Z=null).reshape(-1, 2)
                sp = {k: X[ks[k]] for k in keys}
                if _fan_folded(sp, wedges, X[nd:], np.sin(0.5 * tol.STITCH_CORNER_MIN_ANGLE)):
                    X = None
            solved[key] = X
        return solved[key]

    def place(rot: float, tries) -> NDArray | None:
        """The corner's control slots (``window``) with the corner rule applied, the fan
        turned by ``rot`` from its best fit to the old spokes: the first of ``tries`` that
        folds no corner."""
        for equal, with_row0, angles, fit in tries:
            X = solve(equal, with_row0, angles, fit)
            if X is None:
                continue
            if rot != 0.0:
                c, s = np.cos(rot), np.sin(rot)
                X = X @ np.array([[c, s], [-s, c]])
            sp = {k: X[ks[k]] for k in keys}
            Q = near.copy()
            for k in keys:
                Q[spoke_at[k]] = c0 + sp[k][0] * x_ax + sp[k][1] * y_ax
            for w, d in zip(wedges, X[nd:], strict=True):
                Q[at(w.diag)] = c0 + d[0] * x_ax + d[1] * y_ax
            if not exact:
                _flatten_row2(Q, c0, normal, row2_at)
            return Q
        return None

    def turned(tries) -> tuple[float, NDArray] | None:
        """The best placement of one family of fans over the turns about the normal, and
        its corner-zone jump."""
        first = place(0.0, tries)
        if first is None:
            return None
        if exact:
            return 0.0, first
        # row 0 is not collinear: the normal jump within the first knot span depends on how
        # the fan is turned about the normal against the fixed rows beyond it; keep the turn
        # with the smallest jump (the fitted turn first, so it stays on a tie)
        seen: dict[float, tuple[float, NDArray | None]] = {0.0: (zone(first), first)}

        def best_turn() -> float:  # the fitted turn (0) wins a tie
            return min(seen, key=lambda r: (seen[r][0], r != 0.0))

        def trial(rot: float) -> float:
            if rot not in seen:
                Q = place(rot, tries)
                seen[rot] = (np.inf, None) if Q is None else (zone(Q), Q)
            return seen[rot][0]

        step = 2 * np.pi / _FAN_TURNS
        for t in range(1, _FAN_TURNS):
            trial(step * t)
        # golden-section search within one step of the best turn seen
        mid = best_turn()
        a, b = mid - step, mid + step
        g = 0.5 * (np.sqrt(5.0) - 1.0)
        c, d = b - g * (b - a), a + g * (b - a)
        while b - a > _FAN_TURN_TOL:
            if trial(c) <= trial(d):
                b, d = d, c
                c = b - g * (b - a)
            else:
                a, c = c, d
                d = a + g * (b - a)
        return seen[best_turn()]

    # every trial works on the slots the corner rule writes and its jump reads only, not on
    # a copy of the whole network's controls (a copy per trial made stitching quadratic)
    reads, zone_of = _corner_zone_jump(surfaces, shapes, offs, keys, spoke_index, boundaries)
    window = np.unique(
        np.concatenate(
            [reads.ravel(), *(np.asarray(spoke_index[k]) for k in keys)]
            + [np.asarray([w.diag]).ravel() for w in wedges]
            + [np.asarray(sl, dtype=np.int64) for sl in row2]
        ).astype(np.int64)
    )

    def at(slots):
        return np.searchsorted(window, slots)

    near = P[window]
    spoke_at = {k: at(np.asarray(spoke_index[k])) for k in keys}
    row2_at = [tuple(at(np.asarray(sl)).tolist()) for sl in row2]
    reads_at = at(reads)

    def zone(Q: NDArray) -> float:
        return zone_of(Q[reads_at])

    # the fans from the patches' own corner angles, and (at an interior corner) the fan of
    # equal wedges: where row 0 cannot be collinear the one with the smaller corner-zone
    # jump wins (the own fans on a tie), else the equal fan only where every own fan folds
    found = turned(own)
    if equal_fan and (found is None or not exact):
        other = turned(equal_fan)
        if other is not None and (found is None or other[0] < found[0]):
            found = other
    if found is None:
        return False
    P[window] = found[1]
    return True


#: fan turns tried about the corner normal at a corner whose row 0 cannot be collinear,
#: evenly over a full turn; the best is then refined by a golden-section search within one
#: step of it, to a bracket of ``_FAN_TURN_TOL`` radians
_FAN_TURNS = 12
_FAN_TURN_TOL = 1e-2


def _corner_zone_jump(surfaces, shapes, offs, keys, spoke_index, boundaries):
    """The flat control slots ``IDX`` it reads, and a function of their points
    (``P[IDX]``): the largest normal angle (radians) between the two patches of every
    shared boundary at one corner, over the knot span at that corner (the corner zone of
    :func:`seam_report`), 33 samples. The partials are linear in the control points: their
    weights are computed once."""
    a4 = np.arange(DEGREE + 1)
    sides = []
    for k in keys:
        if k[0] != "b":
            continue
        b = boundaries[k[1]]
        ia, ib = _slot_rows(shapes, offs, b, 0)
        t = np.linspace(0.0, 1.0 / (len(ia) - 3), 33)
        if spoke_index[k][0] not in (ia[1], ib[1]):
            t = 1.0 - t
        pair = []
        for patch, side, tt in ((b.a, b.side_a, t), (b.b, b.side_b, 1.0 - t if b.reversed else t)):
            s = surfaces[patch]
            u, v = _side_params(side, tt)
            fu, Nu = basis_local(u, s.knots_u, DEGREE, 1)
            fv, Nv = basis_local(v, s.knots_v, DEGREE, 1)
            mv = shapes[patch][1]
            idx = (
                offs[patch]
                + (fu[:, None, None] + a4[None, :, None]) * mv
                + (fv[:, None, None] + a4[None, None, :])
            )
            wu = Nu[:, 1, :, None] * Nv[:, 0, None, :]
            wv = Nu[:, 0, :, None] * Nv[:, 1, None, :]
            pair.append((idx, wu, wv))
        sides.append(pair)

    if not sides:
        return np.zeros(0, dtype=np.int64), lambda block: 0.0
    # every side's two patches at once: (sides, 2, 33, 4, 4) slots and weights
    IDX = np.array([[idx for idx, _, _ in pair] for pair in sides])
    WU = np.array([[wu for _, wu, _ in pair] for pair in sides])
    WV = np.array([[wv for _, _, wv in pair] for pair in sides])

    def jump(block: NDArray) -> float:
        du = np.einsum("spnab,spnabc->spnc", WU, block)
        dv = np.einsum("spnab,spnabc->spnc", WV, block)
        n = np.empty(du.shape)  # np.cross's products and differences, without its dispatch
        n[..., 0] = du[..., 1] * dv[..., 2] - du[..., 2] * dv[..., 1]
        n[..., 1] = du[..., 2] * dv[..., 0] - du[..., 0] * dv[..., 2]
        n[..., 2] = du[..., 0] * dv[..., 1] - du[..., 1] * dv[..., 0]
        ln = np.sqrt((n * n).sum(axis=-1))  # np.linalg.norm's sum, without its checks
        n = n / np.where(ln > 0, ln, 1.0)[..., None]
        cos = (n[:, 0] * n[:, 1]).sum(axis=-1)
        ok = (np.abs(n[:, 0]).sum(axis=-1) > 0) & (np.abs(n[:, 1]).sum(axis=-1) > 0)
        if not ok.any():
            return 0.0
        return float(np.arccos(np.clip(cos[ok], -1.0, 1.0)).max())

    return IDX, jump


def _slot_rows(shapes, offs, b: SharedBoundary, depth: int):
    """Flat control-slot indices of a boundary's rows on both patches, aligned (``offs``:
    each patch's first slot)."""
    ia = side_row(np.arange(shapes[b.a][0] * shapes[b.a][1]).reshape(shapes[b.a]), b.side_a, depth)
    ib = side_row(np.arange(shapes[b.b][0] * shapes[b.b][1]).reshape(shapes[b.b]), b.side_b, depth)
    if b.reversed:
        ib = ib[::-1]
    return ia + offs[b.a], ib + offs[b.b]


def stitch_surfaces(surfaces: Sequence[BSplineSurface], network: Network) -> list[BSplineSurface]:  # noqa: C901 (the boundary and corner passes share their state; to split)
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
    3. G1 at a corner whose shared boundaries are all G1 (a corner with a C0 boundary is
       left C0):

       - border corner of valence 2: the corner moves onto the line of its two border
         neighbours in the boundary's ratio; row 0 is then collinear like the others and
         the boundary is G1 to its end;
       - any other valence (see :func:`_g1_corner`): the corner control points (corner,
         spokes ``P[1,0], P[0,1]``, diagonal ``P[1,1]`` of every patch) are laid into one
         plane, the patches' mean tangent plane over their first knot span at the corner,
         as a flat fan that keeps each patch's corner angle (scaled to a full turn) and
         spoke lengths, so no patch corner folds (every corner keeps the orientation of its
         patch, at an angle at least ``tol.STITCH_CORNER_MIN_ANGLE`` from 0 and pi); the
         row-1 collinearity of every boundary there is solved together with it. At an
         interior corner of valence 4 (its boundaries' ratios set to 1) row 0 is made
         collinear too, opposite spokes symmetric about the corner: G1 is exact to the
         boundary's end. At other valences row 0 cannot be collinear (the three spokes of a
         valence-3 corner cannot be pairwise opposite); the fan is pulled towards ``e_a +
         lam e_b`` parallel to the boundary's own spoke (``e_a, e_b`` the two patches' other
         spokes), and row 2 from the corner is translated onto the corner plane, so the
         boundary curves leave the corner without normal curvature; the fan is turned about
         the normal to the smallest normal jump over the first knot span. The normal jump within
         the first knot span is then small but not zero (uniform bicubic patches cannot be
         G1 there in general without extra knots). A corner whose fan would fold is left C0.
    """
    surfaces = _check(surfaces, network)
    shapes = [s.shape for s in surfaces]
    P = np.concatenate([s.control_points.reshape(-1, 3) for s in surfaces])
    offs = np.concatenate([[0], np.cumsum([mu * mv for mu, mv in shapes])])

    # 1. C0: union-find over boundary slots
    sets = DisjointSets(P.shape[0])
    for b in network.boundaries:
        ia, ib = _slot_rows(shapes, offs, b, 0)
        for x, y in zip(ia, ib, strict=True):
            sets.union(int(x), int(y))
    corner_slot = {}
    for c, slots in enumerate(network.corners):
        for k, i, j in slots:
            mu, mv = shapes[k]
            s = offs[k] + (i % mu) * mv + (j % mv)
            corner_slot[(k, i, j)] = int(s)
        first = corner_slot[slots[0]]
        for sl in slots[1:]:
            sets.union(corner_slot[sl], first)
        del c
    roots = np.array([sets.find(x) for x in range(P.shape[0])])
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
            ia, ib = _slot_rows(shapes, offs, b, 0)
            ta, tb = _slot_rows(shapes, offs, b, 1)
            da = np.linalg.norm(P[ia] - P[ta], axis=1).mean()
            db = np.linalg.norm(P[tb] - P[ib], axis=1).mean()
            lam[bi] = float(da / db) if db > 0 and da > 0 else 1.0
    exact4 = set()
    for ci, slots in enumerate(network.corners):
        spokes = _corner_spokes(shapes, offs, slots, bound_of)
        if (
            len(slots) == 4
            and len(spokes) == 4
            and all(len(v) == 2 and bi in lam for bi, v in spokes.items())
        ):
            exact4.add(ci)
            for bi in spokes:
                lam[bi] = 1.0
    for bi, b in enumerate(network.boundaries):
        if bi not in lam:
            continue
        ia, ib = _slot_rows(shapes, offs, b, 0)
        ta, tb = _slot_rows(shapes, offs, b, 1)
        c = (P[ta[1:-1]] + lam[bi] * P[tb[1:-1]]) / (1.0 + lam[bi])
        P[ia[1:-1]] = c
        P[ib[1:-1]] = c

    # 3. G1 at corners of valence 2 (network border) and >= 3 (any), never folding a patch
    for ci, slots in enumerate(network.corners):
        spokes = _corner_spokes(shapes, offs, slots, bound_of)
        if not spokes or any(network.boundaries[bi].continuity != "G1" for bi in spokes):
            continue
        if len(slots) == 2 and len(spokes) == 1 and all(len(v) == 2 for v in spokes.values()):
            _border_corner(P, shapes, offs, slots, bound_of, network.boundaries, lam)
        elif len(slots) >= 2:
            exact = ci in exact4
            _g1_corner(P, shapes, offs, slots, bound_of, network.boundaries, lam, surfaces, exact)
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

    ``samples`` boundary parameters ``t = k / (samples - 1)`` per boundary. At each, both
    patches are evaluated on the boundary itself (side parameter 0 or 1) at the same
    boundary point: the gap is the distance between the two points, the normal jump the
    angle between the two unit normals ``S_u x S_v`` (where those vanish, at a collapsed
    corner, the normal a step ``tol.BSPLINE_NORMAL_STEP`` into the patch). A boundary
    sample belongs to a corner zone when it lies within one knot span of either end of the
    boundary (``t <= 1 / (n - 3)`` or ``t >= 1 - 1 / (n - 3)``, ``n`` control points along
    it): the span where the corner's control points act on the boundary's normals.
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
    """Parameters, world-space vectors, frames and spline points of a map's boundary row (in
    the side's increasing parameter order). The vectors: a vector map's displacements, a
    scalar map's ``s N``, a bump map's normals."""
    h, w = dmap.shape
    n = w if side[0] == "u" else h
    t = np.linspace(0.0, 1.0, n)
    u, v = _side_params(side, t)
    S, T, B, N = surface.points_and_frames(u, v)
    comp = side_row(dmap.values, side)
    if dmap.kind == "scalar":
        world = comp[:, :1] * N
    else:
        world = comp[:, :1] * T + comp[:, 1:2] * B + comp[:, 2:] * N
    return t, world, (T, B, N), S


def _set_row(values: NDArray, side: str, world: NDArray, frames) -> None:
    T, B, N = frames
    comp = np.stack([(world * T).sum(1), (world * B).sum(1), (world * N).sum(1)], axis=1)
    side_row(values, side)[...] = comp


def _interp_rows(t_from: NDArray, rows: NDArray, t_to: NDArray) -> NDArray:
    return np.stack([np.interp(t_to, t_from, rows[:, c]) for c in range(rows.shape[1])], axis=1)


def _seam_rows(t_c, x_c, t_f, x_f):
    """World points of a coarse and a fine displaced boundary row that form one polyline.

    The seam polyline ``Q`` has a vertex at every coarse texel: the mean of the coarse
    texel's displaced point and that of the fine texel nearest it in parameter. The coarse
    row becomes ``Q``; those fine texels take its vertices, and the fine texels between two
    such take points on the straight segment between them, spaced as their parameters.
    Rows that already form one polyline this way are returned as they are, so stitching
    stitched maps changes nothing (a rebuild after editing one map moves no other seam).
    Returns ``(x_c_new, x_f_new)``.
    """
    n_f = len(t_f)
    hit = np.rint(t_c * (n_f - 1)).astype(np.int64)
    hit[0], hit[-1] = 0, n_f - 1
    if (np.diff(hit) <= 0).any():  # more coarse than fine texels: not a coarse row
        raise AssertionError("seam rows out of order")
    q = 0.5 * (x_c + x_f[hit])
    out = np.empty_like(x_f)
    for i in range(len(t_c) - 1):
        j0, j1 = hit[i], hit[i + 1]
        f = (t_f[j0 : j1 + 1] - t_f[j0]) / (t_f[j1] - t_f[j0])
        out[j0 : j1 + 1] = q[i] + f[:, None] * (q[i + 1] - q[i])
    return q, out


#: map kinds whose seams :func:`stitch_displacements` closes
MAP_KINDS = ("vector", "scalar", "bump")


def _check_maps(surfaces, maps, network: Network):
    """The surfaces (checked by `_check`) and one map per surface, all of one kind among
    ``MAP_KINDS``, as lists."""
    surfaces = _check(surfaces, network)
    maps = list(maps)
    if len(maps) != len(surfaces):
        raise InputError(f"{len(maps)} maps for {len(surfaces)} surfaces")
    for k, m in enumerate(maps):
        if not isinstance(m, DisplacementMap) or m.kind not in MAP_KINDS:
            what = m.kind if isinstance(m, DisplacementMap) else type(m).__name__
            hint = " (stitch the vector map it scales)" if what == "magnitude" else ""
            raise InputError(f"maps[{k}] must be a vector, scalar or bump map, not {what}{hint}")
    kinds = sorted({m.kind for m in maps})
    if len(kinds) > 1:
        raise InputError(f"the maps of a network must be of one kind, got {', '.join(kinds)}")
    return surfaces, maps


def match_map_shapes(
    surfaces: Sequence[BSplineSurface],
    maps: Sequence[DisplacementMap],
    network: Network,
) -> list[DisplacementMap]:
    """Maps resampled to equal texel counts along every shared boundary.

    Each map takes the resolution :func:`meshfit.stitch.texel_shapes` gives (the largest
    count of each equal-count class, so no map is made coarser). A map whose resolution
    changes is resampled by :func:`meshfit.displacement.resample_map` with its surface:
    vector maps by their displaced points (each new texel's point on the bilinear
    interpolation of the old displaced grid, so the finer surface stays in the old one's
    cells and as near the scan), bump maps as model-space normals filtered bilinearly and
    expressed in the frames at the new texels, scalar maps as values (applied along the
    normal at the output point).

    Run it before :func:`stitch_displacements` to close the seams at every output
    resolution, not only with each patch tessellated at its map's own resolution.

    Parameters
    ----------
    surfaces : sequence of BSplineSurface
        The (stitched) surfaces, control counts consistent across ``network``.
    maps : sequence of DisplacementMap
        One map per patch, all ``vector``, all ``scalar`` or all ``bump``, any resolutions.
    network : Network

    Returns
    -------
    list of DisplacementMap
        Maps at :func:`meshfit.stitch.texel_shapes`; a map already at its shape is returned
        as it is.

    Raises
    ------
    meshfit.errors.InputError
        Not one map per surface, maps of another or of mixed kinds, or inconsistent control
        counts.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.2 (bilinear reconstruction) and sec. 8.2 (crack-free
       displacement seams).
    """
    from meshfit.displacement import resample_map

    surfaces, maps = _check_maps(surfaces, maps, network)
    shapes = texel_shapes(network, [m.shape for m in maps])
    return [
        m if shape == m.shape else resample_map(m, shape, surface=s, points=m.kind == "vector")
        for s, m, shape in zip(surfaces, maps, shapes, strict=True)
    ]


def stitch_displacements(
    surfaces: Sequence[BSplineSurface],
    maps: Sequence[DisplacementMap],
    network: Network,
    *,
    blend: int = 1,
    gap: float | None = None,
) -> list[DisplacementMap]:
    """Close the seams of displacement or bump maps across shared boundaries (sec. 8.2).

    Parameters
    ----------
    surfaces : sequence of BSplineSurface
        The stitched surfaces (C0 at least: shared boundary curves identical).
    maps : sequence of DisplacementMap
        One map per patch, all ``vector``, all ``scalar`` or all ``bump``, any resolutions.
    network : Network
        Shared boundaries and corners; a bump map reads their continuity (a scalar map
        reads the surfaces' normals instead, see Notes).
    blend : int, keyword-only
        Scalar maps: the texels, counted from the seam row, over which a seam's change of
        value fades into the map (2: the seam row, then half the change on the next row);
        at most half the texels across a map. Default 1, the seam row only: wider blends
        move the rebuilt surface farther from the grids, and are for a softer look.
    gap : float, keyword-only, optional
        Scalar maps: the largest distance, model units, left between the two displaced
        points of a seam (see Notes). Default half of ``tol.STITCH_GAP`` times the bbox
        diagonal of the surfaces' control points: closed up to round-off. A larger ``gap``
        keeps more detail where the two patches' normals differ slightly.

    Returns
    -------
    list of DisplacementMap
        Same kinds and resolutions. Vector and bump maps change on boundary texels only,
        scalar maps within ``blend`` texels of a seam.

    Notes
    -----
    **Vector maps.** At every network corner the corner texels take the mean of their
    model-space vectors. Along a shared boundary:

    - equal texel counts: both rows take the mean model-space vector; the displaced
      boundaries are then one curve at every output resolution
      (:func:`meshfit.displacement.reconstruct` filters model-space vectors);
    - different counts (nested or not): the seam is defined once, as the polyline whose
      vertices are, at the coarser row's texels, the mean of the two patches' displaced
      boundaries (the finer one at its texel nearest in parameter): the coarser row
      reproduces those vertices; in the finer row the texel nearest each vertex in parameter
      reproduces it and the texels between lie on the straight segment between two
      vertices, spaced as their parameters (vector maps may move a point along the seam).

    **Scalar maps** displace along each patch's own normal, so two boundary points
    ``S + s_a N_a`` and ``S + s_b N_b`` meet only where ``s_a = s_b`` and, unless both are
    0, ``N_a = N_b``. Each seam texel takes the mean ``s`` of the two patches' values,
    clipped so that ``|s| |N_a - N_b| <= gap`` on the texel intervals either side of it;
    each corner texel takes the mean over all patches at the corner, clipped likewise (its
    own normals, and the intervals of every seam there). That is the value nearest the mean
    whose displaced seam stays within ``gap``, at the texels and, with equal counts, at
    every resolution in between. Where the splines are G1 the normals are equal and the
    mean stands: the displaced seams are identical. Across a C0 boundary (a crease), and
    within a corner's first knot span where a G1 stitch leaves the normals slightly apart
    (corners of valence other than 4), the value shrinks to about 0: the displaced seam is
    then the shared spline boundary, the only curve both patches reach along their own
    normals. The choice is made per texel from the surfaces' normals, so it holds whatever
    continuity ``network`` declares. The normals are compared at 32 points per interval,
    and an interval where their difference or a patch's partials change fast between two
    of them (a patch folding over) counts as one of opposite normals; a fold narrower than
    that can still open the seam between texels, never at them.

    With different counts along a boundary the coarser row takes the (clipped) mean, with
    the finer row interpolated at its texels, and the finer row the coarser row's values
    interpolated. With nested counts (``n_f - 1`` a multiple of ``n_c - 1``) the seam is
    then closed as :func:`meshfit.displacement.reconstruct` reads the maps at any common
    resolution, but tessellated at the two maps' own resolutions the finer row's vertices
    lie on the displaced curve, not on the coarser row's straight segments; other counts
    leave gaps of the size of the detail between texels. Give scalar maps equal counts
    along shared boundaries (:func:`match_map_shapes`) first.

    **Bump maps** carry shading normals. Across G1 boundaries the two rows take their
    normalised mean model-space normal (corner texels: the mean over the patches at the
    corner joined by G1 boundaries there), so shading has no seam at any resolution
    (:func:`meshfit.displacement.bump_normals` filters model-space normals). Across C0
    boundaries the normals are left as they are: the surface is meant to break there, and
    averaging would round the crease's shading. Unequal counts: as for scalar maps.

    Crack-free, for vector maps, means: each patch tessellated at its own map's resolution
    (the grid of ``reconstruct`` without ``shape``, the displaced mesh the pipeline exports),
    every displaced boundary vertex of one patch lies on the other's displaced boundary
    polyline, so the two polylines are one (``displacement_seam_gaps(...,
    tessellation="texels")`` is 0 up to round-off). With different counts the seams are
    not closed at other output resolutions (the spline between texels is not straight);
    with equal counts they are at every resolution, for every kind.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 8.2 (averaging the boundary rows of adjacent maps),
       sec. 7.1 (scalar maps displace along the normal), sec. 7.4 (bump maps).
    """
    surfaces, maps = _check_maps(surfaces, maps, network)
    if int(blend) != blend or blend < 1:
        raise InputError(f"blend must be a whole number of texels >= 1, got {blend!r}")
    kind = maps[0].kind if maps else "vector"
    if kind == "scalar":
        if gap is not None and not (np.isfinite(gap) and gap >= 0):
            raise InputError(f"gap must be a length >= 0, got {gap!r}")
        return _stitch_scalar(surfaces, maps, network, int(blend), gap)
    if kind == "bump":
        return _stitch_bump(surfaces, maps, network)
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
        # rows, frames and the shared boundary curve at the texels, both in a's direction
        # (t is symmetric: b's texel parameters read backwards are a's)
        ta, wa, fa, sa = _row_world(surfaces[b.a], cur[0], b.side_a)
        tb, wb, fb, sb = _row_world(surfaces[b.b], cur[1], b.side_b)
        if b.reversed:
            wb, fb, sb = wb[::-1], tuple(f[::-1] for f in fb), sb[::-1]
        if len(ta) == len(tb):  # equal rows: the mean vector, crack-free at any resolution
            new_a = new_b = 0.5 * (wa + wb)
        else:
            a_coarse = len(ta) < len(tb)
            tc, sc, wc, tf, sf, wf = (
                (ta, sa, wa, tb, sb, wb) if a_coarse else (tb, sb, wb, ta, sa, wa)
            )
            xc, xf = _seam_rows(tc, sc + wc, tf, sf + wf)
            new_c, new_f = xc - sc, xf - sf
            new_a, new_b = (new_c, new_f) if a_coarse else (new_f, new_c)
        _set_row(vals[b.a], b.side_a, new_a, fa)
        if b.reversed:
            new_b, fb = new_b[::-1], tuple(f[::-1] for f in fb)
        _set_row(vals[b.b], b.side_b, new_b, fb)
    return [DisplacementMap(v, "vector") for v in vals]


#: the sides of a patch meeting at each of its corners ``(i_end, j_end)``, and the end of
#: each side's row (in increasing parameter order) that is the corner
_SIDES_AT_CORNER = {
    (0, 0): (("u0", 0), ("v0", 0)),
    (0, -1): (("u0", -1), ("v1", 0)),
    (-1, 0): (("u1", 0), ("v0", -1)),
    (-1, -1): (("u1", -1), ("v1", -1)),
}


def _diagonal(surfaces: Sequence[BSplineSurface]) -> float:
    """Bounding-box diagonal of the surfaces' control points, model units."""
    P = np.concatenate([s.control_points.reshape(-1, 3) for s in surfaces])
    return float(np.linalg.norm(np.ptp(P, axis=0)))


def _side_normals(surface: BSplineSurface, side: str, t: NDArray) -> NDArray:
    u, v = _side_params(side, t)
    return surface.normals(u, v)


#: samples per texel interval at which a scalar seam's normal difference is measured
_SEAM_SAMPLES = 32
#: an interval where, between two samples, the normal difference ``|N_a - N_b|`` or either
#: patch's ``|S_u x S_v| / (|S_u| |S_v|)`` changes by more than this (a patch folding over
#: near a corner, its normal turning within a fraction of a texel) is taken at the largest
#: difference, 2
_SEAM_STEP = 0.1


def _side_normals_and_sines(surface: BSplineSurface, side: str, t: NDArray):
    """Unit normals ``(n, 3)`` along a side and the sines ``(n,)`` of the angle between the
    partials there."""
    u, v = _side_params(side, t)
    _, su, sv = surface.evaluate(u, v, derivatives=1)
    n = np.cross(su, sv)
    ln = np.linalg.norm(n, axis=1)
    sine = ln / np.maximum(np.linalg.norm(su, axis=1) * np.linalg.norm(sv, axis=1), 1e-300)
    n /= np.maximum(ln, 1e-300)[:, None]
    bad = sine <= tol.BSPLINE_DEGENERATE  # a collapsed point: the surface's own rule
    if bad.any():
        n[bad] = surface.normals(u[bad], v[bad])
    return n, sine


def _seam_limits(at_a, at_b, t: NDArray, eps: float) -> NDArray:
    """Largest ``|s|`` per texel of a scalar seam row at parameters ``t (n,)``: ``eps`` over
    the largest ``|N_a - N_b|`` on the texel intervals either side of it (``_SEAM_SAMPLES``
    per interval; 2 where it or a patch's partials change fast, ``_SEAM_STEP``), so that
    the interpolated value along either normal stays within ``eps`` of the other on the
    seam. ``at_a, at_b``: normals and sines (`_side_normals_and_sines`) at parameters."""
    f = np.linspace(0.0, 1.0, _SEAM_SAMPLES)
    tt = (t[:-1, None] + f[None, :] * np.diff(t)[:, None]).ravel()
    (na, sin_a), (nb, sin_b) = at_a(tt), at_b(tt)
    shape = (len(t) - 1, _SEAM_SAMPLES)
    dn = np.linalg.norm(na - nb, axis=1).reshape(shape)
    fast = np.zeros(shape[0], dtype=bool)
    for x in (dn, sin_a.reshape(shape), sin_b.reshape(shape)):
        fast |= np.abs(np.diff(x, axis=1)).max(axis=1) > _SEAM_STEP
    dn = np.where(fast, 2.0, dn.max(axis=1))
    worst = np.maximum(np.r_[dn, 0.0], np.r_[0.0, dn])
    return eps / np.maximum(worst, np.finfo(float).tiny)


def _end_slot(k: int, side: str, end: int) -> tuple[int, int, int]:
    """The corner slot ``(k, i_end, j_end)`` at end ``end`` (0 or -1) of side ``side``'s row."""
    ((i, j),) = [ij for ij, sides in _SIDES_AT_CORNER.items() if (side, end) in sides]
    return k, i, j


class _ScalarSeam:
    """One shared boundary of scalar maps, rows in a's parameter order: texel parameters
    ``t`` and limits ``lim`` of both rows (the finer row's limits those of the coarser
    interpolated, as its values will be)."""

    def __init__(self, surfaces, shapes, b: SharedBoundary, eps: float):
        self.b = b
        normals_at, self.t = [], []
        for k, side, rev in ((b.a, b.side_a, False), (b.b, b.side_b, b.reversed)):
            self.t.append(np.linspace(0.0, 1.0, shapes[k][1 if side[0] == "u" else 0]))

            def at(t, k=k, side=side, rev=rev):  # at a's parameters t
                return _side_normals_and_sines(surfaces[k], side, 1.0 - t if rev else t)

            normals_at.append(at)
        self.coarse = 0 if len(self.t[0]) <= len(self.t[1]) else 1
        lim = _seam_limits(*normals_at, self.t[self.coarse], eps)
        self.lim = [np.interp(t, self.t[self.coarse], lim) for t in self.t]

    def own(self, x: int, row: NDArray) -> NDArray:
        """Row ``row`` of patch a (``x = 0``) or b (1) in its side's order, to a's order and
        back (the same flip)."""
        return row[::-1] if x == 1 and self.b.reversed else row

    def values(self, vals, corner: dict) -> tuple[NDArray, NDArray]:
        """New rows of both patches, each in its own side's order: the coarser row the
        clipped mean with the corner values at its ends, the finer row it interpolated."""
        b, c = self.b, self.coarse
        rows = [
            self.own(0, side_row(vals[b.a], b.side_a)),
            self.own(1, side_row(vals[b.b], b.side_b)),
        ]
        tc, tf = self.t[c], self.t[1 - c]
        mean = 0.5 * (rows[c] + np.interp(tc, tf, rows[1 - c]))
        new_c = np.clip(mean, -self.lim[c], self.lim[c])
        k, side = (b.a, b.side_a) if c == 0 else (b.b, b.side_b)
        for end in (0, -1):  # corner values, in a's order
            slot = _end_slot(k, side, end if not (c == 1 and b.reversed) else -1 - end)
            if slot in corner:
                new_c[end] = corner[slot]
        new_f = new_c if len(tf) == len(tc) else np.interp(tf, tc, new_c)
        new = [new_c, new_f] if c == 0 else [new_f, new_c]
        return self.own(0, new[0]), self.own(1, new[1])


def _stitch_scalar(surfaces, maps, network: Network, blend: int, gap) -> list[DisplacementMap]:
    """`stitch_displacements` for scalar maps (see its Notes)."""
    eps = 0.5 * tol.STITCH_GAP * _diagonal(surfaces) if gap is None else float(gap)
    vals = [np.array(m.values[:, :, 0]) for m in maps]
    shapes = [m.shape for m in maps]
    seams = [_ScalarSeam(surfaces, shapes, b, eps) for b in network.boundaries]
    limits = {}  # (patch, side) -> limits in the side's order
    for sm in seams:
        limits[(sm.b.a, sm.b.side_a)] = sm.own(0, sm.lim[0])
        limits[(sm.b.b, sm.b.side_b)] = sm.own(1, sm.lim[1])
    corner: dict[tuple[int, int, int], float] = {}
    for slots in network.corners:
        if len(slots) < 2:
            continue
        n = np.array(
            [surfaces[k].normals(float(i == -1), float(j == -1)) for k, i, j in slots]
        ).reshape(-1, 3)
        dn = float(np.linalg.norm(n[:, None] - n[None], axis=-1).max())
        lim = min(
            [eps / max(dn, np.finfo(float).tiny)]
            + [
                float(limits[(k, side)][e])
                for k, i, j in slots
                for side, e in _SIDES_AT_CORNER[(i, j)]
                if (k, side) in limits
            ]
        )
        c = float(np.clip(np.mean([vals[k][i, j] for k, i, j in slots]), -lim, lim))
        corner.update(dict.fromkeys(slots, c))
    targets = {}
    for sm in seams:
        new_a, new_b = sm.values(vals, corner)
        targets[(sm.b.a, sm.b.side_a)], targets[(sm.b.b, sm.b.side_b)] = new_a, new_b
    for (k, i, j), c in corner.items():  # corner texels on no shared side
        if not any((k, side) in targets for side, _ in _SIDES_AT_CORNER[(i, j)]):
            vals[k][i, j] = c
    for (k, side), target in sorted(targets.items()):
        across = vals[k].shape[0 if side[0] == "u" else 1]
        depth = max(1, min(blend, (across - 1) // 2))
        change = target - side_row(vals[k], side)
        side_row(vals[k], side)[...] = target  # exactly: both patches' rows are one
        for d in range(1, depth):
            side_row(vals[k], side, d)[...] += change * (1.0 - d / depth)
    return [DisplacementMap(v, "scalar") for v in vals]


def _unit_rows(x: NDArray) -> NDArray:
    ln = np.linalg.norm(x, axis=-1, keepdims=True)
    return x / np.maximum(ln, np.finfo(float).tiny)


def _stitch_bump(surfaces, maps, network: Network) -> list[DisplacementMap]:  # noqa: C901 (seam rows and corners of one kind share their state; to split)
    """`stitch_displacements` for bump maps (see its Notes)."""
    vals = [m.values.copy() for m in maps]
    g1_ends: set[tuple[tuple[int, int, int], tuple[int, int, int]]] = set()
    for b in network.boundaries:
        if b.continuity != "G1":
            continue
        for end in (0, -1):  # the corner slots of a and b at each end of the boundary
            e_b = end if not b.reversed else -1 - end
            g1_ends.add((_end_slot(b.a, b.side_a, end), _end_slot(b.b, b.side_b, e_b)))
    for slots in network.corners:
        if len(slots) < 2:
            continue
        sets = DisjointSets(len(slots))
        index = {sl: x for x, sl in enumerate(slots)}
        for p, q in g1_ends:
            if p in index and q in index:
                sets.union(index[p], index[q])
        groups: dict[int, list] = {}
        for sl in slots:
            groups.setdefault(sets.find(index[sl]), []).append(sl)
        for group in groups.values():
            if len(group) < 2:
                continue
            frames, world = [], []
            for k, i, j in group:
                T, B, N = surfaces[k].frames(float(i == -1), float(j == -1))
                c = vals[k][i, j]
                frames.append((T, B, N))
                world.append(c[0] * T + c[1] * B + c[2] * N)
            mean = _unit_rows(np.sum(world, axis=0))
            for (k, i, j), (T, B, N) in zip(group, frames, strict=True):
                vals[k][i, j] = [mean @ T, mean @ B, mean @ N]
    for b in network.boundaries:
        if b.continuity != "G1":
            continue
        cur = [DisplacementMap(vals[b.a], "bump"), DisplacementMap(vals[b.b], "bump")]
        ta, wa, fa, _ = _row_world(surfaces[b.a], cur[0], b.side_a)
        tb, wb, fb, _ = _row_world(surfaces[b.b], cur[1], b.side_b)
        if b.reversed:
            wb, fb = wb[::-1], tuple(f[::-1] for f in fb)
        if len(ta) == len(tb):
            new_a = new_b = _unit_rows(wa + wb)
        else:
            a_coarse = len(ta) < len(tb)
            tc, wc, tf, wf = (ta, wa, tb, wb) if a_coarse else (tb, wb, ta, wa)
            new_c = _unit_rows(wc + _unit_rows(_interp_rows(tf, wf, tc)))
            new_f = _unit_rows(_interp_rows(tc, new_c, tf))
            new_a, new_b = (new_c, new_f) if a_coarse else (new_f, new_c)
        _set_row(vals[b.a], b.side_a, new_a, fa)
        if b.reversed:
            new_b, fb = new_b[::-1], tuple(f[::-1] for f in fb)
        _set_row(vals[b.b], b.side_b, new_b, fb)
    return [DisplacementMap(v, "bump") for v in vals]


def _polyline_gap(a: NDArray, b: NDArray) -> float:
    """Largest distance from the points ``a`` to the polyline through the points ``b``."""
    from meshfit._kernels.geometry import polyline_gap

    return float(polyline_gap(np.ascontiguousarray(a), np.ascontiguousarray(b)))


def displacement_seam_gaps(
    surfaces: Sequence[BSplineSurface],
    maps: Sequence[DisplacementMap],
    network: Network,
    *,
    samples: int = 401,
    tessellation: str = "texels",
) -> NDArray[np.float64]:
    """Largest gap between displaced boundaries per shared boundary, model units.

    Maps of every kind that :func:`stitch_displacements` closes: vector, scalar (displaced
    along the normal) and bump (no displacement: the gap is the splines').

    ``tessellation="texels"`` (default): each patch tessellated at its map's own resolution
    (:func:`meshfit.displacement.reconstruct` without ``shape``, the displaced mesh the
    pipeline exports); the gap is the largest distance from a displaced boundary vertex of
    either patch to the other patch's displaced boundary polyline. 0 means the two
    polylines are one: no crack, T-junctions only on straight segments.

    ``tessellation="continuous"``: the displaced boundary at boundary parameter t as
    ``reconstruct`` gives it at any resolution (vector maps: the spline point plus the
    linear interpolation of the boundary texels' model-space vectors; scalar maps: the
    interpolated value along the normal at t); the gap is the largest distance between the
    two patches' points at equal t over ``samples`` parameters. 0 means crack-free at every
    output resolution.
    """
    if tessellation not in ("texels", "continuous"):
        raise InputError(f"tessellation must be 'texels' or 'continuous', got {tessellation!r}")
    surfaces, maps = _check_maps(surfaces, maps, network)
    t = np.linspace(0.0, 1.0, samples)
    out = []
    for b in network.boundaries:
        pts = []
        for k, side, rev in ((b.a, b.side_a, False), (b.b, b.side_b, b.reversed)):
            m = maps[k]
            tr, wr, _, sr = _row_world(surfaces[k], m, side)
            if m.kind == "bump":
                wr = np.zeros_like(wr)
            if tessellation == "texels":
                row = sr + wr
                pts.append(row[::-1] if rev else row)
                continue
            tt = t[::-1] if rev else t
            u, v = _side_params(side, tt)
            if m.kind == "scalar":
                S, _, _, N = surfaces[k].points_and_frames(u, v)
                s = np.interp(tt, tr, side_row(m.values, side)[:, 0])
                pts.append(S + s[:, None] * N)
            else:
                pts.append(surfaces[k].evaluate(u, v) + _interp_rows(tr, wr, tt))
        if tessellation == "texels":
            out.append(max(_polyline_gap(pts[0], pts[1]), _polyline_gap(pts[1], pts[0])))
        else:
            out.append(float(np.linalg.norm(pts[0] - pts[1], axis=1).max()))
    return np.array(out)


def bump_seam_angles(
    surfaces: Sequence[BSplineSurface],
    maps: Sequence[DisplacementMap],
    network: Network,
    *,
    samples: int = 401,
) -> NDArray[np.float64]:
    """Largest angle between the two patches' shading normals per shared boundary, degrees.

    At ``samples`` boundary parameters t, each patch's shading normal on the boundary as
    :func:`meshfit.displacement.bump_normals` gives it at any resolution (the boundary
    texels' model-space normals interpolated linearly, normalised). 0 means the shading
    has no seam there; across a C0 boundary :func:`stitch_displacements` keeps the
    crease's own jump.

    Raises
    ------
    meshfit.errors.InputError
        Maps that are not one bump map per surface.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.4 (bump maps), sec. 8.2 (seams).
    """
    surfaces, maps = _check_maps(surfaces, maps, network)
    if maps and maps[0].kind != "bump":
        raise InputError(f"bump_seam_angles needs bump maps, got {maps[0].kind} maps")
    t = np.linspace(0.0, 1.0, samples)
    out = []
    for b in network.boundaries:
        n = []
        for k, side, rev in ((b.a, b.side_a, False), (b.b, b.side_b, b.reversed)):
            tr, wr, _, _ = _row_world(surfaces[k], maps[k], side)
            n.append(_unit_rows(_interp_rows(tr, wr, t[::-1] if rev else t)))
        cos = np.clip((n[0] * n[1]).sum(axis=1), -1.0, 1.0)
        out.append(float(np.degrees(np.arccos(cos)).max()))
    return np.array(out)
