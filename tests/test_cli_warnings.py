"""Warnings raised inside a command are one line each on stderr, once, after it."""

from __future__ import annotations

import argparse
import warnings

from meshfit import cli


def _parser_with(fn):
    p = argparse.ArgumentParser()
    p.set_defaults(func=fn)
    return p


def test_warnings_are_one_line_each_once(monkeypatch, capsys):
    import numpy as np

    def noisy(args):
        for _ in range(3):
            np.log(np.zeros(2))  # RuntimeWarning: divide by zero, three times
        warnings.warn("an old option", DeprecationWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(cli, "build_parser", lambda: _parser_with(noisy))
    assert cli.main([]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "meshfit: warning: RuntimeWarning: divide by zero encountered in log (3 times)",
        "meshfit: warning: DeprecationWarning: an old option",
    ]


def test_warnings_beside_an_error_are_lines_of_their_own(monkeypatch, capsys):
    from meshfit.errors import InputError

    def failing(args):
        warnings.warn("careful", UserWarning, stacklevel=1)
        raise InputError("bad input")

    monkeypatch.setattr(cli, "build_parser", lambda: _parser_with(failing))
    assert cli.main([]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "meshfit: error: bad input",
        "meshfit: warning: UserWarning: careful",
    ]
