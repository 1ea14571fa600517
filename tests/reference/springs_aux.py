"""Slow, obviously-correct oracles of the spring-mesh bookkeeping kernels
(`meshfit._kernels.springs_aux`): the numpy expressions they stand for."""

from __future__ import annotations

import numpy as np


def face_point_sums(P, F, face, bary):
    """(m, d) barycentric combinations of the vertex values ``P`` at face points."""
    return np.einsum("ij,ijk->ik", bary, P[F[face]])


def mid_parameters(uv, F, face, bary, a, b):
    """(m, 2) mean parameters of the grid points ``a`` and ``b``."""
    return 0.5 * (
        face_point_sums(uv, F, face[a], bary[a]) + face_point_sums(uv, F, face[b], bary[b])
    )


def section_positions(breaks, counts):
    """Positions uniform within each section (``np.linspace``), and the section ends."""
    out = [np.array([breaks[0]])]
    for k, c in enumerate(counts):
        out.append(np.linspace(breaks[k], breaks[k + 1], c + 1)[1:])
    pos = np.concatenate(out)
    ends = np.zeros(pos.size, dtype=bool)
    ends[np.cumsum([0, *counts])] = True
    return pos, ends


def chain_arc(V, chain):
    """(k,) cumulative length along a vertex chain."""
    seg = np.linalg.norm(np.diff(V[chain], axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def chain_edge_faces(F, FN, n_vertices, chains):
    """Per chain, (face, slot of a, slot of b) of each chain edge (a, b) on the boundary, by
    sorting the boundary edges' keys in both directions; raises AssertionError where a
    chain edge is not a boundary edge."""
    f, k = np.nonzero(FN < 0)  # boundary edge k of face f
    a, b = F[f, k], F[f, (k + 1) % 3]
    n = np.int64(n_vertices)
    key = np.concatenate([a * n + b, b * n + a])
    face = np.concatenate([f, f])
    sa = np.concatenate([k, (k + 1) % 3])
    sb = np.concatenate([(k + 1) % 3, k])
    order = np.argsort(key)
    skey = key[order]
    out = []
    for chain in chains:
        want = chain[:-1] * n + chain[1:]
        pos = np.minimum(np.searchsorted(skey, want), len(order) - 1)
        hit = order[pos]
        if not np.array_equal(key[hit], want):
            raise AssertionError("side chains follow the patch boundary")
        out.append((face[hit], sa[hit], sb[hit]))
    return out


def mean_face_edge(V, F):
    """Mean length over the faces' three edges each (numpy; agrees to round-off)."""
    d = V[F[:, [1, 2, 0]]] - V[F]
    return float(np.linalg.norm(d, axis=2).mean()) if len(F) else 0.0
