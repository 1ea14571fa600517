"""The fit of a prepared scan: the stages that read a scan too large to hold whole.

:func:`meshfit.fit` given a folder of :func:`meshfit.pipeline.prepare.prepare_out_of_core`
(or its :class:`~meshfit.pipeline.prepare.Prepared`) runs these stages in place of those
that read the whole mesh; the fit, the stitch and the exports are the same stages. No
process holds the scan whole:

- the layout is the preparation's, made on its proxy; its corners are the carried ones;
- each spring mesh reads its patch's file (``cut/patch-<p>.npz``), on a thread or as a task;
- a map finer than its spring grid searches the patch's piece (its faces and a halo of
  about one proxy edge) rather than the whole scan;
- the errors search each patch's texels in its piece; the scan's vertices are searched a
  chunk at a time in the grids of all patches, or, as tasks, the vertices of each patch's
  core in its own grid and its neighbours';
- the report is drawn on the proxy.

A texel's closest point on the scan lies in its patch's piece wherever it is nearer than
the halo's width; so the maps and the texels' distances equal the whole scan's there, and
elsewhere (a texel farther from its patch than one proxy edge) the distance found is an
upper bound.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit.errors import InputError
from meshfit.pipeline import measure
from meshfit.pipeline.runner import Context, Stage
from meshfit.pipeline.stages import (
    Displacement,
    Errors,
    Exports,
    Report,
    Springs,
    Stitch,
    _check_classes,
    _settle_map_shapes,
    mesh_info,
    patch_displacement,
)
from meshfit.pipeline.stages import (
    Fit as FitStage,
)
from meshfit.pipeline.store import write_json

__all__ = ["ValidatePrepared", "prepared_stages"]

#: scan vertices searched at once in the errors' pass over the store on threads
VERTEX_CHUNK = 1 << 20


class ValidatePrepared(Stage):
    """The prepared scan opened (a folder, or a :class:`Prepared` given): its stores are
    memory-mapped, nothing of the scan is read whole."""

    name = "validate"
    inputs = ("input",)
    outputs = ("prepared", "mesh_info", "diag", "mesh_hash")
    suffix = None

    def key(self, ctx: Context) -> str:
        return ""

    def run(self, ctx: Context) -> None:
        from meshfit.pipeline.prepare import Prepared, open_prepared

        src = ctx["input"]
        prep = src if isinstance(src, Prepared) else open_prepared(src)
        ctx["prepared"] = prep
        ctx["mesh_info"] = mesh_info(prep.name, prep.store.n_vertices, prep.store.n_faces)
        ctx["diag"] = prep.bbox_diagonal
        ctx["mesh_hash"] = prep.sha256
        ctx.notes.append(
            f"fitted out of core from the prepared folder {prep.folder}; the report's layout "
            f"and error views are drawn on the proxy ({prep.proxy.n_faces:,} faces) the layout "
            "was made on, the figures are measured on the whole scan"
        )


class LayoutPrepared(Stage):
    """The preparation's layout (made on its proxy) and its corners carried to the scan."""

    name = "layout"
    inputs = ("prepared", "mesh_hash")
    outputs = ("layout", "corner_xyz")
    suffix = ".json"  # (a record: the layout is read from the folder either way)

    def extra(self, ctx: Context) -> Any:
        from meshfit.layout import layout_to_json
        from meshfit.pipeline.store import content_key

        return [ctx["mesh_hash"], content_key(layout_to_json(ctx["prepared"].layout))]

    def run(self, ctx: Context) -> None:
        prep = ctx["prepared"]
        ctx["layout"] = prep.layout
        ctx["corner_xyz"] = prep.corner_xyz()
        _check_classes(ctx)

    def save(self, ctx: Context, path: Path) -> None:
        write_json(path, {"patches": int(ctx["layout"].n_patches)})

    def load(self, ctx: Context, path: Path) -> bool:
        self.run(ctx)
        return True

    def facts(self, ctx: Context) -> dict[str, Any]:
        prep = ctx["prepared"]
        ctx["layout_source"] = "prepared"
        ctx["layout_report"] = {"proxy_faces": int(prep.proxy.n_faces)}
        ctx["layout_route"] = None
        return {"patches": int(prep.layout.n_patches)}


