"""Wraps shared by the shrink-wrap tests: each real mesh is mapped and wrapped once."""

from __future__ import annotations

from functools import cache

from meshfit.shrinkwrap import shrink_wrap, sphere_map

from ..conftest import real_mesh


@cache
def smap(name: str):
    return sphere_map(real_mesh(name))


@cache
def wrap(name: str, levels: int):
    return shrink_wrap(real_mesh(name), levels=levels, smap=smap(name))
