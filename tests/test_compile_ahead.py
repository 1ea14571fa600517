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
    assert "meshfit-compile-ahead.done" in names


def test_start_does_nothing_when_switched_off_stamped_or_locked(tmp_path, monkeypatch):
    manifest = _cheap_manifest(tmp_path)
    monkeypatch.setattr(warm, "_cache_folder", lambda: tmp_path)
    monkeypatch.setenv(warm.ENV_SWITCH, "0")
    assert warm.start(manifest) is None
    monkeypatch.delenv(warm.ENV_SWITCH)
    (tmp_path / "meshfit-compile-ahead.done").write_text(warm._digest(manifest))
    assert warm.start(manifest) is None
    (tmp_path / "meshfit-compile-ahead.done").write_text("another manifest")
    with open(tmp_path / "meshfit-compile-ahead.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        assert warm.start(manifest) is None  # another helper is at work


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
