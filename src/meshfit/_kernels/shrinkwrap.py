"""Numba kernels of shrink wrapping: point location in spherical triangulations.

No validation here: the public wrappers in :mod:`meshfit.shrinkwrap` check every input and
pass contiguous arrays. ``fastmath`` stays off because sign tests pick the next face.

Conventions: ``S (nv, 3) f8`` unit vectors (vertices of a spherical triangulation, every
triangle positively oriented: ``det[a, b, c] > 0``), ``F (nf, 3) i8`` faces, ``FN (nf, 3) i8``
face across edge ``k = (F[f, k], F[f, (k + 1) % 3])``. A query ``q`` lies inside face ``f``
when ``det[F[f, k], F[f, k+1], q] >= 0`` for the three edges; its barycentric coordinates are
those of the central projection of ``q`` onto the plane of the flat triangle: coordinate
``(k + 2) % 3`` is proportional to the edge-``k`` determinant.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from meshfit._kernels import inner


@inner
def _det3(a0, a1, a2, b0, b1, b2, c0, c1, c2):
    return a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0)


@inner
def _edge_dets(S, F, f, q, out):
    """The three edge determinants of ``q`` in face ``f`` into ``out (3,)``."""
    for k in range(3):
        a = F[f, k]
        b = F[f, (k + 1) % 3]
        out[k] = _det3(S[a, 0], S[a, 1], S[a, 2], S[b, 0], S[b, 1], S[b, 2], q[0], q[1], q[2])


@inner
def _bary_from_dets(e, out):
    """Barycentric coordinates (clipped at 0, normalised) from edge determinants."""
    b0 = max(e[1], 0.0)
    b1 = max(e[2], 0.0)
    b2 = max(e[0], 0.0)
    s = b0 + b1 + b2
    if s > 0.0:
        out[0] = b0 / s
        out[1] = b1 / s
        out[2] = b2 / s
    else:
        out[0] = 1.0 / 3.0
        out[1] = 1.0 / 3.0
        out[2] = 1.0 / 3.0


@njit(cache=True, nogil=True, fastmath=False)
def _walk_one(S, F, FN, f, q, max_steps, e):
    """Visibility walk from face ``f`` toward ``q``; returns (face, found)."""
    prev = -1
    for step in range(max_steps):
        _edge_dets(S, F, f, q, e)
        worst = -1
        wv = 0.0
        second = -1
        for k in range(3):
            if e[k] < 0.0:
                if worst < 0 or e[k] < wv:
                    if worst >= 0:
                        second = worst
                    worst = k
                    wv = e[k]
                else:
                    second = k
        if worst < 0:
            return f, True
        k = worst
        # do not step straight back; alternate on odd steps to break cycles
        if second >= 0 and (FN[f, k] == prev or step % 7 == 6):
            k = second
        nxt = FN[f, k]
        if nxt < 0:
            return f, False
        prev = f
        f = nxt
    return f, False


@njit(cache=True, nogil=True, fastmath=False, parallel=True)
def locate_sphere(S, F, FN, start, Q, max_steps):
    """Kernel of `shrinkwrap.sphere.SphereMap.locate`: walk each query from its start face.

    S (nv, 3) f8; F, FN (nf, 3) i8; start (n,) i8; Q (n, 3) f8 ->
    face (n,) i8, bary (n, 3) f8, found (n,) bool.
    """
    n = Q.shape[0]
    face = np.empty(n, dtype=np.int64)
    bary = np.empty((n, 3))
    found = np.zeros(n, dtype=np.bool_)
    for i in prange(n):  # iteration i writes row i only
        e = np.empty(3)
        f, ok = _walk_one(S, F, FN, start[i], Q[i], max_steps, e)
        face[i] = f
        found[i] = ok
        _edge_dets(S, F, f, Q[i], e)
        _bary_from_dets(e, bary[i])
    return face, bary, found


@njit(cache=True, nogil=True, fastmath=False, parallel=True)
def locate_sphere_brute(S, F, Q):
    """Kernel of the fallback of `SphereMap.locate`: the face whose smallest edge determinant
    (divided by the edge's chord length) is largest, over all faces.

    S (nv, 3) f8; F (nf, 3) i8; Q (n, 3) f8 -> face (n,) i8, bary (n, 3) f8.
    """
    n = Q.shape[0]
    nf = F.shape[0]
    face = np.empty(n, dtype=np.int64)
    bary = np.empty((n, 3))
    for i in prange(n):  # iteration i writes row i only
        e = np.empty(3)
        best = -np.inf
        bf = 0
        for f in range(nf):
            _edge_dets(S, F, f, Q[i], e)
            m = np.inf
            for k in range(3):
                a = F[f, k]
                b = F[f, (k + 1) % 3]
                d0 = S[a, 0] - S[b, 0]
                d1 = S[a, 1] - S[b, 1]
                d2 = S[a, 2] - S[b, 2]
                ln = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                v = e[k] / ln if ln > 0.0 else e[k]
                if v < m:
                    m = v
            if m > best:
                best = m
                bf = f
        face[i] = bf
        _edge_dets(S, F, bf, Q[i], e)
        _bary_from_dets(e, bary[i])
    return face, bary


@njit(cache=True, nogil=True, fastmath=False, parallel=True)
def spherical_dets(S, F):
    """Kernel of `shrinkwrap.sphere.spherical_orientation`: ``det[a, b, c]`` per face.

    S (nv, 3) f8; F (nf, 3) i8 -> (nf,) f8.
    """
    nf = F.shape[0]
    out = np.empty(nf)
    for f in prange(nf):  # iteration f writes row f only
        a = F[f, 0]
        b = F[f, 1]
        c = F[f, 2]
        out[f] = _det3(
            S[a, 0], S[a, 1], S[a, 2], S[b, 0], S[b, 1], S[b, 2], S[c, 0], S[c, 1], S[c, 2]
        )
    return out
