"""Slow reference of the boundary-loop tracing (meshfit._kernels.topology.trace_loops)."""

from __future__ import annotations

import numpy as np


def trace_loops(t, h):
    """Loops of boundary half-edges ``t[i] -> h[i]`` as lists of tails (dict of lists)."""
    by_tail: dict[int, list[int]] = {}
    for i, v in enumerate(t.tolist()):
        by_tail.setdefault(v, []).append(i)
    used = np.zeros(len(t), dtype=bool)
    loops = []
    for s in range(len(t)):
        if used[s]:
            continue
        loop = []
        i = s
        while not used[i]:
            used[i] = True
            loop.append(int(t[i]))
            nxt = [j for j in by_tail.get(int(h[i]), []) if not used[j]]
            if not nxt:
                break
            i = nxt[0]
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops
