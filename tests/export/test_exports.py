from pathlib import Path

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose

from meshfit.bspline import BSplineSurface, fit_bspline, grid_parameters
from meshfit.displacement import DisplacementMap, displacement_map, reconstruct
from meshfit.errors import ExportError, InputError
from meshfit.export import (
    export_3dm,
    export_gltf,
    export_iges,
    export_obj,
    export_step,
    export_usd,
    rhino_knots,
    step_available,
    tessellate,
)
from tests.bspline.grids import random_surface, scan_grid
from tests.export.iges_reader import entity_128_surface, read_entities, read_global, read_sections


@pytest.fixture(scope="module")
def network():
    """Three patches: two fitted to a scan grid (one with a map), one exact random spline."""
    X = scan_grid("igea")
    left, right = X[:31], X[30:]
    s0 = fit_bspline(left, controls=(8, 7))
    s1 = fit_bspline(right, controls=(6, 9))
    s2 = random_surface(np.random.default_rng(5), 5, 4)
    d0 = displacement_map(s0, left)
    return [s0, s1, s2], [d0, None, None], left


def _uv(n=40):
    rng = np.random.default_rng(1)
    return rng.uniform(0, 1, n), rng.uniform(0, 1, n)


def test_iges_round_trip(network, tmp_path):
    surfaces, _, _ = network
    path = export_iges(tmp_path / "net.igs", surfaces, names=["left", "right", "extra"])
    sec = read_sections(path)
    g = read_global(sec)
    assert g[0] == "1H," and g[1] == "1H;" and g[22] == "11"  # IGES 5.3
    ents = read_entities(path)
    assert [e["type"] for e in ents] == [128, 128, 128]
    assert [e["label"] for e in ents] == ["left", "right", "extra"]
    u, v = _uv()
    for e, s in zip(ents, surfaces, strict=True):
        r = entity_128_surface(e["params"])
        np.testing.assert_array_equal(r.control_points, s.control_points)
        np.testing.assert_array_equal(r.knots_u, s.knots_u)
        assert_allclose(r.evaluate(u, v), s.evaluate(u, v), rtol=0, atol=1e-15)


def _xyz(p):
    return [p.X, p.Y, p.Z]


def test_3dm_round_trip(network, tmp_path):
    import rhino3dm

    surfaces, _, _ = network
    path = export_3dm(tmp_path / "net.3dm", surfaces)
    model = rhino3dm.File3dm.Read(str(path))
    assert len(model.Objects) == len(surfaces)
    u, v = _uv(15)
    for obj, s in zip(model.Objects, surfaces, strict=True):
        g = obj.Geometry
        assert isinstance(g, rhino3dm.NurbsSurface)
        mu, mv = s.shape
        assert (g.Points.CountU, g.Points.CountV, g.OrderU, g.OrderV) == (mu, mv, 4, 4)
        assert list(g.KnotsU.ToList()) == rhino_knots(s.knots_u)
        assert len(g.KnotsU.ToList()) == mu + 2  # openNURBS drops one knot at each end
        cp = np.array(
            [[_xyz(g.Points.GetControlPoint(i, j)) for j in range(mv)] for i in range(mu)]
        )
        np.testing.assert_array_equal(cp, s.control_points)
        got = np.array(
            [[p.X, p.Y, p.Z] for p in (g.PointAt(a, b) for a, b in zip(u, v, strict=True))]
        )
        assert_allclose(got, s.evaluate(u, v), rtol=0, atol=1e-12)


