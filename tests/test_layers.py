"""Import layers: kernels import no package code, no stage imports a later stage, and the
command lines and the web app are leaves (nothing imports them).

Every ``import`` in the package is read with ``ast`` (at any depth, so imports inside
functions count; those under ``if TYPE_CHECKING:`` are types only and do not).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

#: the package's parts, low to high (``../shared/DESIGN.md``, "Layout"): a module may import
#: its own part and lower ones. The automatic layout uses the shrink wrap's sphere maps, and
#: the fit writes the report, so those two sit below their users.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("_kernels",),
    ("errors", "_words", "_unionfind", "_atomic", "_malloc", "_threads", "types", "tol"),
    ("_validate", "mesh"),
    ("surface",),
    ("curves",),
    ("shrinkwrap",),
    ("layout",),
    ("springs",),
    ("bspline",),
    ("displacement",),
    ("stitch",),
    ("export", "render"),
    ("report",),
    ("pipeline",),
    ("batch", "demo", "_progress"),
    ("meshfit",),  # the front door: names from the parts above
)
#: the leaves: command lines and the web app (``meshfit.<part>.cli`` too)
LEAVES = ("cli", "fit_cli", "_cliargs", "ui")


def _modules(src: Path = SRC) -> dict[str, Path]:
    out = {}
    for p in (src / "meshfit").rglob("*.py"):
        parts = list(p.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def part(module: str) -> str:
    """The part of the package a module belongs to (``meshfit.layout.cli`` is a CLI)."""
    bits = module.split(".")
    if len(bits) == 1:
        return "meshfit"
    if bits[-1] == "cli" or bits[1] in LEAVES:
        return "cli"
    return bits[1]


def _type_only(node: ast.AST, parents: dict) -> bool:
    while node in parents:
        node = parents[node]
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            return True
    return False


def imports(modules: dict[str, Path]) -> list[tuple[str, str, int]]:
    """``(importer, imported, line)`` for every import of a package module."""
    out = []
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        parents = {c: n for n in ast.walk(tree) for c in ast.iter_child_nodes(n)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [
                    f"{node.module}.{a.name}"
                    if f"{node.module}.{a.name}" in modules
                    else node.module
                    for a in node.names
                ]
            else:
                continue
            if _type_only(node, parents):
                continue
            out += [(name, t, node.lineno) for t in targets if t.split(".")[0] == "meshfit"]
    return out


def violations(edges: list[tuple[str, str, int]]) -> list[str]:
    rank = {p: k for k, layer in enumerate(LAYERS) for p in layer}
    bad = []
    for a, b, line in edges:
        pa, pb = part(a), part(b)
        if pa == pb:
            continue
        if pb == "cli":
            bad.append(f"{a}:{line} imports the leaf {b}")
        elif pa == "_kernels":
            bad.append(f"{a}:{line}: a kernel imports {b}")
        elif pb == "meshfit":
            continue  # the package root itself (``__version__``; its own imports are low)
        elif pa != "cli" and rank.get(pb, -1) > rank.get(pa, -1):
            bad.append(f"{a}:{line} ({pa}) imports the later {b} ({pb})")
    return bad


def test_every_part_has_a_layer():
    parts = {part(m) for m in _modules()} - {"cli"}
    placed = {p for layer in LAYERS for p in layer}
    assert parts <= placed, parts - placed


def test_no_part_imports_a_later_one_and_the_leaves_are_leaves():
    assert violations(imports(_modules())) == []


@pytest.mark.parametrize(
    ("importer", "imported", "why"),
    [
        ("meshfit._kernels.walk", "meshfit.mesh", "kernel"),
        ("meshfit.mesh.core", "meshfit.layout.auto", "later"),
        ("meshfit.demo", "meshfit.fit_cli", "leaf"),
        ("meshfit.pipeline.run", "meshfit.ui.app", "leaf"),
    ],
)
def test_the_check_catches_each_kind_of_violation(importer, imported, why):
    bad = violations([(importer, imported, 1)])
    assert len(bad) == 1
    assert {"kernel": "a kernel", "later": "the later", "leaf": "the leaf"}[why] in bad[0]


def test_imports_under_type_checking_do_not_count(tmp_path):
    pkg = tmp_path / "meshfit"
    (pkg / "mesh").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "mesh" / "__init__.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from meshfit.layout import Layout\n"
        "def f():\n    from meshfit.stitch import Network\n"
    )
    edges = imports(_modules(tmp_path))
    assert [(a, b) for a, b, _ in edges] == [("meshfit.mesh", "meshfit.stitch")]
