"""STEP export: needs the optional extra ``meshfit[cad]`` (cadquery-ocp)."""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Sequence

from meshfit.bspline import BSplineSurface
from meshfit.errors import ExportError

__all__ = ["export_step", "step_available"]


def step_available() -> bool:
    """Whether OpenCASCADE (``OCP``, from cadquery-ocp) can be imported."""
    return importlib.util.find_spec("OCP") is not None


def export_step(
    path: str | os.PathLike, surfaces: BSplineSurface | Sequence[BSplineSurface]
) -> None:
    """Write the patches as STEP B-spline surfaces (not built yet).

    Raises
    ------
    ExportError
        Always for now: without ``OCP`` it names the extra to install; with it, it says the
        writer is not implemented (it has not been testable on the machines without OCP).
    """
    if not step_available():
        raise ExportError(
            "STEP export needs OpenCASCADE: pip install 'meshfit[cad]' (cadquery-ocp)"
        )
    raise ExportError("STEP export is not implemented yet")
