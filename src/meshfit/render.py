"""Headless renders for the report: a small numba z-buffer rasteriser and a PNG writer.

Orthographic camera (:class:`Camera`) looking along a view direction, a head light with
ambient term (two-sided Lambert), flat (per-face) or Gouraud (per-vertex) shading, vertex or
face colours, a checkerboard texture from per-vertex (u, v), and heat-map colours of a scalar.
No display, no OpenGL context: the triangles are scan-converted by
:func:`meshfit._kernels.render.raster` (serial, releases the GIL). Output images are 8-bit
RGB PNG through pypng, written atomically.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._atomic import atomic_write
from meshfit._kernels import frozen
from meshfit._kernels import render as _k
from meshfit.errors import InputError

__all__ = [
    "HEAT_COLORS",
    "HEAT_STOPS",
    "PALETTE",
    "Camera",
    "camera_frame",
    "heat_colors",
    "patch_colors",
    "project",
    "render",
    "write_png_rgb",
]

#: background colour of renders (RGB in [0, 1])
BACKGROUND = (1.0, 1.0, 1.0)
#: ambient share of the head light
AMBIENT = 0.25
#: fraction of the image left as margin around the model
MARGIN = 0.06
#: distinct patch colours (cycled)
PALETTE = np.array(
    [
        [0.894, 0.102, 0.110],
        [0.216, 0.494, 0.722],
        [0.302, 0.686, 0.290],
        [0.596, 0.306, 0.639],
        [1.000, 0.498, 0.000],
        [0.651, 0.337, 0.157],
        [0.969, 0.506, 0.749],
        [0.400, 0.761, 0.647],
        [0.988, 0.553, 0.384],
        [0.553, 0.627, 0.796],
        [0.906, 0.541, 0.765],
        [0.651, 0.847, 0.329],
        [1.000, 0.851, 0.184],
        [0.898, 0.769, 0.580],
    ]
)


#: the heat map of :func:`heat_colors`: fractions of its top value and their colours (RGB in
#: [0, 1], sRGB), interpolated linearly between
HEAT_STOPS = np.array([0.0, 0.33, 0.66, 1.0])
HEAT_COLORS = np.array(
    [[0.05, 0.10, 0.55], [0.10, 0.75, 0.85], [0.98, 0.90, 0.15], [0.85, 0.05, 0.05]]
)

#: a point or direction in model space
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Camera:
    """The orthographic camera of :func:`render`: image size, view, up and framing.

    One value for what several renders of a model share, so that they match and
    :func:`render` keeps a short signature. Array-likes are accepted and stored as tuples
    of floats, so a camera is immutable and hashable.

    Attributes
    ----------
    size : (int, int)
        Image width and height, pixels, each at least 1 (default 640 x 640); each is
        truncated to an integer.
    view : (3,) float
        Viewing direction, from the camera into the scene, of any nonzero length
        (default +y).
    up : (3,) float
        Direction shown upwards, nonzero (default +z). Where it is (nearly) parallel to
        ``view``, :func:`camera_frame` takes another axis.
    bounds : tuple of (3,) float, optional
        Points framed by the camera, given as any ``(k, 3)`` array-like (default None: the
        rendered vertices; two points are a box given by its two extreme corners), so
        several renders of one model share a framing.

    Raises
    ------
    InputError
        A size that is not two integers of at least 1, a view or up that is not a finite
        nonzero 3-vector, or bounds that are not finite points ``(k, 3)``.
    """

    size: tuple[int, int] = (640, 640)
    view: Vec3 = (0.0, 1.0, 0.0)
    up: Vec3 = (0.0, 0.0, 1.0)
    bounds: tuple[Vec3, ...] | None = None

    def __post_init__(self) -> None:
        try:
            w, h = (int(s) for s in self.size)
        except (TypeError, ValueError):
            raise InputError(f"image size must be two integers, got {self.size!r}") from None
        if w < 1 or h < 1:
            raise InputError(f"image size must be positive, got {self.size}")
        object.__setattr__(self, "size", (w, h))
        object.__setattr__(self, "view", _direction(self.view, "view"))
        object.__setattr__(self, "up", _direction(self.up, "up"))
        if self.bounds is not None:
            pts = np.asarray(self.bounds, dtype=np.float64)
            if pts.size == 0:
                pts = pts.reshape(0, 3)
            if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
                raise InputError(f"bounds must be finite points (k, 3), got shape {pts.shape}")
            object.__setattr__(self, "bounds", tuple(map(tuple, pts.tolist())))


def _direction(value: ArrayLike, name: str) -> Vec3:
    """A finite nonzero 3-vector as a tuple of floats, else InputError naming ``name``."""
    try:
        d = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a 3-vector, got {value!r}") from None
    if d.shape != (3,) or not np.isfinite(d).all() or not d.any():
        raise InputError(f"{name} must be a finite nonzero 3-vector, got {value!r}")
    x, y, z = d.tolist()
    return (x, y, z)


def camera_frame(view: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> NDArray[np.float64]:
    """Rows: screen right, screen up, towards the viewer, for a camera looking along ``view``."""
    d = np.asarray(view, dtype=np.float64)
    d = d / np.linalg.norm(d)
    back = -d
    u = np.asarray(up, dtype=np.float64)
    if abs(u @ back) > 0.99 * np.linalg.norm(u):
        u = np.array([0.0, 1.0, 0.0]) if abs(back[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(u, back)
    right /= np.linalg.norm(right)
    upv = np.cross(back, right)
    return np.stack([right, upv, back])


def patch_colors(index: ArrayLike) -> NDArray[np.float64]:
    """Palette colours ``(n, 3)`` for patch indices (``-1``: grey)."""
    idx = np.asarray(index, dtype=np.int64)
    out = PALETTE[np.mod(idx, len(PALETTE))]
    out[idx < 0] = 0.6
    return out


def heat_colors(values: ArrayLike, vmax: float | None = None) -> NDArray[np.float64]:
    """Heat-map colours ``(n, 3)``: 0 dark blue, through cyan, yellow, to red at ``vmax``."""
    v = np.asarray(values, dtype=np.float64)
    top = float(np.max(v)) if vmax is None else float(vmax)
    t = np.clip(v / top, 0.0, 1.0) if top > 0 else np.zeros_like(v)
    stops, cols = HEAT_STOPS, HEAT_COLORS
    return np.stack([np.interp(t, stops, cols[:, c]) for c in range(3)], axis=-1)


def render(
    vertices: ArrayLike,
    faces: ArrayLike,
    *,
    camera: Camera | None = None,
    vertex_colors: ArrayLike | None = None,
    face_colors: ArrayLike | None = None,
    uv: ArrayLike | None = None,
    checker: float = 0.0,
    shading: str = "gouraud",
    depth_out: NDArray[np.float64] | None = None,
) -> NDArray[np.uint8]:
    """Render a triangle mesh to an RGB image.

    Parameters
    ----------
    vertices : (n, 3) float64
        Model units.
    faces : (m, 3) int64
    camera : Camera, optional
        Image size, view, up and framing (default ``Camera()``: 640 x 640 pixels, looking
        along +y with +z up, framing the vertices).
    vertex_colors : (n, 3) float64 in [0, 1] or uint8, optional
        Interpolated across faces; default light grey.
    face_colors : (m, 3) float64 in [0, 1] or uint8, optional
        One colour per face (overrides ``vertex_colors``).
    uv : (n, 2) float64, optional
        Per-vertex parameters of the checkerboard texture.
    checker : float
        Checker squares per unit of ``uv`` (default 0: no texture).
    shading : {"gouraud", "flat"}
        Light per vertex (normals averaged over faces) interpolated, or per face.
    depth_out : (h, w) float64, optional
        Filled with each pixel's depth towards the viewer (model units, larger is nearer;
        ``-inf`` where nothing is drawn): what :func:`project` compares points with to
        tell whether they are in sight.

    Returns
    -------
    (h, w, 3) uint8
    """
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise InputError(f"render needs vertices (n, 3) and faces (m, 3), got {V.shape}, {F.shape}")
    if F.size and (F.min() < 0 or F.max() >= V.shape[0]):
        raise InputError("render: a face index is out of range")
    if shading not in ("gouraud", "flat"):
        raise InputError(f"shading must be 'gouraud' or 'flat', got {shading!r}")
    cam = Camera() if camera is None else camera
    if not isinstance(cam, Camera):
        raise InputError(f"camera must be a Camera, got {type(camera).__name__}")
    w, h = cam.size
    R = camera_frame(cam.view, cam.up)
    X = project(V, cam)
    empty = np.zeros((0, 3))
    fc = vc = empty
    if face_colors is not None:
        fc = np.ascontiguousarray(_as_colors(face_colors, F.shape[0], "face_colors"))
    elif vertex_colors is not None:
        vc = np.ascontiguousarray(_as_colors(vertex_colors, V.shape[0], "vertex_colors"))
    UV = np.zeros((0, 2))
    if uv is not None and checker > 0:
        UV = np.ascontiguousarray(uv, dtype=np.float64)
        if UV.shape != (V.shape[0], 2):
            raise InputError(f"uv must have shape ({V.shape[0]}, 2), got {UV.shape}")
    else:
        checker = 0.0
    image = np.empty((h, w, 3))
    image[:] = BACKGROUND
    depth = np.full((h, w), -np.inf)
    # head light along the view; colours, light and (u, v) gathered per triangle in the kernel
    _k.raster_mesh(
        *frozen(V, X, F),
        np.ascontiguousarray(R[2]),
        float(AMBIENT),
        shading == "flat",
        fc,
        vc,
        UV,
        float(checker),
        image,
        depth,
    )
    if depth_out is not None:
        depth_out[...] = depth
    return np.rint(image * 255.0).astype(np.uint8)


def project(points: ArrayLike, camera: Camera) -> NDArray[np.float64]:
    """Image positions of model points as :func:`render` draws them with ``camera``.

    Parameters
    ----------
    points : (n, 3) float64
        Model units.
    camera : Camera
        Framing ``camera.bounds``, or where that is None these points (as :func:`render`
        frames the vertices it draws): give bounds to place points on another render.

    Returns
    -------
    (n, 3) float64
        Column and row (pixels from the top left, pixel centres at half-integers) and
        depth towards the viewer (model units; larger is nearer), the depth
        :func:`render`'s ``depth_out`` holds.
    """
    V = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    w, h = camera.size
    R = camera_frame(camera.view, camera.up)
    pts = V if camera.bounds is None else np.array(camera.bounds, dtype=np.float64).reshape(-1, 3)
    if pts.shape[0] == 2:  # a box: frame its eight corners
        pts = np.array(
            [[pts[i][0], pts[j][1], pts[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)]
        )
    corners = pts if pts.size else np.zeros((1, 3))
    cs = corners @ R.T
    lo, hi = cs.min(axis=0), cs.max(axis=0)
    extent = max(hi[0] - lo[0], hi[1] - lo[1], 1e-300)
    scale = (1.0 - 2.0 * MARGIN) * min(w, h) / extent
    mid = 0.5 * (lo + hi)
    S = V @ R.T
    X = np.empty_like(S)
    X[:, 0] = (S[:, 0] - mid[0]) * scale + 0.5 * w
    X[:, 1] = 0.5 * h - (S[:, 1] - mid[1]) * scale
    X[:, 2] = S[:, 2]
    return X


def _as_colors(c: ArrayLike, n: int, name: str) -> NDArray[np.float64]:
    a = np.asarray(c)
    if a.ndim != 2 or a.shape[0] != n or a.shape[1] not in (3, 4):
        raise InputError(f"{name} must have shape ({n}, 3), got {a.shape}")
    a = a[:, :3]
    return a.astype(np.float64) / 255.0 if a.dtype == np.uint8 else a.astype(np.float64)


def write_png_rgb(path: str | os.PathLike, image: ArrayLike) -> Path:
    """Write an ``(h, w, 3) uint8`` (or ``(h, w)`` grey) image as an 8-bit PNG, atomically.

    zlib level 3: markedly faster than the default 6 for slightly larger report images.
    """
    import png

    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise InputError(f"image must be uint8, got {img.dtype}")
    grey = img.ndim == 2
    if not grey and (img.ndim != 3 or img.shape[2] != 3):
        raise InputError(f"image must be (h, w, 3) or (h, w), got {img.shape}")
    h, w = img.shape[:2]
    rows = img.reshape(h, -1)

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            png.Writer(w, h, greyscale=grey, bitdepth=8, compression=3).write(fh, rows)

    return atomic_write(path, write)
