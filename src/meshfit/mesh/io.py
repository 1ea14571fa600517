"""Reading and writing mesh files (PLY, OBJ, STL, OFF, GLB/glTF).

PLY, STL and GLB/glTF are read through trimesh with ``process=False``; OBJ and OFF by small
readers here (trimesh drops unreferenced OBJ vertices, splits them along UV seams and
silently drops truncated OFF faces), and binary PLY whose faces have different corner counts
too (trimesh reads binary PLY faces of one corner count only). Vertices are never merged or
reordered; polygons are triangulated (fans), vertex colours are kept. Truncated and
unreadable files raise :class:`meshfit.errors.MeshFileError`.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from meshfit import errors
from meshfit._atomic import write_bytes
from meshfit.mesh.core import Mesh

__all__ = ["FORMATS", "RawMesh", "load_cli_mesh", "load_mesh", "read_mesh_arrays", "save_mesh"]

#: file suffixes meshfit reads and writes
FORMATS = (".ply", ".obj", ".stl", ".off", ".glb", ".gltf")


@dataclass
class RawMesh:
    """Arrays read from a file, before validation.

    Attributes
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64
    vertex_colors : (nv, 3 | 4) uint8 or None
    notes : list of str
        What the reader did (polygons triangulated, scene parts joined).
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    vertex_colors: NDArray[np.uint8] | None
    notes: list[str] = field(default_factory=list)


#: PLY property types and their numpy dtypes (byte order added by the reader)
_PLY_NUMPY = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_PLY_SIZES = {name: np.dtype(code).itemsize for name, code in _PLY_NUMPY.items()}


@dataclass
class _PlyHeader:
    """What a PLY header declares: elements in file order, each ``(name, count, properties)``
    with a property ``(name, type, list count type or None)``."""

    elements: list[tuple[str, int, list[tuple[str, str, str | None]]]]
    length: int  # header bytes, including the end_header line
    fmt: str

    def count(self, name: str) -> int:
        return next((n for e, n, _ in self.elements if e == name), -1)


def _ply_header(path: Path) -> _PlyHeader | None:
    """Elements, header byte length and format of a PLY file (None if not PLY)."""
    with open(path, "rb") as fh:
        head = fh.read(65536)
    if not head.startswith(b"ply"):
        return None
    end = head.find(b"end_header")
    if end < 0:
        raise errors.MeshFileError(f"{path}: PLY header has no end_header line")
    nl = head.find(b"\n", end)
    length = nl + 1 if nl >= 0 else len(head)
    elements: list[tuple[str, int, list[tuple[str, str, str | None]]]] = []
    fmt = "?"
    for line in head[:end].decode("ascii", errors="replace").splitlines():
        w = line.split()
        if len(w) >= 2 and w[0] == "format":
            fmt = w[1]
        elif len(w) >= 3 and w[0] == "element" and w[2].isdigit():
            elements.append((w[1], int(w[2]), []))
        elif len(w) >= 5 and w[0] == "property" and w[1] == "list" and elements:
            elements[-1][2].append((w[4], w[3], w[2]))
        elif len(w) >= 3 and w[0] == "property" and elements:
            elements[-1][2].append((w[2], w[1], None))
    return _PlyHeader(elements, length, fmt)


def _check_whole_indices(path: Path, rows: list[str], first_list: int) -> None:
    """MeshFileError naming the first ASCII PLY face whose vertex indices are not whole
    numbers (a reader would truncate 1.5 to 1: another mesh, silently)."""
    if not re.search(r"[.eE]", "\n".join(rows)):
        return
    for i, ln in enumerate(rows):
        tokens = ln.split()
        try:
            n = int(tokens[first_list])
        except (IndexError, ValueError):
            continue  # (the corner counts are checked apart)
        for t in tokens[first_list + 1 : first_list + 1 + n]:
            if not t.lstrip("+-").isdigit():
                raise errors.MeshFileError(
                    f"{path}: face {i}: vertex index {t!r} is not a whole number"
                )


