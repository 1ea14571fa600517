"""The fit report: ``report.html`` with a 3D view, headless renders and tables.

In ``<out>/report/``: an interactive 3D view of the displaced surface coloured by its
deviation from the scan (:mod:`meshfit.report_view`: a GLB drawn by a three.js bundle shipped
with the package, offline from ``file://``); 8-bit PNG renders (:mod:`meshfit.render`) from
four fixed viewpoints, for print, of the patch layout on the input with patch numbers and of
heat maps of the spline-only and the displaced surfaces' deviation, each with its colour bar
in percent of the bbox diagonal; the spring meshes as a checkerboard (one square per grid
cell), the spline-only and the displaced surface; each patch's displacement map as its image
file shows it (x along u, y up along v; a vector map's T, N, B components as R, G, B;
mid-grey = 0), each on its own scale, printed under it. Figures beyond the bounds of
:mod:`meshfit.report_bounds` are listed with the reason and marked in the tables.

With Blender's Python at hand (``$MESHFIT_BLENDER_PYTHON``, an interpreter that imports
``bpy``) and a USD stage among the fit's outputs, the page also shows that stage as Blender
imports it, rendered with Cycles with its displacement on and off
(:func:`blender_renders`): what a user opening the deliverable in Blender gets.
"""

from __future__ import annotations

import html
import json
import os
import subprocess
import tempfile
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit._atomic import write_bytes, write_text
from meshfit.errors import RenderError
from meshfit.mesh.measures import up_axis
from meshfit.render import (
    HEAT_COLORS,
    HEAT_STOPS,
    Camera,
    heat_colors,
    patch_colors,
    render,
    write_png_rgb,
)
from meshfit.report_bounds import beyond_bounds
from meshfit.report_view import (
    View,
    copy_static,
    deviation_glb,
    fixed_views,
    in_sight,
    near_max,
    pool_max,
    thin_indices,
    write_model,
)

__all__ = [
    "BLENDER_IMAGES",
    "BLENDER_PYTHON_ENV",
    "BLENDER_SCRIPT",
    "REPORT_IMAGES",
    "VIEW_NAMES",
    "VIEW_ROWS",
    "ReportInputs",
    "blender_python",
    "blender_renders",
    "model_view",
    "report_images",
    "usd_layer",
    "write_html",
    "write_report",
]

#: the renders of the report from its main view, in order: (file stem, caption)
REPORT_IMAGES = (
    ("springs", "spring meshes (checkerboard: one square per grid cell)"),
    ("spline", "spline-only surface"),
    ("displaced", "displaced surface (spline + displacement maps)"),
)
#: the rows of renders from the fixed viewpoints (:func:`meshfit.report_view.fixed_views`),
#: in order: (file stem before ``_<view>``, caption)
VIEW_ROWS = (
    ("layout", "Patch layout on the input mesh, with patch numbers"),
    ("error_spline", "Spline-only surface: its distance to the scan"),
    (
        "error_displaced",
        "Displaced surface: the scan's distance to it (each vertex shows the largest "
        "distance of the scan points nearest to it)",
    ),
)
#: names of the fixed viewpoints, in order
VIEW_NAMES = ("front", "right", "back", "left")
#: smallest side of the fixed viewpoints' images, pixels
VIEW_MIN_SIZE = 120
#: the surfaces of the renders are grids thinned to at most about this many points per
#: pixel of the main render: the rasteriser keeps one triangle per pixel, so a finer grid
#: costs memory and time (at the density of a dense scan's maps) and draws no more
RENDER_POINTS_PER_PIXEL = 2
#: the page's own data (scales, viewpoints, labels) beside the images, for a resumed run
PAGE_FILE = "page.json"
#: the columns of the report's patch table
PATCH_COLUMNS = [
    "patch",
    "shape",
    "levels",
    "folded",
    "arc_cv_max",
    "aspect_max",
    "corner_angles",
    "controls",
    "fit_parametric_rms",
    "fit_parametric_max",
    "displacement_max",
    "input_distance_max",
    "seconds",
]

#: the environment variable naming Blender's Python, an interpreter that imports ``bpy``
#: (Blender's module pins its own Python and numpy, so it lives in a virtualenv of its own)
BLENDER_PYTHON_ENV = "MESHFIT_BLENDER_PYTHON"
#: the script Blender's Python runs (a resource of the package: meshfit never imports it)
BLENDER_SCRIPT = Path(__file__).with_name("report_blender.py")
#: the Blender renders of the USD layer, in order: (file stem, the script's variant, what
#: the caption says)
BLENDER_IMAGES = (
    ("blender_displaced", "displaced", "displacement on"),
    ("blender_plain", "plain", "displacement off"),
)
#: Blender renders: largest image side (pixels), Cycles samples, levels of the Simple
#: subdivision that gives the displacement vertices between the texels, and the seconds the
#: interpreter is given for both renders before the report goes on without them
BLENDER_MAX_SIZE = 320
BLENDER_SAMPLES = 8
BLENDER_SUBDIVISION = 1
BLENDER_TIMEOUT = 300.0
#: lines of the renderer's stderr a RenderError quotes
_STDERR_LINES = 6
#: file suffixes of a USD stage
_USD_SUFFIXES = (".usd", ".usda", ".usdc")


