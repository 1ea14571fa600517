"""find_problems / repair_arrays on arrays: every finding, the repair index maps, orientation,
a non-orientable surface, the real scans' defects, and a hypothesis property."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import errors
from meshfit.mesh import (
    Finding,
    Mesh,
    find_problems,
    load_mesh,
    read_mesh_arrays,
    repair_arrays,
    topology,
)
from meshfit.mesh.validate import raise_first

from .. import shapes
from ..conftest import mesh_path, real_mesh

SQUARE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float64)
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])
KINDS = {
    "empty",
    "non_finite",
    "coordinate_range",
    "index_range",
    "non_manifold_edge",
    "non_manifold_vertex",
    "degenerate_face",
    "duplicate_face",
    "unreferenced_vertex",
    "inconsistent_orientation",
}


def kinds(findings: list[Finding]) -> list[str]:
    return [f.kind for f in findings]


def check_repair_maps(v_in, f_in, mesh: Mesh) -> None:
    """Every kept input face is the right row of ``mesh.faces`` (reversed when flipped), and
    every kept vertex sits at its new index with the same position."""
    rep = mesh.repairs
    v_in = np.asarray(v_in, dtype=np.float64)
    f_in = np.asarray(f_in, dtype=np.int64)
    assert rep.vertex_map.shape == (v_in.shape[0],)
    assert rep.face_map.shape == (f_in.shape[0],)
    kept_f = np.flatnonzero(rep.face_map >= 0)
    assert_array_equal(np.sort(rep.face_map[kept_f]), np.arange(mesh.n_faces))  # a bijection
    assert_array_equal(rep.face_map[kept_f], np.arange(kept_f.size))  # order is kept
    kept_v = np.flatnonzero(rep.vertex_map >= 0)
    # kept vertices first, in order; copies of split vertices after them
    assert_array_equal(rep.vertex_map[kept_v], np.arange(kept_v.size))
    assert rep.vertex_parent.shape == (mesh.n_vertices,)
    assert_array_equal(rep.vertex_parent[: kept_v.size], kept_v)
    assert_array_equal(mesh.vertices, v_in[rep.vertex_parent])
    want = f_in[kept_f].copy()
    flipped = np.isin(kept_f, rep.flipped_faces)
    assert np.isin(rep.flipped_faces, kept_f).all()
    want[flipped] = want[flipped][:, ::-1]
    assert_array_equal(rep.vertex_parent[mesh.faces[rep.face_map[kept_f]]], want)
    # the geometry of every kept face is unchanged (same corner positions, as a set)
    assert_array_equal(
        np.sort(mesh.vertices[mesh.faces[rep.face_map[kept_f]]], axis=1),
        np.sort(v_in[f_in[kept_f]], axis=1),
    )


# ------------------------------------------------------------------------ each finding
def test_valid_mesh_has_no_findings():
    assert find_problems(SQUARE_V, SQUARE_F) == []


@pytest.mark.parametrize("nv", [0, 4])
def test_empty(nv):
    v = SQUARE_V[:nv]
    f = np.zeros((0, 3), dtype=np.int64)
    (finding,) = find_problems(v, f)
    assert finding.kind == "empty"
    assert finding.message == f"mesh is empty: it has {'no vertices' if nv == 0 else 'no faces'}"
    assert not finding.repairable
    with pytest.raises(errors.EmptyMeshError):
        Mesh.from_arrays(v, f, repair=True)


def test_a_repair_that_keeps_no_face_says_why():
    # a sphere flattened onto a line: the counts, and no blame on the coordinates'
    # precision (they are float64 near the origin)
    ico = shapes.icosphere(2)
    v = ico.vertices * [1.0, 0.0, 0.0]
    with pytest.raises(errors.EmptyMeshError, match=r"of 320: \d+ degenerate") as err:
        Mesh.from_arrays(v, ico.faces, repair=True)
    assert "32-bit" not in str(err.value)


@pytest.mark.parametrize("offset", [2e5, 4e6])
def test_32_bit_coordinates_far_from_the_origin_are_named(offset):
    # a small part stored as float32 at a georeferenced offset (an STL or a float PLY):
    # its coordinates round onto a grid coarser than the part, every face collapses
    ico = shapes.icosphere(2)
    shift = np.array([offset, -offset, 0.5 * offset])
    v = (1e-3 * ico.vertices + shift).astype(np.float32)
    with pytest.raises(errors.EmptyMeshError, match="32-bit floats") as err:
        Mesh.from_arrays(v.astype(np.float64), ico.faces, repair=True)
    assert "64-bit" in str(err.value)
    # the same part near the origin, or in float64 at the offset, is kept whole
    part = 1e-3 * ico.vertices
    for near in (part.astype(np.float32), part + shift):
        assert (
            Mesh.from_arrays(np.asarray(near, dtype=np.float64), ico.faces, repair=True).n_faces > 0
        )


def test_non_finite_first_vertex_and_count():
    v = np.vstack([SQUARE_V, [[np.nan, 0, 0], [0, np.inf, 0]]])
    f = np.vstack([SQUARE_F, [[1, 0, 4], [2, 1, 5]]])
    findings = find_problems(v, f)
    assert findings[0].kind == "non_finite"
    assert findings[0].first == (4,)
    assert findings[0].count == 2
    assert "vertex 4" in findings[0].message
    assert findings[0].repairable
    # faces on non-finite vertices are neither degenerate nor anything else
    assert kinds(findings) == ["non_finite"]
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert_array_equal(mesh.repairs.face_map, [0, 1, -1, -1])
    assert_array_equal(mesh.repairs.vertex_map, [0, 1, 2, 3, -1, -1])
    check_repair_maps(v, f, mesh)


@pytest.mark.parametrize("bad", [-1, 4, 100])
def test_index_range(bad):
    f = np.vstack([SQUARE_F, [[0, 1, bad]], [[bad, 1, 2]]])
    findings = find_problems(SQUARE_V, f)
    assert kinds(findings) == ["index_range"]  # topology is not checked on bad indices
    assert findings[0].first == (2,)
    assert findings[0].count == 2
    assert f"face 2 = [0, 1, {bad}]" in findings[0].message
    assert not findings[0].repairable
    with pytest.raises(errors.IndexRangeError, match="face 2"):
        Mesh(SQUARE_V, f)
    with pytest.raises(errors.IndexRangeError, match="face 2"):
        Mesh.from_arrays(SQUARE_V, f, repair=True)


def test_degenerate_zero_area_and_repeated_index():
    v = np.vstack([SQUARE_V, [[0.5, 0, 0]]])
    f = np.vstack([SQUARE_F, [[0, 4, 1]], [[1, 2, 2]]])
    findings = find_problems(v, f)
    assert kinds(findings) == ["degenerate_face"]
    assert findings[0].first == (2,)
    assert findings[0].count == 2
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert_array_equal(mesh.repairs.face_map, [0, 1, -1, -1])
    assert_array_equal(mesh.repairs.vertex_map, [0, 1, 2, 3, -1])
    check_repair_maps(v, f, mesh)


def test_repeated_index_face_is_degenerate_not_non_manifold():
    # [1, 2, 2] uses edge (1, 2) twice and has a self-loop (2, 2); before the fix it was
    # reported as a non-manifold edge "in faces [1, 2, 2]" caused by "duplicate faces"
    f = np.vstack([SQUARE_F, [[2, 3, 3]]])
    findings = find_problems(SQUARE_V, f)
    assert kinds(findings) == ["degenerate_face"]
    assert findings[0].first == (2,)
    with pytest.raises(errors.DegenerateFaceError, match=r"face 2 = \[2, 3, 3\]"):
        Mesh(SQUARE_V, f)


def test_degenerate_area_is_relative_to_the_bbox():
    # the same shape at any scale: a sliver whose area is 1e-16 of the bbox diagonal squared
    for scale in (1e-6, 1.0, 1e6):
        v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-16, 0], [0, 1, 0]]) * scale
        f = np.array([[0, 1, 2], [0, 2, 3]])
        assert kinds(find_problems(v, f)) == ["degenerate_face"]
        v[2, 1] = 1e-6 * scale
        assert find_problems(v, f) == []


def test_infinite_coordinates_give_no_numpy_warning():
    # np.cross on inf coordinates warned "invalid value" (an error under filterwarnings)
    v = np.vstack([SQUARE_V, [[np.inf, -np.inf, 1]]])
    f = np.vstack([SQUARE_F, [[1, 0, 4]]])
    assert kinds(find_problems(v, f)) == ["non_finite"]


@pytest.mark.parametrize("big", [1e76, -1e200, 1e308])
def test_coordinates_whose_distances_overflow_are_refused_without_a_warning(big):
    v = np.vstack([SQUARE_V, [[0, big, 1]]])
    f = np.vstack([SQUARE_F, [[1, 0, 4]]])
    (found,) = find_problems(v, f)
    assert (found.kind, found.first, found.repairable) == ("coordinate_range", (4,), False)
    with pytest.raises(errors.CoordinateRangeError, match=r"vertex 4 .*scale the mesh down"):
        Mesh.from_arrays(v, f, repair=True)
    # the bound's edge: a mesh just inside it is valid, and its squared distances finite
    inside = np.vstack([SQUARE_V * 1e75, [[0, 1e75, 1]]])
    assert find_problems(inside, f) == []


def test_duplicate_faces_same_and_opposite_winding():
    v = np.vstack([SQUARE_V, [[3, 0, 0], [4, 0, 0], [3, 1, 0], [6, 0, 0], [7, 0, 0], [6, 1, 0]]])
    f = np.vstack([SQUARE_F, [[4, 5, 6], [5, 6, 4], [7, 8, 9], [9, 8, 7]]])
    findings = find_problems(v, f)
    dup = next(x for x in findings if x.kind == "duplicate_face")
    assert dup.first == (3,)
    assert dup.count == 2
    assert "1 of them back-to-back" in dup.message
    assert "face 3 repeats face 2" in dup.message
    mesh = Mesh.from_arrays(v, f, repair=True)
    # later copies are dropped; both faces of a back-to-back pair are dropped
    assert_array_equal(mesh.repairs.face_map, [0, 1, 2, -1, -1, -1])
    assert_array_equal(mesh.repairs.vertex_map, [0, 1, 2, 3, 4, 5, 6, -1, -1, -1])
    check_repair_maps(v, f, mesh)


def test_non_manifold_edge_fin_is_split_apart():
    v = np.vstack([SQUARE_V, [[0.5, 0.5, 1]]])
    f = np.vstack([SQUARE_F, [[0, 2, 4]]])
    (finding,) = find_problems(v, f)
    assert finding.kind == "non_manifold_edge"
    assert finding.first == (0, 2)
    assert "edge (0, 2) in faces [0, 1, 2]" in finding.message
    assert finding.repairable
    with pytest.raises(errors.NonManifoldEdgeError, match=r"edge \(0, 2\)"):
        Mesh(v, f)
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert mesh.n_faces == 3
    # no edge is shared by more than two faces, and no face was dropped
    assert mesh.edge_face_count.max() <= 2
    assert mesh.repairs.split_vertices >= 1
    assert "split" in mesh.repairs.summary()
    check_repair_maps(v, f, mesh)


def test_bow_tie_vertex_is_split_apart():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 1, 0], [2, 2, 0]], dtype=float)
    f = np.array([[0, 1, 2], [2, 3, 4]])
    (finding,) = find_problems(v, f)
    assert finding.kind == "non_manifold_vertex"
    assert finding.first == (2,)
    assert "vertex 2, 2 fans" in finding.message
    assert finding.repairable
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert mesh.n_vertices == 6
    assert mesh.n_components == 2
    assert mesh.repairs.split_vertices == 1
    check_repair_maps(v, f, mesh)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e4])
def test_inside_out_sphere_is_turned_right_side_out(scale):
    sphere = shapes.icosphere(2)
    v = np.asarray(sphere.vertices) * scale + 5.0 * scale
    f = np.asarray(sphere.faces)[:, ::-1]
    assert find_problems(v, f) == []  # a valid mesh, only inside out
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert mesh.repairs.inverted_components == 1
    assert_array_equal(mesh.faces, np.asarray(sphere.faces))
    assert "inside out" in mesh.repairs.summary()
    # the outward sphere is left as it is, and an open cap is never flipped
    right = Mesh.from_arrays(np.asarray(sphere.vertices), np.asarray(sphere.faces), repair=True)
    assert right.repairs.inverted_components == 0
    assert not right.repairs.changed()
    cap = f[np.asarray(sphere.vertices)[f].mean(axis=1)[:, 2] > 0.3]
    opened = Mesh.from_arrays(np.asarray(sphere.vertices), cap, repair=True)
    assert opened.repairs.inverted_components == 0


def test_pinched_cone_vertex():
    # two cones glued at their apex: a closed-fan non-manifold vertex with no boundary
    ring = np.array([[np.cos(t), np.sin(t), 0.0] for t in np.linspace(0, 2 * np.pi, 6)[:-1]])
    v = np.vstack([[[0, 0, 0]], ring + np.array([0, 0, 1]), ring - np.array([0, 0, 1])])
    f = [[0, 1 + i, 1 + (i + 1) % 5] for i in range(5)]
    f += [[0, 6 + (i + 1) % 5, 6 + i] for i in range(5)]
    findings = find_problems(v, np.array(f))
    assert kinds(findings) == ["non_manifold_vertex"]
    assert findings[0].first == (0,)


def test_unreferenced_vertices():
    v = np.vstack([[[9, 9, 9]], SQUARE_V, [[8, 8, 8]]])
    f = SQUARE_F + 1
    (finding,) = find_problems(v, f)
    assert finding.kind == "unreferenced_vertex"
    assert finding.first == (0,)
    assert finding.count == 2
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert_array_equal(mesh.repairs.vertex_map, [-1, 0, 1, 2, 3, -1])
    assert_array_equal(mesh.repairs.face_map, [0, 1])
    assert_array_equal(mesh.faces, SQUARE_F)
    check_repair_maps(v, f, mesh)


# ------------------------------------------------------------------------- orientation
@pytest.mark.parametrize("flip", [[5, 17, 200], [0], [0, 1, 2, 3], [1279]])
def test_orientation_repair_flips_exactly_the_flipped_faces(flip):
    sphere = shapes.icosphere(3)
    f = sphere.faces.copy()
    f[flip] = f[flip][:, ::-1]
    findings = find_problems(sphere.vertices, f)
    assert kinds(findings) == ["inconsistent_orientation"]
    assert findings[0].repairable
    mesh = Mesh.from_arrays(sphere.vertices, f, repair=True)
    assert_array_equal(mesh.repairs.flipped_faces, sorted(flip))
    assert_array_equal(mesh.faces, sphere.faces)  # the outward orientation is back
    assert_array_equal(mesh.repairs.face_map, np.arange(sphere.n_faces))
    check_repair_maps(sphere.vertices, f, mesh)


def test_orientation_first_edge_named():
    f = np.array([[0, 1, 2], [0, 3, 2]])
    (finding,) = find_problems(SQUARE_V, f)
    assert finding.kind == "inconsistent_orientation"
    assert finding.first == (0, 2)
    assert "edge (0, 2) between faces 0 and 1" in finding.message


def test_orientation_is_fixed_per_component():
    # two squares; in the second, the majority is flipped relative to its first face
    v = np.vstack([SQUARE_V, SQUARE_V + np.array([3, 0, 0])])
    f = np.vstack([SQUARE_F, (SQUARE_F + 4)[:, ::-1]])
    f[3] = f[3][::-1]  # face 3 now disagrees with face 2
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert mesh.repairs.flipped_faces.size == 1
    assert mesh.n_components == 2
    assert find_problems(mesh.vertices, mesh.faces) == []
    check_repair_maps(v, f, mesh)


def moebius_strip(n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """A triangulated Moebius strip: n quads around the loop, the last one glued with a twist."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = []
    for a in t:
        for s in (-0.3, 0.3):
            r = 1 + s * np.cos(a / 2)
            v.append([r * np.cos(a), r * np.sin(a), s * np.sin(a / 2)])
    f = []
    for i in range(n):
        a, b = 2 * i, 2 * i + 1
        c, d = (2 * (i + 1), 2 * (i + 1) + 1) if i < n - 1 else (1, 0)  # the twist
        f += [[a, c, b], [b, c, d]]
    return np.array(v), np.array(f)


