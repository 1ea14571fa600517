"""Allocator settings of the ``meshfit`` command's process.

A fit of a dense scan makes and drops many arrays of tens of megabytes. With glibc's
defaults each of them is a fresh ``mmap`` whose pages fault in one by one and go back to the
system when freed, so the next array of that size faults again. The command keeps such
arrays on the heap and the freed pages in the process instead: fewer page faults and a
somewhat faster fit of a dense scan, at the same peak memory (see
``benchmarks/pipeline.py``). Library callers keep their process's settings: only
:func:`meshfit.cli.main` and the benchmark that stands for it call :func:`tune_malloc`.
"""

from __future__ import annotations

import ctypes
import functools
import sys

__all__ = ["peak_rss", "release_memory", "tune_malloc"]

#: ``mallopt`` parameters (glibc ``malloc.h``)
_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3
#: blocks up to this size come from the heap (glibc's upper bound for the threshold)
MMAP_THRESHOLD = 32 << 20
#: free memory at the top of the heap kept up to this size
TRIM_THRESHOLD = 1 << 30
#: the heap grows by at least this much at a time (address space; pages fault when used)
TOP_PAD = 256 << 20


def _libc():
    """glibc through ctypes (with ``mallopt`` and ``malloc_trim``) on Linux, else None."""
    return _glibc() if sys.platform.startswith("linux") else None


@functools.cache
def _glibc():
    """The C library with the two functions, looked up once, or None: the process's own
    symbols first (the interpreter is linked against it), then ``libc.so.6`` by name. Never
    ``ctypes.util.find_library``, which runs ``ldconfig`` in a child process: a fork of a
    process that may hold gigabytes at that moment."""
    for name in (None, "libc.so.6"):
        try:
            libc = ctypes.CDLL(name)
            libc.mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
            libc.mallopt.restype = ctypes.c_int
            libc.malloc_trim.argtypes = (ctypes.c_size_t,)
            libc.malloc_trim.restype = ctypes.c_int
        except (OSError, AttributeError):
            continue
        return libc
    return None


def tune_malloc() -> bool:
    """Apply the settings above through glibc's ``mallopt``.

    Returns
    -------
    bool
        True if glibc took all three; False elsewhere (other systems or C libraries keep
        their defaults, which only costs speed).
    """
    libc = _libc()
    if libc is None:
        return False
    settings = (
        (_M_MMAP_THRESHOLD, MMAP_THRESHOLD),
        (_M_TRIM_THRESHOLD, TRIM_THRESHOLD),
        (_M_TOP_PAD, TOP_PAD),
    )
    return all(libc.mallopt(p, v) == 1 for p, v in settings)


def release_memory() -> None:
    """Collect garbage and hand the heap's free pages back to the system (glibc's
    ``malloc_trim``; a no-op elsewhere). Called where a fit has just dropped a large working
    set (the layout's adjacency, one surface's search tree) before it builds the next, so
    the freed pages count once in the peak instead of twice (freed memory on the heap is
    otherwise kept up to the trim threshold, and reused only by allocations that fit its
    gaps)."""
    import gc

    gc.collect()
    libc = _libc()
    if libc is not None:
        libc.malloc_trim(0)


def peak_rss() -> int | None:
    """This process's peak resident set size so far, in bytes: Linux's ``VmHWM``, else
    ``getrusage`` (None where the system has neither). Not ``getrusage`` on Linux: its
    figure carries over a fork and an exec, so a command started by a large process would
    report that process's size."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024  # (kB)
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource
    except ImportError:  # (not on Windows)
        return None
    peak = int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
    return peak if sys.platform == "darwin" else peak * 1024  # (other systems: KiB)
