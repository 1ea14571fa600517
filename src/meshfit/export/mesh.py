"""Tessellated exports of a patch network: OBJ, glTF binary and PLY of one welded mesh.

Every writer tessellates with :func:`meshfit.export.patch_mesh`: neighbouring patches share
their boundary vertices, so each file is watertight wherever the patch network is closed, at
every resolution, and a vertex shared by several patches has the same coordinates in every
file written from the same patches.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterator, Mapping, Sequence
from itertools import pairwise
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from meshfit._kernels.textio import face_lines
from meshfit.bspline import BSplineSurface
from meshfit.displacement import DisplacementMap
from meshfit.errors import InputError
from meshfit.export._common import (
    as_displacements,
    as_names,
    as_surfaces,
    atomic_write,
)
from meshfit.export.weld import PatchMesh, _weld, spline_network
from meshfit.stitch import Network

__all__ = ["export_gltf", "export_obj", "export_objs", "export_ply"]

Shapes = tuple[int, int] | Sequence[tuple[int, int]]
Displacements = DisplacementMap | Sequence[DisplacementMap | None] | None


def _patch_meshes(
    outputs: Sequence[Displacements], surfaces, shape, network, scale
) -> Iterator[PatchMesh]:
    """One PatchMesh per entry of ``outputs`` (displacements of the patches, or None), made
    as the caller asks for it (one dense tessellation in memory at a time): the same network
    for all, and texture coordinates addressing each patch's first map among the outputs,
    so spline-only and displaced meshes of one fit carry the same ones. The arguments are
    checked before the first is made."""
    n = len(surfaces)
    maps = [as_displacements(d, n) for d in outputs]
    texels: list[tuple[int, int] | None] = [None] * n
    for ms in reversed(maps):
        texels = [t if m is None else m.shape for t, m in zip(texels, ms, strict=True)]
    if network is None:
        network = spline_network(surfaces)
    return (_weld(surfaces, ms, network, shape, scale, texels) for ms in maps)


def _patch_ranges(pm: PatchMesh) -> np.ndarray:
    """Face ranges of the patches: patch p's faces are ``[r[p], r[p + 1])``."""
    return np.searchsorted(pm.face_patch, np.arange(pm.n_patches + 1))


#: rows formatted and written at a time: an OBJ of millions of vertices is never held as
#: text (its lines as Python strings took several times the file's size)
ROWS = 1 << 16


def _write_rows(fh, fmt: str, cols: NDArray) -> None:
    """``fmt.format(*row)`` for each row of ``cols (k, m)``, one line each, `ROWS` at a
    time (Python floats and ints format faster than numpy scalars: the same text)."""
    for a in range(0, len(cols), ROWS):
        chunk = cols[a : a + ROWS].T.tolist()
        fh.write("".join(map((fmt + "\n").format, *chunk)))


def _write_faces(fh, cols: NDArray[np.int64]) -> None:
    """The face lines ``f a/d/a b/e/b c/f/c`` of ``cols (k, 6)`` (1-based vertex and
    texture indices), `ROWS` at a time, formatted by a kernel (the same bytes as
    `_write_rows` with that format)."""
    fh.flush()
    for a in range(0, len(cols), ROWS):
        fh.buffer.write(face_lines(np.ascontiguousarray(cols[a : a + ROWS])).tobytes())
    fh.buffer.flush()


def _write_uv(fh, UV: NDArray) -> None:
    """``vt`` lines of ``UV (k, 2)``: each distinct coordinate formatted once (a grid has
    few), the same text as formatting every pair."""
    u, iu = np.unique(UV[:, 0], return_inverse=True)
    v, iv = np.unique(UV[:, 1], return_inverse=True)
    su = np.array([f"vt {x:.17g} " for x in u.tolist()], dtype=object)
    sv = np.array([f"{x:.17g}\n" for x in v.tolist()], dtype=object)
    iu, iv = iu.ravel(), iv.ravel()
    for a in range(0, len(iu), ROWS):
        fh.write("".join(su[iu[a : a + ROWS]] + sv[iv[a : a + ROWS]]))


