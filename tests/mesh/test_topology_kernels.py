"""Boundary-loop tracing against its slow reference: real scans cut open, random half-edge
sets with pinches and dead ends."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from meshfit._kernels import topology as kernel
from meshfit.mesh import topology

from ..conftest import real_mesh
from ..reference import topology as ref


def _same(got, want):
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def _kernel_loops(t, h):
    out, starts = kernel.trace_loops(t, h, int(max(t.max(), h.max())) + 1)
    return [out[a:b] for a, b in itertools.pairwise(starts)]


@pytest.mark.parametrize("name", ["spot", "bunny"])
def test_loops_of_real_meshes_with_holes(name, rng):
    mesh = real_mesh(name)
    # punch holes: drop random faces (some sharing vertices: pinched boundaries)
    faces = mesh.faces[rng.random(mesh.n_faces) > 0.02]
    table = topology.edge_table(faces, mesh.n_vertices)
    loops = topology.boundary_loops(faces, table)
    assert len(loops) > 10
    bnd = np.flatnonzero(table.edge_count == 1)
    he = table.order[table.start[bnd]]
    tail, head = topology.halfedges(faces)
    _same(loops, ref.trace_loops(tail[he], head[he]))


def test_random_half_edge_sets(rng):
    for _ in range(50):
        k = int(rng.integers(1, 40))
        t = rng.integers(0, 12, k)
        h = rng.integers(0, 12, k)
        _same(_kernel_loops(t, h), ref.trace_loops(t, h))
