import json

import numpy as np
import pytest

from meshfit.bspline.cli import load_grid
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


def test_fit_command(grid_files, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["fit", *grid_files, "--controls", "6", "--out", str(out), "--json"]
    assert main([*argv, "--formats", "usd,obj,iges,exr,3dm,glb"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert len(res["patches"]) == 4 and res["shared_boundaries"] == 4
    assert res["seams_after"]["gap_max"] <= 1e-12
    assert res["seams_after"]["angle_max_deg"] <= 0.5
    assert res["seams_before"]["gap_max"] > res["seams_after"]["gap_max"]
    names = ("patches.usda", "displaced.obj", "splines.obj", "patches.igs", "patches.3dm")
    for name in (*names, "preview.glb", "patch_000.vector.exr"):
        assert (out / name).is_file()
    assert main(["fit", *grid_files, "--controls", "5", "7"]) == 0
    assert "seams after stitching" in capsys.readouterr().out


def test_fit_command_bad_input(grid_files, tmp_path, capsys):
    assert main(["fit", *grid_files, "--out", str(tmp_path), "--formats", "step"]) == 2
    assert "unknown export format" in capsys.readouterr().err
    bad = tmp_path / "bad.npz"
    np.savez(bad, version=np.int64(7), xyz=np.zeros((5, 5, 3)))
    with pytest.raises(InputError, match="version 7"):
        load_grid(bad)
    with pytest.raises(InputError, match="no such file"):
        load_grid(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    assert main(["fit", str(tmp_path / "junk.npz")]) == 2
