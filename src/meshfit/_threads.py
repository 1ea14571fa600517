"""Independent items on a pool of threads, results in order (private).

The numba kernels release the GIL (``nogil=True``), so patches resampled or fitted on
threads run in parallel on several cores.
"""

from __future__ import annotations

import numbers
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed

from meshfit.errors import InputError


def n_workers(workers: int | None) -> int:
    """``workers``, checked (an integer >= 1), or every core when None."""
    if workers is None:
        return os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, numbers.Integral) or workers < 1:
        raise InputError(f"workers must be an integer >= 1, got {workers!r}")
    return int(workers)


def map_threads(
    fn: Callable,
    items: Sequence,
    workers: int,
    *,
    cost: Sequence[float] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list:
    """``[fn(x) for x in items]`` on up to ``workers`` threads, results in order.

    With ``cost`` (an estimate per item) the items start in order of decreasing cost, so
    the largest does not start last and leave the other workers idle at the end.
    ``progress(done, total)`` is called in the calling thread after each item. The first
    exception raised by ``fn`` is raised again here (the items not started are dropped).
    """
    n = len(items)
    if workers <= 1 or n <= 1:
        out = []
        for i, x in enumerate(items):
            out.append(fn(x))
            if progress is not None:
                progress(i + 1, n)
        return out
    order = range(n) if cost is None else sorted(range(n), key=lambda i: (-cost[i], i))
    out = [None] * n
    with ThreadPoolExecutor(max_workers=min(workers, n)) as pool:
        futures = {pool.submit(fn, items[i]): i for i in order}
        try:
            for done, fut in enumerate(as_completed(futures), start=1):
                out[futures[fut]] = fut.result()
                if progress is not None:
                    progress(done, n)
        except BaseException:
            for fut in futures:
                fut.cancel()
            raise
    return out
