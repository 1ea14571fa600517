"""Adaptive binary range coder and the embedded bit-plane coder of wrap streams.

The range coder is LZMA's (Pavlov): 32-bit range, carry propagated through a cached byte,
adaptive probabilities of `PROB_BITS` bits. After the n-th symbol of a context its
probability moves 1/2**min(`ADAPT`, bit_length(n)) of the way to the symbol seen: about
Laplace's estimate while the context is young (a small file learns fast), then a window of
about 2**`ADAPT` symbols. The decoder stops before the first symbol whose decision needs a
byte the prefix does not have, so every symbol it returns is the one the encoder coded.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner

#: probabilities are integers in (0, 2**PROB_BITS)
PROB_BITS = 15
#: adaptation rate of a context that has seen 2**(ADAPT - 1) symbols and more
ADAPT = 5
#: a context's count stops here, where its rate reaches ADAPT
_COUNT_CAP = 1 << (ADAPT - 1)
_ONE = 1 << PROB_BITS
_HALF = 1 << (PROB_BITS - 1)
_TOP = 1 << 24
_MASK32 = (1 << 32) - 1
#: contexts of a significance decision per level and component: 4 parent states x 2
#: (another component of the vertex significant or not)
SIG_CONTEXTS = 8


@inner
def _bitlen(n):
    """Bits of a non-negative integer."""
    b = 0
    while n:
        n >>= 1
        b += 1
    return b


@inner
def _probs(n):
    """Probabilities (even slots, at 1/2) and symbol counts (odd slots) of n contexts."""
    p = np.zeros(2 * n, np.int64)
    p[0::2] = _HALF
    return p


@inner
def _put(buf, st, byte):
    """Append ``byte`` to ``buf`` (grown by doubling); st[4] is the count written."""
    n = st[4]
    if n == buf.shape[0]:
        nb = np.empty(2 * buf.shape[0], np.uint8)
        for i in range(n):
            nb[i] = buf[i]
        buf = nb
    buf[n] = byte
    st[4] = n + 1
    return buf


@inner
def _shift_low(buf, st):
    """LZMA's ShiftLow: st = [low, range, cache, cache_size, written]."""
    low = st[0]
    if low < 0xFF000000 or low > _MASK32:
        carry = low >> 32
        temp = st[2]
        while True:
            buf = _put(buf, st, (temp + carry) & 0xFF)
            temp = 0xFF
            st[3] -= 1
            if st[3] == 0:
                break
        st[2] = (low >> 24) & 0xFF
    st[3] += 1
    st[0] = (low & 0x00FFFFFF) << 8
    return buf


@inner
def _rate(probs, ctx):
    """The context's probability (of a 0) and adaptation shift, its count advanced: the
    shift starts near Laplace's estimate and settles at ``ADAPT``."""
    n = probs[2 * ctx + 1]
    sh = ADAPT
    if n < _COUNT_CAP:
        sh = min(ADAPT, _bitlen(n + 1))
        probs[2 * ctx + 1] = n + 1
    return probs[2 * ctx], sh


@inner
def _adapt(probs, ctx, p, sh, bit):
    """Move the context's probability toward the symbol just coded."""
    if bit == 0:
        probs[2 * ctx] = p + ((_ONE - p) >> sh)
    else:
        probs[2 * ctx] = p - (p >> sh)


@inner
def _encode_bit(buf, st, probs, ctx, bit):
    """Code one binary symbol with the adaptive probability ``probs[2 ctx]`` (of a 0)."""
    p, sh = _rate(probs, ctx)
    bound = (st[1] >> PROB_BITS) * p
    if bit == 0:
        st[1] = bound
    else:
        st[0] += bound
        st[1] -= bound
    _adapt(probs, ctx, p, sh, bit)
    while st[1] < _TOP:
        st[1] <<= 8
        buf = _shift_low(buf, st)
    return buf


@inner
def _decode_bit(data, n_avail, st, probs, ctx):
    """Decode one symbol; st = [code, range, position, exhausted]. Sets st[3] when the
    next decision would need a byte past ``n_avail``."""
    p, sh = _rate(probs, ctx)
    bound = (st[1] >> PROB_BITS) * p
    if st[0] < bound:
        st[1] = bound
        bit = 0
    else:
        st[0] -= bound
        st[1] -= bound
        bit = 1
    _adapt(probs, ctx, p, sh, bit)
    while st[1] < _TOP:
        st[1] <<= 8
        byte = 0
        if st[2] < n_avail:
            byte = data[st[2]]
        else:
            st[3] = 1
        st[2] += 1
        st[0] = ((st[0] << 8) | byte) & _MASK32
    return bit


@njit(cache=True, nogil=True)
def encode_bits(bits, ctxs, n_ctx):
    """Range-code a sequence of binary symbols, each with its context.

    bits, ctxs (n,) i8 -> (n_bytes,) u1. Kernel of the coder's tests.
    """
    st = np.array([0, _MASK32, 0, 1, 0], np.int64)
    buf = np.empty(64, np.uint8)
    probs = _probs(n_ctx)
    for i in range(bits.shape[0]):
        buf = _encode_bit(buf, st, probs, ctxs[i], bits[i])
    for _ in range(5):
        buf = _shift_low(buf, st)
    return buf[: st[4]].copy()


