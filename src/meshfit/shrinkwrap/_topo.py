"""Connectivity helpers for the small and regularly refined triangulations of shrink wrapping."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import sparse


def unique_edges(faces: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Unique undirected edges sorted lexicographically (smaller index first) and the edge id of
    edge ``k = (F[f, k], F[f, (k + 1) % 3])`` of each face.

    Returns
    -------
    edges : (ne, 2) int64
    face_edges : (nf, 3) int64
    """
    he = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    lo = np.minimum(he[:, 0], he[:, 1]).astype(np.int64)
    hi = np.maximum(he[:, 0], he[:, 1]).astype(np.int64)
    n = int(hi.max()) + 1 if len(hi) else 1
    key, inv = np.unique(lo * n + hi, return_inverse=True)
    edges = np.stack([key // n, key % n], axis=1)
    return edges.astype(np.int64), inv.reshape(-1, 3).astype(np.int64)


def face_neighbors(faces: NDArray[np.int64]) -> NDArray[np.int64]:
    """(nf, 3) int64: face across edge k of each face of a closed manifold triangulation."""
    _, fe = unique_edges(faces)
    nf = faces.shape[0]
    flat = fe.reshape(-1)
    order = np.argsort(flat, kind="stable")
    pair = order.reshape(-1, 2)  # every edge has exactly two half-edges
    fn = np.full(3 * nf, -1, dtype=np.int64)
    fn[pair[:, 0]] = pair[:, 1] // 3
    fn[pair[:, 1]] = pair[:, 0] // 3
    return fn.reshape(nf, 3)


def adjacency(faces: NDArray[np.int64], n: int) -> sparse.csr_matrix:
    """(n, n) symmetric 0/1 vertex adjacency matrix."""
    e, _ = unique_edges(faces)
    m = sparse.coo_matrix(
        (np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)
    )
    return m.tocsr()


def subdivide(
    faces: NDArray[np.int64], n_vertices: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """1-to-4 split: the midpoint of edge ``e`` (row of :func:`unique_edges`) becomes vertex
    ``n_vertices + e``; face ``(a, b, c)`` becomes ``(a, ab, ca), (ab, b, bc), (ca, bc, c),
    (ab, bc, ca)`` in this order (children ``4 f .. 4 f + 3``).

    Returns
    -------
    faces : (4 nf, 3) int64
    edges : (ne, 2) int64
        The split edges; row ``e`` holds the two parents of vertex ``n_vertices + e``.
    """
    edges, fe = unique_edges(faces)
    m = fe + n_vertices
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    ab, bc, ca = m[:, 0], m[:, 1], m[:, 2]
    out = np.stack(
        [
            np.stack([a, ab, ca], 1),
            np.stack([ab, b, bc], 1),
            np.stack([ca, bc, c], 1),
            np.stack([ab, bc, ca], 1),
        ],
        axis=1,
    ).reshape(-1, 3)
    return out, edges
