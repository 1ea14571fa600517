"""Loop (approximating) and Butterfly (interpolating) subdivision of closed triangle meshes,
with the vertex numbering of :func:`meshfit.shrinkwrap._topo.subdivide`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from meshfit import errors
from meshfit.shrinkwrap import _topo

__all__ = ["SCHEMES", "level_faces", "level_sizes", "subdivide_step", "zorin_weights"]

SCHEMES = ("loop", "butterfly")


def _opposite_across(faces: NDArray[np.int64], fn: NDArray[np.int64]) -> NDArray[np.int64]:
    """(nf, 3): vertex of the face across edge k that is not on edge k."""
    g = faces[fn]  # (nf, 3, 3)
    a = faces
    b = np.roll(faces, -1, axis=1)
    not_on = (g != a[:, :, None]) & (g != b[:, :, None])
    return g[not_on].reshape(faces.shape)


def zorin_weights(k: int) -> NDArray[np.float64]:
    """Weights ``s_0 .. s_{k-1}`` of the modified Butterfly rule at a vertex of valence ``k``.

    The new point on the edge from an extraordinary vertex ``v`` to its neighbour ``e_0`` is
    ``3/4 v + sum_j s_j e_j`` over the neighbours ``e_j`` in cyclic order (either direction:
    ``s_j = s_{k-j}``); the ``s_j`` sum to ``1/4``.

    Parameters
    ----------
    k : int
        Valence, at least 3.

    Returns
    -------
    (k,) float64

    References
    ----------
    .. [1] Zorin, Schroeder & Sweldens, "Interpolating subdivision for meshes with arbitrary
       topology", SIGGRAPH 1996, sec. 4.
    """
    if k < 3:
        raise errors.InputError(f"valence must be at least 3, got {k}")
    if k == 3:
        return np.array([5.0 / 12.0, -1.0 / 12.0, -1.0 / 12.0])
    if k == 4:
        return np.array([3.0 / 8.0, 0.0, -1.0 / 8.0, 0.0])
    t = 2.0 * np.pi * np.arange(k) / k
    return (0.25 + np.cos(t) + 0.5 * np.cos(2.0 * t)) / k


def _one_rings(faces: NDArray[np.int64], verts: NDArray[np.int64]) -> list[NDArray[np.int64]]:
    """Neighbours of each vertex of ``verts`` in cyclic order (closed manifold mesh)."""
    out = []
    for v in verts:
        rows, cols = np.nonzero(faces == v)
        nxt = {
            int(faces[r, (c + 1) % 3]): int(faces[r, (c + 2) % 3])
            for r, c in zip(rows, cols, strict=True)
        }
        ring = [next(iter(nxt))]
        for _ in range(len(nxt) - 1):
            ring.append(nxt[ring[-1]])
        out.append(np.asarray(ring, dtype=np.int64))
    return out


def _butterfly_extraordinary(vertices, faces, edges, odd):
    """Replace the new points of edges touching a vertex of valence != 6 by Zorin's rule
    (averaged over both ends when both are extraordinary)."""
    n = len(vertices)
    val = np.bincount(edges.reshape(-1), minlength=n)
    xv = np.flatnonzero(val != 6)
    if len(xv) == 0:
        return odd
    key = edges[:, 0] * n + edges[:, 1]
    acc = np.zeros_like(odd)
    cnt = np.zeros(len(edges))
    for v, ring in zip(xv, _one_rings(faces, xv), strict=True):
        w = zorin_weights(len(ring))
        for j, u in enumerate(ring):
            e = int(np.searchsorted(key, min(v, u) * n + max(v, u)))
            acc[e] += 0.75 * vertices[v] + np.roll(w, j) @ vertices[ring]
            cnt[e] += 1
    hit = cnt > 0
    odd = odd.copy()
    odd[hit] = acc[hit] / cnt[hit, None]
    return odd


def subdivide_step(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], scheme: str = "loop"
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """One step of Loop or Butterfly subdivision of a closed manifold mesh.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (nf, 3) int64
    scheme : {"loop", "butterfly"}
        ``"loop"``: Loop 1987, odd vertices ``3/8 (a + b) + 1/8 (c + d)``, even vertices
        ``(1 - n beta) v + beta sum(neighbours)`` with Loop's ``beta(n)``.
        ``"butterfly"``: the modified Butterfly scheme of Zorin, Schroeder & Sweldens 1996:
        the 8-point stencil of Dyn, Levin & Gregory 1990,
        ``1/2 (a + b) + 1/8 (c + d) - 1/16 (four wings)``, on edges between two vertices of
        valence 6; on an edge with one end of another valence, that end's rule
        ``3/4 v + sum s_j e_j`` (:func:`zorin_weights`); with both ends extraordinary, the
        mean of the two. Even vertices keep their positions (interpolating).

    Returns
    -------
    vertices : (n + ne, 3) float64
        Even vertices first (same indices), then one per edge of ``unique_edges(faces)``.
    faces : (4 nf, 3) int64

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 8.1.
    .. [2] Loop, "Smooth subdivision surfaces based on triangles", MS thesis, Utah 1987.
    .. [3] Dyn, Levin & Gregory, "A butterfly subdivision scheme for surface interpolation
       with tension control", ACM TOG 9(2), 1990.
    .. [4] Zorin, Schroeder & Sweldens, "Interpolating subdivision for meshes with arbitrary
       topology", SIGGRAPH 1996.
    """
    if scheme not in SCHEMES:
        raise errors.InputError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    n = len(vertices)
    new_faces, edges = _topo.subdivide(faces, n)
    _, fe = _topo.unique_edges(faces)
    ne = len(edges)
    a = faces
    b = np.roll(faces, -1, axis=1)
    c = np.roll(faces, -2, axis=1)  # vertex opposite edge k within the face
    he = fe.reshape(-1)
    odd = np.zeros((ne, 3))
    if scheme == "loop":
        contrib = 3.0 / 16.0 * (vertices[a] + vertices[b]) + 1.0 / 8.0 * vertices[c]
        for j in range(3):
            odd[:, j] = np.bincount(he, weights=contrib[:, :, j].reshape(-1), minlength=ne)
        adj = _topo.adjacency(faces, n)
        val = np.asarray(adj.sum(axis=1)).ravel()
        beta = (5.0 / 8.0 - (3.0 / 8.0 + 0.25 * np.cos(2 * np.pi / val)) ** 2) / val
        even = (1 - val * beta)[:, None] * vertices + beta[:, None] * (adj @ vertices)
    else:
        fn = _topo.face_neighbors(faces)
        opp = _opposite_across(faces, fn)
        w1 = np.roll(opp, -1, axis=1)  # across edge k+1
        w2 = np.roll(opp, -2, axis=1)  # across edge k+2
        contrib = (
            0.25 * (vertices[a] + vertices[b])
            + 0.125 * vertices[c]
            - 0.0625 * (vertices[w1] + vertices[w2])
        )
        for j in range(3):
            odd[:, j] = np.bincount(he, weights=contrib[:, :, j].reshape(-1), minlength=ne)
        odd = _butterfly_extraordinary(np.asarray(vertices, dtype=np.float64), faces, edges, odd)
        even = np.array(vertices, dtype=np.float64)
    return np.vstack([even, odd]), new_faces


def level_sizes(base_faces: NDArray[np.int64], n_base: int, levels: int) -> list[int]:
    """Vertex count of each level ``0..levels`` of the regular refinement of a closed mesh."""
    nf = len(base_faces)
    ne = 3 * nf // 2
    sizes = [n_base]
    for _ in range(levels):
        sizes.append(sizes[-1] + ne)
        nf *= 4
        ne = 3 * nf // 2
    return sizes


def level_faces(base_faces: NDArray[np.int64], n_base: int, levels: int) -> list[NDArray]:
    """Faces of every level ``0..levels`` (1-to-4 splits of the base faces)."""
    out = [np.asarray(base_faces, dtype=np.int64)]
    n = n_base
    for _ in range(levels):
        f, e = _topo.subdivide(out[-1], n)
        n += len(e)
        out.append(f)
    return out
