"""SIGTERM ends a command at once with one line and its own exit code, wherever it lands
(in Python, in a kernel's JIT compilation), leaving no temporary file behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("kernels", ["cached", "compiling"])
def test_sigterm_stops_a_fit_with_one_line(tmp_path, kernels):
    out = tmp_path / "demo"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1] / "src")}
    if kernels == "compiling":  # an empty kernel cache: the signal lands in a compilation
        env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")
    argv = [sys.executable, "-m", "meshfit.cli", "demo", "--faces", "60000", "--out", str(out)]
    with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env) as proc:
        try:
            deadline = time.monotonic() + 120
            while not out.exists() and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            assert proc.poll() is None, "the demo ended before it could be stopped"
            time.sleep(0.5)  # inside the work
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    text = err.decode()
    assert proc.returncode == 143
    assert text.rstrip().splitlines()[-1] == "meshfit: terminated"
    assert "Traceback" not in text and "Exception ignored" not in text
    assert not [p for p in out.rglob(".*") if p.is_file()]  # no temporary file is left
