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

from ..fuzz import damaged
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
        path = folder / f"f{suffix}"
        path.write_bytes(damaged(data, original, span=300))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # (a reader may warn; what is asked is no crash)
            try:
                load_mesh(path, repair=True)
            except MeshfitError:
                pass

    run()
