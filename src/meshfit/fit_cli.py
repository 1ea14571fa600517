"""Command-line shell of the fit pipeline: ``meshfit fit`` and ``meshfit batch``."""

from __future__ import annotations

import argparse
from pathlib import Path

from meshfit._cliargs import add_repair_option, own_inputs
from meshfit._progress import stage_progress
from meshfit.errors import InputError
from meshfit.mesh.io import load_cli_mesh

__all__ = ["add_commands", "cmd_batch", "cmd_fit", "parse_controls", "stage_progress"]


def parse_controls(text: str) -> tuple[int, int]:
    """``"16x12"`` -> ``(16, 12)``; ``"16"`` -> ``(16, 16)``."""
    parts = str(text).lower().replace("*", "x").split("x")
    try:
        vals = [int(p) for p in parts]
    except ValueError:
        raise InputError(f"--cv must look like MUxMV (e.g. 16x16), got {text!r}") from None
    if len(vals) == 1:
        vals = vals * 2
    if len(vals) != 2:
        raise InputError(f"--cv must look like MUxMV (e.g. 16x16), got {text!r}")
    return vals[0], vals[1]


def parse_class_controls(text: str | None) -> dict[int, int]:
    """``"3=12,7=8"`` -> ``{3: 12, 7: 8}`` (control counts of equal-count classes)."""
    out: dict[int, int] = {}
    for item in str(text or "").split(","):
        if not item.strip():
            continue
        try:
            c, n = (int(x) for x in item.split("="))
        except ValueError:
            raise InputError(
                f"--class-cv must look like CLASS=COUNT[,CLASS=COUNT...] (e.g. 3=12,7=8), "
                f"got {text!r}"
            ) from None
        out[c] = n
    return out


def _formats(text: str) -> tuple[str, ...]:
    return tuple(f.strip().lower() for f in str(text).split(",") if f.strip())


def _options(args: argparse.Namespace):
    from meshfit.pipeline import FitOptions

    return FitOptions(
        controls=parse_controls(args.cv),
        class_controls=parse_class_controls(getattr(args, "class_cv", None)),
        continuity=args.continuity,
        spline_smoothing=args.spline_smoothing,
        formats=_formats(args.formats),
        patches=args.patches,
        layout_shape={"auto": None, "on": True, "off": False}[args.shape_layout],
        layout_seed=args.layout_seed,
        crease_angle=None if args.crease_angle == 0 else args.crease_angle,
        drop_components_below=args.drop_components,
        remesh=args.remesh,
        spring_level=args.level,
        spring_rescue=not args.no_rescue,
        spring_follow_folds=args.follow_folds,
        map_shapes=args.map_shapes,
        map_kind=args.maps,
        workers=args.workers,
        report=not args.no_report,
        units=args.units,
        up_axis=args.up_axis,
    )


def _gib(n: int | None) -> str:
    return "unknown" if n is None else f"{n / 2**30:.2f} GiB"


def _short_summary(summary: dict) -> dict:
    e = summary["errors"]
    return {
        "mesh": summary["mesh"]["name"],
        "faces": summary["mesh"]["faces"],
        "patches": summary["patches_total"],
        "spline_rms": e["spline_only"]["rms"],
        "spline_hausdorff": e["spline_only"]["hausdorff"],
        "displaced_rms": e["displaced"]["rms"],
        "displaced_hausdorff": e["displaced"]["hausdorff"],
        "seam_gap": summary["seams"]["spline_gap_max"],
        "folded_cells": sum(p["folded"] for p in summary["patches"]),
        "seconds": summary["seconds_total"],
        "peak_memory": _gib(summary.get("memory", {}).get("peak_rss_total")),
        "stages_reused": [s for s, i in summary["stages"].items() if i["cached"]],
    }


def cmd_fit(args: argparse.Namespace) -> int:
    """Fit B-spline patches with displacement maps to one mesh (or a prepared folder)."""
    from meshfit.pipeline.prepare import is_prepared

    options = _options(args)
    if is_prepared(args.mesh):  # a folder of ``meshfit prepare``: fitted out of core
        layout = args.layout not in (None, "auto")
        if layout or args.fill_holes:
            flag = "--layout" if layout else "--fill-holes"
            raise InputError(
                f"{flag} does not apply to a prepared folder (its layout and holes were "
                "settled when it was prepared)"
            )
        return _cmd_fit_on(args, options, args.mesh)
    mesh = load_cli_mesh(args.mesh, args.repair)
    if args.fill_holes and not mesh.is_closed:
        from meshfit.shrinkwrap import fill_holes

        mesh = fill_holes(mesh)
    return _cmd_fit_on(args, options, mesh)


