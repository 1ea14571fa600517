"""A mesh on disk in spatial bricks: the input of the out-of-core preparation.

A scan of tens of millions of triangles need not be held whole in one process to be laid
out: :func:`write_store` reads the file a chunk of faces at a time into memory-mapped
``.npy`` arrays and orders the faces into *bricks*, runs of faces whose centroids lie in
one range of a Morton (Z-order) curve through a grid over the bounding box, so each brick is
a compact piece of the surface. A process then works brick by brick
(:meth:`MeshStore.brick`), holding one brick's faces and vertices at a time, and the pages
of the arrays it is not reading belong to the page cache, not to the process.

A binary PLY whose faces are all triangles (every scanner's and every meshing tool's large
output) is read in place by memory mapping, never whole; any other file is read by
:func:`meshfit.mesh.io.read_mesh_arrays` first (in memory) and then bricked the same way.
The store checks what a chunk can tell (finite coordinates, indices in range) and drops
faces that repeat a vertex; it does not weld vertices or repair the connectivity, which
need the whole mesh.

Layout of a store folder: ``store.json`` (format, version, counts, bounding box, bricks),
``vertices.npy`` (nv, 3) float64 in the input's order, ``faces.npy`` (nf, 3) int64 in brick
order, ``input_face.npy`` (nf,) int64, each stored face's index in the input, and
``brick_start.npy`` (n_bricks + 1,) int64, where each brick's faces start.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from meshfit import errors
from meshfit._jsonio import read_json_file

__all__ = [
    "BRICK_FACES",
    "CHUNK_FACES",
    "STORE_FORMAT",
    "STORE_VERSION",
    "MeshStore",
    "brick_cuts",
    "morton_cells",
    "open_store",
    "write_store",
]

#: the format name and version written to and checked in ``store.json``
STORE_FORMAT = "meshfit-mesh-store"
STORE_VERSION = 1
#: default faces per brick: a brick and its derived arrays take some tens of MiB
BRICK_FACES = 1 << 18
#: faces read, checked and placed per step of :func:`write_store`
CHUNK_FACES = 1 << 20
#: bits per axis of the Morton grid whose cells the bricks are made of (2**18 cells: a
#: brick is a run of whole cells, so a cell should hold far fewer faces than a brick)
MORTON_BITS = 6

#: ``progress(done, total)`` after each chunk of a pass
Progress = Callable[[int, int], None]


def check_new_folder(root: Path) -> None:
    """InputError unless ``root`` is missing or an empty folder (a store never writes over
    anything)."""
    if root.exists() and (not root.is_dir() or any(root.iterdir())):
        raise errors.InputError(f"{root}: exists and is not an empty folder")


@contextmanager
def writing_folder(root: Path) -> Iterator[Path]:
    """A temporary sibling of the new folder ``root`` to write into, renamed to ``root``
    when the block ends, removed when it raises: a failed write leaves nothing."""
    check_new_folder(root)
    root.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{root.name}.", dir=root.parent))
    try:
        yield tmp
        if root.exists():
            root.rmdir()  # (empty: checked above)
        tmp.rename(root)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def read_meta(root: Path, name: str, fmt: str, version: int, what: str) -> tuple[Path, dict]:
    """The versioned JSON ``name`` of a folder of arrays: its path and content, checked to be
    format ``fmt``, version ``version`` (InputError naming the file otherwise)."""
    path = root / name
    if not path.is_file():
        raise errors.InputError(f"{root}: not a {what} (no {name})")
    meta = read_json_file(path, error=errors.InputError)
    if not isinstance(meta, dict) or meta.get("format") != fmt:
        raise errors.InputError(f"{path}: not a {fmt} file")
    if meta.get("version") != version:
        raise errors.InputError(
            f"{path}: {what} version {meta.get('version')!r}; this meshfit reads version {version}"
        )
    return path, meta


def load_array(root: Path, name: str, shape: tuple[int, ...], dtype, meta_name: str) -> NDArray:
    """``root / name`` memory-mapped read-only, checked to have ``shape`` and ``dtype`` as
    ``meta_name`` says (InputError naming the file otherwise)."""
    try:
        a = np.load(root / name, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise errors.InputError(f"{root / name}: cannot read ({exc})") from None
    if a.shape != shape or a.dtype != np.dtype(dtype):
        raise errors.InputError(
            f"{root / name}: {a.dtype}{list(a.shape)} where {meta_name} says "
            f"{np.dtype(dtype)}{list(shape)}"
        )
    return a


@dataclass(frozen=True, eq=False)
class MeshStore:
    """A bricked, memory-mapped mesh (:func:`write_store`, :func:`open_store`).

    Attributes
    ----------
    folder : Path
    vertices : (nv, 3) float64, memory-mapped, read-only
    faces : (nf, 3) int64, memory-mapped, read-only
        In brick order.
    input_face : (nf,) int64, memory-mapped, read-only
        Index in the input file of each stored face.
    brick_start : (n_bricks + 1,) int64
        Brick ``b`` is ``faces[brick_start[b]:brick_start[b + 1]]``.
    bbox : (2, 3) float64
        Lowest and highest corner of the vertices.
    dropped_faces : int
        Input faces that repeat a vertex (not stored).
    """

    folder: Path
    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    input_face: NDArray[np.int64]
    brick_start: NDArray[np.int64]
    bbox: NDArray[np.float64]
    dropped_faces: int

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def n_bricks(self) -> int:
        return int(self.brick_start.size - 1)

    def brick(self, b: int) -> NDArray[np.int64]:
        """The faces of brick ``b`` (global vertex indices), read into memory."""
        if not 0 <= b < self.n_bricks:
            raise errors.InputError(f"brick {b} out of range (the store has {self.n_bricks})")
        return np.array(self.faces[self.brick_start[b] : self.brick_start[b + 1]])


def open_store(folder: str | os.PathLike) -> MeshStore:
    """The store written by :func:`write_store` in ``folder``, its arrays memory-mapped.

    Raises
    ------
    meshfit.errors.InputError
        Not a store, another format or version, or arrays that disagree with ``store.json``.
    """
    root = Path(folder)
    meta_path, meta = read_meta(root, "store.json", STORE_FORMAT, STORE_VERSION, "mesh store")
    try:
        nv, nf, nb = (int(meta[k]) for k in ("n_vertices", "n_faces", "n_bricks"))
        bbox = np.array(meta["bbox"], dtype=np.float64).reshape(2, 3)
        dropped = int(meta["dropped_faces"])
    except (KeyError, TypeError, ValueError) as exc:
        raise errors.InputError(f"{meta_path}: missing or malformed field ({exc})") from None

    def load(name: str, shape: tuple[int, ...], dtype) -> NDArray:
        return load_array(root, name, shape, dtype, "store.json")

    if min(nv, nf, nb) < 0:
        raise errors.InputError(f"{meta_path}: negative counts")
    vertices = load("vertices.npy", (nv, 3), np.float64)
    faces = load("faces.npy", (nf, 3), np.int64)
    input_face = load("input_face.npy", (nf,), np.int64)
    start = np.array(load("brick_start.npy", (nb + 1,), np.int64))
    if start[0] != 0 or start[-1] != nf or (np.diff(start) < 0).any():
        raise errors.InputError(f"{root / 'brick_start.npy'}: not the starts of {nf} faces")
    return MeshStore(root, vertices, faces, input_face, start, bbox, dropped)


# ----------------------------------------------------------------------------- sources


class _Source:
    """Vertices and faces of an input, readable a chunk at a time."""

    n_vertices: int
    n_faces: int

    def vertex_chunk(self, a: int, b: int) -> NDArray[np.float64]:
        raise NotImplementedError

    def face_chunk(self, a: int, b: int) -> NDArray[np.int64]:
        raise NotImplementedError


class _Arrays(_Source):
    def __init__(self, vertices: NDArray, faces: NDArray) -> None:
        self.v, self.f = vertices, faces
        self.n_vertices, self.n_faces = int(vertices.shape[0]), int(faces.shape[0])

    def vertex_chunk(self, a: int, b: int) -> NDArray[np.float64]:
        return np.asarray(self.v[a:b], dtype=np.float64)

    def face_chunk(self, a: int, b: int) -> NDArray[np.int64]:
        return np.asarray(self.f[a:b], dtype=np.int64)


class _PlyInPlace(_Source):
    """A binary PLY read through memory maps of its vertex and face rows (rows of fixed
    size: every face a triangle, checked chunk by chunk)."""

    def __init__(self, path: Path, vrows: NDArray, frows: NDArray, index: str) -> None:
        self.path, self.vrows, self.frows, self.index = path, vrows, frows, index
        self.n_vertices, self.n_faces = int(vrows.shape[0]), int(frows.shape[0])

    def vertex_chunk(self, a: int, b: int) -> NDArray[np.float64]:
        r = self.vrows[a:b]
        return np.stack([r[c].astype(np.float64) for c in "xyz"], axis=1)

    def face_chunk(self, a: int, b: int) -> NDArray[np.int64]:
        r = self.frows[a:b]
        if (r["n"] != 3).any():
            raise _NotTriangles
        return r[self.index].astype(np.int64)


class _NotTriangles(Exception):
    """A face row of a PLY read in place is not a triangle: read the file another way."""


def _ply_in_place(path: Path) -> _PlyInPlace | None:
    """The in-place reader of a binary PLY whose elements have rows of fixed size once its
    faces are taken as triangles (one list property, the vertex indices), else None."""
    from meshfit.mesh.io import _PLY_NUMPY, _ply_header

    header = _ply_header(path)
    if header is None or header.fmt not in ("binary_little_endian", "binary_big_endian"):
        return None
    order = "<" if header.fmt == "binary_little_endian" else ">"
    pos = header.length
    size = path.stat().st_size
    vrows = frows = None
    index = ""
    for name, count, props in header.elements:
        fields: list[tuple] = []
        for pname, typ, ct in props:
            if typ not in _PLY_NUMPY or (ct is not None and ct not in _PLY_NUMPY):
                return None
            if ct is None:
                fields.append((pname, order + _PLY_NUMPY[typ]))
            elif name == "face" and pname in ("vertex_indices", "vertex_index") and not index:
                index = pname
                fields += [("n", order + _PLY_NUMPY[ct]), (pname, order + _PLY_NUMPY[typ], 3)]
            else:
                return None  # a list of unknown length: rows of other sizes
        if len({f[0] for f in fields}) != len(fields):
            return None
        dt = np.dtype(fields)
        end = pos + count * dt.itemsize
        if end > size:
            return None  # (the reader names where a truncated file ends)
        if count and name in ("vertex", "face"):
            rows = np.memmap(path, dtype=dt, mode="r", offset=pos, shape=(count,))
            if name == "vertex":
                vrows = rows
            else:
                frows = rows
        pos = end
    if vrows is None or frows is None or not index:
        return None
    if not all(c in (vrows.dtype.names or ()) for c in "xyz"):
        return None
    if frows.dtype[index].base.kind not in "iu":
        return None
    return _PlyInPlace(path, vrows, frows, index)


def _open_source(source) -> tuple[_Source, str]:
    """A chunked reader of ``source`` (a mesh file, a Mesh or ``(vertices, faces)``) and
    how it is read."""
    from meshfit.mesh.core import Mesh

    if isinstance(source, Mesh):
        return _Arrays(source.vertices, source.faces), "arrays"
    if isinstance(source, tuple) and len(source) == 2:
        v, f = (np.asarray(x) for x in source)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise errors.InputError(
                f"vertices must be (n, 3) and faces (m, 3), got {v.shape} and {f.shape}"
            )
        if f.size and f.dtype.kind not in "iu":
            raise errors.InputError(f"faces must be integers, got {f.dtype}")
        return _Arrays(v, f), "arrays"
    if not isinstance(source, (str, os.PathLike)):
        raise errors.InputError(
            f"source must be a mesh file's path, a Mesh or (vertices, faces), got "
            f"{type(source).__name__}"
        )
    path = Path(source)
    if path.suffix.lower() == ".ply" and path.is_file():
        src = _ply_in_place(path)
        if src is not None:
            return src, "memory-mapped"
    return _read_whole(path), "read whole"


def _read_whole(path: Path) -> _Arrays:
    from meshfit.mesh.io import read_mesh_arrays

    raw = read_mesh_arrays(path)
    return _Arrays(raw.vertices, raw.faces)


# ----------------------------------------------------------------------------- writing


def _chunks(n: int, step: int) -> Iterator[tuple[int, int]]:
    for a in range(0, n, step):
        yield a, min(a + step, n)


def morton_cells(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], lo, hi, bits: int = MORTON_BITS
) -> NDArray[np.int64]:
    """The Morton (Z-order) code of the grid cell holding each face's centroid: the order
    in which :func:`write_store` and the in-memory proxy
    (:func:`meshfit.shrinkwrap.simplify_mesh`) cut a scan into bricks.

    Parameters
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64
        Indices into ``vertices``.
    lo, hi : (3,) float64
        The box the grid spans; an axis of zero extent is one cell across (a flat scan).
    bits : int
        Cells per axis ``2**bits`` (default `MORTON_BITS`).

    Returns
    -------
    (nf,) int64
        Codes in ``[0, 2**(3 bits))``, the axes' bits interleaved, x lowest.
    """
    from meshfit._kernels.decimate import face_cells

    lo = np.asarray(lo, dtype=np.float64)
    extent = np.asarray(hi, dtype=np.float64) - lo
    scale = np.where(extent > 0, (1 << bits) / np.where(extent > 0, extent, 1.0), 0.0)
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    return face_cells(V, F, lo, scale, int(bits))


def brick_cuts(
    count: NDArray[np.int64], brick_faces: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Bricks as runs of whole Morton cells: a brick ends at the cell where the running
    count of faces passes a multiple of ``brick_faces``, and no brick is empty, so a brick
    is a compact region of the scan whatever its density.

    Parameters
    ----------
    count : (n_cells,) int64
        Faces per Morton cell (:func:`morton_cells`).
    brick_faces : int
        About this many faces per brick (at least 1).

    Returns
    -------
    first_cell : (nb,) int64
        Each brick's first cell, increasing.
    start : (nb + 1,) int64
        Each brick's first face in cell order, the total last.
    """
    n = int(count.sum())
    run = np.cumsum(count)
    ends = np.searchsorted(run, np.arange(brick_faces, n, brick_faces), "left")
    cut_cells = np.unique(np.concatenate([[0], ends + 1]))
    cut_cells = cut_cells[cut_cells < count.size]
    per_brick = np.add.reduceat(count, cut_cells) if n else np.zeros(0, np.int64)
    keep = per_brick > 0
    cut_cells, per_brick = cut_cells[keep], per_brick[keep]
    return cut_cells, np.concatenate([[0], np.cumsum(per_brick)]).astype(np.int64)


def write_store(
    source,
    folder: str | os.PathLike,
    *,
    brick_faces: int = BRICK_FACES,
    chunk_faces: int = CHUNK_FACES,
    progress: Progress | None = None,
) -> MeshStore:
    """Write ``source`` as a bricked, memory-mapped store in the new folder ``folder``.

    Four passes over the input, a chunk at a time: the vertices (checked finite, bounding
    box), the faces (indices checked, faces repeating a vertex dropped, each face's Morton
    cell counted), the brick cuts (runs of cells of about ``brick_faces`` faces), and the
    faces again, each written at its brick's next free row. Memory: one chunk and the cell
    counts, besides the pages of the files being read and written.

    Parameters
    ----------
    source : path, Mesh or (vertices, faces)
        A mesh file (a binary PLY of triangles is memory-mapped, any other format read
        whole by :func:`meshfit.mesh.io.read_mesh_arrays`) or arrays.
    folder : path
        Must not exist, or be an empty folder; written through a temporary sibling folder
        renamed at the end, so a failed write leaves nothing.
    brick_faces, chunk_faces : int
        Faces per brick (about: a brick is whole Morton cells) and per read.
    progress : callable(done, total), optional
        Called after each chunk of the face passes.

    Returns
    -------
    MeshStore

    Raises
    ------
    meshfit.errors.MeshFileError
        The file is unreadable, or a vertex coordinate is not finite or a face's index out
        of range (named by vertex or face number).
    meshfit.errors.InputError
        ``folder`` is a non-empty folder or a file, or the input is ``folder`` itself.
    """
    if int(brick_faces) < 1 or int(chunk_faces) < 1:
        raise errors.InputError(
            f"brick_faces and chunk_faces must be >= 1, got {brick_faces}, {chunk_faces}"
        )
    root = Path(folder)
    check_new_folder(root)
    if isinstance(source, (str, os.PathLike)) and Path(source).resolve() == root.resolve():
        raise errors.InputError(f"{root}: the store cannot replace its own input")
    src, how = _open_source(source)
    if isinstance(src, _PlyInPlace):
        try:
            return _write(src, root, how, int(brick_faces), int(chunk_faces), progress)
        except _NotTriangles:
            src, how = _read_whole(src.path), "read whole"
    return _write(src, root, how, int(brick_faces), int(chunk_faces), progress)