def _ply_ascii_scan(path: Path, header: _PlyHeader) -> int:
    """Check the data lines of an ASCII PLY against its header; return how many faces have
    more than three corners.

    Raises MeshFileError naming the element where a truncated file ends, or the first face
    with fewer than three corners.
    """
    with open(path, "rb") as fh:
        fh.seek(header.length)
        lines = [
            ln for ln in fh.read().decode("ascii", errors="replace").splitlines() if ln.strip()
        ]
    row = 0
    polygons = 0
    for name, count, props in header.elements:
        rows = lines[row : row + count]
        # tokens a complete row needs: one per scalar property, 1 + n per list property
        lists = [i for i, (_, _, ct) in enumerate(props) if ct is not None]
        first_list = lists[0] if lists else -1

        def complete(tokens: list[str], props=props, first_list=first_list) -> bool:
            if first_list < 0:
                return len(tokens) >= len(props)
            try:
                n = int(tokens[first_list])
            except (IndexError, ValueError):
                return False
            return len(tokens) >= len(props) + n

        if len(rows) < count or (
            rows and row + count >= len(lines) and not complete(rows[-1].split())
        ):
            done = len(rows) if not rows or complete(rows[-1].split()) else len(rows) - 1
            raise errors.MeshFileError(
                f"{path}: truncated PLY: header declares {count} {name} elements, the file "
                f"ends in {name} {done} (after {done} complete {name} lines)"
            )
        if name == "face" and first_list >= 0:
            try:
                sizes = np.array([ln.split()[first_list] for ln in rows], dtype=np.int64)
            except (IndexError, ValueError):
                sizes = np.zeros(0, dtype=np.int64)  # malformed: left to the reader
            _check_corner_counts(path, sizes)
            _check_whole_indices(path, rows, first_list)
            polygons = int((sizes > 3).sum())
        row += count
    return polygons


def _check_corner_counts(
    path: Path, sizes: NDArray[np.int64], *, unit: str = "corners", line=None
) -> None:
    """MeshFileError naming the first face with fewer than three corners, if any (``line``:
    face index -> its line in a text file, for the message)."""
    short = np.flatnonzero(sizes < 3)
    if short.size:
        k = int(short[0])
        where = "" if line is None else f"line {line(k)}: "
        raise errors.MeshFileError(
            f"{path}: {where}face {k} has {sizes[k]} {unit}, a face needs at least 3 "
            f"({_count(short.size, 'such face')})"
        )


def _ply_binary_min_size(header: _PlyHeader) -> int:
    """Fewest data bytes a binary PLY with this header can hold (faces as triangles)."""
    total = 0
    for name, count, props in header.elements:
        per = 0
        for _, typ, ct in props:
            if ct is None:
                per += _PLY_SIZES.get(typ, 0)
            else:
                per += _PLY_SIZES.get(ct, 0) + (3 * _PLY_SIZES.get(typ, 0) if name == "face" else 0)
        total += count * per
    return total


#: vertex colour properties of a PLY file, in RGBA order
_PLY_COLORS = ("red", "green", "blue", "alpha")


def _ply_offsets(buf, pos, count, kinds, order, what, path, starts, sizes) -> int:
    """Offsets of every property of ``count`` binary PLY rows, row by row (a list's count
    decides where the next property starts), appended to ``starts`` (and list lengths to
    ``sizes``); ``kinds`` per property ``(item size, count size or 0, count signed)``.
    Returns the offset after the rows; MeshFileError naming the row where the data ends."""
    byteorder = "little" if order == "<" else "big"
    n = len(buf)
    for row in range(count):
        for k, (size, csize, signed) in enumerate(kinds):
            if csize:
                if pos + csize > n:
                    break
                m = int.from_bytes(buf[pos : pos + csize], byteorder, signed=signed)
                pos += csize
                if m < 0:
                    raise errors.MeshFileError(
                        f"{path}: cannot read binary PLY: {what} {row} has a list of {m} items"
                    )
                sizes[k].append(m)
                starts[k].append(pos)
                pos += m * size
            else:
                starts[k].append(pos)
                pos += size
            if pos > n:
                break
        else:
            continue
        raise errors.MeshFileError(
            f"{path}: truncated binary PLY: the file ends in {what} {row} of {count}"
        )
    return pos


