"""The stream coder's kernels against the slow oracle of `tests/reference/streamcode.py`:
the same bytes from the encoders, the same symbols from every prefix."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshfit._kernels import streamcode

from ..reference import streamcode as ref


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 3000))
def test_range_coder_matches_the_oracle_on_every_prefix(seed, n):
    rng = np.random.default_rng(seed)
    ctxs = rng.integers(0, 3, n)
    bits = (rng.random(n) < np.array([0.001, 0.5, 0.97])[ctxs]).astype(np.int64)
    code = streamcode.encode_bits(bits, ctxs, 3)
    want = ref.encode_bits(bits.tolist(), ctxs.tolist(), 3)
    assert code.tobytes() == want
    for k in sorted({0, 4, 5, 6, len(want) // 3, len(want) - 1, len(want)}):
        got = streamcode.decode_bits(code, max(k, 0), ctxs, 3)
        assert got.tolist() == ref.decode_bits(want, max(k, 0), ctxs.tolist(), 3)
        assert np.array_equal(got, bits[: len(got)])  # a prefix decodes what was coded
    assert len(streamcode.decode_bits(code, len(code), ctxs, 3)) == n


@pytest.mark.parametrize("seed", range(4))
def test_bit_plane_coder_matches_the_oracle_on_every_prefix(seed):
    rng = np.random.default_rng(seed)
    nv, planes, levels = 150, 10, 3
    parents = rng.integers(-1, nv, (nv, 2)).astype(np.int32)
    node_level = rng.integers(1, levels + 1, nv).astype(np.int8)
    mag = (np.abs(rng.standard_cauchy(3 * nv)) * 10).astype(np.int32).clip(0, 2**planes - 1)
    neg = rng.random(3 * nv) < 0.5
    code = streamcode.encode_planes(mag, neg, node_level, parents, planes, levels)
    want = ref.encode_planes(mag, neg, node_level, parents, planes, levels)
    assert code.tobytes() == want
    for k in (0, 5, 40, len(want) // 2, len(want)):
        got = streamcode.decode_planes(code, k, node_level, parents, planes, levels)[:3]
        exp = ref.as_arrays(ref.decode_planes(want, k, node_level, parents, planes, levels))
        for a, b in zip(got, exp, strict=True):
            assert np.array_equal(np.asarray(a, np.int64), np.asarray(b, np.int64))
        m, last, _ = exp
        known = last >= 0  # the bits decoded are the coefficient's own
        assert np.array_equal(m[known] >> last[known], mag[known] >> last[known])
    m, last, sgn = exp
    assert np.array_equal(m, mag) and (last[mag > 0] == 0).all()
    assert np.array_equal(sgn[mag > 0], neg[mag > 0])
