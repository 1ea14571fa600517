"""Reading and writing mesh files (PLY, OBJ, STL, OFF, GLB/glTF) through trimesh.

Files are read with ``process=False`` so vertices are never merged or reordered; polygons
are triangulated (fans), vertex colours are kept. Truncated and unreadable files raise
:class:`meshfit.errors.MeshFileError`.
"""

from __future__ import annotations

import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from meshfit import errors
from meshfit.mesh.core import Mesh

__all__ = ["FORMATS", "RawMesh", "load_mesh", "read_mesh_arrays", "save_mesh"]

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


def _ply_header(path: Path) -> tuple[dict[str, int], int, str] | None:
    """Element counts, header byte length and format of a PLY file (None if not PLY)."""
    with open(path, "rb") as fh:
        head = fh.read(65536)
    if not head.startswith(b"ply"):
        return None
    end = head.find(b"end_header")
    if end < 0:
        raise errors.MeshFileError(f"{path}: PLY header has no end_header line")
    nl = head.find(b"\n", end)
    text = head[:end].decode("ascii", errors="replace")
    counts = {m.group(1): int(m.group(2)) for m in re.finditer(r"^element\s+(\w+)\s+(\d+)", text, re.M)}
    fmt = re.search(r"^format\s+(\w+)", text, re.M)
    return counts, nl + 1, fmt.group(1) if fmt else "?"


def _ply_polygon_sizes(path: Path, header_len: int, fmt: str, n_vertices: int) -> int:
    """How many faces of an ASCII PLY have more than three corners (0 for binary files)."""
    if fmt != "ascii":
        return 0
    with open(path, encoding="ascii", errors="replace") as fh:
        fh.seek(header_len)
        lines = fh.read().split("\n")
    faces = lines[n_vertices:]
    return sum(1 for ln in faces if ln.strip() and int(ln.split()[0]) > 3)


def _obj_polygons(path: Path) -> int:
    n = 0
    with open(path, encoding="utf-8", errors="replace") as fh:
        for ln in fh:
            if ln.startswith("f ") and len(ln.split()) > 4:
                n += 1
    return n


def _to_single(loaded, path: Path, notes: list[str]):
    import trimesh

    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)] \
            if hasattr(loaded, "dump") else list(loaded.geometry.values())
        geoms = [g for g in geoms if isinstance(g, trimesh.Trimesh)]
        if not geoms:
            raise errors.MeshFileError(f"{path}: the file holds no triangle mesh")
        if len(geoms) > 1:
            notes.append(f"joined {len(geoms)} meshes of the scene into one")
            return trimesh.util.concatenate(geoms)
        return geoms[0]
    if not isinstance(loaded, trimesh.Trimesh):
        raise errors.MeshFileError(f"{path}: the file holds a {type(loaded).__name__}, "
                                   "not a triangle mesh")
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
    """
    import trimesh

    p = Path(path)
    if not p.exists():
        raise errors.MeshFileError(f"{p}: no such file")
    if not p.is_file():
        raise errors.MeshFileError(f"{p}: not a file")
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise errors.MeshFileError(f"{p}: unsupported format {suffix or '(no suffix)'!r}; "
                                   f"meshfit reads {', '.join(FORMATS)}")
    if p.stat().st_size == 0:
        raise errors.MeshFileError(f"{p}: the file is empty")
    notes: list[str] = []
    header = _ply_header(p) if suffix == ".ply" else None
    try:
        loaded = trimesh.load(str(p), process=False, force=None)
    except Exception as exc:  # trimesh raises many types on corrupt input
        raise errors.MeshFileError(f"{p}: cannot read {suffix[1:].upper()} file "
                                   f"({type(exc).__name__}: {exc})") from None
    tm = _to_single(loaded, p, notes)
    vertices = np.asarray(tm.vertices, dtype=np.float64)
    faces = np.asarray(tm.faces, dtype=np.int64).reshape(-1, 3)
    if header is not None:
        counts, header_len, fmt = header
        want_v = counts.get("vertex", -1)
        if want_v >= 0 and vertices.shape[0] != want_v:
            raise errors.MeshFileError(f"{p}: truncated PLY: header declares {want_v} vertices, "
                                       f"file holds {vertices.shape[0]}")
        polys = _ply_polygon_sizes(p, header_len, fmt, want_v)
        want_f = counts.get("face", -1)
        if want_f >= 0 and faces.shape[0] < want_f:
            raise errors.MeshFileError(f"{p}: truncated PLY: header declares {want_f} faces, "
                                       f"file holds {faces.shape[0]} triangles")
        if polys:
            notes.append(f"triangulated {polys} polygon faces into {faces.shape[0]} triangles")
    elif suffix == ".obj":
        polys = _obj_polygons(p)
        if polys:
            notes.append(f"triangulated {polys} polygon faces into {faces.shape[0]} triangles")
    colors = None
    visual = getattr(tm, "visual", None)
    if visual is not None and getattr(visual, "kind", None) == "vertex":
        c = np.asarray(visual.vertex_colors)
        if c.shape[0] == vertices.shape[0]:
            colors = c.astype(np.uint8)
    return RawMesh(vertices, faces, colors, notes)


def load_mesh(path: str | os.PathLike, *, repair: bool = False) -> Mesh:
    """Load and validate a mesh file.

    Parameters
    ----------
    path : str or PathLike
        A ``.ply``, ``.obj``, ``.stl``, ``.off``, ``.glb`` or ``.gltf`` file.
    repair : bool
        Drop degenerate, duplicate and back-to-back faces and unreferenced vertices, and make
        the orientation consistent, instead of raising; index maps are in ``mesh.repairs``.

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
    >>> mesh = load_mesh("bunny.ply", repair=True)  # doctest: +SKIP
    """
    raw = read_mesh_arrays(path)
    return Mesh.from_arrays(raw.vertices, raw.faces, raw.vertex_colors, name=Path(path).name,
                            repair=repair)


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
        raise errors.InputError(f"{p}: unsupported format {suffix!r}; use one of {', '.join(FORMATS)}")
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, vertex_colors=mesh.vertex_colors, process=False)
    data = tm.export(file_type=suffix[1:])
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent or ".")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data if isinstance(data, bytes) else data.encode())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p
