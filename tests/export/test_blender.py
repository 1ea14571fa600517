"""Blender as a client of the USD export: the layer is imported and rendered by Blender itself.

Blender's Python module (``bpy``) pins its own Python and numpy, so it lives in a virtualenv
of its own and the scripts run there in a subprocess: the package's render script
(``meshfit/report_blender.py``, which the fit report runs too) and the inspection script in
``tests/export/blender/``. The interpreter is ``$MESHFIT_BLENDER_PYTHON``, else the venv
``.ci/run`` creates at ``${MESHFIT_BLENDER_VENV:-~/.cache/meshfit/blender-venv}``; without
either the tests fail and say how to make one. The renders are written to
``$MESHFIT_BLENDER_RENDERS`` when set (a report can include them), else to a temporary
folder.
"""

from __future__ import annotations

import functools
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import png
import pytest
from numpy.testing import assert_allclose

import meshfit
from meshfit.demo import demo_mesh
from meshfit.displacement import DisplacementMap, write_exr
from meshfit.export import export_usd
from meshfit.export.units import unit
from meshfit.export.weld import patch_mesh, udim
from meshfit.layout import cube_layout
from meshfit.pipeline import FitOptions
from meshfit.pipeline.outputs import read_manifest
from meshfit.report import BLENDER_PYTHON_ENV, BLENDER_SCRIPT

#: the test scripts, and the package's render script
SCRIPTS = {
    "inspect_usd.py": Path(__file__).parent / "blender" / "inspect_usd.py",
    "render_usd.py": BLENDER_SCRIPT,
}
DEFAULT_VENV = Path.home() / ".cache" / "meshfit" / "blender-venv"
HOW_TO = (
    "the Blender tests need Blender's Python module in its own virtualenv (bpy pins Python "
    "3.11 and numpy<2): run .ci/run, or\n"
    "    python3.11 -m venv ~/.cache/meshfit/blender-venv && "
    "~/.cache/meshfit/blender-venv/bin/pip install bpy==4.5.4\n"
    "or point MESHFIT_BLENDER_PYTHON at a python that can import bpy"
)
#: the map pattern of the pipeline's naming, relative to the layer
PATTERN = "./maps/scan_vector.<UDIM>.exr"
#: renders: pixels a side and Cycles samples
SIZE, SAMPLES = 128, 4
#: the camera looks along this direction (world coordinates)
VIEW = (1.0, 1.0, -0.7)


@functools.cache
def blender_python() -> Path:
    """The interpreter with ``bpy``: ``$MESHFIT_BLENDER_PYTHON``, else the default venv's,
    made here the first time (as ``.ci/run`` makes it), so the README's test command works
    on a fresh machine."""
    env = os.environ.get("MESHFIT_BLENDER_PYTHON")
    if env:
        if Path(env).is_file():
            return Path(env)
        pytest.fail(f"MESHFIT_BLENDER_PYTHON={env}: no such interpreter; {HOW_TO}")
    venv = os.environ.get("MESHFIT_BLENDER_VENV")
    python = (Path(venv) if venv else DEFAULT_VENV) / "bin" / "python"
    ok = python.is_file() and subprocess.run([str(python), "-c", "import bpy"]).returncode == 0
    if not ok:
        _make_venv(python.parent.parent)
    return python


def _make_venv(folder: Path) -> None:
    """A virtualenv at ``folder`` with Blender's module (it pins Python 3.11)."""
    base = shutil.which("python3.11") or (
        sys.executable if sys.version_info[:2] == (3, 11) else None
    )
    if base is None:
        pytest.fail(f"no Python 3.11 to make {folder} with; {HOW_TO}")
    steps = [[base, "-m", "venv", str(folder)]]
    steps.append([str(folder / "bin" / "python"), "-m", "pip", "install", "-q", "bpy==4.5.4"])
    for cmd in steps:
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
        if res.returncode != 0:
            pytest.fail(f"{' '.join(cmd)} failed: {res.stderr[-2000:]}; {HOW_TO}")


