import argparse
import json

import numpy as np
import pytest

from meshfit.bspline.cli import add_commands, load_grid
from meshfit.cli import main
from meshfit.errors import InputError
from tests.stitch.networks import height_field, split_grid


@pytest.fixture
def grid_files(tmp_path):
    paths = []
    for k, g in enumerate(split_grid(height_field(41), [20], [20])):
        p = tmp_path / f"patch_{k:03d}.npz"
        np.savez(p, version=np.int64(1), xyz=g)
        paths.append(str(p))
    return paths


def _own(argv):
    """This module's ``fit`` parser alone (meshfit.fit_cli wraps it in ``meshfit fit``)."""
    parser = argparse.ArgumentParser()
    add_commands(parser.add_subparsers())
    args = parser.parse_args(argv)
    return args.func(args)


def test_grid_fit_command(grid_files, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["fit", *grid_files, "--controls", "6", "--out", str(out), "--json"]
    assert _own([*argv, "--formats", "usd,obj,iges,exr,3dm,glb"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert len(res["patches"]) == 4 and res["shared_boundaries"] == 4
    assert res["seams_after"]["gap_max"] <= 1e-12
    assert res["seams_after"]["angle_max_deg"] <= 0.5
    assert res["seams_before"]["gap_max"] > res["seams_after"]["gap_max"]
    names = ("patches.usda", "displaced.obj", "splines.obj", "patches.igs", "patches.3dm")
    for name in (*names, "preview.glb", "patch_000.vector.exr", "maps/patches_vector.1004.exr"):
        assert (out / name).is_file()
    assert _own(["fit", *grid_files, "--controls", "5", "7"]) == 0
    assert "seams after stitching" in capsys.readouterr().out


def test_meshfit_fit_reaches_the_grid_fit(grid_files, tmp_path, capsys):
    """``meshfit fit *.npz`` (meshfit.fit_cli) hands spring-mesh grids to this command."""
    rc = main(["fit", *grid_files, "--cv", "6x7", "--continuity", "g1", "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert [p["controls"] for p in res["patches"]] == [[6, 7]] * 4
    assert res["seams_after"]["angle_max_deg"] <= 0.5
    # one class's count chosen: the patches sharing it follow, the seams stay closed
    assert main(["fit", *grid_files, "--cv", "6x7", "--class-cv", "0=9", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["control_classes"][0] == 9
    # two patches share class 0 (their u direction) across the 2 x 2 split
    assert sorted(tuple(p["controls"]) for p in res["patches"]) == [(6, 7)] * 2 + [(9, 7)] * 2
    for p in res["patches"]:
        assert (p["controls"][0] == 9) == (p["control_classes"][0] == 0)
    assert res["seams_after"]["gap_max"] <= 1e-12


def test_fit_command_bad_input(grid_files, tmp_path, capsys):
    with pytest.raises(InputError, match="unknown export format"):
        _own(["fit", *grid_files, "--out", str(tmp_path), "--formats", "step"])
    bad = tmp_path / "bad.npz"
    np.savez(bad, version=np.int64(7), xyz=np.zeros((5, 5, 3)))
    with pytest.raises(InputError, match="version 7"):
        load_grid(bad)
    with pytest.raises(InputError, match="no such file"):
        load_grid(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    assert main(["fit", str(tmp_path / "junk.npz")]) == 2
    assert "junk.npz" in capsys.readouterr().err
