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

from meshfit.errors import MeshfitError
from meshfit.layout.regions import CREASE_ANGLE, sharp_edges
from meshfit.mesh import Mesh

__all__ = ["EvenRemesh", "even_remesh", "needle_share"]

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
        boundary loops and components compared), so it cannot stand in for it.
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
    except MeshfitError as exc:
        raise MeshfitError(f"the even remesh is not a valid mesh ({exc})") from None
    _same_topology(mesh, out)
    return EvenRemesh(out, needle_share(mesh), _distance(mesh, out))


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
