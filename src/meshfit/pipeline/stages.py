"""The stages of the fit, in order: validate, layout, cut, springs, fit, displacement, stitch,
errors, exports (and the report, after the summary).

Each stage reads named values from the :class:`~meshfit.pipeline.runner.Context` and writes
its own; the continuity logic lives in :mod:`meshfit.stitch`, the error figures in
:mod:`meshfit.pipeline.measure`, the files in :mod:`meshfit.pipeline.outputs`.
"""

from __future__ import annotations

import hashlib
import os
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._jsonio import read_json_file
from meshfit._threads import map_threads
from meshfit.errors import InputError, LayoutError
from meshfit.mesh import Mesh
from meshfit.mesh.locate import grid_tree, query_order
from meshfit.pipeline import measure
from meshfit.pipeline.notes import small_components
from meshfit.pipeline.runner import Context, Stage
from meshfit.pipeline.springs import patch_payload, spring_patch, spring_task
from meshfit.pipeline.store import (
    as_bytes,
    from_bytes,
    load_npz,
    mesh_hash,
    save_npz,
    sha_file,
    untimed,
    write_json,
)

#: pipeline stages in order (keys of the summary's ``stages``)
STAGES = (
    "validate",
    "layout",
    "cut",
    "springs",
    "fit",
    "displacement",
    "stitch",
    "errors",
    "exports",
    "report",
)


class Validate(Stage):
    """The input as a validated :class:`Mesh` (a path is loaded and repaired), its small
    components noted or dropped, its content hash taken on a thread."""

    name = "validate"
    inputs = ("input",)
    outputs = ("mesh", "mesh_info", "diag", "mesh_hash")
    suffix = None

    def __init__(self, automatic: bool = True, fingerprint: str | None = None) -> None:
        self.automatic = automatic  # the layout is the automatic one (an even remesh may do)
        self.fingerprint = fingerprint  # of the mesh a given layout was made for

    def key(self, ctx: Context) -> str:
        return ""

    def run(self, ctx: Context) -> None:
        mesh = ctx["input"]
        if not isinstance(mesh, Mesh):
            if not isinstance(mesh, (str, os.PathLike)):
                raise InputError(
                    f"mesh must be a Mesh or a mesh file's path, got {type(mesh).__name__}"
                )
            from meshfit.mesh import load_mesh

            mesh = load_mesh(mesh, repair=True)
        if mesh.repairs is not None and mesh.repairs.changed():
            ctx.notes.append(f"the input was {mesh.repairs.summary()}")
        mesh = small_components(mesh, ctx.options.drop_components_below, ctx.notes)
        if self.automatic or self.fingerprint is not None:
            mesh = _even(ctx, mesh, None if self.automatic else self.fingerprint)
        ctx["mesh"] = mesh
        ctx["mesh_info"] = mesh_info(mesh.name, mesh.n_vertices, mesh.n_faces)
        ctx["diag"] = float(mesh.bbox_diagonal)
        pool = ThreadPoolExecutor(max_workers=1)  # hashlib releases the GIL
        ctx["mesh_hash"] = pool.submit(mesh_hash, mesh)
        pool.shutdown(wait=False)


def mesh_info(name: str, n_vertices: int, n_faces: int) -> dict[str, Any]:
    """What the summary, the exports' file names and the cluster's choice read of the
    input: its name and counts (the out-of-core fit has no whole mesh to ask)."""
    return {"name": name, "vertices": int(n_vertices), "faces": int(n_faces)}


def _even(ctx: Context, mesh: Mesh, fingerprint: str | None) -> Mesh:
    """The mesh the fit works on: with ``remesh`` "on", or "auto" and needles over
    `NEEDLE_SHARE` of the area, its even remesh (the notes say so); else ``mesh``. With a
    layout's ``fingerprint`` (a layout given), the remesh only if the layout was made on it
    (a fit's own ``layout.json`` used again); a layout of the input keeps the input."""
    from meshfit.errors import MeshfitError
    from meshfit.layout.even import NEEDLE_SHARE, even_remesh, needle_share
    from meshfit.layout.layout import mesh_fingerprint

    o = ctx.options
    if o.remesh == "off" or (fingerprint is not None and mesh_fingerprint(mesh) == fingerprint):
        return mesh
    share = needle_share(mesh)
    if o.remesh == "auto" and share <= NEEDLE_SHARE:
        return mesh
    try:
        even = even_remesh(mesh, o.crease_angle)
    except MeshfitError as exc:
        if fingerprint is None:
            ctx.notes.append(f"the input could not be remeshed evenly ({exc}): fitted as it is")
        return mesh
    if fingerprint is not None and mesh_fingerprint(even.mesh) != fingerprint:
        return mesh  # (a layout of another mesh: the layout stage says so)
    ctx["remesh"] = even.to_dict()
    why = (
        "the layout was made on its even remesh"
        if fingerprint is not None
        else "remesh on asks for it"
        if o.remesh == "on"
        else f"{share:.0%} of its area is in needle triangles (as a CAD program tessellates)"
    )
    ctx.notes.append(
        f"the input was remeshed evenly ({even.mesh.n_faces:,} faces, within "
        f"{even.distance:.3%} of the diagonal of the input), as {why}; remesh off fits the "
        "input as it is"
    )
    return even.mesh


