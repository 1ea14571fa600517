import json

import numpy as np
import pytest

from meshfit.cli import main
from meshfit.mesh import load_mesh
from meshfit.mesh.io import save_mesh

from ..conftest import analytic_mesh, mesh_path


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


def test_handle_is_a_clear_error(tmp_path, capsys):
    path = tmp_path / "torus.ply"
    save_mesh(analytic_mesh("torus"), path)
    for argv in (["wrap", str(path)], ["stream", "encode", str(path), "-o", str(tmp_path / "t")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert str(path) in err and "genus 1" in err and "genus-0" in err
    assert not (tmp_path / "t").exists()


def test_wrap_sphere_aspect_bound(capsys):
    argv = ["wrap", str(mesh_path("spot")), "--levels", "1", "--json"]
    assert main([*argv, "--sphere-max-aspect", "12"]) == 0
    sm = json.loads(capsys.readouterr().out)["sphere_map"]
    assert sm["flips"] == 0
    assert sm["max_aspect"] <= 12.0  # measured 20 without the bound
    assert any("aspect bound 12" in n for n in sm["notes"])
    assert main([*argv, "--sphere-max-aspect", "0.5"]) == 2
    assert "--sphere-max-aspect must be a finite number >= 1" in capsys.readouterr().err
    assert main([*argv, "--base-faces", "12"]) == 2
    assert "--base-faces must be at least 20" in capsys.readouterr().err
    too_fine = ["wrap", str(mesh_path("spot")), "--levels", "12"]
    assert main(too_fine) == 2
    assert "ask for 9 levels or fewer" in capsys.readouterr().err


def test_stream_encode_decode(tmp_path, capsys):
    s = tmp_path / "spot.mfsw"
    enc = ["stream", "encode", str(mesh_path("spot")), "--levels", "2", "--scheme", "butterfly"]
    assert main([*enc, "-o", str(s), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["bytes"] == s.stat().st_size
    full = tmp_path / "full.ply"
    part = tmp_path / "part.ply"
    assert main(["stream", "decode", str(s), "-o", str(full), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["bytes_used"] == got["bytes"] == info["bytes"]
    assert main(["stream", "decode", str(s), "-o", str(part), "--fraction", "0.5"]) == 0
    a, b = load_mesh(full), load_mesh(part)
    assert np.array_equal(a.faces, b.faces)
    assert not np.allclose(a.vertices, b.vertices)
    # 1% of the bytes is less than the base mesh: the base mesh and what fits beside it
    capsys.readouterr()
    assert main(["stream", "decode", str(s), "-o", str(part), "--fraction", "0.01", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["faces"] == a.n_faces and got["bytes_used"] < info["bytes"] / 2
    # --bytes: the first N bytes, as if only they arrived
    n = info["bytes"] // 3
    assert main(["stream", "decode", str(s), "-o", str(part), "--bytes", str(n), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["bytes_used"] == n and 0 < got["coefficient_bytes"] < n
    # a coarser level
    lvl1 = tmp_path / "l1.ply"
    assert main(["stream", "decode", str(s), "-o", str(lvl1), "--level", "1", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["level"] == 1
    assert got["faces"] == 4 * info["base_faces"] == load_mesh(lvl1).n_faces
    assert main(["stream", "decode", str(s), "-o", str(lvl1), "--level", "3"]) == 2
    assert "--level must be in [0, 2]" in capsys.readouterr().err
    # encode --bytes N writes at most N bytes
    small = tmp_path / "small.mfsw"
    assert main([*enc, "-o", str(small), "--bytes", str(n), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["bytes"] == small.stat().st_size <= n
    assert main([*enc, "-o", str(small), "--bytes", "100"]) == 2
    assert "do not hold the base mesh" in capsys.readouterr().err
    # a file cut short decodes, with a note saying how much arrived
    cut = tmp_path / "cut.mfsw"
    cut.write_bytes(s.read_bytes()[: info["bytes"] // 2])
    assert main(["stream", "decode", str(cut), "-o", str(part)]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{info['bytes'] // 2:,} of {info['bytes']:,} bytes" in err
    bad = tmp_path / "bad.mfsw"
    bad.write_bytes(b"nope")
    assert main(["stream", "decode", str(bad), "-o", str(part)]) == 2
    assert "truncated header" in capsys.readouterr().err


def test_wrap_sphere_stretch(capsys):
    argv = ["wrap", str(mesh_path("spot")), "--levels", "1", "--json"]
    assert main([*argv, "--sphere-stretch", "2"]) == 0
    sm = json.loads(capsys.readouterr().out)["sphere_map"]
    assert sm["flips"] == 0
    assert any("2 rounds of stretch reweighting" in n for n in sm["notes"])
    assert main([*argv, "--sphere-stretch", "-1"]) == 2
    assert "--sphere-stretch must be in 0..100" in capsys.readouterr().err
    assert main([*argv, "--sphere-method", "voxel"]) == 2
    assert "voxel-flow sphere map was removed" in capsys.readouterr().err


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--sphere-max-aspect", "nan"], "--sphere-max-aspect must be a finite number"),
        (["--sphere-max-aspect", "inf"], "--sphere-max-aspect must be a finite number"),
        (["--sphere-stretch", "1000000"], "--sphere-stretch must be in 0..100"),
    ],
)
def test_wrap_options_out_of_range_are_refused_at_once(extra, match, capsys):
    assert main(["wrap", str(mesh_path("spot")), "--levels", "1", *extra]) == 2
    assert match in capsys.readouterr().err


def _closed(tmp_path, name, mesh):
    path = tmp_path / f"{name}.ply"
    mesh.export(path)
    return str(path)


def test_the_smallest_closed_meshes_are_wrapped_or_refused_clearly(tmp_path, capsys):
    """A tetrahedron (4 faces) has fewer faces than the smallest base mesh: refused with
    the reason; a box and a hexagonal prism are wrapped."""
    import trimesh

    tet = trimesh.Trimesh(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    )
    assert main(["wrap", _closed(tmp_path, "tet", tet), "--levels", "2"]) == 2
    assert "has 4 faces: a wrap's base mesh" in capsys.readouterr().err
    for name, mesh in [
        ("box", trimesh.creation.box()),
        ("prism", trimesh.creation.cylinder(radius=1.0, height=1.0, sections=6)),
    ]:
        assert main(["wrap", _closed(tmp_path, name, mesh), "--levels", "2", "--json"]) == 0
        capsys.readouterr()