def _ply_rows(buf: bytes, pos: int, count: int, props, order: str, what: str, path: Path):
    """Read ``count`` rows of a binary PLY element from ``buf`` at ``pos``.

    Returns ``(columns, pos)``: scalar properties as arrays, list properties as
    ``(sizes, flat items)``, and the offset after the element. Rows of scalar properties only
    are read at once; rows with a list property (faces with different corner counts) one by
    one. Raises MeshFileError naming the row where the data ends.
    """
    for _, typ, ct in props:
        if typ not in _PLY_NUMPY or (ct is not None and ct not in _PLY_NUMPY):
            raise errors.MeshFileError(
                f"{path}: cannot read binary PLY: unknown property type in element {what}"
            )
    if all(ct is None for _, _, ct in props):
        dt = np.dtype([(name, order + _PLY_NUMPY[typ]) for name, typ, _ in props])
        end = pos + count * dt.itemsize
        if end > len(buf):
            done = (len(buf) - pos) // max(dt.itemsize, 1)
            raise errors.MeshFileError(
                f"{path}: truncated binary PLY: the file ends in {what} {done} of {count}"
            )
        rows = np.frombuffer(buf, dtype=dt, count=count, offset=pos)
        return {name: rows[name] for name, _, _ in props}, end
    # every property's offsets, row by row (`_ply_offsets`; the usual face row, one uchar
    # count and the indices, inline), then each property gathered at its offsets at once
    kinds = []
    for _, typ, ct in props:
        item = np.dtype(order + _PLY_NUMPY[typ])
        if ct is None:
            kinds.append((item.itemsize, 0, False))
        else:
            cnt = np.dtype(_PLY_NUMPY[ct])
            kinds.append((item.itemsize, cnt.itemsize, cnt.kind == "i"))
    starts: list[list[int]] = [[] for _ in props]
    sizes: list[list[int]] = [[] for _ in props]
    n = len(buf)
    if kinds == [(kinds[0][0], 1, False)]:  # the usual face row: a uchar count, the indices
        size, at, m_of = kinds[0][0], starts[0], sizes[0]
        for row in range(count):
            if pos >= n:
                raise errors.MeshFileError(
                    f"{path}: truncated binary PLY: the file ends in {what} {row} of {count}"
                )
            m = buf[pos]
            m_of.append(m)
            at.append(pos + 1)
            pos += 1 + m * size
        if pos > n:
            raise errors.MeshFileError(
                f"{path}: truncated binary PLY: the file ends in {what} {count - 1} of {count}"
            )
    else:
        pos = _ply_offsets(buf, pos, count, kinds, order, what, path, starts, sizes)
    raw = np.frombuffer(buf, dtype=np.uint8)
    cols: dict = {}
    for k, (name, typ, ct) in enumerate(props):
        item = np.dtype(order + _PLY_NUMPY[typ])
        at = np.asarray(starts[k], dtype=np.int64)
        if ct is not None:
            m = np.asarray(sizes[k], dtype=np.int64)
            first = np.repeat(at, m)
            j = np.arange(int(m.sum())) - np.repeat(np.cumsum(m) - m, m)
            at = first + j * item.itemsize
        data = raw[at[:, None] + np.arange(item.itemsize)].copy().view(item).reshape(-1)
        if ct is None:
            cols[name] = data.astype(_PLY_NUMPY[typ])
        else:
            cols[name] = (np.asarray(sizes[k], dtype=np.int64), data)
    return cols, pos


def _read_ply_binary(path: Path, header: _PlyHeader) -> RawMesh:
    """Vertices, vertex colours and faces of a binary PLY with faces of different corner
    counts, which trimesh does not read; polygons fan-triangulated."""
    order = "<" if header.fmt == "binary_little_endian" else ">"
    buf = path.read_bytes()
    pos = header.length
    vertices = np.zeros((0, 3))
    colors = None
    faces = np.zeros((0, 3), np.int64)
    notes: list[str] = []
    for name, count, props in header.elements:
        cols, pos = _ply_rows(buf, pos, count, props, order, name, path)
        if name == "vertex":
            if not all(c in cols for c in "xyz"):
                raise errors.MeshFileError(f"{path}: PLY vertex element has no x, y, z")
            vertices = np.stack([cols[c].astype(np.float64) for c in "xyz"], axis=1)
            have = [c for c in _PLY_COLORS if c in cols]
            if have[:3] == ["red", "green", "blue"] and all(
                cols[c].dtype == np.uint8 for c in have
            ):
                colors = np.stack([cols[c] for c in have], axis=1).astype(np.uint8)
        elif name == "face":
            lists = [
                cols[p]
                for p, _, ct in props
                if ct is not None and p in ("vertex_indices", "vertex_index")
            ]
            if not lists:
                raise errors.MeshFileError(f"{path}: PLY face element has no vertex_indices list")
            sizes, flat = lists[0]
            if flat.dtype.kind not in "iu":
                raise errors.MeshFileError(f"{path}: PLY face indices are not integers")
            flat = flat.astype(np.int64)
            _check_corner_counts(path, sizes)
            faces = _triangulate(flat, sizes, notes)
    return RawMesh(vertices, faces, colors, notes)


def _text(path: Path, kind: str) -> list[str]:
    """Lines of a text mesh file (MeshFileError when it is not text)."""
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise errors.MeshFileError(
            f"{path}: cannot read {kind} file: not text (undecodable byte at offset {exc.start})"
        ) from None
    if "\0" in text:
        raise errors.MeshFileError(f"{path}: cannot read {kind} file: not text (NUL bytes)")
    return text.splitlines()


def _triangulate(
    flat: NDArray[np.int64], sizes: NDArray[np.int64], notes: list[str]
) -> NDArray[np.int64]:
    """Fan-triangulate polygons given as concatenated corner lists (each size >= 3)."""
    ntri = sizes - 2
    start = np.cumsum(sizes) - sizes
    owner = np.repeat(np.arange(sizes.size), ntri)
    j = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    o = start[owner]
    faces = np.stack([flat[o], flat[o + j], flat[o + j + 1]], axis=1).astype(np.int64)
    polys = int((sizes > 3).sum())
    if polys:
        notes.append(f"triangulated {polys} polygon faces into {faces.shape[0]} triangles")
    return faces


