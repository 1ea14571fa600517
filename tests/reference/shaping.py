"""Slow, obviously-correct quad shape and cost of `meshfit.layout.shaping`, one quad at a time."""

from __future__ import annotations

import math


def _sub(a, b):
    return [a[k] - b[k] for k in range(3)]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _norm(a):
    return math.sqrt(sum(x * x for x in a))


def quad_shape(q) -> float:
    """Mean over the corners of (|e1|^2 + |e2|^2) / (2 |e1 x e2|), e1 to the next corner and
    e2 to the previous one."""
    total = 0.0
    for i in range(4):
        e1 = _sub(q[(i + 1) % 4], q[i])
        e2 = _sub(q[(i - 1) % 4], q[i])
        total += (_norm(e1) ** 2 + _norm(e2) ** 2) / (2.0 * _norm(_cross(e1, e2)))
    return total / 4.0


def quad_area(q) -> float:
    """Half the cross product of the diagonals."""
    return 0.5 * _norm(_cross(_sub(q[2], q[0]), _sub(q[3], q[1])))


def triangle_cost(quads, mean_area: float, area_weight: float) -> float:
    """Summed ``shape - 1 + area_weight * log(area / mean_area)^2`` of a triangle's quads."""
    return sum(
        quad_shape(q) - 1.0 + area_weight * math.log(quad_area(q) / mean_area) ** 2 for q in quads
    )
