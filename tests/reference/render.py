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
