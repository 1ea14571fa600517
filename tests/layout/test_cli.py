"""``meshfit layout`` on the command line."""

from __future__ import annotations

import json

import pytest

from meshfit.cli import main

from ..conftest import mesh_path
from .test_layout import LAYOUTS


def test_layout_command_prints_json(capsys):
    assert main(["layout", str(mesh_path("spot")), str(LAYOUTS / "spot.json"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["patches"] == 24 and len(out["per_patch"]) == 24
    assert out["patch_area_sum"] == pytest.approx(out["mesh_area"], rel=1e-9)


def test_layout_command_table(capsys):
    assert main(["layout", str(mesh_path("spot")), str(LAYOUTS / "spot.json")]) == 0
    assert "patches" in capsys.readouterr().out


def test_layout_of_another_mesh_exits_2(capsys):
    code = main(["layout", str(mesh_path("nefertiti")), str(LAYOUTS / "spot.json"), "--json"])
    assert code == 2
    assert "made for another mesh" in capsys.readouterr().err
