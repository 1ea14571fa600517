"""The result of a fit: a typed object to hold, save, load, edit and rebuild.

A :class:`FitResult` is the hybrid representation of the thesis (ch. 7): per patch a
spring grid, a B-spline surface and a displacement map that holds the detail. The maps
exist to be edited (sec. 9.2.3): paint on a map image, then :meth:`FitResult.rebuild`
(or ``meshfit rebuild FOLDER``) re-applies the maps to the splines and closes the seams.
:meth:`FitResult.save` writes ``fit.npz`` (every array), ``fit.json``, ``layout.json``
and ``summary.json``; :func:`load_fit` reads them back bit for bit.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit._atomic import write_text
from meshfit._jsonio import read_json_file
from meshfit.bspline import BSplineSurface
from meshfit.displacement import DisplacementMap
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.pipeline.options import FitOptions
from meshfit.pipeline.outputs import (
    edited_maps,
    map_patch,
    output_stem,
    update_manifest,
    write_exports,
)
from meshfit.pipeline.store import PIPELINE_FORMAT, load_npz, save_npz, write_json
from meshfit.stitch import Network, SharedBoundary

__all__ = ["FitResult", "PatchFit", "load_fit"]

#: the files :meth:`FitResult.save` writes
FIT_FILES = ("fit.npz", "fit.json", "layout.json", "summary.json")


@dataclass(frozen=True, eq=False)
class PatchFit:
    """One patch of a fit.

    Attributes
    ----------
    index : int
        The patch's number in the layout.
    spring : (nu, nv, 3) float64
        The spring mesh's points, model units (``spring[i, j]`` at ``(i / (nu - 1),
        j / (nv - 1))``).
    surface : BSplineSurface
        The fitted spline, ``control_points (mu, mv, 3)``.
    displacement : DisplacementMap
        The detail: the displaced surface is the spline plus this map.
    errors : dict
        The patch's figures (spring-mesh quality, fit error over the input's bbox diagonal,
        its input vertices' largest distance to the displaced surface, ...).
    """

    index: int
    spring: NDArray[np.float64]
    surface: BSplineSurface
    displacement: DisplacementMap
    errors: dict[str, Any] = field(default_factory=dict)

    def displaced(self) -> NDArray[np.float64]:
        """The displaced surface at the map's texels: ``(h, w, 3) float64``."""
        from meshfit.displacement import reconstruct

        return reconstruct(self.surface, self.displacement)


