"""Kernels compiled ahead of need by a second process (meshfit._compile_ahead)."""

from __future__ import annotations

import fcntl
import functools
import importlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from numba import typeof
from numba.core import types

from meshfit import _compile_ahead as warm


@pytest.mark.parametrize(
    "value",
    [
        np.zeros((2, 3)),
        np.zeros(4, dtype=np.int64),
        np.zeros((2, 2, 2), dtype=np.float32)[:, 0],  # neither C nor F: layout A
        np.zeros((3, 2), order="F"),
        np.zeros(3, dtype=np.uint8),
        np.zeros(3, dtype=np.bool_),
        1,
        1.5,
        True,
    ],
)
def test_a_type_survives_its_short_form(value):
    t = typeof(value)
    assert warm.decode_type(warm.encode_type(t)) == t
    if isinstance(value, np.ndarray):
        ro = value.view()
        ro.flags.writeable = False
        t = typeof(ro)
        assert warm.encode_type(t).endswith(",ro]")
        assert warm.decode_type(warm.encode_type(t)) == t


@pytest.mark.parametrize("text", ["float64[2d]", "float64[x,C]", "str", "Array", "int64[1d,Q]"])
def test_a_damaged_short_form_is_refused(text):
    with pytest.raises(ValueError):
        warm.decode_type(text)


def test_a_type_without_a_short_form_is_refused():
    with pytest.raises(ValueError):
        warm.encode_type(types.UniTuple(types.int64, 2))


def test_every_manifest_entry_names_a_kernel_and_decodes():
    entries = warm.read_manifest()
    assert len(entries) > 20
    assert len(set(entries)) == len(entries)
    for kernel, args in entries:
        module, _, name = kernel.rpartition(".")
        dispatcher = getattr(importlib.import_module("meshfit._kernels." + module), name)
        assert callable(dispatcher.compile)
        assert all(warm.decode_type(a) is not None for a in args)


@functools.cache
def _cheap_entries() -> tuple:
    """One small kernel's entry, as the recorder sees its first call."""
    from meshfit._kernels import bspline

    with warm.recording() as seen:
        bspline.basis_local(np.array([0.25, 0.5]), np.linspace(0.0, 1.0, 8), 3, 3)
    return tuple(seen)


def _cheap_manifest(tmp_path: Path) -> Path:
    """A manifest of one small kernel, as the recorder writes it."""
    seen = _cheap_entries()
    assert seen == (("bspline.basis_local", ("float64[1d,C]", "float64[1d,C]", "int64", "int64")),)
    path = tmp_path / "manifest.json"
    entries = [{"kernel": k, "args": list(a)} for k, a in seen]
    path.write_text(json.dumps({"version": 1, "kernels": entries}))
    return path


