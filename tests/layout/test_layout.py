"""Layouts: the JSON file format and its validation, and patch extraction on the test layouts
of igea, nefertiti and spot and on analytic planes and cylinders."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit import tol
from meshfit.errors import InputError, LayoutError, MeshfitError
from meshfit.layout import (
    Layout,
    Patch,
    check_layout_topology,
    extract_patches,
    layout_from_curves,
    layout_from_json,
    layout_to_json,
    load_layout,
    mesh_fingerprint,
    save_layout,
)
from meshfit.layout.cube import FeatureCurves, cube_layout
from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints

from .. import shapes
from ..conftest import CLOSED_REAL, real_mesh

ROOT = Path(__file__).resolve().parents[2]
LAYOUTS = ROOT / "examples" / "layouts"


@cache
def real_layout(name: str) -> Layout:
    return load_layout(LAYOUTS / f"{name}.json", real_mesh(name), check_topology=False)


@cache
def real_patches(name: str):
    return extract_patches(real_mesh(name), real_layout(name))


@cache
def sphere() -> Mesh:
    return shapes.icosphere(3)


@cache
def sphere_layout() -> Layout:
    return cube_layout(sphere(), frame=np.eye(3), features=FeatureCurves(0))


# ------------------------------------------------------------------------- helpers
def _patch_list(layout: Layout) -> list[list[tuple[int, bool]]]:
    return [layout.patch_sides(p) for p in range(layout.n_patches)]


def _rebuild(mesh, layout, *, curves=None, patches=None, corners=None, features=None):
    return layout_from_curves(
        mesh,
        layout.corners if corners is None else corners,
        list(layout.curves) if curves is None else curves,
        layout.curve_ends,
        _patch_list(layout) if patches is None else patches,
        [list(f) for f in layout.features] if features is None else features,
    )


def _assert_patch_is_disk_with_four_sides(patch):
    m = patch.mesh
    assert m.n_components == 1
    assert m.euler_characteristic == 1
    loops = m.boundary_loops
    assert len(loops) == 1
    loop = loops[0]
    b = patch.boundary
    assert b.size == loop.size
    k = int(np.flatnonzero(loop == b[0])[0])
    assert np.array_equal(np.roll(loop, -k), b)  # the sides follow the boundary half-edges
    # each side edge is a half-edge of a patch face: the patch lies on the left of each side
    tails, heads = m.faces.reshape(-1).tolist(), np.roll(m.faces, -1, 1).reshape(-1).tolist()
    half = set(zip(tails, heads, strict=True))
    for side in patch.sides:
        assert side.size >= 2
        for a, c in zip(side[:-1].tolist(), side[1:].tolist(), strict=True):
            assert (a, c) in half


def _distance_to_polyline(x, pts):
    a, b = pts[:-1], pts[1:]
    e = b - a
    t = np.clip(np.einsum("ij,ij->i", x - a, e) / np.einsum("ij,ij->i", e, e), 0, 1)
    return float(np.min(np.linalg.norm(a + t[:, None] * e - x, axis=1)))


# ------------------------------------------------------------------------- file format
@pytest.mark.parametrize("name", CLOSED_REAL)
def test_real_layout_round_trips(name, tmp_path):
    mesh = real_mesh(name)
    layout = real_layout(name)
    path = save_layout(layout, tmp_path / "out.json", mesh=mesh)
    again = load_layout(path, mesh, check_topology=False)
    assert again == layout
    assert path.read_text() == (LAYOUTS / f"{name}.json").read_text()
    assert path.stat().st_size < 5_000_000
    assert not list(tmp_path.glob(".*.tmp"))  # the temporary file was renamed


def test_patch_sides_rebuild_the_layout():
    layout = sphere_layout()
    sides = layout.patch_sides(3)
    assert [c for c, _ in sides] == layout.patch_curves[3].tolist()
    assert [r for _, r in sides] == layout.patch_reversed[3].tolist()
    assert all(type(c) is int and type(r) is bool for c, r in sides)
    # side s runs from corner s to corner s + 1
    ends = [layout.curve_ends[c][::-1] if r else layout.curve_ends[c] for c, r in sides]
    assert [int(e[0]) for e in ends] == layout.patch_corners(3).tolist()
    assert [int(e[1]) for e in ends] == np.roll(layout.patch_corners(3), -1).tolist()
    again = _rebuild(sphere(), layout)
    assert (again.patch_curves == layout.patch_curves).all()
    assert (again.patch_reversed == layout.patch_reversed).all()


def test_analytic_layout_round_trips_bit_exactly(tmp_path):
    layout = sphere_layout()
    path = save_layout(layout, tmp_path / "sphere.json")
    again = load_layout(path, sphere())
    assert again == layout
    assert len(again.features[0]) == 4


def test_real_layouts_have_at_least_12_patches_and_igea_features():
    for name in CLOSED_REAL:
        assert real_layout(name).n_patches >= 12
    feats = real_layout("igea").features[0]
    assert len(feats) == 4


# ------------------------------------------------------------------------- extraction
@pytest.mark.parametrize("name", CLOSED_REAL)
def test_real_layout_patches_are_disks_covering_the_mesh(name):
    mesh = real_mesh(name)
    layout = real_layout(name)
    patches = real_patches(name)
    assert [p.index for p in patches] == list(range(layout.n_patches))
    for p in patches:
        _assert_patch_is_disk_with_four_sides(p)
        assert_allclose(
            mesh.xyz(p.vertex_source), p.mesh.vertices, atol=tol.TEST_ATOL * mesh.bbox_diagonal
        )
        assert p.face_parent.min() >= 0 and p.face_parent.max() < mesh.n_faces
    area = sum(p.mesh.area for p in patches)
    assert_allclose(area, mesh.area, rtol=tol.LAYOUT_AREA_RTOL)
    # every original face is covered by patch faces of total area equal to its own
    per_face = np.zeros(mesh.n_faces)
    for p in patches:
        np.add.at(per_face, p.face_parent, p.mesh.face_areas)
    assert_allclose(per_face, mesh.face_areas, rtol=1e-6, atol=1e-12 * mesh.bbox_diagonal**2)


@pytest.mark.parametrize("name", CLOSED_REAL)
def test_shared_corners_and_sides_coincide(name):
    mesh = real_mesh(name)
    layout = real_layout(name)
    patches = real_patches(name)
    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    corner_xyz = mesh.xyz(layout.corners)
    for p in patches:
        ids = layout.patch_corners(p.index)
        assert_allclose(p.mesh.vertices[p.corners], corner_xyz[ids], atol=atol)
    # a curve's two sides (one per neighbouring patch) are the same polyline, reversed
    sides: dict[int, list] = {}
    for p in patches:
        for s in range(4):
            c = int(layout.patch_curves[p.index, s])
            pts = p.mesh.vertices[p.sides[s]]
            sides.setdefault(c, []).append(pts[::-1] if layout.patch_reversed[p.index, s] else pts)
    for c, pair in sides.items():
        assert len(pair) == 2, f"curve {c} bounds {len(pair)} patches"
        assert pair[0].shape == pair[1].shape
        assert_allclose(pair[0], pair[1], atol=atol)


def test_feature_curves_end_on_their_sides():
    mesh = real_mesh("igea")
    patch = real_patches("igea")[0]
    assert len(patch.features) == 4
    assert sorted(patch.feature_sides) == [(0, 2), (0, 2), (3, 1), (3, 1)]
    near = tol.FEATURE_END_ON_SIDE * patch.mesh.mean_edge_length
    for f, (a, b) in zip(patch.features, patch.feature_sides, strict=True):
        x = patch.mesh.xyz(f.points)
        assert _distance_to_polyline(x[0], patch.mesh.vertices[patch.sides[a]]) <= near
        assert _distance_to_polyline(x[-1], patch.mesh.vertices[patch.sides[b]]) <= near
        assert f.kind == "feature"
    # the mapped points are the painted points
    layout = real_layout("igea")
    for f, g in zip(patch.features, layout.features[0], strict=True):
        assert_allclose(
            patch.mesh.xyz(f.points)[1:-1],
            mesh.xyz(g.points)[1:-1],
            atol=1e-9 * mesh.bbox_diagonal,
        )


def _plane_points(mesh: Mesh, xy) -> SurfacePoints:
    xyz = np.concatenate([np.asarray(xy, float), np.zeros((len(xy), 1))], axis=1)
    return mesh.closest_points(xyz).points


def _segment(mesh: Mesh, a, b, step: float) -> SurfacePoints:
    n = max(2, int(np.ceil(np.linalg.norm(np.subtract(b, a)) / step)) + 1)
    t = np.linspace(0, 1, n)[:, None]
    return _plane_points(mesh, (1 - t) * np.asarray(a) + t * np.asarray(b))


def plane_grid_layout(k: int = 3):
    mesh = shapes.plane(20)
    g = np.linspace(0, 1, k + 1)
    cid = {(i, j): i * (k + 1) + j for i in range(k + 1) for j in range(k + 1)}
    corners = _plane_points(mesh, [(g[i], g[j]) for i in range(k + 1) for j in range(k + 1)])
    curves, ends, edge = [], [], {}
    step = 0.25 * mesh.mean_edge_length
    for (i, j), c in cid.items():
        for di, dj in ((1, 0), (0, 1)):
            if (i + di, j + dj) in cid:
                d = cid[(i + di, j + dj)]
                edge[(c, d)] = len(curves)
                curves.append(_segment(mesh, (g[i], g[j]), (g[i + di], g[j + dj]), step))
                ends.append((c, d))
    patches = []
    for i in range(k):
        for j in range(k):
            loop = [cid[(i, j)], cid[(i + 1, j)], cid[(i + 1, j + 1)], cid[(i, j + 1)]]
            sides = []
            for s in range(4):
                a, b = loop[s], loop[(s + 1) % 4]
                sides.append((edge[(a, b)], False) if (a, b) in edge else (edge[(b, a)], True))
            patches.append(sides)
    return mesh, layout_from_curves(mesh, corners, curves, ends, patches)


def test_plane_3x3_grid_gives_nine_exact_squares():
    mesh, layout = plane_grid_layout(3)
    patches = extract_patches(mesh, layout)
    assert len(patches) == 9
    # the network cut joins points on faces sharing only a vertex across the fan of faces
    # around it, so straight curves stay straight
    eps = 1e-12
    for p in patches:
        _assert_patch_is_disk_with_four_sides(p)
        assert_allclose(p.mesh.area, 1 / 9, rtol=1e-12)
        c = p.mesh.vertices[p.corners]
        assert_allclose(c[1] - c[0], [1 / 3, 0, 0], atol=1e-12)  # side 0 along +x
        assert_allclose(c[3] - c[0], [0, 1 / 3, 0], atol=1e-12)  # side 3 back along -y
        assert_allclose(p.taper, 1.0, rtol=1e-12)  # opposite sides of equal length
        for s in range(4):  # every side is a straight segment
            x = p.mesh.vertices[p.sides[s]]
            e = (x[-1] - x[0]) / np.linalg.norm(x[-1] - x[0])
            assert np.abs(np.cross(x - x[0], e)).max() <= eps
    assert_allclose(sum(p.mesh.area for p in patches), 1.0, rtol=1e-12)


def test_cylinder_splits_into_four_patches_around():
    mesh = shapes.cylinder()  # 32 around, 16 along, radius 1, height 2
    idx = np.arange(32 * 17).reshape(32, 17)
    cols = [0, 8, 16, 24]
    corner_v = [idx[c, 0] for c in cols] + [idx[c, -1] for c in cols]
    corners = SurfacePoints.at_vertices(mesh.faces, corner_v)
    curves, ends = [], []
    for k, c in enumerate(cols):  # vertical curves 0..3, bottom arcs 4..7, top arcs 8..11
        curves.append(SurfacePoints.at_vertices(mesh.faces, idx[c, :]))
        ends.append((k, k + 4))
    for row, off in ((0, 0), (-1, 4)):
        for k, c in enumerate(cols):
            ring = [idx[(c + s) % 32, row] for s in range(9)]
            curves.append(SurfacePoints.at_vertices(mesh.faces, ring))
            ends.append((off + k, off + (k + 1) % 4))
    patches = [[(4 + k, False), ((k + 1) % 4, False), (8 + k, True), (k, True)] for k in range(4)]
    layout = layout_from_curves(mesh, corners, curves, ends, patches)
    out = extract_patches(mesh, layout)
    assert len(out) == 4
    for p in out:
        _assert_patch_is_disk_with_four_sides(p)
        assert p.mesh.n_faces == mesh.n_faces // 4
        assert [s.size for s in p.sides] == [9, 17, 9, 17]
        n = p.mesh.face_normals.mean(axis=0)
        c = p.mesh.vertices.mean(axis=0)
        assert n[:2] @ c[:2] > 0  # outward: the corners run counter-clockwise from outside
    assert_allclose(sum(p.mesh.area for p in out), mesh.area, rtol=1e-12)


def test_sphere_layout_extracts_and_checks():
    out = extract_patches(sphere(), sphere_layout())
    assert len(out) == 24
    for p in out:
        _assert_patch_is_disk_with_four_sides(p)
    assert_allclose(sum(p.mesh.area for p in out), sphere().area, rtol=tol.LAYOUT_AREA_RTOL)
    calls = []
    extract_patches(sphere(), sphere_layout(), progress=lambda d, t: calls.append((d, t)))
    assert calls and calls[-1][0] == calls[-1][1]


# ------------------------------------------------------------------------- bad layouts


def test_patches_built_on_threads_are_the_same():
    mesh, layout = real_mesh("igea"), real_layout("igea")
    one = extract_patches(mesh, layout)
    calls = []
    two = extract_patches(mesh, layout, workers=2, progress=lambda d, t: calls.append((d, t)))
    assert [d for d, _ in calls] == sorted(d for d, _ in calls) and calls[-1][0] == calls[-1][1]
    assert len(one) == len(two) == layout.n_patches
    for a, b in zip(one, two, strict=True):
        assert a.index == b.index
        np.testing.assert_array_equal(a.mesh.vertices, b.mesh.vertices)
        np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
        np.testing.assert_array_equal(a.face_parent, b.face_parent)
        for sa, sb in zip(a.sides, b.sides, strict=True):
            np.testing.assert_array_equal(sa, sb)
        for fa, fb in zip(a.features, b.features, strict=True):
            np.testing.assert_array_equal(fa.points.bary, fb.points.bary)
    with pytest.raises(InputError, match="workers must be an integer >= 1"):
        extract_patches(mesh, layout, workers=0)
    # the regions checked on threads (no partition kept from the calls above) give the same
    from meshfit.layout import extract

    extract._LAST[0] = None
    three = extract_patches(mesh, layout, workers=2)
    for a, b in zip(one, three, strict=True):
        assert a.mesh.name == b.mesh.name == f"{mesh.name}-patch{a.index}"
        np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
        np.testing.assert_array_equal(a.vertex_source.bary, b.vertex_source.bary)
        np.testing.assert_array_equal(a.corners, b.corners)


def test_a_region_failing_its_mesh_check_raises_in_component_order(monkeypatch):
    from meshfit.errors import DegenerateFaceError
    from meshfit.layout import extract

    real_piece = extract._piece

    def piece(mesh, cut, faces, c):
        if c in (3, 7):
            return DegenerateFaceError(f"region {c} has a degenerate face")
        return real_piece(mesh, cut, faces, c)

    monkeypatch.setattr(extract, "_piece", piece)
    extract._LAST[0] = None
    for workers in (1, 2):
        with pytest.raises(DegenerateFaceError, match="region 3 has"):
            extract_patches(sphere(), sphere_layout(), workers=workers)
        extract._LAST[0] = None


def _corrupt(tmp_path, edit, name="spot"):
    doc = json.loads((LAYOUTS / f"{name}.json").read_text())
    edit(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.__setitem__("meshfit_layout", 2), "unknown layout version 2"),
        (lambda d: d.pop("meshfit_layout"), "not a meshfit layout file"),
        (lambda d: d.pop("curves"), "missing key 'curves'"),
        (lambda d: d["curves"][3].pop("bary"), "missing key 'curves[3].bary'"),
        (lambda d: d["curves"][3]["face"].__setitem__(5, 10**6), "curve 3 point 5: face index"),
        (lambda d: d["corners"]["bary"].__setitem__(2, [0.5, 0.5, 0.5]), "corner 2: barycentric"),
        (lambda d: d["curves"][4]["bary"].__setitem__(7, [1.2, -0.1, -0.1]), "curve 4 point 7"),
        (lambda d: d["patches"][2]["sides"].pop(), "patch 2 has 3 sides"),
        (
            lambda d: d["patches"][5].__setitem__(
                "sides", [d["patches"][5]["sides"][i] for i in (0, 2, 1, 3)]
            ),
            "patch 5: side 0",
        ),
        (lambda d: d["patches"][1]["sides"][0].__setitem__(0, 999), "patch 1 side 0: curve index"),
        (lambda d: d["mesh"].__setitem__("sha256", "0" * 64), "made for another mesh"),
    ],
)
def test_corrupted_files_raise_layout_errors(tmp_path, edit, message):
    path = _corrupt(tmp_path, edit)
    with pytest.raises(LayoutError, match=message.replace("[", r"\[").replace("]", r"\]")):
        load_layout(path, real_mesh("spot"), check_topology=False)


def test_curve_end_away_from_its_corner(tmp_path):
    def edit(d):
        c = d["curves"][4]
        c["face"][0] = c["face"][5]
        c["bary"][0] = c["bary"][5]

    with pytest.raises(LayoutError, match=r"curve 4: its start is .* from corner"):
        load_layout(_corrupt(tmp_path, edit), real_mesh("spot"))


def test_malformed_json_names_the_line(tmp_path):
    text = (LAYOUTS / "spot.json").read_text().splitlines()
    text[5] = '{"corners":[0,1],"face":[1,2,,3]},'  # a broken curve on line 6
    path = tmp_path / "bad.json"
    path.write_text("\n".join(text))
    with pytest.raises(LayoutError, match="malformed JSON at line 6"):
        load_layout(path, real_mesh("spot"))


def test_layout_of_another_mesh(tmp_path):
    path = tmp_path / "igea.json"
    path.write_text((LAYOUTS / "spot.json").read_text())
    with pytest.raises(LayoutError, match="made for another mesh"):
        load_layout(path, real_mesh("nefertiti"))
    assert mesh_fingerprint(real_mesh("spot")) == real_layout("spot").fingerprint


def test_missing_file_raises_meshfit_error(tmp_path):
    with pytest.raises(MeshfitError):
        load_layout(tmp_path / "nope.json", sphere())


def test_crossing_curves_raise():
    from meshfit.curves import paint_curve

    mesh, layout = sphere(), sphere_layout()
    c = 0
    a, b = layout.curve_ends[c]
    # repaint curve 0 through a far point: it crosses other curves on its way
    far = int(np.argmax(np.linalg.norm(mesh.vertices - mesh.xyz(layout.corners[a]), axis=1)))
    picks = SurfacePoints.concatenate(
        [
            layout.corners[a],
            SurfacePoints.at_vertices(mesh.faces, [far]),
            layout.corners[b],
        ]
    )
    curves = list(layout.curves)
    curves[c] = paint_curve(mesh, picks)
    bad = _rebuild(mesh, layout, curves=curves)
    with pytest.raises(LayoutError, match=r"cross|passes through corner"):
        check_layout_topology(mesh, bad)


def test_clockwise_patch_raises():
    mesh, layout = sphere(), sphere_layout()
    patches = _patch_list(layout)
    patches[3] = [(c, not r) for c, r in reversed(patches[3])]
    with pytest.raises(LayoutError, match="patch 3: its sides run clockwise"):
        extract_patches(mesh, _rebuild(mesh, layout, patches=patches))


def test_uncovered_region_raises_naming_a_face():
    mesh, layout = sphere(), sphere_layout()
    patches = _patch_list(layout)[:-1]
    feats = [list(f) for f in layout.features][:-1]
    with pytest.raises(LayoutError, match=r"face \d+ lies in a region .* no patch of the layout"):
        extract_patches(mesh, _rebuild(mesh, layout, patches=patches, features=feats))


def test_patch_with_a_hole_is_not_a_disk():
    full = sphere()
    d = np.array([1.0, 0.5, 0.5]) / np.linalg.norm([1.0, 0.5, 0.5])
    centres = full.vertices[full.faces].mean(axis=1)
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    keep = centres @ d < np.cos(np.radians(8))
    used = np.unique(full.faces[keep])
    remap = np.full(full.n_vertices, -1)
    remap[used] = np.arange(used.size)
    mesh = Mesh(full.vertices[used], remap[full.faces[keep]], name="holed sphere")
    assert len(mesh.boundary_loops) == 1
    layout = cube_layout(mesh, frame=np.eye(3), center=full.vertices.mean(axis=0))
    with pytest.raises(LayoutError, match="not a disk: its region has 2 boundary loops"):
        extract_patches(mesh, layout)


def test_structural_errors_at_construction():
    mesh, layout = sphere(), sphere_layout()
    patches = _patch_list(layout)
    patches[0] = patches[0][:3]
    with pytest.raises(LayoutError, match="patch 0 has 3 sides"):
        _rebuild(mesh, layout, patches=patches)
    patches = _patch_list(layout)
    patches[1][2] = patches[1][1]
    with pytest.raises(LayoutError, match="patch 1 uses a curve twice"):
        _rebuild(mesh, layout, patches=patches)
    assert "meshfit_layout" in layout_to_json(layout)
    d = json.loads(layout_to_json(layout))
    d["curves"] = []
    says = f"{layout.n_patches} patches but no curves: every side is a curve"
    with pytest.raises(LayoutError, match=says):
        layout_from_json(json.dumps(d))


def test_patch_with_a_handle_is_not_a_disk():
    mesh = shapes.torus()  # 48 x 24 grid of vertices idx[u, v] = 24 u + v
    idx = np.arange(48 * 24).reshape(48, 24)
    u0, v0, k = 10, 4, 4
    loop = [idx[u0, v0], idx[u0 + k, v0], idx[u0 + k, v0 + k], idx[u0, v0 + k]]
    corners = SurfacePoints.at_vertices(mesh.faces, loop)
    chains = [
        idx[u0 : u0 + k + 1, v0],
        idx[u0 + k, v0 : v0 + k + 1],
        idx[u0 : u0 + k + 1, v0 + k][::-1],
        idx[u0, v0 : v0 + k + 1][::-1],
    ]
    curves = [SurfacePoints.at_vertices(mesh.faces, c) for c in chains]
    ends = [(s, (s + 1) % 4) for s in range(4)]
    small = [(s, False) for s in range(4)]
    rest = [(s, True) for s in (3, 2, 1, 0)]
    for sides in ((small, rest), (rest, small)):  # one of the two orders is counter-clockwise
        layout = layout_from_curves(mesh, corners, curves, ends, list(sides))
        with pytest.raises(LayoutError, match="not a disk: Euler characteristic -1"):
            extract_patches(mesh, layout)


def test_feature_outside_its_patch_raises():
    mesh, layout = sphere(), sphere_layout()
    feats = [list(f) for f in layout.features]
    feats[7], feats[0] = feats[0], []
    with pytest.raises(LayoutError, match=r"patch 7 feature 0: .*(outside the patch|away from)"):
        extract_patches(mesh, _rebuild(mesh, layout, features=feats))


def test_feature_between_adjacent_sides_raises():
    from meshfit.curves import paint_curve

    mesh, layout = sphere(), sphere_layout()
    c0, c1 = int(layout.patch_curves[0, 0]), int(layout.patch_curves[0, 1])
    a = layout.curves[c0].points[len(layout.curves[c0]) // 2]
    b = layout.curves[c1].points[len(layout.curves[c1]) // 2]
    feats = [list(f) for f in layout.features]
    feats[0] = [paint_curve(mesh, SurfacePoints.concatenate([a, b]), kind="feature")]
    with pytest.raises(LayoutError, match="patch 0 feature 0 runs from side 0 to side 1"):
        extract_patches(mesh, _rebuild(mesh, layout, features=feats))


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("n", [1, 3])
def test_randomly_turned_cube_layouts_extract(seed, n):
    from scipy.spatial.transform import Rotation

    mesh = sphere()
    frame = Rotation.random(random_state=seed).as_matrix()
    patches = extract_patches(mesh, cube_layout(mesh, n=n, frame=frame, picks_per_curve=4))
    assert len(patches) == 6 * n * n
    for p in patches:
        _assert_patch_is_disk_with_four_sides(p)
    assert_allclose(sum(p.mesh.area for p in patches), mesh.area, rtol=tol.LAYOUT_AREA_RTOL)


def test_second_component_without_patches_raises():
    one = sphere()
    two = Mesh(
        np.concatenate([one.vertices, one.vertices + np.array([3.0, 0, 0])]),
        np.concatenate([one.faces, one.faces + one.n_vertices]),
        name="two spheres",
    )
    layout = cube_layout(two, frame=np.eye(3), center=np.zeros(3), picks_per_curve=4)
    with pytest.raises(LayoutError, match=r"face \d+ lies in a closed piece of the mesh"):
        extract_patches(two, layout)


def _trapezoid_patch(bottom: float, top: float, n: int = 6) -> Patch:
    """A flat n x n grid patch whose bottom side is ``bottom`` long and top side ``top``."""
    u, v = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    width = bottom + (top - bottom) * v
    x = (u - 0.5) * width
    V = np.column_stack([x.ravel(), v.ravel(), np.zeros(u.size)])
    idx = np.arange(u.size).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    F = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    mesh = Mesh(V, F)
    sides = (idx[:, 0], idx[-1, :], idx[::-1, -1], idx[0, ::-1])
    corners = np.array([s[0] for s in sides])
    src = mesh.closest_points(V).points
    return Patch(0, mesh, corners, sides, np.arange(len(F)), src)


def test_taper_is_the_ratio_of_opposite_sides_and_warns_above_tapered():
    from meshfit.layout.patch import TAPERED, patch_notes, taper_notes

    assert_allclose(_trapezoid_patch(5.0, 1.0).taper, 5.0, rtol=1e-12)
    assert_allclose(_trapezoid_patch(1.0, 2.0).taper, 2.0, rtol=1e-12)
    assert taper_notes({0: 2.0, 1: TAPERED}) == []
    (note,) = taper_notes({3: 4.5, 7: 6.0, 1: 1.2})
    assert note.startswith("2 patches taper") and "patch 7: 6, patch 3: 4.5" in note
    rows = [{"patch": 0, "bulge": 5.0, "taper": 5.0}, {"patch": 1, "bulge": 1.0, "taper": 1.0}]
    notes = patch_notes(rows)
    assert len(notes) == 2 and "bulges" in notes[0] and "tapers" in notes[1]
    rows[1]["corner_angles"] = [90.0, 200.0, 90.0, 80.0]
    notes = patch_notes(rows)
    assert len(notes) == 3 and "patch 1: 200 degrees at corner 1" in notes[2]


def test_corner_angles_are_the_patch_angles_at_its_corners():
    from meshfit.layout.patch import REFLEX, corner_notes

    # a flat trapezoid 5 wide at the bottom, 1 at the top, 1 high: atan(1 / 2) at the bottom
    low = np.degrees(np.arctan2(1.0, 2.0))
    assert_allclose(_trapezoid_patch(5.0, 1.0).corner_angles, [low, low, 180 - low, 180 - low])
    assert_allclose(_trapezoid_patch(1.0, 1.0).corner_angles, 90.0)
    assert corner_notes({0: [90.0] * 4, 1: [REFLEX, 60.0, 60.0, 60.0]}) == []
    (note,) = corner_notes({4: [90.0, 90.0, 90.0, 190.0], 2: [234.0, 60.0, 60.0, 80.0]})
    assert note.startswith("2 patches turn back at a corner")
    assert note.index("patch 2: 234 degrees at corner 0") < note.index("patch 4: 190 degrees")


@pytest.mark.slow
def test_the_reflex_corners_of_the_test_layouts():
    """Each nefertiti test layout has one corner that turns back inside its patch
    (`REFLEX`; on the cube layout patch 20's, where its least even grid line is); igea's and
    spot's have none."""
    from meshfit.layout.patch import REFLEX

    for name, mesh, want in (
        ("nefertiti", "nefertiti", {20: 3}),
        ("nefertiti_bust", "nefertiti", {27: 2}),
        ("igea", "igea", {}),
        ("spot", "spot", {}),
    ):
        m = real_mesh(mesh)
        patches = extract_patches(m, load_layout(LAYOUTS / f"{name}.json", m))
        angles = {p.index: p.corner_angles for p in patches}
        got = {k: int(np.argmax(a)) for k, a in angles.items() if a.max() > REFLEX}
        assert got == want, name
        for a in angles.values():  # every patch is a disk: no corner angle is a full turn
            assert (a > 0).all() and (a < 360).all()
