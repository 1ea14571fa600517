"""``meshfit springs`` on the spot layout."""

from __future__ import annotations

import argparse
import json
import re

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
        "corner_angles",
    ):
        assert key in row
    assert row["level"] == 2
    assert all(0.5 < r["bulge"] < 3.0 for r in data["patches"])
    # no patch of this layout bulges beyond meshfit.layout.patch.BULGY; the four at the head
    # taper beyond TAPERED
    assert len(data["notes"]) == 1 and data["notes"][0].startswith("4 patches taper")
    assert all(r["taper"] >= 1.0 for r in data["patches"])
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
    assert "spring meshes" in text and "summary" in text and "seconds" in text
    rows = [line.split() for line in text.splitlines() if line.split()[:1] == ["23"]]
    assert len(rows) == 1 and rows[0][2] == "10x9" and rows[0][3] == "0"  # patch 23, level 0
    # values above the quality bounds are marked (spot's near-triangular patch 1)
    assert "median aspect above 1.5" in text and "!" in text


@pytest.mark.parametrize("columns", [None, "72"])
def test_springs_table_keeps_every_figure_whole(columns, capsys, monkeypatch):
    # printed to a pipe (80 columns by default) or a narrow terminal, the table once cut its
    # figures short ("0.48…"): they keep their width, the notes wrap or drop out instead
    if columns is None:
        monkeypatch.delenv("COLUMNS", raising=False)
    else:
        monkeypatch.setenv("COLUMNS", columns)
    layout = ROOT / "examples" / "layouts" / "spot.json"
    assert main(["springs", str(mesh_path("spot")), "--layout", str(layout)]) == 0
    text = capsys.readouterr().out
    assert "…" not in text
    head = next(line for line in text.splitlines() if "fidelity %" in line)
    assert head.split()[:3] == ["patch", "verts", "grid"]
    rows = {int(w[0]): w for w in (ln.split() for ln in text.splitlines()) if w[:1] == ["1"]}
    row = rows[1]  # spot's patch 1: over the arc-length, aspect and fidelity bounds
    assert [c.endswith("!") for c in row[4:8]] == [True, True, False, True]
    assert float(row[4].rstrip("!")) > 0.15 and row[2].count("x") == 1
    if columns is None:  # a pipe: the whole line, notes included
        assert "last level arc length" in " ".join(row[8:])


def test_springs_json_summary_lists_the_patches_over_each_bound(capsys):
    from meshfit.springs import QUALITY_BOUNDS

    layout = ROOT / "examples" / "layouts" / "spot.json"
    args = ["springs", str(mesh_path("spot")), "--layout", str(layout), "--level", "1", "--json"]
    assert main(args) == 0
    data = json.loads(capsys.readouterr().out)
    summary = data["summary"]
    assert summary["patches"] == 24 and summary["bounds"] == QUALITY_BOUNDS
    assert summary["folded_cells"] == sum(r["folded"] for r in data["patches"])
    for key, ids in summary["over_bounds"].items():
        want = [r["patch"] for r in data["patches"] if r[key] > QUALITY_BOUNDS[key]]
        assert ids == want
    assert summary["over_bounds"]["aspect_median"]  # spot's near-triangular patches
    # the tapered head patches whose level 0 the fairness fallback remade
    remade = {r["patch"]: r["fairness"] for r in data["patches"] if r["remade"]}
    assert {0, 2, 4} <= set(remade)
    assert all(remade[k] == 0.0 for k in (0, 2, 4))
    assert all(r["fairness"] == 0.5 for r in data["patches"] if not r["remade"])


def test_out_of_bounds_names_the_metrics_above_their_bounds():
    from meshfit.springs import out_of_bounds

    ok = {"arc_cv_max": 0.15, "aspect_median": 1.2, "folded": 0, "fidelity_max": 1e-4}
    assert out_of_bounds(ok) == []
    bad = {**ok, "arc_cv_max": 0.16, "folded": 2}
    assert out_of_bounds(bad) == ["arc_cv_max", "folded"]
    assert out_of_bounds({"aspect_median": 2.0}) == ["aspect_median"]  # missing ones skipped
    assert out_of_bounds(bad, {"folded": 5}) == []


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


