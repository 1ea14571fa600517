"""``meshfit wrap`` and ``meshfit stream encode|decode``."""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

from meshfit import errors
from meshfit._cliargs import own_inputs
from meshfit.shrinkwrap.sphere import MAX_STRETCH_ITERATIONS, VOXEL_REMOVED

__all__ = ["add_commands"]


def _progress(quiet: bool):
    """A rich progress bar driven by the API's ``progress(stage, fraction)`` callback."""
    if quiet:
        return None, None
    from rich.progress import Progress

    bar = Progress(transient=True)
    tasks: dict[str, int] = {}

    def cb(stage: str, fraction: float) -> None:
        if stage not in tasks:
            tasks[stage] = bar.add_task(stage, total=1.0)
        bar.update(tasks[stage], completed=fraction)

    return bar, cb


#: largest hole closed by ``--fill-holes``, in boundary edges
_FILL_MAX_EDGES = 1000


def _load(path: str, fill: bool):
    from meshfit.mesh import load_mesh
    from meshfit.shrinkwrap import check_genus0, fill_holes

    mesh = load_mesh(path, repair=True)
    try:
        if fill and not mesh.is_closed:
            mesh = fill_holes(mesh, max_edges=_FILL_MAX_EDGES)
        check_genus0(mesh)
    except errors.TopologyError as exc:
        raise errors.TopologyError(f"{path}: {exc}") from None
    return mesh


def _write_json(path: Path, data: dict) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(data, fh, indent=2)
        fh.write("\n")
    os.replace(tmp, path)


def _wrap(args: argparse.Namespace):
    from meshfit.shrinkwrap import WrapOptions, shrink_wrap

    if args.levels < 0:
        raise errors.InputError(f"--levels must be >= 0, got {args.levels}")
    if args.base_faces < 20:
        raise errors.InputError(
            f"--base-faces must be at least 20 (an icosahedron), got {args.base_faces}"
        )
    a = args.sphere_max_aspect
    if a is not None and not 1.0 <= a < float("inf"):  # (NaN fails too)
        raise errors.InputError(
            f"--sphere-max-aspect must be a finite number >= 1 (equilateral), got {a}"
        )
    if not 0 <= args.sphere_stretch <= MAX_STRETCH_ITERATIONS:
        raise errors.InputError(
            f"--sphere-stretch must be in 0..{MAX_STRETCH_ITERATIONS}, got {args.sphere_stretch}"
        )
    if args.sphere_method == "voxel":
        raise errors.InputError(f"--sphere-method voxel: {VOXEL_REMOVED}")
    mesh = _load(args.mesh, args.fill_holes)
    opts = WrapOptions(
        base_faces=args.base_faces,
        sphere_method=args.sphere_method,
        sphere_max_aspect=args.sphere_max_aspect,
        sphere_stretch=args.sphere_stretch,
    )
    bar, cb = _progress(args.json)
    if bar is not None:
        with bar:
            res = shrink_wrap(mesh, opts, levels=args.levels, progress=cb)
    else:
        res = shrink_wrap(mesh, opts, levels=args.levels)
    return mesh, res


def cmd_wrap(args: argparse.Namespace) -> int:
    """Shrink wrap a mesh; write M0..Mm, the stream and the metrics."""
    from meshfit._cliout import print_json, print_table
    from meshfit.mesh.io import save_mesh
    from meshfit.shrinkwrap import encode_stream, wrap_report, write_stream

    _, res = _wrap(args)
    report = wrap_report(res)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        for lv in res.levels:
            save_mesh(lv.mesh, out / f"M{lv.level}.ply")
        top = res.levels[-1]
        st = encode_stream(top.vertices, res.base.faces, len(res.base.sphere), top.level)
        write_stream(st, out / "wrap.mfsw")
        _write_json(out / "metrics.json", report)
        report["out"] = str(out)
    if args.json:
        print_json(report)
    else:
        lv = report["levels"][-1]
        print_table(
            f"wrap {args.mesh}",
            {
                "sphere map": report["sphere_map"]["method"],
                "base faces": report["base"]["faces"],
                "base cell area max/min": report["base"]["cell_area_ratio"],
                "levels": len(report["levels"]) - 1,
                "finest faces": lv["faces"],
                "flipped on the sphere": lv["flips"],
                "facing against the input": lv["normal_flips"],
                "min angle deg": lv["min_angle_deg"],
                "min angle 1st percentile deg": lv["min_angle_p01_deg"],
                "rms / diag": lv["rms"],
                "hausdorff / diag": lv["hausdorff"],
            },
        )
    return 0


def cmd_encode(args: argparse.Namespace) -> int:
    from meshfit._cliout import print_json
    from meshfit.shrinkwrap import encode_stream, write_stream

    if args.bytes is not None and args.bytes < 1:
        raise errors.InputError(f"--bytes must be positive, got {args.bytes}")
    _, res = _wrap(args)
    top = res.levels[-1]
    st = encode_stream(
        top.vertices,
        res.base.faces,
        len(res.base.sphere),
        top.level,
        scheme=args.scheme,
        max_bytes=args.bytes,
    )
    write_stream(st, args.output)
    info = {
        "stream": str(args.output),
        "scheme": st.scheme,
        "levels": st.levels,
        "base_faces": len(st.base_faces),
        "coefficients": st.n_coefficients,
        "bit_planes": st.quant.planes if st.quant else None,
        "bytes": Path(args.output).stat().st_size,
    }
    if args.json:
        print_json(info)
    else:
        print(" ".join(f"{k}={v}" for k, v in info.items()))
    return 0