def _cmd_fit_on(args: argparse.Namespace, options, mesh) -> int:
    """The rest of ``meshfit fit`` on a loaded mesh or a prepared folder's path."""
    from meshfit._cliout import EXIT_OK, print_json, print_table
    from meshfit.pipeline import fit

    out = Path(args.out) if args.out else Path(Path(args.mesh).stem + "-fit")
    cluster = _cluster(args)
    with stage_progress(quiet=args.json) as prog:
        result = fit(
            mesh,
            args.layout or "auto",
            options=options,
            out=out,
            resume=args.resume,
            progress=prog,
            cluster=cluster,
        )
    summary = result.summary
    if args.json:
        print_json(summary)
    else:
        print_table(
            f"fit of {args.mesh} (errors as fractions of the bbox diagonal)",
            _short_summary(summary),
        )
        for note in summary["notes"]:
            print(f"note: {note}")
        print(f"summary: {out / 'summary.json'}")
        if options.report:
            print(f"report: {out / 'report.html'}")
    return EXIT_OK


def _cluster(args: argparse.Namespace):
    """The fit's ``cluster`` from ``--scheduler`` and ``--processes`` (0: threads)."""
    scheduler = getattr(args, "scheduler", None)
    processes = getattr(args, "processes", None)
    if scheduler:
        return scheduler
    if processes is None:
        return "auto"
    if processes < 0:
        raise InputError(f"--processes must be 0 (threads) or more, got {processes}")
    return processes or None


def cmd_rebuild(args: argparse.Namespace) -> int:
    """Rebuild a fit from its maps after they were edited as images."""
    from meshfit._cliout import EXIT_OK, print_json, print_table
    from meshfit.mesh import load_mesh
    from meshfit.pipeline import load_fit
    from meshfit.pipeline.outputs import accept_edits, edited_maps

    folder = Path(args.folder)
    edited = sorted(edited_maps(folder))
    mesh = load_mesh(args.mesh, repair=True) if args.mesh else None
    result = load_fit(folder, mesh=mesh).rebuild()
    out = Path(args.out) if args.out else folder
    formats = _formats(args.formats) if args.formats else None
    files = result.export(out, formats)
    if result.mesh is not None and (folder / "report.html").is_file():
        files["report"] = result.report(out)
    elif (out / "report.html").is_file():
        result.summary.setdefault("notes", []).append(
            "report.html still shows the fit before the rebuild: give the input mesh "
            "(meshfit rebuild --mesh PATH) to render it again"
        )
    result.save(out)
    if out == folder:
        accept_edits(folder)  # the edits are in the fit now
    if args.json:
        print_json(result.summary)
        return EXIT_OK
    e = result.summary["errors"]
    rows = {
        "fit": str(folder),
        "edited maps": ", ".join(edited) or "none",
        "displaced_gap": result.summary["seams"]["displaced_gap_max"],
        "files written": sum(len(v) for v in files.values()),
    }
    if e.get("displaced"):
        rows["displaced_rms"] = e["displaced"]["rms"]
        rows["displaced_hausdorff"] = e["displaced"]["hausdorff"]
    print_table("rebuild (errors as fractions of the bbox diagonal)", rows)
    for note in result.summary["notes"][-2:]:
        if "rebuil" in note or "edited" in note or "report.html" in note:
            print(f"note: {note}")
    return EXIT_OK