def _write(src: _Source, root: Path, how: str, brick_faces: int, step: int, progress) -> MeshStore:
    nv, nf = src.n_vertices, src.n_faces
    with writing_folder(root) as tmp:
        total = 3 * nf + nv
        done = 0
        # 1. vertices: copied as float64, checked finite, bounding box
        V = np.lib.format.open_memmap(tmp / "vertices.npy", "w+", np.float64, (nv, 3))
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for a, b in _chunks(nv, step):
            x = src.vertex_chunk(a, b)
            bad = ~np.isfinite(x).all(axis=1)
            if bad.any():
                raise errors.MeshFileError(
                    f"vertex {a + int(np.argmax(bad))} has a coordinate that is not finite"
                )
            V[a:b] = x
            if b > a:
                lo = np.minimum(lo, x.min(axis=0))
                hi = np.maximum(hi, x.max(axis=0))
            done += b - a
            if progress is not None:
                progress(done, total)
        V.flush()
        if nv == 0:
            lo = hi = np.zeros(3)
        bits = MORTON_BITS

        def cells(f: NDArray[np.int64]) -> NDArray[np.int64]:
            return morton_cells(V, f, lo, hi, bits)

        def kept(a: int, b: int) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
            f = src.face_chunk(a, b)
            out = (f < 0) | (f >= nv)
            if out.any():
                r = int(np.argmax(out.any(axis=1)))
                raise errors.MeshFileError(
                    f"face {a + r} refers to vertex {int(f[r][out[r]][0])}; the mesh has {nv}"
                )
            ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
            return f, ok

        # 2. faces: checked, counted per Morton cell
        count = np.zeros(1 << (3 * bits), dtype=np.int64)
        n_kept = 0
        for a, b in _chunks(nf, step):
            f, ok = kept(a, b)
            count += np.bincount(cells(f[ok]), minlength=count.size)
            n_kept += int(ok.sum())
            done += b - a
            if progress is not None:
                progress(done, total)
        # 3. bricks: runs of whole cells
        cut_cells, start = brick_cuts(count, brick_faces)
        # 4. faces again, each at its brick's next free row (chunk order within a brick)
        F = np.lib.format.open_memmap(tmp / "faces.npy", "w+", np.int64, (n_kept, 3))
        face_in = np.lib.format.open_memmap(tmp / "input_face.npy", "w+", np.int64, (n_kept,))
        cursor = start[:-1].copy()
        for a, b in _chunks(nf, step):
            f, ok = kept(a, b)
            idx = np.flatnonzero(ok)
            f = f[ok]
            brick = np.searchsorted(cut_cells, cells(f), "right") - 1
            order = np.argsort(brick, kind="stable")
            brick = brick[order]
            first = np.searchsorted(brick, np.arange(cut_cells.size), "left")
            n_in = np.bincount(brick, minlength=cut_cells.size)
            rows = cursor[brick] + (np.arange(brick.size) - first[brick])
            F[rows] = f[order]
            face_in[rows] = a + idx[order]
            cursor += n_in
            done += 2 * (b - a)
            if progress is not None:
                progress(done, total)
        F.flush()
        face_in.flush()
        np.save(tmp / "brick_start.npy", start)
        meta = {
            "format": STORE_FORMAT,
            "version": STORE_VERSION,
            "n_vertices": nv,
            "n_faces": n_kept,
            "n_bricks": int(start.size - 1),
            "bbox": [lo.tolist(), hi.tolist()],
            "morton_bits": bits,
            "dropped_faces": nf - n_kept,
            "read": how,
        }
        (tmp / "store.json").write_text(json.dumps(meta, indent=1))
    return open_store(root)
