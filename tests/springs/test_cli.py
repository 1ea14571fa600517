"""``meshfit springs`` on the spot layout."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshfit.cli import main

from ..conftest import ROOT, mesh_path


def test_springs_command_writes_grids_and_prints_metrics(tmp_path, capsys):
    layout = ROOT / "examples" / "layouts" / "spot.json"
    out = tmp_path / "grids"
    code = main(["springs", str(mesh_path("spot")), "--layout", str(layout), "--level", "2",
                 "--out", str(out), "--json"])  # fmt: skip
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["patches"]) == 24
    row = data["patches"][0]
    for key in (
        "grid",
        "level",
        "seconds",
        "arc_cv_max",
        "aspect_median",
        "folded",
        "fidelity_max",
    ):
        assert key in row
    assert row["level"] == 2
    assert all(0.5 < r["bulge"] < 3.0 for r in data["patches"])
    assert data["notes"] == []  # no patch of this layout bulges beyond meshfit.layout.BULGY
    with np.load(out / "patch_000.npz", allow_pickle=False) as z:
        assert int(z["version"]) == 1
        nu, nv = z["kind"].shape
        assert z["xyz"].shape == (nu, nv, 3) and z["face"].shape == (nu * nv,)
        assert [nu, nv] == row["grid"]
    import trimesh

    tm = trimesh.load(out / "patch_000.ply", process=False)
    assert len(tm.vertices) == nu * nv and len(tm.faces) == 2 * (nu - 1) * (nv - 1)
    assert not list(out.glob("*.tmp"))


def test_springs_command_prints_tables(capsys):
    layout = ROOT / "examples" / "layouts" / "spot.json"
    assert main(["springs", str(mesh_path("spot")), "--layout", str(layout), "--level", "0"]) == 0
    text = capsys.readouterr().out
    assert "patch 23" in text and "seconds" in text


def test_springs_command_warns_of_a_bulging_patch(capsys):
    layout = ROOT / "examples" / "layouts" / "nefertiti.json"
    args = ["springs", str(mesh_path("nefertiti")), "--layout", str(layout), "--level", "0"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "note: 1 patch bulges far beyond its boundary" in text and "patch 4: 11" in text


def test_springs_command_rejects_a_layout_of_another_mesh(capsys):
    layout = ROOT / "examples" / "layouts" / "igea.json"
    assert main(["springs", str(mesh_path("spot")), "--layout", str(layout)]) == 2
    assert "error" in capsys.readouterr().err


@pytest.mark.parametrize("level", ["-1"])
def test_springs_command_rejects_a_negative_level(level, capsys):
    layout = ROOT / "examples" / "layouts" / "spot.json"
    assert main(["springs", str(mesh_path("spot")), "--layout", str(layout), "--level", level]) == 2