def test_moebius_strip_is_not_orientable():
    v, f = moebius_strip()
    findings = find_problems(v, f)
    assert kinds(findings) == ["inconsistent_orientation"]
    assert not findings[0].repairable
    assert "not orientable" in findings[0].message
    with pytest.raises(errors.OrientationError, match="not orientable"):
        Mesh.from_arrays(v, f, repair=True)
    with pytest.raises(errors.OrientationError):
        repair_arrays(v, f)


def test_moebius_strip_edges_are_manifold():
    # the strip itself is a valid manifold-with-boundary: only the orientation fails
    v, f = moebius_strip()
    table = topology.edge_table(f, v.shape[0])
    assert table.edge_count.max() == 2
    assert (table.edge_count == 1).sum() == 2 * 12  # one boundary loop of 24 edges


# ------------------------------------------------------------------------- raise_first
def test_raise_first_prefix_and_also():
    v = np.vstack([SQUARE_V, [[9, 9, 9]]])
    f = np.vstack([SQUARE_F, [[0, 1, 1]]])
    findings = find_problems(v, f)
    assert kinds(findings) == ["degenerate_face", "unreferenced_vertex"]
    with pytest.raises(errors.DegenerateFaceError) as info:
        raise_first(findings, where="x.ply")
    msg = str(info.value)
    assert msg.startswith("x.ply: 1 degenerate face")
    assert msg.endswith("(load with repair=True to fix it); also: unreferenced vertex")
    assert info.value.first == (2,)
    assert info.value.count == 1
    raise_first([])  # nothing to raise


