"""The welded tessellation (`meshfit.export.patch_mesh`) and the OBJ, GLB and PLY writers on it.

Closed networks (a generated cube-sphere of six stitched patches, a fit of a closed scan) must
give watertight, manifold meshes at every resolution; an open scan's mesh has boundary edges
exactly along the sides no other patch shares. Files are read back by a parser of our own and
by trimesh.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

import meshfit
from meshfit import FitOptions, tol
from meshfit.bspline import BSplineSurface, fit_bspline, grid_parameters
from meshfit.displacement import DisplacementMap, reconstruct
from meshfit.errors import InputError
from meshfit.export import (
    UDIM_COLUMNS,
    PatchMesh,
    export_gltf,
    export_obj,
    export_objs,
    export_ply,
    patch_mesh,
    spline_network,
    udim,
)
from meshfit.stitch import Network, network_from_grids, stitch_surfaces
from meshfit.types import Side
from tests.conftest import real_mesh

#: cube faces as (normal axis, sign, u axis, v axis) with e_u x e_v = sign e_normal (outward)
_CUBE = ((0, 1, 1, 2), (0, -1, 2, 1), (1, 1, 2, 0), (1, -1, 0, 2), (2, 1, 0, 1), (2, -1, 1, 0))


@cache
def cube_sphere() -> tuple[list[BSplineSurface], Network]:
    """Six stitched patches of a sphere, one per cube face: a closed genus-0 network."""
    t = grid_parameters(13)
    U, V = np.meshgrid(2 * t - 1, 2 * t - 1, indexing="ij")
    grids = []
    for a, s, b, c in _CUBE:
        P = np.zeros((*U.shape, 3))
        P[..., a], P[..., b], P[..., c] = s, U, V
        grids.append(P / np.linalg.norm(P, axis=-1, keepdims=True))
    network = network_from_grids(grids)
    surfaces = stitch_surfaces([fit_bspline(g, controls=(6, 6)) for g in grids], network)
    return surfaces, network


OPTIONS = FitOptions(
    controls=(4, 4), spring_level=1, formats=(), report=False, map_shapes="matched"
)


@cache
def _fit(name: str):
    r = meshfit.fit(real_mesh(name), "auto", options=OPTIONS)
    return name, list(r.surfaces), list(r.maps), r.network


@pytest.fixture(scope="module", params=["spot", "nefertiti_fraunhofer"])
def fitted(request):
    """A quick fit of a closed and an open scan: (name, surfaces, maps, network)."""
    return _fit(request.param)


@pytest.fixture(scope="module")
def closed_fit():
    """The closed scan's fit, for the file formats."""
    return _fit("spot")


