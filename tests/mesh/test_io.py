"""Reading malformed and valid mesh files: every validation case as a file in each format.

Each malformed file is checked twice: ``load_mesh`` raises the exact error subclass with a
message naming the first offending face / vertex / edge, and ``meshfit info`` exits with
code 2 and one ``meshfit: error: ...`` line on stderr naming the same element.
"""

from __future__ import annotations

import json
import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import cli, errors
from meshfit.mesh import Mesh, load_mesh, read_mesh_arrays, save_mesh

from ..conftest import mesh_path, real_mesh

# ----------------------------------------------------------------------------- file writers
# vertex and face lists are written as given (faces 0-based, except OBJ which is written
# verbatim so that 0, negative and out-of-range tokens can be tested)


def ply_ascii(vertices, faces) -> bytes:
    head = (
        f"ply\nformat ascii 1.0\ncomment meshfit test\nelement vertex {len(vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = [" ".join(str(x) for x in v) for v in vertices]
    rows += [f"{len(f)} " + " ".join(str(i) for i in f) for f in faces]
    return (head + "".join(r + "\n" for r in rows)).encode()


def ply_binary(vertices, faces, colors=None) -> bytes:
    head = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
    )
    if colors is not None:
        head += "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    head += f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    out = bytearray(head.encode())
    for i, v in enumerate(vertices):
        out += struct.pack("<3f", *(float(x) for x in v))
        if colors is not None:
            out += struct.pack("<3B", *colors[i])
    for f in faces:
        out += struct.pack("<B", len(f)) + struct.pack(f"<{len(f)}i", *f)
    return bytes(out)


def obj(vertices, faces_tokens) -> bytes:
    rows = ["# meshfit test", "o test"] + ["v " + " ".join(str(x) for x in v) for v in vertices]
    rows += ["f " + " ".join(str(t) for t in f) for f in faces_tokens]
    return ("\n".join(rows) + "\n").encode()


def obj1(vertices, faces) -> bytes:
    """OBJ with 0-based faces converted to OBJ's 1-based indices."""
    return obj(vertices, [[i + 1 for i in f] for f in faces])


def off(vertices, faces) -> bytes:
    rows = ["OFF", f"{len(vertices)} {len(faces)} 0"]
    rows += [" ".join(str(x) for x in v) for v in vertices]
    rows += [f"{len(f)} " + " ".join(str(i) for i in f) for f in faces]
    return ("\n".join(rows) + "\n").encode()


def stl_binary(vertices, faces) -> bytes:
    v = np.asarray(vertices, dtype=np.float64)
    out = bytearray(b"meshfit test".ljust(80, b" ") + struct.pack("<I", len(faces)))
    for f in faces:
        out += struct.pack("<12fH", 0.0, 0.0, 0.0, *v[list(f)].ravel(), 0)
    return bytes(out)


WRITERS = {"ply": ply_ascii, "plyb": ply_binary, "obj": obj1, "off": off, "stl": stl_binary}
SUFFIX = {"ply": ".ply", "plyb": ".ply", "obj": ".obj", "off": ".off", "stl": ".stl"}

# a unit square in z = 0 made of two triangles, plus spare vertices
SQUARE_V = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
SQUARE_F = [[0, 1, 2], [0, 2, 3]]
NAN = float("nan")
INF = float("inf")


@dataclass
class Case:
    """A malformed mesh: its arrays, the error it must raise and what the message must name."""

    name: str
    vertices: list
    faces: list
    error: type[errors.MeshfitError]
    names: tuple[str, ...]  # substrings of the message naming the first offending element
    first: tuple[int, ...] | None = None  # MeshValidationError.first
    formats: tuple[str, ...] = ("ply", "plyb", "obj", "off")
    repairable: bool = False


