"""Benchmark: writing a fit's OBJ files (displaced and spline-only), against an earlier commit.

Usage: ``python benchmarks/obj_export.py --against COMMIT [--mesh igea] [--level 4]
[--repeats 3]``

``MESH`` is fitted once (automatic layout, native map shapes, spring level ``LEVEL`` so
the OBJ files have millions of lines) and saved; then each side loads that fit and writes
its OBJ files in a fresh process, alternating this checkout and ``COMMIT`` (a git worktree)
after one warm-up run each. Printed per side: the export's seconds and the process's peak
resident memory (medians over the runs), the files' megabytes and whether both sides wrote
the same bytes. Writes ``obj_export.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import mesh_path, worktree, write_result


def one(fit_folder: str, out: str) -> dict:
    """Load the fit in ``fit_folder`` and write its OBJ files into ``out``."""
    from meshfit import load_fit

    result = load_fit(fit_folder)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    result.export(out, ["obj"])
    seconds = time.perf_counter() - t0
    files = sorted(Path(out).glob("*.obj"))
    digest = hashlib.sha256()
    for p in files:
        with open(p, "rb") as fh:
            for block in iter(lambda fh=fh: fh.read(1 << 24), b""):
                digest.update(block)
    return {
        "seconds": round(seconds, 3),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "rss_before_export_mb": round(base / 1024, 1),
        # what the export itself added to the process's peak
        "export_rss_mb": round(
            (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024, 1
        ),
        "megabytes": round(sum(p.stat().st_size for p in files) / 2**20, 1),
        "sha256": digest.hexdigest()[:16],
    }


def _run(fit_folder: Path, src: str | None = None) -> dict:
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = src
    with tempfile.TemporaryDirectory() as out:
        run = subprocess.run(
            [sys.executable, __file__, "--one", str(fit_folder), out],
            capture_output=True,
            text=True,
            env=env,
        )
    if run.returncode != 0:
        raise RuntimeError(run.stderr[-2000:])
    return json.loads(run.stdout.strip().splitlines()[-1])


def _median(runs: list[dict]) -> dict:
    out = dict(runs[0])
    for key in ("seconds", "peak_rss_mb", "export_rss_mb"):
        out[key] = statistics.median(r[key] for r in runs)
        out[f"{key}_runs"] = [r[key] for r in runs]
    return out


def compare(args) -> None:
    from meshfit.mesh import load_mesh
    from meshfit.pipeline import FitOptions, fit

    result: dict = {
        "benchmark": "obj_export",
        "against": args.against,
        "mesh": args.mesh,
        "level": args.level,
        "runs": args.repeats,
    }
    with tempfile.TemporaryDirectory() as tmp, worktree(args.against) as old:
        folder = Path(tmp) / "fit"
        opts = FitOptions(formats=(), report=False, spring_level=args.level, map_shapes="native")
        fitted = fit(load_mesh(mesh_path(args.mesh), repair=True), options=opts, out=folder)
        result["texels"] = sum(
            p.displacement.values.shape[0] * p.displacement.values.shape[1] for p in fitted.patches
        )
        _run(folder), _run(folder, str(old / "src"))  # warm-up (kernel caches)
        new, prev = [], []
        for _ in range(max(1, args.repeats)):
            new.append(_run(folder))
            prev.append(_run(folder, str(old / "src")))
        a, b = _median(new), _median(prev)
        result.update(
            new=a,
            old=b,
            seconds_new_over_old=round(a["seconds"] / max(b["seconds"], 1e-9), 3),
            peak_rss_new_over_old=round(a["peak_rss_mb"] / b["peak_rss_mb"], 3),
            export_rss_new_over_old=round(a["export_rss_mb"] / max(b["export_rss_mb"], 1e-9), 3),
            same_bytes=a["sha256"] == b["sha256"],
        )
    write_result("obj_export", result)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", help="the commit to compare with")
    ap.add_argument("--mesh", default="igea")
    ap.add_argument("--level", type=int, default=4)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(*args.one)))
    elif args.against:
        compare(args)
    else:
        ap.error("--against COMMIT is required")


if __name__ == "__main__":
    main()
