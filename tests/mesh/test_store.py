"""The bricked, memory-mapped mesh store (meshfit.mesh.store)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshfit.errors import InputError, MeshFileError
from meshfit.mesh import Mesh, load_mesh, save_mesh
from meshfit.mesh.store import MORTON_BITS, open_store, write_store

from ..conftest import real_mesh
from ..reference.decimate import face_cells
from ..shapes import torus
from .test_io import ply_ascii, ply_binary, ply_binary_general


def _cells(store) -> np.ndarray:
    """Each stored face's Morton cell, as the store computed it."""
    lo, hi = store.bbox
    V, F = np.asarray(store.vertices), np.asarray(store.faces)
    return face_cells(V, F, lo, (1 << MORTON_BITS) / (hi - lo), MORTON_BITS)


def _same(a, b) -> None:
    for name in ("vertices", "faces", "input_face", "brick_start"):
        np.testing.assert_array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name)))


def test_a_binary_ply_is_read_in_place_and_bricked(tmp_path):
    mesh = real_mesh("spot")
    path = tmp_path / "spot.ply"
    save_mesh(mesh, path)
    want = load_mesh(path)
    store = write_store(path, tmp_path / "store", brick_faces=900, chunk_faces=1000)
    assert json.loads((tmp_path / "store" / "store.json").read_text())["read"] == "memory-mapped"
    # nothing lost or changed: the stored faces are the input's, in another order
    np.testing.assert_array_equal(store.vertices, want.vertices)
    assert sorted(store.input_face.tolist()) == list(range(want.n_faces))
    np.testing.assert_array_equal(store.faces, want.faces[store.input_face])
    assert store.n_bricks >= want.n_faces // 900 - 1
    # each brick is one run of Morton cells, the bricks in order along the curve
    code = _cells(store)
    for b in range(store.n_bricks):
        a, e = store.brick_start[b], store.brick_start[b + 1]
        np.testing.assert_array_equal(store.brick(b), store.faces[a:e])
        if b + 1 < store.n_bricks:
            assert code[a:e].max() < code[e : store.brick_start[b + 2]].min()
    # and about brick_faces faces (a brick is whole cells: one cell's faces over)
    most = np.bincount(code).max()
    assert np.diff(store.brick_start).max() <= 900 + most
    # the arrays are mapped from the files, read-only
    assert isinstance(store.faces, np.memmap) and not store.faces.flags.writeable


def test_every_source_gives_the_same_store(tmp_path):
    mesh = torus()
    path = tmp_path / "t.ply"
    save_mesh(mesh, path)
    arrays = load_mesh(path)  # (the file's float32 coordinates)
    stores = [
        write_store(path, tmp_path / "a", brick_faces=700, chunk_faces=333),
        write_store(arrays, tmp_path / "b", brick_faces=700),
        write_store((arrays.vertices, arrays.faces), tmp_path / "c", brick_faces=700),
    ]
    for s in stores[1:]:
        _same(stores[0], s)
    # a file of another format is read whole: the store holds what load_mesh reads
    obj = tmp_path / "t.obj"
    save_mesh(arrays, obj)
    _same(write_store(obj, tmp_path / "d", brick_faces=700),
          write_store(load_mesh(obj), tmp_path / "e", brick_faces=700))  # fmt: skip


@pytest.mark.parametrize("order", ["<", ">"])
def test_other_binary_layouts_are_read_in_place(tmp_path, order):
    mesh = torus(12, 8)
    path = tmp_path / "t.ply"
    path.write_bytes(
        ply_binary_general(mesh.vertices, mesh.faces, order=order, normals=True, face_tail=True)
    )
    store = write_store(path, tmp_path / "s", brick_faces=50)
    assert json.loads((tmp_path / "s" / "store.json").read_text())["read"] == "memory-mapped"
    np.testing.assert_array_equal(store.vertices, mesh.vertices)
    np.testing.assert_array_equal(store.faces, mesh.faces[store.input_face])


