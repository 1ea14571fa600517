"""Slow, obviously-correct oracle of `meshfit._kernels.textio`: Python's own formatting."""

from __future__ import annotations

import numpy as np


def face_lines(cols: np.ndarray) -> bytes:
    """The OBJ face lines of ``cols (k, 6)``, as ``str.format`` writes them."""
    fmt = "f {0}/{3}/{0} {1}/{4}/{1} {2}/{5}/{2}\n"
    return "".join(fmt.format(*row) for row in np.asarray(cols).tolist()).encode("ascii")
