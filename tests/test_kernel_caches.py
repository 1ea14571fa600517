"""Kernel caches are dropped together when any kernel source changes."""

from __future__ import annotations

from pathlib import Path

import meshfit._kernels as kernels
from meshfit._kernels import STAMP, drop_stale_caches, sources_digest


def _caches(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.suffix in (".nbi", ".nbc"))


def test_a_changed_helper_file_drops_every_cache(tmp_path):
    src, cache = tmp_path / "src", tmp_path / "cache"
    src.mkdir()
    (src / "walk.py").write_text("def helper(): return 1\n")
    (src / "springs.py").write_text("from walk import helper\n")
    assert drop_stale_caches(src, cache) is False  # nothing to drop yet, stamp written
    assert (cache / STAMP).read_text() == sources_digest(src)
    # compiled caches of both files, and a file numba's caches are not
    for name in (
        "springs.relax-10.py311.nbi",
        "springs.relax-10.py311.1.nbc",
        "walk.x-3.py311.nbi",
    ):
        (cache / name).write_bytes(b"x")
    (cache / "springs.cpython-311.pyc").write_bytes(b"x")
    assert drop_stale_caches(src, cache) is False  # same sources: kept
    assert len(_caches(cache)) == 3
    # the helper's file changes, the caller's does not: the caller's cache goes too
    (src / "walk.py").write_text("def helper(): return 2\n")
    assert drop_stale_caches(src, cache) is True
    assert _caches(cache) == []
    assert (cache / "springs.cpython-311.pyc").exists()
    assert (cache / STAMP).read_text() == sources_digest(src)
    # a new file changes the digest as well
    before = sources_digest(src)
    (src / "extra.py").write_text("")
    assert sources_digest(src) != before


def test_an_unwritable_cache_folder_is_left_alone(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "a.py").write_text("x = 1\n")
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert drop_stale_caches(src, blocker / "cache") is False  # a file where the folder goes


def test_the_package_caches_are_stamped_with_the_current_sources():
    folder = kernels._cache_folder()
    assert folder is not None
    here = Path(kernels.__file__).resolve().parent
    assert (folder / STAMP).read_text() == sources_digest(here)


_SIGNATURES = """
import json, sys
from numba import typeof
from numba.core.dispatcher import Dispatcher
seen = set()
first_call = Dispatcher._compile_for_args
def record(self, *args, **kws):  # Python's first call of a kernel with new types
    f = self.py_func
    if f.__module__.startswith("meshfit."):
        seen.add((f.__module__ + "." + f.__qualname__, str(tuple(typeof(a) for a in args))))
    return first_call(self, *args, **kws)
Dispatcher._compile_for_args = record
from meshfit.demo import demo_mesh
from meshfit.pipeline import FitOptions, fit
fit(demo_mesh(8000), options=FitOptions(formats=("obj",), report=False), out=sys.argv[1])
json.dump(sorted(seen), sys.stdout)
"""


def test_a_fit_compiles_no_kernel_twice_for_a_read_only_flag(tmp_path):
    """numba compiles a kernel once per signature, and an array's read-only flag is part
    of it: a kernel met with both a mesh's read-only arrays and writable ones compiles
    twice on a first run. The kernels a whole fit calls from Python (whether their code is
    then loaded from the cache or compiled) are met with one flag each
    (:func:`meshfit._kernels.frozen`)."""
    import json
    import re
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, "-c", _SIGNATURES, str(tmp_path / "out")],
        capture_output=True,
        text=True,
        check=True,
    )
    pairs = json.loads(run.stdout)
    by_kernel: dict[str, set[str]] = {}
    twice = []
    for name, args in pairs:
        flagless = re.sub(r"'(C|F|A)', (True|False)", r"'\1'", args)
        if flagless in by_kernel.setdefault(name, set()):
            twice.append(name)
        by_kernel[name].add(flagless)
    assert len(by_kernel) > 20  # the listener saw the kernels of the whole fit
    assert twice == []