class Layout(Stage):
    """The patch layout: a Layout object, a layout file, or the automatic layout."""

    name = "layout"
    inputs = ("mesh", "mesh_hash")
    outputs = ("layout", "corner_xyz")
    suffix = ".json"

    def __init__(self, layout: Any) -> None:
        self.layout = "auto" if layout is None else layout
        self.source = ""
        self.report: list = []

    def _resolve(self, ctx: Context):
        from meshfit.layout import Layout as LayoutType
        from meshfit.layout import layout_to_json, load_layout

        mesh = ctx["mesh"]
        if isinstance(self.layout, LayoutType):
            text = layout_to_json(self.layout)
            return hashlib.sha256(text.encode()).hexdigest(), lambda: self.layout
        if isinstance(self.layout, str) and self.layout == "auto":
            from meshfit.layout.auto import AUTO_LAYOUT_REVISION, auto_layout

            o = ctx.options.layout

            def make():
                return auto_layout(mesh, o, report=self.report)

            return f"auto:r{AUTO_LAYOUT_REVISION}", make
        if not isinstance(self.layout, (str, os.PathLike)):
            raise InputError(
                f"layout must be a Layout, a layout file's path or 'auto', got "
                f"{type(self.layout).__name__}"
            )
        path = Path(self.layout)
        if not path.is_file():
            what = "not a file" if path.exists() else "no such layout file"
            raise LayoutError(f"{path}: {what}")
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        return digest, lambda: load_layout(path, mesh)

    def group(self, ctx: Context) -> Any:
        return ctx.options.layout if self.source.startswith("auto") else None

    def extra(self, ctx: Context) -> Any:
        return [ctx["mesh_hash"], self.source]

    def key(self, ctx: Context) -> str:
        self.source, self.make = self._resolve(ctx)  # once: the source decides the group
        return super().key(ctx)

    def run(self, ctx: Context) -> None:
        ctx["layout"] = self.make()
        ctx["corner_xyz"] = ctx["mesh"].xyz(ctx["layout"].corners)
        _check_classes(ctx)  # (before the spring meshes, not after them)

    def save(self, ctx: Context, path: Path) -> None:
        from meshfit.layout import save_layout

        save_layout(ctx["layout"], path, mesh=ctx["mesh"])

    def load(self, ctx: Context, path: Path) -> bool:
        from meshfit.layout import load_layout

        ctx["layout"] = load_layout(path, ctx["mesh"], check_topology=False)
        ctx["corner_xyz"] = ctx["mesh"].xyz(ctx["layout"].corners)
        return True

    def facts(self, ctx: Context) -> dict[str, Any]:
        lay = ctx["layout"]
        ctx["layout_source"] = "auto" if self.source.startswith("auto") else self.source
        ctx["layout_report"] = self.report[0] if self.report else {}
        self._count_note(ctx, int(lay.n_patches))
        return {"patches": int(lay.n_patches)}

    def _count_note(self, ctx: Context, n: int) -> None:
        o = ctx.options.layout
        route = None
        if self.source.startswith("auto"):
            from meshfit.layout.auto import auto_route

            route = (
                self.report[0]["route"]
                if self.report
                else auto_route(ctx["mesh"], patches=o.patches, crease_angle=o.crease_angle)
            )
        ctx["layout_route"] = route
        if route is None or o.patches is None or n == o.patches:
            return
        from meshfit.layout.auto import MIN_PATCHES

        why = (
            f"it makes three per base triangle, an even number of triangles, at least "
            f"{MIN_PATCHES} patches"
            if route == "sphere"
            else "it makes one per side of every cell, and more cells where a cell is not a "
            "disk or turns too far for one patch (meshfit.layout.regions)"
        )
        ctx.notes.append(f"the automatic layout has {n} patches for the {o.patches} asked: {why}")


class Cut(Stage):
    """The patch submeshes, made only when a later stage needs them (a resumed run whose
    spring meshes are saved never cuts); the file keeps each input face's patch."""

    name = "cut"
    inputs = ("mesh", "layout")
    outputs = ("patches", "face_patch")
    after = ("layout",)

    def run(self, ctx: Context) -> None:
        ctx.lazy("patches", lambda: self._cut(ctx))
        ctx.lazy("face_patch", lambda: self._face_patch(ctx))

    def _cut(self, ctx: Context) -> list:
        from meshfit.layout import extract_patches

        t = time.perf_counter()
        mesh = ctx["mesh"]
        _release_mesh_memory(mesh, ("_edge_table",))  # the layout's working arrays
        ps = extract_patches(mesh, ctx["layout"], workers=ctx.workers)
        face_patch = np.full(mesh.n_faces, -1, dtype=np.int64)
        for p in ps:
            face_patch[p.face_parent] = p.index
        ctx["face_patch"] = face_patch
        path = ctx.path(self.name, ".npz")
        if path is not None:
            save_npz(
                path,
                {
                    "face_patch": face_patch,
                    "n_faces": np.array([p.mesh.n_faces for p in ps], dtype=np.int64),
                    "n_vertices": np.array([p.mesh.n_vertices for p in ps], dtype=np.int64),
                },
            )
        ctx.info[self.name] = {"seconds": round(time.perf_counter() - t, 4), "cached": False}
        ctx.tick(self.name, 1, 1)
        return ps

    def _face_patch(self, ctx: Context):
        path = ctx.path(self.name, ".npz")
        if path is not None and path.is_file():
            return load_npz(path)["face_patch"]
        ctx.get("patches")
        return ctx["face_patch"]

    def save(self, ctx: Context, path: Path) -> None:
        pass  # written by the cut itself, when it runs

    def load(self, ctx: Context, path: Path) -> bool:
        self.run(ctx)
        return True


