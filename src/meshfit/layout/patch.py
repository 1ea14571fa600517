"""A four-sided patch cut out of a mesh: the input of the spring mesh."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints, readonly

__all__ = [
    "BULGY",
    "REFLEX",
    "TAPERED",
    "Patch",
    "bulge_notes",
    "corner_notes",
    "loop_bulge",
    "patch_notes",
    "shape_figures",
    "sides_taper",
    "taper_notes",
    "thin_notes",
]

#: a patch whose :attr:`Patch.bulge` exceeds this bulges far beyond its boundary (a flat
#: disk has 1.27, a hemisphere 2.55): a tensor-product grid anchored on its sides crowds
#: at the boundary and misses the bulge (a patch of a projected cube's face that wraps over
#: a neck and shoulders, for one)
BULGY = 3.0

#: a patch whose :attr:`Patch.bulge` is below this is a sliver, two of its corners near 0
#: degrees: the grid across it folds (thin strips along a protrusion in a fine automatic
#: layout); well-formed patches stay several times above it
THIN = 0.05


#: a patch whose :attr:`Patch.taper` exceeds this has one side much shorter than the side
#: opposite it (a near-triangular patch): its grid's cells change size across it and the
#: spacing along its iso-curves evens out badly (the corner patches of a projected cube
#: where it wraps a narrow end of the model); patches of ordinary layouts stay below it
TAPERED = 4.0


#: a patch whose angle at a corner (:attr:`Patch.corner_angles`) exceeds this many degrees
#: turns back on itself there (a reflex corner, where three patches meet on a curved surface
#: and one takes more than half the turn): the grid cell at that corner cannot be convex,
#: and the spring mesh may squeeze or fold there (a patch's least even grid line can lie at
#: such a corner, and the corner cell can fold in its triangle of three side points, which
#: no repair moves). Not every reflex corner spoils the grid, but corners of ordinary
#: layouts stay well below it.
REFLEX = 180.0


@dataclass(frozen=True, eq=False)
class Patch:
    """One four-sided region of a layout, as a submesh of its own (a topological disk).

    The grid convention every later stage uses: side 0 runs from corner 0 to corner 1 (the
    ``v = 0`` row, ``u`` rising), side 1 from corner 1 to corner 2 (``u = 1``), side 2 from
    corner 2 to corner 3 (``v = 1``, ``u`` falling) and side 3 from corner 3 back to corner 0
    (``u = 0``). The corners run counter-clockwise seen from the side the face normals point
    to, so ``(dS/du) x (dS/dv)`` agrees with the face normals. A grid ``points[i, j]`` of shape
    ``(nu, nv)`` then has ``points[0, 0]`` at corner 0, ``points[-1, 0]`` at corner 1,
    ``points[-1, -1]`` at corner 2 and ``points[0, -1]`` at corner 3.

    Attributes
    ----------
    index : int
        The patch's index in its layout.
    mesh : Mesh
        The patch's faces as a mesh of their own: a disk whose boundary is the four sides.
    corners : (4,) int64
        Vertices of ``mesh`` at the four corners, in order.
    sides : tuple of four (k_s,) int64
        Vertex chains of ``mesh`` along each side, from corner ``s`` to corner ``s + 1``
        (both ends included), following the mesh boundary.
    face_parent : (nf_patch,) int64
        Face of the original (uncut) mesh that each patch face lies in.
    vertex_source : SurfacePoints
        Every patch vertex as a point of the original mesh.
    features : tuple of SurfaceCurve
        Feature curves of this patch as face points of ``mesh`` (``kind="feature"``), each
        running from one side to the opposite side (Krishnamurthy 2000, sec. 5.10).
    feature_sides : tuple of (int, int)
        For each feature curve, the sides its first and last points lie on.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 and fig. 1.2 (patches bounded by painted curves);
       sec. 5.3 (the spring mesh resamples one four-sided patch).
    """

    index: int
    mesh: Mesh
    corners: NDArray[np.int64]
    sides: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]
    face_parent: NDArray[np.int64]
    vertex_source: SurfacePoints
    features: tuple[SurfaceCurve, ...] = ()
    feature_sides: tuple[tuple[int, int], ...] = field(default=())

    def __post_init__(self) -> None:
        corners = np.asarray(self.corners, dtype=np.int64).reshape(-1)
        if corners.shape != (4,):
            raise InputError(f"patch {self.index}: needs 4 corners, got {corners.shape[0]}")
        if len(self.sides) != 4:
            raise InputError(f"patch {self.index}: needs 4 sides, got {len(self.sides)}")
        sides = tuple(readonly(np.asarray(s, dtype=np.int64).reshape(-1)) for s in self.sides)
        for s, chain in enumerate(sides):
            if chain.shape[0] < 2 or chain[0] != corners[s] or chain[-1] != corners[(s + 1) % 4]:
                raise InputError(
                    f"patch {self.index}: side {s} must run from corner {s} "
                    f"(vertex {int(corners[s])}) to corner {(s + 1) % 4} "
                    f"(vertex {int(corners[(s + 1) % 4])})"
                )
        if len(self.feature_sides) != len(self.features):
            raise InputError(
                f"patch {self.index}: {len(self.features)} feature curves but "
                f"{len(self.feature_sides)} feature_sides entries"
            )
        object.__setattr__(self, "corners", readonly(corners))
        object.__setattr__(self, "sides", sides)
        object.__setattr__(
            self, "face_parent", readonly(np.asarray(self.face_parent, dtype=np.int64))
        )

    @cached_property
    def bulge(self) -> float:
        """The patch's area over that of a square with its perimeter: about 1 for a flat,
        square-ish patch (1.27 for a flat disk), 2.55 for a hemisphere, far more for a patch
        that balloons out of a short boundary (`BULGY` and above: split it with more curves).
        """
        return loop_bulge(self.mesh.area, self.mesh.vertices[self.boundary])

    @cached_property
    def taper(self) -> float:
        """The larger of the two ratios of opposite sides' lengths (longer over shorter): 1
        for a rectangle, large where a side shrinks toward a point (`TAPERED` and above:
        move a corner or split the patch)."""
        V = self.mesh.vertices
        return sides_taper(
            [float(np.linalg.norm(np.diff(V[s], axis=0), axis=1).sum()) for s in self.sides]
        )

    @cached_property
    def corner_angles(self) -> NDArray[np.float64]:
        """(4,) float64: the patch's angle at each corner, degrees (the sum of its faces'
        angles there): 90 on a flat square, above `REFLEX` where the boundary turns back on
        itself (move the corner)."""
        V, F = self.mesh.vertices, self.mesh.faces
        indptr, vf = self.mesh.vertex_faces
        out = np.zeros(4)
        for k, c in enumerate(self.corners.tolist()):
            faces = vf[indptr[c] : indptr[c + 1]]
            slot = np.argmax(F[faces] == c, axis=1)
            a = V[F[faces, (slot + 1) % 3]] - V[c]
            b = V[F[faces, (slot + 2) % 3]] - V[c]
            den = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
            cos = np.einsum("ij,ij->i", a, b) / np.where(den > 0, den, 1.0)
            out[k] = float(np.degrees(np.arccos(np.clip(cos[den > 0], -1.0, 1.0))).sum())
        return readonly(out)

    @property
    def boundary(self) -> NDArray[np.int64]:
        """(k,) int64: the closed boundary loop, sides 0..3 joined (each corner once)."""
        return np.concatenate([s[:-1] for s in self.sides])


def loop_bulge(area: float, loop: NDArray[np.float64]) -> float:
    """Area over that of a square whose perimeter is the closed polyline ``loop``.

    Parameters
    ----------
    area : float
        Area of the region the loop bounds, model units squared.
    loop : (k, 3) float64
        The boundary's points in order, the first not repeated at the end.

    Returns
    -------
    float
        1 for a flat square, 1.27 for a flat disk, 2.55 for a hemisphere (see `BULGY`); 0
        for a loop of zero length.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.1 (parametric distortion of a patch's spring mesh).
    """
    X = np.asarray(loop, dtype=np.float64)
    X = np.vstack([X, X[:1]])
    perimeter = float(np.linalg.norm(np.diff(X, axis=0), axis=1).sum())
    return float(area / (perimeter / 4.0) ** 2) if perimeter > 0 else 0.0


def bulge_notes(bulge: dict[int, float]) -> list[str]:
    """The warning of a fit or a layout check about bulging patches.

    Parameters
    ----------
    bulge : dict of int to float
        Patch index -> :attr:`Patch.bulge`.

    Returns
    -------
    list of str
        One note naming the patches above `BULGY`, most bulging first (at most five), with
        what to do; empty when no patch bulges that much.
    """
    return _ranked_note(
        bulge,
        BULGY,
        lambda n, one: (
            f"{n} patch{'' if one else 'es'} bulge{'s' if one else ''} far beyond "
            f"{'its' if one else 'their'} boundary (area over {BULGY:g} times that of a square "
            "with the same perimeter; a hemisphere has 2.55): {patches}: a grid anchored on the "
            "sides crowds at the boundary and misses the bulge; add curves across it"
        ),
    )


def thin_notes(bulge: dict[int, float]) -> list[str]:
    """`bulge_notes` of slivers: one note names the patches whose :attr:`Patch.bulge` is
    below `THIN`, thinnest first (at most five), with what to do (none when there is no
    such patch)."""
    return _ranked_note(
        bulge,
        THIN,
        lambda n, one: (
            f"{n} patch{' is a sliver' if one else 'es are slivers'} (area under "
            f"{THIN:.0%} of that of a square with the same perimeter): {{patches}}: the grid "
            "across a sliver folds; ask for fewer patches, or give a layout file"
        ),
        below=True,
    )


def sides_taper(lengths) -> float:
    """:attr:`Patch.taper` of four side lengths.

    Parameters
    ----------
    lengths : (4,) float
        Side lengths in order around the patch, model units.

    Returns
    -------
    float
        The larger of the two ratios of opposite sides (longer over shorter; 1 for a
        rectangle, inf when a side has zero length).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.1 (parametric distortion of a patch's spring mesh).
    """
    out = 1.0
    for a, b in ((0, 2), (1, 3)):
        lo, hi = sorted((float(lengths[a]), float(lengths[b])))
        out = max(out, hi / lo if lo > 0 else float("inf"))
    return out


def taper_notes(taper: dict[int, float]) -> list[str]:
    """`bulge_notes` of tapered patches: ``taper`` maps patch index -> :attr:`Patch.taper`;
    one note names the patches above `TAPERED`, most tapered first (at most five), with what
    to do (none when no patch tapers that much)."""
    return _ranked_note(
        taper,
        TAPERED,
        lambda n, one: (
            f"{n} patch{'' if one else 'es'} taper{'s' if one else ''}: a side "
            f"over {TAPERED:g} times as long as the side opposite it ({{patches}}): the grid's "
            "cells change size across the patch and its spacing evens out badly; move a corner "
            "or split the patch so that opposite sides match"
        ),
    )


def corner_notes(angles: dict[int, Sequence[float]]) -> list[str]:
    """The warning of a fit or a layout check about reflex corners.

    Parameters
    ----------
    angles : dict of int to sequence of float
        Patch index -> :attr:`Patch.corner_angles` (degrees, corners 0-3).

    Returns
    -------
    list of str
        One note naming the patches with a corner above `REFLEX`, largest angle first (at
        most five, with the corner), with what to do; empty when there is none.
    """
    big = sorted(
        ((p, int(np.argmax(a)), float(np.max(a))) for p, a in angles.items() if max(a) > REFLEX),
        key=lambda t: -t[2],
    )
    if not big:
        return []
    one = len(big) == 1
    named = ", ".join(f"patch {p}: {a:.0f} degrees at corner {c}" for p, c, a in big[:5])
    return [
        f"{len(big)} patch{'' if one else 'es'} turn{'s' if one else ''} back at a corner, "
        f"over {REFLEX:g} degrees inside the patch ({named}): the grid cell there cannot be "
        "convex, and the grid may squeeze or fold at that corner; move the corner so that the "
        "patches meeting there share the turn"
    ]


def _ranked_note(values: dict[int, float], bound: float, text, below: bool = False) -> list[str]:
    """One note naming the patches whose value exceeds ``bound`` (with ``below``: is below
    it), farthest first (at most five, as ``patch i: v``), worded by ``text(count, single)``
    with a ``{patches}`` slot; empty when there is none."""
    sign = -1.0 if below else 1.0
    big = sorted(
        ((p, v) for p, v in values.items() if sign * v > sign * bound), key=lambda kv: -sign * kv[1]
    )
    if not big:
        return []
    named = ", ".join(f"patch {p}: {v:.3g}" for p, v in big[:5])
    return [text(len(big), len(big) == 1).replace("{patches}", named)]


def shape_figures(patch: Patch) -> dict:
    """The figures of a patch's shape that `patch_notes` warns about, rounded for a report.

    Parameters
    ----------
    patch : Patch
        One patch of a layout.

    Returns
    -------
    dict
        ``bulge`` (:attr:`Patch.bulge`, 3 decimals), ``taper`` (:attr:`Patch.taper`, 3
        decimals) and ``corner_angles`` (:attr:`Patch.corner_angles`, a list of four floats in
        degrees, 1 decimal).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.1 (parametric distortion of a patch's spring mesh).
    """
    return {
        "bulge": round(patch.bulge, 3),
        "taper": round(patch.taper, 3),
        "corner_angles": [round(float(a), 1) for a in patch.corner_angles],
    }


def patch_notes(rows: list[dict]) -> list[str]:
    """`bulge_notes`, `thin_notes`, `taper_notes` and `corner_notes` of per-patch rows with a
    ``patch`` key and the `shape_figures` keys (rows without one of those are left out of its
    note)."""

    def of(key: str) -> dict:
        return {r["patch"]: r[key] for r in rows if key in r}

    return (
        bulge_notes(of("bulge"))
        + thin_notes(of("bulge"))
        + taper_notes(of("taper"))
        + corner_notes(of("corner_angles"))
    )
