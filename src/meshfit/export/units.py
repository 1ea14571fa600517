"""Length units the exporters declare: one table for USD, Rhino ``.3dm``, IGES and STEP.

A fit's coordinates are in the input mesh's units, which a mesh file does not record. Every
exporter takes ``units`` (default ``"mm"``), writes the coordinates unchanged and declares
the unit in the file's own way, so a viewer or CAD system shows the model at its real size.
"""

from __future__ import annotations

from dataclasses import dataclass

from meshfit.errors import InputError

__all__ = ["UNITS", "Unit", "unit"]


@dataclass(frozen=True)
class Unit:
    """One length unit and its name in each file format.

    Attributes
    ----------
    name : str
        The name the exporters take (``"mm"``).
    meters : float
        Metres per unit (USD ``metersPerUnit``).
    iges_flag : int
        IGES Global parameter 14 (unit flag).
    iges_name : str
        IGES Global parameter 15 (unit name).
    step_name : str
        OpenCASCADE's name for the unit (``write.step.unit``).
    rhino_name : str
        The member of ``rhino3dm.UnitSystem``.
    """

    name: str
    meters: float
    iges_flag: int
    iges_name: str
    step_name: str
    rhino_name: str


#: the units every exporter declares, by name (IGES 5.3 sec. 2.2.4.3, ISO 10303-41 units)
UNITS: dict[str, Unit] = {
    u.name: u
    for u in (
        Unit("mm", 1e-3, 2, "MM", "MM", "Millimeters"),
        Unit("cm", 1e-2, 10, "CM", "CM", "Centimeters"),
        Unit("m", 1.0, 6, "M", "M", "Meters"),
        Unit("in", 0.0254, 1, "IN", "INCH", "Inches"),
        Unit("ft", 0.3048, 4, "FT", "FT", "Feet"),
    )
}


def unit(name: str) -> Unit:
    """The :class:`Unit` called ``name`` (any case: ``"MM"`` is ``"mm"``).

    Raises
    ------
    InputError
        When ``name`` is not in :data:`UNITS` (the message lists them).
    """
    key = name.lower() if isinstance(name, str) else name
    if key not in UNITS:
        raise InputError(f"units must be one of {tuple(UNITS)}, got {name!r}")
    return UNITS[key]
