"""Z-buffer rasterisation of triangles with per-corner colours, shading and (u, v)."""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner


@inner
def _centre_box(x0, x1, x2, y0, y1, y2, w, h):
    """The pixels of a (h, w) image whose centres (px + 0.5, py + 0.5) lie in a triangle's
    bounding box: ``xmin, xmax, ymin, ymax`` (empty when min > max, as for most triangles
    of a dense mesh, which are smaller than a pixel)."""
    xmin = max(int(np.ceil(min(x0, min(x1, x2)) - 0.5)), 0)
    xmax = min(int(np.floor(max(x0, max(x1, x2)) - 0.5)), w - 1)
    ymin = max(int(np.ceil(min(y0, min(y1, y2)) - 0.5)), 0)
    ymax = min(int(np.floor(max(y0, max(y1, y2)) - 0.5)), h - 1)
    return xmin, xmax, ymin, ymax


@inner
def _fill(P, color, shade, uv, checker, image, depth):
    """Rasterise one triangle: P (3, 3) screen x, y and depth per corner, color (3, 3),
    shade (3,), uv (3, 2); see `raster`. Inlined into its callers: as a call per triangle,
    with its array arguments, it costs more than the fill itself when most triangles cover
    a pixel or less."""
    h, w = depth.shape
    x0, y0, z0 = P[0, 0], P[0, 1], P[0, 2]
    x1, y1, z1 = P[1, 0], P[1, 1], P[1, 2]
    x2, y2, z2 = P[2, 0], P[2, 1], P[2, 2]
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if area == 0.0 or not np.isfinite(area):
        return
    xmin, xmax, ymin, ymax = _centre_box(x0, x1, x2, y0, y1, y2, w, h)
    if xmin > xmax or ymin > ymax:
        return
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
            s = b0 * shade[0] + b1 * shade[1] + b2 * shade[2]
            f = 1.0
            if checker > 0.0:
                u = b0 * uv[0, 0] + b1 * uv[1, 0] + b2 * uv[2, 0]
                v = b0 * uv[0, 1] + b1 * uv[1, 1] + b2 * uv[2, 1]
                k = int(np.floor(u * checker)) + int(np.floor(v * checker))
                if k % 2 != 0:
                    f = 0.55
            for c in range(3):
                col = b0 * color[0, c] + b1 * color[1, c] + b2 * color[2, c]
                image[py, px, c] = min(max(col * s * f, 0.0), 1.0)


@njit(cache=True, nogil=True, fastmath=False)
def raster(P, color, shade, uv, checker, image, depth):
    """Rasterise triangles into ``image (h, w, 3)`` and ``depth (h, w)`` in place.

    P (m, 3, 3) screen x, y (pixels, y down) and depth (larger is nearer) per corner;
    color (m, 3, 3) per-corner RGB in [0, 1]; shade (m, 3) per-corner light factor;
    uv (m, 3, 2) per-corner parameters; checker: squares per unit of (u, v) (0: no texture,
    else the colour is darkened on odd squares).
    """
    for t in range(P.shape[0]):
        _fill(P[t], color[t], shade[t], uv[t], checker, image, depth)


@inner
def _light(nx, ny, nz, view, ambient):
    """Head light: ``ambient + (1 - ambient) |n . view|`` for the unit normal along n."""
    norm = max(np.sqrt(nx * nx + ny * ny + nz * nz), 1e-300)
    return ambient + (1.0 - ambient) * abs((nx * view[0] + ny * view[1] + nz * view[2]) / norm)


@njit(cache=True, nogil=True, fastmath=False)
def raster_mesh(V, X, F, view, ambient, flat, face_color, vertex_color, uv, checker, image, depth):
    """Rasterise an indexed mesh (what `meshfit.render.render` draws), in place.

    V (n, 3) model positions (normals); X (n, 3) screen positions; F (m, 3); view (3,) the
    viewing direction; flat: light per face (else per vertex from area-weighted normals,
    interpolated); face_color (m, 3) or vertex_color (n, 3) RGB in [0, 1] (the other of
    shape (0, 3); both empty: light grey); uv (n, 2) with checker > 0, else (0, 2).
    Each triangle is drawn by the routine of `raster`.
    """
    m = F.shape[0]
    lit = np.empty(V.shape[0] if not flat else 0)
    if not flat:  # area-weighted face normals summed per vertex
        acc = np.zeros((V.shape[0], 3))
        for t in range(m):
            a, b, c = F[t, 0], F[t, 1], F[t, 2]
            ux, uy, uz = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
            wx, wy, wz = V[c, 0] - V[a, 0], V[c, 1] - V[a, 1], V[c, 2] - V[a, 2]
            nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
            for k in range(3):
                acc[F[t, k], 0] += nx
                acc[F[t, k], 1] += ny
                acc[F[t, k], 2] += nz
        for i in range(V.shape[0]):
            lit[i] = _light(acc[i, 0], acc[i, 1], acc[i, 2], view, ambient)
    P = np.empty((3, 3))
    color = np.full((3, 3), 0.82)
    shade = np.empty(3)
    cuv = np.zeros((3, 2))
    use_uv = checker > 0.0 and uv.shape[0] == V.shape[0]
    h, w = depth.shape
    for t in range(m):
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        xmin, xmax, ymin, ymax = _centre_box(
            X[a, 0], X[b, 0], X[c, 0], X[a, 1], X[b, 1], X[c, 1], w, h
        )
        if xmin > xmax or ymin > ymax:
            continue  # no pixel centre in its bounding box: nothing to gather
        for k in range(3):
            v = F[t, k]
            for d in range(3):
                P[k, d] = X[v, d]
            if face_color.shape[0] == m:
                for d in range(3):
                    color[k, d] = face_color[t, d]
            elif vertex_color.shape[0] == V.shape[0]:
                for d in range(3):
                    color[k, d] = vertex_color[v, d]
            if use_uv:
                cuv[k, 0] = uv[v, 0]
                cuv[k, 1] = uv[v, 1]
            if not flat:
                shade[k] = lit[v]
        if flat:
            ux, uy, uz = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
            wx, wy, wz = V[c, 0] - V[a, 0], V[c, 1] - V[a, 1], V[c, 2] - V[a, 2]
            s = _light(uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx, view, ambient)
            shade[0] = s
            shade[1] = s
            shade[2] = s
        _fill(P, color, shade, cuv, checker if use_uv else 0.0, image, depth)
