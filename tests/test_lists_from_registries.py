"""Lists a reader meets in the code are generated from the registries, or checked against them
here: the ``_core.pyi`` stub against the extension it describes, the PettingZoo package's exports
and module list against ``modules()``, and no docstring or comment enumerating task or controller
names that leaves some out (a list of examples ends with "...")."""

from __future__ import annotations

import ast
import importlib
import io
import re
import tokenize
from pathlib import Path

import pytest

import khepera_gym
import khepera_gym.pettingzoo
from khepera_gym import _core

PACKAGE = Path(khepera_gym.__file__).parent
#: The core's task names, from its registry.
TASKS = [name for name, _, _ in _core.tasks()]
#: The core's controller names, from its registry.
CONTROLLERS = [name for name, _ in _core.controllers()]
#: The registries whose names a docstring or comment may list: what → its names.
REGISTRIES = {"task": TASKS, "controller": CONTROLLERS}


def _stub() -> ast.Module:
    return ast.parse((PACKAGE / "_core.pyi").read_text())


def _stub_names(body: list[ast.stmt]) -> set[str]:
    names: set[str] = set()
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def _public(names: set[str]) -> set[str]:
    return {name for name in names if not (name.startswith("__") and name.endswith("__"))}


def test_core_stub_declares_exactly_what_the_extension_has() -> None:
    stub = _stub_names(_stub().body)
    module = _public(set(dir(_core))) - {"khepera_gym"}  # pyo3's submodule attribute, if any
    assert module - stub == set(), "in _core but not in _core.pyi"
    assert stub - module - {"__version__"} == set(), "in _core.pyi but not in _core"


@pytest.mark.parametrize("cls", ["Batch", "Policy"])
def test_core_stub_declares_every_method_and_attribute_of_a_class(cls: str) -> None:
    node = next(n for n in _stub().body if isinstance(n, ast.ClassDef) and n.name == cls)
    stub = _public(_stub_names(node.body)) | {"__init__", "__reduce__"}
    runtime = _public(set(dir(getattr(_core, cls))))
    assert runtime - stub == set(), f"{cls}: in _core but not in _core.pyi"
    assert _public(stub) - runtime - {"__init__"} == set(), f"{cls}: in _core.pyi only"


def test_pettingzoo_package_exports_and_describes_every_module() -> None:
    modules = khepera_gym.pettingzoo.modules()
    assert set(modules) <= set(khepera_gym.pettingzoo.__all__)
    doc = khepera_gym.pettingzoo.__doc__ or ""
    for name in modules:
        stem = name.rpartition("_v")[0]
        assert f"``{stem}_vN``" in doc, f"the package docstring does not describe {stem}"


def _quoted(names: list[str], line: str) -> set[str]:
    return {name for name in names if re.search(rf"[\"'`]{name}[\"'`]", line)}


def _prose(path: Path) -> list[tuple[int, str]]:
    """(line number, text) of every line of a file's docstrings and comments: the prose a reader
    takes a list from (a tuple in the code is data, checked where it is used)."""
    source = path.read_text()
    lines: list[tuple[int, str]] = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            lines.append((token.start[0], token.string))
    for node in ast.walk(ast.parse(source)):
        body = getattr(node, "body", None)
        if not isinstance(body, list) or not body:
            continue
        first = body[0]
        docstring = isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
        if docstring and isinstance(first.value.value, str):
            text = first.value.value.splitlines()
            lines += [(first.lineno + i, line) for i, line in enumerate(text)]
    return lines


def _compare_policies() -> list[str]:
    from khepera_gym.compare.policies import POLICY_NAMES

    return list(POLICY_NAMES)


#: Docstrings that list a registry in full on purpose, grouped for the reader, and are checked
#: here to name every entry: module → the names it must hold.
CHECKED_LISTS = {"khepera_gym.compare": _compare_policies}


@pytest.mark.parametrize("module", list(CHECKED_LISTS))
def test_a_docstring_that_lists_a_registry_names_all_of_it(module: str) -> None:
    doc = importlib.import_module(module).__doc__ or ""
    missing = [name for name in CHECKED_LISTS[module]() if f"``{name}``" not in doc]
    assert not missing, f"{module}'s docstring does not name {missing}"


@pytest.mark.parametrize("registry", list(REGISTRIES))
def test_no_docstring_lists_some_names_of_a_registry_as_if_they_were_all(registry: str) -> None:
    """A line of a docstring or comment naming three or more tasks (or controllers) is a list a
    reader takes for the whole: it names them all, or it is marked as examples ("...")."""
    names = REGISTRIES[registry]
    stale = []
    checked = {PACKAGE.parent / (name.replace(".", "/") + "/__init__.py") for name in CHECKED_LISTS}
    for path in sorted(PACKAGE.rglob("*.py*")):
        if path in checked:
            continue
        for number, line in _prose(path):
            named = _quoted(names, line)
            if len(named) >= 3 and "..." not in line and named != set(names):
                stale.append(f"{path.relative_to(PACKAGE.parent)}:{number}: {line.strip()}")
    assert not stale, "\n".join(stale)