def _edges(F) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edges ``(e, 2)`` of triangles ``F`` and the number of faces on each."""
    e = np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    n = int(F.max()) + 1
    key, count = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
    return np.stack(np.divmod(key, n), axis=1), count


def _assert_closed_manifold(F) -> None:
    _, count = _edges(F)
    assert (count == 2).all(), np.bincount(count)
    directed = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = directed[:, 0] * (int(F.max()) + 1) + directed[:, 1]
    assert len(np.unique(key)) == len(key)  # each edge once each way: consistently oriented


def _diag(pm: PatchMesh) -> float:
    return float(np.linalg.norm(np.ptp(pm.vertices, axis=0)))


def _patch_nodes(pm: PatchMesh, p: int) -> np.ndarray:
    """Rows of ``uv`` (grid nodes) of patch p, as its ``(h, w)`` grid."""
    start = sum(h * w for h, w in pm.shapes[:p])
    h, w = pm.shapes[p]
    return np.arange(start, start + h * w).reshape(h, w)


# --- topology


@pytest.mark.parametrize("scale", [1, 2])
def test_cube_sphere_is_watertight(scale):
    surfaces, network = cube_sphere()
    for net in (network, None):  # the given network, or found from the splines
        pm = patch_mesh(surfaces, network=net, scale=scale)
        _assert_closed_manifold(pm.faces)
        assert len(pm.vertices) - len(_edges(pm.faces)[0]) + len(pm.faces) == 2  # sphere
    # 8 per control point, equal round the cube (its directions form one class), scaled
    assert pm.shapes == ((47 * scale + 1,) * 2,) * 6


def test_scale_keeps_shared_counts_equal():
    surfaces, network = cube_sphere()
    # unequal requests along shared boundaries: each class takes its largest count
    shapes = [(5 + p, 9 - p) for p in range(6)]
    for scale in (0.5, 1.0, 1.7, 3.0):
        pm = patch_mesh(surfaces, network=network, shapes=shapes, scale=scale)
        _assert_closed_manifold(pm.faces)
        for b in network.boundaries:
            na = pm.shapes[b.a][Side(b.side_a).direction]
            nb = pm.shapes[b.b][Side(b.side_b).direction]
            assert na == nb


def test_matching_counts_never_multiplies_the_vertices_past_the_budget():
    """One long strip among small grids: its count spreads over its class (four faces), and
    the other direction too; the grids are capped within the budget, still watertight."""
    from meshfit.stitch.network import MATCH_BUDGET

    surfaces, network = cube_sphere()
    shapes = [(3, 3)] * 5 + [(400, 3)]
    pm = patch_mesh(surfaces, network=network, shapes=shapes)
    _assert_closed_manifold(pm.faces)
    assert sum(h * w for h, w in pm.shapes) <= MATCH_BUDGET * sum(h * w for h, w in shapes)
    assert max(max(s) for s in pm.shapes) > 3  # the strip still gets more than its peers


def test_fit_is_watertight_or_bounded_by_unshared_sides(fitted):
    name, surfaces, maps, network = fitted
    for scale in (1, 2):
        pm = patch_mesh(surfaces, maps, network, scale=scale)
        if name == "spot":  # closed
            _assert_closed_manifold(pm.faces)
            continue
        edges, count = _edges(pm.faces)
        assert set(count.tolist()) == {1, 2}
        shared = {(b.a, b.side_a) for b in network.boundaries}
        shared |= {(b.b, b.side_b) for b in network.boundaries}
        uv_vertex = pm.uv_vertex
        want = []
        for p in range(len(surfaces)):
            for side in Side:
                if (p, side.value) not in shared:
                    row = uv_vertex[side.row(_patch_nodes(pm, p))]
                    want.append(np.sort(np.stack([row[:-1], row[1:]], axis=1), axis=1))
        want = np.unique(np.concatenate(want), axis=0)
        assert_array_equal(edges[count == 1], want)


def test_found_network_welds_like_the_fits(fitted):
    _, surfaces, maps, network = fitted
    a = patch_mesh(surfaces, maps, network)
    b = patch_mesh(surfaces, maps)
    assert_array_equal(a.faces, b.faces)
    assert_array_equal(a.vertices, b.vertices)


def test_patches_sharing_nothing_keep_their_grids():
    surfaces, _ = cube_sphere()
    far = BSplineSurface(surfaces[0].control_points + 10.0)
    pm = patch_mesh([surfaces[0], far], shapes=(7, 6))
    for p, s in enumerate([surfaces[0], far]):
        nodes = _patch_nodes(pm, p)
        grid = s.evaluate_grid(grid_parameters(7), grid_parameters(6))
        assert_array_equal(pm.vertices[pm.uv_vertex[nodes]], grid)
        assert_array_equal(pm.uv_vertex[nodes].ravel(), nodes.ravel())  # the grid's order


# --- geometry


@pytest.mark.parametrize("scale", [1, 2])
def test_positions_are_the_reconstructed_grids(fitted, scale):
    _, surfaces, maps, network = fitted
    for ms in (maps, None):
        pm = patch_mesh(surfaces, ms, network, scale=scale)
        diag = _diag(pm)
        uv_vertex = pm.uv_vertex
        welded = np.bincount(uv_vertex, minlength=len(pm.vertices)) > 1
        for p, s in enumerate(surfaces):
            h, w = pm.shapes[p]
            if ms is None:
                want = s.evaluate_grid(grid_parameters(h), grid_parameters(w))
            else:
                want = reconstruct(s, ms[p], shape=(h, w))
            v = uv_vertex[_patch_nodes(pm, p)]
            err = np.linalg.norm(pm.vertices[v] - want, axis=-1)
            assert (err[~welded[v]] <= tol.TEST_ATOL * diag).all()
            assert (err[welded[v]] <= tol.STITCH_GAP * diag).all()


def test_normals_are_unit_and_outward():
    surfaces, network = cube_sphere()
    pm = patch_mesh(surfaces, network=network)
    assert_allclose(np.linalg.norm(pm.normals, axis=1), 1.0, rtol=0, atol=1e-12)
    radial = pm.vertices / np.linalg.norm(pm.vertices, axis=1, keepdims=True)
    assert ((pm.normals * radial).sum(axis=1) > 0.99).all()
    # area-weighted over every face round the vertex, across patch boundaries
    V, F = pm.vertices, pm.faces
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    corner = int(pm.uv_vertex[_patch_nodes(pm, 0)[0, 0]])
    around = (F == corner).any(axis=1)
    assert len(np.unique(pm.face_patch[around])) == 3  # a cube corner: three patches
    n = fn[around].sum(axis=0)
    assert_allclose(pm.normals[corner], n / np.linalg.norm(n), rtol=0, atol=1e-12)


_angle = st.floats(-np.pi, np.pi, allow_nan=False)
_shift = st.floats(-5.0, 5.0, allow_nan=False)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(a=_angle, b=_angle, c=_angle, t=st.tuples(_shift, _shift, _shift))
def test_rigid_motion_moves_the_mesh_rigidly(a, b, c, t):
    surfaces, _ = cube_sphere()
    rng = np.random.default_rng(3)
    maps = [DisplacementMap(0.02 * rng.standard_normal((7, 9, 3))) for _ in surfaces]
    R = _rotation(a, b, c)
    moved = [BSplineSurface(s.control_points @ R.T + np.array(t)) for s in surfaces]
    pm = patch_mesh(surfaces, maps, scale=0.8)
    pm2 = patch_mesh(moved, maps, scale=0.8)
    for name in ("faces", "face_uv", "face_patch", "uv"):
        assert_array_equal(getattr(pm2, name), getattr(pm, name))
    assert pm2.shapes == pm.shapes
    size = 1.0 + np.abs(t).max()
    assert_allclose(pm2.vertices, pm.vertices @ R.T + np.array(t), rtol=0, atol=1e-12 * size)
    assert_allclose(pm2.normals, pm.normals @ R.T, rtol=0, atol=1e-9)


def _rotation(a: float, b: float, c: float) -> np.ndarray:
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    Rz = np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
    Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    Rx = np.array([[1, 0, 0], [0, cc, -sc], [0, sc, cc]])
    return Rz @ Ry @ Rx


# --- texture coordinates


def test_udim_numbers():
    assert [udim(p) for p in (0, 9, 10, 37)] == [1001, 1010, 1011, 1038]
    assert UDIM_COLUMNS == 10
    with pytest.raises(InputError, match=">= 0"):
        udim(-1)


def test_uvs_lie_in_their_tiles_on_texel_centres(fitted):
    _, surfaces, maps, network = fitted
    assert len(surfaces) > UDIM_COLUMNS  # patches in more than one tile row
    pm = patch_mesh(surfaces, maps, network)
    tile = np.floor(pm.uv).astype(np.int64)
    for p in range(len(surfaces)):
        nodes = _patch_nodes(pm, p)
        assert (tile[nodes.ravel()] == [p % 10, p // 10]).all()
        assert udim(p) == 1001 + tile[nodes[0, 0], 0] + 10 * tile[nodes[0, 0], 1]
        # at the maps' own resolution every vertex sits on a texel centre: bilinear sampling
        # of the image (x along u, y along v) reads the map's value there
        h, w = maps[p].shape
        assert pm.shapes[p] == (h, w)
        x, y = (pm.uv[nodes] - [p % 10, p // 10]).transpose(2, 0, 1)
        I, J = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
        assert_allclose(x * h - 0.5, I, rtol=0, atol=1e-9)
        assert_allclose(y * w - 0.5, J, rtol=0, atol=1e-9)
    # faces of patch p take their corners' coordinates from patch p's own rows
    first = np.concatenate([[0], np.cumsum([h * w for h, w in pm.shapes])])
    assert (first[pm.face_patch][:, None] <= pm.face_uv).all()
    assert (pm.face_uv < first[pm.face_patch + 1][:, None]).all()


def test_uvs_without_maps_are_the_parameters():
    surfaces, network = cube_sphere()
    pm = patch_mesh(surfaces, network=network, shapes=(5, 5))
    U, V = np.meshgrid(grid_parameters(5), grid_parameters(5), indexing="ij")
    for p in range(6):
        uv = pm.uv[_patch_nodes(pm, p)]
        assert_array_equal(uv[..., 0], p + U)
        assert_array_equal(uv[..., 1], V)
    one = patch_mesh(surfaces[0], shapes=(5, 4))  # alone: no count to share
    U, V = np.meshgrid(grid_parameters(5), grid_parameters(4), indexing="ij")
    assert_array_equal(one.uv, np.stack([U.ravel(), V.ravel()], axis=1))


# --- files


def _read_obj(path):
    v, vt, vn, f, groups, mtl = [], [], [], [], [], []
    for line in path.read_text().splitlines():
        key, _, rest = line.partition(" ")
        if key == "v":
            v.append([float(x) for x in rest.split()])
        elif key == "vt":
            vt.append([float(x) for x in rest.split()])
        elif key == "vn":
            vn.append([float(x) for x in rest.split()])
        elif key == "f":
            f.append([[int(i) - 1 for i in c.split("/")] for c in rest.split()])
        elif key == "g":
            groups.append((rest, len(f)))
        elif key in ("mtllib", "usemtl"):
            mtl.append((key, rest))
    return np.array(v), np.array(vt), np.array(vn), np.array(f), groups, mtl


def test_obj_round_trip(closed_fit, tmp_path):
    _, surfaces, maps, network = closed_fit
    images = [f"maps/patch_{p}.vector.exr" for p in range(len(surfaces))]
    path, spline = export_objs(
        {tmp_path / "d.obj": maps, tmp_path / "s.obj": None},
        surfaces,
        network=network,
        scale=0.5,
        materials=images,
    )
    pm = patch_mesh(surfaces, maps, network, scale=0.5)
    assert not (tmp_path / "d.mtl").exists()  # the displaced mesh: no displacement material
    with pytest.raises(InputError, match="spline-only"):
        export_obj(tmp_path / "x.obj", surfaces, displacements=maps, materials=images)
    *_, mtl = _read_obj(spline)
    assert mtl[0] == ("mtllib", "s.mtl")
    v, vt, vn, f, groups, no_mtl = _read_obj(path)
    assert no_mtl == []
    assert_array_equal(v, pm.vertices)  # 17 digits: exact
    assert_array_equal(vt, pm.uv)
    assert_allclose(vn, pm.normals, rtol=0, atol=1e-8)
    assert_array_equal(f[:, :, 0], pm.faces)
    assert_array_equal(f[:, :, 1], pm.face_uv)
    assert_array_equal(f[:, :, 2], pm.faces)
    _assert_closed_manifold(f[:, :, 0])
    assert [g for g, _ in groups] == [f"patch_{p}" for p in range(len(surfaces))]
    assert_array_equal([k for _, k in groups], np.searchsorted(pm.face_patch, range(len(groups))))
    assert [m for k, m in mtl[1:]] == [g for g, _ in groups]
    text = (tmp_path / "s.mtl").read_text()
    assert text.count("newmtl ") == len(surfaces) and f"disp {images[3]}\n" in text
    m = trimesh.load(path, process=False, force="mesh")
    m.merge_vertices(merge_tex=True, merge_norm=True)
    assert m.is_watertight and m.is_winding_consistent


def test_objs_share_coordinates_and_topology(tmp_path):
    surfaces, _ = cube_sphere()
    rng = np.random.default_rng(0)
    maps = [DisplacementMap(0.01 * rng.standard_normal((9, 8, 3))) for _ in surfaces]
    d, s = export_objs({tmp_path / "d.obj": maps, tmp_path / "s.obj": None}, surfaces)
    vd, vtd, _, fd, _, _ = _read_obj(d)
    vs, vts, _, fs, _, _ = _read_obj(s)
    assert_array_equal(vtd, vts)
    assert_array_equal(fd, fs)
    assert not np.array_equal(vd, vs)
    _assert_closed_manifold(fs[:, :, 0])
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind


def test_glb_round_trip(closed_fit, tmp_path):
    _, surfaces, maps, network = closed_fit
    path = export_gltf(tmp_path / "d.glb", surfaces, displacements=maps, network=network)
    pm = patch_mesh(surfaces, maps, network)
    scene = trimesh.load(path, process=False)
    assert len(scene.geometry) == len(surfaces)
    uv_vertex = pm.uv_vertex
    parts = []
    for p in range(len(surfaces)):
        g = scene.geometry[f"patch_{p}"]
        nodes = _patch_nodes(pm, p).ravel()
        assert_array_equal(g.vertices, pm.vertices[uv_vertex[nodes]].astype(np.float32))
        assert_allclose(g.vertex_normals, pm.normals[uv_vertex[nodes]], rtol=0, atol=1e-6)
        assert_allclose(g.visual.uv, pm.uv[nodes], rtol=0, atol=1e-5)
        assert (np.floor(g.visual.uv) == [p % 10, p // 10]).all()
        parts.append(trimesh.Trimesh(g.vertices, g.faces, process=False))
    whole = trimesh.util.concatenate(parts)
    assert not whole.is_watertight  # patch meshes repeat the boundary vertices ...
    whole.merge_vertices()
    assert whole.is_watertight and whole.is_winding_consistent  # ... at the same position
    assert len(whole.vertices) == len(pm.vertices)


@pytest.mark.parametrize("patch_ids", [True, False])
def test_ply_round_trip(patch_ids, tmp_path):
    surfaces, network = cube_sphere()
    rng = np.random.default_rng(1)
    maps = [DisplacementMap(0.01 * rng.standard_normal((9, 8, 3))) for _ in surfaces]
    path = export_ply(tmp_path / "d.ply", surfaces, displacements=maps, patch_ids=patch_ids)
    pm = patch_mesh(surfaces, maps, network, scale=1)
    m = trimesh.load(path, process=False)
    assert_array_equal(m.vertices, pm.vertices)
    assert_array_equal(m.faces, pm.faces)
    assert_allclose(m.vertex_normals, pm.normals, rtol=0, atol=1e-6)
    assert m.is_watertight
    data = path.read_bytes()
    head, body = data.split(b"end_header\n", 1)
    assert (b"property int patch" in head) == patch_ids
    fields = [("k", "u1"), ("f", "<i4", (3,))] + ([("p", "<i4")] if patch_ids else [])
    faces = np.frombuffer(body[len(pm.vertices) * 36 :], dtype=np.dtype(fields))
    assert (faces["k"] == 3).all()
    assert_array_equal(faces["f"], pm.faces)
    if patch_ids:
        assert_array_equal(faces["p"], pm.face_patch)


# --- input checks


def test_patch_mesh_rejects_bad_input():
    surfaces, network = cube_sphere()
    with pytest.raises(InputError, match="network of 6 patches for 5"):
        patch_mesh(surfaces[:5], network=network)
    with pytest.raises(InputError, match="scale"):
        patch_mesh(surfaces, scale=0.0)
    with pytest.raises(InputError, match="5 shapes for 6"):
        patch_mesh(surfaces, shapes=[(4, 4)] * 5)
    with pytest.raises(InputError, match="2 x 2"):
        patch_mesh(surfaces, shapes=(1, 4))
    with pytest.raises(InputError, match="2 maps for 6"):
        patch_mesh(surfaces, [None, None])
    with pytest.raises(InputError, match="not a DisplacementMap"):
        patch_mesh(surfaces, [np.zeros((4, 4, 3))] * 6)
    with pytest.raises(InputError, match="material"):
        export_obj("x.obj", surfaces, materials=["a.exr"] * 5)


def test_patch_mesh_validates_its_arrays():
    surfaces, network = cube_sphere()
    pm = patch_mesh(surfaces, network=network, shapes=(4, 4))
    fields = {k: getattr(pm, k) for k in PatchMesh.__dataclass_fields__}
    assert not pm.vertices.flags.writeable and not pm.faces.flags.writeable
    PatchMesh(**fields)  # the valid mesh passes
    for key, value, match in [
        ("faces", pm.faces[:, :2], "faces must have shape"),
        ("faces", np.where(pm.faces == 0, len(pm.vertices), pm.faces), "faces indexes"),
        ("face_uv", pm.face_uv - 1, "face_uv indexes"),
        ("normals", pm.normals[1:], "normals must have shape"),
        ("face_patch", pm.face_patch + 1, "face_patch indexes"),
        ("shapes", pm.shapes[1:], "grid nodes"),
    ]:
        with pytest.raises(InputError, match=match):
            PatchMesh(**{**fields, key: value})


def test_spline_network_finds_the_cube_faces():
    surfaces, network = cube_sphere()
    found = spline_network(surfaces)
    assert len(found.boundaries) == len(network.boundaries) == 12
    assert len(found.corners) == 8
    assert sorted(len(c) for c in found.corners) == [3] * 8


# --- kernels against their numpy oracles (the same sums in the same order: equal bits)


def _random_weld(seed: int):
    """Grids of random shapes whose nodes are welded at random (some cells' corners
    together, so triangles drop), with random vertex positions."""
    rng = np.random.default_rng(seed)
    shapes = [(int(rng.integers(2, 9)), int(rng.integers(2, 9))) for _ in range(5)]
    offs = np.concatenate([[0], np.cumsum([h * w for h, w in shapes])]).astype(np.int64)
    k = int(offs[-1])
    label = np.arange(k)
    pairs = rng.integers(0, k, size=(k // 4, 2)).tolist()
    w = shapes[0][1]
    pairs += [(0, w), (w + 1, 1)]  # two of the first grid's cells welded shut along an edge
    for a, b in pairs:  # merge b into a's vertex
        label[label == label[b]] = label[a]
    _, vertex_of = np.unique(label, return_inverse=True)
    vertex_of = vertex_of.astype(np.int64)
    nv = int(vertex_of.max()) + 1
    points = rng.standard_normal((k, 3)) * 10.0 ** rng.integers(-3, 4)
    return shapes, offs, vertex_of, nv, points


@pytest.mark.parametrize("seed", range(6))
def test_weld_kernels_match_their_oracles(seed):
    from meshfit._kernels import weld as kw

    from ..reference import weld as ref

    shapes, offs, vertex_of, nv, points = _random_weld(seed)
    shp = np.asarray(shapes, dtype=np.int64)
    V = kw.welded_means(points, vertex_of, nv)
    assert_array_equal(V, ref.welded_means(points, vertex_of, nv))
    faces, face_uv, face_patch, m = kw.welded_faces(shp, offs, vertex_of)
    want = ref.welded_faces(shapes, offs, vertex_of)
    assert m == len(want[0]) and m < len(faces)  # (some triangles welded shut)
    for got, w in zip((faces[:m], face_uv[:m], face_patch[:m]), want, strict=True):
        assert_array_equal(got, w)
    normals = kw.unit_vertex_normals(kw.node_normal_sums(V, vertex_of, shp, offs), vertex_of, nv)
    assert_array_equal(normals, ref.vertex_normals(V, vertex_of, shapes, offs))


def test_a_welded_network_is_the_oracles():
    from meshfit.export.weld import _weld_labels

    from ..reference import weld as ref

    surfaces, network = cube_sphere()
    pm = patch_mesh(surfaces, network=network, shapes=[(5 + p, 9 - p) for p in range(6)])
    offs = np.concatenate([[0], np.cumsum([h * w for h, w in pm.shapes])]).astype(np.int64)
    vertex_of = _weld_labels(network, pm.shapes, offs)
    points = np.concatenate(
        [
            s.evaluate_grid(grid_parameters(h), grid_parameters(w)).reshape(-1, 3)
            for s, (h, w) in zip(surfaces, pm.shapes, strict=True)
        ]
    )
    assert_array_equal(pm.vertices, ref.welded_means(points, vertex_of, len(pm.vertices)))
    faces, face_uv, face_patch = ref.welded_faces(pm.shapes, offs, vertex_of)
    assert_array_equal(pm.faces, faces)
    assert_array_equal(pm.face_uv, face_uv)
    assert_array_equal(pm.face_patch, face_patch)
    assert_array_equal(pm.normals, ref.vertex_normals(pm.vertices, vertex_of, pm.shapes, offs))
