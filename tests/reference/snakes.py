"""Slow oracles of the batched snake kernels (``_kernels.snakes``): one curve at a time
through the public single-curve functions."""

from __future__ import annotations

import numpy as np

from . import snake as single


def forces_many(x, start, levels, w_fair, w_curv, w_arc):
    out = np.zeros_like(x)
    for c in range(len(start) - 1):
        a, b = start[c], start[c + 1]
        out[a:b] = single.snake_forces(
            x[a:b], closed=False, w_fair=w_fair, w_curv=w_curv, w_arc=w_arc, levels=levels[c]
        )
    return out


def moves_many(x, force, nrm, fixed, start, gain, step, floor):
    """Tangent part of ``gain * force`` per point, capped at ``step`` times the mean of its
    adjacent segment lengths (at least the curve's ``floor``)."""
    out = np.zeros_like(x)
    for c in range(len(start) - 1):
        a, b = start[c], start[c + 1]
        for i in range(a, b):
            if fixed[i]:
                continue
            g = gain * force[i]
            t = g - (g @ nrm[i]) * nrm[i]
            segs = [np.linalg.norm(x[j] - x[i]) for j in (i - 1, i + 1) if a <= j < b]
            cap = step * max(np.mean(segs), floor[c])
            ln = np.linalg.norm(t)
            out[i] = t * (cap / ln) if ln > cap else t
    return out