def run_blender(script: str, *args) -> None:
    """Run one of `SCRIPTS` with Blender's Python; fail with its stderr."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    # -P: the script's folder stays off the path (the package's ``types`` module would
    # shadow the standard library's)
    cmd = [str(blender_python()), "-P", str(SCRIPTS[script]), *map(str, args)]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    if res.returncode != 0:
        tail = (res.stderr or res.stdout)[-3000:]
        if "No module named 'bpy'" in tail:
            pytest.fail(f"{cmd[0]} cannot import bpy; {HOW_TO}")
        pytest.fail(f"{script} failed (exit {res.returncode}):\n{tail}")


def read_png(path: Path) -> np.ndarray:
    """``(h, w, 4) float64`` RGBA in [0, 1]."""
    with open(path, "rb") as fh:
        w, h, rows, _ = png.Reader(file=fh).asRGBA8()
        return np.array([list(r) for r in rows], dtype=np.float64).reshape(h, w, 4) / 255.0


@pytest.fixture(scope="module")
def fit(demo_fit):
    """The quick fit of ``conftest.demo_fit``: six stitched patches with vector maps."""
    return demo_fit


@pytest.fixture(scope="module")
def renders(tmp_path_factory) -> Path:
    out = os.environ.get("MESHFIT_BLENDER_RENDERS")
    if out:
        Path(out).mkdir(parents=True, exist_ok=True)
        return Path(out)
    return tmp_path_factory.mktemp("blender_renders")


def write_layer(folder: Path, fit, maps, **kw) -> Path:
    """The maps as the pipeline writes them (``maps/<stem>_vector.<udim>.exr``) and the
    layer ``scan.usda`` referencing them."""
    (folder / "maps").mkdir(parents=True, exist_ok=True)
    for p, m in enumerate(maps):
        write_exr(m, folder / PATTERN.replace("<UDIM>", str(udim(p))))
    return export_usd(
        folder / "scan.usda",
        fit.surfaces,
        displacements=maps,
        network=fit.network,
        map_pattern=PATTERN,
        **kw,
    )


def to_world(points: np.ndarray, units: str, up_axis: str) -> np.ndarray:
    """Model coordinates as Blender places them: metres, Z up (a Y-up stage is turned by
    +90 degrees about X)."""
    P = np.asarray(points, dtype=np.float64) * unit(units).meters
    if up_axis == "y":
        P = np.stack([P[:, 0], -P[:, 2], P[:, 1]], axis=1)
    return P


def _links(material: dict) -> dict:
    """``(to node, to socket) -> (from node, from socket)`` of a material's node tree."""
    return {(a, b): (c, d) for c, d, a, b in material["links"]}


