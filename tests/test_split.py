"""A kernel's parallel loop run from Python (`meshfit._kernels.split`): every index once,
errors raised to the caller, callers on several threads at once, and the same bits at any
thread count."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from numba import config
from numpy.testing import assert_array_equal

import meshfit._kernels as kernels
from meshfit._kernels import bvh, geometry, split
from meshfit.mesh.locate import build_tree
from tests.reference import geometry as ref_geometry


@pytest.fixture(params=[1, 2, 3, 8])
def threads(request, monkeypatch):
    monkeypatch.setattr(config, "NUMBA_NUM_THREADS", request.param)
    return request.param


@pytest.mark.parametrize("n", [0, 1, 2, 7, 100, 1001])
@pytest.mark.parametrize("min_piece", [1, 3, 50])
def test_every_index_is_run_once(threads, n, min_piece):
    seen = np.zeros(n, dtype=np.int64)
    pieces = []
    lock = threading.Lock()

    def kernel(out, lo, hi):
        assert 0 <= lo < hi <= n
        with lock:
            pieces.append((lo, hi))
        out[lo:hi] += 1

    split(kernel, n, seen, min_piece=min_piece)
    assert_array_equal(seen, np.ones(n, dtype=np.int64))
    assert len(pieces) <= max(1, threads * kernels.PIECES_PER_THREAD)
    if n < 2 * min_piece or threads == 1:
        assert len(pieces) == (1 if n else 0)


def test_an_error_in_a_piece_reaches_the_caller(threads):
    def kernel(lo, hi):
        if lo <= 37 < hi:
            raise ValueError("piece with 37")

    with pytest.raises(ValueError, match="piece with 37"):
        split(kernel, 100)


def test_callers_on_several_threads_all_finish(monkeypatch):
    monkeypatch.setattr(config, "NUMBA_NUM_THREADS", 2)
    n = 64
    outs = [np.zeros(n) for _ in range(6)]

    def kernel(out, lo, hi):
        time.sleep(0.002)
        out[lo:hi] = np.arange(lo, hi)

    callers = [threading.Thread(target=split, args=(kernel, n, out)) for out in outs]
    for t in callers:
        t.start()
    for t in callers:
        t.join(timeout=60)
    assert not any(t.is_alive() for t in callers)
    for out in outs:
        assert_array_equal(out, np.arange(n))


def test_kernels_give_the_same_bits_at_any_thread_count(threads, monkeypatch, rng):
    monkeypatch.setattr(geometry, "CROSS_PIECE", 7)
    V = rng.normal(size=(400, 3))
    F = rng.integers(0, 400, size=(997, 3))
    assert_array_equal(geometry.face_cross(V, F), ref_geometry.face_cross(V, F))
    tree = build_tree(V, F)
    Q = rng.normal(size=(3001, 3))
    qorder = rng.permutation(len(Q))
    got = bvh.closest_points(V, F, *tree, Q, qorder)
    monkeypatch.setattr(config, "NUMBA_NUM_THREADS", 1)
    want = bvh.closest_points(V, F, *tree, Q, qorder)
    for a, b in zip(got, want, strict=True):
        assert_array_equal(a, b)
    hit = bvh.within(V, F, *tree, Q, qorder, 0.05)
    assert_array_equal(hit, want[0] <= 0.05)
