"""The report's views: its interactive 3D model, its fixed viewpoints and patch labels.

The 3D view is a GLB of the displaced surface (one mesh per patch, named ``patch N``) whose
vertices carry their deviation from the scan, as heat-map colours (``COLOR_0``) and as a
number (``_DEVIATION``, percent of the input's bbox diagonal). The page draws it with a
three.js bundle shipped in ``meshfit/report_static`` (copied beside the page, with its
licence); a page opened from ``file://`` may neither fetch files nor import ES modules, so
the GLB is written as ``model.js``, its bytes in base64 set on ``window`` (the page saves
them as ``model.glb`` on request), and the scripts are classic ones. No network is used.
"""

from __future__ import annotations

import base64
import json
import struct
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._atomic import write_bytes, write_text
from meshfit.render import Camera, heat_colors, project

__all__ = [
    "STATIC_FILES",
    "VIEWER_VERTICES",
    "View",
    "copy_static",
    "deviation_glb",
    "fixed_views",
    "in_sight",
    "near_max",
    "pool_max",
    "thin_indices",
    "write_model",
]

#: the files of ``meshfit/report_static`` copied beside each report, in ``report/``
STATIC_FILES = ("three.min.js", "three.LICENSE.txt", "viewer.js")
#: largest vertex count of the 3D view's model: the grids are thinned to it (every k-th row
#: and column, boundaries kept), keeping the page light enough to open and turn at once
VIEWER_VERTICES = 60_000
#: how far the fixed viewpoints look down on the model (radians)
VIEW_ELEVATION = np.radians(20.0)
#: glTF component types and buffer targets
_FLOAT, _UBYTE, _USHORT, _UINT = 5126, 5121, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


@dataclass(frozen=True)
class View:
    """A fixed viewpoint: its name, viewing direction and up vector (model space)."""

    name: str
    view: tuple[float, float, float]
    up: tuple[float, float, float]


def fixed_views(view: ArrayLike, up: ArrayLike) -> list[View]:
    """Four viewpoints round the model, a quarter turn apart about ``up``, each looking
    down by :data:`VIEW_ELEVATION` so that tops are seen too: front (along ``view``), right,
    back and left. Printed side by side they show every side of the model but its
    underside."""
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    h = np.asarray(view, dtype=np.float64)
    h = h - (h @ u) * u
    h = h / np.linalg.norm(h)
    side = np.cross(u, h)
    out = []
    for name, angle in (("front", 0.0), ("right", 90.0), ("back", 180.0), ("left", 270.0)):
        a = np.radians(angle)
        d = np.cos(a) * h + np.sin(a) * side
        d = np.cos(VIEW_ELEVATION) * d - np.sin(VIEW_ELEVATION) * u
        out.append(View(name, tuple(float(x) for x in d), tuple(float(x) for x in u)))  # type: ignore[arg-type]
    return out


def in_sight(
    points: NDArray[np.float64], camera: Camera, depth: NDArray[np.float64], slack: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Image positions of ``points`` and whether each is in sight on a render.

    Parameters
    ----------
    points : (n, 3) float64
        Points on the rendered surface.
    camera : Camera
        The render's camera (with bounds).
    depth : (h, w) float64
        The render's depth (:func:`meshfit.render.render`'s ``depth_out``).
    slack : float
        Model units a point may lie behind the drawn surface and still count as on it.

    Returns
    -------
    xy : (n, 2) float64
        Column and row, pixels.
    visible : (n,) bool
        Inside the image and not hidden: no drawn surface within a pixel of it is nearer
        than ``slack`` in front of it.
    """
    X = project(points, camera)
    h, w = depth.shape
    col = np.floor(X[:, 0]).astype(np.int64)
    row = np.floor(X[:, 1]).astype(np.int64)
    visible = (col >= 1) & (col < w - 1) & (row >= 1) & (row < h - 1)
    for i in np.flatnonzero(visible):
        near = depth[row[i] - 1 : row[i] + 2, col[i] - 1 : col[i] + 2]
        drawn = near[np.isfinite(near)]
        visible[i] = drawn.size > 0 and X[i, 2] >= drawn.min() - slack
    return X[:, :2], visible


def near_max(
    targets: NDArray[np.float64], sources: NDArray[np.float64], values: NDArray[np.float64]
) -> NDArray[np.float64]:
    """At each target point, the largest value among the source points nearest to it.

    Carries the scan's distances to a surface (one per scan vertex) onto that surface's
    vertices: a surface that passes through scan points has no deviation at its own
    vertices, while the scan between them may lie far from it. Each target takes the
    largest value of its few nearest sources, so no vertex misses the scan around it.

    Parameters
    ----------
    targets : (n, 3) float64
    sources : (m, 3) float64
    values : (m,) float64

    Returns
    -------
    (n,) float64
    """
    from scipy.spatial import cKDTree

    if len(sources) == 0 or len(targets) == 0:
        return np.zeros(len(targets))
    k = min(6, len(sources))
    _, idx = cKDTree(sources).query(targets, k=k, workers=-1)
    return np.asarray(values)[idx.reshape(len(targets), k)].max(axis=1)


def thin_indices(nu: int, nv: int, step: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Every ``step``-th row and column of a grid, its last ones kept."""
    rows = np.unique(np.append(np.arange(0, nu, step), nu - 1))
    cols = np.unique(np.append(np.arange(0, nv, step), nv - 1))
    return rows, cols


