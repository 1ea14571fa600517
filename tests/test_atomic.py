"""Atomic writes: all or nothing, ordinary permissions."""

from __future__ import annotations

import os
import stat

import pytest

from meshfit._atomic import atomic_write, write_bytes, write_text


def test_new_file_gets_ordinary_permissions(tmp_path):
    mask = os.umask(0o022)
    try:
        p = write_text(tmp_path / "out.json", "{}")
    finally:
        os.umask(mask)
    assert p.read_text() == "{}"
    assert stat.S_IMODE(p.stat().st_mode) == 0o644


def test_failure_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    p = write_bytes(tmp_path / "a.bin", b"old")

    def broken(tmp):
        with open(tmp, "wb") as fh:
            fh.write(b"half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(p, broken)
    assert p.read_bytes() == b"old"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.bin"]


def test_writer_sees_the_target_suffix(tmp_path):
    seen = []
    atomic_write(tmp_path / "m.ply", lambda tmp: (seen.append(tmp), open(tmp, "w").close()))
    assert seen[0].endswith(".ply") and os.path.dirname(seen[0]) == str(tmp_path)
