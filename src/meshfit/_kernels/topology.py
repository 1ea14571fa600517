"""Mesh connectivity kernels."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def trace_loops(t, h, nv):
    """Chain boundary half-edges ``t[i] -> h[i]`` into loops; kernel of
    `meshfit.mesh.topology.boundary_loops`.

    From each unused half-edge in index order, the successor of a half-edge is the unused
    half-edge of lowest index leaving its head; a loop ends when none is left. Returns the
    tails in loop order (k,) and the loop starts (n_loops + 1,).
    """
    k = t.shape[0]
    # half-edges by tail vertex, in index order (a stable counting sort)
    count = np.zeros(nv + 1, dtype=np.int64)
    for i in range(k):
        count[t[i] + 1] += 1
    for v in range(nv):
        count[v + 1] += count[v]
    fill = count[:-1].copy()
    by_tail = np.empty(k, dtype=np.int64)
    for i in range(k):
        by_tail[fill[t[i]]] = i
        fill[t[i]] += 1
    nxt_unused = count[:-1].copy()  # first entry of each vertex's list that may be unused
    used = np.zeros(k, dtype=np.bool_)
    out = np.empty(k, dtype=np.int64)
    starts = [0]
    n = 0
    for s in range(k):
        if used[s]:
            continue
        i = s
        while not used[i]:
            used[i] = True
            out[n] = t[i]
            n += 1
            v = h[i]
            j = -1
            p = nxt_unused[v]
            while p < count[v + 1]:
                if not used[by_tail[p]]:
                    j = by_tail[p]
                    break
                p += 1
            nxt_unused[v] = p
            if j < 0:
                break
            i = j
        starts.append(n)
    return out, np.array(starts, dtype=np.int64)