def test_finding_to_dict_and_error_class():
    (finding,) = find_problems(SQUARE_V, np.vstack([SQUARE_F, [[0, 1, 1]]]))
    assert finding.to_dict() == {
        "kind": "degenerate_face",
        "message": finding.message,
        "first": [2],
        "count": 1,
        "repairable": True,
    }
    assert finding.error_class is errors.DegenerateFaceError
    assert isinstance(finding.to_error(), errors.MeshValidationError)


def test_mesh_constructor_raises_first_finding_class():
    f = np.array([[0, 1, 2], [0, 3, 2]])
    with pytest.raises(errors.OrientationError):
        Mesh(SQUARE_V, f)
    assert issubclass(errors.OrientationError, errors.MeshfitError)


def test_repair_report_summary():
    v = np.vstack([[[9, 9, 9]], SQUARE_V])
    mesh = Mesh.from_arrays(v, SQUARE_F + 1, repair=True)
    assert mesh.repairs.summary() == (
        "repaired (unreferenced vertex: 1): dropped 0 faces and 1 vertex, flipped 0 faces"
    )
    clean = Mesh.from_arrays(SQUARE_V, SQUARE_F, repair=True)
    assert clean.repairs.summary().startswith("repaired (nothing to do)")
    assert_array_equal(clean.repairs.face_map, [0, 1])