class Springs(Stage):
    """A spring mesh per patch, on threads or through ``patch_map`` (Dask tasks)."""

    name = "springs"
    inputs = ("patches",)
    outputs = ("grids", "spring_info")
    after = ("cut",)

    def __init__(self, patch_map=None) -> None:
        self.patch_map = patch_map
        self.tasks = False  # whether the spring meshes were made as tasks

    def group(self, ctx: Context) -> Any:
        return ctx.options.springs

    def run(self, ctx: Context) -> None:
        from meshfit._malloc import release_memory
        from meshfit.layout.extract import forget_partition

        ps = list(ctx["patches"])
        # no later stage reads the patches or the mesh's adjacency: they go now (each patch
        # as soon as its spring mesh exists), as on a dense scan they are most of the memory
        ctx.values.pop("patches", None)
        forget_partition()
        _release_mesh_memory(ctx["mesh"])
        o = ctx.options.springs
        if self.patch_map is not None:
            res = self.patch_map(spring_task, [(patch_payload(p), o) for p in ps])
        elif ctx.tasks is not None:
            res = ctx.tasks.springs(ps, o, lambda d, n: ctx.tick(self.name, d, n))
        else:
            cost = [p.mesh.n_faces for p in ps]

            def one(i: int):
                out = spring_patch(ps[i], o)
                ps[i] = None
                return out

            res = ctx.map(one, list(range(len(ps))), "springs", cost)
        self.tasks = self.patch_map is not None or ctx.tasks is not None
        ctx["grids"] = [g for g, _ in res]
        ctx["spring_info"] = [i for _, i in res]
        ps.clear()
        release_memory()  # (the patches' pages)

    def save(self, ctx: Context, path: Path) -> None:
        arrays = {f"grid_{p}": g for p, g in enumerate(ctx["grids"])}
        arrays["info"] = as_bytes(untimed(ctx["spring_info"]))
        save_npz(path, arrays)

    def load(self, ctx: Context, path: Path) -> bool:
        z = load_npz(path)
        n = ctx["layout"].n_patches
        ctx["grids"] = [z[f"grid_{p}"] for p in range(n)]
        ctx["spring_info"] = from_bytes(z["info"])
        return True

    def facts(self, ctx: Context) -> dict[str, Any]:
        return {"patch_tasks": self.tasks}


#: what the stages after the cut read of the mesh's derived arrays (closest points for the
#: maps and the errors, face normals for the maps), and the ray-hit tree, which no stage
#: builds but a caller may have (the app's picking)
_MESH_KEPT = ("triangle_tree", "face_normals", "aabb")


def _release_mesh_memory(mesh: Mesh, keep: tuple[str, ...] = (), search: bool = True) -> None:
    """Drop the mesh's derived arrays but ``keep``, the caller's ray-hit tree and (with
    ``search``) the rest of `_MESH_KEPT`, and hand the freed pages back
    (:func:`meshfit._malloc.release_memory`): the adjacency the layout built is several
    times the mesh's own size, and the stages after it derive what they need."""
    from meshfit._malloc import release_memory

    mesh.drop_caches(keep=(_MESH_KEPT if search else ("aabb",)) + keep)
    release_memory()


def _refuse_classes(chosen, n_cls: int) -> None:
    """InputError naming the first chosen control class the layout does not have."""
    for c, _ in chosen:
        if c >= n_cls:
            raise InputError(
                f"class_controls: class {c} does not exist (the layout's patches have "
                f"{n_cls} equal-count classes, 0..{n_cls - 1}; see summary['control_classes'])"
            )


def _check_classes(ctx: Context) -> None:
    """The chosen control classes exist in the layout just made: the classes follow from
    its network alone, so a wrong one is refused before any spring mesh is made."""
    o = ctx.options.spline
    if not o.class_controls:
        return
    from meshfit.stitch import control_classes

    n = ctx["layout"].n_patches
    n_cls = len(control_classes(_layout_network(ctx), default=[o.controls] * n).counts)
    _refuse_classes(o.class_controls, n_cls)


def _layout_network(ctx: Context):
    """The continuity network of the fit's layout: C0 or G1 everywhere, or with continuity
    ``"auto"`` C0 across its crease curves and G1 elsewhere."""
    from meshfit.stitch.layout import layout_network

    lay = ctx["layout"]
    cont = ctx.options.spline.continuity
    creases = lay.creases if cont == "auto" else None
    return layout_network(lay, "C0" if cont == "C0" else "G1", creases)


def _controls(ctx: Context) -> None:
    """Control counts per patch, equal along shared curves; the classes and their notes."""
    from meshfit.stitch import control_classes

    o = ctx.options.spline
    net = ctx["network"]
    shapes = [g.shape[:2] for g in ctx["grids"]]
    n = len(shapes)
    plain = control_classes(net, default=[o.controls] * n, grid_shapes=shapes)
    n_cls = len(plain.counts)
    _refuse_classes(o.class_controls, n_cls)
    chosen = dict(o.class_controls)
    cc = control_classes(net, default=[o.controls] * n, counts=chosen, grid_shapes=shapes)
    cap = np.full(n_cls, np.iinfo(np.int64).max)
    asked = np.zeros(n_cls, dtype=np.int64)  # the count the class asks for unconstrained
    members: list[list] = [[] for _ in range(n_cls)]
    for p in range(n):
        for d in (0, 1):
            c = int(cc.labels[p, d])
            members[c].append([p, "uv"[d]])
            cap[c] = min(cap[c], shapes[p][d])
            asked[c] = max(asked[c], o.controls[d])
    notes = []
    capped = [c for c in range(n_cls) if cap[c] < asked[c] and c not in chosen]
    if capped:
        both = " x ".join(str(int(x)) for x in o.controls)
        used = sorted({int(cap[c]) for c in capped})
        span = f"{used[0]}" if len(used) == 1 else f"{used[0]} to {used[-1]}"
        notes.append(
            f"controls: {both} asked, {span} used in {len(capped)} of {n_cls} control classes "
            "(at most the smallest spring grid of the class; see control_classes)"
        )
    for c, m in o.class_controls:
        if m > cap[c]:
            notes.append(
                f"control class {c}: {m} controls asked, {int(cap[c])} used (the smallest "
                "spring grid of the class)"
            )
    ctx.notes.extend(notes)
    ctx["controls"] = cc.controls
    ctx["control_classes"] = [
        {"class": c, "controls": int(cc.counts[c]), "max": int(cap[c]), "members": members[c]}
        for c in range(n_cls)
    ]


