"""No command writes over a file it reads: the output is compared with every input before
any work, by file identity (any spelling of the path, links)."""

from __future__ import annotations

import argparse
import os
import shutil

import pytest

from meshfit._cliargs import refuse_own_input
from meshfit.cli import main
from meshfit.errors import InputError

from .conftest import mesh_path


@pytest.fixture
def files(tmp_path):
    mesh = tmp_path / "s.ply"
    shutil.copyfile(mesh_path("spot"), mesh)
    layout = tmp_path / "L.json"
    layout.write_text('{"format": "meshfit_layout", "version": 1}')
    stream = tmp_path / "s.mfsw"
    stream.write_bytes(b"MFSW not a stream")
    return tmp_path, mesh, layout, stream


def _argv(tmp, mesh, layout, stream, out):
    return {
        "layout": ["layout", str(mesh), str(layout), "--smooth", "2", "--out", str(out)],
        "springs": ["springs", str(mesh), "--layout", str(layout), "--out", str(out)],
        "wrap": ["wrap", str(mesh), "--levels", "2", "--out", str(out)],
        "encode": ["stream", "encode", str(mesh), "--levels", "2", "-o", str(out)],
        "decode": ["stream", "decode", str(stream), "-o", str(out)],
        "fit": ["fit", str(mesh), "--out", str(out)],
    }


@pytest.mark.parametrize("command", ["layout", "springs", "wrap", "encode", "decode", "fit"])
@pytest.mark.parametrize("spelling", ["same", "dotted", "link"])
def test_an_output_that_is_an_input_is_refused(files, command, spelling, capsys):
    tmp, mesh, layout, stream = files
    target = stream if command == "decode" else mesh
    out = {
        "same": target,
        "dotted": tmp / "sub" / ".." / target.name,
        "link": tmp / "link",
    }[spelling]
    (tmp / "sub").mkdir()
    if spelling == "link":
        os.symlink(target, out)
    before = {p: p.read_bytes() for p in (mesh, layout, stream)}
    rc = main(_argv(tmp, mesh, layout, stream, out)[command])
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith("meshfit: error: the output") and "is the input" in err
    assert err.count("\n") == 1
    assert {p: p.read_bytes() for p in before} == before
    # nothing else was written next to the input
    assert sorted(p.name for p in tmp.iterdir()) == sorted(
        ["s.ply", "L.json", "s.mfsw", "sub", *(["link"] if spelling == "link" else [])]
    )


def test_other_outputs_pass_the_check(files):
    tmp, mesh, layout, _ = files
    args = argparse.Namespace(
        mesh=str(mesh),
        layout=str(layout),
        out=str(tmp / "L2.json"),
        _inputs=("mesh", "layout"),
        _outputs=("out",),
    )
    refuse_own_input(args)  # a new file beside the inputs
    args.out = str(layout)
    with pytest.raises(InputError, match=r"L\.json"):
        refuse_own_input(args)
    # a value that names no file (a layout of "auto") is no input
    args.layout, args.out = "auto", "auto"
    refuse_own_input(args)
