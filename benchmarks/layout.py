"""Benchmark: the automatic layout of every kind of mesh, against Instant Meshes' quad layouts.

For every mesh in ``../shared/data/meshes`` and generated closed shapes of genus 0 to 5
(tori in a row blended by a smooth minimum, ``tests/shapes.py``; genus 0: a rounded cube)
a closed genus-0 body with eight long arms (``shapes.spiky``) and three parts with sharp
edges (a cube, a slab with three round through holes: genus 3, and a genus-2 part as a CAD
program tessellates it, in needle triangles, ``shapes.cad_part``), with no options (the
fit's defaults, the meshes loaded with the default repair; a mesh of needle triangles is
remeshed evenly first, as the fit does, its time counted in the layout's and its distance
to the input added to the Hausdorff distance):

- ours: :func:`meshfit.layout.auto.auto_layout` (which route it took, the layout's time),
  then the whole fit (:func:`meshfit.fit` in memory, no exports, no report): its time,
  patch count, displaced RMS and Hausdorff distance (fractions of the bbox diagonal), folded
  spring cells, the largest normal jump across smooth seams away from corners, and crease
  curves;
- the peer, in the same run: Instant Meshes (``pyinstantmeshes``, benchmark-only) remeshing
  the same mesh to as many quads as our layout has patches (its remesh time; the ratio is
  ours over its), then its quad mesh turned into a meshfit layout (every quad edge painted
  as a surface curve, :func:`meshfit.curves.paint_curve`, between the mesh vertices nearest
  its ends; every quad a patch) and
  fitted by the same pipeline, so that the two layouts are compared by the fit's errors and
  folded cells. Where the peer's layout cannot be cut into disks (paths that cross or share
  vertices, two corners on one vertex) that is recorded as its failure.

Run: ``python benchmarks/layout.py [--meshes bunny kitten ...] [--genus 0 1 2 3 4 5]``.
Prints JSON and writes ``benchmarks/results/layout.json`` atomically.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import ROOT, mesh_path, write_result

from meshfit.curves import paint_curve
from meshfit.layout import layout_from_curves
from meshfit.layout.auto import auto_layout, auto_route
from meshfit.layout.even import NEEDLE_SHARE, even_remesh, needle_share
from meshfit.layout.extract import check_layout_topology
from meshfit.mesh import Mesh, load_mesh
from meshfit.pipeline import FitOptions, fit
from meshfit.surface.paths import vertex_points

sys.path.insert(0, str(ROOT))
from tests import shapes

REAL = ("bunny", "igea", "kitten", "nefertiti", "nefertiti_fraunhofer", "rocker-arm", "spot")
OPTIONS = FitOptions(formats=(), report=False)


def _generated(genus: int) -> Mesh:
    if genus == 0:
        return shapes.cube(rounded=0.3, n=24)
    return shapes.tori(genus, edge=0.08)


def _fit_figures(mesh: Mesh, layout, out: Path) -> dict:
    t = time.perf_counter()
    s = fit(mesh, layout, options=OPTIONS).summary
    d = s["errors"]["displaced"]
    return {
        "fit_seconds": round(time.perf_counter() - t, 2),
        "patches": s["patches_total"],
        "displaced_rms": d["rms"],
        "displaced_hausdorff": d["hausdorff"],
        "folded_cells": int(sum(p["folded"] for p in s["patches"])),
        "smooth_seam_jump_deg": s["seams"]["spline_normal_jump_inner_max_deg"],
        "crease_curves": s["seams"].get("crease_curves", 0),
    }


def _peer_layout(mesh: Mesh, quad_v: np.ndarray, quads: np.ndarray):
    """Instant Meshes' quads as a meshfit layout: corners at the mesh vertices nearest the
    quad vertices, sides painted between them."""
    from scipy.spatial import cKDTree

    used = np.unique(quads)
    _, near = cKDTree(mesh.vertices).query(quad_v[used])
    if np.unique(near).size < used.size:
        raise ValueError("two quad corners fall on one mesh vertex")
    corner_of = {int(q): k for k, q in enumerate(used.tolist())}
    corners = vertex_points(mesh, np.asarray(near, dtype=np.int64))
    edges: dict[tuple[int, int], int] = {}
    curves, ends = [], []
    patches = []
    for q in quads.tolist():
        sides = []
        for s in range(4):
            a, b = corner_of[q[s]], corner_of[q[(s + 1) % 4]]
            key = (min(a, b), max(a, b))
            if key not in edges:
                picks = np.asarray([near[key[0]], near[key[1]]], dtype=np.int64)
                edges[key] = len(curves)
                curves.append(paint_curve(mesh, picks).points)
                ends.append(key)
            sides.append((edges[key], a > b))
        patches.append(sides)
    layout = layout_from_curves(mesh, corners, curves, np.asarray(ends), patches)
    check_layout_topology(mesh, layout)
    return layout


def _quiet(fn):
    """``fn()`` with the process's standard output (file descriptor 1) silenced: the
    peer's library logs every step there."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        return fn()
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def _quads(tris: np.ndarray) -> np.ndarray:
    """The quads of Instant Meshes' pure-quad output, which it returns as pairs of
    triangles ``(a, b, c), (d, a, c)`` sharing the diagonal ``a c``."""
    t1, t2 = tris[0::2], tris[1::2]
    if len(t1) != len(t2) or not ((t2[:, 1] == t1[:, 0]) & (t2[:, 2] == t1[:, 2])).all():
        raise ValueError("the output triangles do not pair into quads")
    return np.column_stack([t1, t2[:, 0]])


