"""Damaged copies of valid files for the readers' property tests, and the allocation
budget every reader of a damaged file is held to."""

from __future__ import annotations

import contextlib
import tracemalloc

from hypothesis import strategies as st

#: the most a reader may allocate for a file of n bytes: what parsing the bytes that are
#: there takes (a few copies and the arrays they hold), never what a header claims
BUDGET_FIXED = 4 * 2**20
BUDGET_PER_BYTE = 200

#: runs a damaged file may gain: digits past every integer type, signs and words numbers
#: readers stumble on, line breaks
INSERTS = (b"9" * 30, b"-1", b"nan", b"1e308", b"\n")


def damaged(data, original: bytes, *, edits: int = 6, span: int = 200) -> bytes:
    """``original`` with 1 to ``edits`` random edits drawn from hypothesis' ``data``: a byte
    set to any value, a run of up to ``span`` bytes cut out or repeated, or one of
    `INSERTS` put in."""
    raw = bytearray(original)
    for _ in range(data.draw(st.integers(1, edits))):
        i = data.draw(st.integers(0, max(len(raw) - 1, 0)))
        op = data.draw(st.sampled_from(["set", "cut", "dup", "insert"]))
        if op == "set" and raw:
            raw[i] = data.draw(st.integers(0, 255))
        elif op == "cut":
            del raw[i : i + data.draw(st.integers(1, span))]
        elif op == "dup":
            raw[i:i] = raw[i : i + data.draw(st.integers(1, span))]
        elif op == "insert":
            raw[i:i] = data.draw(st.sampled_from(INSERTS))
    return bytes(raw)


@contextlib.contextmanager
def peak_within(n_bytes: int, per_byte: int = BUDGET_PER_BYTE, fixed: int = BUDGET_FIXED):
    """Assert that the block's peak traced allocation (numpy's included) stays within the
    budget for an input of ``n_bytes``: ``fixed`` + ``per_byte`` per byte."""
    budget = fixed + per_byte * n_bytes
    tracemalloc.start()
    try:
        yield
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= budget, f"peak {peak:,} bytes allocated for {n_bytes:,}, budget {budget:,}"
