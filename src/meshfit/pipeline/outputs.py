"""The fit folder's files: exports by format, and ``manifest.json``, which lists every file
the fit wrote with its kind and content hash.

The manifest is how a later run knows what the user changed: a map image whose hash
differs from the manifest's was edited, and no run overwrites it (:func:`write_exports`
keeps it and says so; ``meshfit rebuild`` applies it).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from meshfit._atomic import write_bytes
from meshfit.errors import InputError
from meshfit.pipeline.store import PIPELINE_FORMAT, sha_file, write_json

__all__ = [
    "MANIFEST",
    "accept_edits",
    "edited_maps",
    "file_kind",
    "patch_names",
    "read_manifest",
    "update_manifest",
    "write_exports",
    "write_manifest",
]

MANIFEST = "manifest.json"
#: version of the manifest's schema
MANIFEST_FORMAT = 1


def patch_names(n: int) -> list[str]:
    """The name of each patch in every output (``patch_000``, ...)."""
    return [f"patch_{p:03d}" for p in range(n)]


def file_kind(name: str) -> str:
    """The kind of a fit folder's file, from its name: map, fit, layout, summary, report,
    image, mesh, usd or cad."""
    if name.endswith((".exr", ".png")) and (name.startswith("maps/") or ".patch_" in name):
        return "map"
    kinds = {
        "fit.npz": "fit",
        "fit.json": "fit",
        "layout.json": "layout",
        "summary.json": "summary",
        "report.html": "report",
    }
    if name in kinds:
        return kinds[name]
    suffix = name.rsplit(".", 1)[-1]
    return {
        "png": "image",
        "obj": "mesh",
        "ply": "mesh",
        "glb": "mesh",
        "usda": "usd",
        "3dm": "cad",
        "igs": "cad",
        "step": "cad",
    }.get(suffix, "other")


def read_manifest(folder: Path) -> dict[str, dict[str, str]]:
    """``{file: {"kind", "sha256"}}`` of a fit folder's manifest (empty without one).

    Raises
    ------
    meshfit.errors.InputError
        A manifest that is not valid JSON of the expected shape.
    """
    path = Path(folder) / MANIFEST
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
        files = data["files"]
        if not isinstance(files, dict) or not all(
            isinstance(k, str) and isinstance(v.get("sha256"), str) for k, v in files.items()
        ):
            raise TypeError
    except (ValueError, KeyError, TypeError, AttributeError):
        raise InputError(f"{path}: not a meshfit manifest") from None
    return files


def write_manifest(folder: Path, files: Sequence[str], keep: dict | None = None) -> Path:
    """Write ``manifest.json`` listing ``files`` (relative to ``folder``) with their kinds
    and hashes; entries of ``keep`` are carried over as they are (the hashes of maps the
    user edited and a run kept, so they still read as edited)."""
    folder = Path(folder)
    entries = {f: {"kind": file_kind(f), "sha256": sha_file(folder / f)} for f in files}
    entries.update(keep or {})
    data: dict[str, Any] = {"meshfit_manifest": MANIFEST_FORMAT, "pipeline": PIPELINE_FORMAT}
    data["files"] = dict(sorted(entries.items()))
    return write_json(folder / MANIFEST, data)


def update_manifest(folder: Path, written: Sequence[str]) -> Path:
    """The manifest with ``written`` (re-hashed) added to what it listed before (files gone
    since are dropped); maps the user edited keep their old entries, so they still read as
    edited."""
    folder = Path(folder)
    old = read_manifest(folder)
    keep = edited_maps(folder)
    others = [f for f in old if f not in written and f not in keep and (folder / f).is_file()]
    return write_manifest(folder, [*others, *written], keep=keep)


def edited_maps(folder: Path) -> dict[str, dict[str, str]]:
    """The map files of a fit folder whose content differs from the manifest's hash (the
    user edited them), with their manifest entries."""
    folder = Path(folder)
    out = {}
    for name, entry in read_manifest(folder).items():
        if entry.get("kind") != "map":
            continue
        path = folder / name
        if path.is_file() and sha_file(path) != entry["sha256"]:
            out[name] = entry
    return out


def _write_format(out: Path, fmt: str, names, surfaces, maps) -> list[str]:
    from meshfit import export
    from meshfit.displacement import write_exr, write_png

    geometry = maps[0].kind != "bump"  # a bump map shades; it does not move the surface
    if fmt == "usd":
        if not geometry:
            export.export_usd(out / "patches.usda", surfaces, names=names)
            return ["patches.usda"]
        export.export_usd(out / "patches.usda", surfaces, displacements=maps, names=names)
        return ["patches.usda"] + [
            f"patches.{n}.{d.kind}.exr" for n, d in zip(names, maps, strict=True)
        ]
    if fmt == "3dm":
        export.export_3dm(out / "patches.3dm", surfaces, names=names)
        return ["patches.3dm"]
    if fmt == "iges":
        export.export_iges(
            out / "patches.igs", surfaces, names=[f"P{k}" for k in range(len(names))]
        )
        return ["patches.igs"]
    if fmt == "step":
        export.export_step(out / "patches.step", surfaces, names=names)
        return ["patches.step"]
    if fmt == "obj":
        # the spline on the displaced surface's vertex grid (a finer tessellation would make
        # the file many times larger)
        objs: dict[str | os.PathLike, Any] = {out / "spline.obj": None}
        if geometry:
            objs = {out / "displaced.obj": maps, **objs}
        export.export_objs(objs, surfaces, names=names, shape=[d.shape[:2] for d in maps])
        return [Path(p).name for p in objs]
    if fmt == "glb":
        name = "displaced.glb" if geometry else "spline.glb"
        export.export_gltf(
            out / name, surfaces, displacements=maps if geometry else None, names=names
        )
        return [name]
    (out / "maps").mkdir(exist_ok=True)
    files = []
    for n, d in zip(names, maps, strict=True):
        f = f"maps/{n}.{d.kind}.{fmt}"
        (write_exr if fmt == "exr" else write_png)(d, out / f)
        files.append(f)
    return files


def write_exports(
    out: Path,
    surfaces: Sequence,
    maps: Sequence,
    formats: Sequence[str],
    *,
    progress: Callable[[int, int], None] | None = None,
    notes: list[str] | None = None,
) -> dict[str, list[str]]:
    """Write ``formats`` of a fit into ``out``; returns the files per format.

    A map the user edited since the last run (:func:`edited_maps`) is put back as the user
    left it after the writers run, and ``notes`` says so: a re-fit never loses an edit.
    """
    out = Path(out)
    kept = {name: (out / name).read_bytes() for name in edited_maps(out)}
    names = patch_names(len(surfaces))
    outputs: dict[str, list[str]] = {}
    for i, fmt in enumerate(formats):
        outputs[fmt] = _write_format(out, fmt, names, surfaces, maps)
        if progress is not None:
            progress(i + 1, len(formats))
    for name, data in kept.items():
        if (out / name).read_bytes() != data:
            write_bytes(out / name, data)
    if kept and notes is not None:
        listed = ", ".join(sorted(kept)[:5]) + (" ..." if len(kept) > 5 else "")
        notes.append(
            f"{len(kept)} edited map file(s) kept as they are ({listed}): their content "
            "differs from manifest.json; `meshfit rebuild` applies them"
        )
    return outputs


def accept_edits(folder: Path) -> None:
    """Record the edited maps' current hashes in the manifest (after a rebuild applied them,
    they are no longer edits)."""
    folder = Path(folder)
    files = [f for f in read_manifest(folder) if (folder / f).is_file()]
    write_manifest(folder, files)