def _helper_env(cache: Path) -> dict[str, str]:
    src = str(Path(warm.__file__).resolve().parents[1])
    return {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": src}


def test_the_helper_fills_an_empty_cache_and_stamps_it(tmp_path):
    manifest = _cheap_manifest(tmp_path)
    cache = tmp_path / "numba"
    subprocess.run(
        [sys.executable, "-m", "meshfit._compile_ahead", "--manifest", str(manifest)],
        env=_helper_env(cache),
        check=True,
        timeout=300,
    )
    names = [p.name for p in cache.rglob("*")]
    assert any(n.startswith("bspline.basis_local-") and n.endswith(".nbi") for n in names)
    assert any(n.endswith(".nbc") for n in names)
    assert "meshfit-compile-ahead.done.all" in names


def test_start_does_nothing_when_switched_off_stamped_or_locked(tmp_path, monkeypatch):
    manifest = _cheap_manifest(tmp_path)
    monkeypatch.setattr(warm, "_cache_folder", lambda: tmp_path)
    joined = []
    monkeypatch.setattr(warm, "claiming", joined.append)  # not this process's compilations
    monkeypatch.setenv(warm.ENV_SWITCH, "0")
    assert warm.start(manifest) is None
    monkeypatch.delenv(warm.ENV_SWITCH)
    (tmp_path / "meshfit-compile-ahead.done.all").write_text(warm._digest(manifest))
    assert warm.start(manifest, scope="fit") is None  # all done: the fit's are too
    assert joined == []
    (tmp_path / "meshfit-compile-ahead.done.all").write_text("another manifest")
    (tmp_path / "meshfit-compile-ahead.done.fit").write_text(warm._digest(manifest))
    assert warm.start(manifest, scope="fit") is None
    with open(tmp_path / "meshfit-compile-ahead.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        assert warm.start(manifest, scope="wrap") is None  # another helper is at work
    assert len(joined) == 1  # ... and this run takes its part of the queue


def test_scopes_list_a_fit_s_and_a_wrap_s_kernels(tmp_path):
    a, b, c = ("m.a", ("int64",)), ("m.b", ("float64[1d,C]",)), ("m.c", ())
    path = tmp_path / "manifest.json"
    warm.write_manifest({"fit": [a, b], "wrap": [b, c]}, path)
    assert warm.read_manifest(path, "fit") == [a, b]
    assert warm.read_manifest(path, "wrap") == [b, c]
    assert warm.read_manifest(path, "all") == [a, b, c]
    with pytest.raises(ValueError):
        warm.read_manifest(path, "everything")
    full = warm.read_manifest(scope="all")
    assert set(warm.read_manifest(scope="fit")) | set(warm.read_manifest(scope="wrap")) == set(full)
    # a fit's first run compiles none of the stream coder's kernels
    assert not any(k.startswith("streamcode.") for k, _ in warm.read_manifest(scope="fit"))


_PARENT = """
import os, sys
from meshfit import _compile_ahead as warm
helper = warm.start()
print(helper.pid if helper is not None else -1, flush=True)
if sys.argv[1] == "abrupt":  # no exit handlers: the helper must notice by itself
    os._exit(0)
"""


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return True
    return state in ("Z", "X")  # ended, not yet reaped by its new parent


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
@pytest.mark.parametrize("ending", ["normal", "abrupt"])
def test_the_helper_ends_with_the_process_that_started_it(tmp_path, ending):
    """A run that ends (here at once, mid-compilation) takes its helper with it."""
    env = _helper_env(tmp_path / "numba")
    env.pop(warm.ENV_SWITCH, None)
    run = subprocess.run(
        [sys.executable, "-c", _PARENT, ending],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    pid = int(run.stdout.split()[0])
    assert pid > 0
    deadline = time.monotonic() + 30
    while not _gone(pid):
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            pytest.fail("the helper outlived its parent by 30 s")
        time.sleep(0.1)


_HOLDER = """
import sys
from pathlib import Path
from meshfit import _compile_ahead as warm
queue = warm.Queue.open(warm.read_manifest(Path(sys.argv[1])), Path(sys.argv[2]))
assert queue.claim(0, wait=False)
print("held", flush=True)
sys.stdin.readline()
queue.compile(0)
"""

_RUN = """
import json, sys
from pathlib import Path
import numpy as np
from meshfit import _compile_ahead as warm
from meshfit._kernels import bspline, geometry
queue = warm.Queue.open(warm.read_manifest(Path(sys.argv[1])), Path(sys.argv[2]))
warm.claiming(queue)
basis = bspline.basis_local(np.array([0.25, 0.5]), np.linspace(0.0, 1.0, 8), 3, 3)
print(json.dumps({
    "basis": np.asarray(basis[0] if isinstance(basis, tuple) else basis).tolist(),
    "called": [sum(bspline.basis_local._cache_hits.values()),
               sum(bspline.basis_local._cache_misses.values())],
    "taken": [sum(geometry.polyline_gap._cache_hits.values()),
              sum(geometry.polyline_gap._cache_misses.values())],
}))
"""


def _two_entry_manifest(tmp_path: Path) -> Path:
    """The small kernel a run calls (entry 0), and another it does not (entry 1)."""
    other = next(e for e in warm.read_manifest() if e[0] == "geometry.polyline_gap")
    path = tmp_path / "manifest.json"
    warm.write_manifest({"fit": [*_cheap_entries(), other], "wrap": []}, path)
    return path


def _end(*procs: subprocess.Popen | None) -> None:
    """Kill what still runs and close the pipes."""
    for p in procs:
        if p is None:
            continue
        if p.poll() is None:
            p.kill()
            p.wait()
        for f in (p.stdin, p.stdout):
            if f is not None:
                f.close()


def _wait_for(check, what: str, seconds: float = 240.0) -> None:
    deadline = time.monotonic() + seconds
    while not check():
        if time.monotonic() > deadline:
            pytest.fail(f"{what} within {seconds:.0f} s")
        time.sleep(0.05)


def test_a_run_compiles_the_last_free_entry_while_the_helper_holds_the_one_it_needs(tmp_path):
    """The queue: a run that needs an entry another process is compiling takes the last
    entry nobody holds meanwhile, then waits for the one it needs and loads it from the
    cache: each kernel is compiled once, by one of the two."""
    manifest = _two_entry_manifest(tmp_path)
    claims = tmp_path / "numba" / "claims"
    claims.parent.mkdir()
    env = _helper_env(tmp_path / "numba")
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLDER, str(manifest), str(claims)],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    run = None
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        run = subprocess.Popen(
            [sys.executable, "-c", _RUN, str(manifest), str(claims)],
            env=env,
            stdout=subprocess.PIPE,
            text=True,
        )
        queue = warm.Queue.open(warm.read_manifest(manifest), claims)
        assert queue is not None
        assert not queue.claim(0, wait=False)  # the holder has it
        _wait_for(lambda: queue.done(1), "the waiting run compiled the free entry")
        assert run.poll() is None  # ... and still waits for the held one
        assert holder.stdin is not None
        holder.stdin.write("\n")
        holder.stdin.flush()
        assert holder.wait(timeout=240) == 0
        assert queue.done(0)
        out, _ = run.communicate(timeout=240)
        assert run.returncode == 0
    finally:
        _end(holder, run)
    got = json.loads(out.strip().splitlines()[-1])
    assert got["called"] == [1, 0]  # loaded from the cache the holder filled, not compiled
    assert got["taken"] == [0, 1]  # compiled by the run while it waited
    from meshfit._kernels import bspline

    want = bspline.basis_local(np.array([0.25, 0.5]), np.linspace(0.0, 1.0, 8), 3, 3)
    want = want[0] if isinstance(want, tuple) else want
    np.testing.assert_array_equal(np.asarray(got["basis"]), want)


def test_the_helper_passes_over_what_is_cached_and_takes_up_what_another_held(tmp_path):
    """The helper's side of the queue: an entry marked cached is not compiled again, and an
    entry another process holds is skipped, then taken up once it is free."""
    manifest = _two_entry_manifest(tmp_path)
    claims = tmp_path / "claims"
    entries = warm.read_manifest(manifest)
    queue = warm.Queue.open(entries, claims)
    assert queue is not None and not queue.done(0) and not queue.done(1)
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLDER, str(manifest), str(claims)],
        env=_helper_env(tmp_path / "numba"),
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        assert queue.take_last(but=1) is None  # entry 0 is held, entry 1 is the exception
        assert queue.take_last(but=-1) == 1
        queue.release(1)
        assert holder.stdin is not None
        holder.stdin.write("\n")
        holder.stdin.flush()
        assert warm.compile_ahead(entries, queue) == 2  # waited for entry 0, compiled 1
        assert holder.wait(timeout=240) == 0
    finally:
        _end(holder)
    assert queue.done(0) and queue.done(1)
    again = warm.Queue.open(entries, claims)  # the marks are in the file
    assert again is not None and again.done(0) and again.done(1)
    assert again.take_last(but=-1) is None
