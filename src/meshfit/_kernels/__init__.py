"""Numba kernels (nopython, compiled once and cached on disk).

numba checks a kernel's cached machine code against the kernel's own file only, but kernels
here call helpers of other files of this package, compiled into the caller's machine code
(the walks of ``walk.py`` in ``springs.py``, ``curves.py``, ``snakes.py`` and ``bvh.py``).
So a digest of all the files here is kept beside the caches, and when it changes every
cache of this package is dropped before any is loaded: an edited helper is never run in
its old form by a caller whose own file did not change.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import os
from pathlib import Path


def frozen(*arrays):
    """Read-only views of arrays a kernel only reads (no copy). numba compiles a kernel once
    per signature, and a writable and a read-only array of one type are two signatures: a
    kernel called with both compiles twice on a first run. Callers of kernels that meet
    both (a mesh's read-only arrays, arrays made on the way) pass their inputs through this.
    """
    out = []
    for a in arrays:
        v = a.view()
        v.flags.writeable = False
        out.append(v)
    return tuple(out)


def inner(func):
    """Decorator of a helper kernel that only other kernels call (``njit``, cached, no GIL,
    no ``fastmath``).

    Every compiled kernel also gets a wrapper that unboxes Python arguments: code that is
    generated, optimised and turned into machine code for each signature, and that a helper
    called only from compiled code never runs (its callers link its code, not its
    wrapper). A helper declared here is compiled without it, which shortens a first run's
    compiling; called from Python it raises :class:`TypeError` instead.
    """
    from numba.core import config

    if config.DISABLE_JIT:
        return func
    disp = _inner_dispatcher()(
        py_func=func,
        locals={},
        targetoptions={"nopython": True, "nogil": True, "no_cpython_wrapper": True},
    )
    disp.enable_caching()
    return disp


@functools.cache
def _inner_dispatcher() -> type:
    """The dispatcher class of :func:`inner` helpers (made on first use: importing this
    package does not import numba)."""
    from numba.core.registry import CPUDispatcher

    class InnerDispatcher(CPUDispatcher):
        def __call__(self, *args, **kwargs):
            raise TypeError(
                f"{self.py_func.__module__}.{self.py_func.__qualname__} is compiled to be "
                "called from kernels only"
            )

    return InnerDispatcher


#: pieces per thread that :func:`split` cuts a range into: a thread that finishes its
#: pieces early takes others, so uneven pieces do not leave a core idle at the end
PIECES_PER_THREAD = 4


def split(kernel, n: int, *args, min_piece: int = 1) -> None:
    """Run ``kernel(*args, lo, hi)`` over pieces ``[lo, hi)`` that cover ``range(n)``, on
    the calling thread and up to ``NUMBA_NUM_THREADS - 1`` worker threads.

    It is the parallel loop of a kernel whose iterations are independent and each write
    only their own rows of arrays in ``args``: the result is the same however the range is
    cut and whichever thread runs a piece. A numba ``prange`` does the same inside the
    kernel, but each such loop is compiled as a separate function with its own scheduler,
    which costs a first run more compiling than the whole serial kernel. The caller takes
    pieces too and stops waiting for a worker that has not started, so a call made while
    the workers are busy (several threads calling at once) still finishes.
    """
    from numba import config

    threads = max(1, int(config.NUMBA_NUM_THREADS))
    pieces = min(threads * PIECES_PER_THREAD, n // max(1, min_piece))
    if threads == 1 or pieces <= 1:
        if n > 0:
            kernel(*args, 0, n)
        return
    bounds = [n * i // pieces for i in range(pieces + 1)]
    counter = itertools.count()  # next() is atomic under the GIL

    def work() -> None:
        while (i := next(counter)) < pieces:
            kernel(*args, bounds[i], bounds[i + 1])

    pool = _workers(threads - 1)
    helpers = [pool.submit(work) for _ in range(min(threads, pieces) - 1)]
    try:
        work()
    finally:
        for h in helpers:
            if not h.cancel():
                h.result()


@functools.cache
def _workers(n: int):
    """The threads :func:`split` hands pieces to (made on first use, kept)."""
    from concurrent.futures import ThreadPoolExecutor

    return ThreadPoolExecutor(max_workers=n, thread_name_prefix="meshfit-kernels")


#: the file beside the caches holding the digest of the sources they were compiled from
STAMP = "meshfit-kernels.sha256"

#: files beside the caches marking what they hold (the queues of ``meshfit._compile_ahead``)
QUEUES = "meshfit-compile-ahead.claims."


def sources_digest(folder: Path) -> str:
    """SHA-256 over the names and contents of the ``*.py`` files of ``folder``, in name
    order."""
    h = hashlib.sha256()
    for src in sorted(folder.glob("*.py")):
        h.update(src.name.encode() + b"\0" + src.read_bytes() + b"\0")
    return h.hexdigest()


def drop_stale_caches(sources: Path, caches: Path) -> bool:
    """Delete numba's cache files (``*.nbi``, ``*.nbc``) and the queues marking them
    (:data:`QUEUES`) in ``caches`` unless the digest of ``sources`` is the one stamped
    there, then stamp it. Returns whether files were dropped.

    Best effort: a folder that cannot be read or written is left as it is (numba then
    compiles into its own fallback location).
    """
    key = sources_digest(sources)
    stamp = caches / STAMP
    try:
        if stamp.read_text() == key:
            return False
    except OSError:
        pass
    try:
        caches.mkdir(parents=True, exist_ok=True)
        dropped = False
        for f in caches.iterdir():
            if f.suffix in (".nbi", ".nbc") or f.name.startswith(QUEUES):
                f.unlink(missing_ok=True)
                dropped = True
        tmp = caches / f"{STAMP}.{os.getpid()}.tmp"
        tmp.write_text(key)
        os.replace(tmp, stamp)
    except OSError:
        return False
    return dropped


def _cache_folder() -> Path | None:
    """Where numba keeps the caches of the kernels of this folder (None when it cannot
    tell)."""
    try:
        from numba.core.caching import FunctionCache

        return Path(FunctionCache(_cache_folder).cache_path)
    except Exception:  # numba without this API, or no cache locator: nothing is dropped
        return None


def _plain_calls() -> None:
    """Kernels called from kernels are compiled for plain argument types.

    numba types a constant argument of a call between compiled functions as a literal
    (``Literal[int](32)``, not ``int64``) and compiles the callee once per literal value:
    calls of one helper with the constants 16, 32 and 64 compiled it three times. For the
    kernels of this package the call is typed with the plain types instead (as numba
    itself does for its library overloads); the compiled code is the same up to constant
    folding, which the compiler still does after it inlines the callee.
    """
    from numba.core import types
    from numba.core.dispatcher import _DispatcherBase

    original = _DispatcherBase.get_call_template
    if getattr(original, "plain_for", None) == __name__:
        return
    prefix = __name__ + "."

    def get_call_template(self, args, kws):
        if getattr(self.py_func, "__module__", "").startswith(prefix):
            args = tuple(types.unliteral(a) for a in args)
            kws = {k: types.unliteral(v) for k, v in kws.items()}
        return original(self, args, kws)

    get_call_template.plain_for = __name__  # type: ignore[attr-defined]
    _DispatcherBase.get_call_template = get_call_template


_plain_calls()
_folder = _cache_folder()
if _folder is not None:
    drop_stale_caches(Path(__file__).resolve().parent, _folder)
