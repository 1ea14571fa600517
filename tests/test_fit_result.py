"""The front door and the result type: meshfit.fit in memory, save / load_fit bit for bit,
editing a map image and rebuilding, and re-runs that never lose an edit."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import OpenEXR
import pytest

import meshfit
from meshfit import tol
from meshfit.cli import main
from meshfit.displacement.io import from_image
from meshfit.errors import InputError
from meshfit.pipeline import FitOptions, FitResult, load_fit, measure
from meshfit.pipeline.outputs import edited_maps, read_manifest

from .conftest import ROOT, mesh_path, real_mesh

LAYOUT = ROOT / "examples" / "layouts" / "spot.json"
# native maps: the displaced surface is the spring mesh itself, which the tests below use
OPTIONS = FitOptions(
    controls=(6, 6), spring_level=1, formats=("exr",), report=False, map_shapes="native"
)
PATCH = 5  # the patch whose map is painted


@pytest.fixture(scope="module")
def spot(tmp_path_factory):
    """An in-memory fit of spot and the same fit through the command line, into a folder."""
    mesh = real_mesh("spot")
    memory = meshfit.fit(mesh, LAYOUT, options=OPTIONS)
    out = tmp_path_factory.mktemp("spot_fit")
    mesh_file = mesh_path("spot")
    argv = ["fit", str(mesh_file), "--layout", str(LAYOUT), "--out", str(out), "--cv", "6x6"]
    argv += ["--level", "1", "--formats", "exr", "--no-report", "--map-shapes", "native"]
    argv += ["--json"]
    assert main(argv) == 0
    return mesh, memory, out


def _arrays(result: FitResult) -> list[np.ndarray]:
    out = []
    for p in result.patches:
        out += [p.spring, p.surface.control_points, p.displacement.values]
    return out


def test_front_door_names():
    for name in ("fit", "load_fit", "wrap", "FitResult", "PatchFit", "FitOptions", "WrapResult"):
        assert name in meshfit.__all__ and getattr(meshfit, name) is not None
    with pytest.raises(AttributeError):
        meshfit.no_such_name  # noqa: B018


def test_in_memory_fit_gives_the_command_lines_figures(spot):
    _, memory, out = spot
    saved = json.loads((out / "summary.json").read_text())
    assert memory.summary["errors"] == saved["errors"]
    assert memory.summary["seams"] == saved["seams"]
    assert memory.summary["control_classes"] == saved["control_classes"]
    assert len(memory.patches) == saved["patches_total"] == 24
    # nothing was written by the in-memory fit: its summary lists no outputs
    assert memory.summary["outputs"] == {}
    p = memory.patches[0]
    assert p.spring.dtype == np.float64 and p.spring.ndim == 3
    assert p.surface.control_points.shape == (6, 6, 3)
    assert p.displacement.values.shape[:2] == p.spring.shape[:2]
    # inside the seams (which the stitch closes) the displaced surface is the spring mesh
    inner = (slice(1, -1), slice(1, -1))
    atol = 1e-9 * memory.summary["mesh"]["bbox_diagonal"]
    assert np.allclose(p.displaced()[inner], p.spring[inner], atol=atol)


def test_save_then_load_is_bit_for_bit(spot, tmp_path):
    _, memory, _ = spot
    memory.save(tmp_path)
    back = load_fit(tmp_path)
    for a, b in zip(_arrays(memory), _arrays(back), strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    assert back.options == memory.options
    assert back.network == memory.network
    assert back.summary == memory.summary
    assert [p.displacement.kind for p in back.patches] == ["vector"] * 24
    assert back.face_patch.tobytes() == memory.face_patch.tobytes()
    assert back.spline_distance.tobytes() == memory.spline_distance.tobytes()
    from meshfit.layout import layout_to_json

    assert layout_to_json(back.layout) == layout_to_json(memory.layout)
    files = read_manifest(tmp_path)
    assert {"fit.npz", "fit.json", "layout.json", "summary.json"} <= set(files)
    assert files["fit.npz"]["kind"] == "fit"


def test_load_fit_refuses_what_is_not_a_fit(tmp_path):
    with pytest.raises(InputError, match="no fit here"):
        load_fit(tmp_path)
    (tmp_path / "fit.json").write_text("{not json")
    (tmp_path / "fit.npz").write_bytes(b"")
    with pytest.raises(InputError, match="not a meshfit fit file"):
        load_fit(tmp_path)


def _paint(path, centre, radius: float, height: float) -> np.ndarray:
    """Add a bump of ``height`` along the normal channel (green: the files hold T, N, B) of
    a vector map image, as a user would with numpy and OpenEXR; returns the bump per pixel."""
    with OpenEXR.File(str(path)) as f:
        header = dict(f.header())
        rgb = np.array(f.channels()["RGB"].pixels, dtype=np.float32)
    h, w = rgb.shape[:2]
    i, j = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    d2 = (i - centre[0]) ** 2 + (j - centre[1]) ** 2
    bump = np.where(d2 < radius**2, height * (1.0 - d2 / radius**2) ** 2, 0.0)
    rgb[:, :, 1] += bump.astype(np.float32)
    keep = {k: v for k, v in header.items() if k.startswith("meshfit") or k == "compression"}
    keep["type"] = OpenEXR.scanlineimage
    with OpenEXR.File(keep, {"RGB": np.ascontiguousarray(rgb)}) as f:
        f.write(str(path))
    return bump


def _painted_fit(spot, tmp_path, height: float = 0.01):
    import shutil

    _, _, out = spot
    folder = tmp_path / "fit"
    shutil.copytree(out, folder)
    before = load_fit(folder)
    diag = before.summary["mesh"]["bbox_diagonal"]
    image = folder / "maps" / f"spot_vector.{1001 + PATCH}.exr"
    h, w = before.patches[PATCH].displacement.shape
    # the image is w rows (v, upwards) by h columns (u); the bump back in texel order
    bump = from_image(_paint(image, (w // 2, h // 2), min(h, w) / 5, height * diag))
    return folder, before, image, bump, diag


def test_an_edited_map_moves_the_surface_there_and_nowhere_else(spot, tmp_path):
    folder, before, image, bump, diag = _painted_fit(spot, tmp_path)
    assert list(edited_maps(folder)) == [f"maps/spot_vector.{1001 + PATCH}.exr"]
    edited_bytes = image.read_bytes()
    assert main(["rebuild", str(folder), "--json"]) == 0
    assert image.read_bytes() == edited_bytes  # the user's image is the input: never rewritten
    assert edited_maps(folder) == {}  # applied: the manifest holds its hash now
    after = load_fit(folder)
    old = before.patches[PATCH].displaced()
    new = after.patches[PATCH].displaced()
    normal = after.patches[PATCH].surface.points_and_frames(
        *np.meshgrid(
            np.linspace(0, 1, old.shape[0]), np.linspace(0, 1, old.shape[1]), indexing="ij"
        )
    )[3]
    moved = new - old
    # the painted amount, at the painted place, along the normal (float32 image precision)
    float32 = 1e-6 * diag
    assert np.abs(moved - bump[:, :, None] * normal).max() < float32
    assert np.abs(moved[bump == 0]).max() < float32
    for p in range(len(after.patches)):
        if p != PATCH:
            assert np.abs(after.patches[p].displaced() - before.patches[p].displaced()).max() < (
                float32
            )
    seams = after.summary["seams"]
    assert seams["displaced_gap_max"] <= tol.STITCH_GAP
    assert after.summary["errors"]["displaced"] is None  # no mesh given: not re-measured
    assert any("without the input mesh" in n for n in after.summary["notes"])


def test_rebuild_with_the_mesh_measures_the_errors_again(spot, tmp_path):
    folder, before, _, _, _ = _painted_fit(spot, tmp_path, height=0.05)
    mesh, _, _ = spot
    after = load_fit(folder, mesh=mesh).rebuild()
    e0, e1 = before.summary["errors"]["displaced"], after.summary["errors"]["displaced"]
    # a bump of 5% of the diagonal the scan does not have: the Hausdorff distance shows it
    # (at most its height plus the fit's own error; the scan may pass nearer than its base)
    assert e1["hausdorff"] > 2 * e0["hausdorff"]
    assert e1["hausdorff"] <= 0.05 + e0["hausdorff"]
    other = dataclasses.replace(mesh, vertices=mesh.vertices * 2.0)
    with pytest.raises(InputError, match="not the fit's input"):
        load_fit(folder, mesh=other).rebuild()


def test_rebuild_renders_the_report_again_where_it_can(spot, tmp_path):
    folder, _, _, _, _ = _painted_fit(spot, tmp_path, height=0.05)
    mesh, _, _ = spot
    with pytest.raises(InputError, match="drawn on the input mesh"):
        load_fit(folder, edited=False).report(folder)
    files = load_fit(folder, edited=False, mesh=mesh).report(folder, image_size=96)
    assert files[0] == "report.html" and "report/displaced.png" in files
    listed = read_manifest(folder)
    assert all(f in listed for f in files)
    shown = (folder / "report" / "displaced.png").read_bytes()
    # without the mesh the page stays as it was, and the rebuild says so
    assert main(["rebuild", str(folder), "--out", str(tmp_path / "bare"), "--json"]) == 0
    notes = json.loads((tmp_path / "bare" / "summary.json").read_text())["notes"]
    assert not any("report.html still shows" in n for n in notes)  # no page there to be stale
    assert main(["rebuild", str(folder), "--json"]) == 0
    notes = load_fit(folder).summary["notes"]
    assert any("report.html still shows the fit before the rebuild" in n for n in notes)
    assert (folder / "report" / "displaced.png").read_bytes() == shown
    # with it the painted bump shows in the displaced render
    assert main(["rebuild", str(folder), "--mesh", str(mesh_path("spot")), "--json"]) == 0
    assert (folder / "report" / "displaced.png").read_bytes() != shown
    assert "report.html" in load_fit(folder).summary["outputs"]["report"]


def test_a_refit_keeps_the_edited_map_and_says_so(spot, tmp_path):
    folder, _, image, _, _ = _painted_fit(spot, tmp_path)
    mesh, _, _ = spot
    edited_bytes = image.read_bytes()
    for resume in (True, False):
        again = meshfit.fit(mesh, LAYOUT, options=OPTIONS, out=folder, resume=resume)
        assert image.read_bytes() == edited_bytes
        assert any("edited map file(s) kept" in n for n in again.summary["notes"])
        assert list(edited_maps(folder)) == [f"maps/spot_vector.{1001 + PATCH}.exr"]
    # the stored fit is the fit's own: the edit waits for a rebuild
    stored = load_fit(folder, edited=False).patches[PATCH].displacement.values
    edited = load_fit(folder).patches[PATCH].displacement.values
    assert np.abs(stored - edited).max() > 0


def test_an_edited_map_of_another_size_is_refused(spot, tmp_path):
    folder, _, image, _, _ = _painted_fit(spot, tmp_path)
    from meshfit.displacement import DisplacementMap, write_exr

    write_exr(DisplacementMap(np.zeros((3, 3, 3)), "vector"), image)
    with pytest.raises(InputError, match="keep the kind and size"):
        load_fit(folder)


def test_rebuild_in_memory_after_replacing_a_map(spot):
    _, memory, _ = spot
    maps = memory.maps
    changed = maps[PATCH].values.copy()
    changed[2, 2, 2] += 0.001
    from meshfit.displacement import DisplacementMap

    maps[PATCH] = DisplacementMap(changed, "vector")
    after = memory.with_maps(maps).rebuild()
    delta = after.patches[PATCH].displaced() - memory.patches[PATCH].displaced()
    assert np.linalg.norm(delta[2, 2]) == pytest.approx(0.001, rel=1e-9)
    rest = np.delete(delta.reshape(-1, 3), 2 * delta.shape[1] + 2, axis=0)
    assert np.abs(rest).max() < 1e-12  # round-off of the frames only
    assert after.summary["errors"]["displaced"] is not None  # the mesh is in memory
    with pytest.raises(InputError, match="maps for a fit"):
        memory.with_maps(maps[:3])


def test_wrap_front_door():
    from meshfit.demo import demo_mesh

    res = meshfit.wrap(demo_mesh(2000), levels=1, options=meshfit.WrapOptions(base_faces=20))
    assert isinstance(res, meshfit.WrapResult)
    assert len(res.meshes) == 2
    with pytest.raises(InputError, match="sphere_method"):
        meshfit.WrapOptions(sphere_method="magic")


def test_spline_smoothing_moves_detail_into_the_maps(spot):
    """Thesis sec. 7.5: with the option the splines hold less of the scan's fine detail and
    the maps more; the displaced surface (spline + vector map) is the same surface."""
    mesh, plain, _ = spot
    smooth = meshfit.fit(mesh, LAYOUT, options=dataclasses.replace(OPTIONS, spline_smoothing=0.5))
    e0, e1 = plain.summary["errors"], smooth.summary["errors"]
    assert e1["spline_only"]["rms"] > e0["spline_only"]["rms"]
    assert e1["displaced"]["rms"] == pytest.approx(e0["displaced"]["rms"], rel=1e-6)
    assert e1["displaced"]["hausdorff"] == pytest.approx(e0["displaced"]["hausdorff"], rel=1e-6)
    energy = [sum(float((m.values**2).sum()) for m in r.maps) for r in (plain, smooth)]
    assert energy[1] > energy[0]
    seams = smooth.summary["seams"]
    assert seams["spline_gap_max"] <= tol.STITCH_GAP  # pinned boundaries filtered alike
    assert seams["displaced_gap_max"] <= tol.STITCH_GAP
    with pytest.raises(InputError, match="spline_smoothing"):
        FitOptions(spline_smoothing=-1.0)


def test_the_spline_only_figures_do_not_depend_on_the_maps(spot):
    # the spline-only surface is measured at its spring grids' parameters: maps matched to
    # equal counts along shared curves (more texels) leave its figures as they are
    mesh, native, _ = spot
    matched = meshfit.fit(mesh, LAYOUT, options=dataclasses.replace(OPTIONS, map_shapes="matched"))
    assert [m.shape for m in matched.maps] != [m.shape for m in native.maps]
    assert matched.summary["errors"]["spline_only"] == native.summary["errors"]["spline_only"]
    assert matched.spline_distance.tobytes() == native.spline_distance.tobytes()
    assert matched.summary["errors"]["displaced"] != native.summary["errors"]["displaced"]


@pytest.mark.parametrize("kind", ["scalar", "bump"])
def test_every_map_kind_fits_saves_and_rebuilds(spot, tmp_path, kind):
    mesh, vector, _ = spot
    opts = dataclasses.replace(OPTIONS, map_kind=kind, formats=("exr", "obj", "usd"))
    res = meshfit.fit(mesh, LAYOUT, options=opts, out=tmp_path)
    assert {m.kind for m in res.maps} == {kind}
    e, ev = res.summary["errors"], vector.summary["errors"]
    if kind == "bump":  # shading only: the surface is the spline, at the map's texels
        texels = measure.texel_grids(res.surfaces, [m.shape for m in res.maps])
        at_texels, _ = measure.spline_errors(mesh, texels)
        assert e["displaced"]["rms"] == pytest.approx(at_texels["rms"], rel=1e-9)
        # (the spline-only figures sample it at its spring grids' parameters)
        assert e["spline_only"]["rms"] == pytest.approx(at_texels["rms"], rel=0.1)
        assert (tmp_path / "spot_spline.obj").is_file() and not (tmp_path / "spot.obj").exists()
    else:  # a distance along the normal: between the spline alone and the vector map
        assert ev["displaced"]["rms"] < e["displaced"]["rms"] < e["spline_only"]["rms"]
        assert res.summary["seams"]["displaced_gap_max"] <= tol.STITCH_GAP
    assert (tmp_path / "maps" / f"spot_{kind}.1001.exr").is_file()
    back = load_fit(tmp_path)
    assert [m.kind for m in back.maps] == [kind] * 24
    for a, b in zip(back.maps, res.maps, strict=True):
        assert a.values.tobytes() == b.values.tobytes()
    again = back.rebuild()  # nothing edited: the same maps, seams closed as before
    for a, b in zip(again.maps, res.maps, strict=True):
        assert np.abs(a.values - b.values).max() <= 1e-12
    with pytest.raises(InputError, match="map_kind"):
        FitOptions(map_kind="height")
    assert FitOptions(map_kind="normal").map_kind == "scalar"  # the older name