CASES = [
    # the non-finite vertex 4 is used by face 2 only: repair drops that face
    Case(
        "nan_coordinate",
        [*SQUARE_V, [NAN, 2, 0]],
        [*SQUARE_F, [2, 4, 3]],
        errors.NonFiniteError,
        ("vertex 4",),
        (4,),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case(
        "inf_coordinate",
        [*SQUARE_V, [0, -INF, 0]],
        [*SQUARE_F, [0, 4, 1]],
        errors.NonFiniteError,
        ("vertex 4",),
        (4,),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case(
        "index_out_of_range",
        SQUARE_V,
        [[0, 1, 2], [0, 2, 7], [0, 9, 1]],
        errors.IndexRangeError,
        ("face 1",),
        (1,),
        ("ply", "plyb", "obj", "off"),
    ),
    Case(
        "negative_index",
        SQUARE_V,
        [[0, 1, 2], [0, 2, -1]],
        errors.IndexRangeError,
        ("face 1", "-1"),
        (1,),
        ("ply", "plyb", "off"),
    ),
    # zero area: vertex 4 lies on the edge (0, 1); the mesh is otherwise valid
    Case(
        "zero_area_face",
        [*SQUARE_V, [0.5, 0, 0]],
        [*SQUARE_F, [0, 4, 1]],
        errors.DegenerateFaceError,
        ("face 2",),
        (2,),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case(
        "repeated_index_face",
        SQUARE_V,
        [*SQUARE_F, [1, 2, 2]],
        errors.DegenerateFaceError,
        ("face 2", "[1, 2, 2]"),
        (2,),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    # a separate triangle listed twice: no edge has three faces, so the duplicate is first
    Case(
        "duplicate_face",
        [*SQUARE_V, [3, 0, 0], [4, 0, 0], [3, 1, 0]],
        [*SQUARE_F, [4, 5, 6], [4, 5, 6]],
        errors.DuplicateFaceError,
        ("face 3", "face 2"),
        (3,),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case(
        "non_manifold_edge",
        [*SQUARE_V, [0.5, 0.5, 1]],
        [*SQUARE_F, [0, 2, 4]],
        errors.NonManifoldEdgeError,
        ("edge (0, 2)", "faces [0, 1, 2]"),
        (0, 2),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case(
        "non_manifold_vertex",
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 1, 0], [2, 2, 0]],
        [[0, 1, 2], [2, 3, 4]],
        errors.NonManifoldVertexError,
        ("vertex 2",),
        (2,),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case(
        "inconsistent_orientation",
        SQUARE_V,
        [[0, 1, 2], [0, 3, 2]],
        errors.OrientationError,
        ("edge (0, 2)", "faces 0 and 1"),
        (0, 2),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case(
        "unreferenced_vertex",
        [[5, 5, 5], *SQUARE_V],
        [[1, 2, 3], [1, 3, 4]],
        errors.UnreferencedVertexError,
        ("vertex 0",),
        (0,),
        ("ply", "plyb", "obj", "off"),
        True,
    ),
    Case("no_faces", SQUARE_V, [], errors.EmptyMeshError, ("no faces",), ()),
    Case("no_vertices", [], [], errors.EmptyMeshError, ("no vertices",), ()),
]
# STL stores a triangle soup (vertex 3 f + k is corner k of face f): only problems of single
# triangles are meaningful there
STL_CASES = [
    # STL corners at equal positions are joined on reading: the NaN corner (the sixth corner
    # written) becomes vertex 4, after the four distinct corners before it
    Case(
        "nan_coordinate",
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, NAN]],
        [[0, 1, 2], [0, 3, 4]],
        errors.NonFiniteError,
        ("vertex 4",),
        (4,),
        ("stl",),
        True,
    ),
    Case(
        "zero_area_face",
        [*SQUARE_V, [2, 0, 0]],
        [[0, 1, 2], [0, 1, 4]],
        errors.DegenerateFaceError,
        ("face 1",),
        (1,),
        ("stl",),
        True,
    ),
    Case("no_faces", [], [], errors.EmptyMeshError, ("no vertices",), (), ("stl",)),
]
PARAMS = [
    pytest.param(c, fmt, id=f"{c.name}-{fmt}") for c in CASES + STL_CASES for fmt in c.formats
]


def write(tmp_path: Path, name: str, data: bytes) -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


def run_info(capsys, *args: str) -> tuple[int, str, str]:
    rc = cli.main(["info", *args])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def assert_one_error_line(err: str, *names: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("meshfit: error: ")
    for n in names:
        assert n in lines[0]
    return lines[0]


# ------------------------------------------------------------------- malformed meshes
@pytest.mark.parametrize(("case", "fmt"), PARAMS)
def test_malformed_file_raises_named_error(tmp_path, case, fmt):
    p = write(tmp_path, f"{case.name}{SUFFIX[fmt]}", WRITERS[fmt](case.vertices, case.faces))
    with pytest.raises(case.error) as info:
        load_mesh(p)
    assert type(info.value) is case.error  # the exact subclass, not a parent
    msg = str(info.value)
    assert p.name in msg
    for n in case.names:
        assert n in msg
    if case.first is not None:
        assert info.value.first == case.first


@pytest.mark.parametrize(("case", "fmt"), PARAMS)
def test_malformed_file_fails_info_with_one_line(tmp_path, capsys, case, fmt):
    p = write(tmp_path, f"{case.name}{SUFFIX[fmt]}", WRITERS[fmt](case.vertices, case.faces))
    rc, _out, err = run_info(capsys, str(p), "--no-repair")
    assert rc == 2
    line = assert_one_error_line(err, str(p), *case.names)
    assert line.endswith("(repairable: run without --no-repair)") == case.repairable
    # repair is the default: a repairable mesh is usable, listed as repaired
    rc, out, err = run_info(capsys, str(p), "--json")
    assert (rc == 0) == case.repairable, err
    if case.repairable:
        data = json.loads(out)
        assert data["repaired"] is True
        assert data["findings"][0]["kind"] == case.error.kind


@pytest.mark.parametrize(("case", "fmt"), PARAMS)
def test_malformed_file_json_lists_the_finding(tmp_path, capsys, case, fmt):
    p = write(tmp_path, f"{case.name}{SUFFIX[fmt]}", WRITERS[fmt](case.vertices, case.faces))
    rc, out, _err = run_info(capsys, str(p), "--json", "--no-repair")
    assert rc == 2
    if case.error is errors.IndexRangeError and fmt in ("obj", "off"):
        # the OBJ / OFF readers reject a face naming a missing vertex while reading, with its
        # line number, before there are arrays to describe
        assert out == ""
    else:
        data = json.loads(out)
        assert data["valid"] is False
        assert data["repaired"] is False
        assert data["findings"][0]["kind"] == case.error.kind
        assert data["findings"][0]["repairable"] == case.repairable
        if case.first:
            assert tuple(data["findings"][0]["first"]) == case.first


def test_interior_duplicate_face_is_a_repairable_non_manifold_edge(tmp_path, capsys):
    # a copy of an interior face puts three faces on its interior edge: reported as a
    # non-manifold edge caused by the duplicate, repairable by dropping the copy
    p = write(tmp_path, "dup.ply", ply_ascii(SQUARE_V, [*SQUARE_F, [2, 0, 1]]))
    with pytest.raises(errors.NonManifoldEdgeError, match=r"caused by duplicate") as info:
        load_mesh(p)
    assert "edge (0, 2) in faces [0, 1, 2]" in str(info.value)
    assert "also: duplicate face" in str(info.value)
    rc, _out, err = run_info(capsys, str(p), "--no-repair")
    assert rc == 2
    assert_one_error_line(err, "edge (0, 2)", "(repairable: run without --no-repair)")
    mesh = load_mesh(p, repair=True)
    assert_array_equal(mesh.repairs.face_map, [0, 1, -1])
    assert_array_equal(mesh.faces, SQUARE_F)


def test_obj_negative_indices_are_relative(tmp_path):
    # OBJ negative indices count back from the last vertex defined so far: valid, not an error
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf -3 -2 -1\nv 0 1 0\nf 1 -2 -1\n"
    mesh = load_mesh(write(tmp_path, "rel.obj", text.encode()))
    assert_array_equal(mesh.faces, SQUARE_F)


@pytest.mark.parametrize(
    ("token", "why"),
    [
        (0, "OBJ indices start at 1: trimesh silently read 0 as the first vertex"),
        (-9, "a negative index counting back past the first vertex"),
    ],
)
def test_obj_index_outside_the_vertices(tmp_path, capsys, token, why):
    p = write(tmp_path, "bad.obj", obj(SQUARE_V, [[1, 2, 3], [1, 3, token]]))
    with pytest.raises(errors.IndexRangeError, match=rf"line 8: face 1 refers to vertex {token},"):
        load_mesh(p)
    with pytest.raises(errors.IndexRangeError):
        load_mesh(p, repair=True)
    rc, _out, err = run_info(capsys, str(p), "--repair")
    assert rc == 2, why
    assert_one_error_line(err, f"face 1 refers to vertex {token}")


@pytest.mark.parametrize(("case", "fmt"), [p for p in PARAMS if not p.values[0].repairable])
def test_unrepairable_file_raises_with_repair(tmp_path, capsys, case, fmt):
    p = write(tmp_path, f"{case.name}{SUFFIX[fmt]}", WRITERS[fmt](case.vertices, case.faces))
    with pytest.raises(case.error) as info:
        load_mesh(p, repair=True)
    for n in case.names:
        assert n in str(info.value)
    rc, out, err = run_info(capsys, str(p), "--repair")
    assert rc == 2
    assert out == ""
    assert_one_error_line(err, *case.names)


def test_obj_line_number_in_index_error(tmp_path):
    p = write(tmp_path, "far.obj", obj(SQUARE_V, [[1, 2, 3], [1, 3, 4], [1, 2, 99]]))
    with pytest.raises(errors.IndexRangeError) as info:
        load_mesh(p)
    # lines: comment, o, 4 vertices, then faces 0, 1, 2 on lines 7, 8, 9
    assert "line 9: face 2 refers to vertex 99" in str(info.value)
    assert info.value.first == (2,)
    assert info.value.count == 1


def test_obj_keeps_unreferenced_vertices_and_order(tmp_path):
    # trimesh drops unreferenced OBJ vertices and renumbers the rest; meshfit keeps them
    raw = read_mesh_arrays(
        write(tmp_path, "u.obj", obj1([[5, 5, 5], *SQUARE_V], [[1, 2, 3], [1, 3, 4]]))
    )
    assert_array_equal(raw.vertices, [[5, 5, 5], *SQUARE_V])
    assert_array_equal(raw.faces, [[1, 2, 3], [1, 3, 4]])


def test_obj_texture_indices_do_not_split_vertices(tmp_path):
    # vertex 1 and 3 carry different UVs in the two faces: a UV seam along the diagonal;
    # trimesh duplicates vertices along it, which would cut the mesh open
    text = (
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
        "vt 0.2 0.2\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\nf 1/5/1 3/6/1 4/4/1\n"
    )
    mesh = load_mesh(write(tmp_path, "uv.obj", text.encode()))
    assert mesh.n_vertices == 4
    assert_array_equal(mesh.faces, SQUARE_F)
    assert mesh.n_components == 1
    assert len(mesh.boundary_loops) == 1


def test_obj_vertex_colors(tmp_path):
    text = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nf 1//1 2//1 3//1 # comment\n"
    mesh = load_mesh(write(tmp_path, "c.obj", text.encode()))
    assert_array_equal(mesh.vertex_colors, [[255, 0, 0], [0, 255, 0], [0, 0, 255]])


# --------------------------------------------------------------- polygons are triangulated
PENTAGON_V = [[0, 0, 0], [1, 0, 0], [1.5, 1, 0], [0.5, 1.5, 0], [-0.5, 1, 0]]
POLYGON_FILES = {
    "quad-ply": ("q.ply", ply_ascii(SQUARE_V, [[0, 1, 2, 3]]), 1, 2),
    "quad-plyb": ("q.ply", ply_binary(SQUARE_V, [[0, 1, 2, 3]]), 1, 2),
    "quad-obj": ("q.obj", obj1(SQUARE_V, [[0, 1, 2, 3]]), 1, 2),
    "quad-off": ("q.off", off(SQUARE_V, [[0, 1, 2, 3]]), 1, 2),
    "pentagon-ply": ("p.ply", ply_ascii(PENTAGON_V, [[0, 1, 2, 3, 4]]), 1, 3),
    "pentagon-plyb": ("p.ply", ply_binary(PENTAGON_V, [[0, 1, 2, 3, 4]]), 1, 3),
    "pentagon-obj": ("p.obj", obj1(PENTAGON_V, [[0, 1, 2, 3, 4]]), 1, 3),
    "mixed-ply": (
        "m.ply",
        ply_ascii([*PENTAGON_V, [0.5, -1, 0]], [[0, 1, 2, 3, 4], [0, 5, 1]]),
        1,
        4,
    ),
    "mixed-obj": ("m.obj", obj1([*PENTAGON_V, [0.5, -1, 0]], [[0, 5, 1], [0, 1, 2, 3, 4]]), 1, 4),
}


@pytest.mark.parametrize("key", list(POLYGON_FILES))
def test_polygons_are_triangulated_and_noted(tmp_path, capsys, key):
    name, data, polys, tris = POLYGON_FILES[key]
    p = write(tmp_path, name, data)
    raw = read_mesh_arrays(p)
    assert raw.notes == [f"triangulated {polys} polygon faces into {tris} triangles"]
    mesh = load_mesh(p)
    assert mesh.n_faces == tris
    assert len(mesh.boundary_loops) == 1  # a fan of a convex polygon is a disk
    assert_allclose(mesh.area, _polygon_area(mesh.vertices[:, :2], key), rtol=1e-12)
    rc, out, err = run_info(capsys, str(p))
    assert rc == 0
    assert err == ""
    assert f"note: triangulated {polys} polygon faces into {tris} triangles" in out


def _polygon_area(xy, key):
    if key.startswith("mixed"):
        return _shoelace(np.array(PENTAGON_V)[:, :2]) + 0.5  # plus the triangle (0, 5, 1)
    return _shoelace(xy[: 4 if key.startswith("quad") else 5])


def _shoelace(xy):
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def ply_binary_general(
    vertices, faces, *, order="<", colors=None, normals=False, face_tail=False, count="B"
) -> bytes:
    """Binary PLY with optional RGBA colours and normals per vertex, a scalar face property
    after the index list (``face_tail``) and the list count type ``count`` (struct code)."""
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    ctype = {"B": "uchar", "i": "int", "H": "ushort"}[count]
    head = f"ply\nformat {fmt} 1.0\nelement vertex {len(vertices)}\n"
    head += "property double x\nproperty double y\nproperty double z\n"
    if normals:
        head += "property float nx\nproperty float ny\nproperty float nz\n"
    if colors is not None:
        head += "".join(f"property uchar {c}\n" for c in ("red", "green", "blue", "alpha"))
    head += f"element face {len(faces)}\nproperty list {ctype} uint vertex_indices\n"
    if face_tail:
        head += "property float quality\n"
    head += "end_header\n"
    out = bytearray(head.encode())
    for i, v in enumerate(vertices):
        out += struct.pack(f"{order}3d", *(float(x) for x in v))
        if normals:
            out += struct.pack(f"{order}3f", 0.0, 0.0, 1.0)
        if colors is not None:
            out += struct.pack("4B", *colors[i])
    for k, f in enumerate(faces):
        out += struct.pack(f"{order}{count}", len(f)) + struct.pack(f"{order}{len(f)}I", *f)
        if face_tail:
            out += struct.pack(f"{order}f", 0.5 * k)
    return bytes(out)


MIXED_V = [*PENTAGON_V, [0.5, -1, 0]]
MIXED_F = [[0, 5, 1], [0, 1, 2, 3, 4]]


def test_binary_ply_with_mixed_polygon_sizes(tmp_path):
    # trimesh reads binary PLY faces of one corner count only: meshfit reads the rest
    p = write(tmp_path, "m.ply", ply_binary(MIXED_V, MIXED_F))
    raw = read_mesh_arrays(p)
    assert raw.notes == ["triangulated 1 polygon faces into 4 triangles"]
    assert_array_equal(raw.faces, [[0, 5, 1], [0, 1, 2], [0, 2, 3], [0, 3, 4]])
    assert_allclose(raw.vertices, MIXED_V)
    mesh = load_mesh(p)
    assert mesh.n_faces == 4
    assert_allclose(mesh.area, _polygon_area(mesh.vertices[:, :2], "mixed"), rtol=1e-12)


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("count", ["B", "i", "H"])
def test_binary_ply_with_mixed_polygons_other_layouts(tmp_path, order, count):
    # both byte orders, wider list counts, extra vertex and face properties, RGBA colours:
    # the same arrays as the ASCII file of the same mesh
    colors = [[10 * i, 20, 30, 255 - i] for i in range(len(MIXED_V))]
    data = ply_binary_general(
        MIXED_V, MIXED_F, order=order, colors=colors, normals=True, face_tail=True, count=count
    )
    raw = read_mesh_arrays(write(tmp_path, "m.ply", data))
    ascii_raw = read_mesh_arrays(write(tmp_path, "a.ply", ply_ascii(MIXED_V, MIXED_F)))
    assert_array_equal(raw.faces, ascii_raw.faces)
    assert_allclose(raw.vertices, ascii_raw.vertices, rtol=0, atol=0)
    assert raw.vertex_colors.dtype == np.uint8
    assert_array_equal(raw.vertex_colors, colors)
    assert raw.notes == ascii_raw.notes


def test_binary_ply_with_mixed_polygons_cut_short_names_the_face(tmp_path):
    data = ply_binary(MIXED_V, [*MIXED_F, [1, 2, 3, 4], [0, 1, 2]])
    # long enough for four triangles (the size check), cut inside the last face
    p = write(tmp_path, "m.ply", data[:-5])
    with pytest.raises(errors.MeshFileError, match=r"truncated binary PLY.*ends in face 3 of 4"):
        load_mesh(p)


def test_binary_ply_with_mixed_polygons_and_a_two_corner_face(tmp_path):
    p = write(tmp_path, "m.ply", ply_binary(MIXED_V, [*MIXED_F, [1, 2]]))
    with pytest.raises(errors.MeshFileError, match="face 2 has 2 corners"):
        load_mesh(p)


def test_corrupt_binary_ply_is_reported_as_unreadable(tmp_path, capsys):
    # a face list whose count runs past the end of the file
    data = bytearray(ply_binary(MIXED_V, MIXED_F))
    data[-5 * 4 - 1] = 200  # the pentagon's corner count
    p = write(tmp_path, "m.ply", bytes(data))
    with pytest.raises(errors.MeshFileError, match="binary PLY"):
        load_mesh(p)
    rc, _out, err = run_info(capsys, str(p))
    assert rc == 2
    assert_one_error_line(err, "binary PLY")


def test_face_with_two_corners_is_an_error(tmp_path):
    p = write(tmp_path, "two.ply", ply_ascii(SQUARE_V, [[0, 1, 2], [1, 2]]))
    with pytest.raises(errors.MeshFileError, match="face 1 has 2 corners"):
        load_mesh(p)
    p = write(tmp_path, "two.obj", obj1(SQUARE_V, [[0, 1, 2], [1, 2]]))
    with pytest.raises(errors.MeshFileError, match="face 1 has 2 vertex indices"):
        load_mesh(p)


# -------------------------------------------------------------- truncated and unreadable
def _cut(data: bytes, marker: bytes, keep: int) -> bytes:
    """``data`` cut ``keep`` bytes into the first occurrence of ``marker``."""
    return data[: data.index(marker) + keep]


SQUARE_PLY = ply_ascii(SQUARE_V, SQUARE_F)
SQUARE_PLYB = ply_binary(SQUARE_V, SQUARE_F)
SQUARE_OFF = off(SQUARE_V, SQUARE_F)
SQUARE_STL = stl_binary(SQUARE_V, SQUARE_F)
TRUNCATED = {
    # ascii PLY cut in the middle of vertex 2 ("1 1 0"): two complete vertices
    "ply-mid-vertex": ("t.ply", _cut(SQUARE_PLY, b"1 1 0\n", 3), ("truncated PLY", "vertex 2")),
    # cut at a line boundary after vertex 1
    "ply-after-vertex": ("t.ply", _cut(SQUARE_PLY, b"1 1 0\n", 0), ("truncated PLY", "vertex 2")),
    # cut in the middle of face 1 ("3 0 2 3")
    "ply-mid-face": ("t.ply", _cut(SQUARE_PLY, b"3 0 2 3", 5), ("truncated PLY", "face 1")),
    "ply-no-faces-left": ("t.ply", _cut(SQUARE_PLY, b"3 0 1 2", 0), ("truncated PLY", "face 0")),
    "plyb-cut-short": ("t.ply", SQUARE_PLYB[:-5], ("truncated binary PLY",)),
    "plyb-header-only": (
        "t.ply",
        _cut(SQUARE_PLYB, b"end_header\n", 11),
        ("truncated binary PLY",),
    ),
    "ply-no-end-header": ("t.ply", SQUARE_PLY[:40], ("no end_header",)),
    "off-mid-vertex": ("t.off", _cut(SQUARE_OFF, b"1 1 0\n", 2), ("truncated OFF", "vertex 2")),
    "off-mid-face": ("t.off", _cut(SQUARE_OFF, b"3 0 2 3", 4), ("truncated OFF", "face 1")),
    "stl-cut-short": ("t.stl", SQUARE_STL[:-30], ("truncated or corrupt binary STL",)),
}


@pytest.mark.parametrize("key", list(TRUNCATED))
def test_truncated_file(tmp_path, capsys, key):
    name, data, names = TRUNCATED[key]
    p = write(tmp_path, name, data)
    with pytest.raises(errors.MeshFileError) as info:
        load_mesh(p)
    assert type(info.value) is errors.MeshFileError
    for n in names:
        assert n in str(info.value)
    rc, out, err = run_info(capsys, str(p))
    assert rc == 2
    assert out == ""
    assert_one_error_line(err, str(p), *names)


def _unreadable(tmp_path: Path, key: str) -> tuple[Path, str]:
    rng = np.random.default_rng(7)
    garbage = bytes(rng.integers(128, 256, size=400, dtype=np.uint8))  # never valid UTF-8
    if key == "garbage-ply":
        return write(tmp_path, "g.ply", garbage), "cannot read PLY"
    if key == "garbage-after-magic-ply":
        return write(tmp_path, "g.ply", b"ply\n" + garbage), "no end_header"
    if key == "garbage-obj":
        return write(tmp_path, "g.obj", garbage), "not text"
    if key == "garbage-off":
        return write(tmp_path, "g.off", garbage), "not text"
    if key == "garbage-stl":
        return write(tmp_path, "g.stl", garbage), "binary STL"
    if key == "not-off":
        return write(tmp_path, "g.off", b"hello\n1 2 3\n"), "does not start with OFF"
    if key == "directory":
        d = tmp_path / "adir.ply"
        d.mkdir()
        return d, "not a file"
    if key == "missing":
        return tmp_path / "missing.ply", "no such file"
    if key == "unsupported-suffix":
        return write(tmp_path, "m.xyz", b"0 0 0\n"), "unsupported format '.xyz'"
    if key == "no-suffix":
        return write(tmp_path, "mesh", SQUARE_PLY), "unsupported format '(no suffix)'"
    if key == "empty-file":
        return write(tmp_path, "e.ply", b""), "the file is empty"
    if key == "empty-obj":
        return write(tmp_path, "e.obj", b""), "the file is empty"
    raise AssertionError(key)


UNREADABLE = [
    "garbage-ply",
    "garbage-after-magic-ply",
    "garbage-obj",
    "garbage-off",
    "garbage-stl",
    "not-off",
    "directory",
    "missing",
    "unsupported-suffix",
    "no-suffix",
    "empty-file",
    "empty-obj",
]


@pytest.mark.parametrize("key", UNREADABLE)
def test_unreadable_file(tmp_path, capsys, key):
    p, phrase = _unreadable(tmp_path, key)
    with pytest.raises(errors.MeshFileError) as info:
        load_mesh(p)
    assert type(info.value) is errors.MeshFileError
    assert phrase in str(info.value)
    assert str(p) in str(info.value)
    rc, out, err = run_info(capsys, str(p))
    assert rc == 2
    assert out == ""
    assert_one_error_line(err, str(p), phrase)


@pytest.mark.parametrize("key", UNREADABLE)
def test_unreadable_file_with_repair(tmp_path, capsys, key):
    p, phrase = _unreadable(tmp_path, key)
    with pytest.raises(errors.MeshFileError, match=re.escape(phrase)):
        load_mesh(p, repair=True)
    rc, _out, err = run_info(capsys, str(p), "--repair")
    assert rc == 2
    assert_one_error_line(err, phrase)


# ----------------------------------------------------------------------- repair from files
@pytest.mark.parametrize("fmt", ["ply", "plyb", "obj", "off"])
def test_repairable_files_load_with_repair(tmp_path, capsys, fmt):
    for case in CASES:
        if not case.repairable:
            continue
        p = write(tmp_path, f"{case.name}{SUFFIX[fmt]}", WRITERS[fmt](case.vertices, case.faces))
        mesh = load_mesh(p, repair=True)
        assert mesh.repairs is not None
        assert mesh.repairs.fixed[0].kind == case.error.kind
        v_in = np.asarray(case.vertices, dtype=np.float64)
        f_in = np.asarray(case.faces)
        kept = np.flatnonzero(mesh.repairs.face_map >= 0)
        # every kept face names the same input vertices (through the copies of split ones)
        new = mesh.repairs.vertex_parent[mesh.faces[mesh.repairs.face_map[kept]]]
        mapped = f_in[kept].copy()
        flipped = np.isin(kept, mesh.repairs.flipped_faces)
        mapped[flipped] = mapped[flipped][:, ::-1]
        assert_array_equal(new, mapped)
        used = mesh.repairs.vertex_map >= 0
        assert_allclose(
            mesh.vertices[mesh.repairs.vertex_map[used]],
            v_in[used].astype(np.float32 if fmt == "plyb" else np.float64),
        )
        rc, out, err = run_info(capsys, str(p), "--repair")
        assert rc == 0, err
        assert err == ""
        assert "repaired: " in out


# ------------------------------------------------------------------------ save and reload
def test_save_mesh_round_trip_with_colors(tmp_path, spot):
    target = tmp_path / "out" / "spot copy.ply"
    target.parent.mkdir()
    assert save_mesh(spot, target) == target
    assert sorted(os.listdir(target.parent)) == ["spot copy.ply"]  # no temp file left
    back = load_mesh(target)
    assert_array_equal(back.faces, spot.faces)
    assert_allclose(back.vertices, spot.vertices, rtol=0, atol=0)
    assert back.vertex_colors is not None
    assert_array_equal(back.vertex_colors, spot.vertex_colors)


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".off", ".stl", ".glb", ".gltf"])
def test_save_mesh_formats_round_trip(tmp_path, suffix):
    mesh = real_mesh("spot")
    p = save_mesh(mesh, tmp_path / f"s{suffix}")
    assert [x.name for x in tmp_path.iterdir()] == [p.name]
    back = read_mesh_arrays(p)
    if suffix == ".stl":  # triangle soup: corner k of face f is vertex 3 f + k
        assert_allclose(
            back.vertices[back.faces], mesh.vertices[mesh.faces], atol=1e-6 * mesh.bbox_diagonal
        )
    else:
        assert_array_equal(back.faces, mesh.faces)
        assert_allclose(back.vertices, mesh.vertices, atol=1e-6 * mesh.bbox_diagonal)


def test_save_mesh_overwrites_atomically(tmp_path, spot, monkeypatch):
    target = tmp_path / "m.ply"
    target.write_bytes(b"old contents")

    def boom(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError, match="disk full"):
        save_mesh(spot, target)
    assert target.read_bytes() == b"old contents"  # the old file is untouched
    assert [x.name for x in tmp_path.iterdir()] == ["m.ply"]  # the temporary file is gone
    monkeypatch.undo()
    save_mesh(spot, target)
    assert load_mesh(target).n_faces == spot.n_faces


def test_save_mesh_unsupported_suffix(tmp_path, spot):
    with pytest.raises(errors.InputError, match="unsupported format"):
        save_mesh(spot, tmp_path / "m.xyz")
    assert list(tmp_path.iterdir()) == []


def test_real_ply_reads_exactly(spot):
    raw = read_mesh_arrays(mesh_path("spot"))
    assert raw.notes == []
    assert raw.vertices.dtype == np.float64
    assert raw.faces.dtype == np.int64
    assert raw.vertex_colors.dtype == np.uint8
    assert raw.vertex_colors.shape == (2930, 4)
    assert_array_equal(raw.faces, spot.faces)


def test_load_mesh_accepts_str_and_path():
    a = load_mesh(str(mesh_path("spot")))
    b = load_mesh(mesh_path("spot"))
    assert a.name == b.name == "spot.ply"
    assert_array_equal(a.faces, b.faces)


def test_mesh_from_file_arrays_equals_mesh(tmp_path):
    p = write(tmp_path, "sq.ply", ply_binary(SQUARE_V, SQUARE_F, colors=[[1, 2, 3]] * 4))
    mesh = load_mesh(p)
    assert isinstance(mesh, Mesh)
    assert_array_equal(mesh.vertex_colors[:, :3], [[1, 2, 3]] * 4)
    assert_array_equal(mesh.faces, SQUARE_F)


@pytest.mark.parametrize("suffix", [".glb", ".stl", ".off", ".obj", ".ply"])
def test_round_trip_keeps_connectivity(tmp_path, suffix):
    spot = real_mesh("spot")
    path = save_mesh(spot, tmp_path / f"spot{suffix}")
    back = load_mesh(path)
    assert back.n_faces == spot.n_faces
    assert back.n_vertices == spot.n_vertices  # STL corners are joined again
    assert back.genus == 0 and back.is_closed
    assert_allclose(back.area, spot.area, rtol=1e-6)


_PLY_HEAD = (
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
)


@pytest.mark.parametrize("index", ["1.5", "1e0", "1.0"])
def test_ascii_ply_face_indices_must_be_whole_numbers(tmp_path, index):
    """A fractional index is refused, never truncated into another mesh."""
    p = tmp_path / "f.ply"
    p.write_text(_PLY_HEAD + f"0 0 0\n1 0 0\n0 1 0\n3 0 {index} 2\n")
    with pytest.raises(
        errors.MeshFileError, match=rf"face 0: vertex index '{index}' is not a whole"
    ):
        read_mesh_arrays(p)
    # fractional coordinates are fine, whole indices too
    p.write_text(_PLY_HEAD + "0.5 0 0\n1 0 0e0\n0 1 0\n3 0 1 2\n")
    assert read_mesh_arrays(p).faces.tolist() == [[0, 1, 2]]


def test_a_truncated_binary_stl_whose_header_says_solid_is_not_empty(tmp_path):
    """A binary STL may start its 80-byte header with "solid"; cut short, it is a
    truncated file, not an empty ASCII one (a UTF-8 name keeps an ASCII STL text)."""
    tri = b"\x00" * 12 + struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + b"\x00\x00"
    p = tmp_path / "t.stl"
    p.write_bytes(b"solid made by a CAD tool".ljust(80, b" ") + struct.pack("<I", 10) + tri * 3)
    with pytest.raises(errors.MeshFileError, match="declares 10 triangles"):
        read_mesh_arrays(p)
    p.write_text("solid Würfel\nendsolid Würfel\n", encoding="utf-8")
    assert read_mesh_arrays(p).faces.shape == (0, 3)
