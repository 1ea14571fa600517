"""Spring mesh initialisation: static boundary sampling and Dijkstra iso-curves (sec. 5.4)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse.csgraph import dijkstra

from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints

__all__ = ["chain_arc", "chain_points", "closest_approach", "project_on_chain"]


def chain_arc(mesh: Mesh, chain: NDArray[np.int64]) -> NDArray[np.float64]:
    """(k,) float64 cumulative length along a vertex chain, model units."""
    seg = np.linalg.norm(np.diff(mesh.vertices[chain], axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def _edge_face(mesh: Mesh, a: int, b: int) -> tuple[int, int, int]:
    """A face holding edge (a, b) and the slots of a and b in it."""
    indptr, vf = mesh.vertex_faces
    for f in vf[indptr[a] : indptr[a + 1]]:
        row = mesh.faces[f]
        if b in row:
            return int(f), int(np.flatnonzero(row == a)[0]), int(np.flatnonzero(row == b)[0])
    raise AssertionError(f"vertices {a} and {b} share no face")  # chains follow mesh edges


def chain_points(
    mesh: Mesh, chain: NDArray[np.int64], arc: NDArray[np.float64], positions: NDArray
) -> SurfacePoints:
    """Face points at arc-length ``positions`` (m,) along a vertex chain (on its edges)."""
    positions = np.clip(np.asarray(positions, dtype=np.float64), 0.0, arc[-1])
    k = np.clip(np.searchsorted(arc, positions, side="right") - 1, 0, len(chain) - 2)
    seg = arc[k + 1] - arc[k]
    t = np.where(seg > 0, (positions - arc[k]) / np.where(seg > 0, seg, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    face = np.empty(len(positions), dtype=np.int64)
    bary = np.zeros((len(positions), 3))
    cache: dict[tuple[int, int], tuple[int, int, int]] = {}
    for n, (kk, tt) in enumerate(zip(k, t, strict=True)):
        key = (int(chain[kk]), int(chain[kk + 1]))
        if key not in cache:
            cache[key] = _edge_face(mesh, *key)
        f, sa, sb = cache[key]
        face[n] = f
        bary[n, sa] = 1.0 - tt
        bary[n, sb] += tt
    return SurfacePoints(face, bary)


def project_on_chain(
    mesh: Mesh, chain: NDArray[np.int64], arc: NDArray[np.float64], xyz: NDArray
) -> tuple[float, float]:
    """Arc-length position of the point of a vertex chain closest to ``xyz`` (3,), and the
    distance to it."""
    p = mesh.vertices[chain]
    a, b = p[:-1], p[1:]
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("ij,ij->i", xyz - a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    q = a + t[:, None] * d
    dist = np.linalg.norm(q - xyz, axis=1)
    k = int(np.argmin(dist))
    return float(arc[k] + t[k] * (arc[k + 1] - arc[k])), float(dist[k])


def closest_approach(
    P: NDArray[np.float64], Q: NDArray[np.float64]
) -> tuple[int, float, int, float, float]:
    """Closest pair of points of two 3-D polylines P (m, 3) and Q (k, 3).

    Returns (segment of P, parameter in it, segment of Q, parameter in it, distance); a
    single-point polyline counts as one zero-length segment.
    """
    if len(P) == 1:
        P = np.repeat(P, 2, axis=0)
    if len(Q) == 1:
        Q = np.repeat(Q, 2, axis=0)
    p0, d1 = P[:-1, None, :], (P[1:] - P[:-1])[:, None, :]
    q0, d2 = Q[None, :-1, :], (Q[1:] - Q[:-1])[None, :, :]
    r = p0 - q0
    a = np.einsum("ijk,ijk->ij", d1, d1) + np.zeros((1, Q.shape[0] - 1))
    e = np.einsum("ijk,ijk->ij", d2, d2) + np.zeros((P.shape[0] - 1, 1))
    b = np.einsum("ijk,ijk->ij", d1, d2)
    c = np.einsum("ijk,ijk->ij", d1, r)
    f = np.einsum("ijk,ijk->ij", d2, r)
    den = a * e - b * b
    safe = np.where(den > 1e-300, den, 1.0)
    s = np.where(den > 1e-300, np.clip((b * f - c * e) / safe, 0.0, 1.0), 0.0)
    t = np.where(e > 0, (b * s + f) / np.where(e > 0, e, 1.0), 0.0)
    # clamp t, then recompute s for the clamped t
    t = np.clip(t, 0.0, 1.0)
    s = np.where(a > 0, np.clip((b * t - c) / np.where(a > 0, a, 1.0), 0.0, 1.0), 0.0)
    diff = p0 + s[..., None] * d1 - (q0 + t[..., None] * d2)
    dist = np.linalg.norm(diff, axis=2)
    i, j = np.unravel_index(int(np.argmin(dist)), dist.shape)
    return int(i), float(s[i, j]), int(j), float(t[i, j]), float(dist[i, j])


def dijkstra_paths(mesh: Mesh, pairs: list[tuple[int, int]]) -> list[NDArray[np.int64]]:
    """Shortest edge paths (vertex chains) between vertex pairs of the patch mesh."""
    if not pairs:
        return []
    sources = np.array([a for a, _ in pairs], dtype=np.int64)
    _, pred = dijkstra(mesh.edge_graph, directed=False, indices=sources, return_predecessors=True)
    out = []
    for row, (a, b) in enumerate(pairs):
        path = [b]
        v = b
        while v != a:
            v = int(pred[row, v])
            if v < 0:
                raise AssertionError("patch mesh is connected")
            path.append(v)
        out.append(np.array(path[::-1], dtype=np.int64))
    return out
