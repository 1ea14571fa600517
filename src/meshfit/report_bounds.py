"""Bounds on a fit's figures, and the reason a value beyond one matters.

The report prints every figure of a fit; those beyond these bounds are marked and listed
with the reason, so that an alarming value (a seam whose normals turn by 179 degrees) is
not read past as one more number. The bounds are what a sound fit stays within by a wide
margin; crossing one says where to look, not that the fit failed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from meshfit import tol

__all__ = ["BOUNDS", "Bound", "Flag", "beyond_bounds"]


@dataclass(frozen=True)
class Bound:
    """A figure's bound: the summary ``section`` (``seams``, ``errors.displaced``,
    ``patches``), its ``key``, the largest (or with ``below``, the smallest) sound value,
    the reason a value beyond it matters, and for seam figures whether it applies only to
    G1 seams (continuity G1, or auto: G1 but at creases)."""

    section: str
    key: str
    limit: float
    reason: str
    below: bool = False
    g1_only: bool = False

    def beyond(self, value: Any) -> bool:
        if isinstance(value, list):
            return any(self.beyond(v) for v in value)
        if not isinstance(value, int | float) or isinstance(value, bool):
            return False
        return value < self.limit if self.below else value > self.limit


#: normal jump (degrees) past which the two sides of a seam face apart: a flipped or
#: folded patch, not a rough seam
OPPOSED_NORMALS_DEG = 90.0
#: normal jump (degrees) past which a G1 seam shows as a crease
G1_CREASE_DEG = 5.0

BOUNDS: tuple[Bound, ...] = (
    Bound("seams", "spline_normal_jump_max_deg", OPPOSED_NORMALS_DEG,
          "the normals on the two sides of a seam face apart: a patch is flipped or folded "
          "there"),
    Bound("seams", "spline_normal_jump_max_deg", G1_CREASE_DEG,
          "G1 continuity was asked: a normal jump this large shows as a crease",
          g1_only=True),
    Bound("seams", "spline_normal_jump_inner_max_deg", 1.0,
          "away from the corners G1 stitching makes the normals agree; this seam was not "
          "made smooth", g1_only=True),
    Bound("seams", "crease_normal_jump_max_deg", OPPOSED_NORMALS_DEG,
          "the two sides of a crease face apart: a patch is flipped or folded there"),
    Bound("seams", "spline_gap_max", tol.STITCH_GAP,
          "stitching closes shared boundaries: a gap is a crack in the spline surface"),
    Bound("seams", "displaced_gap_max", tol.STITCH_GAP,
          "a crack between displaced patches (the maps disagree along a seam)"),
    Bound("seams", "displaced_gap_any_resolution_max", tol.STITCH_GAP,
          "a crack between displaced patches at some map resolution"),
    Bound("errors.displaced", "hausdorff", 0.01,
          "part of the scan lies more than 1% of the diagonal from the displaced surface: "
          "a detail the fit misses"),
    Bound("errors.displaced", "rms", 0.002,
          "the displaced surface is off the scan all over, not at a few points"),
    Bound("patches", "folded", 0,
          "folded spring-grid cells: the grid crosses itself and the fit there is unreliable"),
    Bound("patches", "aspect_max", 8.0,
          "grid cells this stretched sample the scan coarsely across their long side"),
    Bound("patches", "input_distance_max", 0.01,
          "scan points more than 1% of the diagonal from this patch's displaced surface"),
    Bound("patches", "corner_angles", 20.0,
          "a corner this sharp squeezes the grid cells next to it", below=True),
    Bound("patches", "corner_angles", 160.0,
          "a corner this flat is hardly a corner: the grid bends along the side there"),
)  # fmt: skip


@dataclass(frozen=True)
class Flag:
    """A value beyond a bound: where (``section``, ``row`` for patches, else None, and
    ``key``), the value and the reason."""

    section: str
    row: int | None
    key: str
    value: Any
    reason: str


def _get(summary: dict[str, Any], section: str) -> Any:
    out: Any = summary
    for part in section.split("."):
        out = out.get(part) if isinstance(out, dict) else None
    return out


def beyond_bounds(summary: dict[str, Any]) -> list[Flag]:
    """The values of a fit summary beyond :data:`BOUNDS`, each with its reason (the first
    bound a value crosses, in the order of :data:`BOUNDS`)."""
    flags: list[Flag] = []
    seen: set[tuple[str, int | None, str]] = set()
    # "auto" makes every seam but the creases G1 (crease seams have figures of their own)
    g1 = str(_get(summary, "seams.continuity") or "").upper() in ("G1", "AUTO")
    for b in BOUNDS:
        if b.g1_only and not g1:
            continue
        section = _get(summary, b.section)
        rows = list(enumerate(section)) if isinstance(section, list) else [(None, section)]
        for i, row in rows:
            if not isinstance(row, dict) or b.key not in row:
                continue
            at = (b.section, None if i is None else int(row.get("patch", i)), b.key)
            if at not in seen and b.beyond(row[b.key]):
                seen.add(at)
                flags.append(Flag(b.section, at[1], b.key, row[b.key], b.reason))
    return flags
