"""The fit folder's files: exports by format, and ``manifest.json``, which lists every file
the fit wrote with its kind and content hash.

Layout of a fit folder (``<stem>`` is the input's name, made safe for file names)::

    <stem>.usdc  <stem>.obj  <stem>_spline.obj  <stem>_spline.mtl  <stem>.glb  <stem>.ply
    <stem>.3dm  <stem>.igs  <stem>.step             the deliverables, by format
    maps/<stem>_<kind>.<udim>.exr|png               one image per patch, UDIM tile 1001 + p
    report.html  report/                            the report
    fit.npz  fit.json  layout.json  summary.json    the fit itself (meshfit.load_fit)
    manifest.json                                   every file above with kind and hash
    .meshfit/                                       the stage cache (for --resume)

Maps are written once: the USD and the OBJ's materials reference the files in ``maps/``.
PNG maps of one fit share one value range, symmetric about zero (``[-r, r]``, ``r`` the
largest displacement component of the fit; ``[-1, 1]`` for bump maps), so zero is the same
mid-grey in every image.

The manifest is how a later run knows what the user changed: a map image whose hash
differs from the manifest's was edited, and no run overwrites it (:func:`write_exports`
keeps it and says so; ``meshfit rebuild`` applies it).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from meshfit._atomic import write_bytes
from meshfit._jsonio import read_json_file
from meshfit.errors import InputError
from meshfit.export.weld import UDIM_FIRST, udim
from meshfit.pipeline.store import PIPELINE_FORMAT, sha_file, write_json

__all__ = [
    "CACHE",
    "MANIFEST",
    "accept_edits",
    "edited_maps",
    "file_kind",
    "map_file",
    "map_patch",
    "output_stem",
    "patch_names",
    "planned_files",
    "read_manifest",
    "refuse_foreign",
    "remove_stale",
    "update_manifest",
    "write_exports",
    "write_manifest",
]

MANIFEST = "manifest.json"
#: version of the manifest's schema
MANIFEST_FORMAT = 1


#: the stage cache's folder inside a fit folder
CACHE = ".meshfit"
#: extensions of the tessellated and CAD deliverables, by format
#: (the USD stage in the binary crate format: a text layer of a fine mesh is several times
#: larger and slower to read)
DELIVERABLES = {
    "usd": ".usdc",
    "3dm": ".3dm",
    "iges": ".igs",
    "step": ".step",
    "glb": ".glb",
    "ply": ".ply",
}


def patch_names(n: int) -> list[str]:
    """The name of each patch in every output (``patch_000``, ...)."""
    return [f"patch_{p:03d}" for p in range(n)]


def output_stem(name: str | None) -> str:
    """The stem the deliverables are named by: the input's name without a mesh file's
    extension, every run of characters other than letters, digits, ``-`` and ``_`` turned
    into ``_`` (``fit`` when nothing is left)."""
    text = re.sub(r"\.(ply|obj|stl|off|glb|gltf)$", "", str(name or ""), flags=re.IGNORECASE)
    stem = re.sub(r"[^A-Za-z0-9_-]+", "_", text).strip("_")
    return stem or "fit"


def map_file(stem: str, kind: str, patch: int, ext: str) -> str:
    """The map image of ``patch``: ``maps/<stem>_<kind>.<udim>.<ext>``."""
    return f"maps/{stem}_{kind}.{udim(patch)}.{ext}"


def map_patch(name: str, kind: str) -> int | None:
    """The patch a file of ``maps/`` holds the ``kind`` map of (by its UDIM number), or
    None when the name is not such a map."""
    m = re.fullmatch(rf"maps/.+_{re.escape(kind)}\.(\d{{4}})\.(exr|png)", name)
    if m is None or int(m.group(1)) < UDIM_FIRST:
        return None
    return int(m.group(1)) - UDIM_FIRST


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
        "mtl": "mesh",
        "ply": "mesh",
        "glb": "mesh",
        "usda": "usd",
        "usdc": "usd",
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
        data = read_json_file(path, error=ValueError)
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


def _write_maps(out: Path, stem: str, maps, ext: str) -> list[str]:
    """Every map as ``maps/<stem>_<kind>.<udim>.<ext>``; PNG maps share one range."""
    from meshfit.displacement import write_exr, write_png

    (out / "maps").mkdir(exist_ok=True)
    bump = maps[0].kind == "bump"
    r = 1.0 if bump else max(float(abs(d.values).max()) for d in maps)
    files = []
    for p, d in enumerate(maps):
        f = map_file(stem, d.kind, p, ext)
        if ext == "exr":
            write_exr(d, out / f)
        else:
            write_png(d, out / f, value_range=(-r, r) if r > 0 else (-1.0, 1.0))
        files.append(f)
    return files


@dataclass(frozen=True)
class _Export:
    """What every writer of one fit's exports needs."""

    out: Path
    stem: str
    surfaces: Sequence
    maps: Sequence
    network: Any
    units: str
    up_axis: str

    @property
    def geometry(self) -> bool:
        """Whether the maps move the surface (a bump map only shades)."""
        return self.maps[0].kind != "bump"


