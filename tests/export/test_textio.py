"""The OBJ face-line kernel against the slow oracle of `tests/reference/textio.py` (Python's
own formatting): the same bytes for any indices, and the writer's face lines with it."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from meshfit._kernels.textio import face_lines

from ..reference import textio as ref


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    rows=st.integers(0, 300),
    scale=st.sampled_from([1, 9, 10, 11, 99, 100, 10**6, 2**53, 2**63 - 1]),
)
def test_face_lines_are_pythons_text(seed, rows, scale):
    rng = np.random.default_rng(seed)
    cols = rng.integers(-scale, scale, (rows, 6), endpoint=True, dtype=np.int64)
    assert face_lines(cols).tobytes() == ref.face_lines(cols)


def test_face_lines_at_digit_boundaries():
    edges = [0, 1, 9, 10, 99, 100, 999, 1000, -1, -9, -10, 2**63 - 1, -(2**63 - 1)]
    cols = np.array(edges + edges[:5], dtype=np.int64).reshape(-1, 6)
    assert face_lines(cols).tobytes() == ref.face_lines(cols)