class Fit(Stage):
    """A cubic B-spline per patch, least-squares fitted to its spring grid with the shared
    boundaries pinned (C0), then G1 across the smooth boundaries (:mod:`meshfit.stitch`).
    The per-patch fits run on threads or as tasks; the G1 stitch, which couples the
    patches, on the client."""

    name = "fit"
    inputs = ("layout", "grids", "corner_xyz")
    outputs = ("network", "controls", "control_classes", "surfaces", "fit_info")
    after = ("springs",)

    def __init__(self) -> None:
        self.tasks = False  # whether the splines were fitted as tasks

    def group(self, ctx: Context) -> Any:
        return ctx.options.spline

    def _network(self, ctx: Context) -> None:
        ctx["network"] = _layout_network(ctx)
        _controls(ctx)

    def run(self, ctx: Context) -> None:
        from meshfit.stitch import stitch_surfaces
        from meshfit.stitch.layout import boundary_pins

        self._network(ctx)
        grids, counts, diag = ctx["grids"], ctx["controls"], ctx["diag"]
        o = ctx.options.spline
        pins = boundary_pins(ctx["layout"], ctx["corner_xyz"], grids, counts, o.smoothing)
        if ctx.tasks is not None:
            tick = lambda d, n: ctx.tick(self.name, d, n)  # noqa: E731
            res = ctx.tasks.fits(grids, counts, pins, o, diag, tick)
            self.tasks = True
        else:

            def fit(p: int):
                return patch_fit(grids[p], counts[p], pins[p], o, diag)

            res = ctx.map(fit, list(range(len(grids))), "fit")
        surfaces = [s for s, _ in res]
        if any(b.continuity == "G1" for b in ctx["network"].boundaries):
            surfaces = stitch_surfaces(surfaces, ctx["network"])
        ctx["surfaces"] = surfaces
        ctx["fit_info"] = [i for _, i in res]

    def facts(self, ctx: Context) -> dict[str, Any]:
        return {"patch_tasks": self.tasks}

    def save(self, ctx: Context, path: Path) -> None:
        arrays = {f"ctrl_{p}": s.control_points for p, s in enumerate(ctx["surfaces"])}
        arrays["info"] = as_bytes(untimed(ctx["fit_info"]))
        save_npz(path, arrays)

    def load(self, ctx: Context, path: Path) -> bool:
        from meshfit.bspline import BSplineSurface

        self._network(ctx)
        z = load_npz(path)
        n = ctx["layout"].n_patches
        ctx["surfaces"] = [BSplineSurface(z[f"ctrl_{p}"]) for p in range(n)]
        ctx["fit_info"] = from_bytes(z["info"])
        return True


def patch_fit(grid, controls, pins, options, diag: float):
    """One patch's spline and its fit figures: ``grid (h, w, 3) float64`` least-squares
    fitted with ``controls (mu, mv)`` control points, its boundary rows pinned to ``pins``
    (:func:`meshfit.stitch.layout.boundary_pins`), as ``options`` (SplineOptions) ask;
    lengths in the figures are shares of ``diag``."""
    from meshfit.bspline import fit_bspline, fit_errors

    t = time.perf_counter()
    s = fit_bspline(grid, controls=controls, pin_boundary=pins, smoothing=options.smoothing)
    if options.normal_errors:
        e = fit_errors(s, grid).as_dict()
    else:  # parametric error only (eq. 6.1): the closest-point search is costly
        nu, nv = grid.shape[:2]
        S = s.evaluate_grid(np.linspace(0.0, 1.0, nu), np.linspace(0.0, 1.0, nv))
        par = np.linalg.norm(grid - S, axis=2)
        e = {
            "parametric_rms": float(np.sqrt(np.mean(par**2))),
            "parametric_max": float(par.max()),
        }
    return s, {
        "controls": list(controls),
        **{f"fit_{k}": v / diag for k, v in e.items()},
        "seconds": round(time.perf_counter() - t, 4),
    }


