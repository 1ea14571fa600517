"""Shared fixtures: the real scans in ../shared/data/meshes and analytic shapes.

The data folder is found from ``MESHFIT_DATA`` or, by default, ``../shared/data`` beside the
repository. A missing folder is an error, not a skip.
"""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from meshfit.mesh import Mesh, load_mesh

from . import shapes

ROOT = Path(__file__).resolve().parents[1]


#: modules that run one after another on one worker, never beside each other: chromium and
#: the app's servers, Dask LocalClusters, a subprocess's peak memory, signals to a subprocess
EXCLUSIVE = (
    "tests/ui/test_browser.py",
    "tests/ui/test_browser_fit.py",
    "tests/test_report.py",
    "tests/test_cluster.py",
    "tests/test_batch.py",
    "tests/test_memory.py",
    "tests/test_cli_signals.py",
)

#: long tests that share nothing with the rest of their module, each run apart from it (by
#: test id, parameters included, or by function), and tests that share a session fixture
#: (one group: the fixture is made once, on one worker)
APART = {
    "tests/test_outputs.py::test_the_bunny_obj_is_watertight_but_for_its_holes": "bunny-fit",
    "tests/layout/test_regions.py::test_bunny_is_laid_out_as_it_is": "bunny-fit",
    "tests/layout/test_regions.py::test_scans_of_any_topology_fit_with_no_options": None,
    "tests/layout/test_regions.py::test_rigid_motions_and_scalings_give_the_same_fit": None,
    "tests/layout/test_auto.py::test_split_base_meshes_have_their_degrees_balanced": None,
    "tests/layout/test_auto.py::test_a_protrusion_a_quad_would_hold_goes_to_the_region_route": None,
    "tests/layout/test_even.py::test_a_cad_programs_own_tessellation_fits_through_the_remesh": None,
    "tests/test_pipeline.py::test_nefertiti_fits_to_the_targets_from_the_bust_layout": None,
}


def xdist_group(nodeid: str) -> str:
    """The worker group of a test under ``--dist loadgroup`` (``-n 2`` in the test
    configuration): its module, so that a module's tests run on one worker in file order as
    in a run without workers (module fixtures made once, tests that build on an earlier
    one's state keep it); `EXCLUSIVE` modules together; `APART` tests on their own or in
    the group named there."""
    module = nodeid.split("::")[0]
    for key in (nodeid, nodeid.split("[")[0]):
        if key in APART:
            return APART[key] or nodeid
    return "exclusive" if module in EXCLUSIVE else module


def pytest_xdist_make_scheduler(config, log):
    """``--dist loadgroup`` by `xdist_group`, which names the groups from the test ids: with
    pytest 9 an ``xdist_group`` mark no longer reaches the scheduler (pytest-xdist 3.8
    rewrites a test's id in a way pytest 9 ignores)."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class GroupScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return xdist_group(nodeid)

    return GroupScheduling(config, log)


def pytest_sessionstart(session):
    """As a first command-line run does, a second process compiles the kernels a fit calls
    ahead of need (:mod:`meshfit._compile_ahead`): the suite's first run after an install
    compiles on two cores."""
    from meshfit._compile_ahead import start

    start()


def data_dir() -> Path:
    candidates = [
        os.environ.get("MESHFIT_DATA"),
        ROOT.parent / "shared" / "data",
        Path("/work/shared/data"),
    ]
    for c in candidates:
        if c and (Path(c) / "meshes").is_dir():
            return Path(c)
    raise RuntimeError("test data not found: set MESHFIT_DATA to the folder holding meshes/")


def mesh_path(name: str) -> Path:
    return data_dir() / "meshes" / f"{name}.ply"


#: real scans, loaded with repair where they need it (bunny: unreferenced vertices;
#: nefertiti_fraunhofer: back-to-back faces)
REAL = ("spot", "bunny", "nefertiti", "nefertiti_fraunhofer", "igea")
NEEDS_REPAIR = {"bunny", "nefertiti_fraunhofer"}
CLOSED_REAL = ("spot", "nefertiti", "igea")
OPEN_REAL = ("bunny", "nefertiti_fraunhofer")


@cache
def real_mesh(name: str) -> Mesh:
    return load_mesh(mesh_path(name), repair=name in NEEDS_REPAIR)


@cache
def analytic_mesh(name: str) -> Mesh:
    return {
        "icosphere": lambda: shapes.icosphere(3),
        "plane": lambda: shapes.plane(20),
        "cylinder": shapes.cylinder,
        "torus": shapes.torus,
    }[name]()


def any_mesh(name: str) -> Mesh:
    return real_mesh(name) if name in REAL else analytic_mesh(name)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def spot() -> Mesh:
    return real_mesh("spot")


@pytest.fixture(scope="session")
def bunny() -> Mesh:
    return real_mesh("bunny")


@pytest.fixture(scope="session")
def igea() -> Mesh:
    return real_mesh("igea")


@pytest.fixture(scope="session")
def bunny_fit(tmp_path_factory):
    """The one-call fit of bunny with the command line's defaults (OBJ only): made once for
    the OBJ test (tests/test_outputs.py) and the layout test (tests/layout/test_regions.py),
    which reads its automatic layout (group ``bunny-fit`` keeps both on one worker)."""
    from meshfit.pipeline import FitOptions, fit

    mesh = load_mesh(mesh_path("bunny"), repair=True)  # open, with unreferenced vertices
    out = tmp_path_factory.mktemp("bunny_fit")
    result = fit(mesh, options=FitOptions(formats=("obj",), report=False), out=out)
    return mesh, result, out
