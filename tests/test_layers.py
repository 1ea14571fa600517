"""Import layers of the package (``../shared/DESIGN.md``, "Layout").

Three rules, checked on every ``import`` in ``src/meshfit`` as read by ``ast`` (at any depth,
so the imports inside functions count):

a. a kernel (``meshfit._kernels``) imports nothing from the package but other kernels;
b. no part imports a later part (`LAYERS`, low to high);
c. the command lines and the web app (`leaf`) are leaves: nothing else imports them.

An import under ``if TYPE_CHECKING:`` loads nothing at run time, and a low helper may name in
its annotations the type it receives (``tol.length(mesh: Mesh)``): such imports are exempt
from rule b only. Imports by name at run time (``importlib.import_module``: the root's lazy
front-door names, the subcommand registry of ``meshfit.cli``) are not seen; both sit at the
top already.

A violation that cannot be fixed at once goes in `KNOWN` with its reason: it becomes a strict
xfail case of its own (`test_known_violation_is_gone`), so every other edge stays enforced and
a fixed one fails until it is taken off the list. The list is empty now.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

#: the package's parts, low to high: a module may import modules of its own part and of
#: lower ones. A part is the name after ``meshfit.`` (``meshfit.layout.auto``: ``layout``);
#: the command lines and the web app are the part ``leaves`` (see `leaf`); ``meshfit`` is the
#: package's root, the front door (``meshfit.fit``, ``meshfit.wrap``).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("_kernels",),
    # private helpers and the shared vocabulary
    (
        "errors",
        "types",
        "tol",
        "_validate",
        "_words",
        "_unionfind",
        "_atomic",
        "_malloc",
        "_jsonio",
    ),
    ("_version",),
    ("_threads", "_progress", "_cliargs", "_cliout"),
    ("mesh",),
    ("surface",),
    ("curves",),
    # the automatic layout starts from the shrink wrap's sphere map and base mesh, and the
    # shrink wrap itself needs only the mesh: it sits below the layout
    ("shrinkwrap",),
    ("layout",),
    ("springs",),
    ("bspline",),
    ("displacement",),
    ("stitch",),
    # the HTML report is one of the fit's outputs (DESIGN.md lists it with the exports);
    # report_blender is the script the report runs in Blender's Python (it imports no meshfit)
    ("export", "report", "report_bounds", "report_view", "render", "report_blender"),
    ("pipeline",),
    ("batch", "demo"),
    # the front door, and the second process that compiles a first run's kernels ahead of
    # need (it records them from the front door's runs)
    ("meshfit", "_compile_ahead"),
    ("leaves",),
)

#: violations not fixed yet: (importer, imported) -> why
KNOWN: dict[tuple[str, str], str] = {}


def leaf(module: str) -> str | None:
    """The command line or web app a module belongs to, or None: ``meshfit.cli``,
    ``meshfit.<name>_cli``, ``meshfit.<part>.cli`` (each its own), ``meshfit.ui[.*]``."""
    bits = module.split(".")
    if len(bits) > 1 and bits[1] == "ui":
        return "meshfit.ui"
    if bits[-1] == "cli" or bits[-1].endswith("_cli"):
        return module
    return None


def part(module: str) -> str:
    """The row of `LAYERS` a module's part is in (``meshfit.layout.cli`` is a leaf)."""
    if leaf(module):
        return "leaves"
    bits = module.split(".")
    return bits[1] if len(bits) > 1 else "meshfit"


def rank(module: str) -> int:
    p = part(module)
    for k, row in enumerate(LAYERS):
        if p in row:
            return k
    raise KeyError(f"{module}: its part {p!r} has no row in LAYERS")


def modules(src: Path = SRC) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the ``meshfit`` package under ``src``."""
    out = {}
    for p in sorted((src / "meshfit").rglob("*.py")):
        bits = list(p.relative_to(src).with_suffix("").parts)
        if bits[-1] == "__init__":
            bits = bits[:-1]
        out[".".join(bits)] = p
    return out


def _type_only(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> bool:
    """Whether ``node`` is in the body of an ``if TYPE_CHECKING:`` (not in its ``else``)."""
    while node in parents:
        up = parents[node]
        if (
            isinstance(up, ast.If)
            and "TYPE_CHECKING" in ast.unparse(up.test)
            and any(node is n for n in up.body)
        ):
            return True
        node = up
    return False


def _targets(node: ast.AST, name: str, is_package: bool, known: dict) -> list[str]:
    """Modules an import statement of module ``name`` loads (``from a import b`` is the
    module ``a.b`` where that is a module, else ``a``)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if not isinstance(node, ast.ImportFrom):
        return []
    base = node.module or ""
    if node.level:  # relative: resolved against the importer's package
        pkg = name.split(".") if is_package else name.split(".")[:-1]
        pkg = pkg[: len(pkg) - (node.level - 1)]
        base = ".".join(pkg + ([base] if base else []))
    return [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]


def imports(mods: dict[str, Path]) -> list[tuple[str, str, int, bool]]:
    """``(importer, imported, line, type_only)`` for every import of a package module."""
    out = []
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        parents = {c: n for n in ast.walk(tree) for c in ast.iter_child_nodes(n)}
        is_package = path.name == "__init__.py"
        for node in ast.walk(tree):
            for t in _targets(node, name, is_package, mods):
                if t == "meshfit" or t.startswith("meshfit."):
                    out.append((name, t, node.lineno, _type_only(node, parents)))
    return out


