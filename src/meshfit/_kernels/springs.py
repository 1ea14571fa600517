"""Numba kernels of the spring mesh: relaxation sweeps and FindMidPoint subdivision.

No validation here: :mod:`meshfit.springs` checks every input and passes contiguous arrays.
Grids are flattened row-major: point ``(i, j)`` of an ``(nu, nv)`` grid is row ``i * nv + j``;
``i`` runs along ``u`` (the "left-right" neighbours), ``j`` along ``v`` ("up-down").
``fastmath`` stays off: the walking kernels pick exit edges by sign tests.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner
from meshfit._kernels.geometry import _cross
from meshfit._kernels.walk import (
    DONE,
    _face_normal,
    _in_plane,
    _move_in_face,
    _start_direction,
    _walk_one,
)

#: fraction of the way to its face's centre that a point stuck on the boundary is moved
NUDGE = 1e-2

#: spring point kinds (``SpringMesh.kind``)
BOUNDARY = 0
ANCHOR = 1
CURVE = 2
FREE = 3


@njit(cache=True, nogil=True, fastmath=False)
def grid_xyz(V, F, face, bary):
    """Positions of face points; face (n,) i8, bary (n, 3) f8 -> (n, 3) f8."""
    n = face.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        f = face[i]
        for c in range(3):
            out[i, c] = (
                bary[i, 0] * V[F[f, 0], c] + bary[i, 1] * V[F[f, 1], c] + bary[i, 2] * V[F[f, 2], c]
            )
    return out


# the per-point helpers of `relax_sweeps` are inlined into it (calls with array arguments
# cost a noticeable share of the sweeps on a large patch; same grids bit for bit)
@inner
def walk_inside(V, F, FN, f, b, u, total, max_faces, bary_eps, tries, b0, u0):
    """Walk face point (f, b) by ``total`` along unit in-plane ``u``, never onto the boundary.

    A walk that reaches the mesh boundary (or fails on a sliver face) is undone and retried at
    half the length, up to ``tries`` times (then the point stays). ``b`` (3,) is updated in
    place; ``b0``, ``u0`` (3,) are scratch. Returns the new face and the length moved.
    """
    for c in range(3):
        b0[c] = b[c]
        u0[c] = u[c]
    length = total
    for _t in range(tries + 1):
        ok = True
        try:  # a sliver face (zero Gram determinant) divides by zero in the walk
            g, _rest, status, _ = _walk_one(V, F, FN, f, b, u, length, max_faces, bary_eps)
        except Exception:  # numba raises ZeroDivisionError there
            ok = False
            status = -1
            g = f
        if ok and status == DONE and np.isfinite(b[0] + b[1] + b[2]):
            return g, length
        for c in range(3):
            b[c] = b0[c]
            u[c] = u0[c]
        length *= 0.5
    return f, 0.0


@inner
def _spring_vector(X, p, q, n0, n1, n2, tangent):
    """Spring vector from grid point ``p`` to its neighbour ``q`` (three scalars); with
    ``tangent`` turned into the plane of unit normal ``(n0, n1, n2)`` keeping its length."""
    d0 = X[q, 0] - X[p, 0]
    d1 = X[q, 1] - X[p, 1]
    d2 = X[q, 2] - X[p, 2]
    if tangent:
        dn = d0 * n0 + d1 * n1 + d2 * n2
        full = np.sqrt(d0**2 + d1**2 + d2**2)
        d0 -= dn * n0
        d1 -= dn * n1
        d2 -= dn * n2
        flat = np.sqrt(d0**2 + d1**2 + d2**2)
        if flat > 0.0:
            r = full / flat
            d0 *= r
            d1 *= r
            d2 *= r
    return d0, d1, d2


@inner
def _pair_arc(a0, a1, a2, b0, b1, b2):
    """Arc-length force (eq. 5.1) of the spring vectors ``a`` and ``b`` to the two
    neighbours along one grid line, toward the farther one by the difference of the
    lengths: the force (three scalars) and the sum of the two lengths."""
    la = np.sqrt(a0**2 + a1**2 + a2**2)
    lb = np.sqrt(b0**2 + b1**2 + b2**2)
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    if la > lb and la > 0.0:
        s = (la - lb) / la
        f0 += s * a0
        f1 += s * a1
        f2 += s * a2
    elif lb > la and lb > 0.0:
        s = (lb - la) / lb
        f0 += s * b0
        f1 += s * b1
        f2 += s * b2
    return f0, f1, f2, la + lb


@inner
def _line_springs(X, N, p, a, b, n0, n1, n2, tangent, fold):
    """Spring vectors from grid point ``p`` to its two neighbours ``a`` and ``b`` along one
    grid line (six scalars, `_spring_vector`). With ``fold``, a vector to a neighbour across
    a fold (its unit normal ``N[a]`` or ``N[b]`` at more than 90 degrees to p's
    ``(n0, n1, n2)``, the other neighbour's not) points along the line instead, away from
    the other neighbour, keeping its length: the chord across a curled rim, turned into p's
    tangent plane, can point anywhere (often back along the line), and the grid line would
    not cross the rim."""
    a0, a1, a2 = _spring_vector(X, p, a, n0, n1, n2, tangent)
    b0, b1, b2 = _spring_vector(X, p, b, n0, n1, n2, tangent)
    if fold:
        ca = N[a, 0] * n0 + N[a, 1] * n1 + N[a, 2] * n2
        cb = N[b, 0] * n0 + N[b, 1] * n1 + N[b, 2] * n2
        if ca < 0.0 <= cb:
            a0, a1, a2 = _away_from(a0, a1, a2, b0, b1, b2)
        elif cb < 0.0 <= ca:
            b0, b1, b2 = _away_from(b0, b1, b2, a0, a1, a2)
    return a0, a1, a2, b0, b1, b2


@inner
def _away_from(x0, x1, x2, y0, y1, y2):
    """The spring vector ``x`` turned to point away from ``y`` (the other neighbour on the
    grid line), keeping its length; ``x`` itself when ``y`` has no length."""
    lx = np.sqrt(x0**2 + x1**2 + x2**2)
    ly = np.sqrt(y0**2 + y1**2 + y2**2)
    if ly > 0.0:
        return -y0 * (lx / ly), -y1 * (lx / ly), -y2 * (lx / ly)
    return x0, x1, x2


@njit(cache=True, nogil=True, fastmath=False)
def spring_force(X, N, nv, p, w_arc, w_fair, n0, n1, n2, tangent, fold):
    """Resultant force (eq. 5.4) on interior grid point ``p`` and its mean spring length:
    ``(f0, f1, f2, h)``, on scalars (no scratch arrays).

    The spring vectors to the four neighbours are the Euclidean ones (sec. 5.5); with
    ``tangent`` each is turned into the tangent plane of unit normal ``(n0, n1, n2)``
    keeping its length, a first-order stand-in for the geodesic forces of sec. 5.5.3; with
    ``fold`` a vector across a fold follows the grid line instead (`_line_springs`; ``N``
    (n, 3) holds the grid points' unit normals). The force is
    ``w_fair * F_fair / 4 + w_arc * F_arc / 4`` (a Gauss-Seidel step: the fairness part
    alone moves the point to the centroid of its four neighbours).
    """
    l0, l1, l2, r0, r1, r2 = _line_springs(X, N, p, p - nv, p + nv, n0, n1, n2, tangent, fold)
    d0, d1, d2, u0, u1, u2 = _line_springs(X, N, p, p - 1, p + 1, n0, n1, n2, tangent, fold)
    a0, a1, a2, h = _pair_arc(l0, l1, l2, r0, r1, r2)
    c0, c1, c2, h2 = _pair_arc(d0, d1, d2, u0, u1, u2)
    # the arc-length force summed from 0 as the line pairs come: (0 + a) + c
    x0 = 0.0 + a0
    x1 = 0.0 + a1
    x2 = 0.0 + a2
    x0 += c0
    x1 += c1
    x2 += c2
    h += h2
    f0 = 0.25 * (w_fair * (l0 + r0 + d0 + u0) + w_arc * x0)
    f1 = 0.25 * (w_fair * (l1 + r1 + d1 + u1) + w_arc * x1)
    f2 = 0.25 * (w_fair * (l2 + r2 + d2 + u2) + w_arc * x2)
    return f0, f1, f2, 0.25 * h


@njit(cache=True, nogil=True, fastmath=False)
def chain_points(arc, ef, ea, eb, positions):
    """Face points at arc-length ``positions (m,) f8`` along a boundary vertex chain with
    cumulative lengths ``arc (k,) f8`` (k >= 2), whose edge ``i`` lies in face ``ef[i]`` at
    vertex slots ``ea[i]``, ``eb[i]`` (``(k - 1,) i8`` each): ``(face (m,) i8, bary (m, 3)
    f8)``. Positions are clamped to the chain; a point at a vertex shared by two edges goes
    to the later edge. Kernel of `meshfit.springs.init.chain_points`."""
    m = positions.shape[0]
    k_max = arc.shape[0] - 2
    face = np.empty(m, dtype=np.int64)
    bary = np.zeros((m, 3))
    for i in range(m):
        x = min(max(positions[i], 0.0), arc[-1])
        k = np.searchsorted(arc, x, side="right") - 1
        k = min(max(k, 0), k_max)
        seg = arc[k + 1] - arc[k]
        t = (x - arc[k]) / seg if seg > 0 else 0.0
        t = min(max(t, 0.0), 1.0)
        face[i] = ef[k]
        bary[i, ea[k]] = 1.0 - t
        bary[i, eb[k]] += t
    return face, bary


@inner
def _cv(x):
    """Standard deviation over mean of the values ``x (n,)`` (0 for none or a zero mean)."""
    n = x.shape[0]
    if n == 0:  # an empty piece (a repeated feature line)
        return 0.0
    m = 0.0
    for k in range(n):
        m += x[k]
    m /= n
    var = 0.0
    for k in range(n):
        var += (x[k] - m) ** 2
    return np.sqrt(var / n) / m if m > 0 else 0.0


@njit(cache=True, nogil=True, fastmath=False)
def grid_spacing(X, ends_u, ends_v):
    """Spacing figures of a grid ``X (nu, nv, 3) f8``: the coefficient of variation (std
    over mean, 0 for a zero mean) of the point spacing along each iso-curve piece between
    consecutive ``ends_u`` (row ends along u, ``(su + 1,) i8``: 0, feature rows, nu - 1),
    per piece ``nv`` values, then those between ``ends_v``, per piece ``nu`` values; and each
    cell's aspect ratio ``(nu - 1, nv - 1)`` (longer over shorter mean side, inf where the
    shorter is 0). Kernel of `meshfit.springs.metrics.spacing`."""
    nu, nv = X.shape[0], X.shape[1]
    du = np.empty((nu - 1, nv))
    dv = np.empty((nu, nv - 1))
    for i in range(nu):
        for j in range(nv):
            if i + 1 < nu:
                a = X[i + 1, j, 0] - X[i, j, 0]
                b = X[i + 1, j, 1] - X[i, j, 1]
                c = X[i + 1, j, 2] - X[i, j, 2]
                du[i, j] = np.sqrt(a * a + b * b + c * c)
            if j + 1 < nv:
                a = X[i, j + 1, 0] - X[i, j, 0]
                b = X[i, j + 1, 1] - X[i, j, 1]
                c = X[i, j + 1, 2] - X[i, j, 2]
                dv[i, j] = np.sqrt(a * a + b * b + c * c)
    nsu = ends_u.shape[0] - 1
    nsv = ends_v.shape[0] - 1
    cv = np.empty(nsu * nv + nsv * nu)
    at = 0
    for s in range(nsu):
        lo, hi = ends_u[s], ends_u[s + 1]
        for j in range(nv):
            cv[at] = _cv(du[lo:hi, j])
            at += 1
    for s in range(nsv):
        lo, hi = ends_v[s], ends_v[s + 1]
        for i in range(nu):
            cv[at] = _cv(dv[i, lo:hi])
            at += 1
    aspect = np.empty((nu - 1, nv - 1))
    for i in range(nu - 1):
        for j in range(nv - 1):
            a = 0.5 * (du[i, j] + du[i, j + 1])
            b = 0.5 * (dv[i, j] + dv[i + 1, j])
            lo_ = min(a, b)
            r = max(a, b) / lo_ if lo_ > 0 else np.inf
            aspect[i, j] = r if np.isfinite(r) else np.inf
    return cv, aspect


@njit(cache=True, nogil=True, fastmath=False)
def pinched_side_points(V, F, face, bary, nu, nv, ratio):
    """Side points of a grid (face (nu nv,) i8, bary (nu nv, 3) f8, row-major) whose shorter
    chord to a neighbouring side point is below ``ratio`` times the median chord of their
    side: ``(m, 2) i8`` rows (side, place along it), sides in the order bottom (j = 0), top
    (j = nv - 1), left (i = 0), right (i = nu - 1), places ascending. Kernel of
    `meshfit.springs.relax.unpinch_side_points`."""
    out = np.empty((2 * (nu + nv), 2), dtype=np.int64)
    m = 0
    for side in range(4):
        n = nu if side < 2 else nv
        along = np.arange(n)
        if side == 0:
            g = along * nv
        elif side == 1:
            g = along * nv + nv - 1
        elif side == 2:
            g = along
        else:
            g = (nu - 1) * nv + along
        x = grid_xyz(V, F, face[g], bary[g])
        d = np.empty(n - 1)
        for k in range(n - 1):
            a = x[k + 1, 0] - x[k, 0]
            b = x[k + 1, 1] - x[k, 1]
            c = x[k + 1, 2] - x[k, 2]
            d[k] = np.sqrt(a * a + b * b + c * c)
        srt = np.sort(d)
        h = srt.size // 2
        med = srt[h] if srt.size % 2 else (srt[h - 1] + srt[h]) / 2.0
        for k in range(1, n - 1):
            if min(d[k - 1], d[k]) < ratio * med:
                out[m, 0] = side
                out[m, 1] = k
                m += 1
    return out[:m]


@njit(cache=True, nogil=True, fastmath=False)
def red_black_mean(uv, ii, jj, sweeps):
    """``sweeps`` red-black Gauss-Seidel sweeps on the grid parameters ``uv (nu, nv, 2) f8``
    (in place): each listed point ``(ii[k], jj[k])`` (interior) takes the mean of its four
    neighbours, the points with even ``i + j`` first, then the odd ones. Kernel of
    `meshfit.springs.relax.unfold_in_map`."""
    for _ in range(sweeps):
        for colour in range(2):
            for k in range(ii.shape[0]):
                i = ii[k]
                j = jj[k]
                if (i + j) % 2 != colour:
                    continue
                for c in range(2):
                    uv[i, j, c] = 0.25 * (
                        uv[i - 1, j, c] + uv[i + 1, j, c] + uv[i, j - 1, c] + uv[i, j + 1, c]
                    )


@njit(cache=True, nogil=True, fastmath=False)
def line_spacing(V, F, face, bary, nu, nv, ends_u, ends_v):
    """The largest arc-length coefficient of variation along each grid column ``(nv,)``
    and row ``(nu,)`` over its sections, and the median cell aspect ratio, of the grid of
    face points (face (nu nv,) i8, bary (nu nv, 3) f8, row-major; `grid_spacing`'s
    figures). Kernel of `meshfit.springs.resample._shape`."""
    X = grid_xyz(V, F, face, bary).reshape((nu, nv, 3))
    cv, aspect = grid_spacing(X, ends_u, ends_v)
    col = np.full(nv, -np.inf)
    row = np.full(nu, -np.inf)
    nsu = ends_u.shape[0] - 1
    for s in range(nsu):
        for j in range(nv):
            col[j] = max(col[j], cv[s * nv + j])
    at = nsu * nv
    for s in range(ends_v.shape[0] - 1):
        for i in range(nu):
            row[i] = max(row[i], cv[at + s * nu + i])
    return col, row, np.median(aspect)


@inner
def _point_normals(V, F, face):
    """Unit normal of each grid point's face: ``(n, 3)`` float64."""
    N = np.empty((face.shape[0], 3))
    nrm = np.empty(3)
    for i in range(face.shape[0]):
        _face_normal(V, F, face[i], nrm)
        for c in range(3):
            N[i, c] = nrm[c]
    return N


@inner
def _tri_facing(X, N, p, q, r):
    """Dot product of triangle (p, q, r)'s normal ``(q - p) x (r - p)`` with the summed
    normals at its corners, and the product of the two vectors' lengths."""
    cx, cy, cz = _cross(X, p, q, r)
    sx = N[p, 0] + N[q, 0] + N[r, 0]
    sy = N[p, 1] + N[q, 1] + N[r, 1]
    sz = N[p, 2] + N[q, 2] + N[r, 2]
    dot = cx * sx + cy * sy + cz * sz
    return dot, np.sqrt((cx * cx + cy * cy + cz * cz) * (sx * sx + sy * sy + sz * sz))


@inner
def _tri_bad(X, N, p, q, r):
    """1 if triangle (p, q, r) faces against the summed normals at its corners, else 0."""
    return 1 if _tri_facing(X, N, p, q, r)[0] <= 0.0 else 0


@inner
def _bad_around(X, N, nu, nv, p):
    """Folded triangles (the `folded_cells` test) in the up to four cells around point p."""
    i = p // nv
    j = p % nv
    bad = 0
    for ci in range(i - 1, i + 1):
        for cj in range(j - 1, j + 1):
            if ci < 0 or cj < 0 or ci >= nu - 1 or cj >= nv - 1:
                continue
            a = ci * nv + cj
            b = (ci + 1) * nv + cj
            c = (ci + 1) * nv + cj + 1
            d = ci * nv + cj + 1
            bad += _tri_bad(X, N, a, b, c) + _tri_bad(X, N, a, c, d)
    return bad


@njit(cache=True, nogil=True, fastmath=False)
def relax_sweeps(
    V,
    F,
    FN,
    face,
    bary,
    nu,
    nv,
    movable,
    tangent,
    guard,
    alpha,
    prev,
    n_sweeps,
    it0,
    ramp,
    w_fair_end,
    omega,
    eps_rel,
    bary_eps,
    max_faces,
    lazy,
    fold,
):
    """Gauss-Seidel relaxation sweeps of the free spring points, in place.

    V (nv, 3) f8; F, FN (nf, 3) i8; face (n,) i8 and bary (n, 3) f8 (updated in place);
    movable (n,) bool; tangent bool (spring vectors turned into the tangent plane, see
    `spring_force`); guard bool (a move that folds more triangles of the point's four cells
    than it starts with is halved, up to three times, then dropped); alpha (n,) f8 per-point
    step factors and prev (n, 3) f8 previous moves
    (both updated in place: a point whose step turns back halves its factor, otherwise the
    factor grows back towards 1, so points that overshoot on curved parts settle). The
    fairness weight ramps linearly from 0 at sweep 0 to ``w_fair_end`` at sweep ``ramp``
    (eq. 5.4: arc length first, fairness later); sweep ``k`` of this call is sweep ``it0 + k``
    of the schedule. Stops early, once the ramp is over, when the root-mean-square move of the
    free points is below ``eps_rel`` times their mean spring lengths. With ``lazy > 0`` a
    sweep after the first moves only the points that moved, or had one of their four
    neighbours move, more than ``lazy`` times their mean spring length in the sweep before
    (or earlier in the same sweep); the others count as not moving. With ``fold`` a spring
    vector across a fold follows its grid line (see `spring_force`). Returns (sweeps done,
    largest and root-mean-square relative move of the last sweep). Kernel of
    `meshfit.springs.relax.relax`.
    """
    n = face.shape[0]
    X = grid_xyz(V, F, face, bary)
    N = _point_normals(V, F, face)
    nrm = np.zeros(3)
    nrm2 = np.zeros(3)
    step = np.empty(3)
    u = np.empty(3)
    s0 = np.empty(3)
    s1 = np.empty(3)
    sb = np.empty(3)
    sx = np.empty(3)
    sn = np.empty(3)
    kx = np.empty(3)
    kn = np.empty(3)
    worst = 0.0
    done = 0
    active = np.ones(n, dtype=np.bool_)
    nxt = np.zeros(n, dtype=np.bool_)
    for k in range(n_sweeps):
        if lazy > 0.0:
            nxt[:] = False
        it = it0 + k
        t = min(1.0, it / ramp) if ramp > 0 else 1.0
        w_fair = w_fair_end * t
        w_arc = 1.0 - w_fair
        worst = 0.0
        sq = 0.0
        count = 0
        forward = it % 2 == 0
        for q in range(n):
            p = q if forward else n - 1 - q
            if not movable[p]:
                continue
            if lazy > 0.0 and not active[p]:
                count += 1  # settled: counted as a zero move
                continue
            # N[p] is the unit normal of face[p] (kept with every move): no recomputation
            for c in range(3):
                nrm[c] = N[p, c]
            step[0], step[1], step[2], h = spring_force(
                X, N, nv, p, w_arc, w_fair, nrm[0], nrm[1], nrm[2], tangent, fold
            )
            total = _in_plane(nrm[0], nrm[1], nrm[2], step, u)
            if total <= 0.0:
                continue
            turn = u[0] * prev[p, 0] + u[1] * prev[p, 1] + u[2] * prev[p, 2]
            if turn < 0.0:  # the move turns back (e.g. across a crease): damp this point
                alpha[p] *= 0.5
            else:
                alpha[p] = min(1.0, alpha[p] * 1.25)
            total *= omega * alpha[p]
            # the folds around p before the move: counted only when a move folds some
            # (a move that folds none cannot fold more), from the saved position
            before = -1
            f0 = face[p]
            for c in range(3):
                sb[c] = bary[p, c]
                sx[c] = X[p, c]
                sn[c] = N[p, c]
            moved = 0.0
            f = f0
            for attempt in range(4):
                if attempt > 0:  # undo, and try half the step
                    for c in range(3):
                        bary[p, c] = sb[c]
                        X[p, c] = sx[c]
                        N[p, c] = sn[c]
                    face[p] = f0
                    total = (
                        0.5
                        * _in_plane(sn[0], sn[1], sn[2], step, u)
                        * omega
                        * alpha[p]
                        / (2.0 ** (attempt - 1))
                    )
                ok, n0, n1, n2 = _move_in_face(
                    V,
                    F,
                    f0,
                    bary[p, 0],
                    bary[p, 1],
                    bary[p, 2],
                    u[0],
                    u[1],
                    u[2],
                    total,
                    bary_eps,
                )
                if ok:
                    bary[p, 0] = n0
                    bary[p, 1] = n1
                    bary[p, 2] = n2
                    f, moved = f0, total
                else:
                    f, moved = walk_inside(
                        V, F, FN, f0, bary[p], u, total, max_faces, bary_eps, 6, s0, s1
                    )
                if moved == 0.0 and _on_boundary_edge(FN, f, bary[p], bary_eps):
                    # stuck on the boundary (every walk leaves the patch at once): step off
                    # it toward the face's centre so that later sweeps can move it inward
                    for c in range(3):
                        bary[p, c] = (1.0 - NUDGE) * bary[p, c] + NUDGE / 3.0
                face[p] = f
                for c in range(3):
                    X[p, c] = (
                        bary[p, 0] * V[F[f, 0], c]
                        + bary[p, 1] * V[F[f, 1], c]
                        + bary[p, 2] * V[F[f, 2], c]
                    )
                if f != f0:
                    _face_normal(V, F, f, nrm2)
                    for c in range(3):
                        N[p, c] = nrm2[c]
                if not guard:
                    break
                after = _bad_around(X, N, nu, nv, p)
                if after > 0 and before < 0:
                    for c in range(3):
                        kx[c] = X[p, c]
                        kn[c] = N[p, c]
                        X[p, c] = sx[c]
                        N[p, c] = sn[c]
                    before = _bad_around(X, N, nu, nv, p)
                    for c in range(3):
                        X[p, c] = kx[c]
                        N[p, c] = kn[c]
                if after <= max(before, 0):
                    break
                if attempt == 3:  # every try folds a cell: stay
                    for c in range(3):
                        bary[p, c] = sb[c]
                        X[p, c] = sx[c]
                        N[p, c] = sn[c]
                    face[p] = f0
                    f = f0
                    moved = 0.0
            if h > 0.0:
                worst = max(worst, moved / h)
                sq += (moved / h) ** 2
            count += 1
            for c in range(3):
                prev[p, c] = X[p, c] - sx[c]
            if lazy > 0.0 and h > 0.0 and moved > lazy * h:
                for r in (p, p - 1, p + 1, p - nv, p + nv):
                    if 0 <= r < n:
                        nxt[r] = True
                        active[r] = True
        if lazy > 0.0:
            active, nxt = nxt, active
        done = k + 1
        rms = np.sqrt(sq / max(count, 1))
        if it + 1 >= ramp and rms < eps_rel:
            break
    return done, worst, rms


@inner
def _fold_score(X, N, nu, nv, p, margin):
    """Folded triangles of the up to four cells around point p (the `_bad_around` count) and
    their shortfall: the sum over those triangles of ``max(0, margin - cos)``, ``cos`` the
    cosine between a triangle's normal and the summed normals at its corners."""
    i = p // nv
    j = p % nv
    bad = 0
    short = 0.0
    for ci in range(i - 1, i + 1):
        for cj in range(j - 1, j + 1):
            if ci < 0 or cj < 0 or ci >= nu - 1 or cj >= nv - 1:
                continue
            a = ci * nv + cj
            b = (ci + 1) * nv + cj
            c = (ci + 1) * nv + cj + 1
            d = ci * nv + cj + 1
            for t in range(2):
                q = b if t == 0 else c
                r = c if t == 0 else d
                dot, den = _tri_facing(X, N, a, q, r)
                if dot <= 0.0:
                    bad += 1
                cos = dot / den if den > 0.0 else -1.0
                if cos < margin:
                    short += margin - cos
    return bad, short


@njit(cache=True, nogil=True, fastmath=False)
def repair_folds(
    V, F, FN, face, bary, nu, nv, movable, rounds, n_dirs, margin, bary_eps, max_faces
):
    """Move movable points of folded cells to the best of a set of trial places, in place.

    V (nv, 3) f8; F, FN (nf, 3) i8; face (n,) i8 and bary (n, 3) f8 (updated in place);
    movable (n,) bool. Each round visits every movable corner of a folded cell (the
    `folded_cells` test) and tries, each walked on the surface from where it stands: the
    centroid of its four neighbours (and half the way there), and ``n_dirs`` directions in
    its tangent plane at 0.15, 0.35 and 0.7 of its mean spring length. It keeps the trial
    with the fewest folded triangles in its four cells, then the smallest shortfall of the
    triangles' normals from the corners' normals (cosines below ``margin``, see
    `_fold_score`), then the shortest move, and only if it beats staying. The grid's fold
    count never grows. Up to ``rounds`` rounds, until no cell is folded. Returns the folded
    triangles left around the movable points. Kernel of `meshfit.springs.relax.repair_folds`.
    """
    n = face.shape[0]
    X = grid_xyz(V, F, face, bary)
    N = _point_normals(V, F, face)
    nrm = np.empty(3)
    step = np.empty(3)
    u = np.empty(3)
    s0 = np.empty(3)
    s1 = np.empty(3)
    sb = np.empty(3)
    sx = np.empty(3)
    sn = np.empty(3)
    bb = np.empty(3)
    e1 = np.empty(3)
    e2 = np.empty(3)
    scales = (0.15, 0.35, 0.7)
    left = 0
    for _r in range(rounds):
        left = 0
        changed = False
        for p in range(n):
            if not movable[p]:
                continue
            bad0, short0 = _fold_score(X, N, nu, nv, p, margin)
            if bad0 == 0:
                continue
            f0 = face[p]
            for c in range(3):
                sb[c] = bary[p, c]
                sx[c] = X[p, c]
                sn[c] = N[p, c]
            # mean spring length and a tangent frame
            h = 0.0
            for q in (p - nv, p + nv, p - 1, p + 1):
                h += 0.25 * np.sqrt(
                    (X[q, 0] - sx[0]) ** 2 + (X[q, 1] - sx[1]) ** 2 + (X[q, 2] - sx[2]) ** 2
                )
            _face_normal(V, F, f0, nrm)
            for c in range(3):
                e1[c] = X[p + nv, c] - X[p - nv, c]
            dn = e1[0] * nrm[0] + e1[1] * nrm[1] + e1[2] * nrm[2]
            for c in range(3):
                e1[c] -= dn * nrm[c]
            ln = np.sqrt(e1[0] ** 2 + e1[1] ** 2 + e1[2] ** 2)
            if ln <= 0.0 or h <= 0.0:
                continue
            for c in range(3):
                e1[c] /= ln
            e2[0] = nrm[1] * e1[2] - nrm[2] * e1[1]
            e2[1] = nrm[2] * e1[0] - nrm[0] * e1[2]
            e2[2] = nrm[0] * e1[1] - nrm[1] * e1[0]
            best_bad, best_short, best_len = bad0, short0, 0.0
            best_f = f0
            for c in range(3):
                bb[c] = sb[c]
            n_trials = 2 + n_dirs * 3
            for k in range(n_trials):
                if k < 2:  # toward the centroid of the neighbours, all or half the way
                    w = 0.25 if k == 0 else 0.125
                    for c in range(3):
                        step[c] = w * (
                            X[p - nv, c] + X[p + nv, c] + X[p - 1, c] + X[p + 1, c] - 4.0 * sx[c]
                        )
                else:
                    d = (k - 2) % n_dirs
                    ang = 2.0 * np.pi * d / n_dirs
                    r = scales[(k - 2) // n_dirs] * h
                    for c in range(3):
                        step[c] = r * (np.cos(ang) * e1[c] + np.sin(ang) * e2[c])
                total = _start_direction(V, F, f0, step, u)
                if total <= 0.0:
                    continue
                for c in range(3):
                    bary[p, c] = sb[c]
                f, moved = walk_inside(
                    V, F, FN, f0, bary[p], u, total, max_faces, bary_eps, 2, s0, s1
                )
                if moved == 0.0:
                    continue
                for c in range(3):
                    X[p, c] = (
                        bary[p, 0] * V[F[f, 0], c]
                        + bary[p, 1] * V[F[f, 1], c]
                        + bary[p, 2] * V[F[f, 2], c]
                    )
                _face_normal(V, F, f, nrm)
                for c in range(3):
                    N[p, c] = nrm[c]
                bad, short = _fold_score(X, N, nu, nv, p, margin)
                if bad < best_bad or (
                    bad == best_bad
                    and (short < best_short - 1e-12 or (short <= best_short and moved < best_len))
                ):
                    best_bad, best_short, best_len = bad, short, moved
                    best_f = f
                    for c in range(3):
                        bb[c] = bary[p, c]
            face[p] = best_f
            for c in range(3):
                bary[p, c] = bb[c]
            for c in range(3):
                X[p, c] = (
                    bb[0] * V[F[best_f, 0], c]
                    + bb[1] * V[F[best_f, 1], c]
                    + bb[2] * V[F[best_f, 2], c]
                )
            _face_normal(V, F, best_f, nrm)
            for c in range(3):
                N[p, c] = nrm[c]
            if best_f != f0 or best_len > 0.0:
                changed = True
            left += best_bad
        if left == 0 or not changed:
            break
    return left


@inner
def _on_boundary_edge(FN, f, b, eps):
    """Whether face point (f, b) lies on a boundary edge of its face."""
    for k in range(3):
        if FN[f, k] < 0 and b[(k + 2) % 3] <= eps:
            return True
    return False


@inner
def _greedy_mid(V, indptr, indices, v1, v2, max_steps, path):
    """Mid vertex (by length) of a greedy graph path v1 -> v2, or -1 if the descent sticks;
    ``path`` (max_steps + 1,) i8 is scratch."""
    if v1 == v2:
        return v1
    path[0] = v1
    cur = v1
    m = 1
    while cur != v2:
        if m > max_steps:
            return -1
        best = -1
        dx = V[cur, 0] - V[v2, 0]
        dy = V[cur, 1] - V[v2, 1]
        dz = V[cur, 2] - V[v2, 2]
        bd = dx * dx + dy * dy + dz * dz
        for e in range(indptr[cur], indptr[cur + 1]):
            w = indices[e]
            dx = V[w, 0] - V[v2, 0]
            dy = V[w, 1] - V[v2, 1]
            dz = V[w, 2] - V[v2, 2]
            d = dx * dx + dy * dy + dz * dz
            if d < bd:
                bd = d
                best = w
        if best < 0:
            return -1
        path[m] = best
        m += 1
        cur = best
    total = 0.0
    for k in range(1, m):
        a = path[k - 1]
        b = path[k]
        total += np.sqrt(
            (V[a, 0] - V[b, 0]) ** 2 + (V[a, 1] - V[b, 1]) ** 2 + (V[a, 2] - V[b, 2]) ** 2
        )
    acc = 0.0
    for k in range(1, m):
        a = path[k - 1]
        b = path[k]
        el = np.sqrt((V[a, 0] - V[b, 0]) ** 2 + (V[a, 1] - V[b, 1]) ** 2 + (V[a, 2] - V[b, 2]) ** 2)
        if acc + el >= 0.5 * total:
            return a if 0.5 * total - acc < acc + el - 0.5 * total else b
        acc += el
    return path[m - 1]


@njit(cache=True, nogil=True, fastmath=False)
def find_midpoints(
    V,
    F,
    FN,
    VFp,
    VF,
    indptr,
    indices,
    on_boundary,
    fa,
    ba,
    fb,
    bb,
    n_fair,
    max_steps,
    bary_eps,
    max_faces,
):
    """FindMidPoint (sec. 5.6) for n pairs of face points; fa, fb (n,) i8, ba, bb (n, 3) f8.

    The mid vertex of a greedy graph path between the pair's nearest vertices is the first
    guess (half a chord walked from the first point, or the second when the first is on the
    boundary, if the descent sticks or the vertex is on the boundary, ``on_boundary (nv,)
    bool``); ``n_fair``
    local fairness moves (Force(P1, Pmid) + Force(P2, Pmid), walked on the surface) follow.
    Returns face (n,) i8, bary (n, 3) f8. Kernel of `meshfit.springs.subdivide`.
    """
    n = fa.shape[0]
    out_f = np.empty(n, dtype=np.int64)
    out_b = np.empty((n, 3))
    u = np.empty(3)
    step = np.empty(3)
    xa = np.empty(3)
    xb = np.empty(3)
    s0 = np.empty(3)
    s1 = np.empty(3)
    path = np.empty(max_steps + 1, dtype=np.int64)
    for i in range(n):
        for c in range(3):
            xa[c] = (
                ba[i, 0] * V[F[fa[i], 0], c]
                + ba[i, 1] * V[F[fa[i], 1], c]
                + ba[i, 2] * V[F[fa[i], 2], c]
            )
            xb[c] = (
                bb[i, 0] * V[F[fb[i], 0], c]
                + bb[i, 1] * V[F[fb[i], 1], c]
                + bb[i, 2] * V[F[fb[i], 2], c]
            )
        v1 = F[fa[i], np.argmax(ba[i])]
        v2 = F[fb[i], np.argmax(bb[i])]
        mid = _greedy_mid(V, indptr, indices, v1, v2, max_steps, path)
        b = out_b[i]
        if mid >= 0 and mid != v1 and mid != v2 and not on_boundary[mid]:
            # the vertex as a point of the face around it nearest the chord's mid-point, so
            # the fairness moves start into the right face
            f = VF[VFp[mid]]
            best = np.inf
            for e in range(VFp[mid], VFp[mid + 1]):
                g = VF[e]
                d = 0.0
                for c in range(3):
                    m = (V[F[g, 0], c] + V[F[g, 1], c] + V[F[g, 2], c]) / 3.0
                    d += (m - 0.5 * (xa[c] + xb[c])) ** 2
                if d < best:
                    best = d
                    f = g
            for c in range(3):
                b[c] = 1.0 if F[f, c] == mid else 0.0
        else:
            # walk half the chord from the pair's first point, or from the second when the
            # first lies on the boundary (a walk from there may leave at once)
            first = not _on_boundary_edge(FN, fa[i], ba[i], bary_eps)
            f = fa[i] if first else fb[i]
            for c in range(3):
                b[c] = ba[i, c] if first else bb[i, c]
            for c in range(3):
                step[c] = 0.5 * (xb[c] - xa[c]) if first else 0.5 * (xa[c] - xb[c])
            total = _start_direction(V, F, f, step, u)
            if total > 0.0:
                f, _m = walk_inside(V, F, FN, f, b, u, total, max_faces, bary_eps, 6, s0, s1)
        for _k in range(n_fair):
            for c in range(3):
                x = b[0] * V[F[f, 0], c] + b[1] * V[F[f, 1], c] + b[2] * V[F[f, 2], c]
                step[c] = 0.5 * (xa[c] + xb[c]) - x
            total = _start_direction(V, F, f, step, u)
            if total <= 0.0:
                break
            f, _m = walk_inside(V, F, FN, f, b, u, total, max_faces, bary_eps, 6, s0, s1)
        out_f[i] = f
    return out_f, out_b


@njit(cache=True, nogil=True, fastmath=False)
def folded_cells(V, F, face, bary, nu, nv):
    """Cells of an (nu, nv) grid of face points with a triangle whose normal points against
    the summed face normals at its corners; -> (nu - 1, nv - 1) bool. Kernel of
    `meshfit.springs.relax.folded_cells` (the test of `meshfit.springs.grid_metrics`)."""
    return _folded_grid(grid_xyz(V, F, face, bary), _point_normals(V, F, face), nu, nv)


@inner
def _folded_grid(X, N, nu, nv):
    """`folded_cells` of the grid points ``X`` (nu nv, 3) with unit normals ``N``."""
    out = np.zeros((nu - 1, nv - 1), dtype=np.bool_)
    for i in range(nu - 1):
        for j in range(nv - 1):
            a = i * nv + j
            b = (i + 1) * nv + j
            c = (i + 1) * nv + j + 1
            d = i * nv + j + 1
            if _tri_bad(X, N, a, b, c) or _tri_bad(X, N, a, c, d):
                out[i, j] = True
    return out


@inner
def _shortest_grid_edge(X, rows, cols):
    """Shortest chord between neighbouring points of a (rows, cols) row-major grid ``X``."""
    best = np.inf
    for i in range(rows):
        for j in range(cols):
            p = i * cols + j
            for q in (p + cols if i + 1 < rows else -1, p + 1 if j + 1 < cols else -1):
                if q < 0:
                    continue
                dx = X[q, 0] - X[p, 0]
                dy = X[q, 1] - X[p, 1]
                dz = X[q, 2] - X[p, 2]
                best = min(best, np.sqrt(dx * dx + dy * dy + dz * dz))
    return best


@njit(cache=True, nogil=True, fastmath=False)
def window_trials(V, F, face, bary, rows, cols, at, t_face, t_bary):
    """Folded cells and shortest chord of a (rows, cols) window of grid face points as it
    is and with the points at window places ``at`` (m,) i8 put at each trial's face points
    (t_face (T, m) i8, t_bary (T, m, 3) f8).

    face (rows cols,) i8 and bary (rows cols, 3) f8 are the window's points, row-major.
    Returns (folds (T + 1,) i8, shortest (T + 1,) f8), entry 0 for the window as it is and
    entry ``t + 1`` for trial ``t``: the `folded_cells` count and the shortest chord between
    neighbouring points. Kernel of the side-point slides of `meshfit.springs.relax`
    (`slide_side_points`, `unpinch_side_points`)."""
    T = t_face.shape[0]
    folds = np.zeros(T + 1, dtype=np.int64)
    short = np.empty(T + 1)
    f = face.copy()
    b = bary.copy()
    for t in range(T + 1):
        if t > 0:
            for m in range(at.shape[0]):
                f[at[m]] = t_face[t - 1, m]
                for c in range(3):
                    b[at[m], c] = t_bary[t - 1, m, c]
        X = grid_xyz(V, F, f, b)
        folds[t] = _folded_grid(X, _point_normals(V, F, f), rows, cols).sum()
        short[t] = _shortest_grid_edge(X, rows, cols)
    return folds, short


# ------------------------------------------------------------ point location in a planar map


@njit(cache=True, nogil=True, fastmath=False)
def uv_buckets(uv, F, g):
    """Faces of a planar triangulation in the unit square sorted into a ``g`` x ``g`` grid of
    buckets by their bounding boxes (faces of zero area are left out).

    Returns (start (g * g + 1,) int64, items (k,) int64): bucket ``c`` holds
    ``items[start[c]:start[c + 1]]``.
    """
    nf = F.shape[0]
    lo = np.empty((nf, 2), dtype=np.int64)
    hi = np.empty((nf, 2), dtype=np.int64)
    count = np.zeros(g * g + 1, dtype=np.int64)
    for f in range(nf):
        a, b, c = F[f, 0], F[f, 1], F[f, 2]
        area = (uv[b, 0] - uv[a, 0]) * (uv[c, 1] - uv[a, 1]) - (uv[b, 1] - uv[a, 1]) * (
            uv[c, 0] - uv[a, 0]
        )
        if area == 0.0:
            lo[f, 0] = 1
            hi[f, 0] = 0
            continue
        for d in range(2):
            mn = min(uv[a, d], min(uv[b, d], uv[c, d]))
            mx = max(uv[a, d], max(uv[b, d], uv[c, d]))
            lo[f, d] = min(g - 1, max(0, int(np.floor(mn * g))))
            hi[f, d] = min(g - 1, max(0, int(np.floor(mx * g))))
        for i in range(lo[f, 0], hi[f, 0] + 1):
            for j in range(lo[f, 1], hi[f, 1] + 1):
                count[i * g + j + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    items = np.empty(start[-1], dtype=np.int64)
    for f in range(nf):
        for i in range(lo[f, 0], hi[f, 0] + 1):
            for j in range(lo[f, 1], hi[f, 1] + 1):
                items[fill[i * g + j]] = f
                fill[i * g + j] += 1
    return start, items


@njit(cache=True, nogil=True, fastmath=False)
def locate_uv(uv, F, start, items, g, q):
    """Face and barycentrics of each query point ``q`` (m, 2) in the unit square: the face of
    its bucket in which it is most inside (its smallest barycentric largest); barycentrics
    clamped to >= 0 and renormalised.

    Returns (face (m,) int64, bary (m, 3) float64); face -1 where the bucket is empty.
    """
    m = q.shape[0]
    face = np.full(m, -1, dtype=np.int64)
    bary = np.zeros((m, 3))
    for k in range(m):
        x = min(1.0, max(0.0, q[k, 0]))
        y = min(1.0, max(0.0, q[k, 1]))
        cell = min(g - 1, int(x * g)) * g + min(g - 1, int(y * g))
        best = -np.inf
        for t in range(start[cell], start[cell + 1]):
            f = items[t]
            a, b, c = F[f, 0], F[f, 1], F[f, 2]
            d1x, d1y = uv[b, 0] - uv[a, 0], uv[b, 1] - uv[a, 1]
            d2x, d2y = uv[c, 0] - uv[a, 0], uv[c, 1] - uv[a, 1]
            dqx, dqy = x - uv[a, 0], y - uv[a, 1]
            den = d1x * d2y - d1y * d2x
            s = (dqx * d2y - dqy * d2x) / den
            r = (d1x * dqy - d1y * dqx) / den
            w = min(1.0 - s - r, min(s, r))
            if w > best:
                best = w
                face[k] = f
                bary[k, 0] = 1.0 - s - r
                bary[k, 1] = s
                bary[k, 2] = r
            if w >= 0.0:
                break
        tot = 0.0
        for i in range(3):
            bary[k, i] = max(bary[k, i], 0.0)
            tot += bary[k, i]
        if tot > 0.0:
            for i in range(3):
                bary[k, i] /= tot
    return face, bary


@njit(cache=True, nogil=True, fastmath=False)
def chord_rounds(xyz, arc, pos, fixed, rounds):
    """Jacobi rounds evening out the chords between consecutive positions along a polyline,
    in place. Kernel of `meshfit.springs.state.chord_positions`.

    xyz (k, 3) f8 polyline points at cumulative lengths arc (k,) f8; pos (n,) f8 arc-length
    positions, increasing; fixed (n,) bool positions that stay (section ends); rounds int.
    Each round moves every free position towards its longer neighbouring chord by a quarter
    of the chord difference (in arc length), clipped between its neighbours' old positions.
    """
    n = pos.shape[0]
    k = arc.shape[0]
    last = k - 2
    P = np.empty((n, 3))
    c = np.empty(max(n - 1, 0))
    old = np.empty(n)
    for _ in range(rounds):
        for i in range(n):
            old[i] = pos[i]
            # the segment holding pos[i]: searchsorted(arc, pos, side="right") - 1, clipped
            lo, hi = 0, k
            while lo < hi:
                mid = (lo + hi) // 2
                if arc[mid] <= pos[i]:
                    lo = mid + 1
                else:
                    hi = mid
            e = min(max(lo - 1, 0), last)
            seg = arc[e + 1] - arc[e]
            t = (pos[i] - arc[e]) / seg if seg > 0 else 0.0
            for d in range(3):
                P[i, d] = xyz[e, d] + t * (xyz[e + 1, d] - xyz[e, d])
        for i in range(n - 1):
            dx = P[i + 1, 0] - P[i, 0]
            dy = P[i + 1, 1] - P[i, 1]
            dz = P[i + 1, 2] - P[i, 2]
            c[i] = np.sqrt(dx * dx + dy * dy + dz * dz)
        for i in range(1, n - 1):
            if fixed[i]:
                continue
            ca, cb = c[i - 1], c[i]
            span = old[i + 1] - old[i - 1]
            step = 0.5 * (cb - ca) * span / max(ca + cb, 1e-300)
            pos[i] = min(max(old[i] + 0.5 * step, old[i - 1]), old[i + 1])


# ------------------------------------------------- untangling in a tangent-plane chart


@inner
def _lowest(A, m, x, y):
    """min over the first ``m`` rows of ``A[k, 0] x + A[k, 1] y + A[k, 2]``."""
    out = np.inf
    for k in range(m):
        v = A[k, 0] * x + A[k, 1] * y + A[k, 2]
        if v < out:
            out = v
    return out


@njit(cache=True, nogil=True, fastmath=False)
def maxmin_point(A, m, px, py, h):
    """The point of the box ``|x - px| <= h``, ``|y - py| <= h`` that maximizes the least of
    the ``m`` affine functions ``A[k, 0] x + A[k, 1] y + A[k, 2]``, and that least value;
    -> (x, y, s). Exact: the optimum of this linear program in (x, y, s) is a vertex, where
    three functions are equal, two are equal on an edge of the box, or at a box corner; every
    such candidate is evaluated (m is a handful). The start ``(px, py)`` is kept unless a
    candidate is strictly better."""
    bx, by = px, py
    best = _lowest(A, m, px, py)
    xs = (px - h, px + h)
    ys = (py - h, py + h)
    for ci in range(2):  # box corners
        for cj in range(2):
            v = _lowest(A, m, xs[ci], ys[cj])
            if v > best:
                best, bx, by = v, xs[ci], ys[cj]
    for i in range(m):
        for j in range(i + 1, m):
            da, db, dc = A[i, 0] - A[j, 0], A[i, 1] - A[j, 1], A[i, 2] - A[j, 2]
            for e in range(2):  # the two functions equal on an edge of the box
                if db != 0.0:  # vertical edge x = xs[e]
                    y = -(da * xs[e] + dc) / db
                    if ys[0] <= y <= ys[1]:
                        v = _lowest(A, m, xs[e], y)
                        if v > best:
                            best, bx, by = v, xs[e], y
                if da != 0.0:  # horizontal edge y = ys[e]
                    x = -(db * ys[e] + dc) / da
                    if xs[0] <= x <= xs[1]:
                        v = _lowest(A, m, x, ys[e])
                        if v > best:
                            best, bx, by = v, x, ys[e]
            for k in range(j + 1, m):  # three functions equal
                ea, eb, ec = A[i, 0] - A[k, 0], A[i, 1] - A[k, 1], A[i, 2] - A[k, 2]
                det = da * eb - db * ea
                if det == 0.0:
                    continue
                x = (-dc * eb + db * ec) / det
                y = (-da * ec + dc * ea) / det
                if xs[0] <= x <= xs[1] and ys[0] <= y <= ys[1]:
                    v = _lowest(A, m, x, y)
                    if v > best:
                        best, bx, by = v, x, y
    return bx, by, best


@inner
def _cell_tri(i, j, t, nv):
    """Grid rows of triangle ``t`` (0: a b c, 1: a c d) of cell (i, j), as the fold test
    splits it: a = (i, j), b = (i + 1, j), c = (i + 1, j + 1), d = (i, j + 1)."""
    a = i * nv + j
    c = (i + 1) * nv + j + 1
    if t == 0:
        return a, (i + 1) * nv + j, c
    return a, c, i * nv + j + 1


@inner
def _twice_area(Y, p, q, r):
    return (Y[q, 0] - Y[p, 0]) * (Y[r, 1] - Y[p, 1]) - (Y[q, 1] - Y[p, 1]) * (Y[r, 0] - Y[p, 0])


@njit(cache=True, nogil=True, fastmath=False)
def chart_least_area(Y, nu, nv, var):
    """Least twice-signed area of the fold-test triangles of the cells of an (nu, nv) chart
    grid ``Y`` (nu * nv, 2) that have a corner in ``var``."""
    out = np.inf
    for i in range(nu - 1):
        for j in range(nv - 1):
            if not (
                var[i * nv + j] or var[(i + 1) * nv + j] or var[i * nv + j + 1]
                or var[(i + 1) * nv + j + 1]
            ):  # fmt: skip
                continue
            for t in range(2):
                p, q, r = _cell_tri(i, j, t, nv)
                v = _twice_area(Y, p, q, r)
                if v < out:
                    out = v
    return out


@njit(cache=True, nogil=True, fastmath=False)
def chart_untangle(Y, nu, nv, var, h, rounds, goal):
    """Gauss-Seidel rounds over the points ``var`` of an (nu, nv) grid ``Y`` (nu * nv, 2) in a
    plane, in place: each point goes to the place within ``h`` of it (per coordinate) that
    maximizes the least signed area of the fold-test triangles it is a corner of
    (`maxmin_point`). Stops after ``rounds`` rounds or once every triangle of the cells
    touching ``var`` has twice its signed area at least ``goal``; -> (rounds done, that least
    twice-area)."""
    A = np.empty((8, 3))
    done = 0
    worst = chart_least_area(Y, nu, nv, var)
    while done < rounds and worst < goal:
        for p in range(nu * nv):
            if not var[p]:
                continue
            pi, pj = p // nv, p % nv
            m = 0
            for ci in range(pi - 1, pi + 1):
                for cj in range(pj - 1, pj + 1):
                    if ci < 0 or cj < 0 or ci >= nu - 1 or cj >= nv - 1:
                        continue
                    for t in range(2):
                        a, b, c = _cell_tri(ci, cj, t, nv)
                        if a == p:
                            q, r = b, c
                        elif b == p:
                            q, r = c, a
                        elif c == p:
                            q, r = a, b
                        else:
                            continue
                        # twice the area of (P, q, r), affine in P
                        A[m, 0] = Y[q, 1] - Y[r, 1]
                        A[m, 1] = Y[r, 0] - Y[q, 0]
                        A[m, 2] = Y[q, 0] * Y[r, 1] - Y[q, 1] * Y[r, 0]
                        m += 1
            if m == 0:
                continue
            x, y, _s = maxmin_point(A, m, Y[p, 0], Y[p, 1], h)
            Y[p, 0] = x
            Y[p, 1] = y
        done += 1
        worst = chart_least_area(Y, nu, nv, var)
    return done, worst
