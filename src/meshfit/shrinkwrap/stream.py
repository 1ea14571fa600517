"""Progressive transmission of subdivision-connectivity meshes (Kobbelt et al. 1999, sec. 8.1).

The base mesh goes first; every finer level is predicted from the previous one by a
subdivision rule (Loop or Butterfly) and corrected by per-vertex detail coefficients. Packets
of coefficients are indexed on their own (level and vertex range), so any subset, in any
order, decodes: a vertex whose coefficient has not arrived sits at its predicted position.

Binary format, version 2 (little endian)::

    header   magic  b"MFSW"            4 bytes
             version          u16      = 2
             scheme           u8       0 = loop, 1 = butterfly (modified: Zorin's rules at
                                       vertices of valence != 6)
             value bytes      u8       4 (float32) or 8 (float64) per coefficient component
             levels           u16      number of refinement levels m
             reserved         u16      0
             base vertices    u32      n0
             base faces       u32      nf0
             packets          u32      number of packets that follow
             file bytes       u64      length of the whole file
             header CRC       u32      CRC-32 of the header's bytes before it
    base     vertices         f8[n0, 3]
             faces            u32[nf0, 3]
             base CRC         u32      CRC-32 of the base's vertices and faces
    packet   marker b"PK"              2 bytes (repeated for every packet)
             level            u8       1..m
             reserved         u8       0
             start            u32      first vertex index of the level
             count            u32      number of coefficients
             values           f4|f8[count, 3]
             packet CRC       u32      CRC-32 of the packet's bytes before it

A reader checks the header (magic, version, sizes against the file's length, the finest
level against `meshfit.shrinkwrap.wrap.WRAP_MAX_FACES`) before it allocates anything, the
base mesh (indices in range, three distinct corners a face, every edge in two faces) and
every checksum: a flipped bit is a StreamError naming where, never another mesh. Version
1 (no file length, no checksums) is still read. Before it decodes, :func:`decode_stream`
estimates the bytes the decode holds (:func:`decode_bytes`) and refuses a level that would
not fit in the memory the machine has free.

Level ``i`` has ``n_i = n_{i-1} + 3 nf_{i-1} / 2`` vertices, numbered as in
:func:`meshfit.shrinkwrap._topo.subdivide`. Loop packets cover vertices ``[0, n_i)`` of their
level (every vertex moves), Butterfly packets only ``[n_{i-1}, n_i)`` (even vertices are
interpolated). Coefficients are computed against the decoder's own prediction (closed loop),
so storing float32 does not accumulate error across levels.
"""

from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from meshfit import errors
from meshfit._atomic import write_bytes
from meshfit.shrinkwrap.subdivision import SCHEMES, level_faces, level_sizes, subdivide_step

