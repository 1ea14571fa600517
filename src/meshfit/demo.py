"""The embedded default input and the ``meshfit demo`` run.

:func:`demo_mesh` generates a deterministic scan-like surface: a closed genus-0 blob with
bust-like lobes, fine engraved detail and painted vertex colours, irregularly triangulated
like a scan (jittered sample points joined by their spherical Delaunay triangulation).
No file and no network access is needed.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit.errors import InputError
from meshfit.mesh import Mesh

__all__ = ["demo_mesh", "demo_sphere_map", "run_demo"]


def _sphere_points(n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """n jittered Fibonacci points on the unit sphere (irregular but well spaced)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    golden = np.pi * (3.0 - np.sqrt(5.0))
    theta = golden * i
    r = np.sqrt(1.0 - z * z)
    p = np.stack([r * np.cos(theta), r * np.sin(theta), z], axis=1)
    spacing = np.sqrt(4.0 * np.pi / n)
    p += rng.normal(scale=0.22 * spacing, size=p.shape)
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def _radius(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Radial height of the shape in unit direction(s) ``d`` (n, 3): always > 0.4."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    r = 1.0 + 0.18 * z - 0.10 * (x * x - y * y) + 0.06 * x * y * z * 4.0
    # two lobes ("ears") and a ridge ("nose")
    for c, a, w in (
        ((0.6, 0.0, 0.8), 0.22, 0.10),
        ((-0.6, 0.0, 0.8), 0.22, 0.10),
        ((0.0, 0.95, 0.3), 0.12, 0.04),
    ):
        cd = d @ np.asarray(c) / np.linalg.norm(c)
        r += a * np.exp(-(1.0 - cd) / w)
    # fine detail: engraved rings and bumpy texture (scan-like high frequencies)
    r += 0.012 * np.sin(38.0 * z + 3.0 * np.sin(5.0 * x))
    r += 0.006 * np.sin(61.0 * x) * np.sin(53.0 * y + 1.3)
    r += 0.004 * np.sin(97.0 * (x + y + z))
    return r


#: largest default input :func:`demo_mesh` generates (the convex hull of ``faces / 2`` points
#: grows to tens of seconds at this size on a small machine; ten times more is impractical)
DEMO_MAX_FACES = 5_000_000


def demo_mesh(faces: int = 200_000, *, seed: int = 20001121) -> Mesh:
    """Generate the default input: a closed, genus-0, scan-like mesh.

    Parameters
    ----------
    faces : int
        Approximate triangle count (the exact count is ``2 * n_vertices - 4``).
    seed : int
        Seed of the sample-point jitter; the same seed gives the same mesh.

    Returns
    -------
    Mesh
        Named ``"demo_scan"``, with per-vertex RGBA colours (a painted band pattern, useful
        for colour attraction).
    """
    if faces < 100:
        raise InputError(f"faces must be at least 100, got {faces}")
    if faces > DEMO_MAX_FACES:
        raise InputError(f"faces must be at most {DEMO_MAX_FACES:,}, got {faces:,}")
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(seed)
    n = faces // 2 + 2
    d = _sphere_points(n, rng)
    hull = ConvexHull(d)
    tri = np.asarray(hull.simplices, dtype=np.int64)
    # orient outward: the hull of points around the origin has outward normal . centroid > 0
    p = d[tri]
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    flip = np.einsum("ij,ij->i", nrm, p.mean(axis=1)) < 0
    tri[flip] = tri[flip][:, ::-1]
    verts = d * _radius(d)[:, None]
    band = np.sin(9.0 * np.arctan2(d[:, 1], d[:, 0]) + 4.0 * d[:, 2]) > 0.6
    spot = d @ np.array([0.0, -0.8, 0.6]) / 1.0 > 0.85
    colors = np.empty((n, 4), dtype=np.uint8)
    colors[:] = (214, 196, 170, 255)
    colors[band] = (150, 60, 40, 255)
    colors[spot] = (40, 70, 140, 255)
    return Mesh(verts, tri, colors, name="demo_scan")


def _write_json(path: Path, data: dict[str, Any]) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    with os.fdopen(fd, "w") as fh:
        json.dump(data, fh, indent=2)
        fh.write("\n")
    os.replace(tmp, path)


def demo_sphere_map(mesh: Mesh):
    """The exact sphere parameterization of a :func:`demo_mesh`: radial projection.

    The demo surface is ``r(d) d`` over unit directions ``d``, so its vertices normalised are
    a flip-free map onto the unit sphere (no embedding needs to be solved).
    """
    from meshfit.shrinkwrap import SphereMap
    from meshfit.shrinkwrap.sphere import spherical_orientation

    s = mesh.vertices / np.linalg.norm(mesh.vertices, axis=1, keepdims=True)
    det = spherical_orientation(s, mesh.faces)
    flips = int((det <= 0).sum())
    return SphereMap(mesh, s, "radial", flips, float(det.min()), float("nan"))


def run_demo(
    out: Path,
    *,
    faces: int = 200_000,
    patches: int = 60,
    quiet: bool = False,
    options=None,
) -> dict[str, Any]:
    """Fit the embedded default input end to end and write the report.

    Generates :func:`demo_mesh`, lays out about ``patches`` four-sided patches automatically
    (:func:`meshfit.layout.auto.auto_layout` over the demo's exact radial sphere map), and
    runs :func:`meshfit.fit`: spring meshes, B-spline fit, displacement maps,
    stitching, exports and ``report.html``. Writes ``demo_scan.ply``, ``info.json`` and the
    fit outputs into ``out``.

    Parameters
    ----------
    out : Path
        Output folder (created).
    faces : int
        Approximate triangle count of the generated mesh (default 200,000).
    patches : int
        Patch count asked of the automatic layout (default 60).
    quiet : bool
        No progress output (for ``--json``).
    options : meshfit.pipeline.FitOptions, optional
        Fit options (default: 12 x 12 controls, G1 stitching, usd/obj/exr/png outputs and
        the report).

    Returns
    -------
    dict
        The fit summary (``summary.json``) with ``statistics`` of the mesh and ``report``,
        the report's path.
    """
    from rich.console import Console

    from meshfit._progress import stage_progress
    from meshfit.layout.auto import LayoutOptions, auto_layout
    from meshfit.mesh import save_mesh
    from meshfit.mesh.measures import mesh_statistics
    from meshfit.pipeline import FitOptions, fit
    from meshfit.pipeline.outputs import update_manifest

    console = Console(quiet=quiet, stderr=True)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with console.status("generating the default scan-like mesh"):
        t0 = time.perf_counter()
        mesh = demo_mesh(faces)
        generate = time.perf_counter() - t0
    mesh_path = save_mesh(mesh, out / "demo_scan.ply")
    stats = mesh_statistics(mesh)
    _write_json(out / "info.json", {"file": str(mesh_path), **stats})
    console.print(
        f"[bold]mesh[/] {mesh_path}: {stats['vertices']:,} vertices, "
        f"{stats['faces']:,} faces, genus {stats['genus']}, "
        f"{'closed' if stats['closed'] else 'open'}"
    )
    with console.status(f"automatic layout of about {patches} patches"):
        t0 = time.perf_counter()
        layout = auto_layout(mesh, LayoutOptions(patches=patches), sphere=demo_sphere_map(mesh))
        t_layout = time.perf_counter() - t0
    console.print(f"[bold]layout[/] {layout.n_patches} patches in {t_layout:.1f} s")
    if options is None:
        options = FitOptions(
            controls=(12, 12), continuity="G1", formats=("usd", "obj", "exr", "png")
        )
    with stage_progress(quiet=quiet) as prog:
        summary = fit(mesh, layout, options=options, out=out, progress=prog).summary
    update_manifest(out, [mesh_path.name, "info.json"])  # the input beside the fit
    summary["statistics"] = stats
    summary["generate_seconds"] = round(generate, 3)
    summary["layout_seconds"] = round(t_layout, 3)
    report = out / "report.html"
    summary["report"] = str(report) if report.is_file() else None
    e = summary["errors"]
    console.print(
        f"[bold]fit[/] {layout.n_patches} patches in {summary['seconds_total']:.1f} s; "
        f"displaced surface RMS {100 * e['displaced']['rms']:.3f}% and Hausdorff "
        f"{100 * e['displaced']['hausdorff']:.3f}% of the bbox diagonal "
        f"(spline only: {100 * e['spline_only']['rms']:.3f}%, "
        f"{100 * e['spline_only']['hausdorff']:.3f}%)"
    )
    if not quiet and summary["report"]:
        print(summary["report"])
    return summary
