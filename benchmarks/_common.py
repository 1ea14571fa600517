"""Helpers shared by the benchmark scripts: data paths, timing, JSON output."""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

from meshfit._atomic import write_text

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def mesh_path(name: str) -> Path:
    """Path of a shared test mesh (MESHFIT_DATA, else ../shared/data beside the repository)."""
    for base in (
        os.environ.get("MESHFIT_DATA"),
        ROOT.parent / "shared" / "data",
        "/work/shared/data",
    ):
        if base and (Path(base) / "meshes" / f"{name}.ply").is_file():
            return Path(base) / "meshes" / f"{name}.ply"
    sys.exit(f"benchmark data not found: {name}.ply (set MESHFIT_DATA)")


def median_time(fn, repeats: int, clock=time.perf_counter) -> tuple[float, list[float]]:
    """Median time of ``repeats`` calls of ``fn()`` and all the times, by ``clock`` (wall time
    by default)."""
    times = []
    for _ in range(repeats):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return statistics.median(times), times


def median_cpu_time(fn, repeats: int) -> tuple[float, list[float]]:
    """Median CPU time of this process (every thread) over ``repeats`` calls of ``fn()``: less
    disturbed than wall time by other jobs on a shared machine."""
    return median_time(fn, repeats, clock=time.process_time)


def write_result(name: str, data: dict) -> None:
    """Print ``data`` as JSON and write it atomically to benchmarks/results/<name>.json."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    text = json.dumps(data, indent=2)
    print(text)
    write_text(RESULTS / f"{name}.json", text + "\n")