def _write_obj(fh, pm: PatchMesh, names: list[str], mtl: str | None, shared) -> dict:
    """The text of one OBJ file into ``fh``; returns the byte ranges of its ``vt`` lines and
    of each patch's face lines. ``shared`` (the ranges and path of a file already written
    with the same texture coordinates and faces) is copied from there, not formatted
    again."""
    fh.write("# meshfit: welded tessellation of B-spline patches; vt = UDIM coordinates\n")
    if mtl is not None:
        fh.write(f"mtllib {mtl}\n")
    _write_rows(fh, "v {:.17g} {:.17g} {:.17g}", pm.vertices)
    src = None if shared is None else open(shared["path"], "rb")
    try:
        ranges: dict = {"faces": []}
        fh.flush()
        a = fh.buffer.tell()
        if src:
            _copy(src, shared["vt"], fh)
        else:
            _write_uv(fh, pm.uv)
        fh.flush()
        ranges["vt"] = (a, fh.buffer.tell())
        _write_rows(fh, "vn {:.9g} {:.9g} {:.9g}", pm.normals)
        cols = np.hstack([pm.faces + 1, pm.face_uv + 1])
        r = _patch_ranges(pm).tolist()
        for p, (name, (f0, f1)) in enumerate(zip(names, pairwise(r), strict=True)):
            fh.write(f"g {name}\n")
            if mtl is not None:
                fh.write(f"usemtl {name}\n")
            fh.flush()
            a = fh.buffer.tell()
            if src:
                _copy(src, shared["faces"][p], fh)
            else:
                _write_faces(fh, cols[f0:f1])
            fh.flush()
            ranges["faces"].append((a, fh.buffer.tell()))
    finally:
        if src:
            src.close()
    return ranges


def _copy(src, span: tuple[int, int], fh) -> None:
    """Bytes ``[a, b)`` of the open binary file ``src`` into the text file ``fh``."""
    fh.flush()
    a, b = span
    src.seek(a)
    while a < b:
        block = src.read(min(b - a, 1 << 22))
        if not block:
            raise OSError(f"{src.name} is shorter than it was written")
        fh.buffer.write(block)
        a += len(block)
    fh.buffer.flush()


def _as_materials(materials: Sequence[str] | None, n: int) -> list[str] | None:
    if materials is None:
        return None
    out = [os.fspath(m) for m in materials]
    if len(out) != n:
        raise InputError(f"{len(out)} material images for {n} surfaces")
    for m in out:
        if not m.strip() or any(c in m for c in "\r\n"):
            raise InputError(f"material image {m!r} must be a non-empty single-line path")
    return out


def export_obj(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: Displacements = None,
    names: Sequence[str] | None = None,
    shape: Shapes | None = None,
    network: Network | None = None,
    scale: float = 1.0,
    materials: Sequence[str] | None = None,
) -> Path:
    """Write the patches as one welded triangle mesh to a Wavefront OBJ file.

    Parameters
    ----------
    path : str or path
        Output ``.obj`` (written atomically).
    surfaces : BSplineSurface or sequence of them
    displacements : DisplacementMap or sequence of (DisplacementMap or None), optional
        The displaced surface ``S + d`` for patches with a vector, scalar or magnitude map,
        the spline alone otherwise (so ``None`` writes the spline-only surfaces).
    names : sequence of str, optional
        One group (``g``) per patch; default ``patch_0, ...``.
    shape : (int, int) or sequence of them, optional
        Vertex grid of every patch, or one per patch; default the map's resolution, else 8
        per control point (made equal along shared boundaries, see
        :func:`meshfit.export.patch_mesh`).
    network : Network, optional
        The patches' shared boundaries; default found from where the splines meet
        (:func:`meshfit.export.spline_network`).
    scale : float
        Multiplies the number of grid intervals of every patch (default 1).
    materials : sequence of str, optional
        One displacement image path per patch (relative to the OBJ, or a ``<UDIM>`` path
        shared by all): a ``.mtl`` of the same stem is written beside the OBJ with one
        material per patch, named after it, whose ``disp`` is that image, and each group
        uses its material. Default none: no ``.mtl``, no ``usemtl``. Only with
        ``displacements=None``: a displaced mesh holds the detail already, and a renderer
        would displace it twice (to have the texture coordinates address the maps' texels,
        write the spline file together with the displaced one, :func:`export_objs`).

    Returns
    -------
    Path

    Notes
    -----
    ``v`` holds the welded vertices with 17 significant digits (exact float64), ``vt`` the
    UDIM texture coordinates of :func:`meshfit.export.patch_mesh` (17 digits), ``vn`` the
    unit vertex normals (9 digits, float32 exact); faces are ``f v/vt/vn`` and turn like
    ``S_u x S_v``. A vertex on a shared boundary is one ``v`` with one ``vt`` per patch.
    """
    if materials is not None and displacements is not None:
        raise InputError(
            "materials go with a spline-only OBJ (displacements=None): a displaced mesh "
            "holds the detail already"
        )
    return export_objs(
        {path: displacements},
        surfaces,
        names=names,
        shape=shape,
        network=network,
        scale=scale,
        materials=materials,
    )[0]


