"""Working state of one patch's spring mesh while it is built (private)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from meshfit._kernels import springs_aux as _aux
from meshfit._kernels.springs import chain_points as _chain_points
from meshfit._kernels.springs import chord_rounds
from meshfit.mesh import Mesh
from meshfit.springs.features import FeatureLine, Sides
from meshfit.springs.grid import ANCHOR, BOUNDARY, CURVE, FREE, SpringMesh
from meshfit.springs.metrics import _section_ends
from meshfit.types import SurfacePoints


def section_positions(breaks: list[float], counts: list[int]) -> NDArray[np.float64]:
    """Arc-length positions of grid points along a side: uniform within each section
    (``np.linspace`` over each section, its start dropped after the first)."""
    return _sections(breaks, counts)[0]


def _sections(breaks, counts) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`section_positions` and which of them end a section."""
    b = np.asarray(breaks, dtype=np.float64)
    c = np.asarray(counts, dtype=np.int64)
    if c.ndim != 1 or b.shape != (c.size + 1,) or (c.size and c.min() < 1):
        raise ValueError("section_positions needs one more break than counts, counts >= 1")
    return _aux.section_positions(b, c)


#: Jacobi rounds that even out the chords between side points (a few per level suffice)
CHORD_ROUNDS = 30
#: sides are resampled at equal chords only while the grid spacing is at least this many
#: times the side's mean edge length; finer, the chords would follow the edges' zigzag
CHORD_MIN_EDGES = 8.0


def chord_positions(
    xyz: NDArray[np.float64],
    arc: NDArray[np.float64],
    breaks: list[float],
    counts: list[int],
    rounds: int = CHORD_ROUNDS,
) -> NDArray[np.float64]:
    """Arc-length positions along a polyline (points ``xyz`` (k, 3) at cumulative lengths
    ``arc``) whose consecutive chords are equal within each section: the arc-length
    positions of :func:`section_positions` moved along the polyline until neighbouring
    chords agree (section ends stay). Where a side bends, equal arc lengths give unequal
    chords, i.e. uneven spacing of the grid's boundary iso-curves."""
    pos, fixed = _sections(breaks, counts)
    if pos.size == len(counts) + 1:  # every position ends a section
        return pos
    chord_rounds(
        np.ascontiguousarray(xyz, dtype=np.float64),
        np.ascontiguousarray(arc, dtype=np.float64),
        pos,
        fixed,
        int(rounds),
    )
    return pos