def _peer(mesh: Mesh, n_quads: int, out: Path) -> dict:
    import pyinstantmeshes

    v = np.asarray(mesh.vertices, dtype=np.float32)
    f = np.asarray(mesh.faces, dtype=np.int32)
    times = []
    # its pure-quad mode splits every face of its layout in four: ask for a quarter
    for _ in range(3):
        t = time.perf_counter()
        qv, qf = _quiet(
            lambda: pyinstantmeshes.remesh(
                v,
                f,
                target_face_count=max(int(n_quads) // 4, 1),
                pure_quad=True,
                deterministic=True,
            )
        )
        times.append(time.perf_counter() - t)
    row: dict = {"remesh_seconds": round(statistics.median(times), 3)}
    try:
        quads = _quads(np.asarray(qf))
        row["quads"] = len(quads)
        t = time.perf_counter()
        layout = _peer_layout(mesh, np.asarray(qv, dtype=np.float64), quads)
        row["layout_seconds"] = round(time.perf_counter() - t, 2)
    except Exception as exc:  # no quads, or a layout that does not cut the mesh into disks
        row["failure"] = f"{type(exc).__name__}: {str(exc).splitlines()[0][:200]}"
        return row
    row.update(_fit_figures(mesh, layout, out))
    return row


def run_one(name: str, mesh: Mesh, peer: bool) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        row: dict = {"mesh": name, "faces": mesh.n_faces, "genus": mesh.genus}
        row["closed"] = bool(mesh.is_closed)
        row["components"] = mesh.n_components
        input_mesh = mesh
        try:
            # as the fit does: a CAD tessellation of needle triangles is remeshed evenly
            # first (its time counts as layout time; the peer gets the same mesh)
            t_even = time.perf_counter()
            if needle_share(mesh) > NEEDLE_SHARE:
                even = even_remesh(mesh)
                mesh = even.mesh
                row["remeshed"] = even.to_dict()
            t_even = time.perf_counter() - t_even
            import meshfit.layout.auto as auto

            handed = []  # the sphere route hands a mesh with a protrusion to the region route
            region_route = auto._region_route
            auto._region_route = lambda *a: handed.append(1) or region_route(*a)
            times = []
            try:
                for _ in range(2):
                    t = time.perf_counter()
                    layout = auto_layout(mesh)
                    times.append(time.perf_counter() - t)
            finally:
                auto._region_route = region_route
            route = auto_route(mesh)
            row["route"] = "sphere -> regions" if route == "sphere" and handed else route
            row["layout_seconds"] = round(min(times) + t_even, 3)
            row.update(_fit_figures(mesh, layout, tmp / "ours"))
            if mesh is not input_mesh:  # against the input, through the remesh
                row["displaced_hausdorff"] += row["remeshed"]["distance"]
            row["success"] = True
        except Exception as exc:
            row["success"] = False
            row["failure"] = f"{type(exc).__name__}: {str(exc).splitlines()[0][:200]}"
            return row
        if peer:
            p = _peer(mesh, row["patches"], tmp / "peer")
            row["peer"] = p
            if p.get("remesh_seconds"):
                row["layout_time_ratio"] = round(row["layout_seconds"] / p["remesh_seconds"], 2)
        print(row, file=sys.stderr, flush=True)
        return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="*", default=list(REAL))
    ap.add_argument("--genus", nargs="*", type=int, default=[0, 1, 2, 3, 4, 5])
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--no-spiky", dest="spiky", action="store_false")
    ap.add_argument("--no-creased", dest="creased", action="store_false")
    args = ap.parse_args()
    rows = []
    for name in args.meshes:
        rows.append(run_one(name, load_mesh(mesh_path(name), repair=True), not args.no_peer))
    for g in args.genus:
        rows.append(run_one(f"genus{g}", _generated(g), not args.no_peer))
    if args.spiky:
        # a closed genus-0 body with eight long arms: the shape that sent the sphere route's
        # protrusion moves into minutes; now the region route takes it
        rows.append(run_one("spiky8", shapes.spiky(8), not args.no_peer))
    if args.creased:
        # parts with sharp edges: the creases lie on patch boundaries (C0 across them)
        rows.append(run_one("sharp_cube", shapes.cube(), not args.no_peer))
        rows.append(run_one("slab_genus3", shapes.box_with_holes(3), not args.no_peer))
        # a CAD program's own tessellation (needle triangles), remeshed evenly first
        rows.append(run_one("cad_part", shapes.cad_part(), not args.no_peer))
    ok = [r for r in rows if r.get("success")]
    peer_ok = [r for r in ok if "peer" in r and "failure" not in r["peer"]]
    summary = {
        "meshes": len(rows),
        "succeeded": len(ok),
        "median_layout_time_ratio": statistics.median(
            [r["layout_time_ratio"] for r in ok if "layout_time_ratio" in r] or [float("nan")]
        ),
        "peer_layouts_fitted": len(peer_ok),
        "ours_at_or_below_peer_hausdorff": sum(
            r["displaced_hausdorff"] <= r["peer"]["displaced_hausdorff"] for r in peer_ok
        ),
        "ours_folded_at_or_below_peer": sum(
            r["folded_cells"] <= r["peer"]["folded_cells"] for r in peer_ok
        ),
    }
    write_result(
        "layout",
        {
            "machine": platform.platform(),
            "python": platform.python_version(),
            "summary": summary,
            "rows": rows,
        },
    )


if __name__ == "__main__":
    main()
