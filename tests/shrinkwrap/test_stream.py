"""Progressive streams: any subset of packets in any order decodes, and a damaged or hostile
file (flipped bits, random bytes, headers claiming more than it holds) is one StreamError
within an allocation budget."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from meshfit import errors
from meshfit.shrinkwrap import (
    Packet,
    Stream,
    decode_stream,
    encode_stream,
    icosahedron,
    read_stream,
    subdivide_step,
    write_stream,
)
from meshfit.shrinkwrap.subdivision import level_sizes

from ..conftest import real_mesh
from ..fuzz import damaged, peak_within
from .conftest import wrap

LEVELS = 4


@pytest.fixture(scope="module")
def spot_wrap():
    return wrap("spot", LEVELS)


def _encode(res, scheme, **kw):
    top = res.levels[-1]
    return encode_stream(
        top.vertices, res.base.faces, len(res.base.sphere), LEVELS, scheme=scheme, **kw
    )


@pytest.mark.parametrize("scheme", ["loop", "butterfly"])
def test_full_stream_reconstructs_the_finest_level(spot_wrap, scheme):
    st = Stream.from_bytes(_encode(spot_wrap, scheme, packet_size=64).to_bytes())
    x, f = decode_stream(st)
    diag = real_mesh("spot").bbox_diagonal
    assert_allclose(x, spot_wrap.levels[-1].vertices, atol=1e-6 * diag)  # float32 details
    assert np.array_equal(f, spot_wrap.levels[-1].faces)
    st64 = _encode(spot_wrap, scheme, value_bytes=8)
    assert_allclose(decode_stream(st64)[0], spot_wrap.levels[-1].vertices, atol=1e-12 * diag)


@pytest.mark.parametrize("scheme", ["loop", "butterfly"])
def test_permuted_packets_decode_identically(spot_wrap, scheme, rng):
    st = _encode(spot_wrap, scheme, packet_size=50)
    x, _ = decode_stream(st)
    perm = rng.permutation(len(st.packets))
    y, _ = decode_stream(st, [st.packets[i] for i in perm])
    assert np.array_equal(x, y)
    # and through the byte format with the packets written in permuted order
    shuffled = Stream(
        st.scheme,
        st.levels,
        st.base_vertices,
        st.base_faces,
        [st.packets[i] for i in perm],
        st.value_bytes,
    )
    z, _ = decode_stream(Stream.from_bytes(shuffled.to_bytes()))
    assert np.array_equal(x, z)


@pytest.mark.parametrize("scheme", ["loop", "butterfly"])
def test_dropped_packets_degrade_gracefully(spot_wrap, scheme, rng):
    st = _encode(spot_wrap, scheme, packet_size=50)
    ref = spot_wrap.levels[-1].vertices
    diag = real_mesh("spot").bbox_diagonal

    def err(keep):
        x, _ = decode_stream(st, [p for p, k in zip(st.packets, keep, strict=True) if k])
        return float(np.sqrt(np.mean(np.sum((x - ref) ** 2, axis=1)))) / diag

    n = len(st.packets)
    e0 = err(np.zeros(n, bool))
    e50 = err(rng.random(n) < 0.5)
    e90 = err(rng.random(n) < 0.9)
    assert e0 > e50 > e90 > 0
    assert e0 < 0.2  # the base mesh alone already gives a coarse approximation


def test_butterfly_interpolates_and_loop_smooths():
    v, f = icosahedron()
    vb, fb = subdivide_step(v, f, "butterfly")
    assert_allclose(vb[:12], v)
    vl, fl = subdivide_step(v, f, "loop")
    assert np.array_equal(fb, fl)
    r = np.linalg.norm(vl, axis=1)
    assert (r < 1).all()
    assert np.ptp(r[:12]) < 1e-12 and np.ptp(r[12:]) < 1e-12  # symmetric rules
    assert level_sizes(f, 12, 2) == [12, 42, 162]


def test_stream_file_round_trip_and_errors(spot_wrap, tmp_path):
    st = _encode(spot_wrap, "loop")
    path = tmp_path / "s.mfsw"
    write_stream(st, path)
    back = read_stream(path)
    assert back.n_coefficients == st.n_coefficients
    data = path.read_bytes()
    with pytest.raises(errors.StreamError, match="magic"):
        Stream.from_bytes(b"XXXX" + data[4:])
    with pytest.raises(errors.StreamError, match="version"):
        Stream.from_bytes(data[:4] + b"\x09\x00" + data[6:])
    with pytest.raises(errors.StreamError, match="truncated"):
        Stream.from_bytes(data[: len(data) - 10])
    with pytest.raises(errors.StreamError, match="exceed level"):
        decode_stream(st, [Packet(1, 10**6, np.zeros((2, 3)))])
    with pytest.raises(errors.StreamError, match="level 9"):
        decode_stream(st, [Packet(9, 0, np.zeros((2, 3)))])


def _synthetic_stream(scheme):
    """A 3-level hierarchy over the icosahedron with a bumpy finest level."""
    v, f = icosahedron()
    x, ff = v, f
    for _ in range(3):
        x, ff = subdivide_step(x, ff, "butterfly")
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    x *= 1 + 0.1 * np.sin(5 * x[:, :1])
    return encode_stream(x, f, 12, 3, scheme=scheme, packet_size=7)


_STREAMS = {s: _synthetic_stream(s) for s in ("loop", "butterfly")}


@settings(max_examples=40, deadline=None)
@given(scheme=st.sampled_from(["loop", "butterfly"]), data=st.data())
def test_any_subset_in_any_order_decodes_like_the_sorted_subset(scheme, data):
    stream = _STREAMS[scheme]
    n = len(stream.packets)
    keep = data.draw(st.lists(st.integers(0, n - 1), unique=True, max_size=n))
    order = data.draw(st.permutations(keep))
    a, _ = decode_stream(stream, [stream.packets[i] for i in sorted(keep)])
    b, _ = decode_stream(stream, [stream.packets[i] for i in order])
    assert np.array_equal(a, b)


def _v1_bytes(stream: Stream) -> bytes:
    """The version-1 layout (no file length, no checksums), as older meshfit wrote it."""
    import struct

    from meshfit.shrinkwrap.subdivision import SCHEMES

    hdr = struct.pack(
        "<4sHBBHHIII",
        b"MFSW",
        1,
        SCHEMES.index(stream.scheme),
        stream.value_bytes,
        stream.levels,
        0,
        len(stream.base_vertices),
        len(stream.base_faces),
        len(stream.packets),
    )
    parts = [hdr, stream.base_vertices.astype("<f8").tobytes()]
    parts.append(stream.base_faces.astype("<u4").tobytes())
    for p in stream.packets:
        parts.append(struct.pack("<2sBBII", b"PK", p.level, 0, p.start, len(p.values)))
        parts.append(np.asarray(p.values, dtype="<f4").tobytes())
    return b"".join(parts)


def _with_crc(data: bytearray, lo: int, hi: int) -> None:
    import struct
    import zlib

    data[hi : hi + 4] = struct.pack("<I", zlib.crc32(bytes(data[lo:hi])))


def test_every_flipped_bit_is_found():
    """Version 2 covers every byte with a checksum or a size check: a flipped bit anywhere
    is a StreamError, never another mesh."""
    data = _STREAMS["loop"].to_bytes()
    rng = np.random.default_rng(0)
    for pos in sorted(set(rng.integers(0, len(data), 300).tolist()) | {0, 6, 30, len(data) - 1}):
        bad = bytearray(data)
        bad[pos] ^= 1 << int(rng.integers(0, 8))
        with pytest.raises(errors.StreamError):
            Stream.from_bytes(bytes(bad))


def test_hostile_headers_and_bases_are_refused_before_any_work():
    import struct

    stream = _STREAMS["loop"]
    data = bytearray(stream.to_bytes())
    # 13 levels over the 20 base faces: 1.3 billion faces; refused at the header
    many = bytearray(data)
    struct.pack_into("<H", many, 8, 13)
    _with_crc(many, 0, 32)
    with peak_within(0, fixed=1 << 20):  # refused from the header: nothing is allocated for it
        with pytest.raises(errors.StreamError, match="at most 8,000,000 are decoded"):
            Stream.from_bytes(bytes(many))
    # zeroed base faces (checksums made to match): a clear error, not a traceback
    zero = bytearray(data)
    n0, nf0 = len(stream.base_vertices), len(stream.base_faces)
    lo = 36 + 24 * n0
    zero[lo : lo + 12 * nf0] = bytes(12 * nf0)
    _with_crc(zero, 36, lo + 12 * nf0)
    with pytest.raises(errors.StreamError, match="base face 0 repeats a corner"):
        Stream.from_bytes(bytes(zero))
    # more packets than the file can hold
    more = bytearray(data)
    struct.pack_into("<I", more, 20, 10**9)
    _with_crc(more, 0, 32)
    with pytest.raises(errors.StreamError, match="need at least"):
        Stream.from_bytes(bytes(more))


def test_version_1_streams_are_still_read():
    stream = _STREAMS["butterfly"]
    old = Stream.from_bytes(_v1_bytes(stream))
    assert old.levels == stream.levels and old.n_coefficients == stream.n_coefficients
    x, _ = decode_stream(old)
    y, _ = decode_stream(stream)
    assert np.abs(x - y).max() < 1e-6


@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_damaged_streams_raise_only_stream_errors(data):
    raw = damaged(data, _STREAMS["loop"].to_bytes())
    # (whatever the damage, reading takes little more than the file itself)
    with peak_within(len(raw), per_byte=64):
        try:
            Stream.from_bytes(raw)
        except errors.StreamError:
            pass


@settings(max_examples=100, deadline=None)
@given(raw=st.binary(max_size=4096))
def test_random_bytes_raise_only_stream_errors(raw):
    with peak_within(len(raw), per_byte=64), pytest.raises(errors.StreamError):
        Stream.from_bytes(raw)


@pytest.mark.parametrize("scheme", ["loop", "butterfly"])
@pytest.mark.parametrize("levels", [3, 5])
def test_a_decode_is_refused_when_its_estimate_exceeds_the_free_memory(monkeypatch, scheme, levels):
    """The estimate covers what the decode holds (tracemalloc's peak, numpy's arrays
    included) and is refused, before any work, above the memory the machine has free."""
    import tracemalloc
    from dataclasses import replace

    from meshfit.shrinkwrap import stream as sm

    s = replace(_STREAMS[scheme], levels=levels)  # (levels past 3 have no packets: predicted)
    need = sm.decode_bytes(len(s.base_faces), len(s.base_vertices), s.levels)
    tracemalloc.start()
    decode_stream(s)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak <= need <= 4 * peak
    monkeypatch.setattr(sm, "_free_bytes", lambda: need - 1)
    with pytest.raises(errors.StreamError, match="decode a coarser level"):
        decode_stream(s)
    decode_stream(s, level=s.levels - 1)  # a coarser level fits
