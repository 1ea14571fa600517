"""Every option is checked before any work or any file: values that would fail deep in a
stage (a spring level that exhausts the memory, a seed the random generator refuses) are
refused when the options are made, and the command line writes nothing."""

from __future__ import annotations

import shutil

import pytest

from meshfit.cli import main
from meshfit.errors import InputError
from meshfit.layout.auto import MAX_SEED, LayoutOptions
from meshfit.pipeline import FitOptions
from meshfit.springs import SpringOptions
from meshfit.springs.resample import check_spring_options

from .conftest import mesh_path


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(spring_level=-1), "non-negative integer"),
        (dict(spring_level=99), "ask for level 10 or less"),
        (dict(spring_max_points=-5), "max_points must be an integer >= 4"),
        (dict(layout_seed=10**12), f"at most {MAX_SEED}"),
    ],
)
def test_fit_options_refuse_values_the_stages_cannot_take(kw, match):
    with pytest.raises(InputError, match=match):
        FitOptions(**kw)


def test_the_bounds_are_the_last_values_that_work():
    FitOptions(spring_level=10, layout_seed=MAX_SEED)
    check_spring_options(SpringOptions(level=99, max_points=1000))  # capped by max_points
    with pytest.raises(InputError):
        LayoutOptions(seed=MAX_SEED + 1)


@pytest.mark.parametrize(
    "extra", [["--level", "-1"], ["--level", "99"], ["--layout-seed", "1000000000000"]]
)
def test_the_command_line_writes_nothing_for_a_bad_option(tmp_path, extra, capsys):
    mesh = tmp_path / "s.ply"
    shutil.copyfile(mesh_path("spot"), mesh)
    assert main(["fit", str(mesh), "--out", str(tmp_path / "out"), *extra]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert [p.name for p in tmp_path.iterdir()] == ["s.ply"]


def test_a_control_class_the_layout_has_not_is_refused_before_the_spring_meshes(tmp_path):
    """The classes follow from the layout's network alone: a chosen class beyond them is
    refused as soon as the layout is made, before any spring mesh or file (it was
    refused after all of them)."""
    from meshfit.pipeline import fit

    from .shapes import icosphere

    out = tmp_path / "fit"
    options = FitOptions(class_controls={999: 8}, formats=(), report=False)
    with pytest.raises(InputError, match="class 999 does not exist"):
        fit(icosphere(3), options=options, out=out)
    assert not out.exists()  # nothing written, not even the folders it made


def test_a_refused_fit_keeps_the_folders_that_were_there(tmp_path):
    from meshfit.pipeline import fit

    from .shapes import icosphere

    out = tmp_path / "fit"
    out.mkdir()
    options = FitOptions(class_controls={999: 8}, formats=(), report=False)
    with pytest.raises(InputError):
        fit(icosphere(3), options=options, out=out)
    assert out.is_dir() and not any(out.iterdir())