@dataclass(frozen=True, eq=False)
class FitResult:
    """A whole fit: its patches, the layout, the continuity network and the summary.

    Attributes
    ----------
    patches : list of PatchFit
    layout : meshfit.layout.Layout
    network : meshfit.stitch.Network
        Shared boundaries (C0 or G1 each) and corners of the patches.
    summary : dict
        Figures of the whole fit: ``errors`` (``spline_only``, ``displaced``: two-sided RMS
        and Hausdorff distance to the input over its bbox diagonal), ``seams``, ``stages``,
        ``notes``, ``control_classes``, per-patch rows in ``patches``.
    options : FitOptions
    mesh : Mesh, optional
        The input, while in memory (not saved; ``summary["mesh"]`` names it and holds its
        hash).
    face_patch : (n_faces,) int64, optional
        Patch of every input face.
    spline_distance : (n,) float64, optional
        Each spline-only grid point's distance to the input (the report's heat map).
    """

    patches: list[PatchFit]
    layout: Any
    network: Network
    summary: dict[str, Any]
    options: FitOptions
    mesh: Mesh | None = None
    face_patch: NDArray[np.int64] | None = None
    spline_distance: NDArray[np.float64] | None = None

    @property
    def surfaces(self) -> list[BSplineSurface]:
        return [p.surface for p in self.patches]

    @property
    def maps(self) -> list[DisplacementMap]:
        return [p.displacement for p in self.patches]

    @property
    def errors(self) -> dict[str, Any]:
        return self.summary["errors"]

    # ------------------------------------------------------------------ save / load
    def save(self, folder: str | os.PathLike) -> Path:
        """Write the fit into ``folder`` (created): ``fit.npz`` with every array, ``fit.json``
        (options, network, kinds), ``layout.json`` and ``summary.json``; the manifest lists
        them. :func:`load_fit` reads them back bit for bit."""
        out = self._write(folder)
        update_manifest(out, FIT_FILES)
        return out

    def _write(self, folder: str | os.PathLike) -> Path:
        """The files of :meth:`save`, without the manifest (:func:`meshfit.fit` lists every
        file of its folder in one manifest at the end)."""
        from meshfit.layout import layout_to_json

        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, NDArray] = {}
        for p in self.patches:
            arrays[f"spring_{p.index}"] = p.spring
            arrays[f"ctrl_{p.index}"] = p.surface.control_points
            arrays[f"map_{p.index}"] = p.displacement.values
        if self.face_patch is not None:
            arrays["face_patch"] = self.face_patch
        if self.spline_distance is not None:
            arrays["spline_distance"] = self.spline_distance
        save_npz(out / "fit.npz", arrays)
        meta = {
            "meshfit_fit": PIPELINE_FORMAT,
            "options": asdict(self.options),
            "kinds": [p.displacement.kind for p in self.patches],
            "network": _network_json(self.network),
        }
        write_json(out / "fit.json", meta)
        write_text(out / "layout.json", layout_to_json(self.layout))
        write_json(out / "summary.json", self.summary)
        return out

    def export(self, folder: str | os.PathLike, formats: tuple[str, ...] | None = None) -> dict:
        """Write ``formats`` (default the options' formats) into ``folder``; returns the files
        per format. A map image the user edited there is kept (see :mod:`.outputs`)."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        fmts = self.options.formats if formats is None else FitOptions(formats=formats).formats
        notes: list[str] = []
        stem = output_stem(self.summary["mesh"].get("name"))
        o = self.options
        files = write_exports(
            out, self.surfaces, self.maps, fmts, stem=stem, network=self.network,
            units=o.units, up_axis=o.up_axis, notes=notes,
        )  # fmt: skip
        self.summary.setdefault("notes", []).extend(notes)
        self.summary.setdefault("outputs", {}).update(files)
        update_manifest(out, [f for fs in files.values() for f in fs])
        return files

    def report(self, folder: str | os.PathLike, *, image_size: int | None = None) -> list[str]:
        """Render ``report.html`` and its images into ``folder`` (default size the options');
        returns the files written, relative to ``folder``. Needs the input mesh (the result's
        own, or ``load_fit(folder, mesh=...)``): the layout and error renders are drawn on it.
        With ``$MESHFIT_BLENDER_PYTHON`` set and the fit's USD stage in ``folder``, Blender's
        renders of it are included, as in :func:`meshfit.fit`."""
        from meshfit.report import ReportInputs, blender_python, write_report

        if self.mesh is None:
            raise InputError(
                "a report is drawn on the input mesh: load the fit with it "
                "(load_fit(folder, mesh=...), meshfit rebuild --mesh PATH)"
            )
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        shown = ReportInputs(
            mesh=self.mesh,
            grids=[p.spring for p in self.patches],
            surfaces=self.surfaces,
            maps=self.maps,
            displaced=lambda: [p.displaced() for p in self.patches],
            summary=self.summary,
            face_patch=self.face_patch,
            spline_distance=self.spline_distance,
        )
        size = self.options.image_size if image_size is None else int(image_size)
        drawn = write_report(out, shown, image_size=size, blender_python=blender_python())
        images = drawn["images"]
        self.summary.setdefault("outputs", {})["report"] = ["report.html"]
        files = ["report.html", *images]
        update_manifest(out, files)
        return files

    # ------------------------------------------------------------------ edit / rebuild
    def with_maps(self, maps: list[DisplacementMap]) -> FitResult:
        """The same fit with other maps (one per patch), not yet rebuilt."""
        if len(maps) != len(self.patches):
            raise InputError(f"{len(maps)} maps for a fit of {len(self.patches)} patches")
        patches = [replace(p, displacement=m) for p, m in zip(self.patches, maps, strict=True)]
        return replace(self, patches=patches)

    def rebuild(self, mesh: Mesh | None = None) -> FitResult:
        """Re-apply the maps to the splines: seams closed again, seams and errors measured.

        Use after editing maps (:meth:`with_maps`, or map images and :func:`load_fit`).
        The errors against the input are measured again where the input is known (``mesh``
        or the result's own); otherwise the displaced errors are dropped from the summary
        with a note.
        """
        from meshfit.pipeline.rebuild import rebuild

        return rebuild(self, mesh if mesh is not None else self.mesh)


def _network_json(net: Network) -> dict[str, Any]:
    return {
        "n_patches": net.n_patches,
        "boundaries": [
            [b.a, str(b.side_a), b.b, str(b.side_b), bool(b.reversed), b.continuity]
            for b in net.boundaries
        ],
        "corners": [[list(s) for s in c] for c in net.corners],
    }


def _network_from_json(d: dict[str, Any]) -> Network:
    from meshfit.types import Side

    bounds = tuple(
        SharedBoundary(int(a), Side(sa), int(b), Side(sb), bool(r), str(c))
        for a, sa, b, sb, r, c in d["boundaries"]
    )
    corners = tuple(tuple((int(k), int(i), int(j)) for k, i, j in c) for c in d["corners"])
    return Network(int(d["n_patches"]), bounds, corners)


def _map_from_file(path: Path, like: DisplacementMap) -> DisplacementMap:
    from meshfit.displacement import read_exr, read_png

    m = read_exr(path) if path.suffix == ".exr" else read_png(path)
    if m.kind != like.kind or m.shape != like.shape:
        raise InputError(
            f"{path}: a {m.kind} map of {m.shape[0]} x {m.shape[1]} texels where the fit has "
            f"a {like.kind} map of {like.shape[0]} x {like.shape[1]}: keep the kind and size"
        )
    return m


def edited_map_files(folder: Path, n: int, kinds: list[str]) -> dict[int, Path]:
    """Per patch, the newest map image of the fit's kind the user edited in ``folder``."""
    found: dict[int, Path] = {}
    for name in edited_maps(folder):
        p = next((q for q in range(n) if map_patch(name, kinds[q]) == q), None)
        if p is None:
            continue
        path = folder / name
        if p not in found or path.stat().st_mtime > found[p].stat().st_mtime:
            found[p] = path
    return found


def load_fit(
    folder: str | os.PathLike, *, edited: bool = True, mesh: Mesh | None = None
) -> FitResult:
    """Read a fit folder written by :meth:`FitResult.save` (``meshfit fit``).

    Parameters
    ----------
    folder : path
    edited : bool, keyword-only
        Read the maps the user edited (images whose hash differs from ``manifest.json``;
        of an EXR and a PNG of one patch both edited, the newer) instead of the stored
        values (default True). Without edits the result is the saved one, bit for bit;
        apply edits with :meth:`FitResult.rebuild`.
    mesh : Mesh, optional
        The input, for a rebuild that measures errors again.

    Raises
    ------
    meshfit.errors.InputError
        No fit in the folder, a file of another format version, or an edited map of another
        kind or size than the fit's.
    """
    from meshfit.layout import layout_from_json

    out = Path(folder)
    if not (out / "fit.json").is_file() or not (out / "fit.npz").is_file():
        raise InputError(f"{out}: no fit here (fit.json and fit.npz; run meshfit fit first)")
    try:
        meta = read_json_file(out / "fit.json", error=ValueError)
        version = meta["meshfit_fit"]
    except (ValueError, KeyError, TypeError):
        raise InputError(f"{out / 'fit.json'}: not a meshfit fit file") from None
    if version != PIPELINE_FORMAT:
        raise InputError(
            f"{out / 'fit.json'}: fit format {version!r}; this meshfit reads {PIPELINE_FORMAT} "
            "(fit the mesh again)"
        )
    z = load_npz(out / "fit.npz")
    layout = layout_from_json((out / "layout.json").read_text(), source=str(out / "layout.json"))
    options = FitOptions.from_json(meta["options"])
    kinds = meta["kinds"]
    summary = read_json_file(out / "summary.json")
    patches = [
        PatchFit(
            p,
            z[f"spring_{p}"],
            BSplineSurface(z[f"ctrl_{p}"]),
            DisplacementMap(z[f"map_{p}"], kinds[p]),
            summary["patches"][p],
        )
        for p in range(len(kinds))
    ]
    if edited:
        for p, path in edited_map_files(out, len(patches), kinds).items():
            patches[p] = replace(
                patches[p], displacement=_map_from_file(path, patches[p].displacement)
            )
    return FitResult(
        patches,
        layout,
        _network_from_json(meta["network"]),
        summary,
        options,
        mesh=mesh,
        face_patch=z.get("face_patch"),
        spline_distance=z.get("spline_distance"),
    )
