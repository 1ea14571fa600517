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
    assert out["bulge_max"] == max(p["bulge"] for p in out["per_patch"]) < 3.0
    assert out["taper_max"] == max(p["taper"] for p in out["per_patch"]) > 4.0
    assert out["corner_angle_max"] == max(max(p["corner_angles"]) for p in out["per_patch"])
    assert 90.0 < out["corner_angle_max"] < 180.0  # no reflex corner
    # no patch bulges beyond BULGY; the four head patches taper beyond TAPERED
    assert len(out["notes"]) == 1
    assert out["notes"][0].startswith("4 patches taper") and "patch 1: 6.94" in out["notes"][0]


def test_layout_command_notes_a_bulging_patch(capsys):
    args = ["layout", str(mesh_path("nefertiti")), str(LAYOUTS / "nefertiti.json")]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "bulge max" in text and "note: 1 patch bulges far beyond its boundary" in text
    assert "patch 4: 11" in text
    # and one corner of the layout turns back inside a patch
    assert "corner angle max" in text and "note: 1 patch turns back at a corner" in text
    assert "patch 20: 192 degrees at corner 3" in text


def test_layout_command_table(capsys):
    assert main(["layout", str(mesh_path("spot")), str(LAYOUTS / "spot.json")]) == 0
    assert "patches" in capsys.readouterr().out


def test_layout_of_another_mesh_exits_2(capsys):
    code = main(["layout", str(mesh_path("nefertiti")), str(LAYOUTS / "spot.json"), "--json"])
    assert code == 2
    assert "made for another mesh" in capsys.readouterr().err
