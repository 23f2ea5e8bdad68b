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
from khepera_gym import _core, _generate
from khepera_gym.envs import ENV_CLASSES
from khepera_gym.registration import registered_ids
from khepera_gym.vector import VECTOR_ENV_CLASSES

PACKAGE = Path(khepera_gym.__file__).parent
ROOT = PACKAGE.parent
#: The core's task names, from its registry.
TASKS = [name for name, _, _ in _core.tasks()]
#: The core's controller names, from its registry.
CONTROLLERS = [name for name, _ in _core.controllers()]
#: The tasks' env classes (``NavEnv``) and their vector env classes (``NavVectorEnv``).
ENV_CLASS_NAMES = [cls.__name__ for cls in ENV_CLASSES.values()]
VECTOR_CLASS_NAMES = [cls.__name__ for cls in VECTOR_ENV_CLASSES.values()]
#: The tasks' Gymnasium ids without their version (``KheperaIV-Nav``).
ENV_IDS = [ids[0].rsplit("-v", 1)[0] for ids in registered_ids().values()]
#: The PettingZoo families (``formation``), whose modules are ``<family>_vN``.
FAMILIES = list(khepera_gym.pettingzoo.FAMILIES)
#: The registries whose names a docstring, comment or literal may list: what → its names.
REGISTRIES = {
    "task": TASKS,
    "controller": CONTROLLERS,
    "env class": ENV_CLASS_NAMES,
    "vector env class": VECTOR_CLASS_NAMES,
    "id": ENV_IDS,
    "PettingZoo family": FAMILIES,
}
#: Where the lists a reader meets are: the package, the tests and the examples.
SOURCES = [
    path
    for folder in ("khepera_gym", "tests", "examples")
    for path in sorted((ROOT / folder).rglob("*.py*"))
    if path.suffix in (".py", ".pyi")
]


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


def _named(registry: str, text: str) -> set[str]:
    """The entries of a registry a line of prose names: a task or controller quoted
    (``"nav"``), a class by its name, an id with or without its version, a family as its
    module (``formation_v3``, ``formation_vN``)."""
    names = REGISTRIES[registry]
    if registry in ("task", "controller"):
        return {name for name in names if re.search(rf"[\"'`]{name}[\"'`]", text)}
    if registry == "PettingZoo family":
        return {name for name in names if re.search(rf"\b{name}_v(\d+|N)\b", text)}
    return {name for name in names if re.search(rf"(?<![\w-]){re.escape(name)}(?![\w])", text)}


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
    from khepera_gym.learning.policies import POLICY_NAMES

    return list(POLICY_NAMES)


#: Docstrings that list a registry in full on purpose, grouped for the reader, and are checked
#: here to name every entry: module → the names it must hold.
CHECKED_LISTS = {"khepera_gym.analysis.compare": _compare_policies}


@pytest.mark.parametrize("module", list(CHECKED_LISTS))
def test_a_docstring_that_lists_a_registry_names_all_of_it(module: str) -> None:
    doc = importlib.import_module(module).__doc__ or ""
    missing = [name for name in CHECKED_LISTS[module]() if f"``{name}``" not in doc]
    assert not missing, f"{module}'s docstring does not name {missing}"


@pytest.mark.parametrize("registry", list(REGISTRIES))
def test_no_docstring_lists_some_names_of_a_registry_as_if_they_were_all(registry: str) -> None:
    """A line of a docstring or comment naming three or more tasks (or controllers, env classes,
    ids, PettingZoo families) is a list a reader takes for the whole: it names them all, or it
    is marked as examples ("...")."""
    names = REGISTRIES[registry]
    stale = []
    checked = {ROOT / (name.replace(".", "/") + "/__init__.py") for name in CHECKED_LISTS}
    for path in SOURCES:
        if path in checked:
            continue
        for number, line in _prose(path):
            named = _named(registry, line)
            if len(named) >= 3 and "..." not in line and named != set(names):
                stale.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not stale, "\n".join(stale)


