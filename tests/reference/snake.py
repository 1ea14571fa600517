"""Slow, obviously-correct oracles for `meshfit.curves.snake` and `meshfit.curves.color`.

Written as plain per-sample / per-vertex Python loops straight from the thesis' formulas,
independently of the numba kernels.
"""

from __future__ import annotations

import numpy as np

from meshfit.mesh import Mesh


def snake_forces(x, *, closed, w_fair=1.0, w_curv=0.0, w_arc=1.0, levels=1):
    """Coarse-to-fine membrane, thin-plate and arc-length forces (thesis eq. 3.11-3.16)."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    out = np.zeros((n, 3))
    if n < 3:
        return out

    def at(j):
        if closed:
            return x[j % n]
        return x[j] if 0 <= j < n else None

    for i in range(n):
        fair, arc, curv = np.zeros(3), np.zeros(3), np.zeros(3)
        wf = wc = 0.0
        for lev in range(levels):
            k, w = 2**lev, 0.5**lev
            if closed and 2 * k >= n:
                break
            left, right = at(i - k), at(i + k)
            if left is None or right is None:
                break
            fair += w * ((left + right) / 2 - x[i])
            dl, dr = np.linalg.norm(left - x[i]), np.linalg.norm(right - x[i])
            if dl != dr:
                far = left if dl > dr else right
                arc += w * 0.5 * abs(dl - dr) * (far - x[i]) / np.linalg.norm(far - x[i])
            wf += w
            left2, right2 = at(i - 2 * k), at(i + 2 * k)
            if left2 is not None and right2 is not None and not (closed and 4 * k >= n):
                # bi-Laplacian of the curvature vectors C_j = x_{j-k} + x_{j+k} - 2 x_j
                c_left = left2 + x[i] - 2 * left
                c_mid = left + right - 2 * x[i]
                c_right = x[i] + right2 - 2 * right
                curv += w * -(c_left - 2 * c_mid + c_right) / 8
                wc += w
        if wf:
            out[i] = (w_fair * fair + w_arc * arc) / wf
        if wc:
            out[i] += w_curv * curv / wc
    return out


def thesis_gradients(mesh: Mesh, values, normals):
    """Eq. 3.17 per vertex: sum over the one-ring of (S_j - S_0)(v_j - v_0), made tangent."""
    nv = mesh.n_vertices
    nbrs = [set() for _ in range(nv)]
    for a, b, c in mesh.faces:
        nbrs[a] |= {b, c}
        nbrs[b] |= {a, c}
        nbrs[c] |= {a, b}
    out = np.zeros((nv, 3))
    for i in range(nv):
        n = normals[i]
        for j in nbrs[i]:
            e = mesh.vertices[j] - mesh.vertices[i]
            e = e - np.dot(e, n) * n
            out[i] += (values[j] - values[i]) * e
    return out