def test_polygons_are_read_whole_and_triangulated(tmp_path):
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]]
    path = tmp_path / "q.ply"
    path.write_bytes(ply_binary_general(v, [[1, 4, 2], [0, 1, 2, 3]]))
    store = write_store(path, tmp_path / "s")
    assert json.loads((tmp_path / "s" / "store.json").read_text())["read"] == "read whole"
    assert store.n_faces == 3


def test_faces_repeating_a_vertex_are_dropped_and_counted(tmp_path):
    v = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    path = tmp_path / "d.ply"
    path.write_bytes(ply_binary(v, [[0, 1, 2], [1, 1, 2], [1, 3, 2], [3, 3, 3]]))
    store = write_store(path, tmp_path / "s")
    assert store.n_faces == 2 and store.dropped_faces == 2
    assert sorted(store.input_face.tolist()) == [0, 2]


def test_bad_files_name_the_vertex_or_face(tmp_path):
    v = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    path = tmp_path / "i.ply"
    path.write_bytes(ply_binary(v, [[0, 1, 2], [0, 2, 7]]))
    with pytest.raises(MeshFileError, match="face 1 refers to vertex 7"):
        write_store(path, tmp_path / "s")
    assert not (tmp_path / "s").exists() and list(tmp_path.iterdir()) == [path]
    path.write_bytes(ply_ascii([[0, 0, 0], [1, float("nan"), 0], [0, 1, 0]], [[0, 1, 2]]))
    with pytest.raises(MeshFileError, match="vertex 1 has a coordinate that is not finite"):
        write_store(path, tmp_path / "s")
    cut = ply_binary(v, [[0, 1, 2]] * 40)
    path.write_bytes(cut[:-30])
    with pytest.raises(MeshFileError, match="truncated"):
        write_store(path, tmp_path / "s")


def test_the_store_folder_must_be_new_and_not_the_input(tmp_path):
    mesh = torus(12, 8)
    path = tmp_path / "t.ply"
    save_mesh(mesh, path)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("keep")
    with pytest.raises(InputError, match="not an empty folder"):
        write_store(path, tmp_path / "full")
    assert (tmp_path / "full" / "x").read_text() == "keep"
    with pytest.raises(InputError, match="exists and is not an empty folder"):
        write_store(path, path)
    (tmp_path / "empty").mkdir()
    assert write_store(path, tmp_path / "empty").n_faces == mesh.n_faces


def test_a_damaged_store_is_refused(tmp_path):
    mesh = torus(12, 8)
    write_store(mesh, tmp_path / "s")
    meta_path = tmp_path / "s" / "store.json"
    meta = json.loads(meta_path.read_text())
    with pytest.raises(InputError, match="not a mesh store"):
        open_store(tmp_path)
    meta_path.write_text(json.dumps({**meta, "version": 99}))
    with pytest.raises(InputError, match="store version 99"):
        open_store(tmp_path / "s")
    meta_path.write_text(json.dumps({**meta, "n_faces": meta["n_faces"] + 1}))
    with pytest.raises(InputError, match=r"faces\.npy"):
        open_store(tmp_path / "s")
    meta_path.write_text(json.dumps(meta))
    np.save(tmp_path / "s" / "brick_start.npy", np.array([0, 5, 3, meta["n_faces"]]))
    meta_path.write_text(json.dumps({**meta, "n_bricks": 3}))
    with pytest.raises(InputError, match="not the starts"):
        open_store(tmp_path / "s")


def test_bricks_follow_the_shape_not_its_placement():
    # moved and scaled, the bounding box moves with the mesh: the same cells, bricks and
    # face order
    mesh = torus()
    a = write_store_tmp(mesh)
    b = write_store_tmp(Mesh(mesh.vertices * 8.0 + [1e3, -2e3, 5.0], mesh.faces))
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.brick_start, b.brick_start)


def write_store_tmp(mesh):
    import tempfile
    from pathlib import Path

    folder = Path(tempfile.mkdtemp()) / "s"
    return write_store(mesh, folder, brick_faces=500)
