"""What a fit keeps in memory: the mesh's derived arrays go when asked, and nothing of a
fit's patch meshes outlives the fit."""

from __future__ import annotations

import gc
import os

import numpy as np
from numpy.testing import assert_array_equal

import meshfit
from meshfit.mesh import Mesh
from meshfit.pipeline import FitOptions

from . import shapes


def _alive_meshes() -> int:
    gc.collect()
    return sum(type(o) is Mesh for o in gc.get_objects())  # (no call on a dead weak proxy)


def test_drop_caches_forgets_derived_arrays_and_derives_them_again():
    mesh = shapes.torus(24, 12)
    before = {
        "edges": np.array(mesh.edges),
        "face_neighbors": np.array(mesh.face_neighbors),
        "vertex_normals": np.array(mesh.vertex_normals),
        "order": np.array(mesh.triangle_tree.order),
    }
    tree = mesh.triangle_tree
    mesh.drop_caches(keep=("triangle_tree",))
    assert "face_neighbors" not in vars(mesh) and "_edge_table" not in vars(mesh)
    assert mesh.triangle_tree is tree  # kept as asked
    assert_array_equal(mesh.edges, before["edges"])
    assert_array_equal(mesh.face_neighbors, before["face_neighbors"])
    assert_array_equal(mesh.vertex_normals, before["vertex_normals"])
    mesh.drop_caches()
    assert "triangle_tree" not in vars(mesh)
    assert_array_equal(mesh.triangle_tree.order, before["order"])


def test_a_fit_lets_go_of_its_patch_meshes():
    # the patch submeshes (together as large as the scan, with their adjacency and square
    # maps) are dropped once the spring meshes exist; none may be kept by a module's cache
    mesh = shapes.icosphere(4)
    n0 = _alive_meshes()
    res = meshfit.fit(mesh, options=FitOptions(report=False))
    assert res.summary["patches_total"] > 0
    assert _alive_meshes() <= n0


def test_the_fit_drops_the_meshs_adjacency_after_the_spring_meshes():
    mesh = shapes.torus()
    meshfit.fit(mesh, options=FitOptions(report=False))
    kept = set(vars(mesh)) - {"vertices", "faces", "vertex_colors", "name", "repairs"}
    assert "_edge_table" not in kept and "face_neighbors" not in kept, sorted(kept)


def test_a_fit_stays_within_its_memory_bound(tmp_path):
    # the command's peak over its whole life (imports and loading included) stays within
    # 1 GiB + 0.5 GiB per million input triangles; before the fit let go of the layout's
    # adjacency and its patch meshes, this scan's fit peaked at 1.75 GiB against 1.14
    import json
    import subprocess
    import sys

    from .conftest import mesh_path

    run = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from meshfit.cli import main; sys.exit(main(sys.argv[1:]))",
            "fit",
            str(mesh_path("igea")),
            "--out",
            str(tmp_path / "fit"),
            "--formats",
            "obj",
            "--no-report",
            "--json",
        ],
        capture_output=True,
        text=True,
        env={**os.environ, "MESHFIT_COMPILE_AHEAD": "0"},
        timeout=1800,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    summary = json.loads(run.stdout)
    bound = 2**30 + 0.5 * 2**30 * summary["mesh"]["faces"] / 1e6
    peak = summary["memory"]["peak_rss_total"]
    assert peak <= bound, f"{peak / 2**30:.2f} GiB > {bound / 2**30:.2f} GiB"