class CutPrepared(Stage):
    """The patch files of the preparation, and each input face's patch (read from the
    files' face parents when first asked)."""

    name = "cut"
    inputs = ("prepared", "layout")
    outputs = ("patch_files", "face_patch")
    after = ("layout",)
    suffix = ".json"  # (a record: the files are the folder's either way)

    def run(self, ctx: Context) -> None:
        prep = ctx["prepared"]
        ctx["patch_files"] = list(prep.patch_files)
        ctx.lazy("face_patch", lambda: face_patch(prep))

    def save(self, ctx: Context, path: Path) -> None:
        write_json(path, {"patch_files": [p.name for p in ctx["patch_files"]]})

    def load(self, ctx: Context, path: Path) -> bool:
        self.run(ctx)
        return True


def face_patch(prep) -> NDArray[np.int64]:
    """Each input face's patch (-1: a face the store dropped), from the patch files' face
    parents (a face the curves split is in several patches: the last one's)."""
    store = prep.store
    out = np.full(store.n_faces + store.dropped_faces, -1, dtype=np.int64)
    input_face = np.asarray(store.input_face)
    for p, path in enumerate(prep.patch_files):
        with np.load(path, allow_pickle=False) as z:
            out[input_face[z["face_parent"]]] = p
    return out


class SpringsPrepared(Springs):
    """A spring mesh per patch file, on threads (one file in memory per thread), as tasks,
    or through ``patch_map`` (called with :func:`spring_file_item` and ``(path, options)``
    per patch)."""

    inputs = ("patch_files",)

    def run(self, ctx: Context) -> None:
        from meshfit.pipeline.cluster import spring_file_task

        paths = [str(p) for p in ctx["patch_files"]]
        o = ctx.options.springs
        cost = [float(os.path.getsize(p)) for p in paths]
        if self.patch_map is not None:
            res = self.patch_map(spring_file_item, [(p, o) for p in paths])
        elif ctx.tasks is not None:
            tick = lambda d, n: ctx.tick(self.name, d, n)  # noqa: E731
            res = ctx.tasks.spring_files(paths, o, cost, tick)
        else:
            res = ctx.map(lambda p: spring_file_task(p, o), paths, "springs", cost)
        self.tasks = self.patch_map is not None or ctx.tasks is not None
        ctx["grids"] = [g for g, _ in res]
        ctx["spring_info"] = [i for _, i in res]


def spring_file_item(item: tuple[str, Any]):
    """``patch_map`` body of a prepared scan's spring mesh: ``item = (patch file, options)``
    (:func:`meshfit.pipeline.cluster.spring_file_task`)."""
    from meshfit.pipeline.cluster import spring_file_task

    return spring_file_task(*item)


class DisplacementPrepared(Displacement):
    """As :class:`~meshfit.pipeline.stages.Displacement`, a map finer than its spring grid
    taking its points from the patch's piece of the scan."""

    inputs = ("prepared", "network", "surfaces", "grids")

    def run(self, ctx: Context) -> None:
        from meshfit.pipeline.cluster import piece_mesh

        shapes = _settle_map_shapes(ctx)
        surfaces, grids, kind = ctx["surfaces"], ctx["grids"], ctx.options.maps.kind
        folder = ctx["prepared"].folder
        if ctx.tasks is not None:
            tick = lambda d, n: ctx.tick(self.name, d, n)  # noqa: E731
            res = ctx.tasks.maps(None, surfaces, grids, shapes, kind, tick, prepared=folder)
            self.tasks = True
        else:

            def one(p: int):
                finer = tuple(shapes[p]) != tuple(grids[p].shape[:2])
                mesh = piece_mesh(folder, p) if finer else None
                return patch_displacement(mesh, surfaces[p], grids[p], shapes[p], kind)

            cost = [float(h * w) for h, w in shapes]
            res = ctx.map(one, list(range(len(grids))), "displacement", cost)
        ctx["maps"] = [m for m, _ in res]
        ctx["map_bounds"] = [b for _, b in res]


