"""Patch networks: which sides of which patches are shared, and consistent control counts."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from meshfit import tol
from meshfit._unionfind import DisjointSets
from meshfit.errors import InputError
from meshfit.types import Side

__all__ = [
    "SIDES",
    "ControlClasses",
    "Network",
    "SharedBoundary",
    "control_classes",
    "direction_classes",
    "network_from_grids",
    "side_row",
    "texel_shapes",
]

#: sides of a grid or control net (:class:`meshfit.types.Side`), each listed in increasing
#: parameter order: "u0" = A[0, :], "u1" = A[-1, :], "v0" = A[:, 0], "v1" = A[:, -1]
SIDES = tuple(Side)


def side_row(a: NDArray, side: str, depth: int = 0) -> NDArray:
    """Row ``depth`` in from ``side`` of an ``(n, m, ...)`` array, in increasing parameter order.

    ``depth=0`` is the boundary row itself, ``depth=1`` the row of tangent control points.
    Returns a view.
    """
    if side not in SIDES:
        raise InputError(f"side must be one of {', '.join(SIDES)}, got {side!r}")
    return Side(side).row(a, depth)


def _direction(side: str) -> int:
    """Index of the parameter running along a side: 1 (v) for u0/u1, 0 (u) for v0/v1."""
    return 1 if side[0] == "u" else 0


@dataclass(frozen=True)
class SharedBoundary:
    """Side ``side_a`` of patch ``a`` is side ``side_b`` of patch ``b``.

    Attributes
    ----------
    a, b : int
        Patch indices, ``a < b``.
    side_a, side_b : str
        One of ``SIDES``.
    reversed : bool
        True when the two sides run in opposite parameter directions.
    continuity : {"G1", "C0"}
        What :func:`meshfit.stitch.stitch_surfaces` enforces here (default G1).
    """

    a: int
    side_a: str
    b: int
    side_b: str
    reversed: bool
    continuity: str = "G1"


@dataclass(frozen=True)
class Network:
    """Patches and their shared boundaries.

    Attributes
    ----------
    n_patches : int
    boundaries : tuple of SharedBoundary
    corners : tuple of tuple of (int, int, int)
        Each network corner as the (patch, i_end, j_end) corner slots meeting there, with
        ``i_end, j_end`` in {0, -1} (the corner ``P[i_end, j_end]`` of that patch).
    """

    n_patches: int
    boundaries: tuple[SharedBoundary, ...]
    corners: tuple[tuple[tuple[int, int, int], ...], ...]

    def with_continuity(self, choice: str | Mapping[int, str]) -> Network:
        """The same network with continuity set everywhere or per boundary index."""
        bs = list(self.boundaries)
        for k, b in enumerate(bs):
            c = choice if isinstance(choice, str) else choice.get(k, b.continuity)
            if c not in ("C0", "G1"):
                raise InputError(f"continuity must be 'C0' or 'G1', got {c!r} (boundary {k})")
            bs[k] = SharedBoundary(b.a, b.side_a, b.b, b.side_b, b.reversed, c)
        return Network(self.n_patches, tuple(bs), self.corners)


_CORNER_OF_SIDE = {  # the (i_end, j_end) corners at the start and end of each side
    "u0": ((0, 0), (0, -1)),
    "u1": ((-1, 0), (-1, -1)),
    "v0": ((0, 0), (-1, 0)),
    "v1": ((0, -1), (-1, -1)),
}


def network_from_grids(grids: Sequence[NDArray], *, continuity: str = "G1") -> Network:
    """Find the shared boundaries of patch grids from where their sides meet.

    Parameters
    ----------
    grids : sequence of (nu_k, nv_k, 3) float64
        One grid per patch (spring meshes, or any gridded samples), oriented consistently.
    continuity : {"G1", "C0"}
        Continuity to enforce on every shared boundary (change per boundary with
        :meth:`Network.with_continuity`).

    Returns
    -------
    Network

    Notes
    -----
    Two sides are shared when their end points coincide (either way round) within
    ``tol.STITCH_MATCH`` of the bbox diagonal and their middle samples are close (closer than
    a tenth of the side's length), so sides of different resolutions match. Corners are the
    classes of coincident grid corners.
    """
    if continuity not in ("C0", "G1"):
        raise InputError(f"continuity must be 'C0' or 'G1', got {continuity!r}")
    grids = [np.asarray(g, dtype=np.float64) for g in grids]
    for k, g in enumerate(grids):
        if g.ndim != 3 or g.shape[2] != 3 or min(g.shape[:2]) < 2:
            raise InputError(f"grids[{k}] must have shape (nu, nv, 3), got {g.shape}")
    allp = np.concatenate([g.reshape(-1, 3) for g in grids])
    eps = tol.STITCH_MATCH * float(np.linalg.norm(np.ptp(allp, axis=0)))
    sides = []
    for k, g in enumerate(grids):
        for s in SIDES:
            row = side_row(g, s)
            length = float(np.linalg.norm(np.diff(row, axis=0), axis=1).sum())
            mid = _point_at_half_length(row)
            sides.append((k, s, row[0], row[-1], mid, length))
    starts = np.array([x[2] for x in sides])
    tree_start = cKDTree(starts)
    boundaries = []
    used: set[tuple[int, str]] = set()
    for x in range(len(sides)):
        ka, sa, a0, a1, am, la = sides[x]
        # sides starting where this one starts (same direction) or ends (reversed)
        cand = set(tree_start.query_ball_point(a0, eps)) | set(tree_start.query_ball_point(a1, eps))
        for y in sorted(c for c in cand if c > x):
            kb, sb, b0, b1, bm, lb = sides[y]
            if kb == ka:
                continue
            same = np.linalg.norm(a0 - b0) <= eps and np.linalg.norm(a1 - b1) <= eps
            rev = np.linalg.norm(a0 - b1) <= eps and np.linalg.norm(a1 - b0) <= eps
            if not (same or rev) or np.linalg.norm(am - bm) > 0.1 * max(la, lb):
                continue
            for key in ((ka, sa), (kb, sb)):
                if key in used:
                    raise InputError(
                        f"side {key[1]} of patch {key[0]} matches more than one other side"
                    )
            used |= {(ka, sa), (kb, sb)}
            boundaries.append(SharedBoundary(ka, sa, kb, sb, bool(rev and not same), continuity))
    # corners: classes of coincident grid corners
    slots = [(k, i, j) for k in range(len(grids)) for i in (0, -1) for j in (0, -1)]
    pos = np.array([grids[k][i, j] for k, i, j in slots])
    label = -np.ones(len(slots), dtype=np.int64)
    tree = cKDTree(pos)
    n_corners = 0
    for s_ in range(len(slots)):
        if label[s_] >= 0:
            continue
        close = np.array(tree.query_ball_point(pos[s_], eps), dtype=np.int64)
        close = close[label[close] < 0]
        label[close] = n_corners
        n_corners += 1
    corners = tuple(tuple(slots[s_] for s_ in np.flatnonzero(label == c)) for c in range(n_corners))
    return Network(len(grids), tuple(boundaries), corners)


def _point_at_half_length(row: NDArray) -> NDArray:
    seg = np.linalg.norm(np.diff(row, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    half = 0.5 * cum[-1]
    k = int(np.clip(np.searchsorted(cum, half) - 1, 0, len(seg) - 1))
    f = 0.0 if seg[k] == 0 else (half - cum[k]) / seg[k]
    return row[k] + f * (row[k + 1] - row[k])


@dataclass(frozen=True)
class ControlClasses:
    """Equal-count classes of patch directions and the control resolution they give.

    Attributes
    ----------
    labels : (n_patches, 2) int64
        Class of each patch's u and v direction.
    counts : (n_classes,) int64
        Control count of each class.
    controls : list of (int, int)
        ``(mu, mv)`` per patch.
    """

    labels: NDArray[np.int64]
    counts: NDArray[np.int64]
    controls: list[tuple[int, int]]


def direction_classes(network: Network) -> NDArray[np.int64]:
    """Equal-count classes of patch directions: ``(n_patches, 2)`` labels ``0 .. n_classes - 1``.

    Opposite sides of a patch run along the same direction (its u or v); a shared boundary
    joins the two directions that run along it. Classes are the connected components of
    these links (union-find), numbered in order of first appearance (patch 0's u direction
    is class 0). Any per-direction count that must agree across shared boundaries (control
    points, texels) is one count per class.

    Parameters
    ----------
    network : Network

    Returns
    -------
    (n_patches, 2) int64
        Class of each patch's u and v direction.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 8.1.3 (consistent control counts across a network).
    """
    n = network.n_patches
    sets = DisjointSets(2 * n)
    for b in network.boundaries:
        sets.union(2 * b.a + _direction(b.side_a), 2 * b.b + _direction(b.side_b))
    return np.array(sets.labels(), dtype=np.int64).reshape(n, 2)


#: matched shapes may take at most this many times the texels of the shapes they match: a
#: class takes its largest member's count, so where rows of patches differ much in length
#: (thin strips beside wide patches) matching multiplies texels, and the memory and time of
#: everything after, for no detail the scan has
MATCH_BUDGET = 8


def texel_shapes(
    network: Network, shapes: Sequence[tuple[int, int]], *, budget: float | None = None
) -> list[tuple[int, int]]:
    """Map resolutions with equal texel counts along every shared boundary.

    Each class of :func:`direction_classes` takes the largest count of its members, so no
    map loses resolution. With ``budget``, where that would take more than ``budget`` times
    the texels of ``shapes``, every class's count is capped at the largest count that keeps
    the total within it: the longest rows get fewer texels than their members had (a mesh
    tessellated at these shapes is coarser there than the maps), the counts stay equal.

    Parameters
    ----------
    network : Network
    shapes : sequence of (int, int)
        Texel counts ``(h, w)`` of each patch's map, at least 2 x 2.
    budget : float, keyword-only, optional
        At least 1 (e.g. `MATCH_BUDGET`); default None: no cap.

    Returns
    -------
    list of (int, int)
        ``(h, w)`` per patch, equal along every shared boundary.

    Raises
    ------
    meshfit.errors.InputError
        Not one shape per patch, or a shape below 2 x 2.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 8.2 (displacement seams), with the count classes of
       sec. 8.1.3.
    """
    shp = np.asarray(shapes, dtype=np.int64).reshape(-1, 2)
    if len(shp) != network.n_patches:
        raise InputError(f"{len(shp)} shapes for a network of {network.n_patches} patches")
    if (shp < 2).any():
        raise InputError("a map needs at least 2 x 2 texels")
    labels = direction_classes(network)
    best = np.zeros(int(labels.max()) + 1 if len(labels) else 0, dtype=np.int64)
    np.maximum.at(best, labels.ravel(), shp.ravel())
    if budget is not None and len(labels):
        if not budget >= 1:
            raise InputError(f"budget must be at least 1, got {budget}")
        allowed = budget * float((shp[:, 0] * shp[:, 1]).sum())

        def total(cap: int) -> float:
            c = np.minimum(best, cap)
            return float((c[labels[:, 0]] * c[labels[:, 1]]).sum())

        lo, hi = 2, int(best.max())  # total(2) = 4 per patch, within any budget >= 1
        while lo < hi:  # the largest cap within the budget (total grows with the cap)
            mid = (lo + hi + 1) // 2
            lo, hi = (mid, hi) if total(mid) <= allowed else (lo, mid - 1)
        best = np.minimum(best, lo)
    return [(int(best[a]), int(best[b])) for a, b in labels]


def control_classes(
    network: Network,
    *,
    default: int | Sequence[tuple[int, int]] = 8,
    counts: Mapping[int, int] | None = None,
    grid_shapes: Sequence[tuple[int, int]] | None = None,
) -> ControlClasses:
    """Consistent control counts over a network (Krishnamurthy 2000, sec. 8.1.3).

    Opposite sides of a patch share a count (the patch's mu or mv); a shared boundary makes
    the counts along it equal on both patches. The classes of patch directions linked this
    way are solved by union-find; each class gets ``counts[class]`` if given, else the
    largest requested count of its members (``default``: one count for all, or a requested
    ``(mu, mv)`` per patch), capped by the smallest grid size of the class when
    ``grid_shapes`` is given.

    Returns
    -------
    ControlClasses
    """
    n = network.n_patches
    labels = direction_classes(network)
    n_classes = int(labels.max()) + 1 if n else 0
    if isinstance(default, int):
        req = np.full((n, 2), default, dtype=np.int64)
    else:
        req = np.asarray(default, dtype=np.int64)
        if req.shape != (n, 2):
            raise InputError(f"default must be one count or ({n}, 2) counts, got {req.shape}")
    cls = np.zeros(n_classes, dtype=np.int64)
    for c in range(n_classes):
        cls[c] = req[labels == c].max()
    for c, v in (counts or {}).items():
        if not 0 <= int(c) < n_classes:
            raise InputError(f"class {c} does not exist (the network has {n_classes})")
        cls[int(c)] = int(v)
    if grid_shapes is not None:
        shp = np.asarray(grid_shapes, dtype=np.int64)
        for c in range(n_classes):
            cls[c] = min(cls[c], int(shp[labels == c].min()))
    if (cls < 4).any():
        c = int(np.flatnonzero(cls < 4)[0])
        raise InputError(f"class {c} has {cls[c]} control points; a cubic patch needs 4")
    controls = [(int(cls[labels[k, 0]]), int(cls[labels[k, 1]])) for k in range(n)]
    return ControlClasses(labels, cls, controls)
