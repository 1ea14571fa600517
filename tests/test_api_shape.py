"""The shape of the public API: no public function or method takes more than `MAX_KEYWORDS`
keyword parameters (keyword-only ones plus positional ones with defaults) or more than
`MAX_PARAMETERS` parameters in all (``self`` and ``cls`` not counted).

Settings that travel together are a frozen options object (``SpringOptions``,
``LayoutOptions``, ``SnakeOptions``, ``Camera``, ...): one value that can be shared, stored
in a cache key and validated once. The compiled kernels (``meshfit._kernels``) are exempt:
numba functions take arrays and scalars, not objects. Private names (``_x``) are exempt too;
functions nested in others are checked like any other.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "meshfit"
MAX_KEYWORDS = 8
MAX_PARAMETERS = 10


def _counts(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> tuple[int, int]:
    a = fn.args
    keywords = len(a.kwonlyargs) + len(a.defaults)
    total = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs)
    if a.args and a.args[0].arg in ("self", "cls"):
        total -= 1
    return keywords, total


def _public_functions():
    for path in sorted(SRC.rglob("*.py")):
        if "_kernels" in path.relative_to(SRC).parts:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                if not node.name.startswith("_"):
                    yield f"{path.relative_to(SRC)}:{node.lineno} {node.name}", node


def test_the_scan_sees_the_package():
    names = {name.split()[-1] for name, _ in _public_functions()}
    assert {"fit", "load_fit", "auto_layout", "relax_snake", "render", "shrink_wrap"} <= names


def test_no_public_function_takes_too_many_parameters():
    over = []
    for name, fn in _public_functions():
        keywords, total = _counts(fn)
        if keywords > MAX_KEYWORDS or total > MAX_PARAMETERS:
            over.append(f"{name}: {keywords} keywords, {total} parameters")
    assert not over, "\n".join(over)


@pytest.mark.parametrize(
    ("source", "want"),
    [
        ("def f(a, b=1, *, c, d=2): pass", (3, 4)),
        ("def f(self, a, *, b=1): pass", (1, 2)),
        ("def f(a, /, b, c=1): pass", (1, 3)),
    ],
)
def test_the_counts_follow_the_signature(source, want):
    assert _counts(ast.parse(source).body[0]) == want
