"""Benchmark: what a fit writes, against an earlier commit in the same run.

Usage: ``python benchmarks/outputs.py --against COMMIT [--meshes spot,nefertiti,igea]
[--repeats 3]``

Each mesh is fitted with the automatic layout and each side's default options and formats
(what a user gets from ``meshfit fit SCAN``; the report off on both sides, its images are
not exports), in a fresh process per run, alternating this checkout and ``COMMIT`` (a git
worktree) after one warm-up run each. Printed per mesh and side: the exports stage's
seconds (median over the runs), the files and megabytes of the folder, and the same without
the stage cache (``stages/`` before, ``.meshfit/`` now). Writes ``outputs.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import mesh_path, worktree, write_result

CACHES = ("stages", ".meshfit")


def one(name: str) -> dict:
    """One fit of ``name`` into a fresh folder; the figures of its folder."""
    import pxr.Usd  # noqa: F401  (loaded on the main thread on both sides, as the fit does)

    import meshfit.pipeline as pipeline
    from meshfit.mesh import load_mesh
    from meshfit.pipeline import FitOptions

    mesh = load_mesh(mesh_path(name), repair=True)
    opts = FitOptions(report=False)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        if hasattr(pipeline, "run_fit"):
            s = pipeline.run_fit(mesh, out, layout="auto", options=opts)
        else:
            s = pipeline.fit(mesh, "auto", options=opts, out=out).summary
        files = [p for p in out.rglob("*") if p.is_file()]
        kept = [p for p in files if p.relative_to(out).parts[0] not in CACHES]
        return {
            "patches": s["patches_total"],
            "formats": list(opts.formats),
            "exports_seconds": s["stages"]["exports"]["seconds"],
            "files": len(files),
            "megabytes": round(sum(p.stat().st_size for p in files) / 2**20, 2),
            "files_without_cache": len(kept),
            "megabytes_without_cache": round(sum(p.stat().st_size for p in kept) / 2**20, 2),
        }


def _run(name: str, src: str | None = None) -> dict:
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = src
    run = subprocess.run(
        [sys.executable, __file__, "--one", name], capture_output=True, text=True, env=env
    )
    if run.returncode != 0:
        raise RuntimeError(run.stderr[-2000:])
    return json.loads(run.stdout.strip().splitlines()[-1])


def _median(runs: list[dict]) -> dict:
    out = dict(runs[0])
    out["exports_seconds"] = round(statistics.median(r["exports_seconds"] for r in runs), 3)
    out["exports_seconds_runs"] = [r["exports_seconds"] for r in runs]
    return out


def compare(args) -> None:
    result: dict = {"benchmark": "outputs", "against": args.against, "runs": args.repeats}
    with worktree(args.against) as old:
        for name in args.meshes.split(","):
            _run(name), _run(name, str(old / "src"))  # warm-up (kernel caches)
            new, prev = [], []
            for _ in range(max(1, args.repeats)):
                new.append(_run(name))
                prev.append(_run(name, str(old / "src")))
            a, b = _median(new), _median(prev)
            result[name] = {
                "new": a,
                "old": b,
                "exports_new_over_old": round(
                    a["exports_seconds"] / max(b["exports_seconds"], 1e-9), 3
                ),
                "files_new_over_old": round(a["files"] / b["files"], 3),
                "megabytes_new_over_old": round(a["megabytes"] / b["megabytes"], 3),
            }
            print(name, json.dumps(result[name]), flush=True)
    write_result("outputs", result)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", help="the commit to compare with")
    ap.add_argument("--meshes", default="spot,nefertiti,igea")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one)))
    elif args.against:
        compare(args)
    else:
        ap.error("--against COMMIT is required")


if __name__ == "__main__":
    main()
