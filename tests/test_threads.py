"""`meshfit._threads`: items on a thread pool, results in order."""

from __future__ import annotations

import threading

import pytest

from meshfit._threads import map_threads, n_workers
from meshfit.errors import InputError


@pytest.mark.parametrize("workers", [1, 2, 4])
def test_results_come_back_in_the_order_of_the_items(workers):
    seen = []
    out = map_threads(lambda x: x * x, list(range(20)), workers,
                      progress=lambda done, n: seen.append((done, n)))  # fmt: skip
    assert out == [x * x for x in range(20)]
    assert seen == [(k, 20) for k in range(1, 21)]


def test_costly_items_start_first():
    started = []
    lock = threading.Lock()

    def fn(x):
        with lock:
            started.append(x)
        return x

    # the pool takes the submitted items first in, first out: 9 and 5 go to the two
    # threads (either may log first), 1 starts last
    out = map_threads(fn, [5, 1, 9, 3], 2, cost=[5.0, 1.0, 9.0, 3.0])
    assert out == [5, 1, 9, 3]
    assert sorted(started[:2]) == [5, 9] and started[-1] == 1


def test_progress_runs_in_the_calling_thread():
    caller = threading.get_ident()
    threads = set()
    map_threads(lambda x: x, list(range(8)), 2,
                progress=lambda done, n: threads.add(threading.get_ident()))  # fmt: skip
    assert threads == {caller}


def test_the_first_error_is_raised_again():
    def fn(x):
        if x == 3:
            raise ValueError("item 3")
        return x

    with pytest.raises(ValueError, match="item 3"):
        map_threads(fn, list(range(6)), 2)
    with pytest.raises(ValueError, match="item 3"):
        map_threads(fn, list(range(6)), 1)


def test_worker_counts_are_checked():
    assert n_workers(3) == 3
    assert n_workers(None) >= 1
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="workers must be an integer >= 1"):
            n_workers(bad)
