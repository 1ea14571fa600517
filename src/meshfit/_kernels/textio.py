"""Text of index rows, formatted without Python objects: an OBJ's face lines.

Formatting millions of face lines with ``str.format`` took more time than anything else
in a dense fit's exports; the digits of an integer are exact in any language, so the
bytes here are those of ``"f {0}/{3}/{0} {1}/{4}/{1} {2}/{5}/{2}\\n".format(*row)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner


@inner
def _put_int(buf, pos, x):
    """Write the decimal digits of ``x`` (a minus sign first when negative) at ``pos``;
    returns the position after them."""
    if x < 0:
        buf[pos] = 45  # "-"
        pos += 1
        x = -x
    n = 1
    y = x // 10
    while y > 0:
        y //= 10
        n += 1
    q = pos + n
    while True:
        q -= 1
        buf[q] = 48 + x % 10
        x //= 10
        if q == pos:
            break
    return pos + n


@njit(cache=True, nogil=True)
def face_lines(cols):
    """The bytes of the OBJ face lines ``f a/d/a b/e/b c/f/c`` of the rows ``(a, b, c, d,
    e, f)`` of ``cols (k, 6) int64`` (vertex and texture indices, 1-based; the normal index is
    the vertex's), one line each, ``\\n``-terminated. Any value but
    int64's minimum (whose magnitude int64 cannot hold) is written as Python writes it."""
    k = cols.shape[0]
    big = 1
    for i in range(k):
        for j in range(6):
            v = cols[i, j]
            v = -v if v < 0 else v
            if v > big:
                big = v
    digits = 1
    while big >= 10:
        big //= 10
        digits += 1
    width = digits + 1  # (a sign)
    buf = np.empty(k * (2 + 3 * (3 * width + 2) + 3), np.uint8)
    pos = 0
    for i in range(k):
        buf[pos] = 102  # "f"
        pos += 1
        for c in range(3):
            buf[pos] = 32  # " "
            pos += 1
            pos = _put_int(buf, pos, cols[i, c])
            buf[pos] = 47  # "/"
            pos = _put_int(buf, pos + 1, cols[i, c + 3])
            buf[pos] = 47
            pos = _put_int(buf, pos + 1, cols[i, c])
        buf[pos] = 10  # "\n"
        pos += 1
    return buf[:pos]
