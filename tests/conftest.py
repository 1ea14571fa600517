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
