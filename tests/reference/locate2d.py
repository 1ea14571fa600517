"""Obviously-correct oracle for meshfit._kernels.locate2d: every triangle tried."""

from __future__ import annotations

import numpy as np


def locate_all(uv, T, q):
    """The triangle whose smallest barycentric coordinate of each point is largest, and
    those coordinates."""
    a, b, c = uv[T[:, 0]], uv[T[:, 1]], uv[T[:, 2]]
    out_t = np.empty(len(q), dtype=np.int64)
    out_b = np.empty((len(q), 3))
    for i, p in enumerate(q):
        v0, v1, v2 = b - a, c - a, p - a
        den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
        l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
        bary = np.stack([1.0 - l1 - l2, l1, l2], 1)
        k = int(np.argmax(bary.min(axis=1)))
        out_t[i], out_b[i] = k, bary[k]
    return out_t, out_b
