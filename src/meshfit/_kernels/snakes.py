"""Numba kernels of many open surface snakes relaxed together (``meshfit.layout.auto``).

The curves are stored one after another: curve ``c`` holds rows ``start[c]:start[c + 1]``.
Each kernel applies the single-curve kernel of :mod:`meshfit._kernels.snake` to every curve,
so the forces and moves are exactly those of :func:`meshfit.curves.relax_snake`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels.snake import capped_moves, snake_forces


@njit(cache=True, nogil=True, fastmath=False)
def forces_many(x, start, levels, w_fair, w_curv, w_arc):
    """Snake forces of every open curve; x (n, 3) f8, start (k + 1,) i8, levels (k,) i8.

    Kernel of the batched relaxation in `meshfit.layout.auto`.
    """
    out = np.zeros_like(x)
    for c in range(start.shape[0] - 1):
        a = start[c]
        b = start[c + 1]
        out[a:b] = snake_forces(x[a:b], False, w_fair, w_curv, w_arc, levels[c])
    return out


@njit(cache=True, nogil=True, fastmath=False)
def moves_many(x, force, nrm, fixed, start, gain, step, floor):
    """Capped tangent moves of every open curve; x, force, nrm (n, 3) f8, fixed (n,) bool,
    start (k + 1,) i8, floor (k,) f8 -> (n, 3) f8.

    Kernel of the batched relaxation in `meshfit.layout.auto`.
    """
    out = np.zeros_like(x)
    for c in range(start.shape[0] - 1):
        a = start[c]
        b = start[c + 1]
        ids = np.arange(b - a)
        out[a:b] = capped_moves(
            x[a:b], force[a:b], ids, nrm[a:b], fixed[a:b], False, gain, step, floor[c]
        )
    return out


@njit(cache=True, nogil=True, fastmath=False)
def curve_max(values, start):
    """Largest of ``values (n,) f8`` per curve (0 for an empty curve) -> (k,) f8."""
    k = start.shape[0] - 1
    out = np.zeros(k)
    for c in range(k):
        for i in range(start[c], start[c + 1]):
            if values[i] > out[c]:
                out[c] = values[i]
    return out