class Displacement(Stage):
    """A displacement map per patch: its spring grid over its spline; with matched map
    shapes, the scan over the spline at the class resolution
    (:func:`meshfit.displacement.refine_on_scan`)."""

    name = "displacement"
    inputs = ("mesh", "network", "surfaces", "grids")
    outputs = ("maps", "map_bounds")
    after = ("fit",)

    def __init__(self) -> None:
        self.tasks = False  # whether the maps were made as tasks

    def extra(self, ctx: Context) -> Any:
        return [ctx.options.maps.kind, ctx.options.maps.shapes]

    def run(self, ctx: Context) -> None:
        shapes = _settle_map_shapes(ctx)
        self._early(ctx)
        surfaces, grids, kind = ctx["surfaces"], ctx["grids"], ctx.options.maps.kind
        mesh = ctx["mesh"]
        if ctx.tasks is not None:
            tick = lambda d, n: ctx.tick(self.name, d, n)  # noqa: E731
            res = ctx.tasks.maps(mesh, surfaces, grids, shapes, kind, tick)
            self.tasks = True
        else:

            def one(p: int):
                return patch_displacement(mesh, surfaces[p], grids[p], shapes[p], kind)

            res = ctx.map(one, list(range(len(grids))), "displacement")
        ctx["maps"] = [m for m, _ in res]
        ctx["map_bounds"] = [b for _, b in res]

    def facts(self, ctx: Context) -> dict[str, Any]:
        return {"patch_tasks": self.tasks}

    def _early(self, ctx: Context) -> None:
        """With maps at their spring grids' shapes, the spline-only surface (measured at
        those grids' parameters, `_spline_grids`) is known now: its errors are measured on a
        thread while the maps are made and stitched. Not beside matched maps: their finer
        scan sampling already keeps every core busy, and the two together would raise the
        peak memory."""
        if ctx.options.maps.shapes != "native" or ctx.saved.get("errors", False):
            return
        if ctx.tasks is not None:  # (the errors are tasks too)
            return
        shapes = [g.shape[:2] for g in ctx["grids"]]
        pool = ThreadPoolExecutor(max_workers=1)
        ctx["early_spline"] = (
            shapes,
            pool.submit(measure.early_spline, ctx["mesh"], ctx["surfaces"], shapes),
        )
        pool.shutdown(wait=False)

    def save(self, ctx: Context, path: Path) -> None:
        arrays = {f"map_{p}": d.values for p, d in enumerate(ctx["maps"])}
        arrays.update({f"bounds_{p}": b for p, b in enumerate(ctx["map_bounds"])})
        save_npz(path, arrays)

    def load(self, ctx: Context, path: Path) -> bool:
        _settle_map_shapes(ctx)  # (the same choice as when the maps were made)
        _load_maps(ctx, load_npz(path))
        return True


def patch_displacement(mesh, surface, grid, shape: tuple[int, int], kind: str):
    """One patch's displacement map and its texels' `texel_bounds`: its spring ``grid (h,
    w, 3) float64`` over its spline, at ``shape``; a shape other than the grid's first
    takes the finer grid from the scan ``mesh`` (:func:`meshfit.displacement.scan_points`;
    ``mesh`` is read only then)."""
    from meshfit.displacement import displacement_map, scan_points

    on_scan = None  # (a spring grid's points all lie on the scan)
    if tuple(shape) != tuple(grid.shape[:2]):
        grid, on_scan = scan_points(mesh, surface, grid, shape)
    dmap = displacement_map(surface, grid, kind=kind)
    return dmap, texel_bounds(surface, dmap, grid, on_scan)


def texel_bounds(surface, dmap, points, on_scan=None) -> NDArray[np.float32]:
    """Per texel of ``dmap``, an upper bound of its displaced point's distance to the scan.

    The errors stage takes a bound below `tol.KNOWN_DISTANCE` as the distance instead of
    searching the scan: a vector map reproduces the points it was made from to round-off
    (Krishnamurthy 2000, sec. 7.1), so a texel made from a point on the scan is on it.

    Parameters
    ----------
    surface : BSplineSurface
    dmap : DisplacementMap
        The map made from ``points`` over ``surface``, (h, w) texels.
    points : (h, w, 3) float64
        The points the map was made from.
    on_scan : (h, w) bool, optional
        Which of ``points`` lie on the scan; default all (a spring grid).

    Returns
    -------
    (h, w) float32
        The distance from each displaced texel to its point where that lies on the scan,
        rounded up; inf elsewhere.
    """
    from meshfit.displacement import reconstruct

    r = np.linalg.norm(reconstruct(surface, dmap) - points, axis=2)
    if on_scan is not None:
        r[~on_scan] = np.inf
    return (r * (1.0 + 2.0**-20)).astype(np.float32)  # (float32 rounds by at most 2**-24)


def _settle_map_shapes(ctx: Context) -> list[tuple[int, int]]:
    """The maps' shapes: matched (equal counts along shared curves) when asked and within
    `MATCH_BUDGET`; otherwise the spring grids' own, with a note, and the run's options say
    ``map_shapes="native"`` from here on (the stitch, the summary and a rebuild follow)."""
    from dataclasses import replace

    from meshfit.stitch import texel_shapes
    from meshfit.stitch.network import MATCH_BUDGET

    native = [tuple(g.shape[:2]) for g in ctx["grids"]]
    if ctx.options.maps.shapes != "matched":
        return native
    matched = texel_shapes(ctx["network"], native)
    a = sum(h * w for h, w in native)
    b = sum(h * w for h, w in matched)
    if b <= MATCH_BUDGET * a:
        return matched
    ctx.notes.append(
        f"maps kept at their spring grids' resolutions ({a:,} texels): equal texel counts "
        f"along shared curves would take {b:,} ({b / a:.0f} times, {MATCH_BUDGET} allowed), "
        "as rows of patches of very different lengths share one count; the exported "
        "meshes meet at their seams, but a renderer tessellating the maps at another rate "
        "may open them"
    )
    ctx.options = replace(ctx.options, map_shapes="native")
    return native


