"""File access of the app: allowed paths only, uploads capped and validated."""

from __future__ import annotations

import os

import pytest

from meshfit.errors import InputError, MeshfitError
from meshfit.ui.files import FilePolicy, mesh_from_upload
from tests.conftest import mesh_path


def test_paths_inside_the_workdir_are_allowed(tmp_path):
    pol = FilePolicy(tmp_path)
    (tmp_path / "a.json").write_text("{}")
    assert pol.check("a.json", suffixes=(".json",)) == (tmp_path / "a.json").resolve()
    sub = tmp_path / "sub"
    sub.mkdir()
    assert pol.check("sub/new.json", suffixes=(".json",), write=True).parent == sub.resolve()


def test_paths_outside_are_refused(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    outside = tmp_path / "secret.json"
    outside.write_text("{}")
    pol = FilePolicy(work)
    with pytest.raises(InputError, match="outside the allowed folder"):
        pol.check(str(outside), suffixes=(".json",))
    with pytest.raises(InputError, match="outside the allowed folder"):
        pol.check("../secret.json", suffixes=(".json",))
    with pytest.raises(InputError, match="outside the allowed folder"):
        pol.check("/etc/passwd.json", suffixes=(".json",), write=True)
    # a symbolic link inside the folder pointing out of it is outside too
    os.symlink(outside, work / "link.json")
    with pytest.raises(InputError, match="outside the allowed folder"):
        pol.check("link.json", suffixes=(".json",))
    # ... unless the user named the file on the command line
    pol.allow(outside)
    assert pol.check(str(outside), suffixes=(".json",)) == outside.resolve()


def test_suffix_and_missing_files(tmp_path):
    pol = FilePolicy(tmp_path)
    (tmp_path / "x.txt").write_text("")
    with pytest.raises(InputError, match=r"only \.json"):
        pol.check("x.txt", suffixes=(".json",))
    with pytest.raises(InputError, match="no such file"):
        pol.check("missing.json", suffixes=(".json",))
    with pytest.raises(InputError, match="does not exist"):
        pol.check("nofolder/x.json", suffixes=(".json",), write=True)
    with pytest.raises(InputError, match="no file name"):
        pol.check("  ", suffixes=(".json",))
    with pytest.raises(InputError, match="outside"):
        pol.check_folder("../exports")
    assert pol.check_folder("exports").is_dir()


def test_upload_of_a_valid_mesh():
    data = mesh_path("spot").read_bytes()
    mesh = mesh_from_upload("C:\\models\\spot.ply", data)
    assert mesh.name == "spot.ply" and mesh.n_faces == 5856 and mesh.vertex_colors is not None


def test_upload_size_cap():
    data = mesh_path("spot").read_bytes()
    with pytest.raises(InputError, match="the limit is 1,000 bytes"):
        mesh_from_upload("spot.ply", data, max_bytes=1000)


@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("a.ply", b"", "empty"),
        ("a.pkl", b"\x80\x04K\x01.", r"only \.ply"),
        ("a.gltf", b"{}", r"only \.ply"),
        ("a.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n", None),
        ("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", None),
        ("a.stl", bytes(range(256)) + b"solid", None),
    ],
)
def test_malformed_uploads_are_refused(name, content, match):
    with pytest.raises(MeshfitError, match=match):
        mesh_from_upload(name, content)
