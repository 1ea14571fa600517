"""Benchmark: where a first run's compiling goes, phase by phase.

Usage: ``python benchmarks/compile_phases.py [--scope fit] [--repeats 1]``

Compiles every entry of a scope of the kernel manifest (``_kernels/signatures.json``, the
kernels a fit calls from Python with their argument types) in a fresh process with an
empty numba cache folder and the second compiling process off: the whole of a first run's
compiling, on one core. Two listeners on numba's own events split the seconds:

- ``numba:run_pass`` brackets each compiler pass (bytecode analysis, type inference,
  lowering, ...). A helper kernel is compiled inside its caller's type inference, so each
  pass is charged its own seconds only (exclusive of the passes nested in it).
- ``numba:llvm_lock`` brackets every call into LLVM (parsing the generated IR, function
  and module optimisation, machine code). Those seconds are charged to the pass they fall
  in and summed apart: the rest of a pass is numba's own Python.

Each figure is printed with its share of the whole compile (measured in the same
process). The listeners cost time of their own (one Python call per entry into LLVM): each
round also compiles the scope without them, in another fresh process (the peer), and the
listened total over it is the overhead that the shares carry, mostly in numba's Python.
Reading it: a phase that is numba's Python (typing, lowering) shrinks only with less code
to compile; LLVM's shrinks with less code or cheaper optimisation.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

from _common import write_result

_RUN = """
import json, sys, time
from collections import Counter, defaultdict
from numba.core import event

scope, listen = sys.argv[1], sys.argv[2] == "1"
stack = []          # [name, start, seconds of nested passes, LLVM seconds in it]
py_s = Counter()    # pass -> exclusive seconds outside LLVM
llvm_in = Counter() # pass -> LLVM seconds within it
llvm = [0, 0.0, 0.0]  # depth, start, total
outside = [0.0]

class Passes(event.Listener):
    def on_start(self, ev):
        stack.append([ev.data["name"].split(" [")[0], time.perf_counter(), 0.0, 0.0])
    def on_end(self, ev):
        name, t0, nested, in_llvm = stack.pop()
        took = time.perf_counter() - t0
        own = took - nested
        py_s[name] += own - in_llvm
        llvm_in[name] += in_llvm
        if stack:
            stack[-1][2] += took

class Llvm(event.Listener):
    def on_start(self, ev):
        if llvm[0] == 0:
            llvm[1] = time.perf_counter()
        llvm[0] += 1
    def on_end(self, ev):
        llvm[0] -= 1
        if llvm[0] == 0:
            took = time.perf_counter() - llvm[1]
            llvm[2] += took
            if stack:
                stack[-1][3] += took
            else:
                outside[0] += took

from meshfit._compile_ahead import _kernel, decode_type, read_manifest
entries = read_manifest(scope=scope)
kernels = [(_kernel(k), k, tuple(decode_type(a) for a in args)) for k, args in entries]
if listen:
    event.register("numba:run_pass", Passes())
    event.register("numba:llvm_lock", Llvm())
per = Counter()
t = time.perf_counter()
for disp, name, sig in kernels:
    t0 = time.perf_counter()
    disp.compile(sig)
    per[name] += time.perf_counter() - t0
total = time.perf_counter() - t
print(json.dumps({"entries": len(entries), "total_s": total, "llvm_s": llvm[2],
                  "llvm_outside_passes_s": outside[0], "python_s": dict(py_s),
                  "llvm_in_s": dict(llvm_in), "kernels_s": per.most_common(12)}))
"""


def run(scope: str, listen: bool = True) -> dict:
    """One compile of ``scope`` in a fresh process with an empty cache folder (``listen``:
    with the listeners)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, MESHFIT_COMPILE_AHEAD="0")
        p = subprocess.run(
            [sys.executable, "-c", _RUN, scope, "1" if listen else "0"],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
    return json.loads(p.stdout.strip().splitlines()[-1])


def _share(seconds: float, total: float) -> dict:
    return {"s": round(seconds, 2), "of_total": round(seconds / total, 3)}


def summarise(r: dict, bare: dict) -> dict:
    """Phases as seconds and shares of the whole compile: numba's Python by pass (the
    largest first, passes under 1 % of the total pooled), LLVM by the pass it falls in."""
    total = r["total_s"]
    python = sorted(r["python_s"].items(), key=lambda kv: -kv[1])
    big = {k: _share(v, total) for k, v in python if v >= 0.01 * total}
    small = sum(v for _, v in python if v < 0.01 * total)
    big["other passes"] = _share(small, total)
    big_llvm = {k: v for k, v in r["llvm_in_s"].items() if v >= 0.01 * total}
    llvm = {k: _share(v, total) for k, v in big_llvm.items()}
    llvm["elsewhere"] = _share(r["llvm_s"] - sum(big_llvm.values()), total)
    return {
        "entries": r["entries"],
        "total_s": round(total, 1),
        "total_without_listeners_s": round(bare["total_s"], 1),
        "listened_over_without": round(total / bare["total_s"], 3),
        "llvm": _share(r["llvm_s"], total),
        "numba_python": _share(total - r["llvm_s"], total),
        "numba_python_by_pass": big,
        "llvm_by_pass": llvm,
        "slowest_kernels_s": [[k, round(v, 1)] for k, v in r["kernels_s"]],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scope", default="fit", choices=("fit", "wrap", "all"))
    ap.add_argument("--repeats", type=int, default=1, help="rounds, each a fresh process")
    args = ap.parse_args()
    rounds = []
    for _ in range(args.repeats):
        bare = run(args.scope, listen=False)
        rounds.append(summarise(run(args.scope), bare))
    totals = sorted(r["total_s"] for r in rounds)
    peers = sorted(r["total_without_listeners_s"] for r in rounds)
    out = {
        "benchmark": "compile_phases",
        "scope": args.scope,
        "cpus": len(os.sched_getaffinity(0)),
        "rounds": rounds,
        "total_s_median": totals[len(totals) // 2],
        "total_without_listeners_s_median": peers[len(peers) // 2],
    }
    write_result(f"compile_phases_{args.scope}", out)


if __name__ == "__main__":
    main()