def _load_maps(ctx: Context, z: dict) -> None:
    """The maps and their texel bounds from a stage file's arrays ``z`` into ``ctx`` (a
    file without bounds gives inf: every texel is searched)."""
    from meshfit.displacement import DisplacementMap

    kind = ctx.options.maps.kind
    maps = [DisplacementMap(z[f"map_{p}"], kind) for p in range(ctx["layout"].n_patches)]
    ctx["maps"] = maps
    ctx["map_bounds"] = [
        z.get(f"bounds_{p}", np.full(d.values.shape[:2], np.inf, np.float32))
        for p, d in enumerate(maps)
    ]


def displaced_grids(surfaces, maps, workers: int = 1) -> list:
    """Each spline plus its map at the map's texels, patches on up to ``workers`` threads
    (the frames' array arithmetic releases the interpreter lock)."""
    from meshfit.displacement import reconstruct

    pairs = list(zip(surfaces, maps, strict=True))
    cost = [float(np.prod(d.shape[:2])) for _, d in pairs]
    return map_threads(lambda sd: reconstruct(*sd), pairs, workers, cost=cost)


def close_seams(network, surfaces, maps, match: bool) -> list:
    """Crack-free displacement seams over the fit's network
    (:func:`meshfit.stitch.stitch_displacements`). With ``match`` the maps first take equal
    texel counts along shared curves, so the seams are closed at every output resolution;
    scalar and bump maps always do (their seams close only where both rows have the same
    texels)."""
    from meshfit.stitch import match_map_shapes, stitch_displacements

    if match or (maps and maps[0].kind != "vector"):
        maps = match_map_shapes(surfaces, maps, network)
    return stitch_displacements(surfaces, maps, network)


class Stitch(Stage):
    """The displacement seams closed and every seam measured."""

    name = "stitch"
    inputs = ("layout", "network", "surfaces", "grids", "maps", "map_bounds")
    outputs = ("maps", "seams", "displaced", "spline_grids", "map_bounds")
    after = ("displacement",)

    def extra(self, ctx: Context) -> Any:
        return ctx.options.maps.shapes

    def run(self, ctx: Context) -> None:
        from meshfit.stitch.layout import seam_metrics

        match = ctx.options.maps.shapes == "matched"
        maps = close_seams(ctx["network"], ctx["surfaces"], ctx["maps"], match)
        ctx["map_bounds"] = _moved_unbounded(ctx["maps"], maps, ctx["map_bounds"])
        ctx["maps"] = maps
        self._derived(ctx)
        seams = seam_metrics(ctx["layout"], ctx["surfaces"], ctx["displaced"], ctx["diag"])
        seams["continuity"] = ctx.options.spline.continuity
        ctx["seams"] = seams

    def _derived(self, ctx: Context) -> None:
        ctx.lazy("displaced", lambda: displaced_grids(ctx["surfaces"], ctx["maps"], ctx.workers))
        ctx.lazy("spline_grids", lambda: _spline_grids(ctx))

    def save(self, ctx: Context, path: Path) -> None:
        arrays = {f"map_{p}": d.values for p, d in enumerate(ctx["maps"])}
        arrays.update({f"bounds_{p}": b for p, b in enumerate(ctx["map_bounds"])})
        arrays["seams"] = as_bytes(ctx["seams"])
        save_npz(path, arrays)

    def load(self, ctx: Context, path: Path) -> bool:
        z = load_npz(path)
        _load_maps(ctx, z)
        ctx["seams"] = from_bytes(z["seams"])
        self._derived(ctx)
        return True


def vertex_patch(mesh, face_patch: NDArray[np.int64] | None) -> NDArray[np.int64]:
    """One patch per vertex of ``mesh``: that of a face using it (``face_patch``; patch 0
    for a vertex of no labelled face), so the vertices split into shares by patch."""
    owner = np.zeros(mesh.n_vertices, dtype=np.int64)
    if face_patch is not None and len(face_patch) == mesh.n_faces:
        owner[np.asarray(mesh.faces).reshape(-1)] = np.repeat(face_patch, 3)
    return np.maximum(owner, 0)


def _moved_unbounded(before: list, after: list, bounds: list) -> list:
    """The texel bounds of the maps ``after`` stitching: a texel whose values the stitch
    changed, or every texel of a map it resampled, has none (inf); the others keep theirs
    (their displaced points are computed as before, to the bit)."""
    out = []
    for a, b, k in zip(before, after, bounds, strict=True):
        if a.values.shape != b.values.shape:
            out.append(np.full(b.values.shape[:2], np.inf, dtype=np.float32))
            continue
        moved = a.values != b.values
        moved = moved.any(axis=2) if moved.ndim == 3 else moved
        out.append(np.where(moved, np.float32(np.inf), k) if moved.any() else k)
    return out


def _early_future(ctx: Context):
    """The future of the early spline-only errors, where they were started for the spring
    grids of this run; else None."""
    if "early_spline" not in ctx:
        return None
    shapes, future = ctx["early_spline"]
    return future if shapes == [g.shape[:2] for g in ctx["grids"]] else None


def _early_result(ctx: Context):
    """The early spline-only errors (`_early_future`, waited for), or None."""
    future = _early_future(ctx)
    return None if future is None else future.result()


#: where the errors stage samples the spline-only surface (`_spline_grids`), in its key
SPLINE_SAMPLING = "spring grids"