@pytest.mark.parametrize(("units", "up_axis"), [("mm", "z"), ("in", "y")])
def test_blender_imports_the_mesh_material_and_units(fit, tmp_path, units, up_axis):
    layer = write_layer(tmp_path, fit, fit.maps, units=units, up_axis=up_axis)
    run_blender("inspect_usd.py", layer, tmp_path)
    scene = json.loads((tmp_path / "scene.json").read_text())
    points, faces = _usd_mesh(layer)
    pm = patch_mesh(fit.surfaces, fit.maps, fit.network)  # the same grids, displaced

    (mesh,) = [o for o in scene["objects"] if o["type"] == "MESH"]
    assert mesh["name"] == "mesh"
    assert (
        (mesh["vertices"], mesh["faces"])
        == (len(points), len(faces))
        == (len(pm.vertices), len(pm.faces))
    )
    assert mesh["triangles"] == mesh["faces"]
    assert mesh["uv_maps"] == ["st"]
    assert mesh["modifiers"] == []  # subdivisionScheme none: no subdivision surface
    # the NURBS patches are guides: not imported (the other objects are the Xform, Looks)
    assert all(o["type"] == "EMPTY" for o in scene["objects"] if o is not mesh)
    assert not any(o["name"].startswith("patch_") for o in scene["objects"])

    # the material: the UDIM tiles, raw, on st, into a Displacement node, into the output
    (material,) = [m for m in scene["materials"] if m["name"] in mesh["materials"]]
    nodes = {n["name"]: n for n in material["nodes"]}
    links = _links(material)
    disp_node, _ = links[("Material Output", "Displacement")]
    assert nodes[disp_node]["type"] == "DISPLACEMENT"
    assert (nodes[disp_node]["Midlevel"], nodes[disp_node]["Scale"]) == (0.0, 1.0)
    split, channel = links[(disp_node, "Height")]
    assert (nodes[split]["type"], channel) == ("SEPARATE_COLOR", "Green")  # N of T, N, B
    image, _ = links[(split, "Color")]
    tex = nodes[image]
    assert tex["type"] == "TEX_IMAGE" and tex["source"] == "TILED"
    assert tex["tiles"] == [udim(p) for p in range(len(fit.surfaces))]
    assert Path(tex["file"]) == tmp_path / "maps" / "scan_vector.<UDIM>.exr"
    assert tex["colorspace"] == "Non-Color"
    uv_node, _ = links[(image, "Vector")]
    assert nodes[uv_node]["uv_map"] == "st"

    # size and orientation: every vertex where metersPerUnit and upAxis put it
    want = to_world(points, units, up_axis)
    got = np.load(tmp_path / "world.npy")
    size = np.ptp(points, axis=0) * unit(units).meters
    assert_allclose(got, want, rtol=0, atol=1e-6 * size.max())
    assert_allclose(mesh["dimensions"], size, rtol=1e-5)  # object axes: before the turn

    # the faces keep their corners and winding, and Blender's tangent space on st is the
    # maps' frame (T, B, N) up to the tessellation: what the vector wiring (the image's
    # T, N, B straight into a tangent-space Vector Displacement node) relies on
    loops = np.load(tmp_path / "loops.npz")
    np.testing.assert_array_equal(loops["vertex"], faces.ravel())
    T, B, N = _corner_frames(fit.surfaces, pm)
    for name, want_dir in (("tangent", T), ("bitangent", B), ("normal", N)):
        cos = (loops[name] * want_dir).sum(axis=1)
        assert np.median(cos) > 0.999 and cos.min() > 0.9, name


def _usd_mesh(layer: Path) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(n, 3)`` and triangles ``(m, 3)`` of the layer's mesh, as USD reads them."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(layer))
    mesh = UsdGeom.Mesh(stage.GetDefaultPrim().GetChild("mesh"))
    points = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    faces = np.array(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64).reshape(-1, 3)
    return points, faces


def _corner_frames(surfaces, pm):
    """The maps' frame ``(T, B, N)``, each ``(3 m, 3)``, at every face corner, in model
    coordinates (each corner on its own patch)."""
    offs = np.concatenate([[0], np.cumsum([h * w for h, w in pm.shapes])])
    node = pm.face_uv.ravel()
    patch = np.repeat(pm.face_patch, 3)
    T, B, N = (np.zeros((node.size, 3)) for _ in range(3))
    for p, s in enumerate(surfaces):
        sel = patch == p
        h, w = pm.shapes[p]
        i, j = np.divmod(node[sel] - offs[p], w)
        T[sel], B[sel], N[sel] = s.frames(i / (h - 1), j / (w - 1))
    return T, B, N


def _quadrant_maps(fit, amplitude: float, patches) -> list[DisplacementMap]:
    """Vector maps displacing along N by a smooth bump on the quadrant u > 1/2, v < 1/2 of
    ``patches`` (zero on its border), zero elsewhere: where the bump shows tells whether
    the image is read the right way round."""
    out = []
    for p, m in enumerate(fit.maps):
        h, w = m.shape
        u = np.linspace(0, 1, h)[:, None]
        v = np.linspace(0, 1, w)[None, :]
        bump = (u > 0.5) * (v < 0.5) * np.sin(2 * np.pi * u) ** 2 * np.sin(2 * np.pi * v) ** 2
        values = np.zeros((h, w, 3))
        values[:, :, 2] = amplitude * bump * (p in patches)
        out.append(DisplacementMap(values, "vector"))
    return out