@pytest.mark.parametrize("displaced", [True, False])
def test_obj_round_trip(network, tmp_path, displaced):
    surfaces, disps, left = network
    path = export_obj(
        tmp_path / "net.obj", surfaces, displacements=disps if displaced else None, shape=(21, 17)
    )
    m = trimesh.load(path, process=False, maintain_order=True)
    want = [
        tessellate(s, d if displaced else None, shape=(21, 17))
        for s, d in zip(surfaces, disps, strict=True)
    ]
    V = np.concatenate([w[0] for w in want])
    F = np.concatenate([w[1] + 21 * 17 * k for k, w in enumerate(want)])
    np.testing.assert_array_equal(m.vertices, V)
    np.testing.assert_array_equal(m.faces, F)
    first = m.vertices[: 21 * 17].reshape(21, 17, 3)
    if displaced:  # at other resolutions: spline + bilinear map
        assert_allclose(first, reconstruct(surfaces[0], disps[0], shape=(21, 17)), atol=0)
        corners = first[[0, -1]][:, [0, -1]]
        assert_allclose(corners, left[[0, -1]][:, [0, -1]], atol=1e-15)
    else:
        assert_allclose(first, surfaces[0].evaluate_grid(grid_parameters(21), grid_parameters(17)))
    # outward orientation: the first triangle of each cell turns like S_u x S_v
    n_tri = m.face_normals[: 20 * 16].reshape(20, 16, 3)
    cu, cv = (np.arange(20) + 0.5) / 20, (np.arange(16) + 0.5) / 16
    U, V = np.meshgrid(cu, cv, indexing="ij")
    assert ((n_tri * surfaces[0].normals(U, V)).sum(-1) > 0).all()


def test_obj_at_map_resolution_is_the_grid(network, tmp_path):
    surfaces, disps, left = network
    path = export_obj(tmp_path / "one.obj", surfaces[0], displacements=disps[0])
    m = trimesh.load(path, process=False, maintain_order=True)
    assert_allclose(m.vertices.reshape(left.shape), left, rtol=0, atol=1e-15 * 8)


def test_obj_with_a_vertex_grid_per_patch(network, tmp_path):
    surfaces, _, _ = network
    shapes = [(9, 7), (5, 11), (6, 6)]
    path = export_obj(tmp_path / "per.obj", surfaces, shape=shapes)
    m = trimesh.load(path, process=False, maintain_order=True)
    V = np.concatenate(
        [tessellate(s, None, shape=sh)[0] for s, sh in zip(surfaces, shapes, strict=True)]
    )
    np.testing.assert_array_equal(m.vertices, V)
    with pytest.raises(InputError, match="2 shapes for 3 patches"):
        export_obj(tmp_path / "bad.obj", surfaces, shape=shapes[:2])


def test_objs_share_their_topology_text(network, tmp_path):
    from meshfit.export import export_objs

    surfaces, disps, _ = network
    shapes = [disps[0].shape, (5, 11), (6, 6)]
    both = export_objs(
        {tmp_path / "d.obj": disps, tmp_path / "s.obj": None}, surfaces, shape=shapes
    )
    assert [p.name for p in both] == ["d.obj", "s.obj"]
    one_d = export_obj(tmp_path / "d1.obj", surfaces, displacements=disps, shape=shapes)
    one_s = export_obj(tmp_path / "s1.obj", surfaces, shape=shapes)
    assert both[0].read_bytes() == one_d.read_bytes()
    assert both[0].read_bytes() != both[1].read_bytes()
    # the spline-only file takes the displaced file's texture coordinates (on the map's
    # texel centres), and is otherwise the file export_obj writes
    d, s, s1 = (p.read_text().splitlines() for p in (*both, one_s))
    assert [x for x in s if x.startswith("vt ")] == [x for x in d if x.startswith("vt ")]
    assert [x for x in s if not x.startswith("vt ")] == [x for x in s1 if not x.startswith("vt ")]
    assert [x for x in s if x.startswith("vt ")] != [x for x in s1 if x.startswith("vt ")]


@pytest.mark.parametrize("rows", [1, 7])
def test_objs_written_in_chunks_are_the_same_bytes(network, tmp_path, monkeypatch, rows):
    """The files are written `ROWS` lines at a time, the second one's shared lines copied
    from the first: any chunk size gives the same bytes."""
    from meshfit.export import export_objs
    from meshfit.export import mesh as obj

    surfaces, disps, _ = network
    shapes = [disps[0].shape, (5, 11), (6, 6)]
    mats = ["m0.png", "m1.png", "m2.png"]

    def write(folder):
        folder.mkdir()
        outs = {folder / "d.obj": disps, folder / "s.obj": None}
        return [p.read_bytes() for p in export_objs(outs, surfaces, shape=shapes, materials=mats)]

    whole = write(tmp_path / "whole")
    monkeypatch.setattr(obj, "ROWS", rows)
    assert write(tmp_path / "chunks") == whole
    assert b"usemtl patch_0" in whole[1] and b"usemtl" not in whole[0]


