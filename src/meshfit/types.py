"""Small value types shared by every stage: points on a mesh surface and surface curves."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit.errors import InputError

__all__ = ["CONTINUITIES", "Side", "SurfaceCurve", "SurfacePoints", "readonly"]

#: continuity across a shared boundary: positions only, or positions and tangent planes
CONTINUITIES = ("C0", "G1")


class Side(StrEnum):
    """A side of a patch's parameter square, named by the parameter held fixed on it.

    ``U0`` is ``u = 0`` (row ``A[0, :]`` of a grid or control net), ``U1`` is ``u = 1``
    (``A[-1, :]``), ``V0`` is ``v = 0`` (``A[:, 0]``), ``V1`` is ``v = 1`` (``A[:, -1]``).
    The members are strings (``Side.U0 == "u0"``), so files and JSON keep the plain names.
    A layout names a patch's sides by their order around it (side ``s`` runs from corner
    ``s`` to corner ``s + 1``); :meth:`around` converts.
    """

    U0 = "u0"
    U1 = "u1"
    V0 = "v0"
    V1 = "v1"

    @classmethod
    def around(cls, s: int) -> Side:
        """The side that is side ``s`` (0..3) in a layout's order around the patch: the
        grid's corners ``(0, 0), (-1, 0), (-1, -1), (0, -1)`` are layout corners 0..3, so
        sides 0..3 are ``v0, u1, v1, u0`` (sides 2 and 3 run against their parameter)."""
        return _AROUND[s]

    @property
    def direction(self) -> int:
        """Index of the parameter running along this side: 1 (v) on u0/u1, 0 (u) on v0/v1."""
        return 1 if self.value[0] == "u" else 0

    def row(self, a: NDArray, depth: int = 0) -> NDArray:
        """Row ``depth`` in from this side of an ``(n, m, ...)`` array, in increasing
        parameter order: a view, so it can be assigned to (``depth=0`` is the boundary row,
        ``depth=1`` the row of tangent control points)."""
        d = int(depth)
        if self is Side.U0:
            return a[d, :]
        if self is Side.U1:
            return a[-1 - d, :]
        if self is Side.V0:
            return a[:, d]
        return a[:, -1 - d]


_AROUND = (Side.V0, Side.U1, Side.V1, Side.U0)


def readonly(a: NDArray) -> NDArray:
    """``a`` as a contiguous read-only array: itself when it already is one, else a copy
    whose view cannot be made writeable again."""
    a = np.ascontiguousarray(a)
    if a.flags.writeable:
        a = a.copy()
        a.flags.writeable = False
        a = a.view()  # a view of a read-only base cannot be made writeable again
    return a


@dataclass(frozen=True, eq=False)
class SurfacePoints:
    """Points on a triangle mesh as (face, barycentric coordinates): a struct of arrays.

    Parameters
    ----------
    face : (n,) int64
        Face index of each point.
    bary : (n, 3) float64
        Barycentric coordinates with respect to ``faces[face]``; each row sums to 1.

    Notes
    -----
    Face points are the thesis' representation of surface curves and spring meshes: a point
    constrained to a facet of the polygonal surface (Krishnamurthy 2000, sec. 3.1).
    Evaluate positions with ``mesh.xyz(points)``.
    """

    face: NDArray[np.int64]
    bary: NDArray[np.float64]

    def __post_init__(self) -> None:
        face = np.asarray(self.face)
        bary = np.asarray(self.bary, dtype=np.float64)
        if face.ndim != 1 or not (face.size == 0 or np.issubdtype(face.dtype, np.integer)):
            raise InputError(
                f"SurfacePoints.face must be a 1-d integer array, got {face.dtype} "
                f"with shape {face.shape}"
            )
        if bary.shape != (face.shape[0], 3):
            raise InputError(
                f"SurfacePoints.bary must have shape ({face.shape[0]}, 3), got {bary.shape}"
            )
        if not np.isfinite(bary).all():
            bad = int(np.flatnonzero(~np.isfinite(bary).all(axis=1))[0])
            raise InputError(f"SurfacePoints.bary is not finite at point {bad}")
        object.__setattr__(self, "face", readonly(face.astype(np.int64, copy=False)))
        object.__setattr__(self, "bary", readonly(bary))

    @classmethod
    def owned(cls, face: NDArray[np.int64], bary: NDArray[np.float64]) -> SurfacePoints:
        """Points from arrays the caller hands over and keeps no use of.

        The arrays are made read-only in place, without the constructor's shape checks and
        copies (for hot internal paths, e.g. arrays fresh from a kernel).

        Parameters
        ----------
        face : (n,) int64
            Contiguous face indices.
        bary : (n, 3) float64
            Contiguous barycentric coordinates; they must be finite.

        Returns
        -------
        SurfacePoints
            Sharing the two arrays' memory.

        Raises
        ------
        meshfit.errors.InputError
            A coordinate that is not finite (naming the first such point).

        References
        ----------
        .. [1] Krishnamurthy 2000, sec. 3.1 (face points).
        """
        if not np.isfinite(bary).all():
            bad = int(np.flatnonzero(~np.isfinite(bary).all(axis=1))[0])
            raise InputError(f"SurfacePoints.bary is not finite at point {bad}")
        obj = object.__new__(cls)
        for name, a in (("face", face), ("bary", bary)):
            a.flags.writeable = False
            object.__setattr__(obj, name, a.view())
        return obj

    def __len__(self) -> int:
        return int(self.face.shape[0])

    def __getitem__(self, index) -> SurfacePoints:
        """Subset of the points (an integer index keeps a length-1 result)."""
        if isinstance(index, (int, np.integer)):
            i, n = int(index), len(self)
            if not -n <= i < n:
                raise IndexError(f"index {i} is out of range for {n} surface points")
            index = slice(i % n, i % n + 1)
        face, bary = self.face[index], self.bary[index]
        if face.ndim == 1 and face.flags.c_contiguous and bary.flags.c_contiguous:
            # fresh arrays, or views of this one's read-only ones: no copies needed
            return SurfacePoints.owned(face, bary)
        return SurfacePoints(face, bary)

    @classmethod
    def at_vertices(cls, faces: ArrayLike, vertices: ArrayLike) -> SurfacePoints:
        """Face points sitting exactly on mesh vertices.

        Parameters
        ----------
        faces : (nf, 3) int64
            The mesh's faces.
        vertices : (n,) int64
            Vertex indices; each must be referenced by some face.
        """
        faces = np.asarray(faces)
        vertices = np.asarray(vertices, dtype=np.int64).reshape(-1)
        nv = int(faces.max()) + 1 if faces.size else 0
        corner_face = np.full(max(nv, 1), -1, dtype=np.int64)
        corner_slot = np.zeros(max(nv, 1), dtype=np.int64)
        flat = faces.reshape(-1)
        corner_face[flat[::-1]] = np.arange(flat.size)[::-1] // 3
        corner_slot[flat[::-1]] = np.arange(flat.size)[::-1] % 3
        if vertices.size and (
            vertices.min() < 0 or vertices.max() >= nv or (corner_face[vertices] < 0).any()
        ):
            bad = vertices[(vertices < 0) | (vertices >= nv)]
            if bad.size == 0:
                bad = vertices[corner_face[vertices] < 0]
            raise InputError(f"vertex {int(bad[0])} is not referenced by any face")
        bary = np.zeros((vertices.size, 3))
        bary[np.arange(vertices.size), corner_slot[vertices]] = 1.0
        return cls(corner_face[vertices], bary)

    @classmethod
    def concatenate(cls, parts: list[SurfacePoints]) -> SurfacePoints:
        """Join several point sets in order."""
        if not parts:
            return cls(np.zeros(0, np.int64), np.zeros((0, 3)))
        return cls.owned(  # fresh arrays of valid points
            np.concatenate([p.face for p in parts]), np.concatenate([p.bary for p in parts])
        )


@dataclass(frozen=True, eq=False)
class SurfaceCurve:
    """An ordered sequence of face points: a curve on the surface (thesis sec. 3.1).

    Parameters
    ----------
    points : SurfacePoints
        The curve's samples in order. Consecutive points should lie on the same or on
        adjacent faces (the thesis' sampling rule).
    closed : bool
        Whether the last point connects back to the first.
    kind : {"boundary", "feature"}
        Patch boundary or feature curve.
    """

    points: SurfacePoints
    closed: bool = False
    kind: Literal["boundary", "feature"] = "boundary"

    def __post_init__(self) -> None:
        if self.kind not in ("boundary", "feature"):
            raise InputError(
                f"SurfaceCurve.kind must be 'boundary' or 'feature', got {self.kind!r}"
            )

    def __len__(self) -> int:
        return len(self.points)
