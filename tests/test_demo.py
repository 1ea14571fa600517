"""The embedded default input and `meshfit demo`."""

from __future__ import annotations

import json
import re

import numpy as np

from meshfit import cli, tol
from meshfit.demo import demo_mesh, run_demo
from meshfit.mesh import load_mesh

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


def test_run_demo_writes_outputs(tmp_path):
    summary = run_demo(tmp_path, faces=3000, quiet=True)
    mesh = load_mesh(tmp_path / "demo_scan.ply")
    assert mesh.n_faces == summary["statistics"]["faces"]
    assert mesh.vertex_colors is not None
    info = json.loads((tmp_path / "info.json").read_text())
    assert info["genus"] == 0
    walk = json.loads((tmp_path / "demo.json").read_text())["walk"]
    assert walk["hit_boundary"] == 0
    assert walk["max_length_error"] < 1e-9 * mesh.bbox_diagonal
    assert walk["max_distance_off_surface"] < tol.ON_SURFACE * mesh.bbox_diagonal
    assert not list(tmp_path.glob("*.tmp"))


def test_cli_demo_json(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path), "--faces", "2000", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["statistics"]["closed"] is True
    assert out["walk"]["points"] == 100_000


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
