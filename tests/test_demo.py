"""The embedded default input and `meshfit demo`."""

from __future__ import annotations

import json
import os
import re
import subprocess

import numpy as np
import pytest

from meshfit import cli, tol
from meshfit.demo import demo_mesh, run_demo
from meshfit.mesh import load_mesh
from meshfit.pipeline import FitOptions
from meshfit.pipeline.outputs import read_manifest

from .conftest import ROOT


def test_demo_mesh_is_closed_genus0_and_deterministic():
    a = demo_mesh(4000)
    b = demo_mesh(4000)
    assert a.is_closed
    assert a.genus == 0
    assert a.n_components == 1
    assert a.n_faces == 2 * a.n_vertices - 4
    assert a.vertex_colors is not None
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)
    c = demo_mesh(4000, seed=7)
    assert not np.array_equal(a.vertices, c.vertices)


def test_demo_mesh_size_limits():
    from meshfit.errors import InputError

    with pytest.raises(InputError, match="at least 100"):
        demo_mesh(10)
    with pytest.raises(InputError, match="at most 5,000,000, got 50,000,000"):
        demo_mesh(50_000_000)


def test_demo_mesh_default_size_is_scan_like():
    mesh = demo_mesh()
    assert 190_000 <= mesh.n_faces <= 210_000
    # outward orientation: the enclosed volume is positive
    p = mesh.vertices[mesh.faces]
    volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0
    assert volume > 0
    # irregular triangulation: edge lengths vary like a scan's
    cv = mesh.edge_lengths.std() / mesh.edge_lengths.mean()
    assert cv > 0.15


def test_run_demo_fits_and_reports(tmp_path):
    opts = FitOptions(controls=(6, 6), spring_level=1, formats=("obj",), image_size=96)
    summary = run_demo(tmp_path, faces=4000, quiet=True, options=opts)
    mesh = load_mesh(tmp_path / "demo_scan.ply")
    assert mesh.n_faces == summary["statistics"]["faces"]
    assert mesh.vertex_colors is not None
    info = json.loads((tmp_path / "info.json").read_text())
    assert info["genus"] == 0
    assert summary["patches_total"] == 60
    assert summary["report"] == str(tmp_path / "report.html")
    assert (tmp_path / "report.html").is_file()
    assert summary["seams"]["spline_gap_max"] <= tol.STITCH_GAP
    assert sum(p["folded"] for p in summary["patches"]) == 0
    assert summary["errors"]["displaced"]["rms"] < summary["errors"]["spline_only"]["rms"]
    assert not list(tmp_path.rglob("*.tmp"))
    # every file the demo wrote is in the manifest (the stage cache is not a result)
    listed = set(read_manifest(tmp_path))
    written = {
        p.relative_to(tmp_path).as_posix()
        for p in tmp_path.rglob("*")
        if p.is_file() and ".meshfit" not in p.relative_to(tmp_path).parts
    }
    assert written - listed == {"manifest.json"}
    assert read_manifest(tmp_path)["demo_scan.ply"]["kind"] == "mesh"


def test_cli_demo_json(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path), "--faces", "2000", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["statistics"]["closed"] is True
    assert out["report"] == str(tmp_path / "report.html")


@pytest.mark.slow
def test_demo_command_in_a_fresh_folder(tmp_path):
    """The installed ``meshfit demo`` runs from an empty folder (no ../shared) and ends with
    the report's path."""
    env = {k: v for k, v in os.environ.items() if k != "MESHFIT_DATA"}
    run = subprocess.run(
        ["meshfit", "demo", "--faces", "3000", "--out", "out"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    last = run.stdout.strip().splitlines()[-1]
    assert last == "out/report.html"
    assert (tmp_path / last).is_file()


def test_readme_python_example_runs():
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "README has no python example"
    for code in blocks:
        exec(compile(code, "README.md", "exec"), {})


def test_readme_quick_start_matches_ci():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    commands = re.findall(r"```bash\n(.*?)\n```", readme, re.S)
    assert commands[0] == "pip install . && meshfit demo"
    assert commands[1] in ci


def test_the_display_says_when_kernels_are_compiled(capsys):
    """A kernel compiled (not loaded from a cache) while a fit's display is open is said
    once, and counted with its seconds on a line of its own."""
    from numba import njit

    from meshfit._progress import COMPILING, stage_progress

    @njit  # no cache: compiled here
    def add_one(x):
        return x + 1

    with stage_progress() as prog:
        prog("layout", 0, 1)
        assert add_one(1) == 2
        assert add_one(2.5) == 3.5  # a second signature: a second compile
        prog("layout", 1, 1)
    assert prog.compiled == 2 and prog.compile_seconds > 0
    err = capsys.readouterr().err
    assert err.count(COMPILING[:40]) == 1
    with stage_progress() as quiet_run:
        assert add_one(3) == 4  # compiled already: nothing to say
    assert quiet_run.compiled == 0


def test_the_kernels_line_counts_the_compile_ahead_queue(tmp_path, monkeypatch):
    """With a compile-ahead queue, the kernels line shows how many of its entries every
    process sharing it has cached, out of its length: how far a first run has to go."""
    import os

    from numba import njit

    from meshfit import _compile_ahead as warm
    from meshfit import _progress
    from meshfit._progress import stage_progress

    entries = [("m.a", ()), ("m.b", ()), ("m.c", ())]
    queue = warm.Queue.open(entries, tmp_path / "claims")
    assert queue is not None
    queue.mark(1)  # another process cached entry 1
    monkeypatch.setattr(warm, "_queue", queue)
    monkeypatch.setattr(_progress, "queue_counts", warm.queue_progress)  # as claiming() does
    assert warm.queue_progress() == (1, 3)

    @njit  # no cache: compiled here
    def twice(x):
        return 2 * x

    with stage_progress() as prog:
        prog("layout", 0, 1)
        assert twice(2) == 4
        kernels = lambda: next(t for t in prog.bar.tasks if t.id == prog.tasks["kernels"])  # noqa: E731
        assert (kernels().completed, kernels().total) == (1, 3)
        queue.mark(0)
        prog("layout", 1, 1)  # a stage's progress looks again
        assert (kernels().completed, kernels().total) == (2, 3)
    os.close(queue.fd)
