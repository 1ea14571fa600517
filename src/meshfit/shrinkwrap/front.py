"""The front door of shrink wrapping: :func:`wrap` (a path or a mesh in, options in one
frozen dataclass, :class:`WrapOptions`)."""

from __future__ import annotations

import os
from collections.abc import Callable

from meshfit.mesh import Mesh
from meshfit.shrinkwrap.wrap import WrapOptions, WrapResult, shrink_wrap

__all__ = ["WrapOptions", "wrap"]


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
    return shrink_wrap(mesh, options, levels=levels, progress=progress)
