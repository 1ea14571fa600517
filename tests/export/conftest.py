"""Fixtures of the export tests: a quick fit of the embedded demo input."""

from __future__ import annotations

import pytest

import meshfit
from meshfit.demo import demo_mesh
from meshfit.layout import cube_layout
from meshfit.pipeline import FitOptions


@pytest.fixture(scope="session")
def demo_fit():
    """Six patches of a box layout on the demo input, stitched (G1), with vector maps of
    matched texel counts: a closed network."""
    mesh = demo_mesh(4000)
    options = FitOptions(controls=(6, 6), spring_level=1, formats=(), report=False)
    return meshfit.fit(mesh, cube_layout(mesh, n=1), options=options)
