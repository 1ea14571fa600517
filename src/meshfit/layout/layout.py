"""The patch layout: corners, boundary curves between corners, four-sided patches, features."""

from __future__ import annotations

import hashlib
import threading
import weakref
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import tol
from meshfit.errors import LayoutError
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints, readonly

__all__ = ["Layout", "layout_from_curves", "mesh_fingerprint"]


#: fingerprints already computed, per mesh object (its arrays are read-only)
_FINGERPRINTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_FINGERPRINTS_LOCK = threading.Lock()


def mesh_fingerprint(mesh: Mesh) -> str:
    """SHA-256 (hex) of a mesh's vertex and face arrays and their counts (kept per mesh
    object: hashing a large mesh again on every call would cost more than the lookup).

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    str
        64 hex digits; equal for meshes with bit-identical ``vertices (nv, 3) float64`` and
        ``faces (nf, 3) int64`` arrays.
    """
    with _FINGERPRINTS_LOCK:
        hit = _FINGERPRINTS.get(mesh)
    if hit is not None:
        return hit
    h = hashlib.sha256()
    h.update(f"meshfit-mesh:{mesh.n_vertices}:{mesh.n_faces}:".encode())
    h.update(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype="<i8").tobytes())
    digest = h.hexdigest()
    with _FINGERPRINTS_LOCK:
        _FINGERPRINTS[mesh] = digest
    return digest


