"""The layout file: versioned JSON (``{"meshfit_layout": 1, ...}``), saved atomically.

Format, version 1::

    {"meshfit_layout": 1,
     "mesh": {"n_vertices": nv, "n_faces": nf, "sha256": "<mesh_fingerprint>"},
     "corners": {"face": [f, ...], "bary": [[b0, b1, b2], ...]},
     "curves": [{"corners": [a, b], "face": [...], "bary": [[...], ...]}, ...],
     "patches": [{"sides": [[curve, reversed], x 4],
                  "features": [{"face": [...], "bary": [[...], ...]}, ...]}, ...]}

Every point is a face point of the mesh (face index, barycentric coordinates summing to 1).
Curve ``i`` runs from corner ``a`` to corner ``b``; a patch's sides run counter-clockwise seen
from outside (the :class:`meshfit.layout.Patch` convention), ``reversed`` meaning the side runs
from the curve's ``b`` to its ``a``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from meshfit._atomic import write_text
from meshfit._jsonio import read_json
from meshfit.errors import InputError, LayoutError
from meshfit.layout.layout import Layout, check_layout, mesh_fingerprint
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["FORMAT_VERSION", "layout_from_json", "layout_to_json", "load_layout", "save_layout"]

#: the version this module writes and reads
FORMAT_VERSION = 1


def _points_json(pts: SurfacePoints) -> dict[str, Any]:
    return {"face": pts.face.tolist(), "bary": pts.bary.tolist()}


def layout_to_json(layout: Layout, *, mesh_counts: tuple[int, int] | None = None) -> str:
    """The layout as version-1 JSON text (one curve or patch per line).

    Parameters
    ----------
    layout : Layout
    mesh_counts : (int, int), optional
        Vertex and face count of the mesh, stored for messages (default: omitted).

    Returns
    -------
    str
        JSON text; floats are written with Python's shortest round-trip repr, so loading
        gives back bit-identical barycentrics.
    """
    dump = json.dumps
    mesh: dict[str, Any] = {"sha256": layout.fingerprint}
    if mesh_counts is not None:
        mesh = {"n_vertices": int(mesh_counts[0]), "n_faces": int(mesh_counts[1]), **mesh}
    lines = ["{", f'"meshfit_layout": {FORMAT_VERSION},', f'"mesh": {dump(mesh)},']
    lines.append(f'"corners": {dump(_points_json(layout.corners), separators=(",", ":"))},')
    lines.append('"curves": [')
    for i, c in enumerate(layout.curves):
        d = {"corners": layout.curve_ends[i].tolist(), **_points_json(c.points)}
        if layout.creases[i]:
            d["crease"] = True
        sep = "," if i + 1 < len(layout.curves) else ""
        lines.append(dump(d, separators=(",", ":")) + sep)
    lines.append("],")
    lines.append('"patches": [')
    for p in range(layout.n_patches):
        d = {
            "sides": [list(side) for side in layout.patch_sides(p)],
            "features": [_points_json(f.points) for f in layout.features[p]],
        }
        sep = "," if p + 1 < layout.n_patches else ""
        lines.append(dump(d, separators=(",", ":")) + sep)
    lines.append("]")
    lines.append("}")
    return "\n".join(lines) + "\n"


def save_layout(layout: Layout, path: str | os.PathLike, *, mesh: Mesh | None = None) -> Path:
    """Write a layout file atomically (temporary name in the same folder, then rename).

    Parameters
    ----------
    layout : Layout
    path : str or PathLike
        Destination ``.json`` file; its folder must exist.
    mesh : Mesh, optional
        When given, its vertex and face counts are stored too (its fingerprint must match).

    Returns
    -------
    Path
        The written file.
    """
    path = Path(path)
    counts = None
    if mesh is not None:
        if mesh_fingerprint(mesh) != layout.fingerprint:
            raise LayoutError("save_layout: the layout was made for another mesh")
        counts = (mesh.n_vertices, mesh.n_faces)
    text = layout_to_json(layout, mesh_counts=counts)
    write_text(path, text)
    return path


# ------------------------------------------------------------------------------- reading
def _get(d: Any, key: str, where: str, kind: type | tuple[type, ...]) -> Any:
    if not isinstance(d, dict):
        raise LayoutError(f"{where}: expected an object")
    if key not in d:
        raise LayoutError(f"missing key '{where}.{key}'" if where else f"missing key '{key}'")
    v = d[key]
    if not isinstance(v, kind):
        name = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        full = f"{where}.{key}" if where else key
        raise LayoutError(f"key '{full}': expected {name}, got {type(v).__name__}")
    return v


def _points(d: Any, where: str) -> SurfacePoints:
    face = _get(d, "face", where, list)
    bary = _get(d, "bary", where, list)
    try:
        f = np.asarray(face, dtype=np.int64).reshape(-1)
        b = np.asarray(bary, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise LayoutError(f"key '{where}.face' / '{where}.bary': not arrays of numbers") from None
    if any(not isinstance(x, int) or isinstance(x, bool) for x in face):
        raise LayoutError(f"key '{where}.face': face indices must be integers")
    if b.ndim != 2 or b.shape != (f.shape[0], 3):
        raise LayoutError(
            f"key '{where}.bary': expected {f.shape[0]} rows of 3 numbers, got shape {b.shape}"
        )
    if not np.isfinite(b).all():
        k = int(np.flatnonzero(~np.isfinite(b).all(axis=1))[0])
        raise LayoutError(f"key '{where}.bary': row {k} is not finite")
    return SurfacePoints(f, b)


def layout_from_json(text: str, *, source: str = "layout") -> Layout:
    """Parse version-1 layout JSON (structure only; see :func:`load_layout` for the checks
    against a mesh).

    Raises
    ------
    meshfit.errors.LayoutError
        Malformed JSON (with line and column), an unknown version, a missing or mistyped key
        (named by its path, e.g. ``curves[3].face``), sides that do not join end to end.
    """
    doc = read_json(text, source=source, error=LayoutError)
    if not isinstance(doc, dict) or "meshfit_layout" not in doc:
        raise LayoutError(f"{source}: not a meshfit layout file (no 'meshfit_layout' key)")
    version = doc["meshfit_layout"]
    if version != FORMAT_VERSION or isinstance(version, bool):
        raise LayoutError(
            f"{source}: unknown layout version {version!r} (this meshfit reads version "
            f"{FORMAT_VERSION})"
        )
    try:
        mesh = _get(doc, "mesh", "", dict)
        fingerprint = _get(mesh, "sha256", "mesh", str)
        corners = _points(_get(doc, "corners", "", dict), "corners")
        curves, ends, creases = [], [], []
        for i, c in enumerate(_get(doc, "curves", "", list)):
            where = f"curves[{i}]"
            ab = _get(c, "corners", where, list)
            if len(ab) != 2 or any(not isinstance(x, int) or isinstance(x, bool) for x in ab):
                raise LayoutError(f"key '{where}.corners': expected two corner indices")
            ends.append(ab)
            curves.append(SurfaceCurve(_points(c, where), kind="boundary"))
            crease = c.get("crease", False)
            if not isinstance(crease, bool):
                raise LayoutError(f"key '{where}.crease': expected true or false")
            creases.append(crease)
        patch_curves, patch_rev, features = [], [], []
        for p, d in enumerate(_get(doc, "patches", "", list)):
            where = f"patches[{p}]"
            sides = _get(d, "sides", where, list)
            if len(sides) != 4:
                raise LayoutError(f"patch {p} has {len(sides)} sides, needs exactly 4")
            row_c, row_r = [], []
            for s, side in enumerate(sides):
                if (
                    not isinstance(side, list)
                    or len(side) != 2
                    or not isinstance(side[0], int)
                    or isinstance(side[0], bool)
                    or not isinstance(side[1], bool)
                ):
                    raise LayoutError(f"key '{where}.sides[{s}]': expected [curve index, reversed]")
                row_c.append(side[0])
                row_r.append(side[1])
            patch_curves.append(row_c)
            patch_rev.append(row_r)
            fl = d.get("features", []) if isinstance(d, dict) else []
            if not isinstance(fl, list):
                raise LayoutError(f"key '{where}.features': expected list")
            features.append(
                tuple(
                    SurfaceCurve(_points(f, f"{where}.features[{j}]"), kind="feature")
                    for j, f in enumerate(fl)
                )
            )
        return Layout(
            corners,
            tuple(curves),
            np.asarray(ends, dtype=np.int64).reshape(-1, 2),
            np.asarray(patch_curves, dtype=np.int64).reshape(-1, 4),
            np.asarray(patch_rev, dtype=bool).reshape(-1, 4),
            tuple(features),
            fingerprint,
            np.asarray(creases, dtype=bool),
        )
    except LayoutError as exc:
        raise LayoutError(f"{source}: {exc}") from None
    except InputError as exc:  # pragma: no cover - guarded by the checks above
        raise LayoutError(f"{source}: {exc}") from None


def load_layout(path: str | os.PathLike, mesh: Mesh, *, check_topology: bool = True) -> Layout:
    """Read and validate a layout file for ``mesh``.

    Parameters
    ----------
    path : str or PathLike
    mesh : Mesh
        The mesh the layout was made for (checked by fingerprint).
    check_topology : bool, keyword-only
        Also cut the mesh along the curves and check that curves meet only at corners and every
        patch is a disk bounded by its four sides, covering the mesh (default True; this is the
        work of :func:`meshfit.layout.extract_patches` without building the submeshes).

    Returns
    -------
    Layout

    Raises
    ------
    meshfit.errors.LayoutError
        Naming the file and the line, key, corner, curve or patch at fault: malformed JSON,
        unknown version, layout of another mesh, face index out of range, barycentrics not
        summing to 1, curve ends away from their corners, a patch without four sides joined end
        to end, crossing curves, a patch that is not a disk.
    meshfit.errors.MeshFileError
        The file cannot be read.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 and sec. 8.1.3 (the patch network).
    """
    from meshfit.errors import MeshFileError

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise MeshFileError(f"{path}: cannot read layout file: {exc}") from None
    layout = layout_from_json(text, source=str(path))
    try:
        check_layout(mesh, layout)
        if check_topology:
            from meshfit.layout.extract import check_layout_topology

            check_layout_topology(mesh, layout)
    except LayoutError as exc:
        raise LayoutError(f"{path}: {exc}") from None
    return layout
