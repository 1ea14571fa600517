"""Coarse proxies of dense closed meshes: topology-preserving simplification by half-edge
collapses.

The sphere parameterization and the base mesh of a dense scan only need its coarse shape:
:func:`simplify_mesh` gives a closed mesh of the same genus whose vertices are a subset of
the input's (a half-edge collapse ``v -> u`` removes ``v`` and keeps ``u`` in place), with
triangles of bounded valence and shape. :func:`simplify_store` makes the same kind of proxy
of a mesh too large to hold whole, brick by brick from a
:class:`~meshfit.mesh.store.MeshStore`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit import errors
from meshfit._kernels import decimate as _k
from meshfit.mesh import Mesh

__all__ = [
    "BRICKS_ABOVE",
    "MERGE_FACTOR",
    "SimplifiedMesh",
    "collapse_to",
    "simplify_mesh",
    "simplify_store",
]

#: a collapse may turn a surviving face's normal by at most this angle (degrees)
MAX_NORMAL_TURN_DEG = 60.0
#: a collapse may not leave a vertex with more neighbours than this
MAX_VALENCE = 12
#: a surviving face must keep at least this quality (4 sqrt(3) area / sum of squared edge
#: lengths; 1 for an equilateral triangle) unless it was already worse
MIN_QUALITY = 0.15
#: :func:`simplify_store` simplifies the bricks to about this many times the target's faces
#: in all (besides their frozen rims) before the last passes over the whole
MERGE_FACTOR = 40
#: :func:`simplify_mesh` goes brick by brick above this many times ``MERGE_FACTOR`` times
#: the target's faces
BRICKS_ABOVE = 4
#: passes of independent collapses before giving up on the target
_MAX_PASSES = 200


@dataclass(frozen=True, eq=False)
class SimplifiedMesh:
    """Result of :func:`simplify_mesh`.

    Attributes
    ----------
    mesh : Mesh
        The coarse mesh.
    vertex_parent : (nv_coarse,) int64
        Input vertex of each coarse vertex (same position).
    passes : int
        Collapse passes run.
    """

    mesh: Mesh
    vertex_parent: NDArray[np.int64]
    passes: int


def collapse_to(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    target_faces: int,
    frozen: NDArray[np.bool_] | None = None,
    max_length: float = np.inf,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], int]:
    """Passes of independent half-edge collapses (:func:`simplify_mesh`'s rules) until
    ``target_faces`` faces remain or no edge can go; ``frozen`` vertices neither go nor take
    a collapse, so a piece of a larger surface whose rim is frozen keeps its rim and fits
    back into the rest; a vertex goes only while its shortest edge is at most
    ``max_length``.

    Returns ``(vertices, faces, kept, passes)``: the remaining vertices (unmoved), the faces
    on them, each remaining vertex's index in ``vertices`` and the passes run.
    """
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.array(faces, dtype=np.int64, order="C")
    alive = np.ones(F.shape[0], dtype=np.bool_)
    kept = np.arange(V.shape[0], dtype=np.int64)
    fixed = np.zeros(V.shape[0], dtype=np.bool_) if frozen is None else frozen.astype(np.bool_)
    n_alive = F.shape[0]
    min_cos = float(np.cos(np.radians(MAX_NORMAL_TURN_DEG)))
    max_sq = float(max_length) ** 2
    passes = 0
    while n_alive > target_faces and passes < _MAX_PASSES:
        # every collapse removes two faces
        want = (n_alive - target_faces + 1) // 2
        done = _k.collapse_pass(
            V, F, alive, fixed[kept], want, max_sq, MAX_VALENCE, min_cos, MIN_QUALITY
        )
        passes += 1
        if done == 0:
            break
        n_alive -= 2 * done
        # drop the removed faces and vertices, keeping both orders (a monotone renumbering):
        # the next pass sees the same stars and breaks ties the same way, on fewer elements
        V, F, kept = _k.compact(V, F, alive, kept)
        alive = np.ones(F.shape[0], dtype=np.bool_)
    V, F, kept = _k.compact(V, F, alive, kept)
    return V, F, kept, passes


def simplify_mesh(
    mesh: Mesh,
    target_faces: int,
    *,
    workers: int = 1,
    bricks: bool | None = None,
    brick_faces: int | None = None,
) -> SimplifiedMesh:
    """Simplify a closed manifold mesh to about ``target_faces`` faces, same topology.

    Each pass collapses an independent set of edges, shortest first (half-edge collapses:
    the kept vertex does not move), under the link condition (so the genus and the
    manifoldness are kept), a valence cap, a bound on the turn of every surviving face's
    normal and a floor on its shape quality. Passes repeat until the face count reaches
    ``target_faces`` or no edge can be collapsed.

    Parameters
    ----------
    mesh : Mesh
        One closed manifold surface.
    target_faces : int
        Wanted face count (at least 20); the result has at most a few faces fewer, or more
        when the constraints stop the collapses first.
    workers : int, keyword-only
        Threads simplifying bricks (default 1).
    bricks : bool, keyword-only, optional
        Simplify Morton bricks first, as :func:`simplify_store` does (the same result as
        the store of ``mesh`` with the same bricks); their passes stay in cache and run on
        ``workers`` threads. Default: for a mesh of more than `BRICKS_ABOVE` times
        ``MERGE_FACTOR * target_faces`` faces, where the bricks remove most of the faces.
    brick_faces : int, keyword-only, optional
        Faces per brick (about), default :data:`meshfit.mesh.store.BRICK_FACES`.

    Returns
    -------
    SimplifiedMesh

    Raises
    ------
    meshfit.errors.InputError
        ``target_faces`` below 20, ``brick_faces`` below 1.
    meshfit.errors.TopologyError
        The mesh has boundary loops.

    References
    ----------
    .. [1] Hoppe, "Progressive meshes", SIGGRAPH 1996 (edge collapses);
       Dey, Edelsbrunner, Guha & Nekhayev, "Topology preserving edge contraction", 1999
       (the link condition).
    """
    target = int(target_faces)
    if target < 20:
        raise errors.InputError(f"target_faces must be at least 20, got {target_faces}")
    if not mesh.is_closed:
        raise errors.TopologyError(
            f"simplify_mesh needs a closed surface; {mesh.name or 'the mesh'} has boundary loops"
        )
    if brick_faces is not None and int(brick_faces) < 1:
        raise errors.InputError(f"brick_faces must be at least 1, got {brick_faces}")
    if bricks is None:
        bricks = mesh.n_faces > BRICKS_ABOVE * MERGE_FACTOR * target
    if bricks:
        V, F, kept, passes = _mesh_bricks(mesh, target, workers, brick_faces)
    else:
        V, F, kept, passes = collapse_to(mesh.vertices, mesh.faces, target)
    coarse = Mesh(V, F, name=f"{mesh.name}_proxy" if mesh.name else "proxy")
    return SimplifiedMesh(coarse, kept, passes)


def _mesh_bricks(mesh: Mesh, target: int, workers: int, brick_faces: int | None):
    """:func:`_by_bricks` of ``mesh``'s faces sorted into Morton bricks as
    :func:`meshfit.mesh.store.write_store` sorts them."""
    from meshfit.mesh.store import BRICK_FACES, MORTON_BITS, brick_cuts, morton_cells

    V, F = mesh.vertices, mesh.faces
    codes = morton_cells(V, F, V.min(axis=0), V.max(axis=0))
    count = np.bincount(codes, minlength=1 << (3 * MORTON_BITS))
    cut, start = brick_cuts(count, BRICK_FACES if brick_faces is None else int(brick_faces))
    # each brick's faces in input order, as the store holds them
    order = _k.cell_order(np.searchsorted(cut, codes, "right") - 1, cut.size)
    del codes
    sorted_faces = F[order]
    del order
    return _by_bricks(V, lambda b: sorted_faces[start[b] : start[b + 1]], start, target, workers)


def simplify_store(
    store,
    target_faces: int,
    *,
    workers: int = 1,
    progress=None,
) -> SimplifiedMesh:
    """:func:`simplify_mesh` of a :class:`~meshfit.mesh.store.MeshStore`, brick by brick.

    A vertex used by faces of two bricks, or on an edge that does not have two faces in
    its brick, is a brick's rim: it stays, and so does every edge between two such
    vertices. Every other vertex has its whole star in its brick, so each brick is
    simplified alone (on ``workers`` threads, one brick's arrays at a time per thread) by
    the same collapses, the link condition checked on the whole star, of edges up to the
    side of an equilateral triangle of `MERGE_FACTOR` times ``target_faces`` faces of the
    surface's area: shortest first, as the whole would be simplified, and no further, so
    the bricks' insides stay as fine as the mesh would be at that count while their rims
    keep the input's edges. The bricks' results then fit together along their unchanged
    rims into one mesh of the same topology, which the same passes simplify to
    ``target_faces`` (its shortest edges, the rims', first). Memory: the bricks being
    simplified, a byte and an int32 per input vertex, and the merged mesh.

    Parameters
    ----------
    store : MeshStore
    target_faces : int
        At least 20.
    workers : int
        Threads simplifying bricks (the kernel releases the GIL).
    progress : callable(done, total), optional
        After each brick.

    Returns
    -------
    SimplifiedMesh
        ``vertex_parent`` indexes the store's vertices (the input's).

    Raises
    ------
    meshfit.errors.InputError
        ``target_faces`` below 20, or a store without faces.
    """
    target = int(target_faces)
    if target < 20:
        raise errors.InputError(f"target_faces must be at least 20, got {target_faces}")
    if store.n_faces == 0:
        raise errors.InputError(f"{store.folder}: the store has no faces")
    V, F, kept, passes = _by_bricks(
        store.vertices, store.brick, store.brick_start, target, workers, progress
    )
    return SimplifiedMesh(Mesh(V, F, name=f"{store.folder.name}_proxy"), kept, passes)


def _by_bricks(
    vertices: NDArray[np.float64],
    brick,
    brick_start: NDArray[np.int64],
    target: int,
    workers: int,
    progress=None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], int]:
    """:func:`collapse_to` ``target`` of the faces ``brick(b)`` (``b`` below
    ``len(brick_start) - 1``, the bricks' first faces with the total last) on ``vertices``,
    brick by brick as :func:`simplify_store` says; ``kept`` indexes ``vertices``."""
    from meshfit._threads import map_threads

    nb = brick_start.size - 1
    first = np.full(vertices.shape[0], -1, dtype=np.int32)
    shared = np.zeros(vertices.shape[0], dtype=np.bool_)
    whole = np.asarray(vertices)
    area = 0.0
    for b in range(nb):
        faces = np.ascontiguousarray(brick(b), dtype=np.int64)
        area += _k.survey_brick(whole, faces, b, first, shared)
    del first
    # the side of an equilateral triangle of the merged mesh's mean area
    longest = float(np.sqrt(4.0 * area / (np.sqrt(3.0) * MERGE_FACTOR * target)))

    def one(b: int) -> NDArray[np.int64]:
        faces = brick(b)
        used, local = np.unique(faces, return_inverse=True)
        local = local.reshape(-1, 3)
        frozen = shared[used] | _rim(local, used.size)
        _, F, kept, _ = collapse_to(vertices[used], local, 0, frozen, longest)
        return used[kept][F]

    cost = np.diff(brick_start).tolist()
    parts = map_threads(one, list(range(nb)), workers, cost=cost, progress=progress)
    merged = np.concatenate(parts)
    del parts
    used, local = np.unique(merged, return_inverse=True)
    local = local.reshape(-1, 3)
    V, F, kept, passes = collapse_to(vertices[used], local, target, _rim(local, used.size))
    return V, F, used[kept], passes


def _rim(faces: NDArray[np.int64], n_vertices: int) -> NDArray[np.bool_]:
    """Vertices on an edge that does not have exactly two of ``faces``."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    key = e[:, 0] * n_vertices + e[:, 1]
    uniq, count = np.unique(key, return_counts=True)
    odd = uniq[count != 2]
    out = np.zeros(n_vertices, dtype=np.bool_)
    out[odd // n_vertices] = True
    out[odd % n_vertices] = True
    return out
