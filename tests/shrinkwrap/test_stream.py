"""Progressive streams: any prefix of a file decodes, to an error that falls as bytes grow,
and a damaged or hostile file (flipped bits, random bytes, headers claiming more than it
holds) is one StreamError within an allocation budget."""

import itertools
import math
import struct
import tracemalloc
import zlib

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
    reconstruction_errors,
    subdivide_step,
    write_stream,
)
from meshfit.shrinkwrap import stream as sm
from meshfit.shrinkwrap.subdivision import SCHEMES, level_faces, level_sizes

from ..fuzz import damaged, peak_within
from .conftest import wrap

LEVELS = 4
HEADER = sm._HEADER.size


@pytest.fixture(scope="module")
def spot_wrap():
    return wrap("spot", LEVELS)


def _encode(res, scheme, **kw):
    top = res.levels[-1]
    return encode_stream(
        top.vertices, res.base.faces, len(res.base.sphere), LEVELS, scheme=scheme, **kw
    )


def _diag(x):
    return float(np.linalg.norm(np.ptp(x, axis=0)))


def _rms(x, ref):
    return float(np.sqrt(np.mean(np.sum((x - ref) ** 2, axis=1))))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_full_stream_reconstructs_the_finest_level(spot_wrap, scheme):
    """Each level's details are quantised to at most 3 `STREAM_PRECISION` of the diagonal
    (normal component exact to one, the two tangential to two each); Loop's and Butterfly's
    rules carry a coarser level's error on without growing it much: the finest level is
    within levels x 3 `STREAM_PRECISION`."""
    ref = spot_wrap.levels[-1].vertices
    s = Stream.from_bytes(_encode(spot_wrap, scheme).to_bytes())
    x, f = decode_stream(s)
    tol = 3 * LEVELS * sm.STREAM_PRECISION * _diag(ref)
    assert np.abs(x - ref).max() <= tol
    assert np.array_equal(f, spot_wrap.levels[-1].faces)
    sizes = [len(lv.vertices) for lv in spot_wrap.levels]
    per_level = sizes[1:] if scheme == "loop" else np.diff(sizes)  # (Loop: every vertex moves)
    assert s.missing == 0 and s.n_coefficients == sum(per_level)
    # the base mesh goes at 16 bits within its cube
    q = s.quant
    assert np.abs(s.base_vertices - ref[: len(s.base_vertices)]).max() <= q.extent / 2**16


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_file_cut_at_every_5_percent_decodes_and_the_error_falls(spot_wrap, scheme):
    ref = spot_wrap.levels[-1].vertices
    s = _encode(spot_wrap, scheme)
    data = s.to_bytes()
    assert s.min_prefix <= 0.05 * len(data)
    cut_errs, sent_errs = [], []
    for k in range(1, 21):
        n = math.ceil(k * len(data) / 20)
        cut = Stream.from_bytes(data[:n])  # the first n bytes arrived
        assert cut.missing == len(data) - n
        assert s.data.startswith(cut.data)
        cut_errs.append(_rms(decode_stream(cut)[0], ref))
        sent = s.truncate(n)  # a whole file of at most n bytes
        assert len(sent.to_bytes()) == sent.n_bytes <= n
        sent_errs.append(_rms(decode_stream(sent)[0], ref))
    for errs in (cut_errs, sent_errs):
        assert all(b <= a for a, b in itertools.pairwise(errs)), errs
        assert errs[0] > 10 * errs[-1]
    assert cut_errs[-1] == sent_errs[-1]  # (the whole file)
    assert all(a <= b for a, b in zip(sent_errs, cut_errs, strict=True))


def test_a_prefix_decode_allocates_no_more_than_the_full_decode(spot_wrap):
    data = _encode(spot_wrap, "loop").to_bytes()

    def peak(n):
        s = Stream.from_bytes(data[:n])
        peaks = []
        for _ in range(3):  # (the least of three: Python's own objects come and go)
            tracemalloc.start()
            decode_stream(s)
            peaks.append(tracemalloc.get_traced_memory()[1])
            tracemalloc.stop()
        return min(peaks)

    full = peak(len(data))
    for fr in (0.05, 0.3, 0.7):
        assert peak(int(fr * len(data))) <= full + 1024


def test_max_bytes_and_truncate(spot_wrap):
    s = _encode(spot_wrap, "loop")
    for n in (s.min_bytes, s.min_bytes + 1, 3000, 10_000, s.n_bytes, 10 * s.n_bytes):
        cut = _encode(spot_wrap, "loop", max_bytes=n)
        assert len(cut.to_bytes()) == cut.n_bytes <= n
        assert s.data.startswith(cut.data)
        assert n - cut.n_bytes <= 8 or cut.data == s.data  # (a block's CRC at most)
    with pytest.raises(errors.InputError, match="do not hold the base mesh"):
        s.truncate(s.min_bytes - 1)
    base, _ = decode_stream(s.truncate(s.min_bytes), level=0)
    assert_allclose(base, s.base_vertices)


