"""Allocator settings of the meshfit command."""

from __future__ import annotations

import subprocess
import sys

from meshfit import _malloc


def test_glibc_takes_the_settings():
    # in a child process: the settings are process-wide (glibc on Linux takes them)
    code = "from meshfit._malloc import tune_malloc; print(tune_malloc())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str(sys.platform.startswith("linux"))


def test_other_systems_keep_their_defaults(monkeypatch):
    monkeypatch.setattr(_malloc.sys, "platform", "darwin")
    assert _malloc.tune_malloc() is False


def test_a_child_reports_its_own_peak_not_its_parents():
    # a command started by a large process (a test run, a notebook) must not report that
    # process's size as its own peak (getrusage's figure carries over fork and exec)
    import numpy as np

    big = np.ones(2**27)  # 1 GiB, touched
    assert _malloc.peak_rss() >= big.nbytes
    code = "from meshfit._malloc import peak_rss; print(peak_rss())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert int(out.stdout) < big.nbytes // 2


def test_the_c_library_is_found_without_a_child_process(monkeypatch):
    # a fork of a process holding gigabytes (ctypes.util.find_library runs ldconfig) would
    # double its resident size for a moment and copy its page tables
    import os

    def refuse(*args, **kwargs):
        raise AssertionError("a child process was started")

    monkeypatch.setattr(subprocess, "Popen", refuse)
    monkeypatch.setattr(os, "fork", refuse)
    _malloc._glibc.cache_clear()
    try:
        libc = _malloc._libc()
        _malloc.release_memory()
    finally:
        _malloc._glibc.cache_clear()
    assert (libc is not None) == sys.platform.startswith("linux")
    assert libc is None or _malloc._libc() is not None