__all__ = [
    "MAGIC",
    "VERSION",
    "Packet",
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
#: bytes a subdivision step holds at its peak per face it splits (edge tables, sorts, the
#: new positions), an upper bound of what tracemalloc measures for either scheme
STEP_BYTES_PER_FACE = 640
_HEADER = struct.Struct("<4sHBBHHIII")
_HEADER2 = struct.Struct("<4sHBBHHIIIQ")  # + the header CRC (u32)
_PACKET = struct.Struct("<2sBBII")
_CRC = struct.Struct("<I")


@dataclass(frozen=True)
class Packet:
    """Detail coefficients of vertices ``start .. start + count`` of one level.

    Attributes
    ----------
    level : int
    start : int
    values : (count, 3) float32 | float64
    """

    level: int
    start: int
    values: NDArray


@dataclass(frozen=True, eq=False)
class Stream:
    """A decoded or to-be-written stream: base mesh plus packets.

    Attributes
    ----------
    scheme : str
    levels : int
    base_vertices : (n0, 3) float64
    base_faces : (nf0, 3) int64
    packets : list of Packet
        In transmission order (coarse levels first).
    value_bytes : int
        4 or 8.
    """

    scheme: str
    levels: int
    base_vertices: NDArray[np.float64]
    base_faces: NDArray[np.int64]
    packets: list[Packet]
    value_bytes: int = 4

    @property
    def n_coefficients(self) -> int:
        return int(sum(len(p.values) for p in self.packets))

    def to_bytes(self) -> bytes:
        """Serialise in the documented version-2 format."""
        base = (
            np.ascontiguousarray(self.base_vertices, dtype="<f8").tobytes()
            + np.ascontiguousarray(self.base_faces, dtype="<u4").tobytes()
        )
        dt = "<f4" if self.value_bytes == 4 else "<f8"
        packets = []
        for p in self.packets:
            body = _PACKET.pack(b"PK", p.level, 0, p.start, len(p.values))
            body += np.ascontiguousarray(p.values, dtype=dt).tobytes()
            packets.append(body + _CRC.pack(zlib.crc32(body)))
        size = _HEADER2.size + _CRC.size + len(base) + _CRC.size + sum(len(b) for b in packets)
        hdr = _HEADER2.pack(
            MAGIC,
            VERSION,
            SCHEMES.index(self.scheme),
            self.value_bytes,
            self.levels,
            0,
            len(self.base_vertices),
            len(self.base_faces),
            len(self.packets),
            size,
        )
        return b"".join(
            [hdr, _CRC.pack(zlib.crc32(hdr)), base, _CRC.pack(zlib.crc32(base)), *packets]
        )

    @classmethod
    def from_bytes(cls, data: bytes, *, where: str = "stream") -> Stream:
        """Parse a version-2 (or version-1) stream, every size and checksum checked before
        anything is allocated or decoded; raises :class:`meshfit.errors.StreamError`."""
        if len(data) < _HEADER.size:
            raise errors.StreamError(f"{where}: truncated header ({len(data)} bytes)")
        magic, ver = struct.unpack_from("<4sH", data, 0)
        if magic != MAGIC:
            raise errors.StreamError(f"{where}: not a meshfit wrap stream (magic {magic!r})")
        if ver not in (1, VERSION):
            raise errors.StreamError(
                f"{where}: unsupported stream version {ver} (reads 1 and {VERSION})"
            )
        v2 = ver == VERSION
        crc = _check_crc if v2 else _no_crc
        if v2:
            if len(data) < _HEADER2.size + _CRC.size:
                raise errors.StreamError(f"{where}: truncated header ({len(data)} bytes)")
            *fields, size = _HEADER2.unpack_from(data, 0)
            crc(data, 0, _HEADER2.size, f"{where}: header")
            if size != len(data):
                raise errors.StreamError(
                    f"{where}: the header says {size} bytes, the file has {len(data)}"
                    + (" (truncated)" if len(data) < size else "")
                )
            off = _HEADER2.size + _CRC.size
        else:
            fields = list(_HEADER.unpack_from(data, 0))
            off = _HEADER.size
        _, _, scheme, vb, levels, _, n0, nf0, npk = fields
        if scheme >= len(SCHEMES) or vb not in (4, 8):
            raise errors.StreamError(f"{where}: bad scheme {scheme} or value size {vb}")
        _check_sizes(where, levels, n0, nf0, npk, len(data) - off, vb, v2)
        need = 24 * n0 + 12 * nf0
        if len(data) < off + need + (_CRC.size if v2 else 0):
            raise errors.StreamError(f"{where}: truncated base mesh")
        crc(data, off, off + need, f"{where}: base mesh")
        bv = np.frombuffer(data, "<f8", 3 * n0, off).reshape(n0, 3).astype(np.float64)
        off += 24 * n0
        bf = np.frombuffer(data, "<u4", 3 * nf0, off).reshape(nf0, 3).astype(np.int64)
        off += 12 * nf0 + (_CRC.size if v2 else 0)
        _check_base(where, bv, bf)
        dt = "<f4" if vb == 4 else "<f8"
        packets = []
        for k in range(npk):
            if len(data) < off + _PACKET.size:
                raise errors.StreamError(f"{where}: truncated at packet {k} of {npk}")
            mk, lev, _, start, cnt = _PACKET.unpack_from(data, off)
            if mk != b"PK":
                raise errors.StreamError(f"{where}: packet {k} at byte {off}: bad marker {mk!r}")
            end = off + _PACKET.size + 3 * vb * cnt
            if len(data) < end + (_CRC.size if v2 else 0):
                raise errors.StreamError(f"{where}: packet {k} is truncated")
            crc(data, off, end, f"{where}: packet {k} at byte {off}")
            vals = np.frombuffer(data, dt, 3 * cnt, off + _PACKET.size).reshape(cnt, 3).copy()
            if not np.isfinite(vals).all():
                raise errors.StreamError(f"{where}: packet {k}: coefficients that are not finite")
            off = end + (_CRC.size if v2 else 0)
            packets.append(Packet(int(lev), int(start), vals))
        if v2 and off != len(data):
            raise errors.StreamError(f"{where}: {len(data) - off} bytes after the last packet")
        return cls(SCHEMES[scheme], int(levels), bv, bf, packets, int(vb))


def _check_crc(data: bytes, lo: int, hi: int, what: str) -> None:
    """StreamError when the CRC-32 stored after ``data[lo:hi]`` is not that of those bytes."""
    (stored,) = _CRC.unpack_from(data, hi)
    if zlib.crc32(memoryview(data)[lo:hi]) != stored:
        raise errors.StreamError(f"{what}: checksum mismatch (the file is damaged)")


def _no_crc(data: bytes, lo: int, hi: int, what: str) -> None:
    """(version 1 has no checksums)"""


def _check_sizes(where: str, levels, n0, nf0, npk, room: int, vb: int, v2: bool) -> None:
    """StreamError, before any allocation, for counts the file cannot hold or whose finest
    level would exceed `WRAP_MAX_FACES` (the memory a decode takes follows from it)."""
    from meshfit.shrinkwrap.wrap import WRAP_MAX_FACES

    if nf0 < 4 or n0 < 4 or nf0 % 2:
        raise errors.StreamError(f"{where}: a base mesh of {n0} vertices and {nf0} faces")
    if nf0 * 4**levels > WRAP_MAX_FACES:
        raise errors.StreamError(
            f"{where}: {levels} levels over {nf0} base faces make {nf0 * 4**levels:,} faces; "
            f"at most {WRAP_MAX_FACES:,} are decoded"
        )
    least = 24 * n0 + 12 * nf0 + npk * (_PACKET.size + (_CRC.size if v2 else 0))
    if least > room:
        raise errors.StreamError(
            f"{where}: the header's counts need at least {least:,} bytes after it, the file "
            f"has {room:,} (truncated or damaged)"
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


def encode_stream(
    vertices: NDArray[np.float64],
    base_faces: NDArray[np.int64],
    n_base: int,
    levels: int,
    *,
    scheme: str = "loop",
    packet_size: int = 1024,
    value_bytes: int = 4,
) -> Stream:
    """Detail coefficients of a subdivision-connectivity mesh against a subdivision predictor.

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
    scheme : {"loop", "butterfly"}
    packet_size : int
        Coefficients per packet (default 1024).
    value_bytes : {4, 8}
        float32 (default) or float64 coefficients.

    Returns
    -------
    Stream

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 8.1.
    """
    if scheme not in SCHEMES:
        raise errors.InputError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    if value_bytes not in (4, 8):
        raise errors.InputError(f"value_bytes must be 4 or 8, got {value_bytes}")
    if packet_size < 1:
        raise errors.InputError(f"packet_size must be >= 1, got {packet_size}")
    sizes = level_sizes(base_faces, n_base, levels)
    x = np.asarray(vertices, dtype=np.float64)
    if len(x) != sizes[-1]:
        raise errors.InputError(
            f"vertices has {len(x)} rows; {levels} levels of this base need {sizes[-1]}"
        )
    fl = level_faces(base_faces, n_base, levels)
    dt = np.float32 if value_bytes == 4 else np.float64
    rec = x[:n_base].copy()
    packets = []
    for i in range(1, levels + 1):
        pred, _ = subdivide_step(rec, fl[i - 1], scheme)
        lo = 0 if scheme == "loop" else sizes[i - 1]
        d = (x[lo : sizes[i]] - pred[lo:]).astype(dt)
        for s in range(0, len(d), packet_size):
            packets.append(Packet(i, lo + s, d[s : s + packet_size]))
        pred[lo:] += d.astype(np.float64)
        rec = pred
    return Stream(scheme, levels, x[:n_base].copy(), np.asarray(base_faces), packets, value_bytes)


def decode_stream(
    stream: Stream, packets: list[Packet] | None = None, *, level: int | None = None
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Reconstruct a level from the base mesh and any subset of packets, in any order.

    Parameters
    ----------
    stream : Stream
    packets : list of Packet, optional
        The packets received (default: all of ``stream.packets``). Missing coefficients are 0:
        those vertices stay at their predicted positions.
    level : int, optional
        Level to reconstruct (default: the finest).

    Returns
    -------
    vertices : (n_level, 3) float64
    faces : (nf_level, 3) int64

    Raises
    ------
    meshfit.errors.StreamError
        A packet's level or vertex range does not fit the stream.
    """
    m = stream.levels if level is None else int(level)
    if not 0 <= m <= stream.levels:
        raise errors.InputError(f"level must be in [0, {stream.levels}], got {level}")
    need, free = decode_bytes(len(stream.base_faces), len(stream.base_vertices), m), _free_bytes()
    if free is not None and need > free:
        raise errors.StreamError(
            f"decoding level {m} needs about {need / 2**30:.1f} GiB, the machine has "
            f"{free / 2**30:.1f} GiB free: decode a coarser level (--level)"
        )
    pk = stream.packets if packets is None else packets
    sizes = level_sizes(stream.base_faces, len(stream.base_vertices), stream.levels)
    fl = level_faces(stream.base_faces, len(stream.base_vertices), m)
    details = [np.zeros((n, 3)) for n in sizes]
    for k, p in enumerate(pk):
        if not 1 <= p.level <= stream.levels:
            raise errors.StreamError(f"packet {k}: level {p.level} not in [1, {stream.levels}]")
        end = p.start + len(p.values)
        if p.start < 0 or end > sizes[p.level]:
            raise errors.StreamError(
                f"packet {k}: vertices [{p.start}, {end}) exceed level {p.level} "
                f"({sizes[p.level]} vertices)"
            )
        details[p.level][p.start : end] = np.asarray(p.values, dtype=np.float64)
    x = np.array(stream.base_vertices, dtype=np.float64)
    for i in range(1, m + 1):
        x, _ = subdivide_step(x, fl[i - 1], stream.scheme)
        x += details[i]
    return x, fl[m]


def decode_bytes(n_base_faces: int, n_base: int, level: int) -> int:
    """The bytes :func:`decode_stream` holds at its peak to decode ``level`` of a stream
    whose base mesh has ``n_base`` vertices and ``n_base_faces`` faces: the faces of every
    level (int64) and a detail array a level (float64), with the temporaries of the last
    subdivision step (its edge tables and sorts, `STEP_BYTES_PER_FACE` a face it splits)."""
    nf, ne, n, total = n_base_faces, 3 * n_base_faces // 2, n_base, 24 * (n_base_faces + n_base)
    step = 0
    for _ in range(level):
        step = STEP_BYTES_PER_FACE * nf
        n, nf = n + ne, 4 * nf
        ne = 3 * nf // 2
        total += 24 * (nf + n)
    return total + max(step, 3 * 24 * n) + (1 << 16)  # (+ the arrays' own headers)


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
    """RMS vertex distance to ``reference`` after decoding the first fraction of coefficients
    in transmission order (model units), keyed ``"0%"``, ``"1%"``, ..."""
    total = stream.n_coefficients
    out = {}
    for fr in fractions:
        budget = fr * total
        got, used = [], 0
        for p in stream.packets:
            if used + len(p.values) > budget + 1e-9:
                cut = round(budget - used)
                if cut > 0:
                    got.append(Packet(p.level, p.start, p.values[:cut]))
                break
            got.append(p)
            used += len(p.values)
        x, _ = decode_stream(stream, got)
        key = f"{100 * fr:g}%"
        out[key] = float(np.sqrt(np.mean(np.sum((x - reference) ** 2, axis=1))))
    return out


def write_stream(stream: Stream, path: str | os.PathLike) -> None:
    """Write atomically (temporary name in the same folder, then rename)."""
    write_bytes(path, stream.to_bytes())


def read_stream(path: str | os.PathLike) -> Stream:
    """Read a stream file; raises :class:`meshfit.errors.StreamError` on a bad file."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise errors.StreamError(f"{path}: cannot read: {exc.strerror}") from None
    return Stream.from_bytes(data, where=str(path))