class ErrorsPrepared(Errors):
    """As :class:`~meshfit.pipeline.stages.Errors`, patch by patch (:func:`patch_errors`, on
    threads or as tasks): each patch's texels searched in its piece; the scan's vertices a
    chunk at a time in one tree of all grids, or, as tasks, the vertices of each patch's
    core in its grid and the neighbours' that may be nearer (the same distances). The
    store's vertices no face uses are not counted."""

    inputs = ("prepared", "displaced", "spline_grids", "map_bounds", "face_patch")

    def __init__(self) -> None:
        self.tasks = False  # whether the texels were searched as tasks

    def facts(self, ctx: Context) -> dict[str, Any]:
        return {"patch_tasks": self.tasks}

    def run(self, ctx: Context) -> None:
        prep, diag = ctx["prepared"], ctx["diag"]
        displaced, spline = ctx["displaced"], ctx["spline_grids"]
        n = len(displaced)
        near = tol.KNOWN_DISTANCE * diag
        bounds = ctx["map_bounds"]
        if ctx.tasks is not None:
            tick = lambda d, k: ctx.tick(self.name, d, k)  # noqa: E731
            res = ctx.tasks.texel_errors(prep.folder, spline, displaced, bounds, near, tick)
            self.tasks = True
        else:
            grids = {"spline": spline, "displaced": displaced, "bounds": bounds}

            def one(p: int):
                return patch_errors(prep.folder, p, lambda q, k: grids[k][q], None, near)

            cost = [float(np.prod(g.shape[:2])) for g in spline]
            res = ctx.map(one, list(range(n)), "errors", cost)
        spline_to_input = np.concatenate([r[0] for r in res])
        disp_to_input = np.concatenate([r[1] for r in res])
        used, spline_from, disp_from = self._from_input(ctx, [r[2:] for r in res])
        del res
        per_patch = _per_patch_max(prep.store, ctx["face_patch"], disp_from, n)
        ctx["errors"] = {
            "spline_only": measure.figures(spline_to_input, spline_from[used], diag),
            "displaced": measure.figures(disp_to_input, disp_from[used], diag),
            "units": "fraction of the input's bbox diagonal",
            "displaced_from_input_max_per_patch": [
                None if v is None else v / diag for v in per_patch
            ],
            "searched_in": "each patch's texels in its piece of the scan (its faces and a "
            "halo); the scan's vertices in every patch's grid",
        }
        ctx["spline_distance"] = spline_to_input
        ctx["displaced_distance"] = disp_from

    def _from_input(self, ctx: Context, shares: list) -> tuple[NDArray, ...]:
        """Which store vertices a face uses, and their distances to the spline and the
        displaced grids: from the tasks' ``shares`` (each patch's core vertices, a vertex
        in several cores with the same distances in each), or on this machine a chunk of
        vertices at a time in one tree of all grids (faster here than each patch's
        neighbours' grids)."""
        prep, displaced = ctx["prepared"], ctx["displaced"]
        if self.tasks:
            used = np.zeros(prep.store.n_vertices, dtype=bool)
            spline_from = np.zeros(prep.store.n_vertices)
            disp_from = np.zeros(prep.store.n_vertices)
            for ids, s, d in shares:
                used[ids] = True
                spline_from[ids], disp_from[ids] = s, d
            return used, spline_from, disp_from
        used = _used_vertices(prep.store)
        spline = ctx["spline_grids"]
        faces = measure.soup_faces([g.shape[:2] for g in displaced])
        same = [g.shape[:2] for g in spline] == [g.shape[:2] for g in displaced]
        spline_from = _from_scan(prep.store, used, spline, faces if same else None)
        return used, spline_from, _from_scan(prep.store, used, displaced, faces)


def patch_errors(folder: Path, p: int, texels, boxes, near: float):
    """Patch ``p``'s searches for the errors of a prepared scan's fit (``folder``), all in
    its own piece of the scan and the grids near it.

    ``texels(q, kind)`` gives patch ``q``'s ``"spline"`` or ``"displaced"`` texel grid
    ``(h, w, 3)`` or its texels' ``"bounds"`` ``(h, w)``
    (:func:`meshfit.pipeline.stages.texel_bounds`). Returns the distances to the scan,
    searched in the piece, of every spline texel and of every displaced texel whose bound is
    not within ``near`` (the bound standing for the rest). With ``boxes (2, n, 2, 3)``, the
    spline and displaced grids' :func:`meshfit.pipeline.measure.grid_boxes`, also the store
    vertices of the patch's core faces and their distances to all spline grids and to all
    displaced grids (:func:`meshfit.pipeline.measure.nearest_grid_distances`: equal to a
    search of every grid at once, reading only the grids near the patch).
    """
    from meshfit.pipeline.cluster import _unchecked_mesh, piece_arrays

    V, faces, ids, core = piece_arrays(Path(folder), p)
    mesh = _unchecked_mesh(V, faces)
    s = mesh.closest_points(np.asarray(texels(p, "spline")).reshape(-1, 3)).distance
    known = np.asarray(texels(p, "bounds")).reshape(-1).astype(np.float64)
    d = known.copy()
    far = np.flatnonzero(~(known <= near))
    if far.size:
        X = np.asarray(texels(p, "displaced")).reshape(-1, 3)[far]
        d[far] = mesh.closest_points(X).distance
    if boxes is None:
        return s, d
    mine = np.unique(faces[core])
    X = V[mine]
    vs = measure.nearest_grid_distances(X, p, boxes[0], lambda q: texels(q, "spline"))
    vd = measure.nearest_grid_distances(X, p, boxes[1], lambda q: texels(q, "displaced"))
    return s, d, ids[mine], vs, vd


