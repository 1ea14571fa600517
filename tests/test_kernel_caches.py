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
from meshfit._compile_ahead import recording
from meshfit.demo import demo_mesh
from meshfit.pipeline import FitOptions, fit
with recording() as seen:
    fit(demo_mesh(8000), options=FitOptions(formats=("obj",), report=False), out=sys.argv[1])
json.dump(seen, sys.stdout)
"""


def test_a_fit_compiles_no_kernel_twice_for_a_read_only_flag(tmp_path):
    """numba compiles a kernel once per signature, and an array's read-only flag is part
    of it: a kernel met with both a mesh's read-only arrays and writable ones compiles
    twice on a first run. The kernels a whole fit calls from Python (whether their code is
    then loaded from the cache or compiled) are met with one flag each
    (:func:`meshfit._kernels.frozen`), and each is in the compile-ahead manifest."""
    import json
    import subprocess
    import sys

    from meshfit._compile_ahead import read_manifest

    run = subprocess.run(
        [sys.executable, "-c", _SIGNATURES, str(tmp_path / "out")],
        capture_output=True,
        text=True,
        check=True,
    )
    pairs = [(name, tuple(args)) for name, args in json.loads(run.stdout)]
    by_kernel: dict[str, set[tuple[str, ...]]] = {}
    twice = []
    for name, args in pairs:
        flagless = tuple(a.replace(",ro]", "]") for a in args)
        if flagless in by_kernel.setdefault(name, set()):
            twice.append(name)
        by_kernel[name].add(flagless)
    assert len(by_kernel) > 20  # the listener saw the kernels of the whole fit
    assert twice == []
    # what a second process compiles ahead of need on a first run (meshfit._compile_ahead)
    # lists every kernel the fit called: `python -m meshfit._compile_ahead --record` when not
    missing = sorted(set(pairs) - set(read_manifest()))
    assert missing == []


def test_kernels_calling_kernels_with_constants_compile_them_once():
    """A constant argument (here 16, 32, -1) does not make a compilation of the callee of
    its own (numba's literal types), however many constants it is called with."""
    import numpy as np
    from numba import njit

    from meshfit._kernels import cut

    @njit
    def caller(n):
        mask = np.int64(n - 1)
        return cut._hash(1, 16, mask) + cut._hash(-1, 32, mask) + cut._hash(n, n, mask)

    caller(64)
    assert [str(t) for t in cut._hash.signatures[0]] == ["int64", "int64", "int64"]
    assert len(cut._hash.signatures) == 1
