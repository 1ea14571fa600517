"""The front door of shrink wrapping: :func:`wrap` with its options as one frozen dataclass."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import asdict, dataclass

from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.shrinkwrap.wrap import WrapResult, shrink_wrap

__all__ = ["WrapOptions", "wrap"]


@dataclass(frozen=True)
class WrapOptions:
    """Options of :func:`wrap`; each is the keyword of :func:`meshfit.shrinkwrap.shrink_wrap`
    with the same name, whose docstring gives its meaning and default."""

    base_faces: int = 100
    sphere_method: str = "tutte"
    sphere_max_aspect: float | None = None
    sphere_stretch: int = 0
    parameter_iterations: int = 6
    surface_iterations: int = 4
    alpha: float = 0.5
    count_weight: float = 3.0
    min_cell_faces: float = 2.0
    switch_tightness: float = 0.1
    switch_min_angle_deg: float = 10.0
    min_switch_level: int = 2
    clean_min_angle_deg: float = 10.0
    clean_rounds: int = 20

    def __post_init__(self) -> None:
        if self.sphere_method not in ("tutte", "voxel"):
            raise InputError(
                f"sphere_method must be 'tutte' or 'voxel', got {self.sphere_method!r}"
            )
        if int(self.base_faces) < 4:
            raise InputError(f"base_faces must be at least 4, got {self.base_faces}")
        if not 0.0 < float(self.alpha) <= 1.0:
            raise InputError(f"alpha must be in (0, 1], got {self.alpha}")


def wrap(
    mesh: Mesh | str | os.PathLike,
    *,
    levels: int = 5,
    options: WrapOptions | None = None,
    progress: Callable[[str, float], None] | None = None,
) -> WrapResult:
    """Remesh a closed genus-0 mesh with subdivision connectivity by shrink wrapping.

    Parameters
    ----------
    mesh : Mesh or path
        A path is loaded with :func:`meshfit.load_mesh` (harmless defects repaired).
    levels : int, keyword-only
        Refinement levels above the base mesh (default 5).
    options : WrapOptions, keyword-only, optional
    progress : callable(stage, fraction), keyword-only, optional

    Returns
    -------
    WrapResult
        The base mesh and every level ``M0 .. Mm``.

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999.
    """
    if not isinstance(mesh, Mesh):
        from meshfit.mesh import load_mesh

        mesh = load_mesh(mesh, repair=True)
    opts = asdict(options or WrapOptions())
    return shrink_wrap(mesh, levels=levels, progress=progress, **opts)