def test_repair_keeps_colors_of_kept_vertices():
    v = np.vstack([[[9, 9, 9]], SQUARE_V])
    c = np.arange(15, dtype=np.uint8).reshape(5, 3)
    mesh = Mesh.from_arrays(v, SQUARE_F + 1, c, repair=True)
    assert_array_equal(mesh.vertex_colors, c[1:])


# --------------------------------------------------------------------------- real scans
def test_nefertiti_fraunhofer_findings():
    raw = read_mesh_arrays(mesh_path("nefertiti_fraunhofer"))
    findings = find_problems(raw.vertices, raw.faces)
    assert kinds(findings) == ["non_manifold_edge", "duplicate_face"]
    nm, dup = findings
    assert nm.count == 3
    assert nm.first == (695, 696)
    assert "faces [841, 975, " in nm.message  # the back-to-back pair 841 / 975 on the edge
    assert "caused by duplicate or back-to-back faces" in nm.message
    assert nm.repairable
    assert dup.count == 3
    assert dup.first == (975,)
    assert "3 of them back-to-back" in dup.message
    assert "face 975 repeats face 841" in dup.message
    with pytest.raises(errors.NonManifoldEdgeError, match=r"edge \(695, 696\)"):
        load_mesh(mesh_path("nefertiti_fraunhofer"))
    table = topology.edge_table(raw.faces, raw.vertices.shape[0])
    assert table.edges.shape[0] == 29_478
    assert (table.edge_count == 1).sum() == 516
    assert (table.edge_count > 2).sum() == 3
    assert raw.vertices.shape[0] - table.edges.shape[0] + raw.faces.shape[0] == 4