def _write_format(job: _Export, fmt: str, images: list[str]) -> list[str]:
    """Write one format; ``images``: the map files already written (EXR first), which the
    USD and the OBJ's material reference."""
    from meshfit import export

    names = patch_names(len(job.surfaces))
    surfaces, network = job.surfaces, job.network
    maps = job.maps if job.geometry else None
    target = job.out / f"{job.stem}{DELIVERABLES.get(fmt, '')}"
    if fmt == "usd":
        export.export_usd(
            target, surfaces, displacements=maps, network=network, names=names,
            units=job.units, up_axis=job.up_axis,
        )  # fmt: skip
    elif fmt == "3dm":
        export.export_3dm(target, surfaces, names=names, units=job.units)
    elif fmt == "iges":
        export.export_iges(target, surfaces, names=[f"P{k}" for k in range(len(names))],
                           units=job.units)  # fmt: skip
    elif fmt == "step":
        export.export_step(target, surfaces, names=names, units=job.units)
    elif fmt == "glb":
        export.export_gltf(target, surfaces, displacements=maps, names=names, network=network)
    elif fmt == "ply":
        export.export_ply(target, surfaces, displacements=maps, network=network)
    elif fmt == "obj":
        displaced, spline, mtl = _obj_files(job.stem)
        objs: dict[str | os.PathLike, Any] = {job.out / spline: None}
        if maps is not None:
            objs = {job.out / displaced: maps, **objs}
        # the spline's texture coordinates address the maps' texels: it is displaced by them
        shapes = [d.shape[:2] for d in job.maps]
        mats = images if (maps is not None and images) else None
        export.export_objs(objs, surfaces, names=names, shape=shapes, network=network,
                           materials=mats)  # fmt: skip
        files = [Path(p).name for p in objs]
        return files + ([mtl] if mats else [])
    else:
        raise InputError(f"unknown output format {fmt!r}")
    return [target.name]


def _obj_files(stem: str) -> tuple[str, str, str]:
    """The ``obj`` format's files: the displaced mesh, the spline mesh and its material."""
    return f"{stem}.obj", f"{stem}_spline.obj", f"{stem}_spline.mtl"


def planned_files(stem: str, formats: Sequence[str], maps: Sequence = ()) -> list[str]:
    """The files :func:`write_exports` writes for ``formats`` (relative to the folder); the
    map images only when ``maps`` are given (their kind and count name them)."""
    files: list[str] = []
    for fmt in formats:
        if maps and (fmt in ("exr", "png") or (fmt == "usd" and "exr" not in formats)):
            ext = "exr" if fmt == "usd" else fmt
            files += [map_file(stem, maps[0].kind, p, ext) for p in range(len(maps))]
        if fmt == "obj":
            files += _obj_files(stem)
        elif fmt in DELIVERABLES:
            files.append(f"{stem}{DELIVERABLES[fmt]}")
    return files


