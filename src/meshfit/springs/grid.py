"""The spring mesh: a regular grid of face points on one patch."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit._kernels import springs as _k
from meshfit.types import SurfacePoints, readonly

__all__ = ["ANCHOR", "BOUNDARY", "CURVE", "FREE", "SpringMesh", "grid_triangles"]

#: spring point kinds (``SpringMesh.kind``): never moved (on a side of the patch)
BOUNDARY = np.uint8(_k.BOUNDARY)
#: never moved: the crossing of a u and a v feature curve (sec. 5.11.1)
ANCHOR = np.uint8(_k.ANCHOR)
#: moves only along its feature curve (sec. 5.11.1, eq. 5.14-5.17)
CURVE = np.uint8(_k.CURVE)
#: moves freely on the patch (sec. 5.5)
FREE = np.uint8(_k.FREE)


@dataclass(frozen=True, eq=False)
class SpringMesh:
    """A spring mesh: an ``(nu, nv)`` grid of face points on a patch's submesh.

    Attributes
    ----------
    points : SurfacePoints
        ``nu * nv`` face points of ``Patch.mesh``, row-major: grid point ``(i, j)`` is entry
        ``i * nv + j``. ``(0, 0)`` is corner 0, ``(nu - 1, 0)`` corner 1, ``(nu - 1, nv - 1)``
        corner 2 and ``(0, nv - 1)`` corner 3 (the `meshfit.layout.Patch` convention).
    kind : (nu, nv) uint8
        BOUNDARY, ANCHOR, CURVE or FREE per grid point.
    level : int
        Subdivision level: level ``k`` has ``2**k`` times the intervals of level 0.
    patch : int
        Index of the patch in its layout.
    xyz : (nu, nv, 3) float64
        Positions of the grid points, model units.
    u_lines, v_lines : (a,) int64, (b,) int64
        Grid columns ``i`` (constant u) and rows ``j`` (constant v) that follow a feature
        curve, in order; they split the grid into sections (sec. 5.10.3).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.3 (spring mesh), sec. 5.11.1 (anchors, curve points).
    """

    points: SurfacePoints
    kind: NDArray[np.uint8]
    level: int
    patch: int
    xyz: NDArray[np.float64]
    u_lines: NDArray[np.int64]
    v_lines: NDArray[np.int64]

    def __post_init__(self) -> None:
        for name in ("kind", "xyz", "u_lines", "v_lines"):
            object.__setattr__(self, name, readonly(np.asarray(getattr(self, name))))

    @property
    def shape(self) -> tuple[int, int]:
        """(nu, nv): grid points along u and along v."""
        return int(self.kind.shape[0]), int(self.kind.shape[1])

    @property
    def n_points(self) -> int:
        return int(self.kind.size)

    def triangles(self) -> NDArray[np.int64]:
        """(2 (nu - 1) (nv - 1), 3) int64 triangles of the grid (see :func:`grid_triangles`)."""
        return grid_triangles(*self.shape)


def grid_triangles(
    nu: int, nv: int, *, base: int = 0, out: NDArray[np.int64] | None = None
) -> NDArray[np.int64]:
    """Triangulate an ``(nu, nv)`` row-major grid, two triangles per cell.

    Each cell ``(i, j)`` splits along its ``(i, j)``-``(i + 1, j + 1)`` diagonal into
    ``(i, j), (i + 1, j), (i + 1, j + 1)`` and ``(i, j), (i + 1, j + 1), (i, j + 1)``: counter-
    clockwise in ``(u, v)``, so the normals agree with the patch's face normals. All first
    triangles come before all second ones.

    Parameters
    ----------
    nu, nv : int
        Grid shape.
    base : int, keyword-only
        Added to every index (the grid's first point in a soup of several grids).
    out : (2 (nu - 1) (nv - 1), 3) int64, keyword-only, optional
        Written in place and returned (a soup of many grids fills one array, with no
        per-grid copies); default: a new array.

    Returns
    -------
    (2 (nu - 1) (nv - 1), 3) int64
    """
    c = (nu - 1) * (nv - 1)
    if out is None:
        out = np.empty((2 * c, 3), dtype=np.int64)
    elif out.shape != (2 * c, 3):
        raise ValueError(f"out has shape {out.shape}, the grid's triangles {(2 * c, 3)}")
    a = (base + nv * np.arange(nu - 1, dtype=np.int64)[:, None] + np.arange(nv - 1)).ravel()
    first, second = out[:c], out[c:]
    first[:, 0] = a
    np.add(a, nv, out=first[:, 1])
    np.add(a, nv + 1, out=first[:, 2])
    second[:, 0] = a
    second[:, 1] = first[:, 2]
    np.add(a, 1, out=second[:, 2])
    return out


def dilate_grid(mask: NDArray[np.bool_], reach: int) -> NDArray[np.bool_]:
    """(a, b) bool: the grid points within ``reach`` steps along rows and columns of a point
    of ``mask`` (a, b) (``scipy.ndimage.binary_dilation`` with its default cross-shaped
    structure, ``reach`` iterations, nothing outside the grid); a new array."""
    out = np.array(mask, dtype=bool)
    if out.ndim != 2:
        raise ValueError(f"dilate_grid needs a 2-d mask, got shape {out.shape}")
    for _ in range(int(reach)):
        if not out.any():
            break
        grown = out.copy()
        grown[1:] |= out[:-1]
        grown[:-1] |= out[1:]
        grown[:, 1:] |= out[:, :-1]
        grown[:, :-1] |= out[:, 1:]
        out = grown
    return out