@dataclass(frozen=True, eq=False)
class Layout:
    """A network of four-sided patches painted on a mesh.

    Attributes
    ----------
    corners : SurfacePoints
        ``nc`` corner points of the mesh.
    curves : tuple of SurfaceCurve
        ``nk`` open boundary curves (``kind="boundary"``); curve ``i`` runs from corner
        ``curve_ends[i, 0]`` to corner ``curve_ends[i, 1]``, its first and last points at those
        corners.
    curve_ends : (nk, 2) int64
        Start and end corner of each curve.
    patch_curves : (np, 4) int64
        The four boundary curves of each patch, side 0 to side 3.
    patch_reversed : (np, 4) bool
        Whether side ``s`` of a patch runs along its curve backwards (from ``curve_ends[c, 1]``
        to ``curve_ends[c, 0]``). Side ``s`` runs from patch corner ``s`` to ``s + 1``, the
        corners counter-clockwise seen from the side the face normals point to (the
        :class:`meshfit.layout.Patch` convention), so the patch lies on the left of each side.
    features : tuple of tuple of SurfaceCurve
        Per patch, its feature curves (``kind="feature"``) as face points of the mesh, each from
        a point of one side to a point of the opposite side.
    fingerprint : str
        :func:`mesh_fingerprint` of the mesh the layout was made for.
    creases : (nk,) bool
        Which curves run along a sharp crease of the mesh (default none): the fit keeps
        them C0 where its continuity is ``auto`` (the surface is meant to break there).

    Notes
    -----
    Equality (``==``) compares every array exactly. Construction checks only the structure
    (shapes, index ranges, sides joining end to end); :func:`check_layout` checks a layout
    against its mesh and :func:`meshfit.layout.extract_patches` its topology.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 and fig. 1.2 (boundary curves painted between corners
       bound four-sided polygonal patches), sec. 5.10 (feature curves), sec. 8.1.3 (patches
       share boundary curves and corners).
    """

    corners: SurfacePoints
    curves: tuple[SurfaceCurve, ...]
    curve_ends: NDArray[np.int64]
    patch_curves: NDArray[np.int64]
    patch_reversed: NDArray[np.bool_]
    features: tuple[tuple[SurfaceCurve, ...], ...]
    fingerprint: str
    creases: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        curves = tuple(self.curves)
        creases = (
            np.zeros(len(curves), dtype=bool)
            if self.creases is None
            else np.asarray(self.creases, dtype=bool).reshape(-1)
        )
        if creases.shape != (len(curves),):
            raise LayoutError(f"creases has {creases.size} entries for {len(curves)} curves")
        object.__setattr__(self, "creases", readonly(creases))
        ends = np.asarray(self.curve_ends, dtype=np.int64).reshape(-1, 2)
        pc = np.asarray(self.patch_curves, dtype=np.int64)
        pr = np.asarray(self.patch_reversed, dtype=bool)
        if ends.shape[0] != len(curves):
            raise LayoutError(f"curve_ends has {ends.shape[0]} rows for {len(curves)} curves")
        if pc.ndim != 2 or pc.shape[1:] != (4,):
            n = pc.shape[1] if pc.ndim == 2 else pc.size
            raise LayoutError(f"every patch needs exactly 4 sides, got {n}")
        if pr.shape != pc.shape:
            raise LayoutError(f"patch_reversed has shape {pr.shape}, patch_curves {pc.shape}")
        features = tuple(tuple(f) for f in self.features)
        if len(features) != pc.shape[0]:
            raise LayoutError(f"features has {len(features)} entries for {pc.shape[0]} patches")
        nc, nk = len(self.corners), len(curves)
        if pc.shape[0] and not nk:
            raise LayoutError(f"{pc.shape[0]} patches but no curves: every side is a curve")
        if nk and not nc:
            raise LayoutError(f"{nk} curves but no corners: every curve runs corner to corner")
        _check_curves(curves, ends, nc)
        for p in range(pc.shape[0]):
            _check_patch_sides(p, pc, pr, ends, nk)
        object.__setattr__(self, "curves", curves)
        object.__setattr__(self, "curve_ends", readonly(ends))
        object.__setattr__(self, "patch_curves", readonly(pc))
        object.__setattr__(self, "patch_reversed", readonly(pr))
        object.__setattr__(self, "features", features)

    @property
    def n_patches(self) -> int:
        return int(self.patch_curves.shape[0])

    def patch_sides(self, patch: int) -> list[tuple[int, bool]]:
        """A patch's four sides as ``(curve, reversed)`` pairs, side 0 first: the form
        :func:`layout_from_curves` takes.

        Parameters
        ----------
        patch : int
            Patch index, ``0 <= patch < n_patches``.

        Returns
        -------
        list of four (int, bool)
            Curve index and whether side ``s`` runs along it backwards (``patch_curves`` and
            ``patch_reversed`` of the patch as Python values).

        References
        ----------
        .. [1] Krishnamurthy 2000, sec. 1.3, fig. 1.2 (four-sided patches bounded by curves).
        """
        return [
            (int(self.patch_curves[patch, s]), bool(self.patch_reversed[patch, s]))
            for s in range(4)
        ]

    def patch_corners(self, patch: int) -> NDArray[np.int64]:
        """(4,) int64: layout corner ids of a patch's corners 0..3."""
        return np.asarray(
            [
                _side_corners(
                    self.curve_ends, self.patch_curves[patch, s], self.patch_reversed[patch, s]
                )[0]
                for s in range(4)
            ],
            dtype=np.int64,
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Layout):
            return NotImplemented
        return (
            self.fingerprint == other.fingerprint
            and _points_equal(self.corners, other.corners)
            and len(self.curves) == len(other.curves)
            and all(_curve_equal(a, b) for a, b in zip(self.curves, other.curves, strict=True))
            and np.array_equal(self.curve_ends, other.curve_ends)
            and np.array_equal(self.patch_curves, other.patch_curves)
            and np.array_equal(self.patch_reversed, other.patch_reversed)
            and np.array_equal(self.creases, other.creases)
            and len(self.features) == len(other.features)
            and all(
                len(fa) == len(fb) and all(_curve_equal(a, b) for a, b in zip(fa, fb, strict=True))
                for fa, fb in zip(self.features, other.features, strict=True)
            )
        )

    __hash__ = None  # type: ignore[assignment]


def _side_corners(ends: NDArray[np.int64], c, rev) -> tuple[int, int]:
    a, b = int(ends[int(c), 0]), int(ends[int(c), 1])
    return (b, a) if rev else (a, b)


