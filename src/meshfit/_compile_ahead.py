"""Kernels compiled ahead of need by a second process: a first run compiles on two cores.

A first run (a fresh install, a new machine) spends most of its time in numba compiling
kernels, one after another, on one core. ``signatures.json`` lists the kernels a fit calls
from Python with the argument types of each call, in the order a fit first meets them
(recorded by ``python -m meshfit._compile_ahead --record``; a test keeps it true).
:func:`start` launches ``python -m meshfit._compile_ahead``, which compiles them from the
last to the first into numba's on-disk cache while the run compiles from the first: a
kernel the helper has finished is loaded from the cache when the run gets to it, and the two
meet in the middle. Nothing depends on the helper: a kernel it has not reached, or a
signature it does not list, is compiled by the run as before.

The helper holds a lock in the cache folder while it works (one helper at a time, however
many runs start), leaves a stamp there when every listed kernel is cached (no helper is
started after that), runs at a lower priority than the run, and stops as soon as the
process that started it is gone.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

#: the kernels and argument types a fit calls, in the order it first meets them
MANIFEST = Path(__file__).resolve().parent / "_kernels" / "signatures.json"

#: environment variable that, set to 0, keeps :func:`start` from launching the helper
ENV_SWITCH = "MESHFIT_COMPILE_AHEAD"

_PACKAGE = "meshfit._kernels."
_LOCK = "meshfit-compile-ahead.lock"
_DONE = "meshfit-compile-ahead.done"


def encode_type(t) -> str:
    """A numba argument type as a short string: ``int64``, ``float64``, ``bool``, or an
    array as ``float64[2d,C]`` (``,ro`` when read-only)."""
    from numba.core import types

    if isinstance(t, types.Array):
        ro = ",ro" if not t.mutable else ""
        return f"{t.dtype}[{t.ndim}d,{t.layout}{ro}]"
    if isinstance(t, (types.Integer, types.Float, types.Boolean)):
        return str(t)
    raise ValueError(f"no short form for the argument type {t}")


def decode_type(text: str):
    """The numba type :func:`encode_type` wrote as ``text``."""
    from numba.core import types

    if text.endswith("]"):
        dtype, _, spec = text[:-1].partition("[")
        parts = spec.split(",")
        if len(parts) not in (2, 3) or not parts[0].endswith("d") or parts[1] not in "CFA":
            raise ValueError(f"not an array type: {text!r}")
        ro = len(parts) == 3 and parts[2] == "ro"
        return types.Array(_scalar(dtype), int(parts[0][:-1]), parts[1], readonly=ro)
    return _scalar(text)


def _scalar(name: str):
    from numba.core import types

    t = getattr(types, "boolean" if name == "bool" else name, None)
    if not isinstance(t, (types.Integer, types.Float, types.Boolean)):
        raise ValueError(f"not a scalar type: {name!r}")
    return t


def read_manifest(path: Path = MANIFEST) -> list[tuple[str, tuple[str, ...]]]:
    """The manifest's entries: (kernel as ``module.name`` under ``meshfit._kernels``,
    encoded argument types)."""
    data = json.loads(path.read_text())
    return [(e["kernel"], tuple(e["args"])) for e in data["kernels"]]


@contextlib.contextmanager
def recording() -> Iterator[list[tuple[str, tuple[str, ...]]]]:
    """Collect, while open, every kernel of this package that Python calls with argument
    types not met before, with those types, in the order met (whether its code is then
    compiled or loaded from the cache)."""
    from numba import typeof
    from numba.core.dispatcher import Dispatcher

    seen: list[tuple[str, tuple[str, ...]]] = []
    known: set[tuple[str, tuple[str, ...]]] = set()
    first_call = Dispatcher._compile_for_args

    def record(self, *args, **kws):
        f = self.py_func
        if f.__module__.startswith(_PACKAGE) and not kws:
            key = (
                f"{f.__module__[len(_PACKAGE) :]}.{f.__qualname__}",
                tuple(encode_type(typeof(a)) for a in args),
            )
            if key not in known:
                known.add(key)
                seen.append(key)
        return first_call(self, *args, **kws)

    Dispatcher._compile_for_args = record
    try:
        yield seen
    finally:
        Dispatcher._compile_for_args = first_call


def record_manifest(run: Callable[[], object], path: Path = MANIFEST) -> int:
    """Run ``run`` while :func:`recording` and write what it met to ``path``; returns the
    number of entries."""
    with recording() as seen:
        run()
    text = json.dumps(
        {"version": 1, "kernels": [{"kernel": k, "args": list(a)} for k, a in seen]},
        indent=1,
    )
    path.write_text(text + "\n")
    return len(seen)


def _digest(manifest: Path) -> str:
    """The kernels' sources and the manifest: a stamp of one is void for the other."""
    from meshfit._kernels import sources_digest

    here = MANIFEST.parent
    return hashlib.sha256(sources_digest(here).encode() + manifest.read_bytes()).hexdigest()


def _cache_folder() -> Path | None:
    from meshfit._kernels import _cache_folder as folder

    return folder()


