"""``meshfit fit``: B-spline patches, displacement maps, stitching and exports from grids."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from meshfit._cliargs import own_inputs
from meshfit.errors import InputError

__all__ = ["add_commands", "cmd_fit", "load_grid"]

#: spring-mesh .npz versions this command reads
_NPZ_VERSIONS = (1,)
_FORMATS = ("usd", "3dm", "iges", "obj", "glb", "exr")


def load_grid(path: str | Path) -> np.ndarray:
    """The ``xyz (nu, nv, 3) float64`` grid of a spring-mesh ``.npz`` (no pickles)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            version = int(data["version"]) if "version" in data else None
            xyz = np.array(data["xyz"], dtype=np.float64)
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{path}: not a spring-mesh .npz with an xyz grid ({exc})") from None
    if version not in _NPZ_VERSIONS:
        raise InputError(f"{path}: unsupported spring-mesh file version {version}")
    if xyz.ndim != 3 or xyz.shape[2] != 3 or min(xyz.shape[:2]) < 4:
        raise InputError(
            f"{path}: xyz must be a grid (nu, nv, 3) with nu, nv >= 4, got {xyz.shape}"
        )
    return xyz


def cmd_fit(args: argparse.Namespace) -> int:  # noqa: C901 (one branch per output of the grid command; to split)
    """Fit every grid, stitch, build maps, export; print errors, seams and timings."""
    from meshfit._cliout import EXIT_OK, print_json, print_table
    from meshfit.bspline import fit_bspline, fit_errors
    from meshfit.displacement import displacement_map
    from meshfit.export import export_3dm, export_gltf, export_iges, export_obj, export_usd
    from meshfit.export.weld import udim
    from meshfit.stitch import (
        control_classes,
        match_map_shapes,
        network_from_grids,
        seam_report,
        stitch_displacements,
        stitch_surfaces,
    )

    formats = [f for f in args.formats.split(",") if f] if args.formats else []
    bad = [f for f in formats if f not in _FORMATS]
    if bad:
        raise InputError(f"unknown export format {bad[0]!r}; choose from {', '.join(_FORMATS)}")
    if formats and not args.out:
        raise InputError("--formats needs --out")
    t0 = time.perf_counter()
    paths = sorted(Path(p) for p in args.grids)
    grids = [load_grid(p) for p in paths]
    names = [f"patch_{k:03d}" for k in range(len(grids))]
    net = network_from_grids(grids, continuity="C0" if args.continuity == "C0" else "G1")
    mu, mv = (args.controls[0], args.controls[-1])
    cc = control_classes(
        net,
        default=[(mu, mv)] * len(grids),
        counts=getattr(args, "class_controls", None) or None,
        grid_shapes=[g.shape[:2] for g in grids],
    )
    t = time.perf_counter()
    surfaces = [fit_bspline(g, controls=c) for g, c in zip(grids, cc.controls, strict=True)]
    t_fit = time.perf_counter() - t
    before = seam_report(surfaces, net)
    t = time.perf_counter()
    if args.continuity != "none" and net.boundaries:
        surfaces = stitch_surfaces(surfaces, net)
    t_stitch = time.perf_counter() - t
    after = seam_report(surfaces, net)
    t = time.perf_counter()
    maps = [displacement_map(s, g) for s, g in zip(surfaces, grids, strict=True)]
    if net.boundaries:  # equal texel counts along shared sides: crack-free at any resolution
        maps = stitch_displacements(surfaces, match_map_shapes(surfaces, maps, net), net)
    t_maps = time.perf_counter() - t
    rows = []
    for k, (p, g, s, m) in enumerate(zip(paths, grids, surfaces, maps, strict=True)):
        e = fit_errors(s, g)
        rows.append(
            {
                "patch": k,
                "file": str(p),
                "grid": list(g.shape[:2]),
                "controls": list(s.shape),
                "control_classes": [int(c) for c in cc.labels[k]],  # of u and v
                "map": list(m.shape),
                **{k2: float(f"{v:.6g}") for k2, v in e.as_dict().items()},
            }
        )
    files = []
    t = time.perf_counter()
    if formats:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        if "usd" in formats:
            # the layer references its maps as UDIM tiles, maps/patches_vector.<UDIM>.exr
            (out / "maps").mkdir(exist_ok=True)
            for k, m in enumerate(maps):
                files.append(out / "maps" / f"patches_vector.{udim(k)}.exr")
                m.to_exr(files[-1])
            usd = export_usd(
                out / "patches.usda", surfaces, displacements=maps, network=net, names=names
            )
            files.append(usd)
        if "3dm" in formats:
            files.append(export_3dm(out / "patches.3dm", surfaces, names=names))
        if "iges" in formats:
            files.append(export_iges(out / "patches.igs", surfaces))
        if "obj" in formats:
            files.append(
                export_obj(out / "displaced.obj", surfaces, displacements=maps, names=names)
            )
            files.append(export_obj(out / "splines.obj", surfaces, names=names))
        if "glb" in formats:
            files.append(
                export_gltf(out / "preview.glb", surfaces, displacements=maps, names=names)
            )
        if "exr" in formats:
            for n, m in zip(names, maps, strict=True):
                files.append(out / f"{n}.vector.exr")
                m.to_exr(files[-1])
    t_export = time.perf_counter() - t
    result = {
        "patches": rows,
        "control_classes": [int(c) for c in cc.counts],
        "shared_boundaries": len(net.boundaries),
        "seams_before": before.summary(),
        "seams_after": after.summary(),
        "files": [str(f) for f in files],
        "seconds": {
            "fit": round(t_fit, 4),
            "stitch": round(t_stitch, 4),
            "maps": round(t_maps, 4),
            "export": round(t_export, 4),
            "total": round(time.perf_counter() - t0, 4),
        },
    }
    if args.json:
        print_json(result)
    else:
        for r in rows:
            print_table(f"patch {r['patch']}", {k: v for k, v in r.items() if k != "file"})
        print_table("seams before stitching", result["seams_before"])
        print_table("seams after stitching", result["seams_after"])
        print_table("seconds", result["seconds"])
    return EXIT_OK


def add_commands(sub) -> None:
    """Add ``meshfit fit`` to the ``meshfit`` sub-parsers."""
    p = sub.add_parser(
        "fit",
        help="fit B-spline patches and displacement maps to spring-mesh grids, stitch, export",
    )
    p.add_argument("grids", nargs="+", help="spring-mesh .npz files (from meshfit springs --out)")
    p.add_argument(
        "--controls",
        type=int,
        nargs="+",
        default=[8],
        help="control points per patch: one count, or mu mv (made consistent across "
        "shared boundaries; default 8)",
    )
    p.add_argument(
        "--continuity",
        choices=("G1", "C0", "none"),
        default="G1",
        help="continuity enforced on shared boundaries (default G1)",
    )
    p.add_argument("--out", default=None, help="output folder for exports")
    p.add_argument(
        "--formats",
        default="",
        help=f"comma-separated exports: {', '.join(_FORMATS)} (default none)",
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    own_inputs(p, ("grids",), ("out",))
    p.set_defaults(func=cmd_fit)