_OBJ_V = re.compile(r"^[ \t]*v[ \t]+([^\n#]*)", re.M)
_OBJ_F = re.compile(r"^[ \t]*f[ \t]+([^\n#]*)", re.M)
_OBJ_VF = re.compile(r"^[ \t]*([vf])[ \t]", re.M)


def _obj_line(text: str, pattern: re.Pattern, k: int) -> int:
    """Line number of the k-th match of ``pattern`` (error messages only)."""
    for i, m in enumerate(pattern.finditer(text)):
        if i == k:
            return text.count("\n", 0, m.start()) + 1
    return -1


def _read_obj(path: Path) -> RawMesh:
    """Read the vertices and faces of a Wavefront OBJ, keeping the file's vertex order.

    Texture / normal indices (``f v/vt/vn``) are ignored, so vertices are never split along
    UV seams and unreferenced vertices are kept (trimesh drops the latter and splits the
    former). Indices are checked: 0 and indices past the vertices raise IndexRangeError.
    """
    text = "\n".join(_text(path, "OBJ"))
    vrows = [ln.split() for ln in _OBJ_V.findall(text)]
    nv = len(vrows)
    short = next((k for k, r in enumerate(vrows) if len(r) < 3), None)
    if short is not None:
        raise errors.MeshFileError(
            f"{path}: line {_obj_line(text, _OBJ_V, short)}: vertex "
            f"{short} has fewer than 3 coordinates"
        )
    try:
        vertices = np.array([r[:3] for r in vrows], dtype=np.float64).reshape(nv, 3)
    except ValueError:
        k = next(k for k, r in enumerate(vrows) if not _floats(r[:3]))
        raise errors.MeshFileError(
            f"{path}: line {_obj_line(text, _OBJ_V, k)}: vertex {k} has "
            f"a non-numeric coordinate {' '.join(vrows[k][:3])!r}"
        ) from None
    colors = None
    if nv and all(len(r) == 6 for r in vrows) and _floats(vrows[0][3:]):
        try:
            c = np.array([r[3:6] for r in vrows], dtype=np.float64)
        except ValueError:
            c = None
        if c is not None and np.isfinite(c).all():
            colors = np.clip(np.round(c * 255.0 if c.max() <= 1.0 else c), 0, 255).astype(np.uint8)
    del vrows
    notes: list[str] = []
    flines = _OBJ_F.findall(text)
    if any("/" in ln for ln in flines):  # drop texture / normal indices: v/vt/vn -> v
        flines = [re.sub(r"/\S*", "", ln) for ln in flines]
    frows = [ln.split() for ln in flines]
    sizes = np.array([len(r) for r in frows], dtype=np.int64)
    _check_corner_counts(
        path, sizes, unit="vertex indices", line=lambda k: _obj_line(text, _OBJ_F, k)
    )
    try:
        idx = np.array([t for r in frows for t in r], dtype=np.int64)
    except (ValueError, OverflowError):
        k = next(k for k, r in enumerate(frows) if not _ints(r))
        raise errors.MeshFileError(
            f"{path}: line {_obj_line(text, _OBJ_F, k)}: face {k} has a "
            f"non-integer vertex index in {' '.join(frows[k])!r}"
        ) from None
    flat = idx - 1  # OBJ indices are 1-based
    if (idx < 0).any():  # negative indices count back from the last vertex defined so far
        is_v = np.array(_OBJ_VF.findall(text)) == "v"
        base = np.cumsum(is_v)[~is_v]  # vertices before each face
        flat = np.where(idx < 0, np.repeat(base, sizes) + idx, flat)
    wrong = (idx == 0) | (flat < 0) | (flat >= nv)
    if wrong.any():
        owner = np.repeat(np.arange(sizes.size), sizes)
        w = int(np.flatnonzero(wrong)[0])
        k = int(owner[w])
        n_bad = int(np.unique(owner[wrong]).size)
        raise errors.IndexRangeError(
            f"{path}: line {_obj_line(text, _OBJ_F, k)}: face {k} refers to vertex {int(idx[w])}, "
            f"which does not exist (the file has {nv} vertices; OBJ indices run from 1, negative "
            f"ones count back from the last vertex defined; {_count(n_bad, 'such face')})",
            first=(k,),
            count=n_bad,
        )
    faces = _triangulate(flat, sizes, notes) if sizes.size else np.zeros((0, 3), np.int64)
    return RawMesh(vertices, faces, colors, notes)