def compile_ahead(entries: list[tuple[str, tuple[str, ...]]]) -> int:
    """Compile ``entries`` last first (each into numba's cache, its helpers with it);
    returns how many were compiled or found cached."""
    import importlib

    done = 0
    for kernel, args in reversed(entries):
        module, _, name = kernel.rpartition(".")
        dispatcher = getattr(importlib.import_module(_PACKAGE + module), name)
        dispatcher.compile(tuple(decode_type(a) for a in args))
        done += 1
    return done


def _cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _held(lock: Path) -> bool:
    """Whether another process holds ``lock`` (no wait)."""
    import fcntl

    try:
        with open(lock, "a") as f:
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                return True
            fcntl.flock(f, fcntl.LOCK_UN)
            return False
    except OSError:
        return True  # a folder that cannot be written: no helper could cache anything


def start(manifest: Path = MANIFEST) -> subprocess.Popen | None:
    """Launch the helper unless it has nothing to do: the cache holds every listed kernel
    (its stamp), another helper is at work, or ``MESHFIT_COMPILE_AHEAD=0``. Returns the
    process, or None."""
    if os.environ.get(ENV_SWITCH, "1") == "0" or _cores() < 2:
        return None
    if sys.platform == "win32":  # the lock is a POSIX file lock
        return None
    folder = _cache_folder()
    if folder is None:
        return None
    try:
        stamp = _digest(manifest)
    except OSError:  # no manifest: nothing to compile ahead
        return None
    try:
        if (folder / _DONE).read_text() == stamp:
            return None
    except OSError:
        pass
    if _held(folder / _LOCK):
        return None
    global _helper
    _helper = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "meshfit._compile_ahead",
            "--parent",
            str(os.getpid()),
            "--manifest",
            str(manifest),
        ],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # Ctrl-C in a terminal goes to the run, not to the helper
    )
    atexit.register(stop)
    return _helper


#: the helper this process started, if any
_helper: subprocess.Popen | None = None


def stop() -> None:
    """End the helper this process started, if it is still at work (numba writes each
    cache file under a temporary name and renames it whole, so nothing is left half
    written; what it had not reached is compiled by the next run's helper)."""
    global _helper
    if _helper is not None and _helper.poll() is None:
        _helper.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            _helper.wait(timeout=5)
    _helper = None


def _watch(parent: int) -> None:
    """End this process as soon as ``parent`` is gone (polled: the helper is its child)."""
    while os.getppid() == parent:
        time.sleep(0.25)
    os._exit(0)


def _run_helper(parent: int, manifest: Path) -> int:
    """The helper process: take the lock, compile the manifest last first, stamp."""
    import fcntl

    folder = _cache_folder()
    if folder is None:
        return 0
    threading.Thread(target=_watch, args=(parent,), daemon=True).start()
    with contextlib.suppress(OSError):
        os.nice(10)
    try:
        lock = open(folder / _LOCK, "a")
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return 0  # another helper is at work
    with lock:
        entries = read_manifest(manifest)
        if compile_ahead(entries) == len(entries):
            tmp = folder / f"{_DONE}.{os.getpid()}.tmp"
            tmp.write_text(_digest(manifest))
            os.replace(tmp, folder / _DONE)
    return 0


def _record_runs() -> None:
    """What the manifest is recorded from: what a first run most likely is, on a small demo
    scan: the demo, a fit with the automatic layout, and a shrink wrap with its report and
    its stream encoded and decoded."""
    import tempfile

    from meshfit import fit, load_mesh, save_mesh, wrap
    from meshfit.demo import demo_mesh, run_demo
    from meshfit.shrinkwrap import Stream, decode_stream, encode_stream, wrap_report

    with tempfile.TemporaryDirectory() as tmp:
        save_mesh(demo_mesh(8000), Path(tmp) / "scan.ply")
        mesh = load_mesh(Path(tmp) / "scan.ply", repair=True)  # as the command line does
        run_demo(Path(tmp) / "demo", faces=8000, quiet=True)
        fit(mesh, out=Path(tmp) / "fit")
    res = wrap(mesh, levels=3)
    wrap_report(res)
    top = res.levels[-1]
    stream = encode_stream(top.vertices, res.base.faces, len(res.base.sphere), top.level)
    decode_stream(Stream.from_bytes(stream.to_bytes()))


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m meshfit._compile_ahead")
    ap.add_argument("--parent", type=int, help="stop when this process is gone")
    ap.add_argument("--manifest", type=Path, default=MANIFEST, help="kernels to compile")
    ap.add_argument("--record", action="store_true", help="record the manifest again")
    args = ap.parse_args(argv)
    if args.record:
        os.environ[ENV_SWITCH] = "0"  # the runs recorded start no helper of their own
        n = record_manifest(_record_runs, args.manifest)
        print(f"{n} kernel signatures recorded in {args.manifest}")
        return 0
    return _run_helper(args.parent if args.parent is not None else os.getppid(), args.manifest)


if __name__ == "__main__":
    sys.exit(main())
