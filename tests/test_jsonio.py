"""The one reader of project files: bounded nesting and integers, no NaN, one clear error
for anything damaged or hostile (layouts, sessions, fit files, manifests)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from meshfit._jsonio import MAX_DEPTH, read_json, read_json_file
from meshfit.errors import InputError, LayoutError, MeshfitError
from meshfit.layout import layout_from_json, layout_to_json
from meshfit.layout.cube import cube_layout

from .fuzz import damaged, peak_within
from .shapes import icosphere


@pytest.fixture(scope="module")
def layout_text() -> str:
    return layout_to_json(cube_layout(icosphere(2), frame=np.eye(3)))


@pytest.mark.parametrize(
    "text, what",
    [
        ("[" * 100_000 + "]" * 100_000, "nested 100000 levels"),
        ('{"a": ' * (MAX_DEPTH + 1) + "1" + "}" * (MAX_DEPTH + 1), "levels deep"),
        ('{"i": ' + "9" * 5000 + "}", "an integer of 5000 digits"),
        ('{"i": 18446744073709551616}', "outside the 64-bit range"),
        ('{"x": NaN}', "NaN is not a number"),
        ('{"x": -Infinity}', "-Infinity is not a number"),
        ('{"x": [1, 2', "malformed JSON at line 1"),
        (b"\xff\xfe{}", "not UTF-8"),
    ],
)
def test_hostile_json_is_one_clear_error(text, what):
    import tracemalloc

    tracemalloc.start()
    try:
        with pytest.raises(InputError, match=what) as exc:
            read_json(text, source="f.json")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # (a refusal costs a few copies of the text, not a parse tree: 100,000 brackets took
    # the parser into a RecursionError before)
    assert peak < 16 * len(text) + (1 << 20)
    assert str(exc.value).startswith("f.json: ")


def test_what_json_allows_is_read_as_json_reads_it():
    doc = {"s": "[[[{{{ not nesting", "n": [-(2**63), 2**63 - 1, 1.5e300], "d": [[[[1]]]]}
    assert read_json(json.dumps(doc), source="f") == doc


def test_a_file_above_the_size_bound_is_refused_unread(tmp_path):
    p = tmp_path / "big.json"
    p.write_text("[" + "0," * 1000 + "0]")
    with pytest.raises(InputError, match="more than the 100 a project file may have"):
        read_json_file(p, max_bytes=100)
    assert len(read_json_file(p)) == 1001


def test_layout_files_with_hostile_json_raise_layout_errors(layout_text):
    for bad in ("[" * 100_000, '{"meshfit_layout": ' + "1" * 5000 + "}"):
        with pytest.raises(LayoutError):
            layout_from_json(bad)
    doc = json.loads(layout_text)
    doc["curves"][0]["face"][0] = 2**64
    with pytest.raises(LayoutError, match="64-bit"):
        layout_from_json(json.dumps(doc))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_mutated_layout_files_raise_only_meshfit_errors(layout_text, data):
    """Random byte edits, cuts and splices of a valid layout file: it parses or raises a
    MeshfitError, nothing else."""
    raw = damaged(data, layout_text.encode(), edits=8, span=64)
    with peak_within(len(raw)):
        try:
            layout_from_json(raw.decode("utf-8", "replace"))
        except MeshfitError:
            pass


@settings(max_examples=100, deadline=None)
@given(raw=st.binary(max_size=4096))
def test_random_bytes_as_a_layout_file_raise_only_meshfit_errors(raw):
    with peak_within(len(raw)), pytest.raises(MeshfitError):
        layout_from_json(raw.decode("utf-8", "replace"))
