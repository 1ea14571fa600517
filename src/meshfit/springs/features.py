"""Feature curves as iso-curves of the spring mesh (sec. 5.10-5.11)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit.errors import FeatureCurveError
from meshfit.mesh import Mesh
from meshfit.springs.init import closest_approach, project_on_chain
from meshfit.surface import curve_arc_lengths, move_along_curve
from meshfit.surface import walk as _walk
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["FeatureLine", "Sides", "prepare_features"]


@dataclass
class Sides:
    """The patch's four sides as vertex chains running with the grid index.

    ``bottom`` is side 0 (``v = 0``, u rising), ``right`` side 1 (``u = 1``, v rising),
    ``top`` side 2 reversed (``v = 1``, u rising), ``left`` side 3 reversed (``u = 0``).
    """

    chains: dict[str, NDArray[np.int64]]
    arcs: dict[str, NDArray[np.float64]]
    edge_faces: dict[str, tuple[NDArray, NDArray, NDArray]]


@dataclass
class FeatureLine:
    """One feature curve oriented along the grid: a u feature runs bottom -> top, a v
    feature left -> right."""

    index: int
    curve: SurfaceCurve
    arc: NDArray[np.float64]
    xyz: NDArray[np.float64]
    vertices: NDArray[np.int64]
    pieces: object = None  # the curve's surface pieces, computed once (MovePointOnCurve)

    @property
    def total(self) -> float:
        return float(self.arc[-1])

    def points_at(self, mesh: Mesh, s: NDArray) -> SurfacePoints:
        """Face points at arc-length positions ``s`` along the curve (exactly on its surface
        segments, as :func:`meshfit.surface.move_along_curve` places them)."""
        s = np.clip(np.asarray(s, dtype=np.float64), 0.0, self.total)
        if self.pieces is None:
            return move_along_curve(mesh, self.curve, s, 0.0).points
        face, bary, _ = _walk._place_on_pieces(self.curve.points, False, self.pieces, s)
        return SurfacePoints(face, bary)

    def tangent_at(self, s: NDArray) -> NDArray[np.float64]:
        """(n, 3) unit tangents (direction of rising arc length) at positions ``s``."""
        k = np.clip(np.searchsorted(self.arc, s, side="right") - 1, 0, len(self.arc) - 2)
        d = self.xyz[k + 1] - self.xyz[k]
        n = np.linalg.norm(d, axis=1, keepdims=True)
        return d / np.where(n > 0, n, 1.0)

    def position_of(self, seg: int, t: float) -> float:
        return float(self.arc[seg] + t * (self.arc[seg + 1] - self.arc[seg]))


def _line(mesh: Mesh, index: int, curve: SurfaceCurve, reverse: bool) -> FeatureLine:
    pts = curve.points
    if reverse:
        pts = SurfacePoints(pts.face[::-1].copy(), pts.bary[::-1].copy())
    c = SurfaceCurve(pts, closed=False, kind="feature")
    arc = curve_arc_lengths(mesh, c)
    faces = mesh.faces[pts.face]
    # the pieces move_along_curve builds on every call, kept for the relaxation's many calls
    pieces = _walk._curve_pieces(mesh, pts, False, f"feature curve {index}")
    return FeatureLine(index, c, arc, mesh.xyz(pts), np.unique(faces), pieces)


def prepare_features(
    mesh: Mesh, sides: Sides, features, feature_sides, patch_index: int
) -> tuple[
    list[FeatureLine], list[FeatureLine], list[float], list[float], list[float], list[float]
]:
    """Orient, check and order a patch's feature curves.

    Returns the u features (bottom -> top) ordered by where they leave the bottom side, the
    v features (left -> right) ordered along the left side, and the arc-length positions of
    their ends on the bottom, top, left and right sides.

    Raises
    ------
    FeatureCurveError
        A feature curve does not run from one side to the opposite side, does not start and
        end on those sides, or two feature curves of one direction cross (or touch) each
        other.
    """
    if not len(features):
        return [], [], [], [], [], []
    eps = tol.length(mesh, tol.FEATURE_END_ON_SIDE)
    us, vs = [], []
    for k, (curve, (a, b)) in enumerate(zip(features, feature_sides, strict=True)):
        where = f"patch {patch_index}, feature curve {k}"
        if {a, b} == {0, 2}:
            line = _line(mesh, k, curve, reverse=(a == 2))
            lo, hi = "bottom", "top"
            us.append(line)
        elif {a, b} == {1, 3}:
            line = _line(mesh, k, curve, reverse=(a == 1))
            lo, hi = "left", "right"
            vs.append(line)
        else:
            raise FeatureCurveError(
                f"{where}: runs from side {a} to side {b}; a feature curve must run from one "
                "side to the opposite side (0 to 2 or 1 to 3)"
            )
        for end, name in ((0, lo), (-1, hi)):
            _, dist = project_on_chain(mesh, sides.chains[name], sides.arcs[name], line.xyz[end])
            if dist > eps:
                raise FeatureCurveError(
                    f"{where}: its {'first' if end == 0 else 'last'} point is {dist:.3g} away "
                    f"from the side it should end on (tolerance {eps:.3g})"
                )
    ends = {}
    for lines, lo, hi in ((us, "bottom", "top"), (vs, "left", "right")):
        a = [project_on_chain(mesh, sides.chains[lo], sides.arcs[lo], ln.xyz[0])[0] for ln in lines]
        b = [
            project_on_chain(mesh, sides.chains[hi], sides.arcs[hi], ln.xyz[-1])[0] for ln in lines
        ]
        order = np.argsort(a, kind="stable")
        lines[:] = [lines[o] for o in order]
        a = [a[o] for o in order]
        b = [b[o] for o in order]
        direction = "u" if lo == "bottom" else "v"
        ends[lo], ends[hi] = a, b
        gap = tol.length(mesh, tol.FEATURE_END_ON_SIDE)
        for m in range(len(lines) - 1):
            p, q = lines[m], lines[m + 1]
            if b[m + 1] <= b[m] + gap or a[m + 1] <= a[m] + gap:
                raise FeatureCurveError(
                    f"patch {patch_index}: {direction} feature curves {p.index} and {q.index} "
                    "cross each other (their ends are in opposite orders on the two sides)"
                )
            *_, dist = closest_approach(p.xyz, q.xyz)
            if dist <= gap:
                raise FeatureCurveError(
                    f"patch {patch_index}: {direction} feature curves {p.index} and {q.index} "
                    "cross or touch each other"
                )
    return us, vs, ends["bottom"], ends["top"], ends["left"], ends["right"]


def intersect_lines(
    mesh: Mesh, a: FeatureLine, b_xyz: NDArray[np.float64], b_vertices: NDArray[np.int64]
) -> tuple[float, int, float, float]:
    """IntersectSurfaceCurves (sec. 5.11.2) of feature curve ``a`` with a polyline ``b``.

    The closest approach of the two linear reconstructions is searched within the
    intersection neighbourhood: the pieces of each curve near the mesh vertices the two
    curves share (all pieces when they share none). Returns the arc-length position on
    ``a``, the segment of ``b`` and the parameter in it, and the distance.
    """
    share = np.intersect1d(a.vertices, b_vertices)
    ia = np.arange(len(a.xyz))
    ib = np.arange(len(b_xyz))
    if share.size:
        fa = mesh.faces[a.curve.points.face]
        near_a = np.flatnonzero(np.isin(fa, share).any(axis=1))
        if near_a.size:
            ia = np.arange(max(near_a.min() - 2, 0), min(near_a.max() + 3, len(a.xyz)))
    pa = a.xyz[ia]
    pb = b_xyz[ib]
    sa, ta, sb, tb, dist = closest_approach(pa, pb)
    seg = int(ia[min(sa, len(ia) - 2)]) if len(ia) > 1 else int(ia[0])
    seg = min(seg, len(a.arc) - 2)
    return a.position_of(seg, ta), int(ib[min(sb, len(ib) - 2)]) if len(ib) > 1 else 0, tb, dist