@pytest.mark.parametrize(
    ("level", "says"),
    [("-1", "non-negative integer"), ("9", "points; at most 4,000,000 .* ask for level 7 or less")],
)
def test_springs_command_rejects_a_negative_or_too_fine_level(level, says, capsys):
    # level 9 would make 25 million points a patch of spot (the process ran out of memory)
    layout = ROOT / "examples" / "layouts" / "spot.json"
    assert main(["springs", str(mesh_path("spot")), "--layout", str(layout), "--level", level]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and re.search(says, err), err


def test_springs_command_gives_the_same_grids_on_any_number_of_workers(tmp_path, capsys):
    layout = ROOT / "examples" / "layouts" / "spot.json"
    rows, files = {}, {}
    for w in ("1", "2"):
        out = tmp_path / w
        args = ["springs", str(mesh_path("spot")), "--layout", str(layout), "--level", "1",
                "--workers", w, "--out", str(out), "--json"]  # fmt: skip
        assert main(args) == 0
        data = json.loads(capsys.readouterr().out)
        rows[w] = [{k: v for k, v in r.items() if k not in ("seconds", "files")}
                   for r in data["patches"]]  # fmt: skip
        assert [r["patch"] for r in data["patches"]] == list(range(24))  # in layout order
        files[w] = out
    assert rows["1"] == rows["2"]
    for k in range(24):
        with (
            np.load(files["1"] / f"patch_{k:03d}.npz", allow_pickle=False) as a,
            np.load(files["2"] / f"patch_{k:03d}.npz", allow_pickle=False) as b,
        ):
            assert np.array_equal(a["face"], b["face"]) and np.array_equal(a["bary"], b["bary"])


@pytest.mark.parametrize("workers", ["0", "-2"])
def test_springs_command_rejects_a_bad_worker_count(workers, capsys):
    layout = ROOT / "examples" / "layouts" / "spot.json"
    args = ["springs", str(mesh_path("spot")), "--layout", str(layout), "--workers", workers]
    assert main(args) == 2
    assert "workers must be an integer >= 1" in capsys.readouterr().err


def test_springs_command_refines_patches_to_a_tolerance(capsys):
    layout = ROOT / "examples" / "layouts" / "spot.json"
    base = ["springs", str(mesh_path("spot")), "--layout", str(layout), "--json"]
    assert main(base) == 0
    plain = json.loads(capsys.readouterr().out)["patches"]
    assert all(r["tolerance_met"] is None and r["finer"] == 0 for r in plain)
    assert main([*base, "--tolerance", "2e-3"]) == 0
    rows = json.loads(capsys.readouterr().out)["patches"]
    for a, b in zip(plain, rows, strict=True):
        assert b["tolerance_met"] == (b["fidelity_max"] <= 2e-3)
        if a["fidelity_max"] <= 2e-3:  # met already: the same grid
            assert b["finer"] == 0 and b["grid"] == a["grid"]
        else:
            assert b["finer"] > 0 or not b["tolerance_met"]
    assert sum(r["finer"] > 0 for r in rows) > 0
    assert sum(r["tolerance_met"] for r in rows) > sum(r["fidelity_max"] <= 2e-3 for r in plain)
    assert sum(r["folded"] for r in rows) == 0


@pytest.mark.parametrize("extra", [["--tolerance", "0"], ["--tolerance", "1e-3", "--level", "1"]])
def test_springs_command_rejects_a_bad_tolerance(extra, capsys):
    layout = ROOT / "examples" / "layouts" / "spot.json"
    assert main(["springs", str(mesh_path("spot")), "--layout", str(layout), *extra]) == 2
    assert "tolerance" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("where", "says"),
    [
        ("afile", "afile: a file, where a folder is needed"),
        ("afile/sub", "afile: a file, where a folder is needed"),
        ("missing/deeper", None),  # made, with its parents
    ],
)
def test_springs_command_output_folder_errors_are_one_line(tmp_path, where, says, capsys):
    # an output path that cannot be a folder: one error line and exit code 2, no traceback
    (tmp_path / "afile").write_text("not a folder")
    layout = ROOT / "examples" / "layouts" / "spot.json"
    args = ["springs", str(mesh_path("spot")), "--layout", str(layout), "--level", "0"]
    code = main([*args, "--out", str(tmp_path / where)])
    err = capsys.readouterr().err
    if says is None:
        assert code == 0 and (tmp_path / where).is_dir()
        return
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("meshfit: error: ")
    assert err.strip().endswith(says), err


def test_a_file_in_a_missing_folder_is_named(tmp_path):
    from meshfit.cli import _os_error

    with pytest.raises(OSError) as info:
        (tmp_path / "no" / "such" / "x.mfsw").write_bytes(b"")
    assert _os_error(info.value) == f"{tmp_path / 'no' / 'such'}: no such folder"


def test_running_out_of_memory_is_one_error_line(capsys, monkeypatch):
    from meshfit import cli

    def oom(args):
        raise MemoryError

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    monkeypatch.setattr(parser, "parse_args", lambda argv: argparse.Namespace(func=oom))
    assert cli.main([]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("meshfit: error: out of memory")


def test_springs_command_follows_folds_on_request(capsys):
    """``--follow-folds`` carries the grid over spot's horns and ears (patches 1 and 3 miss
    far less of their surface) and leaves the other patches' figures as they were."""
    layout = ROOT / "examples" / "layouts" / "spot.json"
    args = ["springs", str(mesh_path("spot")), "--layout", str(layout), "--json"]
    rows = []
    for extra in ([], ["--follow-folds"]):
        assert main(args + extra) == 0
        rows.append({r["patch"]: r for r in json.loads(capsys.readouterr().out)["patches"]})
    plain, folds = rows
    for k in (1, 3):
        assert folds[k]["fidelity_max"] < 0.5 * plain[k]["fidelity_max"]
    same = [k for k in plain if folds[k]["fidelity_max"] == plain[k]["fidelity_max"]]
    assert len(same) >= 12  # most of spot's patches cross no fold
