"""The stage runner: content keys follow what a stage reads, resumed runs load, contracts hold."""

from __future__ import annotations

import json
from dataclasses import dataclass

import pytest

from meshfit.pipeline.runner import Context, Runner, Stage


@dataclass(frozen=True)
class _Opts:
    a: int = 1
    b: int = 2


class _Double(Stage):
    name = "double"
    inputs = ("x",)
    outputs = ("y",)
    suffix = ".json"
    runs = 0

    def group(self, ctx):
        return ctx.options  # reads the whole group

    def run(self, ctx):
        type(self).runs += 1
        ctx["y"] = 2 * ctx["x"] + ctx.options.a

    def save(self, ctx, path):
        path.write_text(json.dumps(ctx["y"]))

    def load(self, ctx, path):
        ctx["y"] = json.loads(path.read_text())
        return True


class _Then(_Double):
    name = "then"
    inputs = ("y",)
    outputs = ("z",)
    after = ("double",)

    def group(self, ctx):
        return None

    def run(self, ctx):
        type(self).runs += 1
        ctx["z"] = ctx["y"] + 1

    def save(self, ctx, path):
        path.write_text(json.dumps(ctx["z"]))

    def load(self, ctx, path):
        ctx["z"] = json.loads(path.read_text())
        return True


def _ctx(x=3, **opts):
    ctx = Context(_Opts(**opts), workers=1)
    ctx["x"] = x
    return ctx


def test_keys_follow_options_and_earlier_keys():
    a = Runner().run([_Double(), _Then()], _ctx())
    b = Runner().run([_Double(), _Then()], _ctx(a=5))
    assert a.keys["double"] != b.keys["double"]
    assert a.keys["then"] != b.keys["then"]  # through the earlier key only
    assert b["z"] == 2 * 3 + 5 + 1


def test_resume_loads_saved_stages(tmp_path):
    _Double.runs = _Then.runs = 0
    first = Runner(tmp_path, resume=False).run([_Double(), _Then()], _ctx())
    assert (_Double.runs, _Then.runs) == (1, 1)
    again = Runner(tmp_path, resume=True).run([_Double(), _Then()], _ctx())
    assert (_Double.runs, _Then.runs) == (1, 1)
    assert again["z"] == first["z"]
    assert all(i["cached"] for i in again.info.values())
    # another option: the first stage and, through its key, the second run again
    Runner(tmp_path, resume=True).run([_Double(), _Then()], _ctx(b=7))
    assert (_Double.runs, _Then.runs) == (2, 2)
    assert len(list(tmp_path.glob("double-*.json"))) == 2


def test_contracts_are_checked():
    class Forgetful(_Double):
        def run(self, ctx):
            pass

    with pytest.raises(RuntimeError, match="outputs"):
        Runner().run([Forgetful()], _ctx())

    class Early(_Then):
        after = ()

    with pytest.raises(RuntimeError, match="inputs"):
        Runner().run([Early()], _ctx())


def test_a_background_stage_error_reaches_the_caller():
    class Boom(_Double):
        background = True

        def run(self, ctx):
            raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        Runner().run([Boom(), _Then.__base__()], _ctx())


def test_lazy_values_are_made_once_and_only_when_read():
    ctx = _ctx()
    made = []
    ctx.lazy("w", lambda: made.append(1) or 42)
    assert "w" in ctx and made == []
    assert ctx["w"] == 42 and ctx["w"] == 42
    assert made == [1]


@pytest.mark.parametrize("damage", ["{not json", "", '{"y": 1}'])
def test_a_damaged_cache_is_made_again(tmp_path, damage):
    """A stage file that cannot be read (truncated, edited, of another shape) counts as
    missing: the stage runs again and writes it anew; the result is the same."""
    _Double.runs = _Then.runs = 0
    first = Runner(tmp_path, resume=False).run([_Double(), _Then()], _ctx())
    (cache,) = tmp_path.glob("double-*.json")
    cache.write_text(damage)

    class _Strict(_Double):
        def load(self, ctx, path):
            value = json.loads(path.read_text())
            ctx["y"] = value + 0  # (a dict read where a number was written: TypeError)
            return True

    again = Runner(tmp_path, resume=True).run([_Strict(), _Then()], _ctx())
    assert again["z"] == first["z"]
    assert not again.info["double"]["cached"]
    assert json.loads(cache.read_text()) == first["y"]