def test_gltf_round_trip(network, tmp_path):
    surfaces, disps, _ = network
    path = export_gltf(tmp_path / "net.glb", surfaces, displacements=disps, shape=(12, 10))
    scene = trimesh.load(path, process=False)
    assert sorted(scene.geometry) == ["patch_0", "patch_1", "patch_2"]
    for k, (s, d) in enumerate(zip(surfaces, disps, strict=True)):
        g = scene.geometry[f"patch_{k}"]
        V, F, _ = tessellate(s, d, shape=(12, 10))
        assert_allclose(g.vertices, V, rtol=2.0**-23, atol=1e-7 * np.abs(V).max())
        np.testing.assert_array_equal(g.faces, F)


def test_export_rejects_bad_input(network, tmp_path):
    surfaces, disps, _ = network
    with pytest.raises(InputError, match="names"):
        export_obj(tmp_path / "a.obj", surfaces, names=["a", "a", "b"])
    with pytest.raises(InputError, match="2 displacement maps"):
        export_obj(tmp_path / "a.obj", surfaces, displacements=disps[:2])
    with pytest.raises(InputError, match=r"\.usda"):
        export_usd(tmp_path / "a.txt", surfaces)
    with pytest.raises(InputError, match="units"):
        export_iges(tmp_path / "a.igs", surfaces, units="furlong")
    with pytest.raises(InputError, match="BSplineSurface"):
        export_3dm(tmp_path / "a.3dm", [np.zeros((4, 4, 3))])
    bump = DisplacementMap(np.dstack([np.zeros((4, 4, 2)), np.ones((4, 4))]), "bump")
    with pytest.raises(InputError, match="bump"):
        export_obj(tmp_path / "a.obj", surfaces[0], displacements=bump)
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind


def test_step_needs_the_cad_extra(network, tmp_path, monkeypatch):
    import meshfit.export.step as step

    monkeypatch.setattr(step, "step_available", lambda: False)
    with pytest.raises(ExportError, match=r"meshfit\[cad\]"):
        export_step(tmp_path / "a.step", network[0])
    assert not list(tmp_path.iterdir())


needs_ocp = pytest.mark.skipif(not step_available(), reason="needs meshfit[cad] (cadquery-ocp)")


def _read_back(face) -> BSplineSurface:
    return BSplineSurface(face.control_points, face.knots_u, face.knots_v)


@needs_ocp
def test_step_round_trip(network, tmp_path):
    from tests.export.step_reader import read_step

    surfaces, _, _ = network
    path = export_step(tmp_path / "net.step", surfaces, names=["left", "right", "extra"])
    faces, topo = read_step(path)
    by_name = {f.name: f for f in faces}
    assert sorted(by_name) == ["extra", "left", "right"]
    u, v = _uv()
    for name, s in zip(["left", "right", "extra"], surfaces, strict=True):
        f = by_name[name]
        assert f.degree == (3, 3) and not f.rational
        scale = np.abs(s.control_points).max()
        # OpenCASCADE writes 12 significant digits
        assert_allclose(f.control_points, s.control_points, rtol=0, atol=1e-11 * scale)
        assert_allclose(f.knots_u, s.knots_u, rtol=0, atol=1e-12)
        assert_allclose(f.knots_v, s.knots_v, rtol=0, atol=1e-12)
        assert_allclose(_read_back(f).evaluate(u, v), s.evaluate(u, v), rtol=0, atol=1e-11 * scale)
    # the three patches do not share boundaries: three separate shells
    assert topo["shells"] == 3 and topo["closed_shells"] == 0


