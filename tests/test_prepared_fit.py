"""The fit of a prepared scan, out of core (meshfit.pipeline.prepared_stages)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshfit.cli import main
from meshfit.errors import InputError
from meshfit.mesh import Mesh, save_mesh
from meshfit.mesh.locate import grid_tree
from meshfit.pipeline import FitOptions, fit, measure, open_prepared, prepare_out_of_core
from meshfit.pipeline.cluster import piece_mesh
from meshfit.pipeline.prepared_stages import face_patch

from .shapes import tori

#: the fit's defaults (matched maps: a map finer than its spring grid searches the pieces)
OPTIONS = FitOptions(report=False)


@pytest.fixture(scope="module")
def prepared(tmp_path_factory):
    """A genus-2 surface written as a PLY and prepared through a proxy of a quarter of its
    faces (so the curves are carried, not copied), with its fit from the folder."""
    root = tmp_path_factory.mktemp("prep")
    mesh = tori(2)
    path = root / "genus2.ply"
    save_mesh(mesh, path)
    prep = prepare_out_of_core(path, root / "prep", proxy_faces=mesh.n_faces // 4, workers=2)
    result = fit(root / "prep", options=OPTIONS)
    return mesh, prep, result


def _whole(prep) -> Mesh:
    """The prepared scan as one mesh (store order), as only a test holds it."""
    return Mesh(np.array(prep.store.vertices), np.array(prep.store.faces))


def test_the_errors_are_the_whole_scans(prepared):
    # each patch's texels are searched in its piece and the scan's vertices a chunk at a
    # time: the figures are those of the whole scan searched at once, to round-off
    mesh, prep, result = prepared
    whole = _whole(prep)
    disp = [p.displaced() for p in result.patches]
    # (the spline-only surface at its spring grids' parameters, the maps at matched shapes)
    spline = measure.texel_grids(
        [p.surface for p in result.patches], [p.spring.shape[:2] for p in result.patches]
    )
    for key, grids in (("spline_only", spline), ("displaced", disp)):
        V, F = measure.soup(grids)
        tree = grid_tree(V, F, [g.shape[:2] for g in grids])
        want, _, from_input = measure.error_figures(whole, V, F, tree)
        got = result.summary["errors"][key]
        for k, v in want.items():
            assert got[k] == pytest.approx(v, rel=1e-9, abs=1e-15), (key, k)
    # the per-patch figure over each patch's input faces
    n = len(result.patches)
    fp = face_patch(prep)[np.asarray(prep.store.input_face)]
    want = measure.per_patch_max(whole, fp, from_input, n)
    got = result.summary["errors"]["displaced_from_input_max_per_patch"]
    np.testing.assert_allclose(np.array(got) * whole.bbox_diagonal, want, rtol=1e-12)
    assert result.summary["mesh"]["faces"] == mesh.n_faces
    assert result.summary["mesh"]["name"] == "genus2.ply"


def test_every_input_face_has_its_patch(prepared):
    mesh, _, result = prepared
    fp = result.face_patch
    assert fp.shape == (mesh.n_faces,) and fp.min() >= 0 and fp.max() == len(result.patches) - 1
    assert set(fp.tolist()) == set(range(len(result.patches)))


def test_the_fit_is_a_good_one(prepared):
    # the carried layout folds no spring mesh its own patches on the proxy do not fold (a
    # coarse proxy's region layout can have a patch that turns back at a corner: that one
    # folds on either)
    mesh, prep, result = prepared
    on_proxy = fit(prep.proxy, prep.layout, options=FitOptions(remesh="off", report=False))
    folds = [p["folded"] for p in result.summary["patches"]]
    proxy_folds = [p["folded"] for p in on_proxy.summary["patches"]]
    assert all(a == 0 or a <= b for a, b in zip(folds, proxy_folds, strict=True))
    # and the displaced surface is as near the scan as the in-memory fit's
    s, mem = result.summary["errors"], fit(mesh, options=OPTIONS).summary["errors"]
    for k in ("rms", "hausdorff"):
        assert s["displaced"][k] <= 1.5 * mem["displaced"][k], k
    s = result.summary
    assert s["seams"]["displaced_gap_max"] < 1e-9 and s["seams"]["spline_gap_max"] == 0.0


def test_a_finer_map_takes_its_points_from_the_pieces_as_from_the_whole(prepared):
    # a texel's closest point of the scan lies in its patch's piece (its faces and a halo of
    # one proxy edge): the points a finer map is made from are the whole scan's
    from meshfit.displacement import scan_points

    _, prep, result = prepared
    whole = _whole(prep)
    diag = whole.bbox_diagonal
    for p in result.patches[:: max(1, len(result.patches) // 6)]:
        h, w = p.spring.shape[:2]
        shape = (2 * h - 1, 2 * w - 1)
        a, on_a = scan_points(piece_mesh(prep.folder, p.index), p.surface, p.spring, shape)
        b, on_b = scan_points(whole, p.surface, p.spring, shape)
        np.testing.assert_array_equal(on_a, on_b)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * diag)


def test_the_tasks_give_the_threads_bytes(prepared):
    # springs, splines, maps (matched: searched in the pieces) and texels as tasks of a
    # LocalCluster: the same bytes as on the threads of one process
    _, prep, a = prepared
    b = fit(prep.folder, options=OPTIONS, cluster=2)
    for x, y in zip(a.patches, b.patches, strict=True):
        np.testing.assert_array_equal(x.spring, y.spring)
        np.testing.assert_array_equal(x.displacement.values, y.displacement.values)
    assert a.summary["errors"] == b.summary["errors"]
    stages = ("springs", "fit", "displacement", "errors")
    assert all(b.summary["stages"][k]["patch_tasks"] for k in stages)


def test_meshfit_fit_on_a_prepared_folder(prepared, tmp_path, capsys):
    _, prep, _ = prepared
    out = tmp_path / "fit"
    args = ["fit", str(prep.folder), "--out", str(out), "--formats", "obj", "--json"]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (out / "report.html").is_file() and (out / "genus2.obj").is_file()
    assert summary["layout"]["source"] == "prepared"
    assert any("out of core" in n for n in summary["notes"])
    # again with --resume: every stage is read back
    assert main([*args, "--resume"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["work_done"] == [] and again["errors"] == summary["errors"]


def test_bad_calls_are_refused(prepared, tmp_path, capsys):
    _, prep, _ = prepared
    cases = [
        (["--layout", "x.json"], "--layout does not apply to a prepared folder"),
        (["--out", str(prep.folder / "fit")], "inside the prepared folder"),
    ]
    for extra, why in cases:
        argv = ["fit", str(prep.folder), *extra]
        if "--out" not in extra:
            argv += ["--out", str(tmp_path / "o")]
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0], err
    assert not (prep.folder / "fit").exists() and not (tmp_path / "o").exists()
    with pytest.raises(InputError, match="the layout it was prepared with"):
        fit(prep.folder, layout=prep.layout)


def test_a_damaged_preparation_is_refused_by_name(prepared, tmp_path):
    import shutil

    _, prep, _ = prepared
    for what, damage, why in [
        ("meta", lambda d: (d / "prepared.json").unlink(), "not a prepared scan folder"),
        (
            "version",
            lambda d: (d / "prepared.json").write_text(
                json.dumps({**json.loads((d / "prepared.json").read_text()), "version": 99})
            ),
            "version 99",
        ),
        ("patch", lambda d: (d / "cut" / "patch-0.npz").unlink(), "patch-0.npz: missing"),
        ("network", lambda d: (d / "network.npz").write_bytes(b"no"), "damaged preparation"),
    ]:
        copy = tmp_path / what
        shutil.copytree(prep.folder, copy)
        damage(copy)
        with pytest.raises(InputError, match=why):
            open_prepared(copy)
    # a folder without prepared.json is not taken for a prepared one: it is a mesh path
    assert not (tmp_path / "meta" / "prepared.json").exists()
