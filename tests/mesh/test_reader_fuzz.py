"""Damaged mesh files of every format raise only meshfit errors and allocate within a
budget in proportion to the file's size: random byte edits, cuts and splices of small
valid files, random bytes, and headers that claim billions of elements, read as the
command line reads them."""

from __future__ import annotations

import os
import struct
import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from meshfit.errors import MeshfitError
from meshfit.mesh import load_mesh, save_mesh

from ..fuzz import damaged, peak_within
from ..shapes import icosphere

FORMATS = (".ply", ".obj", ".off", ".stl", ".glb", ".gltf")
#: mutations of each format's file (a fixed-seed run: the same ones every time)
EXAMPLES = int(os.environ.get("MESHFIT_FUZZ_EXAMPLES", "400"))


def _read_within_budget(path) -> None:
    """Read ``path`` as the command line does; only a meshfit error may come out, and the
    traced peak stays within the budget for its size."""
    with peak_within(path.stat().st_size), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (a reader may warn; what is asked is no crash)
        try:
            load_mesh(path, repair=True)
        except MeshfitError:
            pass


@pytest.fixture(scope="module")
def valid(tmp_path_factory):
    folder = tmp_path_factory.mktemp("valid")
    mesh = icosphere(1)
    out = {}
    for suffix in FORMATS:
        path = folder / f"m{suffix}"
        save_mesh(mesh, path)
        out[suffix] = path.read_bytes()
    return out


@pytest.mark.parametrize("suffix", FORMATS)
def test_damaged_files_raise_only_meshfit_errors(valid, suffix, tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz")
    original = valid[suffix]

    @settings(
        max_examples=EXAMPLES,
        deadline=None,
        derandomize=True,
        suppress_health_check=list(HealthCheck),
    )
    @given(data=st.data())
    def run(data):
        path = folder / f"f{suffix}"
        path.write_bytes(damaged(data, original, span=300))
        _read_within_budget(path)

    run()


@pytest.mark.parametrize("suffix", FORMATS)
def test_random_bytes_raise_only_meshfit_errors(suffix, tmp_path_factory):
    folder = tmp_path_factory.mktemp("noise")

    @settings(max_examples=EXAMPLES // 4, deadline=None, derandomize=True)
    @given(raw=st.binary(max_size=4096))
    def run(raw):
        path = folder / f"f{suffix}"
        path.write_bytes(raw)
        _read_within_budget(path)

    run()


def _claims(valid) -> dict[str, tuple[str, bytes]]:
    """Small files whose headers claim billions of elements."""
    ply = valid[".ply"]
    head = b"ply\nformat ascii 1.0\nelement vertex 2000000000\nproperty float x\n"
    return {
        "binary PLY vertices": (".ply", ply.replace(b"vertex 42", b"vertex 2000000000")),
        "binary PLY faces": (".ply", ply.replace(b"face 80", b"face 2000000000")),
        "ASCII PLY": (".ply", head + b"end_header\n0\n"),
        "OFF": (".off", b"OFF\n2000000000 2000000000 0\n0 0 0\n"),
        "binary STL": (".stl", b"\0" * 80 + struct.pack("<I", 2**32 - 1) + b"\0" * 50),
    }


@pytest.mark.parametrize(
    "what", ["binary PLY vertices", "binary PLY faces", "ASCII PLY", "OFF", "binary STL"]
)
def test_a_header_claiming_billions_is_refused_without_allocating_them(valid, what, tmp_path):
    suffix, raw = _claims(valid)[what]
    path = tmp_path / f"claim{suffix}"
    path.write_bytes(raw)
    with pytest.raises(MeshfitError, match="truncated"):
        load_mesh(path, repair=True)
    _read_within_budget(path)


@pytest.mark.parametrize(
    "uri", ["/etc/passwd", "../secret.bin", "sub/../../x.bin", "file:///etc/passwd", "http://x/b"]
)
def test_a_gltf_reads_no_file_outside_its_folder(valid, uri, tmp_path):
    import json

    doc = json.loads(valid[".gltf"])
    doc["buffers"][0]["uri"] = uri
    path = tmp_path / "m.gltf"
    path.write_text(json.dumps(doc))
    with pytest.raises(MeshfitError, match="may refer only to data URIs"):
        load_mesh(path)


def test_a_glb_chunk_claiming_more_than_the_file_is_refused(valid, tmp_path):
    raw = bytearray(valid[".glb"])
    raw[12:16] = struct.pack("<I", 2**31)  # the JSON chunk's length
    path = tmp_path / "m.glb"
    path.write_bytes(bytes(raw))
    with pytest.raises(MeshfitError, match="chunk at byte 12 declares 2147483648 bytes"):
        load_mesh(path)
    _read_within_budget(path)