def blender_python() -> Path | None:
    """The interpreter ``$MESHFIT_BLENDER_PYTHON`` names, or None where the variable is unset
    or empty: the report renders with Blender only when the user points it at one."""
    value = os.environ.get(BLENDER_PYTHON_ENV, "").strip()
    return Path(value).expanduser() if value else None


def usd_layer(summary: dict[str, Any]) -> str | None:
    """The USD stage among a fit's outputs (``summary["outputs"]["usd"]``, beside its map
    images), relative to the fit folder; None when the fit wrote none."""
    files = summary.get("outputs", {}).get("usd", [])
    return next((f for f in files if Path(f).suffix.lower() in _USD_SUFFIXES), None)


def blender_renders(
    folder: str | os.PathLike,
    layer: str | os.PathLike,
    *,
    python: str | os.PathLike,
    size: int,
    view: Any,
    up: Any = None,
    timeout: float = BLENDER_TIMEOUT,
) -> list[str]:
    """Render a USD layer with Blender (Cycles on the CPU), displacement on and off.

    Runs :data:`BLENDER_SCRIPT` with ``python`` in a subprocess (Blender's module cannot
    share this interpreter: it pins its own Python and numpy), the spec in a temporary
    file. Both renders share one orthographic camera round the mesh, a sun and a dim sky;
    the material is the one the import builds from the layer's ``UsdPreviewSurface``, its
    displacement method "Displacement Only", on a Simple subdivision of the mesh
    (:data:`BLENDER_SUBDIVISION`) at :data:`BLENDER_SAMPLES` samples. The images are
    written only once both are made, so a failure leaves none behind.

    Parameters
    ----------
    folder : path
        The fit folder: the images go to ``folder/report/``.
    layer : path
        The USD layer (relative to ``folder`` unless absolute); the maps it references are
        read from where it says.
    python : path
        An interpreter that imports ``bpy``.
    size : int
        Width and height of the images, pixels.
    view : (3,) float
        Viewing direction in the layer's coordinates (e.g. :func:`model_view`'s).
    up : (3,) float, optional
        Direction shown upwards, in the layer's coordinates (default: the stage's up axis).
    timeout : float
        Seconds allowed for both renders.

    Returns
    -------
    list of str
        ``report/<stem>.png`` of each of :data:`BLENDER_IMAGES`, relative to ``folder``.

    Raises
    ------
    RenderError
        The interpreter is missing or exits non-zero (the message ends with its last lines
        of stderr), the renders take longer than ``timeout``, or an image is missing.
    """
    folder = Path(folder)
    layer = (folder / layer).absolute()
    python = Path(python)
    if not python.is_file():
        raise RenderError(f"no Blender Python at {python} (${BLENDER_PYTHON_ENV})")
    (folder / "report").mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="meshfit-blender-") as tmp:
        spec = {
            "out": tmp,
            "size": int(size),
            "samples": BLENDER_SAMPLES,
            "view": [float(x) for x in view],
            "subdivision": BLENDER_SUBDIVISION,
            "renders": [[stem, str(layer), variant] for stem, variant, _ in BLENDER_IMAGES],
        }
        if up is not None:
            spec["up"] = [float(x) for x in up]
        spec_file = Path(tmp) / "spec.json"
        spec_file.write_text(json.dumps(spec))
        # run from a copy: Python puts a script's folder first on its path, and the
        # package's own modules (``types``) would shadow the standard library's
        script = Path(tmp) / BLENDER_SCRIPT.name
        script.write_bytes(BLENDER_SCRIPT.read_bytes())
        # the caller's module path would put this interpreter's packages (numpy 2) before
        # Blender's own
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        cmd = [str(python), str(script), str(spec_file)]
        try:
            res = subprocess.run(
                cmd, env=env, capture_output=True, text=True, timeout=timeout,
                stdin=subprocess.DEVNULL, check=False,
            )  # fmt: skip
        except subprocess.TimeoutExpired:
            raise RenderError(
                f"Blender render of {layer.name} with {python} took longer than {timeout:g} s"
            ) from None
        except OSError as exc:
            raise RenderError(f"cannot run Blender Python {python}: {exc}") from None
        if res.returncode != 0:
            tail = (res.stderr or res.stdout or "").strip().splitlines()[-_STDERR_LINES:]
            raise RenderError(
                f"Blender render of {layer.name} with {python} failed (exit {res.returncode})"
                + "".join(f"\n  {line}" for line in tail)
            )
        made = [Path(tmp) / f"{stem}.png" for stem, _, _ in BLENDER_IMAGES]
        for f in made:
            if not f.is_file():
                raise RenderError(f"Blender render of {layer.name} with {python} wrote no {f.name}")
        for f in made:
            write_bytes(folder / "report" / f.name, f.read_bytes())
    return [f"report/{stem}.png" for stem, _, _ in BLENDER_IMAGES]