@needs_ocp
def test_step_sews_a_stitched_network(tmp_path):
    from meshfit.stitch import control_classes, network_from_grids, stitch_surfaces
    from tests.export.step_reader import read_step
    from tests.stitch.networks import cube_sphere

    grids = cube_sphere(33)
    net = network_from_grids(grids)
    cc = control_classes(net, default=8, grid_shapes=[g.shape[:2] for g in grids])
    fitted = [fit_bspline(g, controls=c) for g, c in zip(grids, cc.controls, strict=True)]
    stitched = stitch_surfaces(fitted, net)
    names = [f"face_{k}" for k in range(6)]

    faces, topo = read_step(export_step(tmp_path / "closed.step", stitched, names=names))
    assert topo == {"shells": 1, "closed_shells": 1, "free_edges": 0}  # a closed shell
    assert sorted(f.name for f in faces) == names
    for f in faces:
        s = stitched[names.index(f.name)]
        assert_allclose(f.control_points, s.control_points, rtol=0, atol=1e-11 * 2)

    # independent fits leave gaps along the 12 shared boundaries: nothing is sewn
    _, topo = read_step(export_step(tmp_path / "gaps.step", fitted, names=names))
    assert topo == {"shells": 6, "closed_shells": 0, "free_edges": 24}
    # and sew=False keeps a stitched network's faces apart
    _, topo = read_step(export_step(tmp_path / "loose.step", stitched, sew=False))
    assert topo == {"shells": 6, "closed_shells": 0, "free_edges": 24}


@needs_ocp
@pytest.mark.parametrize(
    ("units", "declared"),
    [
        ("mm", "SI_UNIT(.MILLI.,.METRE.)"),
        ("CM", "SI_UNIT(.CENTI.,.METRE.)"),
        ("M", "SI_UNIT($,.METRE.)"),
        ("in", "'INCH'"),
        ("ft", "'FOOT'"),
    ],
)
def test_step_units(network, tmp_path, units, declared):
    from meshfit.export.units import unit
    from tests.export.step_reader import read_step

    s = network[0][2]
    path = export_step(tmp_path / "u.stp", s, units=units)
    assert declared in path.read_text().replace(" ", "")
    # the unit is declared, the coordinates are not rescaled
    (face,), _ = read_step(path, unit(units).meters)
    scale = np.abs(s.control_points).max()
    assert_allclose(face.control_points, s.control_points, rtol=0, atol=1e-11 * scale)


def test_step_rejects_bad_input(network, tmp_path):
    with pytest.raises(InputError, match="units"):
        export_step(tmp_path / "a.step", network[0], units="furlong")
    with pytest.raises(InputError, match="units"):
        export_step(tmp_path / "a.step", network[0], units="KM")
    with pytest.raises(InputError, match=r"\.step or \.stp"):
        export_step(tmp_path / "a.igs", network[0])
    with pytest.raises(InputError, match="names"):
        export_step(tmp_path / "a.step", network[0], names=["a", "a", "b"])
    assert not list(tmp_path.iterdir())


@needs_ocp
def test_occ_surface_conversion_is_exact(network):
    from meshfit.export.step import step_surface, surface_from_occ

    for s in network[0]:
        back = surface_from_occ(step_surface(s))
        np.testing.assert_array_equal(back.control_points, s.control_points)
        np.testing.assert_array_equal(back.knots_u, s.knots_u)
        np.testing.assert_array_equal(back.knots_v, s.knots_v)
    occ = step_surface(network[0][2])
    occ.IncreaseDegree(4, 3)
    with pytest.raises(InputError, match="bicubic"):
        surface_from_occ(occ)


@needs_ocp
def test_step_first_export_of_a_process_keeps_names_and_units(tmp_path):
    """OpenCASCADE resets its static parameters when the first writer is built."""
    import subprocess
    import sys

    code = (
        "import numpy as np, sys\n"
        "from meshfit.export import export_step\n"
        "from tests.bspline.grids import random_surface\n"
        "s = random_surface(np.random.default_rng(5), 5, 4)\n"
        "export_step(sys.argv[1], [s], names=['first'], units='M')\n"
    )
    path = tmp_path / "fresh.step"
    root = Path(__file__).resolve().parents[2]
    subprocess.run([sys.executable, "-c", code, str(path)], check=True, cwd=root)
    text = path.read_text()
    assert "'first'" in text and "SI_UNIT($,.METRE.)" in text
