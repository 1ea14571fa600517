"""The fit folder as a user finds it: deliverables named after the input, maps once in
``maps/`` with UDIM numbers, PNG maps on one shared range, the stage cache hidden, and a
re-run that removes what the previous run wrote and this one did not (and nothing else)."""

from __future__ import annotations

import dataclasses
import hashlib
import json

import numpy as np
import png
import pytest
import trimesh

import meshfit
from meshfit.errors import InputError
from meshfit.pipeline import FitOptions
from meshfit.pipeline.outputs import edited_maps, map_patch, output_stem, read_manifest

from .conftest import ROOT, mesh_path, real_mesh

LAYOUT = ROOT / "examples" / "layouts" / "spot.json"
OPTIONS = FitOptions(controls=(6, 6), spring_level=1, report=False)


@pytest.fixture(scope="module")
def spot():
    return real_mesh("spot")


def _png_range(path) -> tuple[float, float]:
    for ctype, data in png.Reader(bytes=path.read_bytes()).chunks():
        if ctype == b"tEXt" and data.startswith(b"meshfit\x00"):
            meta = json.loads(data[len(b"meshfit\x00") :].decode("latin-1"))
            return meta["min"], meta["max"]
    raise AssertionError(f"{path}: no meshfit metadata")


def test_the_folder_is_named_after_the_input_and_holds_each_map_once(spot, tmp_path):
    opts = dataclasses.replace(OPTIONS, formats=("usd", "obj", "exr", "png"))
    meshfit.fit(spot, LAYOUT, options=opts, out=tmp_path)
    top = sorted(p.name for p in tmp_path.iterdir() if p.is_file())
    deliverables = [n for n in top if n not in ("fit.npz", "fit.json", "layout.json")]
    deliverables = [n for n in deliverables if n not in ("summary.json", "manifest.json")]
    assert deliverables and all(n.startswith("spot") for n in deliverables), deliverables
    maps = sorted(p.name for p in (tmp_path / "maps").iterdir())
    assert maps == sorted(f"spot_vector.{1001 + p}.{e}" for p in range(24) for e in ("exr", "png"))
    assert [map_patch(f"maps/{m}", "vector") for m in maps if m.endswith(".exr")] == list(range(24))
    # no image twice, byte for byte, anywhere in the folder
    images = [p for p in tmp_path.rglob("*") if p.suffix in (".exr", ".png") and p.is_file()]
    digests = [hashlib.sha256(p.read_bytes()).hexdigest() for p in images]
    assert len(set(digests)) == len(digests)
    # one value range for every PNG map, symmetric about zero: zero is one grey everywhere
    ranges = {_png_range(tmp_path / "maps" / m) for m in maps if m.endswith(".png")}
    assert len(ranges) == 1
    lo, hi = ranges.pop()
    assert lo == -hi and hi > 0
    # the stage cache is hidden and not a deliverable
    assert (tmp_path / ".meshfit").is_dir() and not (tmp_path / "stages").exists()
    assert not any(f.startswith(".meshfit") for f in read_manifest(tmp_path))


def test_a_rerun_removes_what_it_no_longer_writes_and_nothing_else(spot, tmp_path):
    opts = dataclasses.replace(OPTIONS, formats=("obj", "exr", "png"))
    meshfit.fit(spot, LAYOUT, options=opts, out=tmp_path)
    (tmp_path / "notes.txt").write_text("mine")  # a file the user put there
    painted = tmp_path / "maps" / "spot_vector.1002.exr"
    data = bytearray(painted.read_bytes())
    data[-1] ^= 1  # an edit (the hash differs from the manifest's)
    painted.write_bytes(bytes(data))
    assert list(edited_maps(tmp_path)) == ["maps/spot_vector.1002.exr"]
    res = meshfit.fit(spot, LAYOUT, options=dataclasses.replace(opts, formats=("obj",)))
    assert res.summary["outputs"] == {}  # in memory: nothing written
    again = meshfit.fit(
        spot, LAYOUT, options=dataclasses.replace(opts, formats=("obj",)), out=tmp_path
    )
    assert not list((tmp_path / "maps").glob("*.png"))  # the last run's PNG maps are gone
    left = sorted(p.name for p in (tmp_path / "maps").iterdir())
    assert left == ["spot_vector.1002.exr"]  # but never the user's edit
    assert (tmp_path / "notes.txt").read_text() == "mine"  # nor a file no run wrote
    assert any("previous run" in n and "removed" in n for n in again.summary["notes"])
    listed = read_manifest(tmp_path)
    assert "maps/spot_vector.1002.exr" in listed and "notes.txt" not in listed
    assert all((tmp_path / f).is_file() for f in listed)