@dataclass
class State:
    mesh: Mesh
    patch: int
    sides: Sides
    u_feat: list[FeatureLine]
    v_feat: list[FeatureLine]
    breaks: dict[str, list[float]]  # section ends along each side (incl. 0 and the length)
    counts_u: list[int]  # intervals per u section (between u feature columns)
    counts_v: list[int]
    level: int = 0
    face: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    bary: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    s_u: list[NDArray[np.float64]] = field(default_factory=list)  # (nv,) per u feature
    s_v: list[NDArray[np.float64]] = field(default_factory=list)  # (nu,) per v feature
    chords: bool = True  # sides resampled at equal chords (else equal arc lengths)
    _side_cache: dict = field(default_factory=dict)
    _slid: dict = field(default_factory=dict)
    _pinch_tried: dict = field(default_factory=dict)
    _kind_cache: dict = field(default_factory=dict)

    def side_positions(self, name: str) -> NDArray[np.float64]:
        """Arc-length positions of the grid points along side ``name`` at this level."""
        return self._static_positions(name).copy()

    def _static_positions(self, name: str) -> NDArray[np.float64]:
        """:meth:`side_positions` itself, kept for the level (not to be changed)."""
        counts = self.counts_u if name in ("bottom", "top") else self.counts_v
        key = (name, tuple(counts))
        pos = self._side_cache.get(key)
        if pos is None:
            pos = self._side_cache[key] = self._side_positions(name, counts)
        return pos

    def pinch_tried(self) -> set:
        """The (side, place) pairs :func:`meshfit.springs.relax.unpinch_side_points` could not
        improve on this level (a set it updates)."""
        key = (tuple(self.counts_u), tuple(self.counts_v))
        return self._pinch_tried.setdefault(key, set())

    def slid_positions(self, name: str) -> NDArray[np.float64]:
        """Arc-length positions of the grid points along side ``name`` as slid so far on this
        level (:func:`meshfit.springs.relax.slide_side_points`): the array itself, which the
        slides update; the static positions until a point slides."""
        counts = self.counts_u if name in ("bottom", "top") else self.counts_v
        key = (name, tuple(counts))
        if key not in self._slid:
            self._slid[key] = self.side_positions(name)
        return self._slid[key]

    def _side_positions(self, name: str, counts: list[int]) -> NDArray[np.float64]:
        chain = self.sides.chains[name]
        arc = self.sides.arcs[name]
        coarse = arc[-1] / sum(counts) >= CHORD_MIN_EDGES * arc[-1] / max(len(chain) - 1, 1)
        if not (self.chords and coarse):
            return section_positions(self.breaks[name], counts)
        return chord_positions(
            self.mesh.vertices[chain], self.sides.arcs[name], self.breaks[name], counts
        )

    @property
    def on_boundary(self) -> NDArray[np.bool_]:
        """(n_vertices,) bool: vertices of the patch mesh on its boundary."""
        mask = np.zeros(self.mesh.n_vertices, dtype=bool)
        for chain in self.sides.chains.values():
            mask[chain] = True
        return mask

    @property
    def nu(self) -> int:
        return sum(self.counts_u) + 1

    @property
    def nv(self) -> int:
        return sum(self.counts_v) + 1

    @property
    def u_lines(self) -> NDArray[np.int64]:
        return np.array(list(itertools.accumulate(self.counts_u[:-1])), dtype=np.int64)

    @property
    def v_lines(self) -> NDArray[np.int64]:
        return np.array(list(itertools.accumulate(self.counts_v[:-1])), dtype=np.int64)

    def kind(self) -> NDArray[np.uint8]:
        """(nu, nv) uint8: each grid point's kind at this level (a new array each call)."""
        return self._kind()[0].copy()

    def free(self) -> NDArray[np.bool_]:
        """(nu nv,) bool: the FREE grid points at this level, row-major (a new array each
        call)."""
        return self._kind()[1].copy()

    def _kind(self) -> tuple[NDArray[np.uint8], NDArray[np.bool_], NDArray, NDArray]:
        """The level's kinds (nu, nv), flat FREE mask (nu nv,) and section ends along u and
        v (:func:`meshfit.springs.metrics._section_ends`), kept (not to be changed)."""
        key = (tuple(self.counts_u), tuple(self.counts_v))
        hit = self._kind_cache.get(key)
        if hit is None:
            k = np.full((self.nu, self.nv), FREE, dtype=np.uint8)
            ul, vl = self.u_lines, self.v_lines
            k[ul, :] = CURVE
            k[:, vl] = CURVE
            k[np.ix_(ul, vl)] = ANCHOR
            k[0, :] = k[-1, :] = k[:, 0] = k[:, -1] = BOUNDARY
            ends_u = _section_ends(self.nu, ul)
            ends_v = _section_ends(self.nv, vl)
            hit = self._kind_cache[key] = (k, (k == FREE).ravel(), ends_u, ends_v)
        return hit

    def set_boundary(self) -> None:
        """Place the grid points of the four sides by the static resampling (sec. 5.6)."""
        nu, nv = self.nu, self.nv
        # each side's grid points as slices of the flat row-major arrays (views)
        for name, rows in (
            ("bottom", slice(0, None, nv)),
            ("top", slice(nv - 1, None, nv)),
            ("left", slice(0, nv)),
            ("right", slice((nu - 1) * nv, None)),
        ):
            ef, ea, eb = (
                np.ascontiguousarray(a, dtype=np.int64) for a in self.sides.edge_faces[name]
            )
            face, bary = _chain_points(
                np.ascontiguousarray(self.sides.arcs[name], dtype=np.float64),
                ef,
                ea,
                eb,
                self._static_positions(name),
            )
            self.face[rows] = face
            self.bary[rows] = bary

    def set_feature_points(self) -> None:
        """Place every point of the feature columns / rows at its arc position."""
        nv = self.nv
        idx = np.arange(self.nu * nv).reshape(self.nu, nv)
        for line, col, s in zip(self.u_feat, self.u_lines, self.s_u, strict=True):
            pts = line.points_at(self.mesh, s[1:-1])
            self.face[idx[col, 1:-1]] = pts.face
            self.bary[idx[col, 1:-1]] = pts.bary
        for line, row, s in zip(self.v_feat, self.v_lines, self.s_v, strict=True):
            keep = np.ones(self.nu, dtype=bool)
            keep[[0, -1]] = False
            keep[self.u_lines] = False  # anchors already placed on the u feature
            cols = np.flatnonzero(keep)
            if cols.size:
                pts = line.points_at(self.mesh, s[cols])
                self.face[idx[cols, row]] = pts.face
                self.bary[idx[cols, row]] = pts.bary

    def copy(self) -> State:
        """An independent copy (the mesh, sides and feature lines shared)."""
        return replace(
            self,
            face=self.face.copy(),
            bary=self.bary.copy(),
            s_u=[a.copy() for a in self.s_u],
            s_v=[a.copy() for a in self.s_v],
            _side_cache=dict(self._side_cache),
            _slid={k: v.copy() for k, v in self._slid.items()},
            _pinch_tried={k: set(v) for k, v in self._pinch_tried.items()},
            _kind_cache=dict(self._kind_cache),
        )

    def snapshot(self) -> SpringMesh:
        sp = SurfacePoints.owned(self.face.astype(np.int64), self.bary.astype(np.float64))
        # the kernel forms mesh.xyz(sp)'s sums in einsum's order: the same positions
        xyz = _aux.face_point_sums(self.mesh.vertices, self.mesh.faces, sp.face, sp.bary)
        xyz = xyz.reshape(self.nu, self.nv, 3)
        return SpringMesh(sp, self.kind(), self.level, self.patch, xyz, self.u_lines, self.v_lines)
