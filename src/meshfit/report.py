"""The fit report: ``report.html`` with headless renders and tables of metrics and timings.

Images (8-bit PNG, :mod:`meshfit.render`) in ``<out>/report/``: the patch layout on the input
model, the spring meshes as a checkerboard (one square per grid cell), the spline-only
surface, the displaced surface, a heat map of the spline-only surface's distance to the
input, and each patch's displacement map as its image file shows it (x along u, y up along
v; a vector map's T, N, B components as R, G, B; mid-grey = 0).

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
from meshfit.render import Camera, heat_colors, patch_colors, render, write_png_rgb

__all__ = [
    "BLENDER_IMAGES",
    "BLENDER_PYTHON_ENV",
    "BLENDER_SCRIPT",
    "REPORT_IMAGES",
    "ReportInputs",
    "blender_python",
    "blender_renders",
    "model_view",
    "usd_layer",
    "write_html",
    "write_report",
]

#: the model renders of the report, in order: (file stem, caption)
REPORT_IMAGES = (
    ("layout", "patch layout on the input mesh"),
    ("springs", "spring meshes (checkerboard: one square per grid cell)"),
    ("spline", "spline-only surface"),
    ("displaced", "displaced surface (spline + displacement maps)"),
    ("error", "distance of the spline-only surface to the input (heat map)"),
)

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

    V = np.concatenate([X.reshape(-1, 3) for X in grids]) if grids else np.zeros((0, 3))
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


def write_report(
    out: str | os.PathLike,
    fit: ReportInputs,
    *,
    image_size: int = 640,
    render_images: bool = True,
    blender_python: str | os.PathLike | None = None,
) -> dict[str, Any]:
    """Render the report images and write ``report.html``.

    Parameters
    ----------
    out : path
        The fit's output folder; images go to ``out/report/``.
    fit : ReportInputs
        What is shown; its ``summary`` gets ``report_images`` added.
    image_size : int
        Width and height of the model renders, pixels.
    render_images : bool
        False re-uses images already in ``out/report`` (resume) and only rewrites the page
        (the Blender renders are shown where both files are there).
    blender_python : path, optional
        Blender's Python (e.g. :func:`blender_python`): where the summary lists a USD stage
        among the outputs (:func:`usd_layer`) and it is in ``out``, the page also shows it
        rendered by Blender (:func:`blender_renders`, at most :data:`BLENDER_MAX_SIZE`
        pixels, the model renders' view). A failed or timed-out render adds a note to the
        summary instead; the report is written without it. Default None: no Blender.

    Returns
    -------
    dict
        ``images``: paths of the images relative to ``out``; ``notes``: the notes added to
        the summary.
    """
    mesh, grids, surfaces, summary = fit.mesh, fit.grids, fit.surfaces, fit.summary
    face_patch, spline, dmaps = fit.face_patch, fit.spline, fit.maps
    out = Path(out)
    folder = out / "report"
    folder.mkdir(parents=True, exist_ok=True)
    n = len(grids)
    images = [f"report/{stem}.png" for stem, _ in REPORT_IMAGES]
    images += [f"report/map_{p:03d}.png" for p in range(n)]
    layer = usd_layer(summary) if blender_python is not None else None
    if layer is not None and not (out / layer).is_file():
        layer = None
    notes: list[str] = []
    if not render_images and layer is not None:
        shown = [f"report/{stem}.png" for stem, _, _ in BLENDER_IMAGES]
        images += shown if all((out / f).is_file() for f in shown) else []
    if render_images:
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
        camera = Camera(
            size=(int(image_size), int(image_size)),
            view=tuple(view),
            up=tuple(up),
            bounds=_hull_points(mesh.vertices[:: max(1, mesh.n_vertices // 20000)]),
        )
        # layout: input faces coloured by patch
        if face_patch is None:
            face_patch = np.full(mesh.n_faces, -1, dtype=np.int64)
        jobs = {
            "layout": lambda: render(
                mesh.vertices,
                mesh.faces,
                face_colors=patch_colors(face_patch),
                shading="flat",
                camera=camera,
            )
        }
        topology: dict = {}  # the grids, splines and displaced grids share their triangles
        V, F, P, UV = _grid_soup(grids, topology)
        cols = patch_colors(P)
        vcol = np.zeros((V.shape[0], 3))
        vcol[F[:, 0]] = cols
        vcol[F[:, 1]] = cols
        vcol[F[:, 2]] = cols
        jobs["springs"] = lambda: render(
            V, F, camera=camera, vertex_colors=vcol, uv=UV, checker=1.0, shading="flat"
        )
        if spline is None:
            spline = [
                s.evaluate_grid(np.linspace(0, 1, g.shape[0]), np.linspace(0, 1, g.shape[1]))
                for s, g in zip(surfaces, grids, strict=True)
            ]
        Vs, Fs, _, _ = _grid_soup(spline() if callable(spline) else spline, topology)
        jobs["spline"] = lambda: render(Vs, Fs, camera=camera)
        disp = fit.displaced() if callable(fit.displaced) else fit.displaced
        Vd, Fd, _, _ = _grid_soup(disp, topology)
        jobs["displaced"] = lambda: render(Vd, Fd, camera=camera)
        dist = fit.spline_distance
        if dist is None or len(dist) != len(Vs):
            dist = mesh.closest_points(Vs).distance
        vmax = float(np.quantile(dist, 0.99)) if dist.size else 0.0
        summary["error_map_max"] = vmax / mesh.bbox_diagonal
        jobs["error"] = lambda: render(Vs, Fs, camera=camera, vertex_colors=heat_colors(dist, vmax))
        scale = max(float(np.abs(d.values).max()) for d in dmaps) if dmaps else 0.0

        def map_png(p: int) -> None:
            d = dmaps[p]
            # the channels in the files' order: a vector map's T, N, B as R, G, B
            img = _map_image(d.values[..., [0, 2, 1]] if d.kind == "vector" else d.values, scale)
            # rows along v, columns along u, magnified to at least 128 pixels
            img = np.transpose(img, (1, 0, 2))[::-1]
            k = max(1, -(-128 // max(img.shape[:2])))
            img = np.repeat(np.repeat(img, k, axis=0), k, axis=1)
            write_png_rgb(folder / f"map_{p:03d}.png", img)

        # the rasteriser and zlib run without the GIL: the images are made side by side
        with ThreadPoolExecutor(max_workers=max(1, min(len(jobs), os.cpu_count() or 1))) as pool:
            futures = {stem: pool.submit(job) for stem, job in jobs.items()}
            maps = [pool.submit(map_png, p) for p in range(len(dmaps))]
            for stem, fut in futures.items():
                write_png_rgb(folder / f"{stem}.png", fut.result())
            for fut in maps:
                fut.result()
        summary["map_scale"] = scale / mesh.bbox_diagonal
        if blender is not None:
            images += _blender_result(blender, layer, notes)
            summary.setdefault("notes", []).extend(notes)
    summary["report_images"] = images
    write_html(out, summary)
    return {"images": images, "notes": notes}


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
        return " x ".join(_fmt(x) for x in v) if len(v) <= 3 else f"[{len(v)} values]"
    return html.escape(str(v))


def _table(rows: list[dict[str, Any]], columns: list[str] | None = None) -> str:
    if not rows:
        return "<p>none</p>"
    columns = columns or list(rows[0])
    head = "".join(f"<th>{html.escape(c.replace('_', ' '))}</th>" for c in columns)
    body = "".join(
        "<tr>" + "".join(f"<td>{_fmt(r.get(c, ''))}</td>" for c in columns) + "</tr>" for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def write_html(out: str | os.PathLike, summary: dict[str, Any]) -> Path:
    """Write ``out/report.html`` from a fit summary (images listed in ``report_images``)."""
    out = Path(out)
    s = summary
    m = s["mesh"]
    e = s["errors"]
    images = s.get("report_images", [])
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>meshfit report: {html.escape(str(m['name']))}</title>",
        "<style>body{font-family:sans-serif;margin:2em;max-width:1400px}"
        "table{border-collapse:collapse;margin:1em 0;font-size:13px}"
        "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
        "figure{display:inline-block;margin:0.5em;vertical-align:top}"
        "figcaption{font-size:13px;max-width:420px}"
        ".maps img{image-rendering:pixelated;width:128px}</style></head><body>",
        f"<h1>meshfit fit of {html.escape(str(m['name']))}</h1>",
        f"<p>{m['vertices']:,} vertices, {m['faces']:,} triangles, bbox diagonal "
        f"{m['bbox_diagonal']:.6g}; {s['patches_total']} patches; meshfit {s['version']}.</p>",
        "<h2>Errors against the input</h2>",
        "<p>Two-sided distances (reconstruction vertices to the input and input vertices to "
        "the reconstruction) as fractions of the input's bbox diagonal.</p>",
        _table(
            [
                {"surface": k.replace("_", " "), **{kk: vv for kk, vv in e[k].items()}}
                for k in ("spline_only", "displaced")
            ]
        ),
        "<h2>Seams</h2>",
        "<p>Across every curve shared by two patches: gaps as fractions of the bbox diagonal, "
        "normal jumps in degrees (inner: away from the corner zones, one knot span from each "
        "end).</p>",
        _table([s["seams"]]),
    ]
    if s.get("notes"):
        parts.append("<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in s["notes"]) + "</ul>")
    captions = dict(REPORT_IMAGES)
    parts.append("<h2>Renders</h2>")
    for img in images:
        stem = Path(img).stem
        if stem in captions:
            cap = captions[stem]
            if stem == "error" and "error_map_max" in s:
                cap += f" (red: {100 * s['error_map_max']:.3g}% of the bbox diagonal and above)"
            parts.append(
                f"<figure><img src='{html.escape(img)}' width='420'>"
                f"<figcaption>{html.escape(cap)}</figcaption></figure>"
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
    maps = [img for img in images if Path(img).stem.startswith("map_")]
    if maps:
        scale = s.get("map_scale")
        note = f" (full scale +-{100 * scale:.3g}% of the bbox diagonal)" if scale else ""
        parts.append(
            "<h2>Displacement maps</h2><p>T, N, B components as red, green, blue; mid-grey is "
            f"no displacement{html.escape(note)}; u to the right, v upwards.</p><div class='maps'>"
        )
        for img in maps:
            parts.append(
                f"<figure><img src='{html.escape(img)}'><figcaption>patch "
                f"{int(Path(img).stem[4:])}</figcaption></figure>"
            )
        parts.append("</div>")
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
    cols = [
        "patch",
        "shape",
        "levels",
        "folded",
        "arc_cv_max",
        "aspect_max",
        "controls",
        "fit_parametric_rms",
        "fit_parametric_max",
        "displacement_max",
        "input_distance_max",
        "seconds",
    ]
    parts.append(
        "<p>Fit errors, displacements and the largest distance of the patch's input vertices "
        "to the displaced surface, as fractions of the bbox diagonal.</p>"
    )
    parts.append(_table(s["patches"], cols))
    if s.get("control_classes"):
        parts.append("<h2>Control classes</h2>")
        parts.append(
            "<p>Patch directions that must share one control count (linked by shared curves "
            "and opposite sides); set a class's count with <code>--class-cv CLASS=COUNT</code> "
            "(at most <i>max</i>, its smallest spring grid).</p>"
        )
        rows = [
            {
                "class": c["class"],
                "controls": c["controls"],
                "max": c["max"],
                "members": " ".join(f"{q}{d}" for q, d in c["members"]),
            }
            for c in s["control_classes"]
        ]
        parts.append(_table(rows))
    parts.append("</body></html>\n")
    return write_text(out / "report.html", "\n".join(parts))
