"""Damaged mesh files of every format raise only meshfit errors: random byte edits, cuts
and splices of small valid files, read as the command line reads them."""

from __future__ import annotations

import os
import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from meshfit.errors import MeshfitError
from meshfit.mesh import load_mesh, save_mesh

from ..shapes import icosphere

FORMATS = (".ply", ".obj", ".off", ".stl", ".glb")
#: mutations of each format's file (a fixed-seed run: the same ones every time)
EXAMPLES = int(os.environ.get("MESHFIT_FUZZ_EXAMPLES", "400"))


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
        raw = bytearray(original)
        for _ in range(data.draw(st.integers(1, 6))):
            i = data.draw(st.integers(0, max(len(raw) - 1, 0)))
            op = data.draw(st.sampled_from(["set", "cut", "dup", "digits"]))
            if op == "set" and raw:
                raw[i] = data.draw(st.integers(0, 255))
            elif op == "cut":
                del raw[i : i + data.draw(st.integers(1, 300))]
            elif op == "dup":
                raw[i:i] = raw[i : i + data.draw(st.integers(1, 300))]
            else:
                raw[i:i] = data.draw(st.sampled_from([b"9" * 30, b"-1", b"nan", b"1e308", b"\n"]))
        path = folder / f"f{suffix}"
        path.write_bytes(bytes(raw))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # (a reader may warn; what is asked is no crash)
            try:
                load_mesh(path, repair=True)
            except MeshfitError:
                pass

    run()