def test_nefertiti_fraunhofer_repaired():
    raw = read_mesh_arrays(mesh_path("nefertiti_fraunhofer"))
    mesh = real_mesh("nefertiti_fraunhofer")
    rep = mesh.repairs
    assert mesh.n_faces == 19_476
    assert mesh.n_vertices == 9_997
    assert mesh.euler_characteristic == 1
    assert len(mesh.boundary_loops) == 1
    assert mesh.genus == 0
    # the three back-to-back pairs named in SOURCES.md are exactly the dropped faces
    assert_array_equal(np.flatnonzero(rep.face_map < 0), sorted([841, 975, 1041, 10706, 979, 1028]))
    assert (rep.vertex_map < 0).sum() == 3
    assert rep.flipped_faces.size == 0
    check_repair_maps(raw.vertices, raw.faces, mesh)
    assert_array_equal(mesh.vertex_colors, raw.vertex_colors[rep.vertex_map >= 0])


def test_bunny_unreferenced_vertices():
    raw = read_mesh_arrays(mesh_path("bunny"))
    (finding,) = find_problems(raw.vertices, raw.faces)
    assert finding.kind == "unreferenced_vertex"
    assert finding.count == 1_113
    assert finding.first == (8,)
    mesh = real_mesh("bunny")
    assert (mesh.repairs.vertex_map < 0).sum() == 1_113
    assert_array_equal(mesh.repairs.face_map, np.arange(69_451))
    check_repair_maps(raw.vertices, raw.faces, mesh)
    assert len(mesh.boundary_loops) == 5
    assert mesh.euler_characteristic == -3
    assert mesh.genus == 0