def cmd_batch(args: argparse.Namespace) -> int:
    """Fit every mesh matching a glob on a Dask cluster."""
    from meshfit._cliout import EXIT_ERROR, EXIT_OK, print_json, print_table
    from meshfit.batch import run_batch

    summary = run_batch(
        args.glob,
        args.out,
        layout=args.layout,
        options=_options(args),
        scheduler=args.scheduler,
        n_workers=args.n_workers,
        quiet=args.json,
    )
    if args.json:
        print_json(summary)
    else:
        print_table(
            f"batch {args.glob}",
            {k: v for k, v in summary.items() if k in ("meshes", "done", "skipped", "failed")},
        )
        for name, rec in summary["results"].items():
            if rec["status"] == "failed":
                print(f"failed: {name}: {rec['error']}")
        print(f"summary: {Path(args.out) / 'batch.json'}")
    return EXIT_OK if not summary["failed"] else EXIT_ERROR


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--layout",
        default="auto",
        help="layout file (.json), or 'auto': the automatic layout of any mesh "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--patches",
        type=int,
        default=None,
        help="about this many patches in the automatic layout (default 60, at least 24; "
        "a multiple of 6 is met exactly)",
    )
    p.add_argument(
        "--shape-layout",
        choices=("auto", "on", "off"),
        default="auto",
        help="move the automatic layout's corners so that its patches are square on the "
        "surface (default auto: above 60 patches)",
    )
    p.add_argument(
        "--layout-seed",
        type=int,
        default=0,
        metavar="N",
        help="rotation of the automatic layout's base mesh (default 0): another one gives "
        "other patches where the notes name slivers, tapered or bulging patches",
    )
    p.add_argument(
        "--drop-components",
        type=float,
        default=0.0,
        metavar="SHARE",
        help="drop the mesh's components below this share of its area, e.g. 0.01 "
        "(default: none; the summary names those below 1%% either way)",
    )
    p.add_argument(
        "--remesh",
        choices=("auto", "on", "off"),
        default="auto",
        help="fit an even remesh of the input with the automatic layout: auto where needle "
        "triangles cover over a tenth of its area, as a CAD program tessellates (default: "
        "%(default)s)",
    )
    p.add_argument(
        "--crease-angle",
        type=float,
        default=40.0,
        metavar="DEG",
        help="chains of edges sharper than this become patch boundaries of the automatic "
        "layout, C0 with --continuity auto (default: %(default)s; 0: none)",
    )
    p.add_argument(
        "--cv", default="16x16", help="control points per patch, MUxMV (default: %(default)s)"
    )
    p.add_argument(
        "--continuity",
        type=lambda s: s if s == "auto" else s.upper(),
        choices=("auto", "C0", "G1"),
        default="auto",
        help="across patches: auto is G1 except across sharp creases, which stay C0 "
        "(default: auto)",
    )
    p.add_argument(
        "--spline-smoothing",
        type=float,
        default=0.0,
        metavar="KNOTS",
        help="keep detail narrower than about this many knot spacings out of the splines, "
        "in the maps (0.5 suits maps you edit; default 0: the spline alone fits closest)",
    )
    p.add_argument(
        "--formats",
        default="usd,obj,exr",
        help="outputs among usd,3dm,iges,step,obj,glb,ply,exr,png; step needs meshfit[cad] "
        "(default: %(default)s: USD for studio tools and Blender, OBJ for mesh tools, the "
        "EXR maps both reference)",
    )
    p.add_argument(
        "--units",
        default="mm",
        choices=("mm", "cm", "m", "in", "ft"),
        help="length unit of the scan's coordinates, declared in the USD, 3dm, IGES and STEP "
        "files (never scaled; default: %(default)s)",
    )
    p.add_argument(
        "--up-axis",
        default="auto",
        choices=("auto", "y", "z"),
        help="axis the exports declare as up (default auto: z for models much taller along z "
        "than along y, else y)",
    )
    p.add_argument(
        "--level", type=int, default=None, help="final spring-mesh level (default: auto)"
    )
    p.add_argument(
        "--no-rescue",
        action="store_true",
        help="keep every relaxed spring mesh, also where it misses its patch (a pleat, a "
        "squeezed bulge, a protrusion) by more than a grid spacing: no area-balanced remake "
        "and no finer grid",
    )
    p.add_argument(
        "--follow-folds",
        action="store_true",
        help="spring vectors across a fold of the surface follow the grid line, so the "
        "spring meshes cross the curled rims of ears and horns (see meshfit springs; with "
        "the rescue on, the displaced error does not fall: the rescued grids fit closer)",
    )
    p.add_argument(
        "--maps",
        choices=("vector", "scalar", "bump"),
        default="vector",
        help="what the maps hold: the exact displacement in the spline's frame (vector), a "
        "distance along the spline's normal, what you paint (scalar), or shading normals "
        "for renderers (bump; the surface is the spline) (default: %(default)s)",
    )
    p.add_argument(
        "--map-shapes",
        choices=("matched", "native"),
        default="matched",
        help="displacement map resolutions: equal texel counts along shared curves, so the "
        "exported meshes are watertight and the seams crack-free at any resolution (matched), "
        "or each at its spring grid's (native; fewer texels) (default: %(default)s)",
    )
    p.add_argument("--no-report", action="store_true", help="skip report.html and its images")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")