def _generated_lines(text: str) -> set[int]:
    """The line numbers (1-based) of a file's blocks written by ``make generated``
    (:mod:`khepera_gym._generate`): lists there are built from the registries, and
    ``tests/test_generated.py`` checks they are current."""
    lines: set[int] = set()
    inside = False
    for number, line in enumerate(text.splitlines(), start=1):
        if line == _generate.BEGIN:
            inside = True
        elif line == _generate.END:
            inside = False
        if inside:
            lines.add(number)
    return lines


def _literal_entries(node: ast.AST) -> list[ast.AST]:
    """The elements of a list, tuple or set display, or the keys of a dict one."""
    if isinstance(node, (ast.List, ast.Tuple, ast.Set)):
        return list(node.elts)
    if isinstance(node, ast.Dict):
        return [key for key in node.keys if key is not None]
    return []


def _entry_name(registry: str, node: ast.AST) -> str | None:
    """The registry entry one element of a literal is, if it is one: a string naming a task,
    an id or a module (``"KheperaIV-Nav-v3"``, ``"multinav_v1"``), a class by its name, or the
    tests' ``LATEST["nav"]`` (the latest id of a task)."""
    names = REGISTRIES[registry]
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        text = node.value
        candidates = {
            "task": text,
            "id": text.rsplit("-v", 1)[0],
            "PettingZoo family": text.rpartition("_v")[0],
        }
        name = candidates.get(registry)
        return name if name in names else None
    if isinstance(node, ast.Name) and registry.endswith("class"):
        return node.id if node.id in names else None
    is_latest = (
        isinstance(node, ast.Subscript)
        and isinstance(node.value, ast.Name)
        and node.value.id == "LATEST"
        and isinstance(node.slice, ast.Constant)
    )
    if registry == "task" and is_latest:
        return node.slice.value if node.slice.value in names else None  # type: ignore[union-attr]
    return None


#: Literals that name part of a registry on purpose: "path:line" → why. Each is data about those
#: entries (not a list of them all), and says so.
PARTIAL_ON_PURPOSE: dict[str, str] = {
    "tests/test_torchrl.py:45": "smaller scenes for the multi-robot tasks; others run as they are",
    "examples/compare_baselines.py:157": "the three tasks of the KH4VREP paper, beside its scenes",
}


@pytest.mark.parametrize("registry", [r for r in REGISTRIES if r != "controller"])
def test_no_literal_in_the_code_lists_some_entries_of_a_registry(registry: str) -> None:
    """A list, tuple or set written in the code whose elements are three or more tasks, ids,
    env classes or PettingZoo families (or a dict keyed by them), but not all of them, is a list
    kept by hand: the next task is missing from it. It is built from the registry instead, or
    marked in :data:`PARTIAL_ON_PURPOSE` with the reason it names only some. (A controller
    belongs to some tasks, so lists of controllers are the tasks' data, not checked here.)"""
    names = set(REGISTRIES[registry])
    stale = []
    for path in SOURCES:
        text = path.read_text(encoding="utf-8")
        generated = _generated_lines(text)
        for node in ast.walk(ast.parse(text)):
            if getattr(node, "lineno", None) in generated:
                continue
            entries = _literal_entries(node)
            named = [_entry_name(registry, entry) for entry in entries]
            if len(entries) < 3 or None in named:
                continue
            where = f"{path.relative_to(ROOT)}:{node.lineno}"
            if set(named) != names and where not in PARTIAL_ON_PURPOSE:
                stale.append(
                    f"{where}: names {sorted(set(named))}, not {sorted(names - set(named))}"
                )
    assert not stale, "\n".join(stale)


def test_tool_choices_keyed_by_task_name_tasks_of_the_registry() -> None:
    # Tool choices stay with their tool (issue 51) but may only name tasks the core has: a task
    # renamed in the core must not leave a choice that silently applies to nothing.
    from khepera_gym import registry
    from khepera_gym.analysis.compare.command import DEMO_PLOTTED_WORLDS
    from khepera_gym.learning.policies import VARIANT_TASKS

    tasks = set(registry.task_names())
    assert set(DEMO_PLOTTED_WORLDS) <= tasks
    assert {task for named in VARIANT_TASKS.values() for task in named} <= tasks