# ---------------------------------------------------------------------- property tests
@st.composite
def small_meshes(draw):
    """Random small arrays: any indices in [-1, nv], coordinates with exact degeneracies."""
    nv = draw(st.integers(0, 7))
    nf = draw(st.integers(0, 9))
    # small integer coordinates make exact degeneracies (collinear, coincident) common
    coord = st.one_of(st.integers(-2, 2).map(float), st.sampled_from([np.nan, np.inf]))
    v = np.array(
        draw(st.lists(st.tuples(coord, coord, coord), min_size=nv, max_size=nv)), dtype=np.float64
    ).reshape(nv, 3)
    lo, hi = (-1, nv) if draw(st.booleans()) else (0, max(nv - 1, 0))
    f = np.array(
        draw(st.lists(st.tuples(*[st.integers(lo, hi)] * 3), min_size=nf, max_size=nf)),
        dtype=np.int64,
    ).reshape(nf, 3)
    return v, f


_ICO = shapes.icosphere(1)
EDITS = ["flip", "copy", "reversed_copy", "repeat_index", "collapse", "nan", "spare", "delete"]


@st.composite
def damaged_spheres(draw):
    """A closed icosphere with a few random defects of the kinds scans have."""
    v = np.array(_ICO.vertices)
    f = np.array(_ICO.faces)
    for op, k in draw(
        st.lists(st.tuples(st.sampled_from(EDITS), st.integers(0, 10**6)), max_size=10)
    ):
        i = k % f.shape[0]
        if op == "flip":
            f[i] = f[i][::-1]
        elif op == "copy":
            f = np.vstack([f, f[i]])
        elif op == "reversed_copy":
            f = np.vstack([f, f[i][::-1]])
        elif op == "repeat_index":
            f[i, 2] = f[i, 1]
        elif op == "collapse":  # two vertices at one position: zero-area faces
            v[f[i, 0]] = v[f[i, 1]]
        elif op == "nan":
            v[k % v.shape[0], 0] = np.nan
        elif op == "spare":
            v = np.vstack([v, [[5.0, 5.0, 5.0]]])
        elif op == "delete":
            f = np.delete(f, i, axis=0)
    return v, f


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(small_meshes(), damaged_spheres()))
def test_find_problems_and_repair_never_crash(mesh):
    v, f = mesh
    findings = find_problems(v, f)
    assert all(isinstance(x, Finding) and x.kind in KINDS for x in findings)
    assert all(x.count >= 0 for x in findings)
    if findings:
        with pytest.raises(findings[0].error_class):
            Mesh(v, f)
    else:
        assert Mesh(v, f).n_faces == f.shape[0]
    # repair succeeds exactly when every finding says it is repairable
    repairable = all(x.repairable for x in findings)
    try:
        result = repair_arrays(v, f)
    except errors.MeshfitError as exc:
        assert isinstance(exc, errors.MeshValidationError)
        assert not repairable, [x.message for x in findings]
        result = None
    if result is not None:
        assert repairable, [x.message for x in findings]
        nv2, nf2, _c, report = result
        assert find_problems(nv2, nf2) == []  # a repair always validates
        repaired = Mesh.from_arrays(v, f, repair=True)
        assert_array_equal(repaired.faces, nf2)
        assert_allclose(repaired.vertices, nv2)
        assert_array_equal(report.face_map, repaired.repairs.face_map)
        check_repair_maps(v, f, repaired)


