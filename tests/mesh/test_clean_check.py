"""The fast clean-mesh test (validate.clean_edge_table, kernels simple_ok / manifold_ok)
against its slow reference, find_problems: clean exactly when there is no finding, and the
edge table the constructor caches equal to the one built afresh."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from meshfit import tol
from meshfit.mesh import Mesh, find_problems, load_mesh, topology
from meshfit.mesh.validate import clean_edge_table

from .. import shapes
from ..conftest import mesh_path
from .test_validate import damaged_spheres, small_meshes


def _agrees(v, f) -> bool:
    """True when the fast test and find_problems agree (clean <=> no finding)."""
    v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
    return (clean_edge_table(v, f) is not None) == (find_problems(v, f) == [])


def _pinched_cones():
    ring = np.array([[np.cos(t), np.sin(t), 0.0] for t in np.linspace(0, 2 * np.pi, 6)[:-1]])
    up = np.array([0.0, 0.0, 1.0])
    v = np.vstack([[[0, 0, 0]], ring + up, ring - up])
    f = [[0, 1 + i, 1 + (i + 1) % 5] for i in range(5)]
    f += [[0, 6 + (i + 1) % 5, 6 + i] for i in range(5)]
    return v, np.array(f)


def _fan_and_closed_fan():
    # a closed cone and an open fan sharing their apex: one fan closes, the other does not
    v, f = _pinched_cones()
    return v, f[:9]


CASES = {
    "square": (
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float),
        np.array([[0, 1, 2], [0, 2, 3]]),
    ),
    "bow_tie": (
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 1, 0], [2, 2, 0]], dtype=float),
        np.array([[0, 1, 2], [2, 3, 4]]),
    ),
    "pinched_cones": _pinched_cones(),
    "closed_and_open_fan": _fan_and_closed_fan(),
    "back_to_back_pair": (
        np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float),
        np.array([[0, 1, 2], [0, 2, 1]]),
    ),
    "fin": (
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], dtype=float),
        np.array([[0, 1, 2], [0, 2, 3], [0, 2, 4]]),
    ),
    "flipped_face": (np.array(shapes.icosphere(1).vertices), shapes.icosphere(1).faces[::-1]),
    "torus": (shapes.torus().vertices, shapes.torus().faces),
    "plane": (shapes.plane().vertices, shapes.plane().faces),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_named_meshes_agree_with_find_problems(name):
    v, f = CASES[name]
    assert _agrees(v, f)


def test_non_manifold_vertices_are_not_clean():
    for name in ("bow_tie", "pinched_cones", "closed_and_open_fan"):
        v, f = CASES[name]
        assert clean_edge_table(v, f) is None
        assert [x.kind for x in find_problems(v, f)] == ["non_manifold_vertex"]


def test_area_near_the_limit_is_left_to_find_problems():
    # a sliver (0, 4, 3) with |cross| = eps just above the degenerate limit: find_problems
    # passes it, the fast test leaves it to find_problems (within its margin)
    diag = np.sqrt(2.0)
    eps = 2.0 * tol.DEGENERATE_AREA * diag * diag * (1.0 + 1e-7)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [eps, 0, 0]], dtype=float)
    f = np.array([[0, 4, 3], [4, 1, 3], [0, 3, 2]])
    assert find_problems(v, f) == []
    assert clean_edge_table(v, f) is None
    v[4, 0] = 2.0 * eps  # well clear of the limit: the fast test says clean
    assert clean_edge_table(v, f) is not None


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(small_meshes(), damaged_spheres()))
def test_random_meshes_agree_with_find_problems(mesh):
    v, f = mesh
    assert _agrees(v, f)


@pytest.mark.parametrize("name", ["igea", "spot", "nefertiti"])
def test_real_scans_cache_the_edge_table(name):
    # loaded afresh: the cached real_mesh may have had its caches dropped by a fit that ran
    # before this test in the same worker
    mesh = load_mesh(mesh_path(name))
    assert "_edge_table" in mesh.__dict__  # set by the constructor's check
    fresh = topology.edge_table(mesh.faces, mesh.n_vertices)
    for field in fields(fresh):
        assert_array_equal(getattr(mesh._edge_table, field.name), getattr(fresh, field.name))
    assert find_problems(mesh.vertices, mesh.faces) == []


def test_a_mesh_with_a_problem_still_raises_its_first_finding():
    v, f = CASES["bow_tie"]
    with pytest.raises(Exception, match="vertex 2"):
        Mesh(v, f)
