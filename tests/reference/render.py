"""Slow reference of the z-buffer rasteriser kernel (meshfit._kernels.render.raster)."""

from __future__ import annotations

import math

import numpy as np


def raster(P, color, shade, uv, checker, image, depth):
    """Pixel-by-pixel loops over every triangle and every pixel of the image."""
    h, w = depth.shape
    for t in range(P.shape[0]):
        (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = P[t]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0.0:
            continue
        for py in range(h):
            for px in range(w):
                cx, cy = px + 0.5, py + 0.5
                b0 = ((x1 - cx) * (y2 - cy) - (x2 - cx) * (y1 - cy)) / area
                b1 = ((x2 - cx) * (y0 - cy) - (x0 - cx) * (y2 - cy)) / area
                b2 = 1.0 - b0 - b1
                if min(b0, b1, b2) < 0.0:
                    continue
                z = b0 * z0 + b1 * z1 + b2 * z2
                if z <= depth[py, px]:
                    continue
                depth[py, px] = z
                b = np.array([b0, b1, b2])
                s = b @ shade[t]
                f = 1.0
                if checker > 0:
                    u, v = b @ uv[t]
                    if (math.floor(u * checker) + math.floor(v * checker)) % 2:
                        f = 0.55
                image[py, px] = np.clip((b @ color[t]) * s * f, 0.0, 1.0)


def mesh_inputs(V, X, F, view, ambient, flat, face_color, vertex_color, uv, checker):
    """Per-corner arrays of an indexed mesh for `raster` (numpy gathers): what
    `meshfit._kernels.render.raster_mesh` draws, triangle by triangle."""
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    if flat:
        n = fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
        shade = np.repeat((ambient + (1.0 - ambient) * np.abs(n @ view))[:, None], 3, axis=1)
    else:
        vn = np.zeros_like(V)
        for k in range(3):
            np.add.at(vn, F[:, k], fn)
        vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
        shade = (ambient + (1.0 - ambient) * np.abs(vn @ view))[F]
    if len(face_color) == len(F):
        color = np.repeat(face_color[:, None, :], 3, axis=1)
    elif len(vertex_color) == len(V):
        color = vertex_color[F]
    else:
        color = np.full((len(F), 3, 3), 0.82)
    use_uv = checker > 0 and len(uv) == len(V)
    cuv = uv[F] if use_uv else np.zeros((len(F), 3, 2))
    return X[F], color, shade, cuv, (checker if use_uv else 0.0)