def _floats(tokens: list[str]) -> bool:
    try:
        [float(t) for t in tokens]
    except ValueError:
        return False
    return True


def _ints(tokens: list[str]) -> bool:
    """Whether every token is a whole number within the int64 range."""
    try:
        values = [int(t.split("/", 1)[0]) for t in tokens]
    except ValueError:
        return False
    return all(-(2**63) <= v < 2**63 for v in values)


def _count(n: int, what: str) -> str:
    return f"1 {what}" if n == 1 else f"{n} {what.replace('face', 'faces')}"


def _read_off(path: Path) -> RawMesh:
    """Read an (ASCII) OFF file: header, counts, vertices, polygon faces; checks truncation and
    face indices (trimesh silently drops missing faces)."""
    lines = _text(path, "OFF")
    rows: list[tuple[int, list[str]]] = []
    for i, ln in enumerate(lines):
        w = ln.split("#", 1)[0].split()
        if w:
            rows.append((i + 1, w))
    if not rows or not rows[0][1][0].upper().endswith("OFF"):
        raise errors.MeshFileError(f"{path}: cannot read OFF file: it does not start with OFF")
    head = rows[0][1][1:]  # counts may follow the keyword on the same line
    body = rows[1:]
    if not head:
        if not body:
            raise errors.MeshFileError(f"{path}: truncated OFF: no vertex / face count line")
        head = body[0][1]
        body = body[1:]
    try:
        nv, nf = int(head[0]), int(head[1])
    except (IndexError, ValueError):
        raise errors.MeshFileError(
            f"{path}: cannot read OFF file: malformed count line {' '.join(head)!r}"
        ) from None
    vrows = body[:nv]
    frows = body[nv : nv + nf]
    if len(vrows) < nv or (vrows and len(vrows[-1][1]) < 3):
        done = len(vrows) if not vrows or len(vrows[-1][1]) >= 3 else len(vrows) - 1
        raise errors.MeshFileError(
            f"{path}: truncated OFF: header declares {nv} vertices, the "
            f"file ends in vertex {done} ({done} complete)"
        )
    short = next((k for k, (_, w) in enumerate(vrows) if len(w) < 3), None)
    if short is not None:
        raise errors.MeshFileError(
            f"{path}: line {vrows[short][0]}: vertex {short} has fewer than 3 coordinates"
        )
    try:
        vertices = np.array([w[:3] for _, w in vrows], dtype=np.float64).reshape(nv, 3)
    except ValueError:
        k = next(k for k, (_, w) in enumerate(vrows) if not _floats(w[:3]))
        raise errors.MeshFileError(
            f"{path}: line {vrows[k][0]}: vertex {k} has a non-numeric coordinate"
        ) from None
    try:
        sizes = np.array([w[0] for _, w in frows], dtype=np.int64)
    except (ValueError, OverflowError):
        k = next(k for k, (_, w) in enumerate(frows) if not _ints(w[:1]))
        raise errors.MeshFileError(
            f"{path}: line {frows[k][0]}: face {k} does not start with its corner count"
        ) from None
    complete = [len(w) >= 1 + n for (_, w), n in zip(frows, sizes.tolist(), strict=True)]
    if len(frows) < nf or (frows and not complete[-1]):
        done = len(frows) if not frows or complete[-1] else len(frows) - 1
        raise errors.MeshFileError(
            f"{path}: truncated OFF: header declares {nf} faces, the file "
            f"ends in face {done} ({done} complete)"
        )
    _check_corner_counts(path, sizes, line=lambda k: frows[k][0])
    short = next((k for k, ok in enumerate(complete) if not ok), None)
    if short is not None:
        raise errors.MeshFileError(
            f"{path}: line {frows[short][0]}: face {short} has fewer vertex indices than its "
            f"count {int(sizes[short])}"
        )
    try:
        flat = np.array(
            [t for (_, w), n in zip(frows, sizes.tolist(), strict=True) for t in w[1 : 1 + n]],
            dtype=np.int64,
        )
    except (ValueError, OverflowError):
        k = next(k for k, (_, w) in enumerate(frows) if not _ints(w[1 : 1 + int(sizes[k])]))
        raise errors.MeshFileError(
            f"{path}: line {frows[k][0]}: face {k} has a non-integer vertex index"
        ) from None
    wrong = (flat < 0) | (flat >= nv)
    if wrong.any():
        owner = np.repeat(np.arange(sizes.size), sizes)
        w = int(np.flatnonzero(wrong)[0])
        k = int(owner[w])
        n_bad = int(np.unique(owner[wrong]).size)
        raise errors.IndexRangeError(
            f"{path}: line {frows[k][0]}: face {k} refers to vertex {int(flat[w])}, outside "
            f"[0, {nv}) ({_count(n_bad, 'such face')})",
            first=(k,),
            count=n_bad,
        )
    notes: list[str] = []
    faces = _triangulate(flat, sizes, notes) if nf else np.zeros((0, 3), np.int64)
    return RawMesh(vertices, faces, None, notes)


