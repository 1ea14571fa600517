"""Slow, obviously-correct oracles for `meshfit.surface.walk`.

The walker here is written independently of the kernel and with a different formulation:
each point's path is the positive x-axis of a 2-D chart. The start triangle is laid out in the
chart with the point at the origin and the (projected) step along +x; every edge crossing
unfolds the next triangle into the same chart by placing its far vertex from the two edge
lengths (intersection of two circles), so the path stays the straight line ``y = 0``. The
exit edge is found by clipping the line against the triangle; the end point's barycentrics
come from the chart coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints


@dataclass
class ReferenceWalk:
    end: SurfacePoints
    length: np.ndarray
    hit_boundary: np.ndarray
    capped: np.ndarray


def _chart_bary(q: np.ndarray, x: float) -> np.ndarray:
    """Barycentrics of the chart point (x, 0) in the chart triangle q (3, 2)."""
    t = np.array([[q[0, 0] - q[2, 0], q[1, 0] - q[2, 0]], [q[0, 1] - q[2, 1], q[1, 1] - q[2, 1]]])
    l01 = np.linalg.solve(t, np.array([x - q[2, 0], -q[2, 1]]))
    b = np.array([l01[0], l01[1], 1.0 - l01[0] - l01[1]])
    b = np.clip(b, 0.0, None)
    return b / b.sum()


def _line_exit(q: np.ndarray, skip: int) -> tuple[float, int]:
    """Largest x where the line y = 0 leaves chart triangle q, and through which edge.

    Edge k joins corners k and k + 1; edge ``skip`` (the one entered through) is ignored.
    """
    best_x, best_k = -np.inf, -1
    for k in range(3):
        if k == skip:
            continue
        (xa, ya), (xb, yb) = q[k], q[(k + 1) % 3]
        if ya == 0.0 and yb == 0.0:
            xk = max(xa, xb)
        elif (ya <= 0.0 <= yb) or (yb <= 0.0 <= ya):
            xk = xa + (xb - xa) * ya / (ya - yb)
        else:
            continue
        if xk > best_x:
            best_x, best_k = xk, k
    return best_x, best_k


def walk_one(
    mesh: Mesh, face: int, bary: np.ndarray, step: np.ndarray, max_faces: int = 10_000
) -> tuple[int, np.ndarray, float, bool, bool]:
    """Walk one face point; returns ``(face, bary, length, hit_boundary, capped)``."""
    V, F, FN = mesh.vertices, mesh.faces, mesh.face_neighbors
    tri = V[F[face]]
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    n /= np.linalg.norm(n)
    d = step - np.dot(step, n) * n
    total = float(np.linalg.norm(d))
    if total <= 1e-12 * mesh.mean_edge_length:
        return face, np.array(bary, dtype=float), 0.0, False, False
    ex = d / total
    ey = np.cross(n, ex)
    x0 = bary @ tri
    q = np.stack([(tri - x0) @ ex, (tri - x0) @ ey], axis=1)  # chart corners, point at 0
    ids = F[face].copy()  # global vertex of each chart corner
    f, skip, x = face, -1, 0.0
    for crossed in range(max_faces + 1):
        x_exit, k = _line_exit(q, skip)
        if k < 0 or x_exit >= total:
            return f, _chart_bary(q, total), total, False, False
        x = max(x, x_exit)
        g = FN[f, k]
        if g < 0:
            return f, _chart_bary(q, x), x, True, False
        if crossed == max_faces:
            return f, _chart_bary(q, x), x, False, True
        a, c = ids[k], ids[(k + 1) % 3]
        qa, qc = q[k], q[(k + 1) % 3]
        qo_old = q[(k + 2) % 3]
        o = next(v for v in F[g] if v != a and v != c)
        # place o from its distances to a and c, on the far side of edge (a, c)
        base = np.linalg.norm(qc - qa)
        ra = np.linalg.norm(V[o] - V[a])
        rc = np.linalg.norm(V[o] - V[c])
        along = (ra * ra - rc * rc + base * base) / (2.0 * base)
        height = np.sqrt(max(ra * ra - along * along, 0.0))
        t = (qc - qa) / base
        perp = np.array([-t[1], t[0]])
        if np.dot(qo_old - qa, perp) > 0:
            perp = -perp
        qo = qa + along * t + height * perp
        # chart corners in g's vertex order
        pos = {a: qa, c: qc, o: qo}
        ids = F[g].copy()
        q = np.stack([pos[v] for v in ids])
        skip = next(j for j in range(3) if {ids[j], ids[(j + 1) % 3]} == {a, c})
        f = g
    raise AssertionError("unreachable")


def walk_points(
    mesh: Mesh, start: SurfacePoints, step: np.ndarray, *, max_faces: int = 10_000
) -> ReferenceWalk:
    """Reference `walk_points`: one Python walk per point."""
    step = np.asarray(step, dtype=float).reshape(-1, 3)
    out = [
        walk_one(mesh, int(f), b, s, max_faces)
        for f, b, s in zip(start.face, start.bary, step, strict=True)
    ]
    face = np.array([o[0] for o in out], dtype=np.int64)
    bary = np.array([o[1] for o in out]).reshape(-1, 3)
    return ReferenceWalk(
        SurfacePoints(face, bary),
        np.array([o[2] for o in out]),
        np.array([o[3] for o in out], dtype=bool),
        np.array([o[4] for o in out], dtype=bool),
    )


def _closest_on_segments(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.einsum("ij,ij->i", ab, ab), 0.0, 1.0)
    return a + t[:, None] * ab


def closest_point_bruteforce(mesh: Mesh, target: np.ndarray) -> tuple[np.ndarray, float]:
    """Global closest surface point to ``target`` (3,) by checking every face.

    Per face: the foot of the perpendicular if it lies inside the triangle, else the
    closest point on its three edges. Returns ``(xyz (3,), distance)``.
    """
    tri = mesh.vertices[mesh.faces]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    foot = target - np.einsum("ij,ij->i", target - a, n)[:, None] * n
    inside = np.ones(len(a), dtype=bool)
    for p0, p1 in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(p1 - p0, foot - p0), n) >= 0.0
    cands = [np.where(inside[:, None], foot, np.inf)]
    for p0, p1 in ((a, b), (b, c), (c, a)):
        cands.append(_closest_on_segments(np.broadcast_to(target, a.shape), p0, p1))
    cands = np.stack(cands)  # (4, nf, 3)
    d = np.linalg.norm(cands - target, axis=2)
    j = np.unravel_index(np.argmin(d), d.shape)
    return cands[j], float(d[j])


def curve_segment(
    mesh: Mesh, p: tuple[int, np.ndarray], q: tuple[int, np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """The surface segment from face point p to face point q (same or edge-adjacent faces).

    The two triangles are laid out in a 2-D chart (the shared edge on the x-axis, p above it,
    q unfolded below it); the segment is the straight chart line when it crosses the shared
    edge, otherwise the two straight lines through the shared edge's nearer end.

    Returns ``(xp, xx, xq, straight)``: the 3-D start, the point where the segment meets the
    shared edge (``xq`` for a shared face), the end, and whether the chart line is straight.
    """
    V, F = mesh.vertices, mesh.faces
    fp, bp = p
    fq, bq = q
    xp = np.asarray(bp) @ V[F[fp]]
    xq = np.asarray(bq) @ V[F[fq]]
    if fp == fq:
        return xp, xq, xq, True
    shared = [v for v in F[fp] if v in F[fq]]
    assert len(shared) == 2, "faces are not edge-adjacent"
    a, c = V[shared[0]], V[shared[1]]
    el = np.linalg.norm(c - a)
    e = (c - a) / el

    def chart(x, side):
        r = x - a
        along = r @ e
        return np.array([along, side * np.linalg.norm(r - along * e)])

    cp, cq = chart(xp, 1.0), chart(xq, -1.0)
    if cp[1] - cq[1] > 0:
        cross = cp[0] + (cq[0] - cp[0]) * cp[1] / (cp[1] - cq[1])
    else:  # both on the edge line
        cross = cq[0]
    straight = 0.0 <= cross <= el
    xx = a + min(max(cross, 0.0), el) * e
    return xp, xx, xq, straight


def curve_point(
    mesh: Mesh, p: tuple[int, np.ndarray], q: tuple[int, np.ndarray], s: float
) -> np.ndarray:
    """xyz (3,) at arc length ``s`` along :func:`curve_segment` from p to q."""
    xp, xx, xq, _ = curve_segment(mesh, p, q)
    l1 = np.linalg.norm(xx - xp)
    l2 = np.linalg.norm(xq - xx)
    if s <= l1:
        return xp if l1 == 0 else xp + s / l1 * (xx - xp)
    return xx if l2 == 0 else xx + min(s - l1, l2) / l2 * (xq - xx)


def curve_length(mesh: Mesh, p: tuple[int, np.ndarray], q: tuple[int, np.ndarray]) -> float:
    """Length of :func:`curve_segment` from p to q."""
    xp, xx, xq, _ = curve_segment(mesh, p, q)
    return float(np.linalg.norm(xx - xp) + np.linalg.norm(xq - xx))
