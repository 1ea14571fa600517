"""Kernels compiled ahead of need by a second process: a first run compiles on two cores.

A first run (a fresh install, a new machine) spends most of its time in numba compiling
kernels, one after another, on one core. ``signatures.json`` lists the kernels a fit calls
from Python with the argument types of each call, in the order a fit first meets them
(recorded by ``python -m meshfit._compile_ahead --record``; a test keeps it true).
:func:`start` launches ``python -m meshfit._compile_ahead``, which works through that list
in order into numba's on-disk cache, ahead of the run. The list is a queue shared by every
process compiling it: an entry is claimed (a lock on its byte of a claims file in the cache
folder) by whichever process compiles it, the helper skips entries a run has claimed, and a
run that needs an entry the helper is compiling waits for it and loads it from the cache
rather than compiling it a second time. So each kernel is compiled once, by the helper
while the run does other work, or by the run when it gets there first. Nothing depends on
the helper: an entry it has not claimed, or a signature it does not list, is compiled by the
run as before.

The helper holds a lock in the cache folder while it works (one helper at a time, however
many runs start), leaves a stamp there when every listed kernel is cached (no helper is
started after that), and stops as soon as the process that started it is gone; a claim is
a POSIX record lock, so it goes with its process, whatever ends it. It runs at the run's
priority: it compiles what the run is about to need, and at a lower one it would progress
only while the run itself compiles or waits. A command lists its scope of the manifest
(:data:`SCOPES`): a fit's first run compiles none of a shrink wrap's kernels.
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
_DONE = "meshfit-compile-ahead.done"  # .<scope>


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


#: what a run compiles: a fit's kernels (``fit``), a shrink wrap's (``wrap``) or both (``all``)
SCOPES = ("fit", "wrap", "all")


def read_manifest(path: Path = MANIFEST, scope: str = "all") -> list[tuple[str, tuple[str, ...]]]:
    """The manifest's entries for ``scope``, in the order its runs meet them: (kernel as
    ``module.name`` under ``meshfit._kernels``, encoded argument types). ``all`` is the
    fit's entries, then the shrink wrap's that a fit does not meet. A manifest of one list
    (``kernels``) has it for every scope."""
    if scope not in SCOPES:
        raise ValueError(f"scope {scope!r}: one of {SCOPES}")
    data = json.loads(path.read_text())
    if "kernels" in data:
        return [(e["kernel"], tuple(e["args"])) for e in data["kernels"]]
    lists = {
        name: [(e["kernel"], tuple(e["args"])) for e in data["scopes"][name]]
        for name in ("fit", "wrap")
    }
    if scope != "all":
        return lists[scope]
    seen = set(lists["fit"])
    return lists["fit"] + [e for e in lists["wrap"] if e not in seen]


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


def record_scope(run: Callable[[], object]) -> list[tuple[str, tuple[str, ...]]]:
    """What ``run`` meets while :func:`recording` (in a process that has called no kernel
    yet, so that it meets every one)."""
    with recording() as seen:
        run()
    return seen


def write_manifest(scopes: dict[str, list[tuple[str, tuple[str, ...]]]], path: Path) -> None:
    """Write the entries of the ``fit`` and ``wrap`` scopes to ``path``."""
    data = {
        "version": 2,
        "scopes": {
            name: [{"kernel": k, "args": list(a)} for k, a in scopes[name]]
            for name in ("fit", "wrap")
        },
    }
    path.write_text(json.dumps(data, indent=1) + "\n")


def _digest(manifest: Path) -> str:
    """The kernels' sources, the manifest and the compiler: a stamp of one is void for
    another."""
    import numba

    from meshfit._kernels import sources_digest

    here = MANIFEST.parent
    h = hashlib.sha256(sources_digest(here).encode() + manifest.read_bytes())
    h.update(f"numba {numba.__version__}, python {sys.version}".encode())  # new compiler: new code
    return h.hexdigest()


def _cache_folder() -> Path | None:
    from meshfit._kernels import _cache_folder as folder

    return folder()


def _kernel(name: str):
    """The dispatcher of ``module.name`` under :mod:`meshfit._kernels`."""
    import importlib

    module, _, attr = name.rpartition(".")
    return getattr(importlib.import_module(_PACKAGE + module), attr)


class Queue:
    """The manifest as a queue shared by the processes compiling it, in a claims file of
    the cache folder: byte ``i`` is entry ``i``. A process compiling an entry holds a POSIX
    record lock on its byte (released however the process ends), and writes 1 there once
    the entry is in the cache."""

    def __init__(self, entries: list[tuple[str, tuple[str, ...]]], fd: int) -> None:
        self.entries = entries
        self.fd = fd
        self.failed: set[int] = set()  # entries this process could not compile

    @classmethod
    def open(cls, entries: list[tuple[str, tuple[str, ...]]], path: Path) -> Queue | None:
        """The queue of ``entries`` kept in ``path`` (None when it cannot be opened)."""
        try:
            return cls(entries, os.open(path, os.O_RDWR | os.O_CREAT, 0o644))
        except OSError:
            return None

    def claim(self, i: int, *, wait: bool) -> bool:
        """Lock entry ``i`` for this process (waiting for the process holding it when
        ``wait``); False when another process holds it."""
        import fcntl

        flags = fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB
        try:
            fcntl.lockf(self.fd, flags, 1, i)
        except OSError:
            return False
        return True

    def release(self, i: int) -> None:
        import fcntl

        with contextlib.suppress(OSError):
            fcntl.lockf(self.fd, fcntl.LOCK_UN, 1, i)

    def done(self, i: int) -> bool:
        """Whether entry ``i`` is marked as cached."""
        try:
            return os.pread(self.fd, 1, i) == b"\1"
        except OSError:
            return False

    def mark(self, i: int) -> None:
        """Mark entry ``i`` as cached."""
        with contextlib.suppress(OSError):
            os.pwrite(self.fd, b"\1", i)

    def counts(self) -> tuple[int, int]:
        """(entries marked cached, entries)."""
        try:
            cached = os.pread(self.fd, len(self.entries), 0).count(b"\1")
        except OSError:
            cached = 0
        return cached, len(self.entries)

    def compile(self, i: int) -> None:
        """Compile entry ``i`` (this process holds its claim) and mark it cached."""
        kernel, args = self.entries[i]
        _kernel(kernel).compile(tuple(decode_type(a) for a in args))
        self.mark(i)

    def take_last(self, but: int) -> int | None:
        """Claim the last entry, other than ``but``, that is neither cached nor claimed;
        None when there is none."""
        for j in range(len(self.entries) - 1, -1, -1):
            if j == but or j in self.failed or self.done(j) or not self.claim(j, wait=False):
                continue
            if not self.done(j):
                return j
            self.release(j)
        return None


def compile_ahead(entries: list[tuple[str, tuple[str, ...]]], queue: Queue | None = None) -> int:
    """Compile ``entries`` in order, each into numba's cache with its helpers; returns how
    many were compiled or found cached.

    With ``queue``, an entry marked cached is passed over, and an entry another process
    has claimed is taken up again at the end, once that process is done with it."""
    if queue is None:
        for kernel, args in entries:
            _kernel(kernel).compile(tuple(decode_type(a) for a in args))
        return len(entries)
    done = 0
    skipped: list[int] = []
    for i in range(len(entries)):
        if queue.done(i):
            done += 1
        elif not queue.claim(i, wait=False):
            skipped.append(i)
        else:
            try:
                queue.compile(i)
                done += 1
            finally:
                queue.release(i)
    for i in skipped:
        queue.claim(i, wait=True)
        try:
            queue.compile(i)  # cached by the process that held it: loaded, not compiled
            done += 1
        finally:
            queue.release(i)
    return done


def _queue_path(folder: Path, stamp: str, scope: str) -> Path:
    """The claims file of the queue of ``scope`` in the cache ``folder``, named by the
    manifest's ``stamp`` (:func:`_digest`), so that a changed manifest, changed sources or
    another compiler start an empty one."""
    from meshfit._kernels import QUEUES

    return folder / f"{QUEUES}{scope}.{stamp[:16]}"


def _stamped(folder: Path, scope: str, stamp: str) -> bool:
    """Whether the cache ``folder`` holds every entry of ``scope`` (or of all scopes)."""
    for name in {scope, "all"}:
        try:
            if (folder / f"{_DONE}.{name}").read_text() == stamp:
                return True
        except OSError:
            pass
    return False


def claiming(queue: Queue) -> None:
    """From now on, this process takes its part of ``queue``: it claims each listed entry
    it calls while it compiles it; when the helper holds that entry's claim, it compiles
    the queue's last free entry meanwhile (the helper works from the first), and when none
    is left it waits, then loads the entry from the cache. Set up once per process."""
    global _queue
    if _queue is not None:
        return
    from numba import typeof
    from numba.core.dispatcher import Dispatcher

    index = {key: i for i, key in enumerate(queue.entries)}
    compile_for_args = Dispatcher._compile_for_args

    def claimed(self, *args, **kws):
        f = self.py_func
        i = None
        if f.__module__.startswith(_PACKAGE) and not kws:
            try:
                key = (
                    f"{f.__module__[len(_PACKAGE) :]}.{f.__qualname__}",
                    tuple(encode_type(typeof(a)) for a in args),
                )
                i = index.get(key)
            except ValueError:  # an argument type the manifest cannot list
                i = None
        if i is None:
            return compile_for_args(self, *args, **kws)
        while not queue.done(i) and not queue.claim(i, wait=False):
            j = queue.take_last(but=i)
            if j is None:
                queue.claim(i, wait=True)
                break
            try:
                queue.compile(j)
            except Exception:  # not this call's kernel: whoever needs it meets the error
                queue.failed.add(j)
            finally:
                queue.release(j)
        try:
            out = compile_for_args(self, *args, **kws)
            queue.mark(i)
            return out
        finally:
            queue.release(i)

    Dispatcher._compile_for_args = claimed
    _queue = queue
    from meshfit import _progress

    _progress.queue_counts = queue_progress  # the display counts the queue


#: the queue this process takes part in, once :func:`claiming` is set up
_queue: Queue | None = None


def queue_progress() -> tuple[int, int] | None:
    """(entries cached, entries) of the queue this process takes part in, counting what
    every process sharing it has compiled; None when it takes part in none."""
    return None if _queue is None else _queue.counts()


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


def start(manifest: Path = MANIFEST, scope: str = "all") -> subprocess.Popen | None:
    """Take part in the queue of ``scope`` (:func:`claiming`) and launch the helper, unless
    it has nothing to do: the cache holds every entry of the scope (its stamp), another
    helper is at work, or ``MESHFIT_COMPILE_AHEAD=0``. Returns the helper, or None."""
    if os.environ.get(ENV_SWITCH, "1") == "0" or _cores() < 2:
        return None
    if sys.platform == "win32":  # the locks are POSIX file locks
        return None
    folder = _cache_folder()
    if folder is None:
        return None
    try:
        stamp = _digest(manifest)
        entries = read_manifest(manifest, scope)
    except (OSError, ValueError, KeyError):  # no manifest, or not one: nothing to compile
        return None
    if _stamped(folder, scope, stamp):
        return None
    queue = Queue.open(entries, _queue_path(folder, stamp, scope))
    if queue is not None:
        claiming(queue)
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
            "--scope",
            scope,
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


def _run_helper(parent: int, manifest: Path, scope: str) -> int:
    """The helper process: take the lock, work through the queue of ``scope``, stamp."""
    import fcntl

    folder = _cache_folder()
    if folder is None:
        return 0
    threading.Thread(target=_watch, args=(parent,), daemon=True).start()
    try:
        lock = open(folder / _LOCK, "a")
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return 0  # another helper is at work
    with lock:
        entries = read_manifest(manifest, scope)
        stamp = _digest(manifest)
        queue = Queue.open(entries, _queue_path(folder, stamp, scope))
        if compile_ahead(entries, queue) == len(entries):
            tmp = folder / f"{_DONE}.{scope}.{os.getpid()}.tmp"
            tmp.write_text(stamp)
            os.replace(tmp, folder / f"{_DONE}.{scope}")
    return 0


def _demo_scan(folder: Path):
    """A small demo scan, saved and loaded with repair as the command line does."""
    from meshfit import load_mesh, save_mesh
    from meshfit.demo import demo_mesh

    save_mesh(demo_mesh(8000), folder / "scan.ply")
    return load_mesh(folder / "scan.ply", repair=True)


def _record_fit() -> None:
    """What the fit scope is recorded from: what a first run most likely is, on a small
    demo scan: the demo, and a fit with the automatic layout."""
    import tempfile

    from meshfit import fit
    from meshfit.demo import run_demo

    with tempfile.TemporaryDirectory() as tmp:
        mesh = _demo_scan(Path(tmp))
        run_demo(Path(tmp) / "demo", faces=8000, quiet=True)
        fit(mesh, out=Path(tmp) / "fit")


def _record_wrap() -> None:
    """What the wrap scope is recorded from: a shrink wrap of a small demo scan with its
    report, and its stream encoded and decoded."""
    import tempfile

    from meshfit import wrap
    from meshfit.shrinkwrap import Stream, decode_stream, encode_stream, wrap_report

    with tempfile.TemporaryDirectory() as tmp:
        mesh = _demo_scan(Path(tmp))
    res = wrap(mesh, levels=3)
    wrap_report(res)
    top = res.levels[-1]
    stream = encode_stream(top.vertices, res.base.faces, len(res.base.sphere), top.level)
    decode_stream(Stream.from_bytes(stream.to_bytes()))


_RECORDERS = {"fit": _record_fit, "wrap": _record_wrap}


def _record(path: Path) -> int:
    """Record each scope in a fresh process (one that has met no kernel) and write the
    manifest; returns the number of entries over all scopes."""
    env = {**os.environ, ENV_SWITCH: "0"}  # the runs recorded start no helper of their own
    scopes = {}
    for name in _RECORDERS:
        run = subprocess.run(
            [sys.executable, "-m", "meshfit._compile_ahead", "--record-scope", name],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        rows = json.loads(run.stdout.strip().splitlines()[-1])
        scopes[name] = [(k, tuple(a)) for k, a in rows]
    write_manifest(scopes, path)
    return sum(len(v) for v in scopes.values())


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m meshfit._compile_ahead")
    ap.add_argument("--parent", type=int, help="stop when this process is gone")
    ap.add_argument("--manifest", type=Path, default=MANIFEST, help="kernels to compile")
    ap.add_argument("--scope", choices=SCOPES, default="all", help="which of its kernels")
    ap.add_argument("--record", action="store_true", help="record the manifest again")
    ap.add_argument("--record-scope", choices=sorted(_RECORDERS), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.record_scope:
        seen = record_scope(_RECORDERS[args.record_scope])
        print(json.dumps(seen))
        return 0
    if args.record:
        n = _record(args.manifest)
        print(f"{n} kernel signatures recorded in {args.manifest}")
        return 0
    parent = args.parent if args.parent is not None else os.getppid()
    return _run_helper(parent, args.manifest, args.scope)


if __name__ == "__main__":
    sys.exit(main())
