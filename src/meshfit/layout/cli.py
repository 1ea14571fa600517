"""``meshfit layout``: check a layout file against its mesh and summarise its patches
(optionally smoothing its boundary curves into a new layout file)."""

from __future__ import annotations

import argparse
import time

from meshfit._cliargs import add_repair_option, own_inputs
from meshfit.mesh.io import load_cli_mesh

__all__ = ["add_commands", "cmd_layout"]


def add_commands(sub) -> None:
    """Add ``meshfit layout MESH LAYOUT [--smooth N --out OUT] [--json]`` to the CLI's
    sub-parsers."""
    p = sub.add_parser(
        "layout",
        help="check a patch layout file against its mesh and summarise the patches",
        description=(
            "Load a layout (JSON, version 1), check it against the mesh (fingerprint, points, "
            "curve ends at corners, four sides joined end to end, curves meeting only at "
            "corners, every patch a disk, the patches covering the mesh) and print per-patch "
            "sizes. With --smooth N the boundary curves are first relaxed N surface-snake steps "
            "(mesh-edge-scale wiggles damped, corners kept) and the result is written to --out "
            "and summarised."
        ),
    )
    p.add_argument("mesh", help="mesh file the layout was made for")
    add_repair_option(p)
    p.add_argument("layout", help="layout .json file")
    p.add_argument(
        "--smooth",
        type=int,
        metavar="N",
        help="relax the boundary curves N snake steps (8 is a good start) and write the "
        "smoothed layout to --out; sides of patches with feature curves are kept",
    )
    p.add_argument("--out", help="where --smooth writes the smoothed layout (.json)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    own_inputs(p, ("mesh", "layout"), ("out",))
    p.set_defaults(func=cmd_layout)


def cmd_layout(args: argparse.Namespace) -> int:
    from meshfit._cliout import print_json, print_table
    from meshfit.layout import extract_patches, load_layout
    from meshfit.layout.patch import patch_notes, shape_figures

    mesh = load_cli_mesh(args.mesh, args.repair)
    t0 = time.perf_counter()
    layout = load_layout(args.layout, mesh, check_topology=False)
    load_s = time.perf_counter() - t0
    smoothed = None
    if args.smooth is not None:
        smoothed = _smooth(mesh, layout, args)
        layout = smoothed["layout"]
    t1 = time.perf_counter()
    if args.json:
        patches = extract_patches(mesh, layout)
    else:
        from rich.progress import Progress

        with Progress(transient=True) as bar:
            task = bar.add_task("extracting patches", total=None)
            patches = extract_patches(
                mesh, layout, progress=lambda d, t: bar.update(task, completed=d, total=t)
            )
    t2 = time.perf_counter()
    faces = [p.mesh.n_faces for p in patches]
    summary = {
        "mesh": str(args.mesh),
        "layout": str(args.layout),
        "patches": layout.n_patches,
        "corners": len(layout.corners),
        "curves": len(layout.curves),
        "curve_points": int(sum(len(c) for c in layout.curves)),
        "feature_curves": int(sum(len(f) for f in layout.features)),
        "patch_faces_min": int(min(faces)),
        "patch_faces_max": int(max(faces)),
        "patch_area_sum": float(sum(p.mesh.area for p in patches)),
        "mesh_area": float(mesh.area),
        "load_s": load_s,
        "extract_s": t2 - t1,
        "per_patch": [
            {
                "patch": p.index,
                "faces": p.mesh.n_faces,
                "vertices": p.mesh.n_vertices,
                "side_vertices": [int(s.size) for s in p.sides],
                "features": [list(fs) for fs in p.feature_sides],
                **shape_figures(p),
            }
            for p in patches
        ],
    }
    summary["bulge_max"] = max(r["bulge"] for r in summary["per_patch"])
    summary["taper_max"] = max(r["taper"] for r in summary["per_patch"])
    summary["corner_angle_max"] = max(max(r["corner_angles"]) for r in summary["per_patch"])
    summary["notes"] = patch_notes(summary["per_patch"])
    if smoothed is not None:
        summary["smoothed"] = {k: v for k, v in smoothed.items() if k != "layout"}
    if args.json:
        print_json(summary)
    else:
        print_table(
            f"layout {args.layout}",
            {k: v for k, v in summary.items() if k not in ("per_patch", "notes", "smoothed")},
        )
        if smoothed is not None:
            print_table("smoothed", summary["smoothed"])
        for note in summary["notes"]:
            print(f"note: {note}")
    return 0


def _smooth(mesh, layout, args: argparse.Namespace) -> dict:
    """``--smooth``: the smoothed layout, saved to ``--out`` (checked to cut the mesh into
    disks first), and the curves' wiggle before and after (fractions of the bbox
    diagonal)."""
    import numpy as np

    from meshfit.errors import InputError
    from meshfit.layout import check_layout_topology, save_layout
    from meshfit.layout.smooth import curve_wiggle, smooth_layout

    if not args.out:
        raise InputError("--smooth writes a new layout: name it with --out")

    def wiggle(lay) -> tuple[float, float]:
        w = np.concatenate([np.zeros(0), *(curve_wiggle(mesh, c) for c in lay.curves)])
        w = w / mesh.bbox_diagonal
        return (float(np.median(w)), float(np.percentile(w, 99))) if w.size else (0.0, 0.0)

    t = time.perf_counter()
    out = smooth_layout(mesh, layout, iterations=args.smooth)
    check_layout_topology(mesh, out)
    seconds = time.perf_counter() - t
    path = save_layout(out, args.out, mesh=mesh)
    (m0, p0), (m1, p1) = wiggle(layout), wiggle(out)
    return {
        "layout": out,
        "iterations": int(args.smooth),
        "out": str(path),
        "wiggle_median_before": m0,
        "wiggle_median_after": m1,
        "wiggle_p99_before": p0,
        "wiggle_p99_after": p1,
        "smooth_s": seconds,
    }