def _check_curves(curves: tuple[SurfaceCurve, ...], ends: NDArray[np.int64], nc: int) -> None:
    """Every boundary curve is open, has two points or more and joins two different corners
    of the ``nc``."""
    for i, c in enumerate(curves):
        if c.closed:
            raise LayoutError(f"curve {i} is closed: boundary curves run corner to corner")
        if len(c) < 2:
            raise LayoutError(f"curve {i} has {len(c)} point(s), needs at least 2")
        a, b = int(ends[i, 0]), int(ends[i, 1])
        if not (0 <= a < nc and 0 <= b < nc):
            raise LayoutError(f"curve {i}: corner index out of range 0..{nc - 1}: [{a}, {b}]")
        if a == b:
            raise LayoutError(f"curve {i} starts and ends at the same corner {a}")


def _check_patch_sides(
    p: int, pc: NDArray[np.int64], pr: NDArray[np.bool_], ends: NDArray[np.int64], nk: int
) -> None:
    """Patch ``p``'s four sides are four different curves of the ``nk``, each ending at the
    corner where the next one starts."""
    for s in range(4):
        c = int(pc[p, s])
        if not 0 <= c < nk:
            raise LayoutError(f"patch {p} side {s}: curve index {c} out of range 0..{nk - 1}")
    if len(set(pc[p].tolist())) != 4:
        raise LayoutError(f"patch {p} uses a curve twice: {pc[p].tolist()}")
    for s in range(4):
        here = _side_corners(ends, pc[p, s], pr[p, s])
        nxt = _side_corners(ends, pc[p, (s + 1) % 4], pr[p, (s + 1) % 4])
        if here[1] != nxt[0]:
            raise LayoutError(
                f"patch {p}: side {s} (curve {int(pc[p, s])}) ends at corner {here[1]} but "
                f"side {(s + 1) % 4} (curve {int(pc[p, (s + 1) % 4])}) starts at corner "
                f"{nxt[0]}: sides must join end to end"
            )


def _points_equal(a: SurfacePoints, b: SurfacePoints) -> bool:
    return np.array_equal(a.face, b.face) and np.array_equal(a.bary, b.bary)


def _curve_equal(a: SurfaceCurve, b: SurfaceCurve) -> bool:
    return a.closed == b.closed and a.kind == b.kind and _points_equal(a.points, b.points)


def check_layout(mesh: Mesh, layout: Layout) -> None:
    """Check a layout's points against its mesh (no cutting).

    Checks the fingerprint, face indices and barycentric coordinates of every point, and that
    every curve starts and ends at its corners (within ``tol.LAYOUT_CORNER_MATCH`` mean edge
    lengths).

    Raises
    ------
    meshfit.errors.LayoutError
        Naming the corner, curve or patch at fault.
    """
    fp = mesh_fingerprint(mesh)
    if layout.fingerprint != fp:
        raise LayoutError(
            f"the layout was made for another mesh: fingerprint {layout.fingerprint[:12]}... "
            f"but {mesh.name or 'the mesh'} has {fp[:12]}... ({mesh.n_vertices} vertices, "
            f"{mesh.n_faces} faces)"
        )
    _check_points(mesh, layout.corners, "corner")
    for i, c in enumerate(layout.curves):
        _check_points(mesh, c.points, f"curve {i} point")
    for p, fs in enumerate(layout.features):
        for j, c in enumerate(fs):
            _check_points(mesh, c.points, f"patch {p} feature {j} point")
    corner_xyz = mesh.xyz(layout.corners)
    near = tol.length(mesh, tol.LAYOUT_CORNER_MATCH)
    for i, c in enumerate(layout.curves):
        ends = mesh.xyz(c.points[[0, len(c) - 1]])
        for k, which in ((0, "start"), (1, "end")):
            corner = int(layout.curve_ends[i, k])
            d = float(np.linalg.norm(ends[k] - corner_xyz[corner]))
            if d > near:
                raise LayoutError(
                    f"curve {i}: its {which} is {d:.3g} away from corner {corner} "
                    f"(must be within {near:.3g})"
                )