def test_back_to_back_copies_on_a_surface_that_leave_a_bow_tie_are_split():
    # two surface faces meeting at a single vertex each get a reversed copy: repair drops all
    # four, leaving two holes that touch at that vertex, which it then splits apart
    sphere = shapes.icosphere(1)
    f = np.array(sphere.faces)
    corner = f[0, 0]
    vf = np.flatnonzero((f == corner).any(axis=1))
    # a face around the corner sharing only the vertex with face 0
    other = next(int(g) for g in vf if np.intersect1d(f[g], f[0]).size == 1)
    bad = np.vstack([f, f[0][::-1], f[other][::-1]])
    findings = find_problems(sphere.vertices, bad)
    assert kinds(findings)[:2] == ["non_manifold_edge", "duplicate_face"]
    assert all(x.repairable for x in findings)
    mesh = Mesh.from_arrays(sphere.vertices, bad, repair=True)
    assert mesh.repairs.split_vertices == 1
    assert mesh.repairs.vertex_parent[-1] == corner
    # the two triangular holes become one loop through both copies of the corner
    (loop,) = mesh.boundary_loops
    assert loop.size == 6
    assert set(mesh.repairs.vertex_parent[loop].tolist()) >= {int(corner)}
    assert (mesh.repairs.vertex_parent[loop] == corner).sum() == 2
    check_repair_maps(sphere.vertices, bad, mesh)


def test_bow_tie_made_by_a_degenerate_face_is_repairable():
    # the zero-area face (2, 4, 5) touches the square only at vertex 2
    v = np.vstack([SQUARE_V, [[2, 2, 0], [3, 3, 0]]])
    f = np.vstack([SQUARE_F, [[2, 4, 5]]])
    findings = find_problems(v, f)
    assert kinds(findings) == ["non_manifold_vertex", "degenerate_face"]
    assert findings[0].first == (2,)
    assert findings[0].repairable
    mesh = Mesh.from_arrays(v, f, repair=True)
    assert mesh.repairs.split_vertices == 0
    assert_array_equal(mesh.faces, SQUARE_F)
    check_repair_maps(v, f, mesh)
