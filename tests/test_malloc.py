"""Allocator settings of the meshfit command."""

from __future__ import annotations

import subprocess
import sys

import pytest

from meshfit import _malloc


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_glibc_takes_the_settings():
    # in a child process: the settings are process-wide
    code = "from meshfit._malloc import tune_malloc; print(tune_malloc())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"


def test_other_systems_keep_their_defaults(monkeypatch):
    monkeypatch.setattr(_malloc.sys, "platform", "darwin")
    assert _malloc.tune_malloc() is False