def pool_max(values: NDArray[np.float64], step: int) -> NDArray[np.float64]:
    """Each grid value replaced by the largest within ``step // 2`` rows and columns of it,
    so that a thinned grid (`thin_indices`) keeps the peaks between its kept vertices."""
    if step <= 1:
        return values
    from scipy.ndimage import maximum_filter

    return maximum_filter(values, size=2 * (step // 2) + 1, mode="nearest")


def _srgb_to_linear(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """glTF vertex colours are linear; the heat map's colours are sRGB."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def deviation_glb(
    grids: list[NDArray[np.float64]],
    deviation: list[NDArray[np.float64]],
    vmax: float,
    *,
    max_vertices: int = VIEWER_VERTICES,
) -> bytes:
    """A GLB of surface grids coloured by their deviation.

    Parameters
    ----------
    grids : list of (nu, nv, 3) float64
        The surface of each patch, sampled on a grid (model units).
    deviation : list of (nu, nv) float64
        Deviation at each grid vertex, percent of the bbox diagonal.
    vmax : float
        Deviation shown red (percent); 0 blue (:func:`meshfit.render.heat_colors`).
    max_vertices : int
        The grids are thinned alike to at most about this many vertices in all; each kept
        vertex takes the largest deviation around it.

    Returns
    -------
    bytes
        glTF 2.0 binary: a node and mesh ``patch N`` per grid, each one indexed triangle
        primitive with ``POSITION`` (float), ``COLOR_0`` (RGBA unsigned bytes, linear) and
        ``_DEVIATION`` (float, percent).
    """
    from meshfit.springs import grid_triangles

    total = sum(g.shape[0] * g.shape[1] for g in grids)
    step = max(1, int(np.ceil(np.sqrt(total / max(int(max_vertices), 1)))))
    blob = bytearray()
    views: list[dict] = []
    accessors: list[dict] = []
    meshes: list[dict] = []

    def add(data: NDArray, target: int, **accessor) -> int:
        while len(blob) % 4:
            blob.append(0)
        raw = np.ascontiguousarray(data).tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw),
                      "target": target})  # fmt: skip
        blob.extend(raw)
        accessors.append({"bufferView": len(views) - 1, **accessor})
        return len(accessors) - 1

    for p, (G, D) in enumerate(zip(grids, deviation, strict=True)):
        rows, cols = thin_indices(G.shape[0], G.shape[1], step)
        X = G[np.ix_(rows, cols)].reshape(-1, 3).astype(np.float32)
        dev = pool_max(np.asarray(D, dtype=np.float64), step)[np.ix_(rows, cols)].reshape(-1)
        rgb = _srgb_to_linear(heat_colors(dev, vmax))
        rgba = np.rint(np.concatenate([rgb, np.ones((len(rgb), 1))], axis=1) * 255)
        F = grid_triangles(len(rows), len(cols))
        small = len(X) < 65536
        attributes = {
            "POSITION": add(X, _ARRAY_BUFFER, componentType=_FLOAT, count=len(X), type="VEC3",
                            min=X.min(axis=0).tolist(), max=X.max(axis=0).tolist()),
            "COLOR_0": add(rgba.astype(np.uint8), _ARRAY_BUFFER, componentType=_UBYTE,
                           normalized=True, count=len(X), type="VEC4"),
            "_DEVIATION": add(dev.astype(np.float32), _ARRAY_BUFFER, componentType=_FLOAT,
                              count=len(X), type="SCALAR"),
        }  # fmt: skip
        index = add(
            F.astype(np.uint16 if small else np.uint32).reshape(-1),
            _ELEMENT_ARRAY_BUFFER,
            componentType=_USHORT if small else _UINT,
            count=F.size,
            type="SCALAR",
        )
        meshes.append(
            {"name": f"patch {p}", "primitives": [{"attributes": attributes, "indices": index}]}
        )
    while len(blob) % 4:
        blob.append(0)
    doc = {
        "asset": {"version": "2.0", "generator": "meshfit report"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(meshes)))}],
        "nodes": [{"mesh": i, "name": m["name"]} for i, m in enumerate(meshes)],
        "meshes": meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    if blob:
        chunks += struct.pack("<II", len(blob), 0x004E4942) + bytes(blob)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def write_model(folder: str | Path, glb: bytes) -> list[str]:
    """Write ``model.js`` into ``folder``: the GLB's bytes in base64 set on ``window``
    (the page's view cannot read files; its "save model.glb" button writes them out, so
    the model is not stored twice). Returns its name."""
    folder = Path(folder)
    script = "window.MESHFIT_MODEL = " + json.dumps(base64.b64encode(glb).decode()) + ";\n"
    write_text(folder / "model.js", script)
    return ["model.js"]


def copy_static(folder: str | Path) -> list[str]:
    """Copy :data:`STATIC_FILES` (the three.js bundle, its licence, the viewer script)
    from the package into ``folder``; their names."""
    folder = Path(folder)
    static = resources.files("meshfit") / "report_static"
    for name in STATIC_FILES:
        write_bytes(folder / name, (static / name).read_bytes())
    return list(STATIC_FILES)
