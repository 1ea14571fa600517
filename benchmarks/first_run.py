"""Benchmark: the first ``meshfit demo`` on a fresh install (kernels compiled) against a later
run (kernels loaded from the cache).

Usage: ``python benchmarks/first_run.py [--faces 200000] [--repeats 1]``

Each run is a fresh process of ``meshfit demo``. The first runs with an empty numba cache
folder (``NUMBA_CACHE_DIR``), as after ``pip install``; the second with the cache the first
filled: the peer, today's speed once compiled. A third, again with an empty cache, has the
second process that compiles ahead of need switched off (``MESHFIT_COMPILE_AHEAD=0``): one
core compiling, the other peer. A listener on numba's compile events sums the seconds
spent compiling kernels called from Python (their callees count as theirs), counts how
often one kernel is compiled for more than one signature, and counts the compilations of
numba's shape-mismatch error path of array assignments (string formatting code), all in
the run's own process: what the second process compiled is loaded from the cache. Target
(issue 52): the first run within 60 s on two cores. With ``--repeats``, the medians (and
every run's wall time) of that many rounds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from _common import write_result

TARGET_FIRST_RUN = 60.0

_RUN = """
import json, sys, time
from collections import Counter
from numba.core import event
spent, names, secs, depth, t0, who = [0.0], Counter(), Counter(), [0], [0.0], [""]
error_paths = [0]
class Compiles(event.Listener):
    def on_start(self, ev):
        if "raise_with_shape_context" in ev.data["dispatcher"].py_func.__qualname__:
            error_paths[0] += 1
        if depth[0] == 0:
            t0[0] = time.perf_counter()
            f = ev.data["dispatcher"].py_func
            who[0] = f.__module__.rsplit(".", 1)[-1] + "." + f.__qualname__
            names[who[0]] += 1
        depth[0] += 1
    def on_end(self, ev):
        depth[0] -= 1
        if depth[0] == 0:
            spent[0] += time.perf_counter() - t0[0]
            secs[who[0]] += time.perf_counter() - t0[0]
event.register("numba:compile", Compiles())
from meshfit.cli import main
rc = main(["demo", "--out", sys.argv[1], "--faces", sys.argv[2], "--json"])
top = [(k, round(v, 1)) for k, v in secs.most_common(8)]
print(json.dumps({"rc": rc, "compile_s": spent[0], "compiles": sum(names.values()),
                  "kernels": len(names), "recompiled": sum(1 for n in names.values() if n > 1),
                  "shape_error_paths": error_paths[0],
                  "slowest_s": top}), file=sys.stderr)
"""


def run(faces: int, cache: str, out: str, *, ahead: bool = True) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, MESHFIT_COMPILE_AHEAD="1" if ahead else "0")
    t = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-c", _RUN, out, str(faces)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    wall = time.perf_counter() - t
    info = json.loads(p.stderr.strip().splitlines()[-1])
    info["wall_s"] = round(wall, 1)
    info["compile_s"] = round(info["compile_s"], 1)
    return info


def _median(runs: list[dict]) -> dict:
    """The run of median wall time, with every run's wall time."""
    mid = sorted(runs, key=lambda r: r["wall_s"])[len(runs) // 2]
    return {**mid, "wall_s_runs": [r["wall_s"] for r in runs]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--faces", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=1, help="rounds of the three runs")
    args = ap.parse_args()
    firsts, laters, alones = [], [], []
    for r in range(max(1, args.repeats)):
        with tempfile.TemporaryDirectory() as tmp:
            cache = os.path.join(tmp, "numba-cache")
            firsts.append(run(args.faces, cache, os.path.join(tmp, "first")))
            laters.append(run(args.faces, cache, os.path.join(tmp, "later")))
            alone_cache = os.path.join(tmp, "c2")
            alones.append(run(args.faces, alone_cache, os.path.join(tmp, "alone"), ahead=False))
        print(f"round {r + 1}: first {firsts[-1]['wall_s']} s", file=sys.stderr, flush=True)
    first, later, alone = _median(firsts), _median(laters), _median(alones)
    result = {
        "faces": args.faces,
        "cpus": os.cpu_count(),
        "rounds": len(firsts),
        "first_run": first,
        "later_run": later,
        "first_run_one_process": alone,
        "first_over_later": round(first["wall_s"] / later["wall_s"], 2),
        "first_over_one_process": round(first["wall_s"] / alone["wall_s"], 2),
        "target_first_run_s": TARGET_FIRST_RUN,
        "first_over_target": round(first["wall_s"] / TARGET_FIRST_RUN, 2),
    }
    write_result("first_run", result)


if __name__ == "__main__":
    main()
