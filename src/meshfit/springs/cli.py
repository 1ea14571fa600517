"""``meshfit springs``: resample every patch of a layout into a spring mesh."""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from meshfit._cliargs import add_repair_option, own_inputs
from meshfit.mesh.io import load_cli_mesh

__all__ = ["add_commands", "cmd_springs", "save_spring_mesh"]

#: format version of the .npz files written by `save_spring_mesh`
NPZ_VERSION = 1


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def save_spring_mesh(spring, folder: str | os.PathLike, stem: str) -> tuple[Path, Path]:
    """Write a spring mesh as ``stem.npz`` and a triangulated ``stem.ply``, atomically.

    The .npz holds ``version`` (int, 1), ``face (n,) int64`` and ``bary (n, 3) float64`` (face
    points of the patch mesh, row-major over the grid), ``xyz (nu, nv, 3) float64``,
    ``kind (nu, nv) uint8``, ``level``, ``patch``, ``u_lines``, ``v_lines``. No pickles.
    """
    import io

    import trimesh

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    np.savez(
        buf,
        version=np.int64(NPZ_VERSION),
        face=spring.points.face,
        bary=spring.points.bary,
        xyz=spring.xyz,
        kind=spring.kind,
        level=np.int64(spring.level),
        patch=np.int64(spring.patch),
        u_lines=spring.u_lines,
        v_lines=spring.v_lines,
    )
    npz = folder / f"{stem}.npz"
    _atomic_write(npz, buf.getvalue())
    tm = trimesh.Trimesh(spring.xyz.reshape(-1, 3), spring.triangles(), process=False)
    ply = folder / f"{stem}.ply"
    _atomic_write(ply, tm.export(file_type="ply"))
    return npz, ply


def cmd_springs(args: argparse.Namespace) -> int:
    """Resample every patch of a layout; print metrics and timings."""
    from meshfit._cliout import EXIT_OK, print_json, print_table
    from meshfit._threads import map_threads, n_workers
    from meshfit.layout import extract_patches, load_layout
    from meshfit.layout.patch import shape_figures
    from meshfit.springs import SpringOptions, resample_patch, spring_metrics
    from meshfit.springs.metrics import out_of_bounds

    t0 = time.perf_counter()
    mesh = load_cli_mesh(args.mesh, args.repair)
    layout = load_layout(args.layout, mesh)
    t_load = time.perf_counter() - t0
    t = time.perf_counter()
    patches = extract_patches(mesh, layout)
    t_extract = time.perf_counter() - t
    workers = n_workers(args.workers)

    def one(patch) -> dict:
        t = time.perf_counter()
        res = resample_patch(
            patch,
            SpringOptions(
                level=args.level,
                rescue=args.rescue,
                tolerance=args.tolerance,
                follow_folds=args.follow_folds,
                scale=mesh.bbox_diagonal,
                metrics=False,
            ),
        )
        seconds = time.perf_counter() - t
        met = spring_metrics(patch.mesh, res.final, scale=mesh.bbox_diagonal, places=True)
        places = met.pop("places")
        row = {
            "patch": patch.index,
            "vertices": patch.mesh.n_vertices,
            "level": res.final.level,
            "grid": list(res.final.shape),
            "seconds": round(seconds, 4),
            "rescued": bool(res.rescued),
            "evened": bool(res.evened),
            "finer": int(res.finer),
            "tolerance_met": None if args.tolerance is None else res.distance <= args.tolerance,
            "remade": bool(res.remade),
            "fairness": res.fairness,
            "final_arc": bool(res.final_arc),
            **shape_figures(patch),
            **{k: v for k, v in met.items() if k not in ("nu", "nv")},
        }
        if out_of_bounds(met):  # where to look: the worst spacing, the folds, the distance
            row["places"] = places
        if args.out:
            npz, ply = save_spring_mesh(res.final, args.out, f"patch_{patch.index:03d}")
            row["files"] = [str(npz), str(ply)]
        return row

    progress = None
    if not args.json:
        from rich.progress import Progress

        progress = Progress(transient=True)
        progress.start()
        task = progress.add_task("spring meshes", total=len(patches))
    t = time.perf_counter()
    try:
        rows = map_threads(
            one,
            patches,
            workers,
            cost=[float(p.mesh.n_vertices) for p in patches],
            progress=None
            if progress is None
            else lambda done, n: progress.update(task, completed=done),
        )
    finally:
        if progress is not None:
            progress.stop()
    t_springs = time.perf_counter() - t
    from meshfit.layout.patch import patch_notes

    out = {
        "mesh": str(args.mesh),
        "layout": str(args.layout),
        "patches": rows,
        "summary": _summary(rows),
        "notes": patch_notes(rows),
        "seconds": {
            "load": round(t_load, 3),
            "extract": round(t_extract, 3),
            "springs": round(t_springs, 3),
            "total": round(time.perf_counter() - t0, 3),
        },
    }
    if args.json:
        print_json(out)
    else:
        _print_patches(rows)
        for line in _place_lines(rows):
            print(line)
        print_table("summary", _summary_lines(out["summary"]))
        print_table("seconds", out["seconds"])
        for note in out["notes"]:
            print(f"note: {note}")
    return EXIT_OK