def refuse_foreign(folder: Path, files: Sequence[str]) -> None:
    """InputError when a file about to be written exists and no fit wrote it (neither the
    last manifest nor a cached exports record of an interrupted run lists it): the input,
    or a file of the user's, is never overwritten."""
    listed = set(read_manifest(folder))
    for record in (Path(folder) / CACHE).glob("exports-*.json"):
        try:
            listed |= set(json.loads(record.read_text())["sha256"])
        except (ValueError, KeyError, TypeError):
            continue  # a damaged record vouches for nothing
    for name in files:
        if (folder / name).exists() and name not in listed:
            raise InputError(
                f"{folder / name} exists and no fit wrote it: meshfit does not overwrite it "
                "(is it the input?); choose another output folder"
            )


def write_exports(
    out: Path,
    surfaces: Sequence,
    maps: Sequence,
    formats: Sequence[str],
    *,
    stem: str = "fit",
    network: Any = None,
    units: str = "mm",
    up_axis: str = "auto",
    progress: Callable[[int, int], None] | None = None,
    notes: list[str] | None = None,
) -> dict[str, list[str]]:
    """Write ``formats`` of a fit into ``out``, the deliverables named ``stem``; returns the
    files per format.

    The maps are written first, once (EXR where ``exr`` or ``usd`` is asked for, since the
    USD stage reads them; PNG where ``png`` is), and the USD and the spline OBJ's material
    reference them. ``network`` (the fit's shared boundaries) makes the tessellated meshes
    watertight; ``units`` and ``up_axis`` (``"auto"``: from the splines' extent, see
    :func:`meshfit.mesh.measures.up_axis`) are declared where a format can say them.

    A map the user edited since the last run (:func:`edited_maps`) is put back as the user
    left it after the writers run, and ``notes`` says so: a re-fit never loses an edit.
    """
    from meshfit._malloc import release_memory
    from meshfit.mesh.measures import up_axis as guess_up

    out = Path(out)
    refuse_foreign(out, planned_files(stem, formats, maps))
    kept = {name: (out / name).read_bytes() for name in edited_maps(out)}
    if up_axis == "auto":
        up_axis = guess_up(np.concatenate([s.control_points.reshape(-1, 3) for s in surfaces]))
    job = _Export(out, stem, surfaces, maps, network, units, up_axis)
    outputs: dict[str, list[str]] = {}
    images: list[str] = []
    todo = list(formats)
    for ext in ("exr", "png"):
        if ext in todo or (ext == "exr" and "usd" in todo):
            files = _write_maps(out, stem, maps, ext)
            outputs[ext if ext in todo else "usd"] = files
            images = images or files
    for i, fmt in enumerate(todo):
        if fmt not in ("exr", "png"):
            outputs[fmt] = outputs.get(fmt, []) + _write_format(job, fmt, images)
            release_memory()  # (one tessellation's pages, before the next format's)
        if progress is not None:
            progress(i + 1, len(todo))
    outputs = {f: outputs[f] for f in todo if f in outputs}
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


def remove_stale(folder: Path, listed: Mapping[str, Any], written: Sequence[str]) -> list[str]:
    """Delete the files a previous run's manifest (``listed``) named that this run did not
    write, except maps the user edited; nothing else is ever deleted. Returns them."""
    folder = Path(folder)
    keep = set(written) | set(edited_maps(folder))
    gone = []
    for name in listed:
        path = folder / name
        if name in keep or Path(name).is_absolute() or ".." in Path(name).parts:
            continue
        if not path.is_file():
            continue
        path.unlink()
        gone.append(name)
    return sorted(gone)
