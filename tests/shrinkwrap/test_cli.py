import json

import numpy as np

from meshfit.cli import main
from meshfit.mesh import load_mesh

from ..conftest import mesh_path


def test_wrap_json_and_outputs(tmp_path, capsys):
    rc = main(["wrap", str(mesh_path("spot")), "--levels", "2", "--json", "--out", str(tmp_path)])
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["sphere_map"]["method"] == "tutte"
    assert len(rep["levels"]) == 3
    assert {"1%", "3%", "10%"} <= set(rep["reconstruction"]["loop"])
    for i in range(3):
        assert load_mesh(tmp_path / f"M{i}.ply").n_faces == rep["levels"][i]["faces"]
    assert json.loads((tmp_path / "metrics.json").read_text())["base"] == rep["base"]
    assert (tmp_path / "wrap.mfsw").is_file()


def test_open_mesh_is_a_clear_error_and_fill_holes_fixes_it(capsys):
    rc = main(["wrap", str(mesh_path("bunny")), "--levels", "1"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "5 boundary loop" in err and "--fill-holes" in err
    rc = main(["wrap", str(mesh_path("bunny")), "--levels", "1", "--fill-holes", "--json"])
    assert rc == 0
    assert json.loads(capsys.readouterr().out)["levels"][1]["flips"] == 0


def test_stream_encode_decode(tmp_path, capsys):
    s = tmp_path / "spot.mfsw"
    assert (
        main(
            [
                "stream",
                "encode",
                str(mesh_path("spot")),
                "--levels",
                "2",
                "-o",
                str(s),
                "--scheme",
                "butterfly",
                "--json",
            ]
        )
        == 0
    )
    info = json.loads(capsys.readouterr().out)
    assert info["bytes"] == s.stat().st_size
    full = tmp_path / "full.ply"
    part = tmp_path / "part.ply"
    assert main(["stream", "decode", str(s), "-o", str(full), "--json"]) == 0
    capsys.readouterr()
    assert main(["stream", "decode", str(s), "-o", str(part), "--fraction", "0.1"]) == 0
    a, b = load_mesh(full), load_mesh(part)
    assert np.array_equal(a.faces, b.faces)
    assert not np.allclose(a.vertices, b.vertices)
    bad = tmp_path / "bad.mfsw"
    bad.write_bytes(b"nope")
    assert main(["stream", "decode", str(bad), "-o", str(part)]) == 2
    assert "truncated header" in capsys.readouterr().err