def _summary(rows: list[dict]) -> dict:
    """Patch count, folded cells, and the patches whose metrics exceed each quality bound
    (`meshfit.springs.metrics.QUALITY_BOUNDS`)."""
    from meshfit.springs.metrics import QUALITY_BOUNDS, out_of_bounds

    over: dict[str, list[int]] = {k: [] for k in QUALITY_BOUNDS}
    for r in rows:
        for k in out_of_bounds(r):
            over[k].append(r["patch"])
    return {
        "patches": len(rows),
        "folded_cells": int(sum(r["folded"] for r in rows)),
        "bounds": dict(QUALITY_BOUNDS),
        "over_bounds": over,
    }


#: columns of the per-patch table: (row key, header, format)
_COLUMNS = (
    ("patch", "patch", "{}"),
    ("vertices", "verts", "{}"),
    ("grid", "grid", "{0[0]}x{0[1]}"),
    ("level", "lvl", "{}"),
    ("arc_cv_max", "arc CV", "{:.3f}"),
    ("aspect_median", "aspect", "{:.2f}"),
    ("folded", "folds", "{}"),
    ("fidelity_max", "fidelity %", "{:.3f}"),
)


def _print_patches(rows: list[dict]) -> None:
    """One row per patch (the rest of each patch's figures are in ``--json``); a value above
    its quality bound is marked ``!`` (and red)."""
    from rich import box
    from rich.table import Table

    from meshfit._cliout import console
    from meshfit.springs.metrics import out_of_bounds

    table = Table(title="spring meshes", title_justify="left", box=box.SIMPLE_HEAD)
    texts = []  # (text, over its bound) per figure cell
    for r in rows:
        over = set(out_of_bounds(r))
        texts.append(
            [
                (fmt.format(r[key] * 100 if key == "fidelity_max" else r[key]), key in over)
                for key, _, fmt in _COLUMNS
            ]
        )
    # the figures keep their full width on a narrow terminal (or piped output, 80 columns):
    # the notes wrap instead
    for c, (_, head, _) in enumerate(_COLUMNS):
        width = max([len(head)] + [len(t[c][0]) + t[c][1] for t in texts])
        table.add_column(head, justify="right", no_wrap=True, min_width=width)
    table.add_column("notes", overflow="fold")
    for r, row in zip(rows, texts, strict=True):
        cells = [f"[red]{text}![/]" if over else text for text, over in row]
        notes = []
        if r["rescued"]:
            notes.append("rescued, lines evened" if r["evened"] else "rescued")
        if r["remade"]:
            notes.append("remade")
        if r["final_arc"]:
            notes.append("last level arc length")
        if r["finer"]:
            notes.append(f"{r['finer']} finer")
        if r["tolerance_met"] is False:
            notes.append("over tolerance")
        table.add_row(*cells, ", ".join(notes))
    console().print(table)


#: `meshfit.springs.metrics.worst_places` places in words
_WHERE = {"corner": "near a corner", "side": "near a side", "interior": "inside the patch"}


