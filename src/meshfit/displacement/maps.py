"""Vector, scalar and bump maps of a grid over its fitted spline, and their reconstruction.

Kinds
-----
* ``vector``: the displacement ``d = X - S`` of each grid point from the spline at the same
  parameters, three components (sec. 7.2); rebuilds the grid exactly.
* ``scalar``: one value per texel, a displacement along the spline's unit normal, the grey
  image a user paints (sec. 7.3, fig. 7.4); see :func:`displacement_map` for how it is
  measured. ``"normal"``, the kind's former name, is read as ``scalar`` (maps, files).
* ``bump``: the grid's unit normals, three components (sec. 7.4): shading only, the
  geometry is the spline's.
* ``magnitude``: ``|d|``, which scales a vector map along its own directions (sec. 7.3).

Frame
-----
Every map is stored in the orthonormal local frame of the spline at the same (u, v):

* channel 0, ``T = S_u / |S_u|``: the unit tangent along u;
* channel 1, ``B = N x T``: the unit tangent across it (leaning towards ``S_v``);
* channel 2, ``N = S_u x S_v / |S_u x S_v|``: the unit outward normal.

The thesis writes the displacement in the (generally not orthonormal) frame of the partials
``S_u, S_v, N`` (Krishnamurthy 2000, sec. 7.2, eq. 7.1); an orthonormal frame makes the
components plain dot products and keeps the normal component a true distance along N.
The order (T, B, N) is the usual tangent-space order of normal maps (a flat bump map is blue).

Sampling
--------
``values[i, j]`` belongs to parameter ``(u, v) = (i / (h - 1), j / (w - 1))``: image rows
follow u, columns follow v, and the corner texels sit on the patch corners (the grid of the
spring mesh itself). Reconstruction at any resolution filters bilinearly between texels:
vector and bump maps as model-space vectors (each texel's components in its own frame), a
scalar map as the value, applied along the spline's normal at the output point (sec. 7.1,
``S + s N``, as renderers read a scalar displacement map).

Precision
---------
Maps keep their float64 values in memory (``values``); ``image`` is the float32 array written
to files. From ``values``, spline + displacement reproduces the grid to float64 round-off
(~1e-16 of the coordinates); from a float32 file each displacement component carries a
relative error of at most 2**-24 (6e-8) of its own size, so the rebuilt grid is within
``2**-24 * |d| * sqrt(3)`` of the original (d the displacement), plus float64 round-off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import tol
from meshfit._kernels import bspline as _k
from meshfit.bspline import BSplineSurface, grid_parameters
from meshfit.bspline.fit import _as_grid
from meshfit.errors import InputError

__all__ = [
    "KINDS",
    "KIND_ALIASES",
    "RAY_CELLS",
    "SCALAR_METHODS",
    "DisplacementMap",
    "bump_map",
    "bump_normals",
    "canonical_kind",
    "displacement_map",
    "grid_normals",
    "reconstruct",
    "refine_on_scan",
    "resample_map",
    "sample_bilinear",
    "shading_normals",
    "vector_values",
]

#: map kinds and their channel count
KINDS = {"vector": 3, "scalar": 1, "magnitude": 1, "bump": 3}
#: former kind names, read as the kind they name now (maps made and files written with them)
KIND_ALIASES = {"normal": "scalar"}
#: how :func:`displacement_map` measures a scalar map: ``ray`` (signed distance along the
#: normal to the grid's triangles) or ``component`` (the normal component ``d . N``)
SCALAR_METHODS = ("ray", "component")
#: a scalar map's ray is met with the grid's triangles in the cells within this many cells
#: of the texel's own grid point (a hit farther away is another part of a folded grid)
RAY_CELLS = 2
#: the frame of every map, channel by channel (stored in file metadata)
FRAME = "T=dS/du normalised, B=N x T, N=unit normal (S_u x S_v)"


def canonical_kind(kind: str) -> str:
    """The kind a name stands for: one of :data:`KINDS` (``"normal"`` is ``"scalar"``).

    Raises
    ------
    meshfit.errors.InputError
        Not a kind or a former kind name.
    """
    k = KIND_ALIASES.get(kind, kind) if isinstance(kind, str) else kind
    if k not in KINDS:
        raise InputError(f"kind must be one of {tuple(KINDS)}, got {kind!r}")
    return k


@dataclass(frozen=True, eq=False)
class DisplacementMap:
    """A displacement or bump map of one patch, in the spline's local frame.

    Attributes
    ----------
    values : (h, w, c) float64
        Map values; c = 3 for ``vector`` (components along T, B, N, model units) and ``bump``
        (unit normal in T, B, N), c = 1 for ``scalar`` (displacement along N, model units)
        and ``magnitude`` (length of the vector displacement, model units). ``values[i, j]``
        is at ``(u, v) = (i / (h - 1), j / (w - 1))``; h, w >= 2.
    kind : {"vector", "scalar", "magnitude", "bump"}
        ``"normal"`` is accepted as the former name of ``"scalar"`` and stored as
        ``"scalar"``.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.1-7.4.
    """

    values: NDArray[np.float64]
    kind: str = "vector"

    def __post_init__(self) -> None:
        kind = canonical_kind(self.kind)
        object.__setattr__(self, "kind", kind)
        try:
            a = np.array(self.values, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("values must be a numeric (h, w, c) array") from None
        if a.ndim == 2:
            a = a[:, :, None]
        c = KINDS[kind]
        if a.ndim != 3 or a.shape[2] != c or a.shape[0] < 2 or a.shape[1] < 2:
            raise InputError(
                f"a {kind} map needs values of shape (h, w, {c}) with h, w >= 2, "
                f"got {np.shape(self.values)}"
            )
        if not np.isfinite(a).all():
            i, j = np.argwhere(~np.isfinite(a).all(axis=2))[0]
            raise InputError(f"{kind} map value at texel [{i}, {j}] is not finite")
        a.flags.writeable = False
        object.__setattr__(self, "values", a)

    @property
    def image(self) -> NDArray[np.float32]:
        """``(h, w, c) float32``: the values as written to image files."""
        return self.values.astype(np.float32)

    @property
    def shape(self) -> tuple[int, int]:
        """Resolution ``(h, w)``: texels along u and along v."""
        return int(self.values.shape[0]), int(self.values.shape[1])

    @property
    def channels(self) -> int:
        return int(self.values.shape[2])

    # file I/O lives in meshfit.displacement.io; these delegate
    def to_exr(self, path, *, compression: str = "zip") -> None:
        """Write an OpenEXR float32 file; see :func:`meshfit.displacement.write_exr`."""
        from meshfit.displacement.io import write_exr

        write_exr(self, path, compression=compression)

    @classmethod
    def from_exr(cls, path) -> DisplacementMap:
        """Read a map written by :meth:`to_exr` (or an edited copy keeping its header)."""
        from meshfit.displacement.io import read_exr

        return read_exr(path)

    def to_png(self, path, *, value_range: tuple[float, float] | None = None) -> None:
        """Write a 16-bit PNG with the value range in its text metadata; see ``write_png``."""
        from meshfit.displacement.io import write_png

        write_png(self, path, value_range=value_range)

    @classmethod
    def from_png(cls, path) -> DisplacementMap:
        """Read a 16-bit PNG written by :meth:`to_png` (or an edited copy keeping its text)."""
        from meshfit.displacement.io import read_png

        return read_png(path)


def _components(vec: NDArray, T: NDArray, B: NDArray, N: NDArray) -> NDArray:
    """Components ``(..., 3)`` of model-space vectors ``(..., 3)`` in the frames T, B, N."""
    return np.stack([(vec * T).sum(-1), (vec * B).sum(-1), (vec * N).sum(-1)], axis=-1)


def _grid_frames(surface: BSplineSurface, h: int, w: int):
    u, v = grid_parameters(h), grid_parameters(w)
    S, Su, Sv = surface.evaluate_grid(u, v, derivatives=1)
    U, V = np.meshgrid(u, v, indexing="ij")
    from meshfit.bspline.surface import _frames_from_partials

    T, B, N = _frames_from_partials(surface, U, V, Su, Sv)
    return S, T, B, N


def _grid_normals(surface: BSplineSurface, h: int, w: int) -> NDArray[np.float64]:
    """The unit normals of `_grid_frames` at an ``(h, w)`` map's texels, without the frames'
    other axes: the banded grid products, not a spline evaluation per texel."""
    from meshfit.bspline.surface import _unit_normals

    u, v = grid_parameters(h), grid_parameters(w)
    _, Su, Sv = surface.evaluate_grid(u, v, derivatives=1)
    U, V = np.meshgrid(u, v, indexing="ij")
    return _unit_normals(surface, U, V, Su, Sv)


def _ray_distances(X: NDArray, S: NDArray, N: NDArray, cells: int = RAY_CELLS) -> NDArray:
    """Signed distance ``t`` along each line ``S[i, j] + t N[i, j]`` to the triangles of the
    grid ``X`` (two per cell, split along the (i, j)-(i+1, j+1) diagonal) in the cells
    within ``cells`` of grid point ``(i, j)``: the hit nearest ``S`` (smallest ``|t|``),
    NaN where the line meets none of them. ``X, S, N (h, w, 3)`` -> ``(h, w)``."""
    h, w = X.shape[:2]
    best = np.full((h, w), np.nan)
    ii, jj = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    eps = tol.BARY_EPS
    for di in range(-cells, cells):
        for dj in range(-cells, cells):
            ci, cj = ii + di, jj + dj
            ok = (ci >= 0) & (ci < h - 1) & (cj >= 0) & (cj < w - 1)
            if not ok.any():
                continue
            ci, cj = np.clip(ci, 0, h - 2), np.clip(cj, 0, w - 2)
            p00, p11 = X[ci, cj], X[ci + 1, cj + 1]
            for a, b, c in ((p00, X[ci + 1, cj], p11), (p00, p11, X[ci, cj + 1])):
                # Moeller-Trumbore on the whole line (t of either sign)
                e1, e2 = b - a, c - a
                pv = np.cross(N, e2)
                det = (e1 * pv).sum(-1)
                good = ok & (det != 0)
                inv = 1.0 / np.where(good, det, 1.0)
                sv = S - a
                beta = (sv * pv).sum(-1) * inv
                qv = np.cross(sv, e1)
                gamma = (N * qv).sum(-1) * inv
                t = (e2 * qv).sum(-1) * inv
                inside = good & (beta >= -eps) & (gamma >= -eps) & (beta + gamma <= 1 + eps)
                nearer = inside & ~(np.abs(t) >= np.abs(best))  # NaN best: any hit is nearer
                best = np.where(nearer, t, best)
    return best


def displacement_map(
    surface: BSplineSurface,
    grid_xyz: ArrayLike,
    *,
    kind: str = "vector",
    scalar: str = "ray",
) -> DisplacementMap:
    """A map of the grid over its spline, in the spline's local frame.

    Parameters
    ----------
    surface : BSplineSurface
        The spline fitted to the grid.
    grid_xyz : (nu, nv, 3) float64
        Grid points (the spring mesh), at ``(u_i, v_j) = (i / (nu - 1), j / (nv - 1))``.
    kind : {"vector", "scalar", "bump", "magnitude"}
        ``vector``: ``d = X - S`` as (d.T, d.B, d.N) (sec. 7.2), exact. ``scalar``: a
        displacement along the spline's normal N (sec. 7.3), see ``scalar``. ``bump``:
        :func:`bump_map` with the grid's own normals (sec. 7.4). ``magnitude``: |d|
        (sec. 7.3). ``"normal"`` is read as ``"scalar"``. Default ``vector``.
    scalar : {"ray", "component"}
        How a scalar map is measured. ``ray`` (default): the signed distance from the spline
        point along N to the grid's triangles (the hit nearest the spline within
        :data:`RAY_CELLS` cells of the texel), so ``S + s N`` lies on the grid's surface;
        where the line meets none of them (mostly along the patch border), ``d . N``. It
        rebuilds the grid's surface closer than ``component``, which drops the tangential
        part of ``d`` (the thesis' perpendicular projection, sec. 7.2, fig. 7.1, made local).
        ``component``: ``d . N`` everywhere, the normal component of the vector map: edits of
        it apply to a vector map through ``reconstruct(..., base=)`` (fig. 7.4).

    Returns
    -------
    DisplacementMap
        ``(nu, nv, c)``: model units, unit normals for ``bump``. See the module notes for
        the frame and precision.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.1 (scalar and vector maps), sec. 7.2, eq. 7.1; sec. 7.3;
       sec. 7.4.
    """
    kind = canonical_kind(kind)
    if scalar not in SCALAR_METHODS:
        raise InputError(f"scalar must be one of {SCALAR_METHODS}, got {scalar!r}")
    if kind == "bump":
        return bump_map(surface, grid_xyz)
    X = _as_grid(grid_xyz)
    S, T, B, N = _grid_frames(surface, *X.shape[:2])
    comp = _components(X - S, T, B, N)
    if kind == "vector":
        return DisplacementMap(comp, "vector")
    if kind == "scalar":
        s = comp[:, :, 2]
        if scalar == "ray":
            t = _ray_distances(X, S, N)
            s = np.where(np.isnan(t), s, t)
        return DisplacementMap(s[:, :, None], "scalar")
    return DisplacementMap(np.linalg.norm(comp, axis=-1)[:, :, None], "magnitude")


def grid_normals(grid_xyz: ArrayLike) -> NDArray[np.float64]:
    """Unit normals of a grid from central differences: ``(nu, nv, 3) float64``.

    ``dX/du x dX/dv`` by ``numpy.gradient`` (one-sided at the borders), normalised.
    """
    X = _as_grid(grid_xyz)
    du = np.gradient(X, axis=0)
    dv = np.gradient(X, axis=1)
    n = np.cross(du, dv)
    ln = np.linalg.norm(n, axis=-1, keepdims=True)
    if (ln == 0).any():
        i, j = np.argwhere(ln[..., 0] == 0)[0]
        raise InputError(f"grid has no normal at point [{i}, {j}] (coincident neighbours)")
    return n / ln


def bump_map(
    surface: BSplineSurface, grid_xyz: ArrayLike, *, normals: ArrayLike | None = None
) -> DisplacementMap:
    """Normals of the grid in the spline's local frame: a ``bump`` map.

    A bump map changes shading, not geometry: :func:`reconstruct` of it is the spline, and
    :func:`bump_normals` gives its shading normals at any resolution.

    Parameters
    ----------
    surface : BSplineSurface
    grid_xyz : (nu, nv, 3) float64
        Grid points (the spring mesh).
    normals : (nu, nv, 3) float64, optional
        Normals at the grid points (e.g. the input mesh's face normals at the spring points);
        default: :func:`grid_normals` of the grid.

    Returns
    -------
    DisplacementMap
        kind ``bump``, ``(nu, nv, 3)`` unit vectors (n.T, n.B, n.N); a grid lying on its
        spline gives (0, 0, 1) everywhere.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.4.
    """
    X = _as_grid(grid_xyz)
    if normals is None:
        n = grid_normals(X)
    else:
        n = _as_grid(normals)
        if n.shape != X.shape:
            raise InputError(f"normals must have the grid's shape {X.shape}, got {n.shape}")
        ln = np.linalg.norm(n, axis=-1, keepdims=True)
        if (ln == 0).any():
            i, j = np.argwhere(ln[..., 0] == 0)[0]
            raise InputError(f"normal [{i}, {j}] is zero")
        n = n / ln
    _, T, B, N = _grid_frames(surface, *X.shape[:2])
    return DisplacementMap(_components(n, T, B, N), "bump")


def _bilinear_weights(n_out: int, n_in: int) -> NDArray[np.float64]:
    """``(n_out, n_in)`` bilinear (tent) weights from corner-aligned texels to parameters."""
    x = grid_parameters(n_out) * (n_in - 1)
    i0 = np.clip(np.floor(x).astype(np.int64), 0, n_in - 2)
    f = x - i0
    W = np.zeros((n_out, n_in))
    W[np.arange(n_out), i0] = 1.0 - f
    W[np.arange(n_out), i0 + 1] += f
    return W


def sample_bilinear(values: ArrayLike, u: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
    """Bilinear samples of a corner-aligned ``(h, w, c)`` image at parameters: ``(n, c)``."""
    a = np.asarray(values, dtype=np.float64)
    h, w = a.shape[:2]
    x = np.clip(np.asarray(u, dtype=np.float64).ravel(), 0, 1) * (h - 1)
    y = np.clip(np.asarray(v, dtype=np.float64).ravel(), 0, 1) * (w - 1)
    i0 = np.clip(np.floor(x).astype(np.int64), 0, h - 2)
    j0 = np.clip(np.floor(y).astype(np.int64), 0, w - 2)
    fx = (x - i0)[:, None]
    fy = (y - j0)[:, None]
    return (
        (1 - fx) * (1 - fy) * a[i0, j0]
        + fx * (1 - fy) * a[i0 + 1, j0]
        + (1 - fx) * fy * a[i0, j0 + 1]
        + fx * fy * a[i0 + 1, j0 + 1]
    )


def _filtered(values: NDArray, shape: tuple[int, int]) -> NDArray:
    """The ``(h, w, c)`` image filtered bilinearly to ``shape`` as plain channels."""
    if tuple(shape) == values.shape[:2]:
        return np.array(values, dtype=np.float64)
    Wu = _bilinear_weights(shape[0], values.shape[0])
    Wv = _bilinear_weights(shape[1], values.shape[1])
    return _k.dense_sandwich(Wu, np.ascontiguousarray(values), Wv)


def _world_filtered(surface: BSplineSurface, comp: NDArray, shape: tuple[int, int]) -> NDArray:
    """Model-space vectors of frame components ``comp``, bilinearly filtered to ``shape``."""
    _, T, B, N = _grid_frames(surface, *comp.shape[:2])
    world = comp[..., :1] * T + comp[..., 1:2] * B + comp[..., 2:] * N
    return _filtered(world, shape)


def _unit(n: NDArray) -> NDArray:
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), np.finfo(float).tiny)


def refine_on_scan(
    mesh, surface: BSplineSurface, grid: NDArray, shape: tuple[int, int]
) -> NDArray[np.float64]:
    """A patch's grid of points on the scan at a finer resolution ``shape``, for a map of
    that resolution made with :func:`displacement_map`.

    Each new point starts on the bilinear interpolation of ``grid`` (points on the scan, a
    spring mesh) and moves to its closest point on ``mesh`` where the scan faces there the
    way the spline does (a thin shell's other sheet faces the other way, so a point never
    jumps to it); the grid's own points, on the scan already, keep their places.
    Interpolating alone would cut the scan's detail between the grid's points; the scan
    has it.

    Parameters
    ----------
    mesh : Mesh
        The scan (its triangle tree is built once and kept).
    surface : BSplineSurface
        The patch's spline, whose normals decide which way the scan must face.
    grid : (h, w, 3) float64
        The patch's spring grid, points at ``(i / (h - 1), j / (w - 1))``.
    shape : (int, int)
        The finer resolution ``(h', w')``, at least ``(h, w)``.

    Returns
    -------
    (h', w', 3) float64
        Points at ``(i / (h' - 1), j / (w' - 1))``, model units.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.1 (the displacement map as the scan over the spline)
       and sec. 8.2 (equal texel counts along shared boundaries).
    """
    return scan_points(mesh, surface, grid, shape)[0]


def scan_points(
    mesh, surface: BSplineSurface, grid: NDArray, shape: tuple[int, int]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`refine_on_scan`'s points, and which of them lie on the scan.

    Parameters
    ----------
    mesh, surface, grid, shape
        As for :func:`refine_on_scan`.

    Returns
    -------
    points : (h', w', 3) float64
        :func:`refine_on_scan`'s result.
    on_scan : (h', w') bool
        True where the point is the scan's closest point (within round-off of the scan,
        so a displaced texel made from it can be measured without a search); False where
        the scan faced away and the point stayed on the interpolation.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.1.
    """
    X = _filtered(np.asarray(grid, dtype=np.float64), shape)
    cp = mesh.closest_points(X.reshape(-1, 3))
    normal = _grid_normals(surface, *shape).reshape(-1, 3)
    facing = (mesh.face_normals[cp.points.face] * normal).sum(axis=1) > 0
    out = X.reshape(-1, 3).copy()
    out[facing] = cp.xyz[facing]
    return out.reshape(X.shape), facing.reshape(X.shape[:2])


def resample_map(
    dmap: DisplacementMap,
    shape: tuple[int, int],
    *,
    surface: BSplineSurface | None = None,
    points: bool = False,
) -> DisplacementMap:
    """The map bilinearly resampled to ``shape = (h', w')`` (the thesis' image scaling).

    Without ``surface`` the frame components are filtered as image channels (bump normals
    renormalised). With the map's ``surface``, each kind is resampled as
    :func:`reconstruct` (vector), :func:`bump_normals` (bump) read it at any resolution:
    the model-space vectors are filtered and expressed in the frames at the new texels, so
    the resampled map read at its own resolution is the old map read at ``shape``. Scalar
    and magnitude maps are filtered as values either way (for a scalar map that is exact
    in the same sense: its value is applied along the normal at the output point).

    With ``points`` (a vector map and its ``surface``) the displaced points are filtered
    instead: the resampled map puts each new texel's point on the bilinear interpolation of
    the old displaced grid, the surface the old map's own tessellation draws, and holds
    what is left after the spline there. Filtering the vectors instead adds them to the
    spline between the old texels, which cuts outside the scan wherever the spline bends
    away from the displaced grid (a fold, a thin rim); the points never leave the old
    displaced grid's cells. At the old texels both give the old displaced points.
    """
    h2, w2 = (int(s) for s in shape)
    if h2 < 2 or w2 < 2:
        raise InputError(f"a map needs at least 2 x 2 texels, got {shape}")
    if points:
        if surface is None or dmap.kind != "vector":
            raise InputError("points=True resamples a vector map with its surface")
        S, T, B, N = _grid_frames(surface, *dmap.shape)
        c = dmap.values
        X = _filtered(S + c[..., :1] * T + c[..., 1:2] * B + c[..., 2:] * N, (h2, w2))
        S2, T2, B2, N2 = _grid_frames(surface, h2, w2)
        return DisplacementMap(_components(X - S2, T2, B2, N2), "vector")
    if surface is not None and dmap.kind in ("vector", "bump"):
        world = _world_filtered(surface, dmap.values, (h2, w2))
        if dmap.kind == "bump":
            world = _unit(world)
        _, T, B, N = _grid_frames(surface, h2, w2)
        return DisplacementMap(_components(world, T, B, N), dmap.kind)
    vals = _filtered(dmap.values, (h2, w2))
    if dmap.kind == "bump":
        vals = _unit(vals)
    return DisplacementMap(vals, dmap.kind)


def vector_values(dmap: DisplacementMap, base: DisplacementMap | None = None) -> NDArray:
    """Frame components ``(h, w, 3) float64`` of the vector displacement a map stands for.

    ``vector`` maps are returned as they are; a ``bump`` map stands for none (zeros). A
    ``scalar`` map replaces the normal component of ``base`` (a vector map of the same
    resolution) or, without ``base``, displaces along N only. A ``magnitude`` map scales
    ``base``'s vectors to the given lengths along their own directions (sec. 7.3); it needs
    ``base``; where ``base`` is zero it displaces along N.
    """
    if dmap.kind == "bump":
        return np.zeros((*dmap.shape, 3))
    if dmap.kind == "vector":
        return dmap.values
    if base is not None:
        if base.kind != "vector":
            raise InputError(f"base must be a vector map, got a {base.kind} map")
        if base.shape != dmap.shape:
            base = resample_map(base, dmap.shape)
    s = dmap.values[:, :, 0]
    if dmap.kind == "scalar":
        out = np.zeros((*dmap.shape, 3)) if base is None else base.values.copy()
        out[:, :, 2] = s
        return out
    if base is None:
        raise InputError("a magnitude map needs the vector map it came from (base) for directions")
    b = base.values
    ln = np.linalg.norm(b, axis=-1)
    out = np.zeros_like(b)
    nz = ln > 0
    out[nz] = b[nz] * (s[nz] / ln[nz])[:, None]
    out[~nz, 2] = s[~nz]
    return out


def _out_shape(dmap: DisplacementMap, shape) -> tuple[int, int]:
    h2, w2 = dmap.shape if shape is None else (int(shape[0]), int(shape[1]))
    if h2 < 2 or w2 < 2:
        raise InputError(f"output shape must be at least 2 x 2, got {(h2, w2)}")
    return h2, w2


def reconstruct(
    surface: BSplineSurface,
    dmap: DisplacementMap,
    *,
    shape: tuple[int, int] | None = None,
    base: DisplacementMap | None = None,
) -> NDArray[np.float64]:
    """The displaced surface ``S + d`` on a regular grid of any resolution.

    Parameters
    ----------
    surface : BSplineSurface
    dmap : DisplacementMap
        Any kind. A ``bump`` map displaces nothing: the result is the spline (its shading
        normals are :func:`bump_normals`).
    shape : (int, int), optional
        Output grid ``(h', w')``, points at ``(i / (h' - 1), j / (w' - 1))``; default the
        map's resolution.
    base : DisplacementMap, optional
        Vector map giving the tangential part to a scalar map or the directions to a
        magnitude map (see :func:`vector_values`).

    Returns
    -------
    (h', w', 3) float64
        Displaced points, model units. At the map's own resolution and from a vector map
        made by :func:`displacement_map` this is the original grid to float64 round-off.

    Notes
    -----
    Vector (and scalar or magnitude with ``base``): each texel's components are turned into
    a model-space vector with the frame at the texel's own (u, v); the vectors are filtered
    bilinearly and added to the spline at the output parameters. Filtering vectors rather
    than frame components keeps two patches whose boundary texels carry the same vectors
    crack-free at every resolution (sec. 8.2). Scalar without ``base``: the value is
    filtered bilinearly and applied along the unit normal at the output point,
    ``S + s N`` (sec. 7.1), as a renderer applies a scalar displacement map; two patches
    with equal normals and equal values along a shared boundary meet at every resolution.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.1 (S_disp = S + D, S + s N), sec. 7.2 (bilinear
       reconstruction), sec. 7.4 (bump maps change shading only).
    """
    h2, w2 = _out_shape(dmap, shape)
    if dmap.kind == "bump":
        return surface.evaluate_grid(grid_parameters(h2), grid_parameters(w2))
    if dmap.kind == "scalar" and base is None:
        S, _, _, N = _grid_frames(surface, h2, w2)
        return S + _filtered(dmap.values, (h2, w2)) * N
    comp = vector_values(dmap, base)
    world = _world_filtered(surface, comp, (h2, w2))
    return surface.evaluate_grid(grid_parameters(h2), grid_parameters(w2)) + world


def bump_normals(
    surface: BSplineSurface, dmap: DisplacementMap, *, shape: tuple[int, int] | None = None
) -> NDArray[np.float64]:
    """Shading normals of a bump map on a grid of any resolution: ``(h', w', 3) float64``.

    Each texel's normal is taken to model space with the frame at its own (u, v); the
    model-space normals are filtered bilinearly to ``shape`` (default the map's) and
    normalised. As with :func:`reconstruct`, two patches whose boundary texels carry the
    same normals shade alike along their shared boundary at every resolution.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.4; Blinn, "Simulation of wrinkled surfaces", 1978.
    """
    if dmap.kind != "bump":
        raise InputError(f"bump_normals needs a bump map, got a {dmap.kind} map")
    return _unit(_world_filtered(surface, dmap.values, _out_shape(dmap, shape)))


def shading_normals(
    surface: BSplineSurface,
    dmap: DisplacementMap | None = None,
    *,
    shape: tuple[int, int] | None = None,
    base: DisplacementMap | None = None,
) -> NDArray[np.float64]:
    """Unit normals to shade a patch with, on a grid of any resolution: ``(h', w', 3)``.

    ``bump`` map: :func:`bump_normals`. Vector, scalar or magnitude map: the normals of the
    displaced grid (:func:`grid_normals` of :func:`reconstruct` at ``shape``, with ``base``
    as there). No map: the spline's own normals. ``shape`` defaults to the map's resolution
    (without a map it is required).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.4 (bump maps), sec. 7.1 (displaced surfaces).
    """
    if dmap is None:
        if shape is None:
            raise InputError("shading_normals needs a shape when there is no map")
        h2, w2 = (int(shape[0]), int(shape[1]))
        if h2 < 2 or w2 < 2:
            raise InputError(f"output shape must be at least 2 x 2, got {(h2, w2)}")
        return _grid_frames(surface, h2, w2)[3]
    if dmap.kind == "bump":
        return bump_normals(surface, dmap, shape=shape)
    return grid_normals(reconstruct(surface, dmap, shape=shape, base=base))
