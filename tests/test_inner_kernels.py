"""Helper kernels compiled for kernels only (:func:`meshfit._kernels.inner`): no Python
wrapper is built for them, a Python call is refused, and no Python code calls one."""

from __future__ import annotations

import ast
import importlib
import pkgutil
from pathlib import Path

import numpy as np
import pytest
from numba.core import types

import meshfit
import meshfit._kernels as kernels
from meshfit._kernels import textio

SRC = Path(meshfit.__file__).resolve().parent
KERNELS = SRC / "_kernels"


def _inner_helpers() -> dict[str, set[str]]:
    """The inner helpers of each kernel module: module name -> helper names."""
    cls = kernels._inner_dispatcher()
    out: dict[str, set[str]] = {}
    for info in pkgutil.iter_modules(kernels.__path__):
        mod = importlib.import_module(f"{kernels.__name__}.{info.name}")
        names = {
            n
            for n, v in vars(mod).items()
            if isinstance(v, cls) and v.py_func.__module__ == mod.__name__
        }
        if names:
            out[info.name] = names
    return out


def test_the_package_has_inner_helpers_and_each_refuses_a_python_call():
    helpers = _inner_helpers()
    assert sum(len(v) for v in helpers.values()) > 50
    for module, names in helpers.items():
        mod = importlib.import_module(f"{kernels.__name__}.{module}")
        for name in names:
            with pytest.raises(TypeError, match="called from kernels only"):
                getattr(mod, name)(0)


def test_an_inner_helper_is_compiled_into_its_caller_without_a_python_wrapper():
    cols = np.array([[1, 2, 3, 4, 5, 6], [-7, 80, 900, 1, 2, 3]], dtype=np.int64)
    text = bytes(textio.face_lines(cols))
    assert text == b"f 1/4/1 2/5/2 3/6/3\nf -7/1/-7 80/2/80 900/3/900\n"
    # compiled here for the signature its caller uses (a caller loaded from the cache has
    # the helper's code in it and compiles nothing)
    sig = (types.uint8[::1], types.int64, types.int64)
    cres = textio._put_int.get_compile_result(types.int64(*sig))
    assert cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name) != 0
    assert cres.library.get_pointer_to_function(cres.fndesc.llvm_cpython_wrapper_name) == 0
    (top,) = textio.face_lines.signatures
    caller = textio.face_lines.overloads[top]
    assert caller.library.get_pointer_to_function(caller.fndesc.llvm_cpython_wrapper_name)


def _kernel_aliases(tree: ast.Module) -> tuple[dict[str, str], set[tuple[str, str]]]:
    """Names bound to kernel modules in ``tree`` (alias -> module), and the kernel names it
    imports directly ((module, name))."""
    aliases: dict[str, str] = {}
    direct: set[tuple[str, str]] = set()
    prefix = kernels.__name__
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module == prefix:
                for a in node.names:
                    aliases[a.asname or a.name] = a.name
            elif node.module.startswith(prefix + "."):
                module = node.module[len(prefix) + 1 :]
                for a in node.names:
                    direct.add((module, a.name))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(prefix + ".") and a.asname:
                    aliases[a.asname] = a.name[len(prefix) + 1 :]
    return aliases, direct


def _python_uses(path: Path, helpers: dict[str, set[str]]) -> list[str]:
    """Inner helpers that the Python code of ``path`` refers to, outside compiled kernels."""
    tree = ast.parse(path.read_text())
    aliases, direct = _kernel_aliases(tree)
    imported = {n: f"{m}.{n}" for m, n in direct if n in helpers.get(m, ())}
    if path.parent == KERNELS:
        # kernels import each other's helpers to compile them in: only a plain Python
        # function of a kernel module may not call one
        known = {n: f"{path.stem}.{n}" for n in helpers.get(path.stem, ())} | imported
        found = []
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and not node.decorator_list:
                for sub in ast.walk(node):
                    if isinstance(sub, ast.Name) and sub.id in known:
                        found.append(known[sub.id])
        return found
    found = sorted(imported.values())
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.attr in helpers.get(aliases.get(node.value.id, ""), ())
        ):
            found.append(f"{aliases[node.value.id]}.{node.attr}")
    return found


def test_no_python_code_of_the_package_calls_an_inner_helper():
    helpers = _inner_helpers()
    uses = {}
    for path in sorted(SRC.rglob("*.py")):
        tree_uses = _python_uses(path, helpers)
        if tree_uses:
            uses[str(path.relative_to(SRC))] = sorted(set(tree_uses))
    assert uses == {}


def test_the_check_finds_a_python_call_of_an_inner_helper(tmp_path):
    helpers = _inner_helpers()
    module, names = next(iter(sorted(helpers.items())))
    name = sorted(names)[0]
    src = tmp_path / "user.py"
    src.write_text(
        f"from meshfit._kernels import {module} as _k\n"
        f"from meshfit._kernels.{module} import {name}\n"
        f"def f(x):\n    return _k.{name}(x) + {name}(x)\n"
    )
    assert _python_uses(src, helpers) == [f"{module}.{name}"] * 2