def cmd_decode(args: argparse.Namespace) -> int:
    import sys

    from meshfit._cliout import print_json
    from meshfit.mesh import Mesh
    from meshfit.mesh.io import save_mesh
    from meshfit.shrinkwrap import Stream, decode_stream

    if args.fraction is not None and not 0.0 <= args.fraction <= 1.0:
        raise errors.InputError(f"--fraction must be in [0, 1], got {args.fraction}")
    if args.bytes is not None and args.bytes < 0:
        raise errors.InputError(f"--bytes must be >= 0, got {args.bytes}")
    try:
        raw = Path(args.stream).read_bytes()
    except OSError as exc:
        raise errors.StreamError(f"{args.stream}: cannot read: {exc.strerror}") from None
    st = Stream.from_bytes(raw, where=args.stream)
    if st.missing:
        arrived, whole = len(raw), len(raw) + st.missing
        print(
            f"meshfit: note: {args.stream} is cut short: {arrived:,} of {whole:,} bytes "
            f"arrived ({100 * arrived / whole:.1f}%); decoding its complete blocks",
            file=sys.stderr,
        )
    used, declared = len(raw), len(raw) + st.missing
    if args.bytes is not None or args.fraction is not None:
        if st.quant is None:
            raise errors.InputError("--bytes and --fraction need a version-2 stream")
        if args.bytes is not None:
            used = min(args.bytes, len(raw))
        else:
            # (at least the blocks that hold the base mesh)
            used = max(st.min_prefix, int(args.fraction * len(raw)))
        st = Stream.from_bytes(raw[:used], where=f"{args.stream} (first {used:,} bytes)")
    level = st.levels if args.level is None else args.level
    if not 0 <= level <= st.levels:
        raise errors.InputError(f"--level must be in [0, {st.levels}], got {level}")
    x, f = decode_stream(st, level=level)
    save_mesh(Mesh(x, f, name=Path(args.output).name), args.output)
    info = {
        "output": str(args.output),
        "level": level,
        "vertices": len(x),
        "faces": len(f),
        "bytes_used": used,
        "bytes": declared,
        "coefficient_bytes": len(st.data),
    }
    if args.json:
        print_json(info)
    else:
        print(" ".join(f"{k}={v}" for k, v in info.items()))
    return 0


def _wrap_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("mesh", help="closed genus-0 mesh file")
    p.add_argument("--levels", type=int, default=5, help="refinement levels (default: 5)")
    p.add_argument(
        "--base-faces", type=int, default=100, help="base mesh face budget (default: 100)"
    )
    p.add_argument(
        "--fill-holes",
        action="store_true",
        help=f"close holes (boundary loops of up to {_FILL_MAX_EDGES} edges) first, with patches "
        "that continue the surface",
    )
    p.add_argument(
        "--sphere-method",
        choices=("tutte", "voxel"),  # voxel: refused with the reason (VOXEL_REMOVED)
        default="tutte",
        help="sphere map: convex disk embeddings (the default and only one; 'voxel', the "
        "paper's distance-field flow, is refused with the reason)",
    )
    p.add_argument(
        "--sphere-max-aspect",
        type=float,
        default=None,
        metavar="A",
        help="bound the aspect ratio of the spherical triangles by A (flip-guarded smoothing "
        "on the sphere; default: no bound)",
    )
    p.add_argument(
        "--sphere-stretch",
        type=int,
        default=0,
        metavar="N",
        help="N rounds of stretch-minimizing reweighting of the sphere map (default 0): "
        "protrusions such as ears get their share of the sphere, and the wrap reaches their "
        "tips, at the price of less even triangles",
    )
    p.add_argument("--json", action="store_true", help="print JSON")


def add_commands(sub) -> None:
    """Add ``wrap`` and ``stream`` to the ``meshfit`` sub-parsers."""
    p = sub.add_parser("wrap", help="subdivision-connectivity remesh by shrink wrapping")
    _wrap_args(p)
    p.add_argument("--out", help="folder for M0..Mm (.ply), wrap.mfsw and metrics.json")
    own_inputs(p, ("mesh",), ("out",))
    p.set_defaults(func=cmd_wrap)

    s = sub.add_parser("stream", help="progressive transmission streams")
    ssub = s.add_subparsers(dest="stream_command", required=True, metavar="ACTION")
    e = ssub.add_parser("encode", help="wrap a mesh and write its progressive stream")
    _wrap_args(e)
    e.add_argument("-o", "--output", required=True, help="stream file (.mfsw)")
    e.add_argument(
        "--scheme",
        choices=("loop", "butterfly"),
        default="butterfly",
        help="subdivision predictor (default: butterfly, the fewer bytes for an error)",
    )
    e.add_argument(
        "--bytes",
        type=int,
        default=None,
        metavar="N",
        help="write at most N bytes: the stream's first N bytes, cut where a decoder still "
        "gets whole bit-plane decisions (default: the whole stream)",
    )
    own_inputs(e, ("mesh",), ("output",))
    e.set_defaults(func=cmd_encode)

    d = ssub.add_parser("decode", help="reconstruct a mesh from a stream")
    d.add_argument("stream", help="stream file (.mfsw)")
    d.add_argument("-o", "--output", required=True, help="mesh file to write")
    d.add_argument("--level", type=int, default=None, help="level (default: finest)")
    cut = d.add_mutually_exclusive_group()
    cut.add_argument(
        "--bytes",
        type=int,
        default=None,
        metavar="N",
        help="decode the file's first N bytes (as if only they arrived)",
    )
    cut.add_argument(
        "--fraction",
        type=float,
        default=None,
        metavar="F",
        help="decode the file's first fraction F of bytes, at least those of the base mesh",
    )
    d.add_argument("--json", action="store_true", help="print JSON")
    own_inputs(d, ("stream",), ("output",))
    d.set_defaults(func=cmd_decode)
