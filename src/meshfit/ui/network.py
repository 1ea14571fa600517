"""Layout status of a painted curve network: which regions are four-sided patches, and why not.

The painted boundary curves run from corner to corner. The mesh is cut along all of them at
once (:func:`meshfit.surface.cut.cut_mesh_network`); each face component of the cut mesh is a
region. A region is a valid patch when it is a disk (one boundary loop, Euler characteristic
1) whose boundary runs along exactly four distinct curves joined at four corners. Its sides,
read in half-edge order (the region on the left, i.e. counter-clockwise seen from the side the
face normals point to), are the patch's sides in the :class:`meshfit.layout.Layout`
convention.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from meshfit.errors import CutError, InputError
from meshfit.layout.patch import loop_bulge, sides_taper
from meshfit.mesh import Mesh
from meshfit.surface.cut import cut_mesh_network
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["NetworkStatus", "RegionStatus", "network_status"]


@dataclass(frozen=True)
class RegionStatus:
    """One region of the mesh between the painted curves.

    Attributes
    ----------
    index : int
        Region number (in order of the cut mesh's face components).
    valid : bool
        A four-sided disk bounded by four distinct curves at four corners.
    reason : str
        Empty when valid, else why the region is no patch.
    sides : tuple of (int, bool)
        The (curve, reversed) pairs along the region's boundary, region on the left, starting
        at a corner; four of them for a valid patch.
    faces : (k,) int64
        Faces of the input mesh that (partly) lie in the region.
    area : float
        Area of the region, model units squared.
    bulge : float
        Area over that of a square with the region's perimeter (as
        :attr:`meshfit.layout.Patch.bulge`; NaN unless the region has one boundary loop): a
        patch above :data:`meshfit.layout.patch.BULGY` balloons out of its sides.
    taper : float
        The larger ratio of opposite sides' lengths of a valid region (as
        :attr:`meshfit.layout.Patch.taper`; NaN for other regions): a patch above
        :data:`meshfit.layout.patch.TAPERED` is near-triangular.
    """

    index: int
    valid: bool
    reason: str
    sides: tuple[tuple[int, bool], ...]
    faces: NDArray[np.int64]
    area: float
    bulge: float = float("nan")
    taper: float = float("nan")

    def as_dict(self) -> dict:
        return {
            "region": self.index,
            "valid": self.valid,
            "reason": self.reason,
            "sides": [[c, r] for c, r in self.sides],
            "faces": int(self.faces.size),
            "area": self.area,
            "bulge": None if np.isnan(self.bulge) else self.bulge,
            "taper": None if np.isnan(self.taper) else self.taper,
        }


@dataclass(frozen=True)
class NetworkStatus:
    """Result of :func:`network_status`.

    Attributes
    ----------
    regions : list of RegionStatus
    error : str
        Empty when the mesh could be cut along the network; else why not (curves crossing away
        from corners, a curve collapsing), and ``regions`` is empty.
    region_of_face : (nf,) int64
        Region of each input face (the region holding most of it), -1 when not cut.
    """

    regions: list[RegionStatus] = field(default_factory=list)
    error: str = ""
    region_of_face: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def complete(self) -> bool:
        """Every region is a valid patch (and there is at least one)."""
        return not self.error and bool(self.regions) and all(r.valid for r in self.regions)

    @property
    def patches(self) -> list[list[tuple[int, bool]]]:
        """The sides of every valid region, in region order."""
        return [list(r.sides) for r in self.regions if r.valid]

    def as_dict(self) -> dict:
        return {
            "complete": self.complete,
            "error": self.error,
            "n_regions": len(self.regions),
            "n_valid": sum(r.valid for r in self.regions),
            "regions": [r.as_dict() for r in self.regions],
        }


def network_status(
    mesh: Mesh,
    corners: SurfacePoints,
    curves: list[SurfaceCurve],
    ends: NDArray[np.int64],
) -> NetworkStatus:
    """Classify the regions a network of corner-to-corner curves cuts a mesh into.

    Parameters
    ----------
    mesh : Mesh
    corners : SurfacePoints
        ``nc`` corners.
    curves : list of SurfaceCurve
        ``nk`` open boundary curves; curve ``i`` from corner ``ends[i, 0]`` to ``ends[i, 1]``.
    ends : (nk, 2) int64

    Returns
    -------
    NetworkStatus
        Each region with its validity and the reason when it is not a four-sided patch; a cut
        that fails (curves crossing away from corners) is reported in ``error``, not raised.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 and fig. 1.2 (four-sided regions between painted
       boundary curves), sec. 1.2.1 (real-time feedback while the user paints).
    """
    ends = np.asarray(ends, dtype=np.int64).reshape(-1, 2)
    if not curves:
        return NetworkStatus([], "no boundary curves painted yet", np.full(mesh.n_faces, -1))
    try:
        res = cut_mesh_network(mesh, list(curves), corners, ends)
    except (CutError, InputError) as exc:
        return NetworkStatus([], str(exc).splitlines()[0], np.full(mesh.n_faces, -1))
    cut = res.mesh
    copy_of = res.copy_of
    corner_v = set(res.corners.tolist())
    along: dict[tuple[int, int], tuple[int, bool]] = {}
    for i, path in enumerate(res.curve_vertices):
        for a, b in itertools.pairwise(path.tolist()):
            along[(a, b)] = (i, False)
            along[(b, a)] = (i, True)
    labels = cut.face_components
    n_comp = cut.n_components
    vcomp = cut.vertex_components
    n_f = np.bincount(labels, minlength=n_comp)
    n_v = np.bincount(vcomp, minlength=n_comp)
    n_e = np.bincount(vcomp[cut.edges[:, 0]], minlength=n_comp)
    chi = n_v - n_e + n_f
    loops_of: list[list[NDArray[np.int64]]] = [[] for _ in range(n_comp)]
    for loop in cut.boundary_loops:
        loops_of[int(vcomp[loop[0]])].append(loop)
    areas = np.bincount(labels, weights=cut.face_areas, minlength=n_comp)
    # region of each input face: the one holding most of its area
    parent = res.face_parent
    key = parent * n_comp + labels
    uniq, inv = np.unique(key, return_inverse=True)
    acc = np.bincount(inv, weights=cut.face_areas)
    region_of_face = np.full(mesh.n_faces, -1, dtype=np.int64)
    best = np.full(mesh.n_faces, -1.0)
    for k in np.argsort(acc, kind="stable"):
        f, r = divmod(int(uniq[k]), n_comp)
        if acc[k] >= best[f]:
            best[f], region_of_face[f] = acc[k], r
    regions = []
    for c in range(n_comp):
        faces = np.unique(parent[labels == c])
        loops = loops_of[c]
        sides: list[tuple[int, bool]] = []
        reason = ""
        if not loops:
            reason = "no curve bounds it (a closed piece of the mesh without curves)"
        elif len(loops) != 1:
            reason = (
                f"not a disk: {len(loops)} boundary loops (curves that do not close around "
                "it, or a hole of the mesh inside it)"
            )
        elif chi[c] != 1:
            reason = f"not a disk: Euler characteristic {int(chi[c])} (a handle inside it)"
        else:
            sides, reason = _sides(copy_of[loops[0]].tolist(), along, corner_v)
        bulge = loop_bulge(areas[c], cut.vertices[loops[0]]) if len(loops) == 1 else np.nan
        taper = np.nan
        if not reason:
            taper = sides_taper(_side_lengths(cut.vertices[loops[0]], copy_of[loops[0]], corner_v))
        regions.append(
            RegionStatus(c, not reason, reason, tuple(sides), faces, float(areas[c]), bulge, taper)
        )
    return NetworkStatus(regions, "", region_of_face)


def _side_lengths(
    loop_xyz: NDArray[np.float64], ref: NDArray[np.int64], corner_v: set[int]
) -> list[float]:
    """Lengths of the closed loop's pieces between its corner vertices (``ref`` are the
    input-mesh vertices of the loop's points), in loop order from the first corner."""
    pos = [k for k, v in enumerate(ref.tolist()) if v in corner_v]
    seg = np.linalg.norm(np.roll(loop_xyz, -1, axis=0) - loop_xyz, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    ends = [*pos, pos[0] + len(ref)]
    total = cum[-1]
    return [
        float(cum[b] - cum[a]) if b <= len(ref) else float(total - cum[a] + cum[b - len(ref)])
        for a, b in itertools.pairwise(ends)
    ]


def _sides(
    ref: list[int], along: dict[tuple[int, int], tuple[int, bool]], corner_v: set[int]
) -> tuple[list[tuple[int, bool]], str]:
    n = len(ref)
    for k in range(n):
        if (ref[k], ref[(k + 1) % n]) not in along:
            return [], "reaches the mesh boundary away from the curves (an unpainted side)"
    pos = [k for k, v in enumerate(ref) if v in corner_v]
    # a corner where the same curve continues (a curve passing its own corner) splits nothing
    seq = [along[(ref[k], ref[(k + 1) % n])] for k in pos]
    if not seq:
        return [], "its boundary has no corner"
    curves = [s[0] for s in seq]
    if len(seq) != 4:
        return [
            (int(c), bool(r)) for c, r in seq
        ], f"{len(seq)} sides (curves {sorted(set(curves))}); a patch needs exactly 4"
    if len(set(curves)) != 4:
        return [(int(c), bool(r)) for c, r in seq], (
            f"a curve bounds it on two sides (curves {curves}): a dangling curve inside it"
        )
    return [(int(c), bool(r)) for c, r in seq], ""
