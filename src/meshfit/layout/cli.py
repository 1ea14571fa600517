"""``meshfit layout``: check a layout file against its mesh and summarise its patches."""

from __future__ import annotations

import argparse
import time

__all__ = ["add_commands", "cmd_layout"]


def add_commands(sub) -> None:
    """Add ``meshfit layout MESH LAYOUT [--json]`` to the CLI's sub-parsers."""
    p = sub.add_parser(
        "layout",
        help="check a patch layout file against its mesh and summarise the patches",
        description=(
            "Load a layout (JSON, version 1), check it against the mesh (fingerprint, points, "
            "curve ends at corners, four sides joined end to end, curves meeting only at "
            "corners, every patch a disk, the patches covering the mesh) and print per-patch "
            "sizes."
        ),
    )
    p.add_argument("mesh", help="mesh file the layout was made for")
    p.add_argument("layout", help="layout .json file")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_layout)


def cmd_layout(args: argparse.Namespace) -> int:
    from meshfit.cli import print_json, print_table
    from meshfit.layout import extract_patches, load_layout
    from meshfit.layout.patch import patch_notes, shape_figures
    from meshfit.mesh import load_mesh

    mesh = load_mesh(args.mesh)
    t0 = time.perf_counter()
    layout = load_layout(args.layout, mesh, check_topology=False)
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
        "load_s": t1 - t0,
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
    if args.json:
        print_json(summary)
    else:
        print_table(
            f"layout {args.layout}",
            {k: v for k, v in summary.items() if k not in ("per_patch", "notes")},
        )
        for note in summary["notes"]:
            print(f"note: {note}")
    return 0