def test_blender_renders_the_displacement_where_the_map_is(fit, tmp_path, renders):
    renders = renders / "displacement"
    renders.mkdir(exist_ok=True)
    view = np.asarray(VIEW) / np.linalg.norm(VIEW)
    facing = [-float(s.normals(0.5, 0.5) @ view) for s in fit.surfaces]  # Z up, mm
    front = int(np.argmax(facing))
    shown = {p for p in range(len(fit.surfaces)) if p % 2 == front % 2}
    diag = float(np.linalg.norm(np.ptp(fit.mesh.vertices, axis=0)))
    layer = write_layer(tmp_path, fit, _quadrant_maps(fit, 0.08 * diag, shown))
    # in the bump's quadrant, and in the three others of the patch facing the camera
    corners = [(0.75, 0.25), (0.25, 0.75), (0.75, 0.75), (0.25, 0.25)]
    probes = [fit.surfaces[front].evaluate(u, v).tolist() for u, v in corners]
    spec = {
        "out": str(renders),
        "size": SIZE,
        "samples": SAMPLES,
        "view": list(VIEW),
        "subdivision": 1,
        "probes": probes,
        "renders": [
            ["displaced", str(layer), "displaced"],
            ["plain", str(layer), "plain"],
            ["mask", str(layer), "mask"],
        ],
    }
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    run_blender("render_usd.py", tmp_path / "spec.json")

    on, off, mask = (read_png(renders / f"{n}.png") for n in ("displaced", "plain", "mask"))
    pixels = json.loads((renders / "render.json").read_text())["probes"]
    lit = mask[:, :, 0] > 0.5  # where the texture lookup finds a non-zero map
    assert lit.any() and not lit.all()
    inside, *outside = (lit[int(r), int(c)] for c, r in pixels)
    assert inside and not any(outside)  # the image is read the right way round
    # displacement changes the image on the map's non-zero region and round it (its
    # shadow, a few pixels; and where the bumps stand out over the background); over the
    # rest of the surface the two renders agree
    near = lit.copy()
    for _ in range(3):
        near[1:] |= near[:-1]
        near[:-1] |= near[1:]
        near[:, 1:] |= near[:, :-1]
        near[:, :-1] |= near[:, 1:]
    diff = np.abs(on - off).max(axis=2)
    rest = ~near & (off[:, :, 3] == 1.0)
    assert (diff[lit] > 0.05).mean() > 0.3
    assert (diff[rest] > 0.05).mean() < 0.002
    assert diff[rest].mean() < 0.002


def test_blender_vector_displacement_wired_as_documented(fit, tmp_path, renders):
    """The fit's own vector maps, their image straight into a tangent-space Vector
    Displacement node as ``export_usd`` documents, render as the displaced surface itself."""
    renders = renders / "vector_displacement"
    renders.mkdir(exist_ok=True)
    layer = write_layer(tmp_path, fit, fit.maps)
    # the reference: the displaced mesh (S + d at the texels), no displacement material
    reference = _mesh_layer(
        tmp_path / "reference.usda", patch_mesh(fit.surfaces, fit.maps, fit.network)
    )
    spec = {
        "out": str(renders),
        "size": SIZE,
        "samples": SAMPLES,
        "view": list(VIEW),
        "subdivision": 0,
        "probes": [],
        "renders": [
            ["vector", str(layer), "vector"],
            ["reference", str(reference), "plain"],
            ["spline", str(layer), "plain"],
        ],
    }
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    run_blender("render_usd.py", tmp_path / "spec.json")
    vector, ref, spline = (
        read_png(renders / f"{n}.png") for n in ("vector", "reference", "spline")
    )
    off_by = np.abs(vector - ref).max(axis=2).mean()
    undisplaced = np.abs(spline - ref).max(axis=2).mean()
    assert off_by < 0.4 * undisplaced, (off_by, undisplaced)