def _beside(point: list[int], points: list[list[int]]) -> bool:
    """Whether grid point ``point`` is one of ``points`` or next to one (diagonals too)."""
    return any(max(abs(point[0] - i), abs(point[1] - j)) <= 1 for i, j in points)


def _place_lines(rows: list[dict]) -> list[str]:
    """Where the patches over the arc-length or fold bound miss it (see
    `meshfit.springs.metrics.worst_places`; the largest distances' places are in ``--json``
    only: at the vertex-count level nearly every patch of a scan is over that bound)."""
    from meshfit.springs.metrics import out_of_bounds

    lines = []
    for r in rows:
        over, places = set(out_of_bounds(r)), r.get("places")
        if not places:
            continue
        if "arc_cv_max" in over:
            a = places["arc_cv"]
            (i0, j0), (i1, j1) = a["points"]
            line = (
                f"patch {r['patch']}: arc CV {a['cv']:.3f}, worst {_WHERE[a['place']]}: "
                f"interval ({i0}, {j0})-({i1}, {j1}) is {a['ratio']:.2f} times its line's mean"
            )
            f = places.get("fidelity")
            if f and f["from"] == "patch" and _beside(f["grid_point"], a["points"]):
                line += (
                    f", where the patch is farthest from the grid ({f['distance'] * 100:.3f}%): "
                    "the grid steps over a pleat or a bulge"
                    + ("" if r["rescued"] else " (--rescue resamples such grids)")
                )
            lines.append(line)
        if "folded" in over:
            cells = ", ".join(
                f"({c['cell'][0]}, {c['cell'][1]}) {_WHERE[c['place']]}" for c in places["folded"]
            )
            lines.append(f"patch {r['patch']}: folded cells {cells}")
    return lines


def _summary_lines(summary: dict) -> dict:
    """The summary as quantity -> value rows for `meshfit._cliout.print_table`."""
    bounds = summary["bounds"]
    labels = {
        "arc_cv_max": f"arc CV above {bounds['arc_cv_max']:g}",
        "aspect_median": f"median aspect above {bounds['aspect_median']:g}",
        "folded": "patches with folded cells",
        "fidelity_max": f"fidelity above {bounds['fidelity_max'] * 100:g}%",
    }
    out = {"patches": summary["patches"], "folded cells": summary["folded_cells"]}
    for key, ids in summary["over_bounds"].items():
        out[labels[key]] = f"{len(ids)} ({', '.join(map(str, ids))})" if ids else "0"
    return out


def add_commands(sub) -> None:
    """Add ``meshfit springs`` to the ``meshfit`` sub-parsers."""
    p = sub.add_parser(
        "springs",
        help="resample every patch of a layout into a spring mesh (gridded resampling)",
    )
    p.add_argument("mesh", help="mesh file the layout was made for")
    add_repair_option(p)
    p.add_argument("--layout", required=True, help="layout JSON file (meshfit_layout 1)")
    p.add_argument(
        "--level",
        type=int,
        default=None,
        help="final subdivision level (default: spring points comparable to the patch's "
        "vertex count)",
    )
    p.add_argument(
        "--rescue",
        action="store_true",
        help="resample again from an area-balanced map, lightly relaxed, where the spring "
        "mesh misses its patch by more than a grid spacing (a pleat, a squeezed bulge), and "
        "up to two levels finer where that still misses (without --level); where neither "
        "helps, even out the grid lines along their paths in the patch's map",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=None,
        help="largest distance wanted between each spring mesh and its patch, as a fraction "
        "of the model's bounding-box diagonal (e.g. 5e-4); patches that miss it are "
        "resampled up to three levels finer (without --level or --rescue)",
    )
    p.add_argument(
        "--follow-folds",
        action="store_true",
        help="spring vectors to a neighbour across a fold of the surface (a curled rim: an "
        "ear, a horn) follow the grid line instead of the chord, so the grid crosses the rim "
        "and stays much closer to a patch over such a rim",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="threads resampling patches side by side (default: all cores; the grids do not "
        "depend on it)",
    )
    p.add_argument("--out", default=None, help="folder for one .npz and .ply per patch")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    own_inputs(p, ("mesh", "layout"), ("out",))
    p.set_defaults(func=cmd_springs)
