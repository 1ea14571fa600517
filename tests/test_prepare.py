"""``meshfit prepare``: a scan cut into patch files out of core (meshfit.pipeline.prepare)."""

from __future__ import annotations

import json

import numpy as np

from meshfit.cli import main
from meshfit.mesh import save_mesh
from meshfit.pipeline.cluster import spring_file_task
from meshfit.pipeline.options import FitOptions

from .conftest import real_mesh


def test_prepare_cuts_a_scan_into_the_spring_tasks_files(tmp_path, capsys):
    mesh = real_mesh("spot")
    path = tmp_path / "spot.ply"
    save_mesh(mesh, path)
    assert main(["prepare", str(path), "--out", str(tmp_path / "prep"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["faces"] == mesh.n_faces and out["patches"] >= 12
    files = sorted((tmp_path / "prep" / "cut").glob("patch-*.npz"))
    assert len(files) == out["patches"]
    # the patches cover the scan once, and a spring mesh is made from a patch's file alone
    area = 0.0
    for f in files:
        z = np.load(f)
        x = z["vertices"][z["faces"]]
        area += 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1).sum()
    np.testing.assert_allclose(area, mesh.face_areas.sum(), rtol=1e-9)
    xyz, info = spring_file_task(str(files[0]), FitOptions().springs)
    assert xyz.ndim == 3 and info["folded"] == 0


def test_prepare_refuses_bad_calls_with_one_line(tmp_path, capsys):
    path = tmp_path / "spot.ply"
    save_mesh(real_mesh("spot"), path)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("keep")
    cases = [
        (["--out", str(tmp_path / "full")], "not an empty folder"),
        (["--out", str(tmp_path / "p"), "--proxy-faces", "5"], "--proxy-faces must be >= 20"),
    ]
    for extra, why in cases:
        assert main(["prepare", str(path), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0]
    assert main(["prepare", str(tmp_path / "none.ply"), "--out", str(tmp_path / "q")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert (tmp_path / "full" / "x").read_text() == "keep"
    assert not (tmp_path / "p").exists() and not (tmp_path / "q").exists()