@njit(cache=True, nogil=True)
def decode_bits(data, n_avail, ctxs, n_ctx):
    """Decode the symbols of `encode_bits` from the first ``n_avail`` bytes of ``data``.

    data (m,) u1; ctxs (n,) i8 -> (bits (k,) i8, k <= n: the symbols the prefix settles).
    """
    out = np.zeros(ctxs.shape[0], np.int64)
    if n_avail < 5:
        return out[:0]
    st = np.zeros(4, np.int64)
    st[1] = _MASK32
    for i in range(5):
        st[0] = ((st[0] << 8) | data[i]) & _MASK32
    st[2] = 5
    probs = _probs(n_ctx)
    k = 0
    for i in range(ctxs.shape[0]):
        if st[3]:
            break
        out[i] = _decode_bit(data, n_avail, st, probs, ctxs[i])
        k = i + 1
    return out[:k]


@inner
def _sig_context(c, node_level, parents, vsig):
    """Context of the significance decision of coefficient ``c``: its level, component,
    how many of its parents (the vertices of the coarser level it was inserted between,
    or itself there) are significant, and whether its vertex already is."""
    v = c // 3
    a = parents[v, 0]
    b = parents[v, 1]
    total = 0
    cnt = 0
    if a >= 0:
        total += 1
        if vsig[a]:
            cnt += 1
    if b >= 0:
        total += 1
        if vsig[b]:
            cnt += 1
    if total == 0:
        ps = 0
    elif cnt == 0:
        ps = 1
    elif cnt < total:
        ps = 2
    else:
        ps = 3
    own = 1 if vsig[v] else 0
    return ((node_level[v] - 1) * 3 + c % 3) * SIG_CONTEXTS + ps * 2 + own


@njit(cache=True, nogil=True)
def encode_planes(mag, neg, node_level, parents, planes, n_levels):
    """Embedded bit-plane code of quantised coefficients, planes from the top down.

    mag (3 nv,) i4 (< 2**planes), component ``c % 3`` of vertex node ``c // 3``; neg (3 nv,)
    b1; node_level (nv,) i1 (1..n_levels); parents (nv, 2) i4 (-1: none) -> (n_bytes,) u1.
    Kernel of `meshfit.shrinkwrap.stream.encode_stream`.
    Each plane: a significance pass over the coefficients not yet significant (bit, then
    the sign of a newly significant one), then a refinement pass over those significant
    before it.
    """
    n = mag.shape[0]
    st = np.array([0, _MASK32, 0, 1, 0], np.int64)
    buf = np.empty(max(64, n // 2), np.uint8)
    p_sig = _probs(n_levels * 3 * SIG_CONTEXTS)
    p_sgn = _probs(3)
    p_ref = _probs(3)
    sigplane = np.full(n, -1, np.int64)
    vsig = np.zeros(parents.shape[0], np.bool_)
    for p in range(planes - 1, -1, -1):
        for c in range(n):
            if sigplane[c] >= 0:
                continue
            ctx = _sig_context(c, node_level, parents, vsig)
            bit = (mag[c] >> p) & 1
            buf = _encode_bit(buf, st, p_sig, ctx, bit)
            if bit:
                buf = _encode_bit(buf, st, p_sgn, c % 3, 1 if neg[c] else 0)
                sigplane[c] = p
                vsig[c // 3] = True
        for c in range(n):
            if sigplane[c] > p:
                buf = _encode_bit(buf, st, p_ref, c % 3, (mag[c] >> p) & 1)
    for _ in range(5):
        buf = _shift_low(buf, st)
    return buf[: st[4]].copy()


@njit(cache=True, nogil=True)
def decode_planes(data, n_avail, node_level, parents, planes, n_levels):
    """Inverse of `encode_planes` over the first ``n_avail`` bytes of ``data``.

    -> mag (3 nv,) i4 (the bits decoded), last (3 nv,) i1 (the lowest plane decoded of a
    significant coefficient, -1 for one not significant), neg (n,) b1, symbols (int).
    Stops before the first decision the prefix does not settle. Kernel of
    `meshfit.shrinkwrap.stream.decode_stream`.
    """
    n = 3 * node_level.shape[0]
    mag = np.zeros(n, np.int32)
    last = np.full(n, -1, np.int8)
    neg = np.zeros(n, np.bool_)
    if n_avail < 5:
        return mag, last, neg, 0
    st = np.zeros(4, np.int64)
    st[1] = _MASK32
    for i in range(5):
        st[0] = ((st[0] << 8) | data[i]) & _MASK32
    st[2] = 5
    p_sig = _probs(n_levels * 3 * SIG_CONTEXTS)
    p_sgn = _probs(3)
    p_ref = _probs(3)
    vsig = np.zeros(parents.shape[0], np.bool_)
    symbols = 0
    for p in range(planes - 1, -1, -1):
        for c in range(n):
            if last[c] >= 0:
                continue
            if st[3]:
                return mag, last, neg, symbols
            ctx = _sig_context(c, node_level, parents, vsig)
            symbols += 1
            if _decode_bit(data, n_avail, st, p_sig, ctx):
                if st[3]:  # the sign is not settled: the coefficient stays unknown
                    return mag, last, neg, symbols
                neg[c] = _decode_bit(data, n_avail, st, p_sgn, c % 3) == 1
                symbols += 1
                mag[c] = np.int32(1 << p)
                last[c] = p
                vsig[c // 3] = True
        for c in range(n):
            if last[c] > p:
                if st[3]:
                    return mag, last, neg, symbols
                mag[c] |= np.int32(_decode_bit(data, n_avail, st, p_ref, c % 3) << p)
                last[c] = p
                symbols += 1
    return mag, last, neg, symbols