def _used_vertices(store) -> NDArray[np.bool_]:
    """Which of the store's vertices a face uses, a chunk of faces at a time."""
    from meshfit.mesh.store import CHUNK_FACES

    used = np.zeros(store.n_vertices, dtype=bool)
    for a in range(0, store.n_faces, CHUNK_FACES):
        used[np.asarray(store.faces[a : a + CHUNK_FACES]).reshape(-1)] = True
    return used


def _from_scan(store, used, grids: list, faces) -> NDArray[np.float64]:
    """Each used store vertex's distance to the soup of ``grids`` (0 for unused ones), a
    chunk of vertices at a time, each chunk searched in its own Morton order."""
    from meshfit._malloc import release_memory
    from meshfit.mesh.locate import grid_tree, query_order, triangle_distances

    V, F = measure.soup(grids, faces)
    tree = grid_tree(V, F, [g.shape[:2] for g in grids])
    out = np.zeros(store.n_vertices)
    for a in range(0, store.n_vertices, VERTEX_CHUNK):
        b = min(a + VERTEX_CHUNK, store.n_vertices)
        ids = a + np.flatnonzero(used[a:b])
        if ids.size:
            X = np.asarray(store.vertices[ids])
            out[ids], _ = triangle_distances(X, V, F, tree=tree, qorder=query_order(X))
    del V, F, tree
    release_memory()
    return out


def _per_patch_max(store, face_patch, value, n: int) -> list[float | None]:
    """Largest ``value`` (per store vertex) over each patch's input vertices, a chunk of
    faces at a time (as :func:`meshfit.pipeline.measure.per_patch_max`)."""
    from meshfit._kernels.geometry import label_corner_max
    from meshfit.mesh.store import CHUNK_FACES

    worst = np.full(n, -np.inf)
    value = np.ascontiguousarray(value, dtype=np.float64)
    for a in range(0, store.n_faces, CHUNK_FACES):
        f = np.ascontiguousarray(store.faces[a : a + CHUNK_FACES], dtype=np.int64)
        label = np.ascontiguousarray(face_patch[store.input_face[a : a + CHUNK_FACES]])
        worst = np.maximum(worst, label_corner_max(f, label, value, int(n)))
    return np.maximum(worst, 0.0).tolist()


class ReportPrepared(Report):
    """The report drawn on the preparation's proxy, the layout's patches coloured on it
    (the report measures the proxy's vertices itself); the figures are the whole scan's."""

    inputs = ("prepared", "layout", "surfaces", "maps", "summary")

    def shown(self, ctx: Context) -> dict[str, Any]:
        prep = ctx["prepared"]
        return {
            "mesh": prep.proxy,
            "face_patch": proxy_face_patch(prep),
            "spline_distance": None,
            "displaced_distance": None,
        }


def proxy_face_patch(prep) -> NDArray[np.int64]:
    """Each proxy face's patch under the preparation's layout."""
    from meshfit.layout import extract_patches

    out = np.full(prep.proxy.n_faces, -1, dtype=np.int64)
    for p in extract_patches(prep.proxy, prep.layout):
        out[p.face_parent] = p.index
    return out


def prepared_stages(layout: Any, patch_map=None, out: Path | None = None) -> list[Stage]:
    """The stages after validation of a prepared scan's fit; with ``out`` the exports run
    too. ``layout`` must be "auto" (the preparation's own)."""
    if not (layout is None or (isinstance(layout, str) and layout == "auto")):
        raise InputError(
            "a prepared scan is fitted with the layout it was prepared with: give "
            "layout='auto' (prepare again for another layout)"
        )
    stages: list[Stage] = [
        LayoutPrepared(),
        CutPrepared(),
        SpringsPrepared(patch_map),
        FitStage(),
        DisplacementPrepared(),
        Stitch(),
        ErrorsPrepared(),
    ]
    if out is not None:
        stages.append(Exports(out))
    return stages
