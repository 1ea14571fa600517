"""SIGTERM is taken like Ctrl-C: one line, its own exit code, no half-written files."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigterm_stops_a_fit_with_one_line_and_whole_files(tmp_path):
    out = tmp_path / "demo"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1] / "src")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "meshfit.cli", "demo", "--faces", "60000", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    deadline = time.monotonic() + 120
    while not out.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "the demo ended before it could be stopped"
    time.sleep(0.5)  # inside the work
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143
    assert err.decode().rstrip().splitlines()[-1] == "meshfit: terminated"
    assert "Traceback" not in err.decode()
    # atomic writes: no temporary file is left behind
    assert not [p for p in out.rglob(".*") if p.is_file()]