def _spline_grids(ctx: Context) -> list:
    """Each spline at its spring grid's parameters: the spline-only surface as its errors
    measure it. Its fit saw the scan at those points alone, and they do not depend on the
    maps' resolution (matched shapes can hold twice the texels), so neither do its
    figures, and they are known before the maps are made."""
    done = _early_result(ctx)
    if done is not None:
        return done[0]
    return measure.texel_grids(ctx["surfaces"], [g.shape[:2] for g in ctx["grids"]])


class Errors(Stage):
    """Two-sided distances of the spline-only and the displaced surfaces to the input: on
    the threads of this process, or as one task per patch (:meth:`_as_tasks`)."""

    name = "errors"
    inputs = ("mesh", "displaced", "spline_grids", "map_bounds", "face_patch")
    outputs = ("errors", "spline_distance", "displaced_distance")
    after = ("stitch",)
    suffix = ".json"

    def extra(self, ctx: Context) -> Any:
        # (the sampling of the spline-only surface: a stage file measured otherwise, at the
        # maps' texels, does not stand for this one)
        return [ctx["mesh_hash"], SPLINE_SAMPLING]

    def __init__(self) -> None:
        self.tasks = False  # whether the searches ran as tasks

    def facts(self, ctx: Context) -> dict[str, Any]:
        return {"patch_tasks": self.tasks}

    def run(self, ctx: Context) -> None:
        from meshfit._malloc import release_memory

        if ctx.tasks is not None:
            self._as_tasks(ctx)
            return
        mesh, diag = ctx["mesh"], ctx["diag"]
        displaced = ctx["displaced"]
        future = _early_future(ctx)
        # the input's vertices are searched in both surfaces
        order = query_order(mesh.vertices)
        faces = measure.soup_faces([g.shape[:2] for g in displaced])
        if future is None:  # first, so one surface's soup and tree are in memory at a time
            grids = ctx["spline_grids"]
            same = [g.shape[:2] for g in grids] == [g.shape[:2] for g in displaced]
            spline = measure.spline_errors(mesh, grids, faces if same else None, order)
            release_memory()
        # (built while the spline-only searches started early may still run on their thread)
        Vd, Fd = measure.soup(displaced, faces)
        tree = grid_tree(Vd, Fd, [g.shape[:2] for g in displaced])
        if future is not None:
            spline = future.result()[1:]
        spline_fig, spline_to_input = spline
        known = np.concatenate([b.reshape(-1) for b in ctx["map_bounds"]]).astype(np.float64)
        disp_fig, _, from_input = measure.error_figures(mesh, Vd, Fd, tree, known, order)
        n = len(displaced)
        ctx["errors"] = {
            "spline_only": spline_fig,
            "displaced": disp_fig,
            "units": "fraction of the input's bbox diagonal",
            # per patch: its input vertices' largest distance to the displaced surface
            "displaced_from_input_max_per_patch": [
                None if v is None else v / diag
                for v in measure.per_patch_max(mesh, ctx["face_patch"], from_input, n)
            ],
        }
        ctx["spline_distance"] = spline_to_input
        ctx["displaced_distance"] = from_input  # (the report's heat map reads it)

    def _as_tasks(self, ctx: Context) -> None:
        """The same searches patch by patch, as tasks (:meth:`PatchTasks.errors`): each
        patch's texels in the whole scan, and its share of the scan's vertices (each vertex
        in one patch's share) in its grid and its neighbours'. The distances are those of
        :meth:`run`, to the bit: each is a least distance over the same triangles."""
        mesh, diag = ctx["mesh"], ctx["diag"]
        spline, displaced = ctx["spline_grids"], ctx["displaced"]
        n = len(displaced)
        owner = vertex_patch(mesh, ctx["face_patch"])
        tick = lambda d, k: ctx.tick(self.name, d, k)  # noqa: E731
        near = tol.KNOWN_DISTANCE * mesh.bbox_diagonal
        res = ctx.tasks.errors(mesh, owner, spline, displaced, ctx["map_bounds"], near, tick)
        self.tasks = True
        spline_from, disp_from = np.zeros(mesh.n_vertices), np.zeros(mesh.n_vertices)
        share = np.argsort(owner, kind="stable")
        cut = np.cumsum(np.bincount(owner, minlength=n))[:-1]
        for ids, r in zip(np.split(share, cut), res, strict=True):
            spline_from[ids], disp_from[ids] = r[2], r[3]
        spline_to = np.concatenate([r[0] for r in res])
        disp_to = np.concatenate([r[1] for r in res])
        d = mesh.bbox_diagonal
        ctx["errors"] = {
            "spline_only": measure.figures(spline_to, spline_from, d),
            "displaced": measure.figures(disp_to, disp_from, d),
            "units": "fraction of the input's bbox diagonal",
            "displaced_from_input_max_per_patch": [
                None if v is None else v / diag
                for v in measure.per_patch_max(mesh, ctx["face_patch"], disp_from, n)
            ],
        }
        ctx["spline_distance"] = spline_to
        ctx["displaced_distance"] = disp_from

    def save(self, ctx: Context, path: Path) -> None:
        save_npz(
            path.with_suffix(".npz"),
            {
                "spline_to_input": ctx["spline_distance"],
                "input_to_displaced": ctx["displaced_distance"],
            },
        )
        write_json(path, ctx["errors"])

    def load(self, ctx: Context, path: Path) -> bool:
        ctx["errors"] = read_json_file(path)
        dist = path.with_suffix(".npz")
        z = load_npz(dist) if dist.is_file() else {}
        ctx["spline_distance"] = z.get("spline_to_input")
        ctx["displaced_distance"] = z.get("input_to_displaced")
        return True