def export_objs(
    outputs: Mapping[str | os.PathLike, Displacements],
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    names: Sequence[str] | None = None,
    shape: Shapes | None = None,
    network: Network | None = None,
    scale: float = 1.0,
    materials: Sequence[str] | None = None,
) -> list[Path]:
    """Several OBJ files of the same patches, e.g. the displaced and the spline-only surface.

    Parameters
    ----------
    outputs : mapping of path to displacements
        ``{path: displacements}``: each file as :func:`export_obj` writes it with those
        displacements (None: the splines alone).
    surfaces : BSplineSurface or sequence of them
    names, shape, network, scale, materials
        As for :func:`export_obj`, for every file, except that ``materials`` go only to the
        spline-only files (displacements None): the maps complete those, while a displaced
        file holds the detail already and a renderer would displace it twice.

    Returns
    -------
    list of Path
        The files, in the order of ``outputs`` (each written atomically).

    Raises
    ------
    meshfit.errors.InputError
        Bad names, displacements, shapes or materials (as :func:`export_obj`).

    Notes
    -----
    All files use one network, and their texture coordinates address each patch's first
    map among the outputs: a spline-only file carries the displaced file's coordinates, so a
    renderer can displace it with the same images, and with the same vertex grids the files
    share the text of their texture coordinates and faces, formatted once.
    """
    surfaces = as_surfaces(surfaces)
    names_ = as_names(names, len(surfaces))
    mats = _as_materials(materials, len(surfaces))
    meshes = _patch_meshes(list(outputs.values()), surfaces, shape, network, scale)
    written: list[tuple[bytes, dict]] = []  # (`_shared_key`, ranges and path) of each file
    out = []
    for (path, displacements), pm in zip(outputs.items(), meshes, strict=True):
        key = _shared_key(pm)
        shared = next((w for k, w in written if k == key), None)
        path = Path(path)
        # the maps complete a spline-only file; a displaced file holds the detail already
        mtl = None
        if mats is not None and displacements is None:
            mtl = path.with_suffix(".mtl").name
            _write_mtl(path.with_suffix(".mtl"), names_, mats)
        ranges: dict = {}

        def write(tmp: str, pm=pm, mtl=mtl, shared=shared, ranges=ranges) -> None:
            with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
                ranges.update(_write_obj(fh, pm, names_, mtl, shared))

        out.append(atomic_write(path, write))
        written.append((key, {**ranges, "path": path}))
        del pm, write  # (before the next file's tessellation is made)
    return out


def _shared_key(pm: PatchMesh) -> bytes:
    """A digest of what two OBJ files with equal ``vt`` and face lines share: the faces,
    the texture indices and coordinates (with their shapes and types)."""
    h = hashlib.sha256()
    for a in (pm.faces, pm.face_uv, pm.uv):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(memoryview(a).cast("B"))
    return h.digest()


def _write_mtl(path: Path, names: list[str], images: list[str]) -> Path:
    lines = ["# meshfit: one material per patch; disp = its displacement image"]
    for name, image in zip(names, images, strict=True):
        lines += [f"newmtl {name}", "Kd 0.8 0.8 0.8", f"disp {image}", ""]

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write("\n".join(lines))

    return atomic_write(path, write)