def test_reconstruction_errors_fall_with_the_bytes(spot_wrap):
    s = _encode(spot_wrap, "butterfly")
    e = reconstruction_errors(s, spot_wrap.levels[-1].vertices, (0.0, 0.05, 0.2, 1.0))
    assert e["0%"] > e["5%"] > e["20%"] > e["100%"] > 0


def test_coarser_levels_decode_from_a_prefix(spot_wrap):
    s = _encode(spot_wrap, "loop")
    cut = Stream.from_bytes(s.to_bytes()[: s.n_bytes // 2])
    for lv in range(LEVELS + 1):
        x, f = decode_stream(cut, level=lv)
        assert np.array_equal(f, spot_wrap.levels[lv].faces)
        assert len(x) == len(spot_wrap.levels[lv].vertices)
    with pytest.raises(errors.InputError, match="level must be in"):
        decode_stream(s, level=LEVELS + 1)


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


def _bumpy(levels=3):
    """A hierarchy over the icosahedron with a bumpy finest level."""
    v, f = icosahedron()
    x, ff = v, f
    for _ in range(levels):
        x, ff = subdivide_step(x, ff, "butterfly")
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    return x * (1 + 0.1 * np.sin(5 * x[:, :1])), f


def _synthetic_stream(scheme, levels=3):
    x, f = _bumpy(levels)
    return encode_stream(x, f, 12, levels, scheme=scheme)


_STREAMS = {s: _synthetic_stream(s) for s in SCHEMES}


def test_stream_file_round_trip_and_errors(spot_wrap, tmp_path):
    s = _encode(spot_wrap, "loop")
    path = tmp_path / "s.mfsw"
    write_stream(s, path)
    back = read_stream(path)
    assert back.data == s.data and back.quant.step == s.quant.step
    data = path.read_bytes()
    with pytest.raises(errors.StreamError, match="magic"):
        Stream.from_bytes(b"XXXX" + data[4:])
    with pytest.raises(errors.StreamError, match="version"):
        Stream.from_bytes(data[:4] + b"\x09\x00" + data[6:])
    with pytest.raises(errors.StreamError, match="truncated header"):
        Stream.from_bytes(data[: HEADER - 1])
    with pytest.raises(errors.StreamError, match="base mesh is not complete"):
        Stream.from_bytes(data[: HEADER + 10])
    with pytest.raises(errors.StreamError, match="the header says"):
        Stream.from_bytes(data + b"\0")


def _rewrite_crcs(data: bytearray) -> None:
    """Checksums made to match the bytes (the header's and every block's)."""
    struct.pack_into("<I", data, HEADER - 4, zlib.crc32(bytes(data[: HEADER - 4])))
    (block,) = struct.unpack_from("<I", data, 22)
    off, k = HEADER, 0
    while off < len(data):
        end = min(off + block, len(data) - 4)
        struct.pack_into("<I", data, end, zlib.crc32(bytes(data[off:end]), k))
        off, k = end + 4, k + 1


def test_every_flipped_bit_is_found():
    """The header and every block carry a CRC-32: a flipped bit anywhere in a whole file is
    a StreamError naming the header or the block, never another mesh."""
    data = _STREAMS["loop"].to_bytes()
    block = _STREAMS["loop"].block_bytes + 4
    rng = np.random.default_rng(0)
    picks = set(rng.integers(0, len(data), 300).tolist()) | {0, 6, HEADER - 1, len(data) - 1}
    for pos in sorted(picks):
        bad = bytearray(data)
        bad[pos] ^= 1 << int(rng.integers(0, 8))
        where = "header" if pos < HEADER else f"block {(pos - HEADER) // block}"
        with pytest.raises(errors.StreamError, match=where if pos >= 6 else "magic|version"):
            Stream.from_bytes(bytes(bad))


def test_flipped_bits_in_the_complete_blocks_of_a_cut_file_are_found():
    s = _STREAMS["butterfly"]
    data = s.to_bytes()
    block = s.block_bytes + 4
    cut = data[: HEADER + block + block // 2]  # one complete block and part of the next
    Stream.from_bytes(cut)
    bad = bytearray(cut)
    bad[HEADER + block // 2] ^= 4
    with pytest.raises(errors.StreamError, match="block 0"):
        Stream.from_bytes(bytes(bad))
    worse = bytearray(cut)
    worse[-10] ^= 4  # in the partial block: dropped, not read
    assert Stream.from_bytes(bytes(worse)).data == Stream.from_bytes(cut).data


def test_hostile_headers_and_bases_are_refused_before_any_work():
    s = _STREAMS["loop"]
    data = bytearray(s.to_bytes())
    # 13 levels over the 20 base faces: 1.3 billion faces; refused at the header
    many = bytearray(data)
    struct.pack_into("<H", many, 8, 13)
    _rewrite_crcs(many)
    with peak_within(0, fixed=1 << 20):  # refused from the header: nothing is allocated for it
        with pytest.raises(errors.StreamError, match="at most 8,000,000 are decoded"):
            Stream.from_bytes(bytes(many))
    # zeroed base faces (checksums made to match): a clear error, not a traceback
    zero = bytearray(data)
    n0, nf0 = len(s.base_vertices), len(s.base_faces)
    lo = HEADER + 6 * n0
    zero[lo : lo + 3 * nf0 * 4 // 8] = bytes(3 * nf0 * 4 // 8)
    _rewrite_crcs(zero)
    with pytest.raises(errors.StreamError, match="base face 0 repeats a corner"):
        Stream.from_bytes(bytes(zero))
    # a file longer than its header says
    short = bytearray(data)
    struct.pack_into("<Q", short, 26, len(data) - 1)
    _rewrite_crcs(short)
    with pytest.raises(errors.StreamError, match="the header says"):
        Stream.from_bytes(bytes(short))
    # a header claiming more than the file: a cut file, whose blocks are what arrived
    long = bytearray(data)
    struct.pack_into("<Q", long, 26, 10**12)
    _rewrite_crcs(long)
    assert Stream.from_bytes(bytes(long)).missing == 10**12 - len(data)
    # quantisation that is not finite
    nan = bytearray(data)
    struct.pack_into("<d", nan, 58, float("nan"))
    _rewrite_crcs(nan)
    with pytest.raises(errors.StreamError, match="not finite"):
        Stream.from_bytes(bytes(nan))
    huge = bytearray(data)
    struct.pack_into("<d", huge, 66, 1e300)  # (a step whose details overflow)
    _rewrite_crcs(huge)
    with pytest.raises(errors.StreamError, match="beyond the largest coordinate"):
        Stream.from_bytes(bytes(huge))


def _v1_bytes(x, f, n0, levels, scheme) -> bytes:
    """The version-1 layout (float32 details against the decoder's prediction, no file
    length, no checksums), as older meshfit wrote it."""
    sizes = level_sizes(f, n0, levels)
    fl = level_faces(f, n0, levels)
    parts = [
        struct.pack(
            "<4sHBBHHIII", b"MFSW", 1, SCHEMES.index(scheme), 4, levels, 0, n0, len(f), levels
        ),
        x[:n0].astype("<f8").tobytes(),
        f.astype("<u4").tobytes(),
    ]
    rec = x[:n0]
    for i in range(1, levels + 1):
        pred, _ = subdivide_step(rec, fl[i - 1], scheme)
        lo = 0 if scheme == "loop" else sizes[i - 1]
        d = (x[lo : sizes[i]] - pred[lo:]).astype("<f4")
        parts += [struct.pack("<2sBBII", b"PK", i, 0, lo, len(d)), d.tobytes()]
        pred[lo:] += d
        rec = pred
    return b"".join(parts)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_version_1_streams_are_still_read(scheme):
    x, f = _bumpy()
    old = Stream.from_bytes(_v1_bytes(x, f, 12, 3, scheme))
    assert old.version == 1 and old.levels == 3 and len(old.packets) == 3
    y, _ = decode_stream(old)
    assert np.abs(x - y).max() < 1e-6
    assert np.abs(decode_stream(old, old.packets[:1])[0] - y).max() > 1e-3
    with pytest.raises(errors.StreamError, match="exceed level"):
        decode_stream(old, [Packet(1, 10**6, np.zeros((2, 3)))])
    with pytest.raises(errors.StreamError, match="truncated"):
        Stream.from_bytes(_v1_bytes(x, f, 12, 3, scheme)[:-10])


@settings(max_examples=40, deadline=None)
@given(scheme=st.sampled_from(SCHEMES), frac=st.floats(0, 1))
def test_any_cut_decodes_a_prefix_of_the_code(scheme, frac):
    s = _STREAMS[scheme]
    data = s.to_bytes()
    n = s.min_prefix + int(frac * (len(data) - s.min_prefix))
    cut = Stream.from_bytes(data[:n])
    assert s.data.startswith(cut.data)
    assert len(s.data) - len(cut.data) <= len(data) - n + s.block_bytes
    decode_stream(cut)


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


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("levels", [3, 4])
def test_a_decode_is_refused_when_its_estimate_exceeds_the_free_memory(monkeypatch, scheme, levels):
    """The estimate covers what the decode holds (tracemalloc's peak, numpy's arrays
    included) and is refused, before any work, above the memory the machine has free."""
    s = _synthetic_stream(scheme, levels)
    need = sm.decode_bytes(len(s.base_faces), len(s.base_vertices), levels, levels)
    tracemalloc.start()
    decode_stream(s)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak <= need <= 4 * peak
    monkeypatch.setattr(sm, "_free_bytes", lambda: need - 1)
    with pytest.raises(errors.StreamError, match="decode a coarser level"):
        decode_stream(s)
    decode_stream(s, level=levels - 1)  # a coarser level fits
