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
from numpy.typing import ArrayLike, NDArray

from meshfit.errors import InputError, MeshfitError
from meshfit.layout.regions import CREASE_ANGLE, sharp_edges
from meshfit.mesh import Mesh, find_problems, topology
from meshfit.mesh.validate import area2_limit, degenerate_faces, raise_first

__all__ = [
    "EvenRemesh",
    "collapse_short_edges",
    "even_remesh",
    "mend_degenerate_faces",
    "needle_share",
]

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
#: rounds of `mend_degenerate_faces`, each mending what it can of the degenerate faces the
#: round before left (a collapse may leave a neighbour degenerate, a cap beside a degenerate
#: face waits for it to be mended); a round that mends nothing ends it earlier
MEND_ROUNDS = 8


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
    `NEEDLE_RATIO` times their height over it (one parallel pass over the faces,
    :func:`meshfit._kernels.geometry.needle_areas`)."""
    from meshfit._kernels import frozen
    from meshfit._kernels.geometry import needle_areas

    V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    total, needles = needle_areas(*frozen(V, F), NEEDLE_RATIO)
    if total <= 0.0:
        return 0.0
    return float(needles / total)


def even_remesh(mesh: Mesh, crease_angle: float | None = CREASE_ANGLE) -> EvenRemesh:
    """``mesh`` remeshed into even triangles of about its face count (at least `MIN_FACES`).

    The remesher projects its vertices onto the input and may leave a few faces of zero
    area there (two vertices on one point, or one on the edge across from it): those are
    mended first (`mend_degenerate_faces`), as a mesh cannot hold them. Edges it leaves
    shorter than `SHORT_EDGE` of its target length are then collapsed
    (`collapse_short_edges`). A remesh with no degenerate face is not touched by the mend.

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
        boundary loops and components compared; degenerate faces no collapse or flip mends
        count as invalid), or it pinches the surface (an edge
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
        U, G = mend_degenerate_faces(
            np.asarray(U, dtype=np.float64), np.asarray(G, dtype=np.int64), SHORT_EDGE * h,
            crease_angle,
        )  # fmt: skip
        out = Mesh(U, G, name=mesh.name)
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
    _check_length(length)
    el = mesh.edge_lengths
    short = np.flatnonzero(el < length)
    if short.size == 0:
        return mesh
    E = mesh.edges
    rim = np.zeros(mesh.n_vertices, dtype=bool)
    rim[E[mesh.edge_face_count == 1].reshape(-1)] = True
    degree = np.zeros(mesh.n_vertices, dtype=np.int64)
    if crease_angle is not None:
        sharp = sharp_edges(mesh, FEATURE_SHARE * crease_angle)
        np.add.at(degree, E[sharp].reshape(-1), 1)
    edit = _Edit(mesh.vertices, mesh.faces, mesh.vertex_faces, flat=-np.inf)
    for e in short[np.argsort(el[short], kind="stable")]:
        a, b = (int(x) for x in E[e])
        if not (edit.gone[a] or edit.gone[b] or rim[a] or rim[b]):
            edit.collapse_edge(a, b, degree)
    return Mesh(*edit.arrays(), name=mesh.name)


def mend_degenerate_faces(
    vertices: ArrayLike,
    faces: ArrayLike,
    length: float,
    crease_angle: float | None = CREASE_ANGLE,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A triangle list's degenerate faces mended by edge collapses and flips, topology kept.

    A face is degenerate by the mesh validator's own test (a repeated index, or an area at
    most `meshfit.tol.DEGENERATE_AREA` times the squared bbox diagonal): a remesher that
    projects its vertices onto a surface leaves such faces where two vertices land on one
    point or one lands on the edge across from it, and a `Mesh` cannot hold them. Each is
    mended the standard way, a few rounds at most (`MEND_ROUNDS`):

    - a needle, its shortest edge shorter than ``length`` (zero when two corners are one
      point), is collapsed as in `collapse_short_edges`: a half-edge collapse under the
      link condition, keeping the end on the boundary if one is (an edge with both ends on
      it is left), else the end on more feature edges; its moved faces of nonzero area may
      not turn their normals by a right angle or more;
    - else, or when no such collapse is allowed, a cap (its third corner on its longest
      edge) has that edge flipped: made only when the edge is interior, the new edge is not
      an edge already, and both new faces have nonzero area and the normal of the face
      across. Such a flip moves no point of the surface (the two new faces tile the face
      across) and the flipped edge's line stays covered by the cap's two other edges, so a
      crease along it stays edges. Two caps back to back (all four corners on one line)
      are flipped onto their shorter diagonal, which leaves two caps that each have a
      face of area across their longest edge.

    Parameters
    ----------
    vertices : (nv, 3) float64
        Vertex positions, model units.
    faces : (nf, 3) int64
        Consistently oriented triangles with indices in ``[0, nv)``, every edge on one or
        two of them (what a remesher gives, degenerate faces and all).
    length : float
        A degenerate face's shortest edge is collapsed when shorter than this (model units,
        finite, >= 0).
    crease_angle : float or None
        Degrees, as for `even_remesh`: a collapse keeps the end on more edges turning by
        more than `FEATURE_SHARE` of it (between faces of nonzero area); None: no feature
        edges.

    Returns
    -------
    vertices : (nv2, 3) float64
    faces : (nf2, 3) int64
        ``vertices`` and ``faces`` themselves (as float64 and int64) when no face is
        degenerate; else the mended list, whose vertices are a subset of ``vertices``,
        unmoved, renumbered in their order, and which has the same Euler characteristic,
        boundary and components.

    Raises
    ------
    meshfit.errors.InputError
        ``length`` negative or not finite, or ``faces`` not ``(nf, 3)`` indices into
        ``vertices``.
    meshfit.errors.MeshValidationError
        ``faces`` has degenerate faces and an edge on more than two of them.
    meshfit.errors.MeshfitError
        Degenerate faces that no collapse or flip mends (named with their count and the
        first one, as the validator would).

    References
    ----------
    .. [1] Botsch & Kobbelt, "A remeshing approach to multiresolution modeling", SGP 2004
       (the remesher, its collapses and flips); Hoppe, "Progressive meshes", SIGGRAPH 1996
       (half-edge collapses); Dey, Edelsbrunner, Guha & Nekhayev, "Topology preserving edge
       contraction", 1999 (the link condition).
    """
    _check_length(length)
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f"vertices must have shape (n, 3), got {V.shape}")
    vf = topology.vertex_faces(F, V.shape[0])  # (checks the indices)
    used = V[np.unique(F)]
    # the validator's limit on the squared cross product, for the bbox of the used vertices:
    # a mend only drops vertices, so the mended list's bbox, and limit, are no larger
    diag = float(np.linalg.norm(used.max(axis=0) - used.min(axis=0))) if used.size else 0.0
    flat = area2_limit(diag)
    bad = np.flatnonzero(degenerate_faces(V, F, flat))
    if bad.size == 0:
        return V, F
    table = topology.edge_table(F, V.shape[0])
    if (table.edge_count > 2).any():
        raise_first(find_problems(V, F))
    rim = np.zeros(V.shape[0], dtype=bool)
    rim[table.edges[table.edge_count == 1].reshape(-1)] = True
    degree = _feature_degree(V, F, table, flat, crease_angle)
    edit = _Edit(V, F, vf, flat=flat)
    for _ in range(MEND_ROUNDS):
        if not any([edit.mend(int(f), length, rim, degree) for f in bad]):
            break  # (nothing changed: ``bad`` is still the list's)
        live = np.flatnonzero(edit.alive)
        bad = live[degenerate_faces(V, edit.F[live], flat)]
        if bad.size == 0:
            break
    if bad.size:
        f = int(bad[0])
        raise MeshfitError(
            f"{bad.size} degenerate face(s) (zero area or repeated vertex) that no collapse "
            f"or flip mends (first: face {f} of the list, now {edit.F[f].tolist()})"
        )
    return edit.arrays()


def _check_length(length: float) -> None:
    if not (np.isfinite(length) and length >= 0.0):
        raise InputError(f"length must be a finite distance >= 0, got {length}")


def _feature_degree(V, F, table, flat: float, crease_angle: float | None) -> NDArray[np.int64]:
    """Per vertex, how many of its interior edges turn by more than `FEATURE_SHARE` of
    ``crease_angle`` between two faces whose squared cross products exceed ``flat`` (as
    :func:`meshfit.layout.regions.sharp_edges` on a mesh; a face of no area has no normal)."""
    degree = np.zeros(V.shape[0], dtype=np.int64)
    if crease_angle is None:
        return degree
    p = V[F]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    norm2 = np.einsum("ij,ij->i", cross, cross)
    ok = norm2 > flat
    n = cross / np.sqrt(np.where(ok, norm2, 1.0))[:, None]
    two = np.flatnonzero(table.edge_count == 2)
    fa = table.order[table.start[two]] // 3
    fb = table.order[table.start[two] + 1] // 3
    limit = np.cos(np.radians(FEATURE_SHARE * crease_angle))
    sharp = ok[fa] & ok[fb] & (np.einsum("ij,ij->i", n[fa], n[fb]) < limit)
    np.add.at(degree, table.edges[two[sharp]].reshape(-1), 1)
    return degree


class _Edit:
    """A triangle list edited in place by half-edge collapses and edge flips; the faces
    around each vertex an edit touched are kept as sets (the others: the list's own CSR).

    Faces whose squared cross product is at most ``flat`` have no normal a collapse must
    keep (-inf: every face has one)."""

    def __init__(self, V: NDArray, F: NDArray, vertex_faces: tuple, *, flat: float) -> None:
        self.V = V
        self.F = np.array(F, dtype=np.int64)
        self.alive = np.ones(self.F.shape[0], dtype=bool)
        self.gone = np.zeros(V.shape[0], dtype=bool)
        self.flat = flat
        self._indptr, self._vf = vertex_faces
        self._star: dict[int, set[int]] = {}

    def faces_of(self, v: int) -> set[int]:
        if v not in self._star:
            self._star[v] = set(self._vf[self._indptr[v] : self._indptr[v + 1]].tolist())
        return self._star[v]

    def ring(self, v: int) -> set[int]:
        return set(self.F[list(self.faces_of(v))].reshape(-1).tolist()) - {v}

    def arrays(self) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """The surviving faces and the vertices on them, renumbered in their order."""
        keep = np.zeros(self.V.shape[0], dtype=bool)
        keep[self.F[self.alive].reshape(-1)] = True
        new_id = np.cumsum(keep) - 1
        return self.V[keep], new_id[self.F[self.alive]]

    def collapse_edge(
        self, a: int, b: int, degree: NDArray[np.int64], rim: NDArray[np.bool_] | None = None
    ) -> bool:
        """Collapse edge ``a b`` into the end on more feature edges (``degree``), else the
        other way; only into the end on the boundary when one is (``rim``); whether it was
        made."""
        order: tuple[tuple[int, int], ...] = (
            ((b, a), (a, b)) if degree[a] >= degree[b] else ((a, b), (b, a))
        )
        if rim is not None and (rim[a] or rim[b]):
            order = ((b, a),) if rim[a] else ((a, b),)
        for v, u in order:  # collapse v into u
            if self.collapse(v, u):
                self.gone[v] = True
                return True
        return False

    def collapse(self, v: int, u: int) -> bool:
        """Collapse ``v`` into ``u`` if the link condition holds, both opposite vertices keep
        three neighbours and no face around ``v`` that survives turns its normal (if it has
        one) by a right angle or more; whether it was made."""
        F, V = self.F, self.V
        rv, ru = self.ring(v), self.ring(u)
        if u not in rv:
            return False
        common = rv & ru
        if len(common) != 2 or any(len(self.ring(o)) <= 3 for o in common):
            return False
        fv = self.faces_of(v)
        both = [f for f in fv if u in F[f]]
        moved = [f for f in fv if u not in F[f]]
        for f in moved:
            p = V[F[f]]
            q = np.where((F[f] == v)[:, None], V[u], p)
            n0 = np.cross(p[1] - p[0], p[2] - p[0])
            n1 = np.cross(q[1] - q[0], q[2] - q[0])
            if float(n0 @ n0) > self.flat and float(n0 @ n1) <= 0.0:
                return False
        for f in both:
            self.alive[f] = False
            for w in F[f].tolist():
                self.faces_of(w).discard(f)
        for f in moved:
            F[f][F[f] == v] = u
            self.faces_of(u).add(f)
        fv.clear()
        return True

    def flip(self, f: int, k: int) -> bool:
        """Flip edge ``k`` of face ``f`` if it is interior, the new edge is not an edge
        already and both new faces have nonzero area and the normal of the face across (or,
        when that face has no area either, the new edge is the shorter); whether it was
        made."""
        F, V = self.F, self.V
        p, q, m = (int(F[f, (k + j) % 3]) for j in range(3))
        across = (self.faces_of(p) & self.faces_of(q)) - {f}
        if len(across) != 1:
            return False
        (g,) = across
        j = [int(x) for x in F[g]].index(q)
        if int(F[g, (j + 1) % 3]) != p:  # (not the other way round: a fold)
            return False
        x = int(F[g, (j + 2) % 3])
        if x == m or x in self.ring(m):
            return False
        normal = np.cross(V[p] - V[q], V[x] - V[q])
        new = ((p, x, m), (x, q, m))  # the quad p x q m split along x m
        if float(normal @ normal) <= self.flat:
            # two caps back to back, all four corners on one line: the flip moves the pair
            # onto the shorter diagonal, whose new caps each have a face of area across
            # their longest edge (the edge shortens, so no flip is undone)
            if np.linalg.norm(V[x] - V[m]) >= np.linalg.norm(V[p] - V[q]):
                return False
        else:
            for a, b, c in new:
                n = np.cross(V[b] - V[a], V[c] - V[a])
                if not (float(n @ n) > self.flat and float(n @ normal) > 0.0):
                    return False
        F[f], F[g] = new
        self.faces_of(p).discard(g)
        self.faces_of(q).discard(f)
        self.faces_of(m).add(g)
        self.faces_of(x).add(f)
        return True

    def mend(self, f: int, length: float, rim: NDArray[np.bool_], degree: NDArray) -> bool:
        """Collapse the shortest edge of face ``f`` if shorter than ``length`` and not both
        ends on the boundary (the one on it stays), else flip its longest edge (see
        `mend_degenerate_faces`); whether either was made (none when ``f`` is gone or no
        longer degenerate)."""
        if not self.alive[f] or not degenerate_faces(self.V, self.F[f : f + 1], self.flat)[0]:
            return False
        c = self.F[f]
        if len(set(c.tolist())) < 3:
            return False  # (no edges to collapse or flip)
        p = self.V[c]
        el = np.linalg.norm(p[[1, 2, 0]] - p, axis=1)  # edge k: c[k] -> c[k + 1]
        k = int(np.argmin(el))
        a, b = int(c[k]), int(c[(k + 1) % 3])
        if el[k] < length and not (rim[a] and rim[b]) and self.collapse_edge(a, b, degree, rim):
            return True
        return self.flip(f, int(np.argmax(el)))


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
