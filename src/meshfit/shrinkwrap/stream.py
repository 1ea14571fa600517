"""Progressive transmission of subdivision-connectivity meshes (Kobbelt et al. 1999, sec. 8.1;
Khodakovsky, Schroeder & Sweldens 2000).

The base mesh goes first; every finer level is predicted from the previous one by a
subdivision rule (Loop or Butterfly) and corrected by per-vertex detail coefficients. The
coefficients of all levels are sent as one embedded bit-plane code: each pass halves the
threshold and sends which coefficients became significant, their signs, and one more bit of
those already significant, so the bits that reduce the error most come first whatever their
level, and any prefix of the file decodes to the best mesh those bytes allow.

Coefficients
    Level ``i`` has ``n_i = n_{i-1} + 3 nf_{i-1} / 2`` vertices, numbered as in
    :func:`meshfit.shrinkwrap._topo.subdivide`. Loop details cover vertices ``[0, n_i)`` of
    their level (every vertex moves), Butterfly details only ``[n_{i-1}, n_i)`` (even vertices
    are interpolated). A detail is the vertex's position minus the subdivision prediction
    from the coarser level, expressed in the local frame of the predicted surface (the
    normal, then the tangent towards a fixed neighbour, then their cross product): on a
    remesh lying on a surface, normal components carry most of the energy. The encoder
    predicts from the exact coarser levels (and the quantised base mesh); the decoder from
    what it has decoded, frames included, so the error at full length is the quantisation
    error carried through the (stable) subdivision rules.
Quantisation and ordering
    A coefficient component of level ``i`` is weighted by ``2**(-level_shift i / 2)`` and
    tangential components by a further ``2**-tangent_shift`` (a tangential error moves the
    surface along itself), divided by the step, and coded as sign and magnitude bits from
    plane ``planes - 1`` down to 0 (:mod:`meshfit._kernels.streamcode`). A decoded
    component is the middle of the interval its bits leave open; one not yet significant is
    0. The step makes the finest level's normal components exact to `STREAM_PRECISION`
    times the bounding-box diagonal. The default ``level_shift = 1`` lies between the L2
    norm of a level's basis functions (2: a level holds four times the vertices of the one
    before), which RMS error follows, and the maximum norm (0), which the Hausdorff
    distance follows.
Entropy coding
    An adaptive binary range coder (LZMA's) with contexts: a significance bit by its level,
    component, how many of its parents (the coarser vertices it was inserted between, or
    itself on the coarser level) are significant, and whether its own vertex already is
    (the zerotrees of Khodakovsky et al. as contexts); signs and refinement bits by
    component. The decoder stops before the first decision its bytes do not settle.

Binary format, version 2 (little endian)::

    header   magic  b"MFSW"            4 bytes
             version          u16      = 2
             scheme           u8       0 = loop, 1 = butterfly (modified: Zorin's rules at
                                       vertices of valence != 6)
             frame            u8       1 = local frames (0 = x, y, z)
             levels           u16      number of refinement levels m
             planes           u8       bit planes of the magnitudes (<= 30)
             level shift      u8       level weight 2**(-shift i / 2)
             tangent shift    u8       tangential weight 2**-shift
             reserved         u8       0
             base vertices    u32      n0
             base faces       u32      nf0
             block bytes      u32      B, payload bytes of a block
             file bytes       u64      length of the whole file
             origin           f8[3]    corner of the base mesh's quantisation cube
             extent           f8       its side
             step             f8       quantisation step of the weighted coefficients
             header CRC       u32      CRC-32 of the header's bytes before it
    body     blocks of B payload bytes (the last one shorter), each followed by the CRC-32
             of its payload started from the block's index (u32); B is the power of two
             from 256 to 4096 nearest to a 40th of the whole stream
    payload  base vertices    u16[n0, 3]   coordinates within the cube, 65535 = the side
             base faces       nf0 x 3 indices of ceil(log2 n0) bits, least significant
                                       bit first, padded to a byte
             coefficients     the range coder's bytes, to the end

A reader checks the header (magic, version, CRC, sizes, the finest level against
`meshfit.shrinkwrap.wrap.WRAP_MAX_FACES`) before it allocates anything, then every complete
block's CRC: a flipped bit in the header or a complete block is a StreamError naming where,
never another mesh. A file shorter than its header says is a cut file: its complete blocks
decode (the partial last block is dropped; `Stream.missing` says how much did not arrive),
provided the base mesh arrived; a file longer than its header says is an error. The base
mesh is validated (indices in range, three distinct corners a face, every edge in two
faces). Before it decodes, :func:`decode_stream` estimates the bytes the decode holds
(:func:`decode_bytes`) and refuses a level that would not fit in the memory the machine has
free. Version 1 (float detail packets, no checksums) is still read.
"""