def _stl_check(path: Path) -> RawMesh | None:
    """Binary STL sanity: an empty mesh for 0 triangles, MeshFileError when the size does not
    match the triangle count (trimesh reports a truncated file as holding no mesh)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
    n = int(np.frombuffer(head[80:84], dtype="<u4")[0]) if size >= 84 else -1
    if n >= 0 and size == 84 + 50 * n:  # a consistent binary STL
        return RawMesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), None, []) if n == 0 else None
    data = path.read_bytes() if head[:5].lower() == b"solid" else b""
    # an ASCII STL is text (a name may be UTF-8); a binary one whose header starts with
    # "solid" has control bytes in its numbers
    if data and not re.search(rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]", data[80:]):
        if b"facet" not in data:
            return RawMesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), None, [])
        return None
    if n < 0:
        raise errors.MeshFileError(
            f"{path}: not an STL file: {size} bytes, shorter than a binary "
            "STL header, and no 'solid' line"
        )
    raise errors.MeshFileError(
        f"{path}: truncated or corrupt binary STL: the header declares "
        f"{n} triangles ({84 + 50 * n} bytes), the file holds {size}"
    )


def _glb_check(path: Path) -> None:
    """Binary glTF sanity before trimesh reads it: the header's length is the file's and
    every chunk fits in what is left (trimesh allocates a chunk's claimed length before
    reading it); the JSON chunk obeys the URI rule of `_gltf_check`."""
    raw = path.read_bytes()
    size = len(raw)
    if size < 20 or raw[:4] != b"glTF":
        raise errors.MeshFileError(f"{path}: not a GLB file (no 'glTF' header)")
    length = int(np.frombuffer(raw[8:12], dtype="<u4")[0])
    if length != size:
        raise errors.MeshFileError(
            f"{path}: truncated or corrupt GLB: the header declares {length} bytes, the "
            f"file holds {size}"
        )
    pos, first = 12, True
    while pos + 8 <= size:
        n = int(np.frombuffer(raw[pos : pos + 4], dtype="<u4")[0])
        if n > size - pos - 8:
            raise errors.MeshFileError(
                f"{path}: truncated or corrupt GLB: a chunk at byte {pos} declares {n} "
                f"bytes, {size - pos - 8} follow it"
            )
        if first:
            _gltf_refs(path, raw[pos + 8 : pos + 8 + n])
        pos, first = pos + 8 + n, False


def _gltf_refs(path: Path, text: bytes) -> None:
    """A glTF's buffers and images name only data URIs or files beside it: no absolute
    path, no ``..``, no URL scheme (meshfit reads only the files the user names and what
    sits next to them)."""
    from meshfit._jsonio import read_json

    doc = read_json(text, source=str(path), error=errors.MeshFileError)
    if not isinstance(doc, dict):
        raise errors.MeshFileError(f"{path}: the glTF JSON is not an object")
    for kind in ("buffers", "images"):
        items = doc.get(kind, [])
        for i, item in enumerate(items if isinstance(items, list) else []):
            uri = item.get("uri") if isinstance(item, dict) else None
            if not isinstance(uri, str) or uri.startswith("data:"):
                continue
            parts = Path(uri).parts
            if Path(uri).is_absolute() or ".." in parts or re.match(r"^[A-Za-z][\w+.-]*:", uri):
                raise errors.MeshFileError(
                    f"{path}: {kind}[{i}] refers to {uri[:80]!r}; a glTF may refer only "
                    "to data URIs and files in its own folder"
                )


def _to_single(loaded, path: Path, notes: list[str]):
    import trimesh

    if isinstance(loaded, trimesh.Scene):
        geoms = (
            [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
            if hasattr(loaded, "dump")
            else list(loaded.geometry.values())
        )
        geoms = [g for g in geoms if isinstance(g, trimesh.Trimesh)]
        if not geoms:
            raise errors.MeshFileError(f"{path}: the file holds no triangle mesh")
        if len(geoms) > 1:
            notes.append(f"joined {len(geoms)} meshes of the scene into one")
            return trimesh.util.concatenate(geoms)
        return geoms[0]
    if not isinstance(loaded, trimesh.Trimesh):
        raise errors.MeshFileError(
            f"{path}: the file holds a {type(loaded).__name__}, not a triangle mesh"
        )
    return loaded


def read_mesh_arrays(path: str | os.PathLike) -> RawMesh:
    """Read a mesh file into arrays without validating it.

    Parameters
    ----------
    path : str or PathLike
        A ``.ply``, ``.obj``, ``.stl``, ``.off``, ``.glb`` or ``.gltf`` file.

    Returns
    -------
    RawMesh

    Raises
    ------
    MeshFileError
        Missing, unreadable, truncated or unsupported file.
    IndexRangeError
        An OBJ or OFF face refers to a vertex the file does not define (named by face number
        and line).

    Notes
    -----
    OBJ and OFF are read by meshfit itself, keeping the file's vertex order and unreferenced
    vertices, ignoring texture and normal indices; PLY, STL, GLB and glTF through trimesh,
    except binary PLY with faces of different corner counts (read here too).
    """
    import trimesh

    p = Path(path)
    suffix = _readable_suffix(p)
    if suffix == ".obj":
        return _read_obj(p)
    if suffix == ".off":
        return _read_off(p)
    if suffix == ".stl":
        empty = _stl_check(p)
        if empty is not None:
            return empty
    if suffix == ".glb":
        _glb_check(p)
    elif suffix == ".gltf":
        _gltf_refs(p, p.read_bytes())
    notes: list[str] = []
    header = _ply_header(p) if suffix == ".ply" else None
    polys = 0
    if header is not None:
        if header.count("vertex") == 0:  # trimesh reads no geometry at all
            return RawMesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), None, notes)
        if header.fmt == "ascii":
            polys = _ply_ascii_scan(p, header)
    try:
        loaded = trimesh.load(str(p), process=False, force=None)
    except Exception as exc:  # trimesh raises many types on corrupt input
        return _read_what_trimesh_cannot(p, suffix, header, exc)
    if isinstance(loaded, trimesh.PointCloud):  # vertices but no faces
        vertices = np.asarray(loaded.vertices, dtype=np.float64).reshape(-1, 3)
        return RawMesh(vertices, np.zeros((0, 3), np.int64), None, notes)
    tm = _to_single(loaded, p, notes)
    vertices = np.asarray(tm.vertices, dtype=np.float64)
    faces = np.asarray(tm.faces, dtype=np.int64).reshape(-1, 3)
    if header is not None:
        _check_ply_counts(p, header, vertices, faces, polys, notes)
    colors = _vertex_colors(tm, vertices.shape[0])
    if suffix == ".stl" and faces.size:
        vertices, faces = _weld_stl(vertices, faces, notes)
        colors = None
    return RawMesh(vertices, faces, colors, notes)


def _readable_suffix(p: Path) -> str:
    """The lower-case suffix of an existing, non-empty file of a format meshfit reads."""
    if not p.exists():
        raise errors.MeshFileError(f"{p}: no such file")
    if not p.is_file():
        raise errors.MeshFileError(f"{p}: not a file")
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise errors.MeshFileError(
            f"{p}: unsupported format {suffix or '(no suffix)'!r}; "
            f"meshfit reads {', '.join(FORMATS)}"
        )
    if p.stat().st_size == 0:
        raise errors.MeshFileError(f"{p}: the file is empty")
    return suffix


def _read_what_trimesh_cannot(p: Path, suffix: str, header, exc: Exception) -> RawMesh:
    """After trimesh failed on ``p`` with ``exc``: a binary PLY with faces of different
    corner counts read here; otherwise MeshFileError saying why (a binary PLY shorter than
    its header asks for is truncated)."""
    if header is not None and header.fmt.startswith("binary"):
        need = header.length + _ply_binary_min_size(header)
        have = p.stat().st_size
        if have < need:
            raise errors.MeshFileError(
                f"{p}: truncated binary PLY: the header's {header.count('vertex')} vertices "
                f"and {header.count('face')} faces need at least {need} bytes, the file holds "
                f"{have}"
            ) from None
        try:  # faces of different corner counts, which trimesh does not read
            return _read_ply_binary(p, header)
        except errors.MeshFileError:
            raise
        except Exception as exc2:
            raise errors.MeshFileError(
                f"{p}: cannot read binary PLY: the data does not match the header (a "
                f"corrupt file) ({type(exc).__name__}: {exc}; {type(exc2).__name__}: {exc2})"
            ) from None
    raise errors.MeshFileError(
        f"{p}: cannot read {suffix[1:].upper()} file ({type(exc).__name__}: {exc})"
    ) from None


def _check_ply_counts(
    p: Path, header, vertices: NDArray, faces: NDArray, polys: int, notes: list[str]
) -> None:
    """Raise MeshFileError where trimesh read fewer vertices or faces than the PLY header
    declares (a truncated file); note the polygon faces it triangulated."""
    want_v = header.count("vertex")
    if want_v >= 0 and vertices.shape[0] != want_v:
        raise errors.MeshFileError(
            f"{p}: truncated PLY: header declares {want_v} vertices, file holds {vertices.shape[0]}"
        )
    want_f = header.count("face")
    if want_f >= 0 and faces.shape[0] < want_f:
        raise errors.MeshFileError(
            f"{p}: truncated PLY: header declares {want_f} faces, "
            f"file holds {faces.shape[0]} triangles"
        )
    if header.fmt != "ascii" and faces.shape[0] > want_f >= 0:
        polys = want_f  # binary PLY: trimesh reads only faces of one corner count
    if polys:
        notes.append(f"triangulated {polys} polygon faces into {faces.shape[0]} triangles")


def _vertex_colors(tm, n: int) -> NDArray[np.uint8] | None:
    """The per-vertex colours trimesh read, if there is one per vertex."""
    visual = getattr(tm, "visual", None)
    if visual is not None and getattr(visual, "kind", None) == "vertex":
        c = np.asarray(visual.vertex_colors)
        if c.shape[0] == n:
            return c.astype(np.uint8)
    return None


def _weld_stl(vertices: NDArray[np.float64], faces: NDArray[np.int64], notes: list[str]):
    """Join STL corners with exactly equal coordinates: STL stores every triangle's corners
    separately, so exact equality is the format's only record of connectivity."""
    uniq, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # keep first-appearance order
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    notes.append(
        f"joined {vertices.shape[0]} STL triangle corners at {uniq.shape[0]} distinct positions"
    )
    return uniq[order], rank[inverse.reshape(-1)][faces]