@pytest.mark.parametrize(
    ("name", "stem"),
    [("spot.ply", "spot"), ("My Scan.OBJ", "My_Scan"), ("a/b", "a_b"), ("", "fit"), (None, "fit")],
)
def test_output_stem(name, stem):
    assert output_stem(name) == stem


def test_a_manifest_naming_files_outside_the_folder_deletes_nothing(tmp_path):
    from meshfit.pipeline.outputs import remove_stale

    outside = tmp_path / "outside.txt"
    outside.write_text("keep")
    folder = tmp_path / "fit"
    folder.mkdir()
    listed = {"../outside.txt": {}, str(outside): {}, "gone.obj": {}}
    (folder / "gone.obj").write_text("old")
    assert remove_stale(folder, listed, []) == ["gone.obj"]
    assert outside.read_text() == "keep"


def assert_obj_watertight(path, closed: bool) -> None:
    """The OBJ's patches share their boundary vertices: after merging the corners of one
    vertex (a texture coordinate per patch), every edge has two faces on a closed input, one
    or two (the mesh boundary's) on an open one, and the faces turn consistently."""
    obj = trimesh.load(path, process=False, force="mesh")
    obj.merge_vertices(merge_tex=True, merge_norm=True)
    e = np.sort(np.asarray(obj.faces)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    counts = np.unique(e, axis=0, return_counts=True)[1]
    assert counts.max() == 2 and obj.is_winding_consistent
    if closed:
        assert obj.is_watertight
    else:
        assert (counts == 1).any()


@pytest.mark.slow
def test_the_bunny_obj_is_watertight_but_for_its_holes(bunny_fit):
    # open, with unreferenced vertices: the command line's defaults (the other shared meshes:
    # tests/test_pipeline.py and tests/layout/test_regions.py)
    _, _, out = bunny_fit
    assert_obj_watertight(out / "bunny.obj", closed=False)


def test_the_3dm_spline_and_the_exr_map_rebuild_the_displaced_surface(spot, tmp_path):
    # as a CAD or texturing tool would: the spline from the 3dm (rhino3dm), the map read with
    # OpenEXR in the standard orientation (x along u, y up along v; R, G, B = T, N, B)
    import OpenEXR
    import rhino3dm

    opts = dataclasses.replace(OPTIONS, formats=("3dm", "exr"))
    res = meshfit.fit(spot, LAYOUT, options=opts, out=tmp_path)
    diag = res.summary["mesh"]["bbox_diagonal"]
    model = rhino3dm.File3dm.Read(str(tmp_path / "spot.3dm"))
    surfaces = {o.Attributes.Name: o.Geometry for o in model.Objects}
    for p in (0, 7, 23):
        srf = surfaces[f"patch_{p:03d}"]
        with OpenEXR.File(str(tmp_path / "maps" / f"spot_vector.{1001 + p}.exr")) as f:
            img = np.asarray(f.channels()["RGB"].pixels, dtype=np.float64)
        rows, cols = img.shape[:2]  # rows along v (top: v = 1), columns along u
        (u0, u1), (v0, v1) = ((srf.Domain(k).T0, srf.Domain(k).T1) for k in (0, 1))
        want = res.patches[p].displaced()
        assert want.shape[:2] == (cols, rows)
        for i in range(0, cols, 3):
            for j in range(0, rows, 3):
                u = u0 + (u1 - u0) * i / (cols - 1)
                v = v0 + (v1 - v0) * j / (rows - 1)
                frame = srf.FrameAt(u, v)[1]  # X: dS/du, Y: N x X, Z: the normal
                t, n, b = img[rows - 1 - j, i]
                x = [frame.Origin, frame.XAxis, frame.YAxis, frame.ZAxis]
                x = np.array([[q.X, q.Y, q.Z] for q in x])
                got = x[0] + t * x[1] + b * x[2] + n * x[3]
                assert np.linalg.norm(got - want[i, j]) <= 1e-6 * diag, (p, i, j)


def test_the_input_and_the_users_files_are_never_overwritten(tmp_path):
    import shutil

    scan = tmp_path / "spot.ply"
    shutil.copy(mesh_path("spot"), scan)
    before = scan.read_bytes()
    opts = dataclasses.replace(OPTIONS, formats=("ply",))
    with pytest.raises(InputError, match="no fit wrote it"):
        meshfit.fit(scan, LAYOUT, options=opts, out=tmp_path)  # spot.ply is the input
    assert scan.read_bytes() == before
    # in its own folder the PLY is written, watertight, with the fit's patch of each face
    out = tmp_path / "fit"
    meshfit.fit(scan, LAYOUT, options=opts, out=out)
    ply = trimesh.load(out / "spot.ply", process=False)
    ply.merge_vertices()
    assert ply.is_watertight
    # a re-run into the same folder overwrites what the fit wrote
    meshfit.fit(scan, LAYOUT, options=opts, out=out)
    assert "spot.ply" in read_manifest(out)
