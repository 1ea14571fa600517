"""Helpers shared by the benchmark scripts: data paths, timing, JSON output."""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from meshfit._atomic import write_text

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


@contextmanager
def worktree(commit: str) -> Iterator[Path]:
    """A git worktree of ``commit`` of this repository in a temporary folder (removed on
    exit): the ``src`` folder of an earlier meshfit, for the ``--against`` comparisons."""
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "old"
        git = ["git", "-C", str(ROOT), "worktree"]
        subprocess.run([*git, "add", "-f", "--detach", str(old), commit], check=True,
                       capture_output=True)  # fmt: skip
        try:
            yield old
        finally:
            subprocess.run([*git, "remove", "--force", str(old)], check=False,
                           capture_output=True)  # fmt: skip


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