def load_mesh(path: str | os.PathLike, *, repair: bool = False) -> Mesh:
    """Load and validate a mesh file.

    Parameters
    ----------
    path : str or PathLike
        A ``.ply``, ``.obj``, ``.stl``, ``.off``, ``.glb`` or ``.gltf`` file.
    repair : bool
        Repair what can be repaired safely instead of raising
        (:func:`meshfit.mesh.validate.repair_arrays`: degenerate, duplicate and back-to-back
        faces and unreferenced vertices dropped, non-manifold edges and vertices split apart,
        orientation made consistent, inside-out closed components turned); index maps are in
        ``mesh.repairs``. Default False: the file as it is, or an error.

    Returns
    -------
    Mesh

    Raises
    ------
    MeshFileError
        The file cannot be read.
    MeshValidationError
        A subclass naming the first problem and the first offending element.

    Examples
    --------
    >>> mesh = load_mesh("scan.ply", repair=True)  # doctest: +SKIP
    """
    raw = read_mesh_arrays(path)
    return Mesh.from_arrays(
        raw.vertices, raw.faces, raw.vertex_colors, name=Path(path).name, repair=repair
    )


def save_mesh(mesh: Mesh, path: str | os.PathLike) -> Path:
    """Write a mesh (with vertex colours) atomically: to a temporary name, then renamed.

    Parameters
    ----------
    mesh : Mesh
    path : str or PathLike
        Target; the suffix picks the format.
    """
    import trimesh

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise errors.InputError(
            f"{p}: unsupported format {suffix!r}; use one of {', '.join(FORMATS)}"
        )
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, vertex_colors=mesh.vertex_colors, process=False)
    # a glTF carries its buffer inside, as a data URI: one file, as with every format
    extra = {"embed_buffers": True} if suffix == ".gltf" else {}
    data = tm.export(file_type=suffix[1:], **extra)
    if isinstance(data, dict):  # (trimesh names the glTF's one file "model.gltf")
        (data,) = data.values()
    return write_bytes(p, data if isinstance(data, bytes) else data.encode())


def load_cli_mesh(path: str | os.PathLike, repair: bool) -> Mesh:
    """:func:`load_mesh` as the command line reads a mesh: on the strict path
    (``--no-repair``) an inside-out closed component is refused too (a repair turns it right
    side out, with a note), so no command fits a surface facing the wrong way.

    Parameters
    ----------
    path : str or PathLike
        A mesh file (:data:`FORMATS`).
    repair : bool
        ``repair`` of :func:`load_mesh`.

    Returns
    -------
    Mesh

    Raises
    ------
    meshfit.errors.MeshValidationError
        As :func:`load_mesh`; without ``repair`` also a closed component whose signed
        volume is negative (named by its first face, with the repair hint).
    meshfit.errors.MeshFileError
        As :func:`load_mesh`.
    """
    from meshfit.mesh.validate import REPAIR_HINT, inside_out_finding

    mesh = load_mesh(path, repair=repair)
    if not repair:
        found = inside_out_finding(mesh.vertices, mesh.faces)
        if found is not None:
            raise errors.MeshValidationError(
                f"{Path(path).name}: {found.message}{REPAIR_HINT}",
                first=found.first,
                count=found.count,
            )
    return mesh