def export_gltf(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: Displacements = None,
    names: Sequence[str] | None = None,
    shape: Shapes | None = None,
    network: Network | None = None,
    scale: float = 1.0,
) -> Path:
    """Write a glTF binary (``.glb``): one mesh per patch, cut from one welded mesh.

    Parameters
    ----------
    path : str or path
        Output ``.glb`` (written atomically).
    surfaces, displacements, names, shape, network, scale
        As for :func:`export_obj`; ``names`` name the nodes and meshes.

    Returns
    -------
    Path

    Notes
    -----
    Each patch's mesh holds ``POSITION``, ``NORMAL`` and ``TEXCOORD_0`` per vertex. glTF
    attributes are per vertex, so a vertex on a shared boundary is repeated in each patch's
    mesh (with that patch's texture coordinate) at the same float32 position and normal:
    merging coincident vertices gives the watertight mesh. glTF stores float32 (positions
    carry about 6e-8 relative rounding). Its texture origin is the image's top-left corner,
    so ``TEXCOORD_0`` holds ``(x, 1 - y)`` of the UDIM coordinates ``(x, y)`` of
    :func:`meshfit.export.patch_mesh`; readers that flip back to a bottom-left origin
    (trimesh, Blender) recover ``(x, y)``. The material is plain grey, without images, so
    no image library is needed.
    """
    import trimesh
    from trimesh.visual.material import PBRMaterial
    from trimesh.visual.texture import TextureVisuals

    surfaces = as_surfaces(surfaces)
    names_ = as_names(names, len(surfaces))
    pm = next(_patch_meshes([displacements], surfaces, shape, network, scale))
    uv_vertex = pm.uv_vertex
    material = PBRMaterial(name="meshfit", baseColorFactor=[204, 204, 204, 255])
    r = _patch_ranges(pm)
    scene = trimesh.Scene()
    for p, name in enumerate(names_):
        used, local = np.unique(pm.face_uv[r[p] : r[p + 1]], return_inverse=True)
        vertex = uv_vertex[used]
        mesh = trimesh.Trimesh(
            vertices=pm.vertices[vertex],
            faces=local.reshape(-1, 3),
            vertex_normals=pm.normals[vertex],
            process=False,
            visual=TextureVisuals(uv=pm.uv[used], material=material),
        )
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    data = scene.export(file_type="glb", include_normals=True)

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    return atomic_write(path, write)


def export_ply(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: Displacements = None,
    shape: Shapes | None = None,
    network: Network | None = None,
    scale: float = 1.0,
    patch_ids: bool = True,
) -> Path:
    """Write the welded mesh to a binary little-endian PLY file.

    Parameters
    ----------
    path : str or path
        Output ``.ply`` (written atomically).
    surfaces, displacements, shape, network, scale
        As for :func:`export_obj`.
    patch_ids : bool
        Give each face an ``int patch`` property, its patch index (default True).

    Returns
    -------
    Path

    Notes
    -----
    ``element vertex``: ``double x, y, z`` (exact float64) and ``float nx, ny, nz`` (unit
    normals); ``element face``: ``list uchar int vertex_indices`` turning like
    ``S_u x S_v``, then ``int patch``. PLY has no per-corner texture coordinates, so the
    UDIM coordinates are left to the OBJ and glTF files.
    """
    surfaces = as_surfaces(surfaces)
    pm = next(_patch_meshes([displacements], surfaces, shape, network, scale))
    n, m = len(pm.vertices), len(pm.faces)
    if n > np.iinfo(np.int32).max:
        raise InputError(f"{n} vertices: PLY's int vertex indices hold at most 2**31 - 1")
    vdt = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("n", "<f4", (3,))])
    fields = [("k", "u1"), ("f", "<i4", (3,))] + ([("p", "<i4")] if patch_ids else [])
    fdt = np.dtype(fields)
    verts = np.empty(n, dtype=vdt)
    verts["x"], verts["y"], verts["z"] = pm.vertices.T
    verts["n"] = pm.normals
    faces = np.empty(m, dtype=fdt)
    faces["k"] = 3
    faces["f"] = pm.faces
    if patch_ids:
        faces["p"] = pm.face_patch
    header = [
        "ply",
        "format binary_little_endian 1.0",
        "comment meshfit: welded tessellation of B-spline patches",
        f"element vertex {n}",
        *(f"property double {c}" for c in "xyz"),
        *(f"property float {c}" for c in ("nx", "ny", "nz")),
        f"element face {m}",
        "property list uchar int vertex_indices",
        *(["property int patch"] if patch_ids else []),
        "end_header",
    ]

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii"))
            fh.write(verts.tobytes())
            fh.write(faces.tobytes())

    return atomic_write(path, write)
