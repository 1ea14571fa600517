"""Spring mesh initialisation: static boundary sampling and Dijkstra iso-curves (sec. 5.4)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from meshfit._kernels import frozen
from meshfit._kernels import springs_aux as _aux
from meshfit._kernels.springs import chain_points as _chain_points
from meshfit.mesh import Mesh
from meshfit.surface import astar_path
from meshfit.types import SurfacePoints

__all__ = ["chain_arc", "chain_points", "closest_approach", "project_on_chain"]


def chain_arc(mesh: Mesh, chain: NDArray[np.int64]) -> NDArray[np.float64]:
    """(k,) float64 cumulative length along a vertex chain, model units."""
    chain = np.ascontiguousarray(chain, dtype=np.int64).reshape(-1)
    if chain.size == 0:
        return np.zeros(1)
    if chain.min() < 0 or chain.max() >= mesh.n_vertices:
        raise IndexError("chain_arc: vertex index out of range")
    return _aux.chain_arc(*frozen(mesh.vertices, chain))


def chain_edge_faces(
    mesh: Mesh, chains: list[NDArray[np.int64]]
) -> list[tuple[NDArray, NDArray, NDArray]]:
    """For each edge of vertex chains along the mesh boundary: the face holding it and the
    slots of the edge's two vertices in that face; per chain, three (k - 1,) int64 arrays."""
    chains = [np.ascontiguousarray(c, dtype=np.int64).reshape(-1) for c in chains]
    if not chains:
        return []
    sizes = [max(c.size, 1) for c in chains]
    # an empty chain (no edges) stands in as one vertex
    flat = np.concatenate([c if c.size else np.zeros(1, dtype=np.int64) for c in chains])
    if flat.min() < 0 or flat.max() >= mesh.n_vertices:
        raise IndexError("chain_edge_faces: vertex index out of range")
    ends = np.zeros(len(chains) + 1, dtype=np.int64)
    np.cumsum(sizes, out=ends[1:])
    face, sa, sb, ok = _aux.chain_edge_faces(
        mesh.faces, mesh.face_neighbors, np.int64(mesh.n_vertices), flat, ends
    )
    if not ok:
        raise AssertionError("side chains follow the patch boundary")
    cut = ends[1:] - np.arange(1, len(chains) + 1)  # edge ends: one fewer per chain
    starts = np.concatenate([[0], cut[:-1]])
    return [
        (face[a:b].copy(), sa[a:b].copy(), sb[a:b].copy())
        for a, b in zip(starts.tolist(), cut.tolist(), strict=True)
    ]


def chain_points(
    mesh: Mesh,
    chain: NDArray[np.int64],
    arc: NDArray[np.float64],
    positions: NDArray,
    edge_faces: tuple[NDArray, NDArray, NDArray] | None = None,
) -> SurfacePoints:
    """Face points at arc-length ``positions`` (m,) along a vertex chain (on its edges)."""
    if edge_faces is None:
        edge_faces = chain_edge_faces(mesh, [chain])[0]
    ef, ea, eb = (np.ascontiguousarray(a, dtype=np.int64) for a in edge_faces)
    face, bary = _chain_points(
        np.ascontiguousarray(arc, dtype=np.float64),
        ef,
        ea,
        eb,
        np.ascontiguousarray(positions, dtype=np.float64).reshape(-1),
    )
    return SurfacePoints.owned(face, bary)


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
    """Shortest edge paths (vertex chains) between vertex pairs of the patch mesh.

    Dijkstra's single-source single-destination search (sec. 5.4) run as A* with the
    straight-line heuristic, which returns a shortest path of the same graph while
    visiting far fewer vertices.
    """
    return [astar_path(mesh, int(a), int(b)).vertices for a, b in pairs]