class Exports(Stage):
    """The chosen formats written to the output folder, after the error searches (beside
    them, the exports' arrays and the searches' add up to a dense scan's peak memory, and
    the searches already use every core), without the scan's search tree and face normals
    (of the later stages only the report reads them, and derives them again); the record
    keeps every file's hash, so a resumed run re-writes only what changed."""

    name = "exports"
    inputs = ("surfaces", "maps", "network")
    outputs = ("outputs",)
    after = ("stitch",)
    suffix = ".json"
    background = False

    def __init__(self, out: Path) -> None:
        self.out = out

    def extra(self, ctx: Context) -> Any:
        return list(ctx.options.outputs.formats)

    def prepare(self, ctx: Context) -> None:
        import importlib

        import meshfit.export  # noqa: F401 (the writers, before the thread starts)

        modules = {
            "usd": ("pxr.Usd", "pxr.UsdGeom", "pxr.Sdf", "pxr.Gf", "pxr.Vt"),
            "3dm": ("rhino3dm",),
            "step": ("OCP.Geom", "OCP.gp", "OCP.TColgp", "OCP.TColStd"),
        }
        for fmt in ctx.options.outputs.formats:
            for name in modules.get(fmt, ()):
                importlib.import_module(name)

    def run(self, ctx: Context) -> None:
        from meshfit.pipeline.outputs import output_stem, write_exports

        if "mesh" in ctx:
            _release_mesh_memory(ctx["mesh"], keep=(), search=False)
        ctx["outputs"] = write_exports(
            self.out,
            ctx["surfaces"],
            ctx["maps"],
            ctx.options.outputs.formats,
            stem=output_stem(ctx["mesh_info"]["name"]),
            network=ctx["network"],
            units=ctx.options.outputs.units,
            up_axis=ctx.options.outputs.up_axis,
            progress=lambda d, n: ctx.tick(self.name, d, n),
            notes=ctx.notes,
        )

    def save(self, ctx: Context, path: Path) -> None:
        files = [f for fs in ctx["outputs"].values() for f in fs]
        record = {"outputs": ctx["outputs"], "sha256": {f: sha_file(self.out / f) for f in files}}
        write_json(path, record)

    def load(self, ctx: Context, path: Path) -> bool:
        record = read_json_file(path)
        for f, h in record["sha256"].items():
            if not (self.out / f).is_file() or sha_file(self.out / f) != h:
                return False
        ctx["outputs"] = record["outputs"]
        return True


class Report(Stage):
    """``report.html`` and its renders (the renders are kept on a resumed run).

    With ``$MESHFIT_BLENDER_PYTHON`` set and a USD stage among the formats, the page also
    shows that stage rendered by Blender (:func:`meshfit.report.blender_renders`); the
    interpreter is part of the key, so setting or changing it renders the report again. A
    failed Blender render is a note (kept in the record, so a resumed run says it again),
    never a failed fit.
    """

    name = "report"
    inputs = ("mesh", "layout", "surfaces", "maps", "summary")
    outputs = ("report",)
    after = ("stitch", "layout")
    suffix = ".json"

    def __init__(self, out: Path) -> None:
        from meshfit.report import blender_python

        self.out = out
        self.images_ok = False
        self.blender = blender_python()

    def extra(self, ctx: Context) -> Any:
        size = ctx.options.outputs.image_size
        if self.blender is None or "usd" not in ctx.options.outputs.formats:
            return size  # the key of a report without Blender renders
        return [size, str(self.blender)]

    def load(self, ctx: Context, path: Path) -> bool:
        rec = read_json_file(path)
        self.images_ok = all((self.out / f).is_file() for f in rec["images"])
        if self.images_ok:
            ctx["summary"].setdefault("notes", []).extend(rec.get("notes", []))
            self.run(ctx)
        return self.images_ok

    def shown(self, ctx: Context) -> dict[str, Any]:
        """What the report draws the fit on: the mesh, each face's patch and the distances
        of the mesh's vertices and the spline's texels (the error searches')."""
        return {
            "mesh": ctx["mesh"],
            "face_patch": ctx["face_patch"],
            "spline_distance": ctx["spline_distance"],
            "displaced_distance": ctx["displaced_distance"],
        }

    def run(self, ctx: Context) -> None:
        from meshfit.report import ReportInputs, write_report

        shown = ReportInputs(
            grids=ctx["grids"],
            surfaces=ctx["surfaces"],
            maps=ctx["maps"],
            displaced=lambda: ctx["displaced"],
            summary=ctx["summary"],
            spline=lambda: ctx["spline_grids"],
            **self.shown(ctx),
        )
        ctx["report"] = write_report(
            self.out,
            shown,
            image_size=ctx.options.outputs.image_size,
            render_images=not self.images_ok,
            blender_python=self.blender,
        )

    def save(self, ctx: Context, path: Path) -> None:
        report = ctx["report"]
        write_json(path, {"images": report["images"], "notes": report["notes"]})


def fit_stages(layout: Any, patch_map=None, out: Path | None = None) -> list[Stage]:
    """The stages after validation, in order; with ``out`` the exports run too."""
    stages: list[Stage] = [
        Layout(layout),
        Cut(),
        Springs(patch_map),
        Fit(),
        Displacement(),
        Stitch(),
    ]
    stages.append(Errors())
    if out is not None:
        stages.append(Exports(out))
    return stages


def patch_count(ctx: Context) -> int:
    return int(ctx["layout"].n_patches)


__all__ = ["STAGES", "fit_stages", "patch_count"]