def violations(edges: list[tuple[str, str, int, bool]]) -> dict[tuple[str, str], str]:
    """(importer, imported) -> what is wrong, for every edge that breaks a rule."""
    bad: dict[tuple[str, str], str] = {}
    for a, b, line, type_only in edges:
        where = f"{a}:{line} imports {b}"
        if a.startswith("meshfit._kernels") and not b.startswith("meshfit._kernels"):
            why = f"{where}: a kernel imports package code"
        elif leaf(b) and leaf(b) != leaf(a):
            why = f"{where}: the command line / web app {leaf(b)} is a leaf"
        elif not type_only and rank(b) > rank(a):
            why = f"{where}: part {part(a)!r} imports the later part {part(b)!r}"
        else:
            continue
        bad.setdefault((a, b), why)
    return bad


@pytest.fixture(scope="module")
def found() -> dict[tuple[str, str], str]:
    return violations(imports(modules()))


def test_every_part_has_a_row():
    for m in modules():
        rank(m)


def test_layers_hold(found):
    assert sorted(v for k, v in found.items() if k not in KNOWN) == []


if KNOWN:  # (an empty parametrization would show as a skipped test)

    @pytest.mark.parametrize(
        "edge",
        [pytest.param(e, marks=pytest.mark.xfail(strict=True, reason=r)) for e, r in KNOWN.items()],
        ids="->".join,
    )
    def test_known_violation_is_gone(found, edge):
        """Fails (xfail) while the edge is there; passes, and so fails strictly, once it is
        fixed, until it is taken off `KNOWN`."""
        assert edge not in found, found[edge]


# ----------------------------------------------------------------- the check itself


def _package(tmp_path: Path, files: dict[str, str]) -> dict[str, Path]:
    for rel, text in files.items():
        p = tmp_path / "meshfit" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return modules(tmp_path)


def test_the_check_finds_each_kind_of_violation(tmp_path):
    """A synthetic package with one violation of each kind (two inside functions, one
    relative), beside imports that are allowed."""
    mods = _package(
        tmp_path,
        {
            "__init__.py": "from meshfit import errors\n",
            "errors.py": "",
            "_kernels/__init__.py": "",
            "_kernels/walk.py": "def f():\n    from meshfit.mesh import Mesh\n",
            "_kernels/ok.py": "from meshfit._kernels import walk\n",
            "mesh/__init__.py": "from meshfit import errors\nfrom meshfit._kernels import walk\n",
            "mesh/core.py": "def f():\n    import meshfit.layout.auto\n",
            "layout/__init__.py": "from ..mesh import core\n",
            "layout/auto.py": "from . import cli\n",
            "layout/cli.py": "from meshfit.layout import auto\nfrom meshfit.cli import main\n",
            "cli.py": "from meshfit import __version__\nfrom meshfit.demo import run\n",
            "demo.py": "from meshfit.ui.app import App\n",
            "ui/__init__.py": "from meshfit.ui import app\n",
            "ui/app.py": "from meshfit.layout import auto\n",
            "ui/cli.py": "from meshfit.ui import app\n",
        },
    )
    got = violations(imports(mods))
    assert sorted(got) == [
        ("meshfit._kernels.walk", "meshfit.mesh"),
        ("meshfit.demo", "meshfit.ui.app"),
        ("meshfit.layout.auto", "meshfit.layout.cli"),
        ("meshfit.layout.cli", "meshfit.cli"),
        ("meshfit.mesh.core", "meshfit.layout.auto"),
    ], got
    assert "a kernel" in got[("meshfit._kernels.walk", "meshfit.mesh")]
    assert "later part 'layout'" in got[("meshfit.mesh.core", "meshfit.layout.auto")]
    assert "is a leaf" in got[("meshfit.demo", "meshfit.ui.app")]


def test_type_only_imports_are_exempt_from_the_order_only(tmp_path):
    mods = _package(
        tmp_path,
        {
            "__init__.py": "",
            "tol.py": (
                "from typing import TYPE_CHECKING\n"
                "if TYPE_CHECKING:\n    from meshfit.mesh import Mesh\n"
                "else:\n    from meshfit.stitch import Network\n"
            ),
            "mesh.py": "",
            "stitch.py": "",
            "_kernels/walk.py": "from typing import TYPE_CHECKING\n"
            "if TYPE_CHECKING:\n    from meshfit.mesh import Mesh\n",
        },
    )
    assert sorted(violations(imports(mods))) == [
        ("meshfit._kernels.walk", "meshfit.mesh"),
        ("meshfit.tol", "meshfit.stitch"),
    ]


def test_a_part_without_a_row_is_an_error():
    with pytest.raises(KeyError, match="newpart"):
        rank("meshfit.newpart.module")


def test_the_blender_script_imports_no_meshfit():
    """``report_blender`` runs in Blender's Python, which has no meshfit to import."""
    mods = modules()
    script = "meshfit.report_blender"
    assert not [b for a, b, _, _ in imports({script: mods[script]}) if a == script]
