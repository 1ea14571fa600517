"""Damaged copies of valid files for the readers' property tests."""

from __future__ import annotations

from hypothesis import strategies as st

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
