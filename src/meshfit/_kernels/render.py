"""Z-buffer rasterisation of triangles with per-corner colours, shading and (u, v)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, fastmath=False)
def raster(P, color, shade, uv, checker, image, depth):
    """Rasterise triangles into ``image (h, w, 3)`` and ``depth (h, w)`` in place.

    P (m, 3, 3) screen x, y (pixels, y down) and depth (larger is nearer) per corner;
    color (m, 3, 3) per-corner RGB in [0, 1]; shade (m, 3) per-corner light factor;
    uv (m, 3, 2) per-corner parameters; checker: squares per unit of (u, v) (0: no texture,
    else the colour is darkened on odd squares). Wrapped by ``meshfit.render.render``.
    """
    h, w = depth.shape
    for t in range(P.shape[0]):
        x0, y0, z0 = P[t, 0, 0], P[t, 0, 1], P[t, 0, 2]
        x1, y1, z1 = P[t, 1, 0], P[t, 1, 1], P[t, 1, 2]
        x2, y2, z2 = P[t, 2, 0], P[t, 2, 1], P[t, 2, 2]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0.0 or not np.isfinite(area):
            continue
        xmin = max(int(np.floor(min(x0, min(x1, x2)))), 0)
        xmax = min(int(np.ceil(max(x0, max(x1, x2)))), w - 1)
        ymin = max(int(np.floor(min(y0, min(y1, y2)))), 0)
        ymax = min(int(np.ceil(max(y0, max(y1, y2)))), h - 1)
        inv = 1.0 / area
        for py in range(ymin, ymax + 1):
            cy = py + 0.5
            for px in range(xmin, xmax + 1):
                cx = px + 0.5
                b0 = ((x1 - cx) * (y2 - cy) - (x2 - cx) * (y1 - cy)) * inv
                b1 = ((x2 - cx) * (y0 - cy) - (x0 - cx) * (y2 - cy)) * inv
                b2 = 1.0 - b0 - b1
                if b0 < 0.0 or b1 < 0.0 or b2 < 0.0:
                    continue
                z = b0 * z0 + b1 * z1 + b2 * z2
                if z <= depth[py, px]:
                    continue
                depth[py, px] = z
                s = b0 * shade[t, 0] + b1 * shade[t, 1] + b2 * shade[t, 2]
                f = 1.0
                if checker > 0.0:
                    u = b0 * uv[t, 0, 0] + b1 * uv[t, 1, 0] + b2 * uv[t, 2, 0]
                    v = b0 * uv[t, 0, 1] + b1 * uv[t, 1, 1] + b2 * uv[t, 2, 1]
                    k = int(np.floor(u * checker)) + int(np.floor(v * checker))
                    if k % 2 != 0:
                        f = 0.55
                for c in range(3):
                    col = b0 * color[t, 0, c] + b1 * color[t, 1, c] + b2 * color[t, 2, c]
                    image[py, px, c] = min(max(col * s * f, 0.0), 1.0)