def _take_over(sub, name: str):
    """Remove an already registered sub-command ``name``; return its ``func`` (or None)."""
    parser = sub.choices.pop(name, None)
    if parser is None:
        return None
    sub._choices_actions[:] = [a for a in sub._choices_actions if a.dest != name]
    return parser.get_default("func")


def _fit_grids(grid_func, args: argparse.Namespace) -> int:
    """``meshfit fit GRID.npz ...``: the grid command of meshfit.bspline.cli."""
    mu, mv = parse_controls(args.cv)
    ns = argparse.Namespace(
        grids=args.mesh,
        controls=[mu, mv],
        class_controls=parse_class_controls(getattr(args, "class_cv", None)),
        continuity="C0" if args.continuity == "C0" else "G1",
        out=args.out,
        formats=",".join(f for f in _formats(args.formats) if f != "png") if args.out else "",
        json=args.json,
    )
    return grid_func(ns)


def add_commands(sub) -> None:
    # meshfit.bspline.cli registers ``fit`` for spring-mesh grids; ``meshfit fit`` takes a
    # mesh (the whole pipeline) or, when every input is a .npz grid, runs that command
    grid_func = _take_over(sub, "fit")

    def fit(args: argparse.Namespace) -> int:
        if grid_func is not None and all(str(m).endswith(".npz") for m in args.mesh):
            return _fit_grids(grid_func, args)
        if len(args.mesh) != 1:
            raise InputError(f"meshfit fit takes one mesh file, got {len(args.mesh)} inputs")
        args.mesh = args.mesh[0]
        return cmd_fit(args)

    p = sub.add_parser("fit", help="fit B-spline patches and displacement maps to a mesh")
    p.add_argument(
        "mesh",
        nargs="+",
        help="mesh file (.ply .obj .stl .off .glb .gltf), a folder of meshfit prepare (fitted "
        "out of core), or spring-mesh .npz grids",
    )
    p.add_argument("--out", default=None, help="output folder (default: <mesh name>-fit)")
    _common(p)
    p.add_argument(
        "--class-cv",
        default=None,
        metavar="CLASS=COUNT,...",
        help="control counts of equal-count classes (listed in summary.json under "
        "'control_classes'), e.g. 3=12,7=8; with --resume the stages before the fit are reused",
    )
    p.add_argument("--resume", action="store_true", help="re-use finished stages in --out")
    p.add_argument("--workers", type=int, default=None, help="threads (default: all cores)")
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--processes",
        type=int,
        default=None,
        metavar="N",
        help="make the spring meshes and maps in N worker processes (a Dask LocalCluster on "
        "127.0.0.1, 4 GiB each; 0: threads of this process) (default: threads)",
    )
    where.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="make the spring meshes and maps on a running Dask cluster, e.g. "
        "tcp://host:8786 (its workers must read --out: a shared file system)",
    )
    add_repair_option(p)
    p.add_argument(
        "--fill-holes",
        action="store_true",
        help="close small holes (at most 1000 boundary edges each) before the layout; "
        "without it an open mesh is laid out as it is, the holes' rims on patch boundaries",
    )
    own_inputs(p, ("mesh", "layout"), ("out",))
    p.set_defaults(func=fit)

    p = sub.add_parser(
        "rebuild",
        help="rebuild a fit from its displacement maps after editing them as images",
    )
    p.add_argument("folder", help="a fit folder (written by meshfit fit)")
    p.add_argument(
        "--formats",
        default=None,
        help="outputs to write, among usd,3dm,iges,step,obj,glb,ply,exr,png (default: the fit's)",
    )
    p.add_argument("--mesh", default=None, help="the fit's input mesh, to measure the errors again")
    p.add_argument(
        "--out", default=None, help="write the rebuilt fit here (default: in the fit folder)"
    )
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    own_inputs(p, ("mesh",), ("out",))
    p.set_defaults(func=cmd_rebuild)

    p = sub.add_parser("batch", help="fit every mesh matching a glob on a Dask cluster")
    p.add_argument("glob", help="mesh files, e.g. 'scans/*.ply' (quote it)")
    p.add_argument("--out", required=True, help="output folder: one sub-folder per mesh")
    _common(p)
    p.add_argument(
        "--scheduler", default=None, help="Dask scheduler address (default: a LocalCluster)"
    )
    p.add_argument(
        "--n-workers",
        "--workers",
        dest="n_workers",
        type=int,
        default=None,
        help="LocalCluster worker processes (default: 2)",
    )
    p.set_defaults(func=cmd_batch, workers=1)
