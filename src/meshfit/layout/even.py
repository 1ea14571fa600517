"""An even remesh for inputs of needle triangles (CAD tessellations).

A CAD program tessellates a part with as few triangles as its faces allow: fans of needles
across flat faces, strips along cylinders, each triangle often tens of times longer than it
is high. The automatic layout grows its cells over mesh vertices and edges, and a flat face
whose only vertices are on its rims gives cells of 1 to 20 degree corners whose spring grids
fold; splitting the needles' long edges leaves them needles and does not help (measured in
the CHANGELOG). Such an input is remeshed first into even triangles of about the same count
(Botsch & Kobbelt 2004: edge splits, collapses and flips, tangential smoothing, every vertex
projected back onto the input), its creases kept as edges and its boundary as it is; the fit
then works on that mesh, whose distance to the input is measured and reported.

Scans are left as they are: their triangles are even already (a needle share of at most 3%
of the area on every scan tested, against 10 to 90% on CAD tessellations).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from meshfit.errors import InputError, MeshfitError
from meshfit.layout.regions import CREASE_ANGLE, sharp_edges
from meshfit.mesh import Mesh

__all__ = ["EvenRemesh", "collapse_short_edges", "even_remesh", "needle_share"]

#: a triangle whose longest edge is more than this many times its height over that edge is
#: a needle (about a 7 degree smallest angle)
NEEDLE_RATIO = 8.0
#: share of the area in needles above which ``remesh="auto"`` remeshes the input
NEEDLE_SHARE = 0.1
#: fewest faces of the remesh: the default layout's cells need hundreds of faces each, and a
#: CAD program's tessellation may have a few hundred in all
MIN_FACES = 20_000
#: edges of the input turning by more than this share of the crease angle stay edges of the
#: remesh, each on its own: where two solids meet, the turn of their seam changes round it
#: and dips below the crease angle in places, and a seam smoothed over there leaves the
#: remesh far from the input (the layout's creases, chains pruned of dangling ends, would
#: drop such a seam whole)
FEATURE_SHARE = 0.75
#: split, collapse, flip and smoothing rounds of the remesh
ITERATIONS = 10
#: edges of the remesh shorter than this share of its target length are collapsed after it:
#: where two kept feature lines meet at a glancing angle the remesher may not collapse
#: between them and can leave edges a millionth of the target long, at which the layout's
#: cells put two corners on one point (its own collapses stop at 4/5 of the target)
SHORT_EDGE = 0.1
#: an edge shorter than this share of the target length that no collapse can remove (the
#: link condition refuses it: three such edges round a neck where the surface is pinched to
#: a point) makes the remesh unfit to stand in for the input
PINCH_EDGE = 0.01


@dataclass(frozen=True)
class EvenRemesh:
    """An even remesh and how far it is from its input.

    Attributes
    ----------
    mesh : Mesh
        The remesh (same name as the input).
    needle_share : float
        Share of the input's area in needle triangles (`needle_share`).
    distance : float
        Two-sided largest distance between the remesh and the input, over the input's bbox
        diagonal (each side's vertices, edge mid-points and face centroids to the other
        surface).
    """

    mesh: Mesh
    needle_share: float
    distance: float

    def to_dict(self) -> dict:
        return {
            "faces": int(self.mesh.n_faces),
            "vertices": int(self.mesh.n_vertices),
            "needle_share": round(self.needle_share, 4),
            "distance": self.distance,
        }


def needle_share(mesh: Mesh) -> float:
    """Share of the surface's area in needles: triangles whose longest edge is more than
    `NEEDLE_RATIO` times their height over it."""
    nf = mesh.n_faces
    area = np.empty(nf)
    needles = np.empty(nf, dtype=bool)
    for a in range(0, nf, _CHUNK):  # (the corner arrays of a dense scan's every face at once
        b = min(a + _CHUNK, nf)  # would take some 250 bytes per face)
        P = mesh.vertices[mesh.faces[a:b]]
        longest = np.linalg.norm(P[:, [1, 2, 0]] - P, axis=2).max(axis=1)
        area[a:b] = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
        needles[a:b] = longest * longest > NEEDLE_RATIO * 2.0 * np.maximum(
            area[a:b], np.finfo(float).tiny
        )
    total = float(area.sum())
    if total <= 0.0:
        return 0.0
    return float(area[needles].sum() / total)


#: faces per block of `needle_share`
_CHUNK = 1 << 16


def even_remesh(mesh: Mesh, crease_angle: float | None = CREASE_ANGLE) -> EvenRemesh:
    """``mesh`` remeshed into even triangles of about its face count (at least `MIN_FACES`).

    Edges the remesher leaves shorter than `SHORT_EDGE` of its target length are collapsed
    afterwards (`collapse_short_edges`).

    Parameters
    ----------
    mesh : Mesh
        A valid mesh.
    crease_angle : float or None
        Edges turning by more than `FEATURE_SHARE` of this angle
        (:func:`meshfit.layout.regions.sharp_edges`) stay edges of the remesh (split along
        their line, never flipped), so the layout finds the creases again; None: none kept.

    Returns
    -------
    EvenRemesh

    Raises
    ------
    meshfit.errors.MeshfitError
        The remesh is not a valid mesh of the input's topology (Euler characteristic,
        boundary loops and components compared), or it pinches the surface (an edge
        shorter than `PINCH_EDGE` of the target length that no collapse removes: a layout
        would put two corners on one point there), so it cannot stand in for it.
    """
    with warnings.catch_warnings():  # (its package imports deprecated scipy and numpy names)
        warnings.simplefilter("ignore", DeprecationWarning)
        from gpytoolbox import remesh_botsch

    # (writable copies: the bindings take no read-only arrays)
    V = np.array(mesh.vertices, dtype=np.float64, order="C")
    F = np.array(mesh.faces, dtype=np.int32, order="C")
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    # equilateral triangles of that total area and count
    count = max(mesh.n_faces, MIN_FACES)
    h = float(np.sqrt(4.0 * area.sum() / (np.sqrt(3.0) * count)))
    crease = None if crease_angle is None else sharp_edges(mesh, FEATURE_SHARE * crease_angle)
    features = None
    if crease is not None and crease.any():
        features = np.array(mesh.edges[crease], dtype=np.int32, order="C")
    U, G = remesh_botsch(
        V, F, i=ITERATIONS, h=h, project=True, feature=np.zeros(0, dtype=np.int32),
        feature_edges=features,
    )  # fmt: skip
    try:
        out = Mesh(np.asarray(U, dtype=np.float64), np.asarray(G, dtype=np.int64), name=mesh.name)
        out = collapse_short_edges(out, SHORT_EDGE * h, crease_angle)
    except MeshfitError as exc:
        raise MeshfitError(f"the even remesh is not a valid mesh ({exc})") from None
    _refuse_pinches(out, PINCH_EDGE * h)
    _same_topology(mesh, out)
    return EvenRemesh(out, needle_share(mesh), _distance(mesh, out))


def collapse_short_edges(
    mesh: Mesh, length: float, crease_angle: float | None = CREASE_ANGLE
) -> Mesh:
    """``mesh`` with its interior edges shorter than ``length`` collapsed, shortest first.

    A half-edge collapse ``v -> u`` (``u`` stays where it is, so the surface moves by less
    than ``length``) keeps the vertex on more feature edges (edges turning by more than
    `FEATURE_SHARE` of ``crease_angle``), and is made only under the link condition (``u``
    and ``v`` share exactly the two vertices opposite their edge, so the topology is kept),
    when both opposite vertices keep three neighbours and no surviving face turns its
    normal by a right angle or more; otherwise the other direction is tried, then the edge
    is left. Edges with an end on the boundary are left (the boundary is the input's).
    Meant for the few edges a remesher leaves far below its target length: each collapse
    is checked in Python, so the cost grows with the number of short edges.

    Parameters
    ----------
    mesh : Mesh
        A valid manifold mesh.
    length : float
        Edges shorter than this (model units, finite, >= 0) are collapsed where they can be.
    crease_angle : float or None
        Degrees, as for `even_remesh`; None: every vertex counts as on no feature edge.

    Returns
    -------
    Mesh
        ``mesh`` itself when no edge is that short; else a new mesh (same name) whose
        vertices are a subset of ``mesh``'s, unmoved, renumbered in their order.

    Raises
    ------
    meshfit.errors.InputError
        ``length`` negative or not finite.

    References
    ----------
    .. [1] Hoppe, "Progressive meshes", SIGGRAPH 1996 (half-edge collapses); Dey,
       Edelsbrunner, Guha & Nekhayev, "Topology preserving edge contraction", 1999 (the
       link condition).
    """
    if not (np.isfinite(length) and length >= 0.0):
        raise InputError(f"length must be a finite distance >= 0, got {length}")
    el = mesh.edge_lengths
    short = np.flatnonzero(el < length)
    if short.size == 0:
        return mesh
    E = mesh.edges
    V = mesh.vertices
    F = np.array(mesh.faces, dtype=np.int64)
    nv = mesh.n_vertices
    rim = np.zeros(nv, dtype=bool)
    rim[E[mesh.edge_face_count == 1].reshape(-1)] = True
    degree = np.zeros(nv, dtype=np.int64)
    if crease_angle is not None:
        sharp = sharp_edges(mesh, FEATURE_SHARE * crease_angle)
        np.add.at(degree, E[sharp].reshape(-1), 1)
    indptr, vf = mesh.vertex_faces
    star = {}  # the faces around each vertex a collapse touched (others: the mesh's stars)

    def faces_of(v: int) -> set:
        if v not in star:
            star[v] = set(vf[indptr[v] : indptr[v + 1]].tolist())
        return star[v]

    def ring(v: int) -> set:
        return set(F[list(faces_of(v))].reshape(-1).tolist()) - {v}

    alive = np.ones(F.shape[0], dtype=bool)
    gone = np.zeros(nv, dtype=bool)
    for e in short[np.argsort(el[short], kind="stable")]:
        a, b = (int(x) for x in E[e])
        if gone[a] or gone[b] or rim[a] or rim[b]:
            continue
        order = ((b, a), (a, b)) if degree[a] >= degree[b] else ((a, b), (b, a))
        for v, u in order:  # collapse v into u
            if _collapse(F, V, alive, faces_of, ring, v, u):
                gone[v] = True
                break
    keep = np.zeros(nv, dtype=bool)
    keep[F[alive].reshape(-1)] = True
    new_id = np.cumsum(keep) - 1
    return Mesh(V[keep], new_id[F[alive]], name=mesh.name)


def _collapse(F, V, alive, faces_of, ring, v: int, u: int) -> bool:
    """Collapse ``v`` into ``u`` in ``F`` (in place) if the link condition holds, both
    opposite vertices keep three neighbours and no face around ``v`` that survives turns
    its normal by a right angle or more; whether it was made."""
    rv, ru = ring(v), ring(u)
    if u not in rv:
        return False
    common = rv & ru
    if len(common) != 2 or any(len(ring(o)) <= 3 for o in common):
        return False
    fv = faces_of(v)
    both = [f for f in fv if u in F[f]]
    moved = [f for f in fv if u not in F[f]]
    for f in moved:
        p = V[F[f]]
        q = np.where((F[f] == v)[:, None], V[u], p)
        n0 = np.cross(p[1] - p[0], p[2] - p[0])
        n1 = np.cross(q[1] - q[0], q[2] - q[0])
        if float(n0 @ n1) <= 0.0:
            return False
    for f in both:
        alive[f] = False
        for w in F[f].tolist():
            faces_of(w).discard(f)
    for f in moved:
        F[f][F[f] == v] = u
        faces_of(u).add(f)
    fv.clear()
    return True


def _refuse_pinches(mesh: Mesh, length: float) -> None:
    """MeshfitError naming the shortest interior edge of ``mesh`` when it is shorter than
    ``length`` (after `collapse_short_edges`, such an edge is a pinch of the surface; the
    boundary is the input's own, short edges and all)."""
    el = np.where(mesh.edge_face_count == 2, mesh.edge_lengths, np.inf)
    e = int(np.argmin(el))
    if el[e] < length:
        at = ", ".join(f"{x:.6g}" for x in mesh.vertices[mesh.edges[e]].mean(axis=0))
        n = int((el < length).sum())
        raise MeshfitError(
            f"the remesh pinches the surface at ({at}): {n} edge(s) shorter than "
            f"{length:.3g} that no collapse removes without changing the topology (the "
            f"shortest {el[e]:.3g})"
        )


def _same_topology(a: Mesh, b: Mesh) -> None:
    """MeshfitError unless ``b`` has ``a``'s Euler characteristic, boundary loops and
    components."""

    def shape(m: Mesh) -> tuple[int, int, int]:
        return m.euler_characteristic, len(m.boundary_loops), m.n_components

    if shape(a) != shape(b):
        raise MeshfitError(
            "the even remesh changed the surface's topology (Euler characteristic, boundary "
            f"loops, components: {shape(a)} -> {shape(b)})"
        )


def _distance(a: Mesh, b: Mesh) -> float:
    """Largest distance from either mesh to the other surface, over ``a``'s bbox diagonal:
    measured from each one's vertices, edge mid-points and face centroids (a chord of the
    remesh across a curved face is farthest from the input between its ends)."""

    def samples(m: Mesh) -> np.ndarray:
        mids = m.vertices[m.edges].mean(axis=1)
        return np.vstack([m.vertices, mids, m.vertices[m.faces].mean(axis=1)])

    d_ab = float(b.closest_points(samples(a)).distance.max())
    d_ba = float(a.closest_points(samples(b)).distance.max())
    return max(d_ab, d_ba) / float(a.bbox_diagonal)