def _check_points(mesh: Mesh, pts: SurfacePoints, what: str) -> None:
    face, bary = pts.face, pts.bary
    bad = np.flatnonzero((face < 0) | (face >= mesh.n_faces))
    if bad.size:
        k = int(bad[0])
        raise LayoutError(
            f"{what} {k}: face index {int(face[k])} out of range 0..{mesh.n_faces - 1}"
        )
    s = bary.sum(axis=1)
    bad = np.flatnonzero(
        (np.abs(s - 1.0) > tol.LAYOUT_BARY_SUM) | (bary < -tol.LAYOUT_BARY_SUM).any(axis=1)
    )
    if bad.size:
        k = int(bad[0])
        raise LayoutError(
            f"{what} {k}: barycentric coordinates {bary[k].tolist()} are not a point of the "
            f"face (sum {s[k]:.15g}, must be 1 with none negative)"
        )


def _clean(pts: SurfacePoints) -> SurfacePoints:
    b = np.clip(pts.bary, 0.0, None)
    return SurfacePoints(pts.face, b / b.sum(axis=1, keepdims=True))


def layout_from_curves(
    mesh: Mesh,
    corners: SurfacePoints,
    curves: list[SurfaceCurve | SurfacePoints],
    curve_ends: ArrayLike,
    patches: list[list[tuple[int, bool]]] | ArrayLike,
    features: list[list[SurfaceCurve | SurfacePoints]] | None = None,
    *,
    snap_ends: bool = True,
    creases: ArrayLike | None = None,
) -> Layout:
    """Build a layout of ``mesh`` from painted curves.

    Parameters
    ----------
    mesh : Mesh
    corners : SurfacePoints
        ``nc`` corners.
    curves : list of SurfaceCurve or SurfacePoints
        ``nk`` open boundary curves, curve ``i`` from corner ``curve_ends[i][0]`` to corner
        ``curve_ends[i][1]``.
    curve_ends : (nk, 2) int64
    patches : list of four (curve, reversed) pairs per patch
        The sides of each patch in order, counter-clockwise seen from outside (the patch on
        the left of each side).
    features : list of lists of SurfaceCurve, optional
        Feature curves of each patch (default none).
    snap_ends : bool, keyword-only
        Replace each curve's first and last point by its corners exactly (default True).
    creases : (nk,) bool, keyword-only, optional
        Curves that run along sharp creases (:attr:`Layout.creases`; default none).

    Returns
    -------
    Layout
        With the fingerprint of ``mesh``; checked with :func:`check_layout`.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3, fig. 1.2; sec. 5.10.1 (specifying feature curves).
    """
    corners = _clean(corners)
    ends = np.asarray(curve_ends, dtype=np.int64).reshape(-1, 2)
    out_curves = []
    for i, c in enumerate(curves):
        pts = c.points if isinstance(c, SurfaceCurve) else c
        pts = _clean(pts)
        if snap_ends and len(pts) >= 2 and ends.shape[0] > i:
            face = pts.face.copy()
            bary = pts.bary.copy()
            for k, pos in ((0, 0), (1, len(pts) - 1)):
                cid = int(ends[i, k])
                if 0 <= cid < len(corners):
                    face[pos] = corners.face[cid]
                    bary[pos] = corners.bary[cid]
            pts = SurfacePoints(face, bary)
        out_curves.append(SurfaceCurve(pts, closed=False, kind="boundary"))
    pc, pr = _patch_arrays(patches)
    feats = []
    for p in range(pc.shape[0]):
        fs = features[p] if features is not None and p < len(features) else []
        feats.append(
            tuple(
                SurfaceCurve(_clean(f.points if isinstance(f, SurfaceCurve) else f), kind="feature")
                for f in fs
            )
        )
    layout = Layout(
        corners,
        tuple(out_curves),
        ends,
        pc,
        pr,
        tuple(feats),
        mesh_fingerprint(mesh),
        None if creases is None else np.asarray(creases, dtype=bool),
    )
    check_layout(mesh, layout)
    return layout


def _patch_arrays(patches) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    rows_c, rows_r = [], []
    for p, sides in enumerate(patches):
        sides = list(sides)
        if len(sides) != 4:
            raise LayoutError(f"patch {p} has {len(sides)} sides, needs exactly 4")
        rows_c.append([int(s[0]) for s in sides])
        rows_r.append([bool(s[1]) for s in sides])
    return (
        np.asarray(rows_c, dtype=np.int64).reshape(-1, 4),
        np.asarray(rows_r, dtype=bool).reshape(-1, 4),
    )