def _mesh_layer(path: Path, pm) -> Path:
    """A bare USD mesh of ``pm`` (millimetres, Z up) without material."""
    from pxr import Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, unit("mm").meters)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/reference").GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/reference/mesh")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pm.vertices.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(pm.faces), 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(pm.faces.ravel().astype(np.int32)))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    stage.GetRootLayer().Save()
    return path


def _report_fit(out: Path, resume: bool = False):
    """A quick fit with the report into ``out``: a box layout on the demo input, the USD
    stage the only format, small images."""
    mesh = demo_mesh(4000)
    options = FitOptions(controls=(6, 6), spring_level=1, formats=("usd",), image_size=96)
    return meshfit.fit(mesh, cube_layout(mesh, n=1), options=options, out=out, resume=resume)


BLENDER_PNGS = ["report/blender_displaced.png", "report/blender_plain.png"]


def test_the_report_shows_blender_renders_of_the_usd(tmp_path, monkeypatch, renders):
    monkeypatch.setenv(BLENDER_PYTHON_ENV, str(blender_python()))
    out = tmp_path / "fit"
    result = _report_fit(out)
    layer = next(f for f in result.summary["outputs"]["usd"] if f.endswith((".usda", ".usdc")))
    page = (out / "report.html").read_text()
    srcs = re.findall(r"src='([^']+)'", page)
    assert [s for s in srcs if "blender" in s] == BLENDER_PNGS
    assert f"Blender (Cycles) render of {layer}: displacement on" in page
    assert f"Blender (Cycles) render of {layer}: displacement off" in page
    assert not [n for n in result.summary["notes"] if "Blender" in n]
    assert all(f in read_manifest(out) for f in BLENDER_PNGS)

    on, off = (read_png(out / f) for f in BLENDER_PNGS)
    assert on.shape == off.shape == (96, 96, 4)  # the report's size (below the cap)
    for img in (on, off):  # the model, framed: neither empty nor filling the image
        assert 0.1 < (img[:, :, 3] > 0.5).mean() < 0.9
    # the maps move the surface: the shading differs over much of the model
    model = (on[:, :, 3] == 1.0) & (off[:, :, 3] == 1.0)
    diff = np.abs(on - off)[model].max(axis=1)
    assert (diff > 0.05).mean() > 0.05, (diff > 0.05).mean()  # identical geometry: 0
    for f in BLENDER_PNGS:
        (renders / "report").mkdir(exist_ok=True)
        (renders / "report" / Path(f).name).write_bytes((out / f).read_bytes())

    # a resumed run keeps the report stage and its Blender renders
    stamp = [(out / f).stat().st_mtime_ns for f in BLENDER_PNGS]
    again = _report_fit(out, resume=True)
    assert again.summary["stages"]["report"]["cached"]
    assert [(out / f).stat().st_mtime_ns for f in BLENDER_PNGS] == stamp
    assert [s for s in re.findall(r"src='([^']+)'", (out / "report.html").read_text())
            if "blender" in s] == BLENDER_PNGS  # fmt: skip
    assert all(f in read_manifest(out) for f in BLENDER_PNGS)


def test_a_failed_blender_render_is_a_note_not_a_failed_fit(tmp_path, monkeypatch):
    monkeypatch.setenv(BLENDER_PYTHON_ENV, sys.executable)  # no bpy there
    out = tmp_path / "fit"
    result = _report_fit(out)
    (note,) = [n for n in result.summary["notes"] if "Blender" in n]
    assert "Blender render" in note and "failed" in note and "bpy" in note
    page = (out / "report.html").read_text()
    assert "blender_" not in page and "Blender (Cycles)" not in page
    assert not list((out / "report").glob("blender_*"))
    assert (out / "report" / "displaced.png").is_file()  # the rest of the report is there
    # a resumed run keeps the report stage, and says again why it has no Blender render
    again = _report_fit(out, resume=True)
    assert again.summary["stages"]["report"]["cached"]
    assert [n for n in again.summary["notes"] if "Blender" in n] == [note]