from __future__ import annotations

import math
import os
import struct
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from meshfit import errors, tol
from meshfit._atomic import write_bytes
from meshfit._kernels import streamcode
from meshfit.shrinkwrap import _topo
from meshfit.shrinkwrap.subdivision import SCHEMES, level_faces, level_sizes, subdivide_step

__all__ = [
    "BLOCKS",
    "BLOCK_BYTES",
    "MAGIC",
    "MIN_BLOCK",
    "STREAM_PRECISION",
    "VERSION",
    "Packet",
    "Quantisation",
    "Stream",
    "decode_bytes",
    "decode_stream",
    "encode_stream",
    "read_stream",
    "reconstruction_errors",
    "write_stream",
]

MAGIC = b"MFSW"
VERSION = 2
#: a file is cut into about this many blocks (each followed by its CRC-32), of a power of
#: two between `MIN_BLOCK` and `BLOCK_BYTES` payload bytes: a cut file loses at most one
MIN_BLOCK, BLOCK_BYTES, BLOCKS = 256, 4096, 40
#: a full stream's finest-level normal components are exact to this, times the bounding-box
#: diagonal of the finest level (coarser levels and the base mesh to less)
STREAM_PRECISION = 2.0**-17
#: base mesh coordinates are quantised to this many bits within their cube
BASE_BITS = 16
#: the default weights (halves of a power of two a level; a power of two for tangents)
LEVEL_SHIFT = 1
TANGENT_SHIFT = 1
#: details in local frames (1) or x, y, z (0)
FRAME = 1
#: most bit planes (magnitudes are int32)
MAX_PLANES = 30
#: bytes a subdivision step holds at its peak per face it splits (edge tables, sorts, the
#: new positions), an upper bound of what tracemalloc measures for either scheme
STEP_BYTES_PER_FACE = 640
_HEADER = struct.Struct("<4sHBBHBBBBIIIQdddddI")  # (the CRC is the last field)
_V1_HEADER = struct.Struct("<4sHBBHHIII")
_V1_PACKET = struct.Struct("<2sBBII")
_CRC = struct.Struct("<I")


@dataclass(frozen=True)
class Packet:
    """Float detail coefficients of vertices ``start .. start + count`` of one level, as
    version-1 files hold them.

    Attributes
    ----------
    level : int
    start : int
    values : (count, 3) float32 | float64
    """

    level: int
    start: int
    values: NDArray


@dataclass(frozen=True)
class Quantisation:
    """How the coefficients of a version-2 stream are weighted and quantised.

    Attributes
    ----------
    origin : (3,) float64
        Corner of the cube the base mesh is quantised in.
    extent : float
        Side of that cube, model units.
    step : float
        Quantisation step of the weighted coefficients, model units.
    planes : int
        Bit planes of the magnitudes.
    level_shift, tangent_shift : int
        Weights ``2**(-level_shift i / 2)`` of level ``i`` and ``2**-tangent_shift`` of
        tangential components.
    frame : int
        1: local frames, 0: x, y, z.
    """

    origin: NDArray[np.float64]
    extent: float
    step: float
    planes: int
    level_shift: int = LEVEL_SHIFT
    tangent_shift: int = TANGENT_SHIFT
    frame: int = 1

    def weights(self, level: int) -> NDArray[np.float64]:
        """(3,) float64: weights of the three components of a level's coefficients."""
        w = 2.0 ** (-self.level_shift * level / 2)
        t = w * 2.0**-self.tangent_shift if self.frame else w
        return np.array([w, t, t])