def model_view(vertices: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """View direction and up vector of the report's images.

    Up is +y (the convention of PLY, OBJ and glTF), or +z where the model is much taller
    along z than along y (:func:`meshfit.mesh.measures.up_axis`). The camera looks along
    the horizontal axis of least spread, turned slightly towards the other one (a slightly
    oblique view shows relief better than a straight one): a scanned figure or head is seen
    upright from its broader side, a bust in profile.

    Parameters
    ----------
    vertices : (n, 3) float64
        The model's vertices.

    Returns
    -------
    view : (3,) float64
        Viewing direction (from the camera into the scene), horizontal.
    up : (3,) float64
        Unit vector shown upwards: +y or +z.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 7.6 (the fitted and displaced models shown as renders).
    """
    V = np.asarray(vertices, dtype=np.float64)
    up = np.array([0.0, 0.0, 1.0]) if up_axis(V) == "z" else np.array([0.0, 1.0, 0.0])
    x = V - V.mean(axis=0) if len(V) else np.zeros((1, 3))
    flat = x - np.outer(x @ up, up)  # the horizontal spread
    w, vecs = np.linalg.eigh(flat.T @ flat)
    # of the three axes, the one along ``up`` carries no horizontal spread: drop it
    horizontal = [vecs[:, i] for i in np.argsort(w) if abs(vecs[:, i] @ up) < 0.5]
    if len(horizontal) < 2:  # no horizontal spread (a point, a vertical segment)
        side = np.array([1.0, 0.0, 0.0])
        horizontal = [side, np.cross(up, side)]
    view = horizontal[0] + 0.35 * horizontal[1]
    return view, up


def _grid_soup(grids: list[NDArray[np.float64]], topology: dict | None = None):
    """Vertices, triangles, patch of each triangle and (u, v) of each vertex of the grids.

    ``topology`` (a dict) keeps the triangles, patches and (u, v) per list of grid shapes,
    for the next call with the same shapes.
    """
    from meshfit.springs import grid_triangles

    V = _grid_points(grids)
    shapes = tuple(X.shape[:2] for X in grids)
    if topology is not None and shapes in topology:
        return (V, *topology[shapes])
    F, P, UV, base = [], [], [], 0
    for p, (nu, nv) in enumerate(shapes):
        f = grid_triangles(nu, nv)
        F.append(f + base)
        P.append(np.full(f.shape[0], p))
        i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
        UV.append(np.stack([i.ravel() + 0.01, j.ravel() + 0.01], axis=1).astype(np.float64))
        base += nu * nv
    rest = (np.vstack(F), np.concatenate(P), np.vstack(UV))
    if topology is not None:
        topology[shapes] = rest
    return (V, *rest)


def _hull_points(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """The points of ``points`` on their convex hull: a camera framing them frames all of
    them the same (the extremes of a projection lie on the hull), from far fewer points."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):  # flat or too few points: frame them all
        return points


def _map_image(values: NDArray[np.float64], scale: float) -> NDArray[np.uint8]:
    """A displacement map as an 8-bit RGB image, 0 at mid-grey, +-scale at the ends."""
    c = values if values.shape[2] == 3 else np.repeat(values, 3, axis=2)
    t = 0.5 + 0.5 * np.clip(c / scale, -1.0, 1.0) if scale > 0 else np.full(c.shape, 0.5)
    return np.rint(t * 255.0).astype(np.uint8)


@dataclass(frozen=True, eq=False)
class ReportInputs:
    """What :func:`write_report` shows of a fit.

    Attributes
    ----------
    mesh : Mesh
        The input.
    grids : list of (nu, nv, 3) float64
        Spring meshes.
    surfaces : list of BSplineSurface
    maps : list of DisplacementMap
    displaced : list of (nu, nv, 3) float64, or a callable returning it
        Displaced reconstructions (a callable is called only when images are rendered).
    summary : dict
        The fit summary (tables); ``report_images`` and the map and error scales are added
        to it.
    face_patch : (nf,) int64, optional
        Patch of each input face (from the cut); None draws the input in one grey.
    spline : list of (nu, nv, 3) float64, or a callable returning it, optional
        Each surface evaluated at its spring grid's parameters, when already computed;
        default evaluated here.
    spline_distance : (n,) float64, optional
        Distance of each spline-only grid vertex (patches in order, row-major) to the input,
        model units, when already measured; default measured here.
    displaced_distance : (nv,) float64, optional
        Distance of each input vertex to the displaced surface (its grids as triangle
        pairs), model units, when already measured (the fit's error figures); default
        measured here.
    """

    mesh: Any
    grids: list[NDArray[np.float64]]
    surfaces: list
    maps: list
    displaced: Callable[[], list[NDArray[np.float64]]] | list[NDArray[np.float64]]
    summary: dict[str, Any]
    face_patch: NDArray[np.int64] | None = None
    spline: Callable[[], list[NDArray[np.float64]]] | list[NDArray[np.float64]] | None = None
    spline_distance: NDArray[np.float64] | None = None
    displaced_distance: NDArray[np.float64] | None = None


def _view_size(image_size: int) -> int:
    """Side of the fixed viewpoints' images: half the main renders', four to a row."""
    return max(VIEW_MIN_SIZE, int(image_size) // 2)


def _deviations(fit: ReportInputs, spline, disp) -> tuple[NDArray, NDArray]:
    """Deviation from the scan at each spline-only and each displaced grid vertex (the
    grids ``spline`` and ``disp``, one row of the result per vertex in grid order), model
    units: the spline's own distance to the scan, and for the displaced surface (which
    passes through scan points at its vertices) the scan's distance to it, carried to the
    nearest vertices (:func:`meshfit.report_view.near_max`)."""
    from meshfit.mesh.locate import grid_tree, triangle_distances

    mesh = fit.mesh
    dist = fit.spline_distance
    if dist is None or len(dist) != sum(g.shape[0] * g.shape[1] for g in spline):
        dist = mesh.closest_points(_grid_points(spline)).distance
    Vd = _grid_points(disp)
    if len(Vd):
        from_input = fit.displaced_distance
        if from_input is None or len(from_input) != mesh.n_vertices:
            shapes = [d.shape[:2] for d in disp]
            _, Fd, _, _ = _grid_soup(disp)
            from_input, _ = triangle_distances(
                mesh.vertices, Vd, Fd, tree=grid_tree(Vd, Fd, shapes)
            )
        dev = near_max(Vd, mesh.vertices, from_input)
    else:
        dev = np.zeros(0)
    return np.asarray(dist, dtype=np.float64), dev


def _grid_points(grids: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """The points of ``grids`` as one (n, 3) array, in grid order."""
    return np.concatenate([X.reshape(-1, 3) for X in grids]) if grids else np.zeros((0, 3))


def _render_step(grids: list[NDArray[np.float64]], pixels: int) -> int:
    """The thinning step of grids drawn on an image of ``pixels`` pixels: at most about
    `RENDER_POINTS_PER_PIXEL` grid points per pixel."""
    total = sum(g.shape[0] * g.shape[1] for g in grids)
    return max(1, int(np.ceil(np.sqrt(total / (RENDER_POINTS_PER_PIXEL * max(pixels, 1))))))


def _thinned(
    grids: list[NDArray[np.float64]], step: int, values: NDArray[np.float64] | None = None
) -> tuple[list[NDArray[np.float64]], NDArray[np.float64]]:
    """Every ``step``-th row and column of each grid (`thin_indices`), and ``values`` (one
    per grid vertex, in grid order) pooled to the largest around each kept vertex
    (`pool_max`) and thinned alike (empty when ``values`` is None)."""
    out, kept, base = [], [], 0
    for G in grids:
        nu, nv = G.shape[:2]
        rows, cols = thin_indices(nu, nv, step)
        out.append(G[np.ix_(rows, cols)])
        if values is not None:
            v = values[base : base + nu * nv].reshape(nu, nv)
            kept.append(pool_max(v, step)[np.ix_(rows, cols)].reshape(-1))
        base += nu * nv
    return out, (np.concatenate(kept) if kept else np.zeros(0))


def _top(values: NDArray[np.float64]) -> float:
    """The heat map's red end: the 99th percentile, so that a few outliers do not wash the
    rest out (they show red)."""
    return float(np.quantile(values, 0.99)) if values.size else 0.0


def _labels(points, camera: Camera, depth, slack: float) -> list[list[float]]:
    """``[patch, x %, y %]`` of each patch label in sight on a render."""
    if not len(points):
        return []
    xy, visible = in_sight(points, camera, depth, slack)
    w, h = camera.size
    return [
        [int(p), round(100 * xy[p, 0] / w, 2), round(100 * xy[p, 1] / h, 2)]
        for p in np.flatnonzero(visible)
    ]


def _render_views(fit: ReportInputs, folder: Path, size: int, view, up, page: dict) -> None:
    """Draw every render and map image; the jobs' images go to ``folder``. Fills ``page``
    (the scales, viewpoints, labels, model and viewer files the page refers to)."""
    mesh, grids, dmaps = fit.mesh, fit.grids, fit.maps
    diag = mesh.bbox_diagonal
    bounds = _hull_points(mesh.vertices[:: max(1, mesh.n_vertices // 20000)])
    camera = Camera(size=(size, size), view=tuple(view), up=tuple(up), bounds=bounds)
    vsize = _view_size(size)
    views = fixed_views(view, up)
    cams = [Camera(size=(vsize, vsize), view=v.view, up=v.up, bounds=bounds) for v in views]
    face_patch = fit.face_patch
    if face_patch is None:
        face_patch = np.full(mesh.n_faces, -1, dtype=np.int64)
    layout_colors = patch_colors(face_patch)
    # the surfaces are drawn thinned to the largest render's pixels; the figures, the heat
    # map's scale and the model come from every grid vertex
    V, F, P, UV = _grid_soup(_thinned(grids, _render_step(grids, size * size))[0])
    cols = patch_colors(P)
    vcol = np.zeros((V.shape[0], 3))
    for k in range(3):
        vcol[F[:, k]] = cols
    spline = fit.spline
    if spline is None:
        spline = [
            s.evaluate_grid(np.linspace(0, 1, g.shape[0]), np.linspace(0, 1, g.shape[1]))
            for s, g in zip(fit.surfaces, grids, strict=True)
        ]
    spline = spline() if callable(spline) else spline
    disp = fit.displaced() if callable(fit.displaced) else fit.displaced
    dist, dev = _deviations(fit, spline, disp)
    top_s, top_d = _top(dist), _top(dev)
    topology: dict = {}  # the thinned splines and displaced grids share their triangles
    spline_drawn, dist_drawn = _thinned(spline, _render_step(spline, size * size), dist)
    Vs, Fs, _, _ = _grid_soup(spline_drawn, topology)
    disp_drawn, dev_drawn = _thinned(disp, _render_step(disp, size * size), dev)
    Vd, Fd, _, _ = _grid_soup(disp_drawn, topology)
    del spline_drawn, disp_drawn
    page["error_scale"] = {"spline": top_s / diag, "displaced": top_d / diag}
    page["error_max"] = {
        "spline": float(dist.max()) / diag if dist.size else 0.0,
        "displaced": float(dev.max()) / diag if dev.size else 0.0,
    }
    page["views"] = [{"name": v.name, "view": list(v.view), "up": list(v.up)} for v in views]
    heat_s, heat_d = heat_colors(dist_drawn, top_s), heat_colors(dev_drawn, top_d)

    jobs: dict[str, Callable[[], NDArray[np.uint8]]] = {
        "springs": lambda: render(
            V, F, camera=camera, vertex_colors=vcol, uv=UV, checker=1.0, shading="flat"
        ),
        "spline": lambda: render(Vs, Fs, camera=camera),
        "displaced": lambda: render(Vd, Fd, camera=camera),
    }
    label_points = np.array([g[g.shape[0] // 2, g.shape[1] // 2] for g in grids]).reshape(-1, 3)
    page["labels"] = {}

    def layout_view(v: View, cam: Camera) -> NDArray[np.uint8]:
        depth = np.empty((vsize, vsize))
        img = render(
            mesh.vertices, mesh.faces, face_colors=layout_colors, shading="flat", camera=cam,
            depth_out=depth,
        )  # fmt: skip
        page["labels"][f"layout_{v.name}"] = _labels(label_points, cam, depth, 0.01 * diag)
        return img

    for v, cam in zip(views, cams, strict=True):
        jobs[f"layout_{v.name}"] = lambda v=v, cam=cam: layout_view(v, cam)
        jobs[f"error_spline_{v.name}"] = lambda cam=cam: render(
            Vs, Fs, camera=cam, vertex_colors=heat_s
        )
        jobs[f"error_displaced_{v.name}"] = lambda cam=cam: render(
            Vd, Fd, camera=cam, vertex_colors=heat_d
        )
    # each map on its own scale: its largest displacement is full scale
    scales = [float(np.abs(d.values).max()) if d.values.size else 0.0 for d in dmaps]
    page["map_scales"] = [x / diag for x in scales]

    def map_png(p: int) -> None:
        d = dmaps[p]
        # the channels in the files' order: a vector map's T, N, B as R, G, B
        img = _map_image(d.values[..., [0, 2, 1]] if d.kind == "vector" else d.values, scales[p])
        # rows along v, columns along u, magnified to at least 128 pixels
        img = np.transpose(img, (1, 0, 2))[::-1]
        k = max(1, -(-128 // max(img.shape[:2])))
        img = np.repeat(np.repeat(img, k, axis=0), k, axis=1)
        write_png_rgb(folder / f"map_{p:03d}.png", img)

    deviation = []
    base = 0
    for D in disp:
        n = D.shape[0] * D.shape[1]
        deviation.append(100.0 * dev[base : base + n].reshape(D.shape[:2]) / diag)
        base += n
    glb = deviation_glb(disp, deviation, 100.0 * top_d / diag)
    page["model"] = write_model(folder, glb)
    page["static"] = copy_static(folder)
    # the rasteriser and zlib run without the GIL: the images are made side by side
    with ThreadPoolExecutor(max_workers=max(1, min(len(jobs), os.cpu_count() or 1))) as pool:
        futures = {stem: pool.submit(job) for stem, job in jobs.items()}
        maps = [pool.submit(map_png, p) for p in range(len(dmaps))]
        for stem, fut in futures.items():
            write_png_rgb(folder / f"{stem}.png", fut.result())
        for fut in maps:
            fut.result()


def report_images(n_patches: int) -> list[str]:
    """The images of a report of ``n_patches`` patches (relative to the fit folder), in
    the page's order: the fixed viewpoints of :data:`VIEW_ROWS`, :data:`REPORT_IMAGES`, the
    maps."""
    names = [f"layout_{v}" for v in VIEW_NAMES]
    names += [f"{row}_{v}" for row, _ in VIEW_ROWS[1:] for v in VIEW_NAMES]
    names += [stem for stem, _ in REPORT_IMAGES]
    names += [f"map_{p:03d}" for p in range(n_patches)]
    return [f"report/{n}.png" for n in names]


def write_report(
    out: str | os.PathLike,
    fit: ReportInputs,
    *,
    image_size: int = 640,
    render_images: bool = True,
    blender_python: str | os.PathLike | None = None,
) -> dict[str, Any]:
    """Render the report images, write its 3D model and ``report.html``.

    Parameters
    ----------
    out : path
        The fit's output folder; images, the model and the viewer go to ``out/report/``.
    fit : ReportInputs
        What is shown; its ``summary`` gets ``report_images`` and ``report_page`` (scales,
        viewpoints, patch labels: what the page prints besides the summary) added.
    image_size : int
        Width and height of the main renders, pixels; the fixed viewpoints are half that.
    render_images : bool
        False re-uses the files already in ``out/report`` (resume) and only rewrites the
        page, from the ``page.json`` written beside them (the Blender renders are shown
        where both files are there).
    blender_python : path, optional
        Blender's Python (e.g. :func:`blender_python`): where the summary lists a USD stage
        among the outputs (:func:`usd_layer`) and it is in ``out``, the page also shows it
        rendered by Blender (:func:`blender_renders`, at most :data:`BLENDER_MAX_SIZE`
        pixels, the main renders' view). A failed or timed-out render adds a note to the
        summary instead; the report is written without it. Default None: no Blender.

    Returns
    -------
    dict
        ``images``: the files of the report relative to ``out`` (images, model, viewer);
        ``notes``: the notes added to the summary.
    """
    mesh, summary = fit.mesh, fit.summary
    out = Path(out)
    folder = out / "report"
    folder.mkdir(parents=True, exist_ok=True)
    images = report_images(len(fit.grids))
    layer = usd_layer(summary) if blender_python is not None else None
    if layer is not None and not (out / layer).is_file():
        layer = None
    notes: list[str] = []
    page: dict[str, Any] = {}
    if not render_images:
        if (folder / PAGE_FILE).is_file():
            page = json.loads((folder / PAGE_FILE).read_text())
        if layer is not None:
            shown = [f"report/{stem}.png" for stem, _, _ in BLENDER_IMAGES]
            images += shown if all((out / f).is_file() for f in shown) else []
    else:
        view, up = model_view(mesh.vertices)
        blender = None
        if layer is not None and blender_python is not None:
            # Blender works in its own process: it renders while the images below are made
            side = ThreadPoolExecutor(max_workers=1)
            blender = side.submit(
                blender_renders, out, layer, python=blender_python, view=view, up=up,
                size=min(int(image_size), BLENDER_MAX_SIZE),
            )  # fmt: skip
            side.shutdown(wait=False)  # its thread ends with the render
        _render_views(fit, folder, int(image_size), view, up, page)
        write_text(folder / PAGE_FILE, json.dumps(page))
        if blender is not None:
            images += _blender_result(blender, layer, notes)
            summary.setdefault("notes", []).extend(notes)
    files = [f"report/{f}" for f in (*page.get("model", ()), *page.get("static", ()))]
    summary["report_images"] = images
    summary["report_page"] = page
    write_html(out, summary)
    return {"images": [*images, *files, f"report/{PAGE_FILE}"], "notes": notes}


def _blender_result(future: Future, layer: str | None, notes: list[str]) -> list[str]:
    """The Blender renders' images, or none and a note saying why: the report is complete
    without them, so their failure is reported, not raised."""
    try:
        return future.result()
    except RenderError as exc:
        reason = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
        notes.append(f"the report has no Blender render of {layer}: {reason}")
        return []


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return " x ".join(_fmt(x) for x in v) if len(v) <= 3 else " ".join(_fmt(x) for x in v)
    return html.escape(str(v))


def _table(
    rows: list[dict[str, Any]],
    columns: list[str] | None = None,
    flagged: dict[tuple[int, str], int] | None = None,
) -> str:
    """An HTML table; ``flagged`` maps (row, column) to the number of the reason that
    value is beyond its bound (:func:`_flag_list`): the cell is marked and points to it."""
    if not rows:
        return "<p>none</p>"
    columns = columns or list(rows[0])
    flagged = flagged or {}
    head = "".join(f"<th>{html.escape(c.replace('_', ' '))}</th>" for c in columns)
    body = []
    for i, r in enumerate(rows):
        cells = []
        for c in columns:
            k = flagged.get((i, c))
            if k is None:
                cells.append(f"<td>{_fmt(r.get(c, ''))}</td>")
            else:
                cells.append(
                    f"<td class='beyond' title='beyond bound: see note {k}'>"
                    f"{_fmt(r.get(c, ''))} <a href='#beyond-{k}'>[{k}]</a></td>"
                )
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _pct(x: float) -> str:
    return f"{100 * x:.3g}%"


def _legend(top: float, peak: float) -> str:
    """The heat map's colour bar, 0 to ``top`` (fractions of the diagonal), and the
    largest value shown (red beyond ``top``)."""
    stops = ", ".join(
        f"rgb({', '.join(str(round(255 * c)) for c in col)}) {100 * s:g}%"
        for s, col in zip(HEAT_STOPS, HEAT_COLORS, strict=True)
    )
    return (
        f"<div class='legend'><span>0</span><span class='bar' style='background:"
        f"linear-gradient(to right, {stops})'></span><span>{_pct(top)} of the bbox diagonal"
        f" and above</span> <span class='note'>(largest: {_pct(peak)})</span></div>"
    )


def _flag_list(summary: dict[str, Any]) -> tuple[str, dict[str, dict[tuple[int, str], int]]]:
    """The section listing values beyond the bounds (with their reasons), and for each
    table (``errors``, ``seams``, ``patches``) the cells to mark with their note numbers."""
    flags = beyond_bounds(summary)
    marks: dict[str, dict[tuple[int, str], int]] = {"errors": {}, "seams": {}, "patches": {}}
    if not flags:
        return (
            "<p class='ok'>Every figure below is within the report's bounds "
            "(<code>meshfit.report_bounds.BOUNDS</code>).</p>",
            marks,
        )
    items = []
    for k, f in enumerate(flags, start=1):
        where = f.key.replace("_", " ")
        if f.section == "patches":
            where = f"patch {f.row}: {where}"
            marks["patches"][(f.row if f.row is not None else 0, f.key)] = k
        elif f.section.startswith("errors."):
            surface = f.section.split(".", 1)[1]
            where = f"{surface.replace('_', ' ')} surface: {where}"
            row = 0 if surface == "spline_only" else 1
            marks["errors"][(row, f.key)] = k
        else:
            marks["seams"][(0, f.key)] = k
        items.append(
            f"<li id='beyond-{k}'><b>{html.escape(where)} = {_fmt(f.value)}</b>: "
            f"{html.escape(f.reason)}</li>"
        )
    return (
        "<div class='alarm'><h2>Beyond the bounds</h2><p>These figures lie beyond what a "
        "sound fit stays within; they are marked in the tables below.</p><ol>"
        + "".join(items)
        + "</ol></div>",
        marks,
    )


def _view3d(summary: dict[str, Any], page: dict[str, Any]) -> list[str]:
    """The interactive 3D view (screen only; the fixed viewpoints below print)."""
    if not page.get("model"):
        return []
    views = page.get("views", [])
    buttons = "".join(
        f"<button type='button' data-view='{k}'>{html.escape(v['name'])}</button>"
        for k, v in enumerate(views)
    )
    scale = page.get("error_scale", {}).get("displaced", 0.0)
    peak = page.get("error_max", {}).get("displaced", 0.0)
    return [
        "<section class='screen-only'><h2>3D view: displaced surface, deviation from the scan</h2>",
        "<p>Drag to turn, wheel to zoom, right-drag to pan; the buttons go to the fixed "
        "viewpoints printed below. The pointer shows the patch and the deviation under it. "
        "<i>save model.glb</i> saves the model (glTF, deviation as vertex colours and as "
        "the <code>_DEVIATION</code> attribute, percent of the bbox diagonal).</p>",
        f"<div id='view3d' data-views='{html.escape(json.dumps(views))}' "
        "data-background='#ffffff'><canvas></canvas>"
        f"<div class='view3d-bar'>{buttons}<button type='button' class='view3d-save'>save "
        "model.glb</button><span class='view3d-readout'></span></div>"
        "<p class='view3d-status'>3D view loading...</p></div>",
        _legend(scale, peak),
        "</section>",
    ]


def _view_rows(summary: dict[str, Any], page: dict[str, Any], images: list[str]) -> list[str]:
    """The fixed viewpoints: one row of images per :data:`VIEW_ROWS` entry, patch numbers
    over the layout's, a colour bar under each heat map's."""
    have = set(images)
    names = [v["name"] for v in page.get("views", [])] or list(VIEW_NAMES)
    scale = page.get("error_scale", {})
    peak = page.get("error_max", {})
    labels = page.get("labels", {})
    parts = ["<h2>Fixed viewpoints</h2>"]
    for row, caption in VIEW_ROWS:
        shown = [(n, f"report/{row}_{n}.png") for n in names if f"report/{row}_{n}.png" in have]
        if not shown:
            continue
        parts.append(f"<div class='viewrow'><h3>{html.escape(caption)}</h3><div class='pics'>")
        for name, img in shown:
            tags = "".join(
                f"<span class='tag' style='left:{x}%;top:{y}%'>{p}</span>"
                for p, x, y in labels.get(f"{row}_{name}", [])
            )
            parts.append(
                f"<figure><div class='pic'><img src='{html.escape(img)}'>{tags}</div>"
                f"<figcaption>{html.escape(name)}</figcaption></figure>"
            )
        parts.append("</div>")
        kind = row.removeprefix("error_")
        if kind in scale:
            parts.append(_legend(scale[kind], peak.get(kind, 0.0)))
        if row == "layout" and labels:
            seen = {p for tags in labels.values() for p, _, _ in tags}
            hidden = [p for p in range(summary.get("patches_total", 0)) if p not in seen]
            if hidden:
                parts.append(
                    "<p class='note'>Not in sight from these viewpoints (use the 3D view): "
                    f"patches {', '.join(map(str, hidden))}.</p>"
                )
        parts.append("</div>")
    return parts


_STYLE = (
    "body{font-family:sans-serif;margin:2em;max-width:1400px}"
    "table{border-collapse:collapse;margin:1em 0;font-size:13px}"
    "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
    "td.beyond{background:#fde0dc;color:#a00;font-weight:bold}"
    ".alarm{border:2px solid #c00;background:#fff4f2;padding:0.2em 1em;margin:1em 0}"
    ".alarm h2{color:#a00;margin:0.4em 0}.ok{color:#060}"
    "figure{display:inline-block;margin:0.5em;vertical-align:top}"
    "figcaption{font-size:13px;max-width:420px}"
    ".viewrow .pics{display:grid;grid-template-columns:repeat(4,1fr);gap:0.5em;max-width:1300px}"
    ".viewrow figure{margin:0}.viewrow img{width:100%;display:block}"
    ".pic{position:relative}"
    ".tag{position:absolute;transform:translate(-50%,-50%);font:bold 11px sans-serif;"
    "background:rgba(255,255,255,0.85);border:1px solid #333;border-radius:3px;"
    "padding:0 2px;color:#000}"
    ".legend{display:flex;align-items:center;gap:0.5em;font-size:13px;margin:0.3em 0}"
    ".legend .bar{display:inline-block;width:240px;height:14px;border:1px solid #888;"
    "-webkit-print-color-adjust:exact;print-color-adjust:exact}"
    ".note{color:#555;font-size:13px}"
    "#view3d{position:relative;width:100%;max-width:900px;border:1px solid #ccc}"
    "#view3d canvas{width:100%;height:560px;display:block;touch-action:none}"
    ".view3d-bar{padding:4px;font-size:13px}.view3d-bar button{margin-right:4px}"
    ".view3d-readout{margin-left:1em}.view3d-status{margin:4px;color:#a00}"
    ".maps img{image-rendering:pixelated;width:128px}"
    ".maps figcaption{max-width:140px}"
    "@media print{.screen-only{display:none}body{margin:0}.tag{font-size:8px}"
    ".viewrow{break-inside:avoid}}"
)


def write_html(out: str | os.PathLike, summary: dict[str, Any]) -> Path:
    """Write ``out/report.html`` from a fit summary: images listed in ``report_images``,
    scales, viewpoints and labels in ``report_page`` (:func:`write_report`)."""
    out = Path(out)
    s = summary
    m = s["mesh"]
    e = s["errors"]
    images = s.get("report_images", [])
    page = s.get("report_page", {})
    alarm, marks = _flag_list(s)
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>meshfit report: {html.escape(str(m['name']))}</title>",
        f"<style>{_STYLE}</style></head><body>",
        f"<h1>meshfit fit of {html.escape(str(m['name']))}</h1>",
        f"<p>{m['vertices']:,} vertices, {m['faces']:,} triangles, bbox diagonal "
        f"{m['bbox_diagonal']:.6g}; {s['patches_total']} patches; meshfit {s['version']}.</p>",
        alarm,
        *_view3d(s, page),
        "<h2>Errors against the input</h2>",
        "<p>Two-sided distances (reconstruction vertices to the input and input vertices to "
        "the reconstruction) as fractions of the input's bbox diagonal.</p>",
        _table(
            [
                {"surface": k.replace("_", " "), **{kk: vv for kk, vv in e[k].items()}}
                for k in ("spline_only", "displaced")
            ],
            flagged=marks["errors"],
        ),
        "<h2>Seams</h2>",
        "<p>Across every curve shared by two patches: gaps as fractions of the bbox diagonal, "
        "normal jumps in degrees (inner: away from the corner zones, one knot span from each "
        "end).</p>",
        _table([s["seams"]], flagged=marks["seams"]),
    ]
    if s.get("notes"):
        parts.append("<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in s["notes"]) + "</ul>")
    parts += _view_rows(s, page, images)
    captions = dict(REPORT_IMAGES)
    parts.append("<h2>Renders</h2>")
    for img in images:
        stem = Path(img).stem
        if stem in captions:
            parts.append(
                f"<figure><img src='{html.escape(img)}' width='420'>"
                f"<figcaption>{html.escape(captions[stem])}</figcaption></figure>"
            )
    blender = {stem: what for stem, _, what in BLENDER_IMAGES}
    for img in images:
        stem = Path(img).stem
        if stem in blender:
            cap = f"Blender (Cycles) render of {usd_layer(s) or 'the USD layer'}: {blender[stem]}"
            parts.append(
                f"<figure><img src='{html.escape(img)}' width='420'>"
                f"<figcaption>{html.escape(cap)}</figcaption></figure>"
            )
    parts += _map_figures(images, page.get("map_scales", []))
    parts.append("<h2>Stage timings (seconds)</h2>")
    parts.append(
        _table(
            [
                {"stage": k, "seconds": v["seconds"], "cached": v["cached"]}
                for k, v in s["stages"].items()
            ]
        )
    )
    parts.append("<h2>Patches</h2>")
    parts.append(
        "<p>Fit errors, displacements and the largest distance of the patch's input vertices "
        "to the displaced surface, as fractions of the bbox diagonal; corner angles in "
        "degrees.</p>"
    )
    patches = s["patches"]
    rows = {(i, c): k for (p, c), k in marks["patches"].items() for i, r in enumerate(patches)
            if int(r.get("patch", i)) == p}  # fmt: skip
    parts.append(_table(patches, PATCH_COLUMNS, flagged=rows))
    if s.get("control_classes"):
        parts.append("<h2>Control classes</h2>")
        parts.append(
            "<p>Patch directions that must share one control count (linked by shared curves "
            "and opposite sides); set a class's count with <code>--class-cv CLASS=COUNT</code> "
            "(at most <i>max</i>, its smallest spring grid).</p>"
        )
        rows_cc = [
            {
                "class": c["class"],
                "controls": c["controls"],
                "max": c["max"],
                "members": " ".join(f"{q}{d}" for q, d in c["members"]),
            }
            for c in s["control_classes"]
        ]
        parts.append(_table(rows_cc))
    if page.get("model"):
        parts += [
            "<script src='report/three.min.js'></script>",
            "<script src='report/model.js'></script>",
            "<script src='report/viewer.js'></script>",
        ]
    parts.append("</body></html>\n")
    return write_text(out / "report.html", "\n".join(parts))


def _map_figures(images: list[str], scales: list[float]) -> list[str]:
    """The displacement maps, each on its own scale, the scale under it."""
    maps = [img for img in images if Path(img).stem.startswith("map_")]
    if not maps:
        return []
    parts = [
        "<h2>Displacement maps</h2><p>T, N, B components as red, green, blue; mid-grey is no "
        "displacement; u to the right, v upwards. Each map is shown on its own scale: full "
        "colour is its largest displacement, printed under it (percent of the bbox "
        "diagonal).</p><div class='maps'>"
    ]
    for img in maps:
        p = int(Path(img).stem[4:])
        scale = f": &plusmn;{_pct(scales[p])}" if p < len(scales) else ""
        parts.append(
            f"<figure><img src='{html.escape(img)}'><figcaption>patch {p}{scale}"
            "</figcaption></figure>"
        )
    parts.append("</div>")
    return parts
