"""Vector, scalar and bump maps of a grid over its fitted spline, and their reconstruction.

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
spring mesh itself). Reconstruction at any resolution filters bilinearly between texels.

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

from meshfit._kernels import bspline as _k
from meshfit.bspline import BSplineSurface, grid_parameters
from meshfit.bspline.fit import _as_grid
from meshfit.errors import InputError

__all__ = [
    "KINDS",
    "DisplacementMap",
    "bump_map",
    "bump_normals",
    "displacement_map",
    "grid_normals",
    "reconstruct",
    "resample_map",
    "sample_bilinear",
    "vector_values",
]

#: map kinds and their channel count
KINDS = {"vector": 3, "normal": 1, "magnitude": 1, "bump": 3}
#: the frame of every map, channel by channel (stored in file metadata)
FRAME = "T=dS/du normalised, B=N x T, N=unit normal (S_u x S_v)"


@dataclass(frozen=True, eq=False)
class DisplacementMap:
    """A displacement or bump map of one patch, in the spline's local frame.

    Attributes
    ----------
    values : (h, w, c) float64
        Map values; c = 3 for ``vector`` (components along T, B, N, model units) and ``bump``
        (unit normal in T, B, N), c = 1 for ``normal`` (component along N, model units) and
        ``magnitude`` (length of the vector displacement, model units). ``values[i, j]`` is at
        ``(u, v) = (i / (h - 1), j / (w - 1))``; h, w >= 2.
    kind : {"vector", "normal", "magnitude", "bump"}

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.1-7.4.
    """

    values: NDArray[np.float64]
    kind: str = "vector"

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"kind must be one of {tuple(KINDS)}, got {self.kind!r}")
        try:
            a = np.array(self.values, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("values must be a numeric (h, w, c) array") from None
        if a.ndim == 2:
            a = a[:, :, None]
        c = KINDS[self.kind]
        if a.ndim != 3 or a.shape[2] != c or a.shape[0] < 2 or a.shape[1] < 2:
            raise InputError(
                f"a {self.kind} map needs values of shape (h, w, {c}) with h, w >= 2, "
                f"got {np.shape(self.values)}"
            )
        if not np.isfinite(a).all():
            i, j = np.argwhere(~np.isfinite(a).all(axis=2))[0]
            raise InputError(f"{self.kind} map value at texel [{i}, {j}] is not finite")
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


def displacement_map(
    surface: BSplineSurface, grid_xyz: ArrayLike, *, kind: str = "vector"
) -> DisplacementMap:
    """Displacement of grid points from the spline at the same parameters, in the local frame.

    Parameters
    ----------
    surface : BSplineSurface
        The spline fitted to the grid.
    grid_xyz : (nu, nv, 3) float64
        Grid points (the spring mesh), at ``(u_i, v_j) = (i / (nu - 1), j / (nv - 1))``.
    kind : {"vector", "normal", "magnitude"}
        ``vector``: ``d = X - S`` as (d.T, d.B, d.N) (sec. 7.2); ``normal``: d.N;
        ``magnitude``: |d| (sec. 7.3). Default ``vector``.

    Returns
    -------
    DisplacementMap
        ``(nu, nv, c)``, model units. See the module notes for the frame and precision.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.2, eq. 7.1; sec. 7.3.
    """
    if kind not in ("vector", "normal", "magnitude"):
        raise InputError(f"kind must be 'vector', 'normal' or 'magnitude', got {kind!r}")
    X = _as_grid(grid_xyz)
    S, T, B, N = _grid_frames(surface, *X.shape[:2])
    d = X - S
    comp = _components(d, T, B, N)
    if kind == "vector":
        return DisplacementMap(comp, "vector")
    if kind == "normal":
        return DisplacementMap(comp[:, :, 2:], "normal")
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
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    _, T, B, N = _grid_frames(surface, *X.shape[:2])
    comp = np.stack([(n * T).sum(-1), (n * B).sum(-1), (n * N).sum(-1)], axis=-1)
    return DisplacementMap(comp, "bump")


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


def _world_filtered(surface: BSplineSurface, comp: NDArray, shape: tuple[int, int]) -> NDArray:
    """Model-space vectors of frame components ``comp``, bilinearly filtered to ``shape``."""
    _, T, B, N = _grid_frames(surface, *comp.shape[:2])
    world = comp[..., :1] * T + comp[..., 1:2] * B + comp[..., 2:] * N
    if tuple(shape) == comp.shape[:2]:
        return world
    Wu = _bilinear_weights(shape[0], comp.shape[0])
    Wv = _bilinear_weights(shape[1], comp.shape[1])
    return _k.dense_sandwich(Wu, np.ascontiguousarray(world), Wv)


def resample_map(
    dmap: DisplacementMap, shape: tuple[int, int], *, surface: BSplineSurface | None = None
) -> DisplacementMap:
    """The map bilinearly resampled to ``shape = (h', w')`` (the thesis' image scaling).

    Without ``surface`` the frame components are filtered as image channels. With the
    ``surface`` of a ``vector`` map, the model-space vectors are filtered and expressed in
    the frames at the new texels, as :func:`reconstruct` reads a map at any resolution: the
    resampled map's reconstruction at its own resolution is the old map's reconstruction
    at ``shape``.
    """
    h2, w2 = (int(s) for s in shape)
    if h2 < 2 or w2 < 2:
        raise InputError(f"a map needs at least 2 x 2 texels, got {shape}")
    if surface is not None:
        if dmap.kind != "vector":
            raise InputError(f"resampling with a surface needs a vector map, got {dmap.kind}")
        world = _world_filtered(surface, dmap.values, (h2, w2))
        _, T, B, N = _grid_frames(surface, h2, w2)
        return DisplacementMap(_components(world, T, B, N), "vector")
    Wu = _bilinear_weights(h2, dmap.shape[0])
    Wv = _bilinear_weights(w2, dmap.shape[1])
    vals = _k.dense_sandwich(Wu, np.ascontiguousarray(dmap.values), Wv)
    if dmap.kind == "bump":
        vals /= np.linalg.norm(vals, axis=-1, keepdims=True)
    return DisplacementMap(vals, dmap.kind)


def vector_values(dmap: DisplacementMap, base: DisplacementMap | None = None) -> NDArray:
    """Frame components ``(h, w, 3) float64`` of the vector displacement a map stands for.

    ``vector`` maps are returned as they are. A ``normal`` map replaces the normal component
    of ``base`` (a vector map of the same resolution) or, without ``base``, displaces along
    N only. A ``magnitude`` map scales ``base``'s vectors to the given lengths along their
    own directions (sec. 7.3); it needs ``base``; where ``base`` is zero it displaces along N.
    """
    if dmap.kind == "bump":
        raise InputError("a bump map changes normals, not positions: use bump_normals")
    if dmap.kind == "vector":
        return dmap.values
    if base is not None:
        if base.kind != "vector":
            raise InputError(f"base must be a vector map, got a {base.kind} map")
        if base.shape != dmap.shape:
            base = resample_map(base, dmap.shape)
    s = dmap.values[:, :, 0]
    if dmap.kind == "normal":
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
        ``vector``, ``normal`` or ``magnitude`` map (see :func:`vector_values` for ``base``).
    shape : (int, int), optional
        Output grid ``(h', w')``, points at ``(i / (h' - 1), j / (w' - 1))``; default the
        map's resolution.
    base : DisplacementMap, optional
        Vector map giving directions to a scalar map.

    Returns
    -------
    (h', w', 3) float64
        Displaced points, model units. At the map's own resolution and from a map made by
        :func:`displacement_map` this is the original grid to float64 round-off.

    Notes
    -----
    Each texel's components are turned into a model-space vector with the frame at the
    texel's own (u, v); the vectors are filtered bilinearly and added to the spline at the
    output parameters. Filtering vectors rather than frame components keeps two patches
    whose boundary texels carry the same vectors crack-free at every resolution (sec. 8.2).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.1 (S_disp = S + D), sec. 7.2 (bilinear reconstruction).
    """
    comp = vector_values(dmap, base)
    h2, w2 = dmap.shape if shape is None else (int(shape[0]), int(shape[1]))
    if h2 < 2 or w2 < 2:
        raise InputError(f"output shape must be at least 2 x 2, got {(h2, w2)}")
    world = _world_filtered(surface, comp, (h2, w2))
    return surface.evaluate_grid(grid_parameters(h2), grid_parameters(w2)) + world


def bump_normals(
    surface: BSplineSurface, dmap: DisplacementMap, *, shape: tuple[int, int] | None = None
) -> NDArray[np.float64]:
    """World-space unit normals of a bump map on a grid of ``shape``: ``(h', w', 3) float64``."""
    if dmap.kind != "bump":
        raise InputError(f"bump_normals needs a bump map, got a {dmap.kind} map")
    m = dmap if shape is None or tuple(shape) == dmap.shape else resample_map(dmap, shape)
    _, T, B, N = _grid_frames(surface, *m.shape)
    c = m.values
    n = c[..., :1] * T + c[..., 1:2] * B + c[..., 2:] * N
    return n / np.linalg.norm(n, axis=-1, keepdims=True)