@dataclass(frozen=True, eq=False)
class Stream:
    """A progressive stream: the base mesh and the coded detail coefficients.

    Attributes
    ----------
    scheme : str
    levels : int
    base_vertices : (n0, 3) float64
        As decoded (quantised for version 2).
    base_faces : (nf0, 3) int64
    data : bytes
        The range coder's bytes (version 2), possibly a prefix.
    quant : Quantisation or None
        None for version 1.
    packets : list of Packet
        Version 1 only: the float detail packets in file order.
    missing : int
        Bytes of the file that did not arrive (a cut file), 0 for a whole one.
    block_bytes : int
    """

    scheme: str
    levels: int
    base_vertices: NDArray[np.float64]
    base_faces: NDArray[np.int64]
    data: bytes = b""
    quant: Quantisation | None = None
    packets: tuple[Packet, ...] = ()
    missing: int = 0
    block_bytes: int = BLOCK_BYTES

    @property
    def version(self) -> int:
        return 1 if self.quant is None else VERSION

    @property
    def n_coefficients(self) -> int:
        """Detail vectors of all levels (one a vertex of a level that has one)."""
        if self.quant is None:
            return int(sum(len(p.values) for p in self.packets))
        sizes = level_sizes(self.base_faces, len(self.base_vertices), self.levels)
        lo = [0 if self.scheme == "loop" else s for s in sizes[:-1]]
        return int(sum(n - a for a, n in zip(lo, sizes[1:], strict=True)))

    @property
    def n_bytes(self) -> int:
        """Length of :meth:`to_bytes`."""
        return _file_size(len(self._base_payload()) + len(self.data), self.block_bytes)

    @property
    def min_bytes(self) -> int:
        """The shortest file that holds the base mesh (no coefficient)."""
        return _file_size(len(self._base_payload()), self.block_bytes)

    @property
    def min_prefix(self) -> int:
        """The shortest prefix of :meth:`to_bytes` that decodes: the blocks holding the base
        mesh, whole."""
        blocks = -(-len(self._base_payload()) // self.block_bytes)
        return min(self.n_bytes, _HEADER.size + blocks * (self.block_bytes + _CRC.size))

    def _base_payload(self) -> bytes:
        q = self.quant
        if q is None:
            raise errors.InputError("a version-1 stream is read only; encode it anew")
        scale = (2**BASE_BITS - 1) / q.extent
        qv = np.rint((self.base_vertices - q.origin) * scale).astype("<u2")
        bits = _index_bits(len(self.base_vertices))
        idx = np.asarray(self.base_faces, dtype=np.int64).reshape(-1)
        planes = ((idx[:, None] >> np.arange(bits)) & 1).astype(np.uint8)
        return qv.tobytes() + np.packbits(planes.reshape(-1), bitorder="little").tobytes()

    def to_bytes(self) -> bytes:
        """Serialise in the documented version-2 format (a cut stream as a whole, shorter
        file)."""
        q = self.quant
        payload = self._base_payload() + self.data
        size = _file_size(len(payload), self.block_bytes)
        hdr = _HEADER.pack(
            MAGIC,
            VERSION,
            SCHEMES.index(self.scheme),
            q.frame,
            self.levels,
            q.planes,
            q.level_shift,
            q.tangent_shift,
            0,
            len(self.base_vertices),
            len(self.base_faces),
            self.block_bytes,
            size,
            *map(float, q.origin),
            q.extent,
            q.step,
            0,
        )[: -_CRC.size]
        out = [hdr, _CRC.pack(zlib.crc32(hdr))]
        b = self.block_bytes
        for k, s in enumerate(range(0, len(payload), b)):
            blk = payload[s : s + b]
            out += [blk, _CRC.pack(zlib.crc32(blk, k))]
        return b"".join(out)

    def truncate(self, max_bytes: int) -> Stream:
        """This stream cut to a whole file of at most ``max_bytes`` bytes: the longest
        prefix of its coefficient bytes that fits.

        Raises
        ------
        meshfit.errors.InputError
            ``max_bytes`` is below :attr:`min_bytes` (the base mesh does not fit).
        """
        if max_bytes < self.min_bytes:
            raise errors.InputError(
                f"{max_bytes:,} bytes do not hold the base mesh: at least {self.min_bytes:,}"
            )
        room = max_bytes - _HEADER.size
        blocks, rest = divmod(room, self.block_bytes + _CRC.size)
        payload = blocks * self.block_bytes + max(0, rest - _CRC.size)
        k = min(len(self.data), payload - len(self._base_payload()))
        return replace(self, data=self.data[:k], missing=0)

    @classmethod
    def from_bytes(cls, data: bytes, *, where: str = "stream") -> Stream:
        """Parse a version-2 (or version-1) stream, every size and checksum checked before
        anything is allocated or decoded; a cut version-2 file gives the stream of its
        complete blocks. Raises :class:`meshfit.errors.StreamError`."""
        if len(data) < 6:
            raise errors.StreamError(f"{where}: truncated header ({len(data)} bytes)")
        magic, ver = struct.unpack_from("<4sH", data, 0)
        if magic != MAGIC:
            raise errors.StreamError(f"{where}: not a meshfit wrap stream (magic {magic!r})")
        if ver == 1:
            return _read_v1(data, where)
        if ver != VERSION:
            raise errors.StreamError(
                f"{where}: unsupported stream version {ver} (reads 1 and {VERSION})"
            )
        return _read_v2(data, where)


def _index_bits(n: int) -> int:
    """Bits of a base face index when the base has ``n`` vertices."""
    return max(1, (n - 1).bit_length())


def _file_size(payload: int, block: int) -> int:
    """Bytes of a version-2 file whose blocks hold ``payload`` bytes."""
    return _HEADER.size + payload + _CRC.size * -(-payload // block)


def _read_v2(data: bytes, where: str) -> Stream:
    """The version-2 reader of :meth:`Stream.from_bytes`."""
    if len(data) < _HEADER.size:
        raise errors.StreamError(f"{where}: truncated header ({len(data)} bytes)")
    (_, _, scheme, frame, levels, planes, lsh, tsh, _, n0, nf0, block, size, ox, oy, oz, ext, step,
     stored) = _HEADER.unpack_from(data, 0)  # fmt: skip
    if zlib.crc32(memoryview(data)[: _HEADER.size - _CRC.size]) != stored:
        raise errors.StreamError(f"{where}: header: checksum mismatch (the file is damaged)")
    if scheme >= len(SCHEMES) or frame > 1 or not 1 <= planes <= MAX_PLANES:
        raise errors.StreamError(f"{where}: bad scheme {scheme}, frame {frame} or {planes} planes")
    if lsh > 8 or tsh > 8 or not 64 <= block <= 1 << 24:
        raise errors.StreamError(f"{where}: bad weights ({lsh}, {tsh}) or block size {block}")
    origin = np.array([ox, oy, oz])
    if not (np.isfinite(origin).all() and 0 < ext < np.inf and 0 < step < np.inf):
        raise errors.StreamError(f"{where}: quantisation cube or step not finite and positive")
    largest = step * 2.0 ** (planes + (lsh * levels) / 2 + tsh)  # (a detail, unweighted)
    if max(np.abs(origin).max() + ext, largest) > tol.MAX_COORDINATE:
        raise errors.StreamError(
            f"{where}: quantisation cube or step beyond the largest coordinate "
            f"({tol.MAX_COORDINATE:g})"
        )
    _check_sizes(where, levels, n0, nf0)
    if size < len(data):
        raise errors.StreamError(
            f"{where}: the header says {size:,} bytes, the file has {len(data):,}"
        )
    base_len = 6 * n0 + -(-3 * nf0 * _index_bits(n0) // 8)
    if size < _file_size(base_len, block):
        raise errors.StreamError(
            f"{where}: the header says {size:,} bytes, its base mesh needs "
            f"{_file_size(base_len, block):,}"
        )
    body = len(data) - _HEADER.size
    if size == len(data):
        n_blocks = -(-body // (block + _CRC.size))
    else:
        n_blocks = body // (block + _CRC.size)
    parts = []
    off = _HEADER.size
    for k in range(n_blocks):
        end = min(off + block, len(data) - _CRC.size)
        (crc,) = _CRC.unpack_from(data, end)
        blk = memoryview(data)[off:end]
        if zlib.crc32(blk, k) != crc:
            raise errors.StreamError(
                f"{where}: block {k} (bytes {off:,} to {end + _CRC.size:,}): checksum "
                "mismatch (the file is damaged)"
            )
        parts.append(blk)
        off = end + _CRC.size
    if size == len(data) and off != len(data):
        raise errors.StreamError(f"{where}: blocks do not fill the file")
    payload = b"".join(parts)
    if len(payload) < base_len:
        raise errors.StreamError(
            f"{where}: truncated: {len(data):,} of {size:,} bytes arrived, the base mesh "
            "is not complete"
        )
    qv = np.frombuffer(payload, "<u2", 3 * n0, 0).reshape(n0, 3)
    bits = _index_bits(n0)
    packed = np.frombuffer(payload, np.uint8, base_len - 6 * n0, 6 * n0)
    flat = np.unpackbits(packed, bitorder="little")[: 3 * nf0 * bits].reshape(-1, bits)
    bf = (flat.astype(np.int64) << np.arange(bits)).sum(axis=1).reshape(nf0, 3)
    bv = origin + qv.astype(np.float64) * (ext / (2**BASE_BITS - 1))  # (as the encoder)
    _check_base(where, bv, bf)
    quant = Quantisation(origin, float(ext), float(step), int(planes), int(lsh), int(tsh), frame)
    return Stream(
        SCHEMES[scheme],
        int(levels),
        bv,
        bf,
        payload[base_len:],
        quant,
        missing=size - len(data),
        block_bytes=int(block),
    )


def _read_v1(data: bytes, where: str) -> Stream:
    """Version 1: base mesh in float64 and float detail packets, no checksums."""
    if len(data) < _V1_HEADER.size:
        raise errors.StreamError(f"{where}: truncated header ({len(data)} bytes)")
    _, _, scheme, vb, levels, _, n0, nf0, npk = _V1_HEADER.unpack_from(data, 0)
    off = _V1_HEADER.size
    if scheme >= len(SCHEMES) or vb not in (4, 8):
        raise errors.StreamError(f"{where}: bad scheme {scheme} or value size {vb}")
    _check_sizes(where, levels, n0, nf0)
    least = 24 * n0 + 12 * nf0 + npk * _V1_PACKET.size
    if least > len(data) - off:
        raise errors.StreamError(
            f"{where}: the header's counts need at least {least:,} bytes after it, the file "
            f"has {len(data) - off:,} (truncated or damaged)"
        )
    bv = np.frombuffer(data, "<f8", 3 * n0, off).reshape(n0, 3).astype(np.float64)
    off += 24 * n0
    bf = np.frombuffer(data, "<u4", 3 * nf0, off).reshape(nf0, 3).astype(np.int64)
    off += 12 * nf0
    _check_base(where, bv, bf)
    sizes = level_sizes(bf, n0, levels)
    dt = "<f4" if vb == 4 else "<f8"
    packets = []
    for k in range(npk):
        if len(data) < off + _V1_PACKET.size:
            raise errors.StreamError(f"{where}: truncated at packet {k} of {npk}")
        mk, lev, _, start, cnt = _V1_PACKET.unpack_from(data, off)
        if mk != b"PK":
            raise errors.StreamError(f"{where}: packet {k} at byte {off}: bad marker {mk!r}")
        end = off + _V1_PACKET.size + 3 * vb * cnt
        if len(data) < end:
            raise errors.StreamError(f"{where}: packet {k} is truncated")
        if not 1 <= lev <= levels or start + cnt > sizes[lev]:
            raise errors.StreamError(f"{where}: packet {k} does not fit level {lev}")
        vals = np.frombuffer(data, dt, 3 * cnt, off + _V1_PACKET.size).reshape(cnt, 3).copy()
        if not np.isfinite(vals).all():
            raise errors.StreamError(f"{where}: packet {k}: coefficients that are not finite")
        off = end
        packets.append(Packet(int(lev), int(start), vals))
    return Stream(SCHEMES[scheme], int(levels), bv, bf, packets=tuple(packets))


def _check_sizes(where: str, levels, n0, nf0) -> None:
    """StreamError, before any allocation, for a base mesh that cannot be closed or whose
    finest level would exceed `WRAP_MAX_FACES` (the memory a decode takes follows from it)."""
    from meshfit.shrinkwrap.wrap import WRAP_MAX_FACES

    if nf0 < 4 or n0 < 4 or nf0 % 2 or n0 > nf0 // 2 + 2:  # (closed: n0 = nf0 / 2 + 2 - 2g)
        raise errors.StreamError(f"{where}: a base mesh of {n0} vertices and {nf0} faces")
    if nf0 * 4**levels > WRAP_MAX_FACES:
        raise errors.StreamError(
            f"{where}: {levels} levels over {nf0} base faces make {nf0 * 4**levels:,} faces; "
            f"at most {WRAP_MAX_FACES:,} are decoded"
        )


def _check_base(where: str, bv: NDArray, bf: NDArray) -> None:
    """StreamError unless the base mesh is a closed manifold of finite points: indices in
    range, three distinct corners a face, every edge in exactly two faces."""
    if not np.isfinite(bv).all():
        raise errors.StreamError(f"{where}: base vertices that are not finite")
    if bf.max() >= len(bv):
        raise errors.StreamError(f"{where}: base face index {int(bf.max())} >= {len(bv)}")
    bad = (bf[:, 0] == bf[:, 1]) | (bf[:, 1] == bf[:, 2]) | (bf[:, 2] == bf[:, 0])
    if bad.any():
        raise errors.StreamError(
            f"{where}: base face {int(np.flatnonzero(bad)[0])} repeats a corner"
        )
    e = np.sort(np.concatenate([bf[:, [0, 1]], bf[:, [1, 2]], bf[:, [2, 0]]]), axis=1)
    _, count = np.unique(e, axis=0, return_counts=True)
    if (count != 2).any():
        raise errors.StreamError(
            f"{where}: the base mesh is not closed (an edge in {int(count[count != 2][0])} faces)"
        )


@dataclass(frozen=True)
class _Hierarchy:
    """Connectivity of the levels and the coefficient nodes over them."""

    sizes: list[int]
    faces: list[NDArray[np.int64]]
    lo: list[int]  # first vertex with a coefficient, a level (index 1..m; 0 unused)
    offset: list[int]  # first node of a level
    node_level: NDArray[np.int8]
    parents: NDArray[np.int32]


def _hierarchy(base_faces, n_base: int, levels: int, scheme: str, upto: int | None = None):
    """Faces of levels ``0..upto`` and the coefficient nodes of levels ``1..levels`` with
    their parents (the coarser level's node of the same vertex, or of the two ends of the
    edge a vertex was inserted on; -1 where the coarser level has no coefficient there)."""
    upto = levels if upto is None else upto
    sizes = level_sizes(base_faces, n_base, levels)
    faces = [np.asarray(base_faces, dtype=np.int64)]
    lo = [0] + [0 if scheme == "loop" else sizes[i - 1] for i in range(1, levels + 1)]
    offset = [0, 0]
    for i in range(1, levels + 1):
        offset.append(offset[-1] + sizes[i] - lo[i])
    node_level = np.empty(offset[-1], np.int8)
    parents = np.full((offset[-1], 2), -1, np.int32)
    cur = faces[0]
    for i in range(1, levels + 1):
        nxt, edges = _topo.subdivide(cur, sizes[i - 1])
        if i <= upto:
            faces.append(nxt)
        a, b = offset[i], offset[i + 1]
        node_level[a:b] = i
        if i >= 2:
            v = np.arange(lo[i], sizes[i])
            odd = v >= sizes[i - 1]
            ends = np.empty((len(v), 2), np.int64)
            ends[~odd, 0] = v[~odd]
            ends[~odd, 1] = -1
            ends[odd] = edges[v[odd] - sizes[i - 1]]
            ok = (ends >= lo[i - 1]) & (ends < sizes[i - 1])
            parents[a:b] = np.where(ok, ends - lo[i - 1] + offset[i - 1], -1)
        cur = nxt
    return _Hierarchy(sizes, faces, lo, offset, node_level, parents)


def _frames(x: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray[np.float64]:
    """(n, 3, 3): rows normal, tangent, bitangent at each vertex of a mesh: the area-weighted
    vertex normal, the direction to the vertex's first neighbour (by face order) projected
    off it, and their cross product; x, y, z where a vector vanishes."""
    n = len(x)
    fn = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    nrm = np.zeros((n, 3))
    for k in range(3):
        np.add.at(nrm, faces[:, k], fn)
    first, idx = np.unique(faces.reshape(-1), return_index=True)
    ref = np.empty(n, np.int64)
    ref[first] = faces.reshape(-1)[idx - idx % 3 + (idx % 3 + 1) % 3]
    t = x[ref] - x
    out = np.zeros((n, 3, 3))
    ln = np.linalg.norm(nrm, axis=1)
    good = ln > 0
    out[good, 0] = nrm[good] / ln[good, None]
    t -= np.einsum("ij,ij->i", t, out[:, 0])[:, None] * out[:, 0]
    lt = np.linalg.norm(t, axis=1)
    good &= lt > 1e-12 * np.maximum(np.linalg.norm(x[ref] - x, axis=1), 1e-300)
    out[good, 1] = t[good] / lt[good, None]
    out[good, 2] = np.cross(out[good, 0], out[good, 1])
    out[~good] = np.eye(3)
    return out


def encode_stream(
    vertices: NDArray[np.float64],
    base_faces: NDArray[np.int64],
    n_base: int,
    levels: int,
    *,
    scheme: str = "butterfly",
    max_bytes: int | None = None,
    precision: float = STREAM_PRECISION,
) -> Stream:
    """Progressive stream of a subdivision-connectivity mesh: quantised base mesh, detail
    coefficients against a subdivision predictor in one embedded bit-plane code.

    Parameters
    ----------
    vertices : (n_m, 3) float64
        Finest level ``M_m``; its first ``n_i`` vertices are level ``i`` (the coarser levels
        are sub-samples, as in sec. 2 of the paper).
    base_faces : (nf0, 3) int64
    n_base : int
        Vertices of the base mesh.
    levels : int
        ``m``.
    scheme : {"butterfly", "loop"}
        Butterfly (default) interpolates: only the new vertices of a level carry details,
        and a cut stream reaches a given error in fewer bytes than with Loop (measured in
        ``benchmarks/stream.py``).
    max_bytes : int, optional
        Cut the stream to a file of at most this many bytes (:meth:`Stream.truncate`).
    precision : float
        Quantisation of the finest level's normal components, times the bounding-box
        diagonal (default `STREAM_PRECISION`).

    Returns
    -------
    Stream

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 8.1.
    .. [2] Khodakovsky, Schroeder & Sweldens, "Progressive geometry compression",
       SIGGRAPH 2000, sec. 3-4.
    """
    if scheme not in SCHEMES:
        raise errors.InputError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    if not 0 < precision < 1:
        raise errors.InputError(f"precision must be in (0, 1), got {precision}")
    sizes = level_sizes(base_faces, n_base, levels)
    x = np.asarray(vertices, dtype=np.float64)
    if len(x) != sizes[-1]:
        raise errors.InputError(
            f"vertices has {len(x)} rows; {levels} levels of this base need {sizes[-1]}"
        )
    if not np.isfinite(x).all():
        raise errors.InputError("vertices that are not finite")
    lo_x, hi_x = x.min(axis=0), x.max(axis=0)
    extent = float(np.ptp(x, axis=0).max()) or 1.0
    diag = float(np.linalg.norm(hi_x - lo_x)) or 1.0
    quant = Quantisation(lo_x, extent, 1.0, 1, LEVEL_SHIFT, TANGENT_SHIFT, FRAME)
    quant = replace(quant, step=2 * precision * diag * float(quant.weights(levels)[0]))
    qv = np.rint((x[:n_base] - lo_x) * ((2**BASE_BITS - 1) / extent))
    base = lo_x + qv * (extent / (2**BASE_BITS - 1))  # (as the reader computes it)
    h = _hierarchy(base_faces, n_base, levels, scheme)
    coef = np.empty((h.offset[-1], 3))
    prev = base
    for i in range(1, levels + 1):
        pred, _ = subdivide_step(prev, h.faces[i - 1], scheme)
        d = x[h.lo[i] : sizes[i]] - pred[h.lo[i] :]
        if quant.frame:
            d = np.einsum("nij,nj->ni", _frames(pred, h.faces[i])[h.lo[i] :], d)
        coef[h.offset[i] : h.offset[i + 1]] = d * (quant.weights(i) / quant.step)
        prev = x[: sizes[i]]
    flat = coef.reshape(-1)
    mag = np.floor(np.abs(flat))
    planes = max(1, int(mag.max(initial=0)).bit_length())
    if planes > MAX_PLANES:
        raise errors.InputError(
            f"details up to {mag.max():.3g} steps need {planes} bit planes, at most "
            f"{MAX_PLANES}: ask for a coarser precision"
        )
    data = streamcode.encode_planes(
        mag.astype(np.int32), flat < 0, h.node_level, h.parents, planes, levels
    )
    st = Stream(
        scheme,
        levels,
        base,
        np.asarray(base_faces, dtype=np.int64),
        data.tobytes(),
        replace(quant, planes=planes),
    )
    size = len(st._base_payload()) + len(data)
    block = 2 ** round(math.log2(max(size, 1) / BLOCKS))
    st = replace(st, block_bytes=min(max(block, MIN_BLOCK), BLOCK_BYTES))
    return st if max_bytes is None else st.truncate(max_bytes)


def decode_stream(
    stream: Stream, packets: list[Packet] | None = None, *, level: int | None = None
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Reconstruct a level from the base mesh and the coefficient bytes the stream holds
    (all of them, or the prefix of a cut or truncated stream).

    Parameters
    ----------
    stream : Stream
    packets : list of Packet, optional
        Version 1 only: the packets received (default: all), any subset in any order;
        missing coefficients are 0.
    level : int, optional
        Level to reconstruct (default: the finest).

    Returns
    -------
    vertices : (n_level, 3) float64
    faces : (nf_level, 3) int64

    Raises
    ------
    meshfit.errors.StreamError
        The decode would not fit in the free memory, or a version-1 packet does not fit.
    """
    m = stream.levels if level is None else int(level)
    if not 0 <= m <= stream.levels:
        raise errors.InputError(f"level must be in [0, {stream.levels}], got {level}")
    nf0, n0 = len(stream.base_faces), len(stream.base_vertices)
    coded = 0 if stream.quant is None else stream.levels
    need, free = decode_bytes(nf0, n0, m, coded), _free_bytes()
    if free is not None and need > free:
        raise errors.StreamError(
            f"decoding level {m} needs about {need / 2**30:.1f} GiB, the machine has "
            f"{free / 2**30:.1f} GiB free: decode a coarser level (--level)"
        )
    if stream.quant is None:
        return _decode_v1(stream, stream.packets if packets is None else packets, m)
    q = stream.quant
    h = _hierarchy(stream.base_faces, n0, stream.levels, stream.scheme, upto=m)
    del packets
    raw = np.frombuffer(stream.data, np.uint8)
    mag, last, neg, _ = streamcode.decode_planes(
        raw, len(raw), h.node_level, h.parents, q.planes, stream.levels
    )
    x = np.array(stream.base_vertices, dtype=np.float64)
    for i in range(1, m + 1):
        a, b = 3 * h.offset[i], 3 * h.offset[i + 1]
        la = last[a:b].astype(np.int64)
        val = np.where(la >= 0, mag[a:b] + np.ldexp(0.5, np.maximum(la, 0)), 0.0)
        val[neg[a:b]] *= -1
        d = val.reshape(-1, 3) * (q.step / q.weights(i))
        x, _ = subdivide_step(x, h.faces[i - 1], stream.scheme)
        if q.frame:
            d = np.einsum("nji,nj->ni", _frames(x, h.faces[i])[h.lo[i] :], d)
        x[h.lo[i] :] += d
    return x, h.faces[m]


def _decode_v1(stream: Stream, pk, m: int) -> tuple[NDArray, NDArray]:
    """Version 1: float details, any subset of packets in any order."""
    sizes = level_sizes(stream.base_faces, len(stream.base_vertices), stream.levels)
    fl = level_faces(stream.base_faces, len(stream.base_vertices), m)
    details = [np.zeros((n, 3)) for n in sizes[: m + 1]]
    for k, p in enumerate(pk):
        if not 1 <= p.level <= stream.levels:
            raise errors.StreamError(f"packet {k}: level {p.level} not in [1, {stream.levels}]")
        end = p.start + len(p.values)
        if p.start < 0 or end > sizes[p.level]:
            raise errors.StreamError(
                f"packet {k}: vertices [{p.start}, {end}) exceed level {p.level} "
                f"({sizes[p.level]} vertices)"
            )
        if p.level <= m:
            details[p.level][p.start : end] = np.asarray(p.values, dtype=np.float64)
    x = np.array(stream.base_vertices, dtype=np.float64)
    for i in range(1, m + 1):
        x, _ = subdivide_step(x, fl[i - 1], stream.scheme)
        x += details[i]
    return x, fl[m]


def decode_bytes(n_base_faces: int, n_base: int, level: int, coded_levels: int = 0) -> int:
    """The bytes :func:`decode_stream` holds at its peak to decode ``level`` of a stream
    whose base mesh has ``n_base`` vertices and ``n_base_faces`` faces and whose coefficients
    cover ``coded_levels`` levels (0 for version 1): the faces of every level decoded
    (int64), the coefficient state of every coded level (all are decoded to stay in step
    with the range coder: magnitudes, planes, signs, parents, 22 bytes a vertex), a level's
    positions, details and frames, and the temporaries of the last subdivision step (its
    edge tables and sorts, `STEP_BYTES_PER_FACE` a face it splits)."""
    nf, ne, n, total = n_base_faces, 3 * n_base_faces // 2, n_base, 24 * (n_base_faces + n_base)
    step = 0
    for _ in range(level):
        step = STEP_BYTES_PER_FACE * nf
        n, nf = n + ne, 4 * nf
        ne = 3 * nf // 2
        total += 24 * (nf + n)
    nodes = sum(level_sizes(np.empty((n_base_faces, 3)), n_base, coded_levels)[1:])
    total += 22 * nodes + 24 * nodes  # (the nodes' state; the subdivision's edge tables)
    if not coded_levels:
        return total + max(step, 3 * 24 * n) + (1 << 16)  # (+ the arrays' own headers)
    # positions, details, frames and their products beside the step's temporaries
    return total + step + 216 * n + (1 << 16)


def _free_bytes() -> int | None:
    """The memory available to a new allocation (MemAvailable of /proc/meminfo), or None
    where the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def reconstruction_errors(
    stream: Stream, reference: NDArray[np.float64], fractions=(0.0, 0.01, 0.03, 0.1, 1.0)
) -> dict[str, float]:
    """RMS vertex distance to ``reference`` (model units) of the finest level decoded from
    the stream cut to a fraction of its bytes (at least its base mesh: ``"0%"`` is the base
    mesh alone), keyed ``"0%"``, ``"1%"``, ..."""
    total = stream.n_bytes
    out = {}
    for fr in fractions:
        cut = stream.truncate(max(stream.min_bytes, math.floor(fr * total)))
        x, _ = decode_stream(cut)
        out[f"{100 * fr:g}%"] = float(np.sqrt(np.mean(np.sum((x - reference) ** 2, axis=1))))
    return out


def write_stream(stream: Stream, path: str | os.PathLike) -> None:
    """Write atomically (temporary name in the same folder, then rename)."""
    write_bytes(path, stream.to_bytes())


def read_stream(path: str | os.PathLike) -> Stream:
    """Read a stream file (a cut one gives its complete blocks: see `Stream.missing`);
    raises :class:`meshfit.errors.StreamError` on a bad file."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise errors.StreamError(f"{path}: cannot read: {exc.strerror}") from None
    return Stream.from_bytes(data, where=str(path))
