"""Slow, obviously-correct oracle of the stream coder (`meshfit._kernels.streamcode`).

The encoder keeps the range coder's lower end as one unbounded integer, so carries need no
care: the code is that integer's bytes. The bit-plane coder lists its decisions as
(bit, context) pairs and codes them in one go.
"""

from __future__ import annotations

import numpy as np

PROB_BITS = 15
ADAPT = 5
ONE = 1 << PROB_BITS
TOP = 1 << 24


def _adapt(p: int, n: int, bit: int) -> int:
    """The probability of a 0 after the n-th symbol (from 1) of a context: it moves
    1/2**min(ADAPT, bits of n) of the way to the symbol."""
    shift = min(ADAPT, n.bit_length())
    return p + ((ONE - p) >> shift) if bit == 0 else p - (p >> shift)


def encode_bits(bits, ctxs, n_ctx: int) -> bytes:
    """The code of binary symbols ``bits``, each with its context's adaptive probability."""
    probs, seen = [ONE // 2] * n_ctx, [0] * n_ctx
    low, rng, shifts = 0, (1 << 32) - 1, 0
    for bit, ctx in zip(bits, ctxs, strict=True):
        bound = (rng >> PROB_BITS) * probs[ctx]
        if bit:
            low, rng = low + bound, rng - bound
        else:
            rng = bound
        seen[ctx] += 1
        probs[ctx] = _adapt(probs[ctx], seen[ctx], int(bit))
        while rng < TOP:
            rng, low, shifts = rng << 8, low << 8, shifts + 1
    return low.to_bytes(shifts + 5, "big")


class Decoder:
    """Symbols from the first ``n_avail`` bytes of a code; ``done`` once the next decision
    needs a byte beyond them."""

    def __init__(self, data: bytes, n_avail: int, n_ctx: int):
        self.data, self.n = bytes(data[:n_avail]), n_avail
        self.probs, self.seen = [ONE // 2] * n_ctx, [0] * n_ctx
        self.done = n_avail < 5
        self.code = int.from_bytes(self.data[:5], "big") if not self.done else 0
        self.rng, self.pos = (1 << 32) - 1, 5

    def bit(self, ctx: int) -> int:
        bound = (self.rng >> PROB_BITS) * self.probs[ctx]
        bit = int(self.code >= bound)
        if bit:
            self.code, self.rng = self.code - bound, self.rng - bound
        else:
            self.rng = bound
        self.seen[ctx] += 1
        self.probs[ctx] = _adapt(self.probs[ctx], self.seen[ctx], bit)
        while self.rng < TOP:
            if self.pos >= self.n:
                self.done = True
            byte = self.data[self.pos] if self.pos < self.n else 0
            self.code, self.rng, self.pos = (
                ((self.code << 8) | byte) % (1 << 32),
                self.rng << 8,
                self.pos + 1,
            )
        return bit


def decode_bits(data: bytes, n_avail: int, ctxs, n_ctx: int) -> list[int]:
    dec = Decoder(data, n_avail, n_ctx)
    out = []
    for ctx in ctxs:
        if dec.done:
            break
        out.append(dec.bit(ctx))
    return out


def _sig_ctx(c, node_level, parents, vsig) -> int:
    v = c // 3
    par = [int(a) for a in parents[v] if a >= 0]
    cnt = sum(bool(vsig[a]) for a in par)
    ps = 0 if not par else 1 if cnt == 0 else 3 if cnt == len(par) else 2
    return ((int(node_level[v]) - 1) * 3 + c % 3) * 8 + ps * 2 + int(vsig[v])


def encode_planes(mag, neg, node_level, parents, planes: int, n_levels: int) -> bytes:
    """Decisions of the embedded bit-plane code, significance (and sign) then refinement a
    plane, coded with three context sets laid end to end."""
    n = len(mag)
    n_sig = n_levels * 24
    bits, ctxs = [], []
    sigplane = [-1] * n
    vsig = [False] * len(parents)
    for p in range(planes - 1, -1, -1):
        for c in range(n):
            if sigplane[c] < 0:
                b = (int(mag[c]) >> p) & 1
                bits.append(b)
                ctxs.append(_sig_ctx(c, node_level, parents, vsig))
                if b:
                    bits.append(int(neg[c]))
                    ctxs.append(n_sig + c % 3)
                    sigplane[c] = p
                    vsig[c // 3] = True
        for c in range(n):
            if sigplane[c] > p:
                bits.append((int(mag[c]) >> p) & 1)
                ctxs.append(n_sig + 3 + c % 3)
    return encode_bits(bits, ctxs, n_sig + 6)


def decode_planes(data: bytes, n_avail: int, node_level, parents, planes: int, n_levels: int):
    """(mag, last, neg) of the coefficients a prefix settles (last: -1 for none)."""
    n = 3 * len(node_level)
    n_sig = n_levels * 24
    dec = Decoder(data, n_avail, n_sig + 6)
    mag, last, neg = [0] * n, [-1] * n, [False] * n
    vsig = [False] * len(parents)
    for p in range(planes - 1, -1, -1):
        for c in range(n):
            if last[c] < 0:
                if dec.done:
                    return mag, last, neg
                if dec.bit(_sig_ctx(c, node_level, parents, vsig)):
                    if dec.done:
                        return mag, last, neg
                    neg[c] = bool(dec.bit(n_sig + c % 3))
                    mag[c], last[c] = 1 << p, p
                    vsig[c // 3] = True
        for c in range(n):
            if last[c] > p:
                if dec.done:
                    return mag, last, neg
                mag[c] |= dec.bit(n_sig + 3 + c % 3) << p
                last[c] = p
    return mag, last, neg


def as_arrays(res):
    mag, last, neg = res
    return np.array(mag, np.int64), np.array(last, np.int64), np.array(neg, bool)
