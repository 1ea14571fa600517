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
