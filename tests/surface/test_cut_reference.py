"""The cut against its slow oracle (tests/reference/cut.py) on real layouts: identical
vertices, faces, parents, vertex sources and paths."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from meshfit.layout import load_layout
from meshfit.layout.cube import cube_layout
from meshfit.surface.cut import cut_mesh, cut_mesh_network
from tests.conftest import real_mesh
from tests.reference import cut as reference

LAYOUTS = Path(__file__).resolve().parents[2] / "examples" / "layouts"


@cache
def _layout(name: str):
    if name == "igea-cube":
        mesh = real_mesh("igea")
        return mesh, cube_layout(mesh, n=2)
    mesh = real_mesh(name)
    return mesh, load_layout(LAYOUTS / f"{name}.json", mesh, check_topology=False)


def _same_mesh(got, want):
    np.testing.assert_array_equal(got.vertices, want.vertices)
    np.testing.assert_array_equal(got.faces, want.faces)
    if want.vertex_colors is None:
        assert got.vertex_colors is None
    else:
        np.testing.assert_array_equal(got.vertex_colors, want.vertex_colors)


def _same_sources(got, want):
    np.testing.assert_array_equal(got.face, want.face)
    np.testing.assert_array_equal(got.bary, want.bary)


@pytest.mark.parametrize("split", [True, False])
@pytest.mark.parametrize("name", ["spot", "igea", "nefertiti", "igea-cube"])
def test_network_cut_matches_oracle(name, split):
    mesh, layout = _layout(name)
    args = (mesh, list(layout.curves), layout.corners, layout.curve_ends)
    got = cut_mesh_network(*args, split=split)
    want = reference.cut_mesh_network(*args, split=split)
    _same_mesh(got.mesh, want.mesh)
    assert len(got.curve_vertices) == len(want.curve_vertices)
    for a, b in zip(got.curve_vertices, want.curve_vertices, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(got.corners, want.corners)
    np.testing.assert_array_equal(got.copy_of, want.copy_of)
    np.testing.assert_array_equal(got.face_parent, want.face_parent)
    np.testing.assert_array_equal(got.vertex_parent, want.vertex_parent)
    _same_sources(got.vertex_source, want.vertex_source)


@pytest.mark.parametrize("k", [0, 7])
@pytest.mark.parametrize("name", ["spot", "nefertiti"])
def test_single_curve_cut_matches_oracle(name, k):
    mesh, layout = _layout(name)
    curve = layout.curves[k].points
    for split in (True, False):
        got = cut_mesh(mesh, curve, split=split)
        want = reference.cut_mesh(mesh, curve, split=split)
        _same_mesh(got.mesh, want.mesh)
        np.testing.assert_array_equal(got.path, want.path)
        np.testing.assert_array_equal(got.path_other_side, want.path_other_side)
        np.testing.assert_array_equal(got.face_parent, want.face_parent)
        np.testing.assert_array_equal(got.vertex_parent, want.vertex_parent)
        _same_sources(got.vertex_source, want.vertex_source)
        assert not got.closed
