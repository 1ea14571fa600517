"""``meshfit info``: statistics of the real scans, findings, --repair, --json and exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshfit import __version__, cli

from . import shapes
from .conftest import REAL, mesh_path
from .mesh.test_validate import moebius_strip

# counts from ../shared/data/meshes/SOURCES.md for the meshes that are valid as stored
VALID = {
    "spot": {
        "vertices": 2_930,
        "faces": 5_856,
        "edges": 8_784,
        "euler_characteristic": 2,
        "boundary_loops": 0,
        "genus": 0,
        "closed": True,
        "vertex_colors": True,
    },
    "nefertiti": {
        "vertices": 49_971,
        "faces": 99_938,
        "edges": 149_907,
        "euler_characteristic": 2,
        "boundary_loops": 0,
        "genus": 0,
        "closed": True,
        "vertex_colors": False,
    },
    "igea": {
        "vertices": 134_345,
        "faces": 268_686,
        "edges": 403_029,
        "euler_characteristic": 2,
        "boundary_loops": 0,
        "genus": 0,
        "closed": True,
        "vertex_colors": False,
    },
}


def info(capsys, *args: str) -> tuple[int, str, str]:
    rc = cli.main(["info", *args])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def one_line(err: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("meshfit: error: ")
    return lines[0]


@pytest.mark.parametrize("name", list(VALID))
def test_valid_real_mesh_json(capsys, name):
    rc, out, err = info(capsys, str(mesh_path(name)), "--json")
    assert rc == 0
    assert err == ""
    data = json.loads(out)
    for key, want in VALID[name].items():
        assert data[key] == want, key
    assert data["components"] == 1
    assert data["valid"] is True
    assert data["findings"] == []
    assert data["repaired"] is False
    assert "repair" not in data
    assert data["file"] == str(mesh_path(name))


def test_valid_mesh_table(capsys):
    rc, out, err = info(capsys, str(mesh_path("spot")))
    assert rc == 0
    assert err == ""
    assert "valid: no problems found" in out
    assert "euler characteristic" in out
    assert "8784" in out  # edges


@pytest.mark.parametrize("name", REAL)
def test_repair_flag_exits_zero_on_every_real_mesh(capsys, name):
    rc, out, err = info(capsys, str(mesh_path(name)), "--json", "--repair")
    assert rc == 0
    assert err == ""
    data = json.loads(out)
    assert data["genus"] == 0
    assert data["components"] == 1
    assert data["repaired"] is (name in ("bunny", "nefertiti_fraunhofer"))


def test_bunny_reports_unreferenced_vertices(capsys):
    path = str(mesh_path("bunny"))
    rc, out, err = info(capsys, path, "--json", "--no-repair")
    assert rc == 2
    line = one_line(err)
    assert line == (
        f"meshfit: error: {path}: 1113 vertices not used by any face "
        "(first: vertex 8) (repairable: run without --no-repair)"
    )
    data = json.loads(out)
    assert data["vertices"] == 35_947
    assert data["faces"] == 69_451
    assert [f["kind"] for f in data["findings"]] == ["unreferenced_vertex"]
    assert data["findings"][0]["count"] == 1_113
    assert data["findings"][0]["repairable"] is True
    assert "edges" not in data  # topology statistics need a valid mesh


def test_bunny_repaired(capsys):
    rc, out, err = info(capsys, str(mesh_path("bunny")), "--json", "--repair")
    assert rc == 0
    assert err == ""
    data = json.loads(out)
    assert data["repaired"] is True
    assert data["vertices"] == 34_834
    assert data["faces"] == 69_451
    assert data["boundary_loops"] == 5
    assert data["euler_characteristic"] == -3
    assert data["genus"] == 0
    assert sum(data["boundary_loop_sizes"]) == 223
    assert data["repair"] == (
        "repaired (unreferenced vertex: 1113): dropped 0 faces and 1113 vertices, flipped 0 faces"
    )
    assert data["findings"][0]["count"] == 1_113  # what was found before the repair


def test_nefertiti_fraunhofer_reported_precisely(capsys):
    path = str(mesh_path("nefertiti_fraunhofer"))
    rc, out, err = info(capsys, path, "--json", "--no-repair")
    assert rc == 2
    line = one_line(err)
    assert line.startswith(
        f"meshfit: error: {path}: 3 non-manifold edges shared by more than "
        "two faces (first: edge (695, 696) in faces [841, 975, "
    )
    assert line.endswith(
        "(all caused by duplicate or back-to-back faces) (repairable: run without --no-repair)"
    )
    data = json.loads(out)
    nm, dup = data["findings"]
    assert (nm["kind"], nm["count"], nm["first"], nm["repairable"]) == (
        "non_manifold_edge",
        3,
        [695, 696],
        True,
    )
    assert (dup["kind"], dup["count"], dup["first"], dup["repairable"]) == (
        "duplicate_face",
        3,
        [975],
        True,
    )
    assert "3 of them back-to-back" in dup["message"]
    assert "face 975 repeats face 841" in dup["message"]
    assert data["vertices"] == 10_000
    assert data["faces"] == 19_482
    assert data["vertex_colors"] is True
    assert data["bbox_diagonal"] == pytest.approx(36.4421, rel=5e-6)


def test_nefertiti_fraunhofer_table_lists_both_findings(capsys):
    rc, out, err = info(capsys, str(mesh_path("nefertiti_fraunhofer")), "--no-repair")
    assert rc == 2
    assert "repairable: 3 non-manifold edges" in out
    assert "repairable: 3 duplicate faces, 3 of them back-to-back" in out
    one_line(err)


def test_nefertiti_fraunhofer_repaired(capsys):
    rc, out, err = info(capsys, str(mesh_path("nefertiti_fraunhofer")), "--json", "--repair")
    assert rc == 0
    assert err == ""
    data = json.loads(out)
    assert (
        data["faces"],
        data["vertices"],
        data["euler_characteristic"],
        data["boundary_loops"],
        data["genus"],
    ) == (19_476, 9_997, 1, 1, 0)
    assert data["repaired"] is True
    assert data["repair"] == (
        "repaired (non manifold edge: 3, duplicate face: 3): dropped 6 "
        "faces and 3 vertices, flipped 0 faces"
    )
    rc, out, err = info(capsys, str(mesh_path("nefertiti_fraunhofer")), "--repair")
    assert rc == 0
    assert "repaired: 3 non-manifold edges" in out


def _write_obj(path, v, f):
    rows = [f"v {x} {y} {z}" for x, y, z in np.asarray(v).tolist()]
    rows += ["f " + " ".join(str(i + 1) for i in tri) for tri in np.asarray(f).tolist()]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_moebius_strip_is_not_repairable(tmp_path, capsys):
    v, f = moebius_strip()
    p = _write_obj(tmp_path / "moebius.obj", v, f)
    rc, out, err = info(capsys, str(p), "--no-repair")
    assert rc == 2
    line = one_line(err)
    assert "not orientable" in line
    assert "repairable" not in line  # repair cannot fix it: no false hint
    assert "error: " in out
    rc, out, err = info(capsys, str(p), "--repair")
    assert rc == 2
    assert out == ""
    line = one_line(err)
    assert line.startswith("meshfit: error: moebius.obj: the surface is not orientable")


def test_fin_is_split_apart_by_default(tmp_path, capsys):
    # a fin: three faces on edge (0, 2); the default repair splits the sheets apart
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]]
    p = _write_obj(tmp_path / "fin.obj", v, [[0, 1, 2], [0, 2, 3], [0, 2, 4]])
    rc, out, err = info(capsys, str(p), "--json")
    assert rc == 0, err
    data = json.loads(out)
    assert data["repaired"] is True
    assert data["faces"] == 3
    assert "split" in data["repair"]
    rc, _out, err = info(capsys, str(p), "--no-repair")
    assert rc == 2
    assert "edge (0, 2)" in one_line(err)


def test_inside_out_sphere_is_noted_and_turned(tmp_path, capsys):
    sphere = shapes.icosphere(2)
    p = _write_obj(tmp_path / "inside_out.obj", sphere.vertices, np.asarray(sphere.faces)[:, ::-1])
    rc, out, err = info(capsys, str(p), "--json")
    assert rc == 0, err
    data = json.loads(out)
    assert data["repaired"] is True
    assert "inside out: 1 component" in data["repair"]
    # the strict path does not take it: valid, but a fit of it would face the wrong way
    rc, out, err = info(capsys, str(p), "--json", "--no-repair")
    assert rc == 2
    assert json.loads(out)["repaired"] is False
    assert "1 closed component inside out" in err and "run without --no-repair" in err


def test_repair_of_a_valid_mesh_changes_nothing(capsys):
    rc, out, _err = info(capsys, str(mesh_path("spot")), "--json", "--repair")
    assert rc == 0
    data = json.loads(out)
    assert data["repaired"] is False
    assert "repair" not in data  # a valid mesh is not passed through repair at all


def test_info_on_a_missing_file_and_bad_arguments(tmp_path, capsys):
    rc, out, err = info(capsys, str(tmp_path / "nope.ply"))
    assert rc == 2
    assert out == ""
    assert one_line(err) == f"meshfit: error: {tmp_path / 'nope.ply'}: no such file"
    with pytest.raises(SystemExit) as exc:
        cli.main(["info"])  # argparse: usage on stderr, exit 2
    assert exc.value.code == 2
    assert "usage: meshfit info" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"meshfit {__version__}"


def test_every_command_that_fits_refuses_an_inside_out_mesh_strictly(tmp_path, capsys):
    """--no-repair refuses an inside-out closed mesh before any file is written; the same
    sphere right side out passes."""
    from meshfit.cli import main

    sphere = shapes.icosphere(3)
    p = _write_obj(tmp_path / "inside.obj", sphere.vertices, np.asarray(sphere.faces)[:, ::-1])
    assert main(["fit", "--no-repair", str(p), "--out", str(tmp_path / "f")]) == 2
    assert "inside out" in capsys.readouterr().err
    assert not (tmp_path / "f").exists()
    right = _write_obj(tmp_path / "right.obj", sphere.vertices, np.asarray(sphere.faces))
    rc, _out, _err = info(capsys, str(right), "--no-repair")
    assert rc == 0
