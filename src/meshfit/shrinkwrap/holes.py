"""Closing small holes so that an open genus-0 scan can be shrink wrapped."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.sparse.linalg import spsolve

from meshfit import errors
from meshfit.mesh import Mesh

__all__ = ["fill_holes"]

#: a fill triangle is split at its centroid while the centroid lies farther than this
#: factor times the local edge length from each of its corners (Liepa 2003's density rule)
SPLIT_FACTOR = float(np.sqrt(2.0))
#: rounds of splitting and edge flipping at most (each round splits every triangle still
#: too large; a hole of n edges needs about log2(n) rounds)
REFINE_ROUNDS = 30
#: edge flips per patch face at most in one relaxation (flips by the angle rule end in the
#: plane; on a curved patch a cycle is cut short)
FLIPS_PER_FACE = 10
#: a hole whose rim faces stand on average more than this many degrees from the plane of
#: the rim is a cut across the model (the open base of a bust, whose walls meet the rim's
#: plane nearly at right angles; the holes of a scan's surface stand far lower): its patch
#: is faired as a membrane, flat across a flat rim, not as a thin plate, which would carry
#: the walls on past the rim (a bulge below the base, and spring grids that fold over it)
CUT_ANGLE = 60.0


def fill_holes(mesh: Mesh, *, max_edges: int = 1000, fair: bool = True) -> Mesh:
    """Close every boundary loop of at most ``max_edges`` edges with a patch of triangles
    about as large as the mesh's triangles round the hole, shaped to continue the surface.

    Each hole is triangulated by the triangulation of its boundary polygon of least area
    (dynamic programming over the polygon's diagonals, none along an edge the mesh already
    has), then refined: a triangle is split at its centroid while that lies farther than
    `SPLIT_FACTOR` times the local edge length from its corners (that of the edges round the
    hole, at least the mesh's mean edge length), and edges are flipped
    wherever the two angles opposite them add up to more than 180 degrees. With ``fair``
    the new vertices then solve the discrete thin-plate equation (the umbrella operator
    applied twice is zero at every new vertex, the hole's boundary and the ring of vertices
    round it held), so the patch leaves the boundary along the surrounding surface; a hole
    that cuts across the model (its rim faces on average over `CUT_ANGLE` degrees from the
    rim's plane, e.g. a bust's base) is faired as a membrane instead (the umbrella operator
    zero at every new vertex, the rim held): flat across a flat rim.

    Parameters
    ----------
    mesh : Mesh
    max_edges : int, keyword-only
        Largest hole closed, in boundary edges (default 1000).
    fair : bool, keyword-only
        Move the new vertices to the thin-plate surface, or the membrane for a cut (default
        True); else they stay in the least-area triangulation's triangles.

    Returns
    -------
    Mesh
        The input vertices and faces first (same indices), then the new vertices and faces
        of each hole in turn. Raises :class:`meshfit.errors.TopologyError` when a hole is
        larger than ``max_edges``.

    References
    ----------
    .. [1] Liepa, "Filling holes in meshes", Eurographics Symposium on Geometry Processing
       2003 (least-area triangulation, refinement by centroid splits and edge relaxation,
       fairing).
    .. [2] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 5 (the umbrella operator).
    """
    loops = mesh.boundary_loops
    big = [len(lp) for lp in loops if len(lp) > max_edges]
    if big:
        raise errors.TopologyError(
            f"mesh {mesh.name!r}: hole of {big[0]} edges is larger than max_edges={max_edges}"
        )
    if not loops:
        return mesh
    V = [mesh.vertices]
    F = [mesh.faces]
    n = mesh.n_vertices
    edge_len = _vertex_edge_lengths(mesh)
    rim = np.zeros(mesh.n_vertices, dtype=bool)
    rim[np.concatenate(loops)] = True
    e = mesh.edges
    existing = e[rim[e[:, 0]] & rim[e[:, 1]]]  # the edges a fill triangle could repeat
    colors = mesh.vertex_colors
    extra_colors = []
    cut = []
    for lp in loops:
        lp = np.asarray(lp, dtype=np.int64)
        P = mesh.vertices[lp]
        if len(set(lp.tolist())) < len(lp):  # a loop through a vertex twice: a fan
            pos, tris = _fan(P)
        else:
            forbidden = _forbidden(lp, existing)
            tris = _least_area(P, forbidden)
            if tris is None:  # every triangulation joins two loop vertices the mesh joins
                P, tris = _fan(P)
                forbidden = np.pad(forbidden, ((0, 1), (0, 1)))
            sigma = np.maximum(edge_len[lp], mesh.mean_edge_length)
            pos, tris = _refine(P, tris, _scales(P, sigma), forbidden)
        new = len(pos) - len(lp)
        cut += [_is_cut(mesh, lp)] * new
        index = np.concatenate([lp, np.arange(n, n + new)])
        V.append(pos[len(lp) :])
        F.append(index[tris])
        n += new
        if colors is not None:
            c = colors[lp].mean(axis=0).round().astype(np.uint8)
            extra_colors.append(np.repeat(c[None], new, axis=0))
    vertices = np.vstack(V)
    faces = np.vstack(F)
    if fair and n > mesh.n_vertices:
        vertices = _fair(vertices, faces, np.arange(mesh.n_vertices, n), np.asarray(cut))
    if colors is not None:
        colors = np.vstack([colors, *extra_colors])
    return Mesh(vertices, faces, colors, name=mesh.name)


def _vertex_edge_lengths(mesh: Mesh) -> NDArray[np.float64]:
    """(nv,) mean length of the edges at each vertex (0 for an isolated vertex)."""
    e = mesh.edges
    w = mesh.edge_lengths
    total = np.bincount(e.ravel(), weights=np.repeat(w, 2), minlength=mesh.n_vertices)
    count = np.bincount(e.ravel(), minlength=mesh.n_vertices)
    return np.divide(total, count, out=np.zeros(mesh.n_vertices), where=count > 0)


def _fan(P: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A fan round a new vertex at the loop's centroid (loop vertices first)."""
    k = len(P)
    i = np.arange(k)
    tris = np.stack([(i + 1) % k, i, np.full(k, k)], axis=1)
    return np.vstack([P, P.mean(axis=0, keepdims=True)]), tris


def _forbidden(lp: NDArray[np.int64], existing: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(k, k) bool: pairs of loop positions joined by an edge of the mesh that is not a
    side of the loop (a diagonal there would give that edge a third face)."""
    k = len(lp)
    where = {int(v): i for i, v in enumerate(lp.tolist())}
    out = np.zeros((k, k), dtype=bool)
    for a, b in existing.tolist():
        if a in where and b in where:
            i, j = where[a], where[b]
            if (i - j) % k not in (1, k - 1):
                out[i, j] = out[j, i] = True
    return out


def _least_area(P: NDArray[np.float64], forbidden: NDArray[np.bool_]) -> NDArray[np.int64] | None:
    """(k - 2, 3) triangles of the closed polygon ``P (k, 3)`` of least total area, none
    with a ``forbidden`` diagonal, oriented against the polygon's order (the mesh's faces
    run along the loop the other way); None where every triangulation uses one."""
    from meshfit._kernels.holes import least_area_table

    k = len(P)
    if k == 3:
        return np.array([[0, 2, 1]], dtype=np.int64)
    W, best = least_area_table(
        np.ascontiguousarray(P, dtype=np.float64), np.ascontiguousarray(forbidden)
    )
    if not np.isfinite(W[0, k - 1]):
        return None
    tris = []
    stack = [(0, k - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        m = int(best[i, j])
        tris.append((i, j, m))  # loop order i -> m -> j, reversed
        stack += [(i, m), (m, j)]
    return np.asarray(tris, dtype=np.int64)


def _scales(P: NDArray[np.float64], sigma: NDArray[np.float64]) -> NDArray[np.float64]:
    """Local edge lengths of a patch's starting vertices ``P``: ``sigma`` for the loop's,
    their mean for a fan's centre."""
    return np.concatenate([sigma, np.full(len(P) - len(sigma), sigma.mean())])


def _refine(
    P: NDArray[np.float64],
    tris: NDArray[np.int64],
    sigma: NDArray[np.float64],
    forbidden: NDArray[np.bool_],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Split the triangles of a hole's patch at their centroids until they are about as
    large as the edges round the hole (``sigma``: the local edge length at each vertex of
    ``P``), relaxing edges by flips after each round (never joining two of the first
    ``len(forbidden)`` vertices that ``forbidden`` marks). Returns every vertex (``P``'s
    first) and the triangles."""
    pos = [p for p in P]
    scale = list(np.asarray(sigma, dtype=np.float64))
    faces = [tuple(int(x) for x in t) for t in tris]
    for _ in range(REFINE_ROUNDS):
        split = False
        out = []
        for a, b, c in faces:
            pa, pb, pc = pos[a], pos[b], pos[c]
            centre = (pa + pb + pc) / 3.0
            s = (scale[a] + scale[b] + scale[c]) / 3.0
            far = all(
                SPLIT_FACTOR * np.linalg.norm(centre - pos[v]) > max(s, scale[v]) for v in (a, b, c)
            )
            if far:
                p = len(pos)
                pos.append(centre)
                scale.append(s)
                out += [(a, b, p), (b, c, p), (c, a, p)]
                split = True
            else:
                out.append((a, b, c))
        faces = _relax_edges([tuple(p) for p in pos], out, forbidden)
        if not split:
            break
    return np.asarray(pos), np.asarray(faces, dtype=np.int64)


def _angle(p, a, b) -> float:
    """Angle at ``p`` of the triangle ``p, a, b`` (3-sequences of floats), radians."""
    ux, uy, uz = a[0] - p[0], a[1] - p[1], a[2] - p[2]
    vx, vy, vz = b[0] - p[0], b[1] - p[1], b[2] - p[2]
    cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * vx + uy * vy + uz * vz)


def _relax_edges(pos: list, faces: list, forbidden: NDArray[np.bool_]) -> list:
    """Flip interior edges of a hole's patch whose two opposite angles add up to more than
    pi, until none does (at most `FLIPS_PER_FACE` flips a face). The loop's sides, whose
    other face is the mesh's, never flip; nor does an edge whose flip would repeat an edge
    of the patch or join two of the first ``len(forbidden)`` vertices that ``forbidden``
    marks (joined by the mesh)."""
    k = len(forbidden)
    faces = [list(f) for f in faces]
    where: dict[tuple[int, int], tuple[int, int]] = {}
    for t, f in enumerate(faces):
        for s in range(3):
            where[(f[s], f[(s + 1) % 3])] = (t, s)
    queue = [e for e in where if e[0] < e[1] and (e[1], e[0]) in where]
    budget = FLIPS_PER_FACE * len(faces)
    while queue and budget > 0:
        a, b = queue.pop()
        if (a, b) not in where or (b, a) not in where:
            continue
        t1, s1 = where[(a, b)]
        t2, s2 = where[(b, a)]
        c = faces[t1][(s1 + 2) % 3]
        d = faces[t2][(s2 + 2) % 3]
        if c == d or (c, d) in where or (d, c) in where or (c < k and d < k and forbidden[c, d]):
            continue
        if _angle(pos[c], pos[a], pos[b]) + _angle(pos[d], pos[a], pos[b]) <= np.pi + 1e-9:
            continue
        for t in (t1, t2):
            f = faces[t]
            for s in range(3):
                del where[(f[s], f[(s + 1) % 3])]
        faces[t1] = [c, a, d]
        faces[t2] = [d, b, c]
        for t in (t1, t2):
            f = faces[t]
            for s in range(3):
                where[(f[s], f[(s + 1) % 3])] = (t, s)
        queue += [(min(x, y), max(x, y)) for x, y in ((c, a), (a, d), (d, b), (b, c))]
        budget -= 1
    return [tuple(f) for f in faces]


def _is_cut(mesh: Mesh, loop: NDArray[np.int64]) -> bool:
    """Whether the faces along a hole's rim ``loop`` stand on average more than `CUT_ANGLE`
    degrees from the rim's least-squares plane."""
    P = mesh.vertices[loop]
    normal = np.linalg.svd(P - P.mean(axis=0), full_matrices=False)[2][2]
    rim = np.isin(mesh.faces, loop).sum(axis=1) >= 2
    cos = np.abs(mesh.face_normals[rim] @ normal)
    return bool(np.degrees(np.arccos(np.clip(cos, 0.0, 1.0))).mean() > CUT_ANGLE)


def _fair(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    free: NDArray[np.int64],
    membrane: NDArray[np.bool_],
) -> NDArray[np.float64]:
    """``vertices`` with those in ``free`` moved so that the umbrella operator of ``faces``
    is zero at those ``membrane`` marks and applied twice is zero at the others (the other
    vertices held). The umbrella's weights are the inverse edge lengths before the move (the
    scale-dependent umbrella: on a patch refined unevenly the uniform one pulls vertices
    toward the finer parts, so a hole cut from a smooth surface is filled further from it)."""
    nv = len(vertices)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    w = 1.0 / np.maximum(np.linalg.norm(vertices[e[:, 0]] - vertices[e[:, 1]], axis=1), 1e-300)
    A = sparse.coo_matrix(
        (
            np.concatenate([w, w]),
            (np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])),
        ),
        shape=(nv, nv),
    ).tocsr()
    total = np.asarray(A.sum(axis=1)).ravel()
    L = (sparse.diags(1.0 / np.where(total > 0, total, 1.0)) @ A - sparse.identity(nv)).tocsr()
    rows = sparse.vstack([(L @ L).tocsr()[free[~membrane]], L[free[membrane]]]).tocsr()
    order = np.concatenate([free[~membrane], free[membrane]])
    held = np.ones(nv, dtype=bool)
    held[free] = False
    M = rows[:, order].tocsc()
    rhs = -(rows[:, np.flatnonzero(held)] @ vertices[held])
    out = vertices.copy()
    out[order] = np.asarray(spsolve(M, rhs)).reshape(len(order), 3)
    return out
