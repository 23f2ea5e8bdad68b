"""The Python package's layers are the ones ``docs/architecture.md`` draws, and the modules that
moved keep their old paths.

The Python twin of ``tests/layers.rs``: every ``import`` and ``from ... import`` of every module of
``khepera_gym/`` (those inside functions included, and ``importlib.import_module("khepera_gym...")``
with a literal name) is an edge from the importing module's layer to the imported one's; each
such edge must be one the architecture page's block allows, and each edge the block draws must
be used (a drawing that allows more than the code does is not a drawing of the code).
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from khepera_gym import _moved

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "khepera_gym"
ARCHITECTURE = ROOT / "docs" / "architecture.md"

#: The folders of the tool layers (everything else in the package is the env library).
TOOL_FOLDERS = ("tooling", "learning", "analysis", "robot")


def _drawn_layers() -> dict[str, set[str]]:
    """The layer block of docs/architecture.md: layer → the layers it may import."""
    text = ARCHITECTURE.read_text(encoding="utf-8")
    block = text.split("<!-- python-layers:start -->")[1].split("<!-- python-layers:end -->")[0]
    allowed: dict[str, set[str]] = {}
    for line in block.splitlines():
        match = re.match(r"^(\w+)\s*->\s*(.*)$", line.strip())
        if match:
            targets = match.group(2)
            names = set() if targets.startswith("(") else {t.strip() for t in targets.split(",")}
            allowed[match.group(1)] = names
    return allowed


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _layer(module: str) -> str:
    parts = module.split(".")
    if parts == ["khepera_gym", "cli"]:
        return "cli"
    if len(parts) > 1 and parts[1] in TOOL_FOLDERS:
        return parts[1]
    return "env"


def _imports(path: Path) -> set[str]:
    """The khepera_gym modules (or names) one file imports, anywhere in it."""
    module = _module_name(path)
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join([*base, *([node.module] if node.module else [])])
            else:
                target = node.module or ""
            # `from khepera_gym.x import y` may import the submodule x.y: count the longest module
            found |= {f"{target}.{alias.name}" for alias in node.names}
            found.add(target)
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            found.add(node.args[0].value)
    return {name for name in found if name.split(".")[0] == "khepera_gym"}


def _existing(name: str) -> str | None:
    """The module a dotted import name is (itself, or its parent for an imported attribute)."""
    for candidate in (name, name.rsplit(".", 1)[0]):
        relative = Path(*candidate.split("."))
        if (ROOT / relative).with_suffix(".py").exists() or (
            ROOT / relative / "__init__.py"
        ).exists():
            return candidate
        if candidate == "khepera_gym._core":
            return candidate
    return None


def _edges() -> dict[tuple[str, str], list[str]]:
    edges: dict[tuple[str, str], list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        source = _module_name(path)
        for name in _imports(path):
            target = _existing(name)
            assert target is not None, f"{path.relative_to(ROOT)} imports {name}, no such module"
            pair = (_layer(source), _layer(target))
            if pair[0] != pair[1]:
                edges.setdefault(pair, []).append(f"{source} -> {target}")
    return edges


def test_the_architecture_page_draws_every_layer_once() -> None:
    drawn = _drawn_layers()
    assert set(drawn) == {"env", *TOOL_FOLDERS, "cli"}
    assert drawn["env"] == set(), "the env library imports no tool"
    for layer, targets in drawn.items():
        assert targets <= set(drawn) - {layer}, f"{layer} draws an unknown layer: {targets}"


def test_every_import_of_the_package_follows_the_drawn_layers() -> None:
    drawn = _drawn_layers()
    wrong = [
        f"{source_layer} -> {target_layer}: {', '.join(sorted(examples)[:3])}"
        for (source_layer, target_layer), examples in _edges().items()
        if target_layer not in drawn[source_layer]
    ]
    assert not wrong, "imports against docs/architecture.md's layers:\n" + "\n".join(wrong)


def test_every_drawn_edge_is_used() -> None:
    used = set(_edges())
    unused = [
        f"{layer} -> {target}"
        for layer, targets in _drawn_layers().items()
        for target in targets
        if (layer, target) not in used
    ]
    assert not unused, f"docs/architecture.md draws edges no import uses: {unused}"


def test_the_env_library_needs_no_tool_folder_at_import() -> None:
    """What ``import khepera_gym`` loads (the env library) holds no tool module."""
    code = (
        "import sys, khepera_gym, khepera_gym.vector, khepera_gym.pettingzoo, "
        "khepera_gym.baselines, khepera_gym.envs\n"
        "print([m for m in sys.modules if m.split('.')[1:2] and "
        f"m.split('.')[1] in {TOOL_FOLDERS!r}"
        " and m.startswith('khepera_gym.')])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_no_two_modules_of_a_folder_have_names_a_reader_confuses() -> None:
    """The names that once sat side by side in one folder (bench.py, benchmark/, benchmarl.py,
    swarm_bench.py) each sit apart now: no folder holds two of them."""
    confusable = {"bench", "benchmark", "benchmarl", "swarm_bench"}
    for folder in [PACKAGE, *(p for p in PACKAGE.rglob("*") if p.is_dir())]:
        names = {
            p.stem for p in folder.iterdir() if p.suffix == ".py" or (p / "__init__.py").exists()
        }
        assert len(names & confusable) <= 1, f"{folder.relative_to(ROOT)}: {names & confusable}"


# The old paths: each resolves to its new module (the same object) and warns once, naming it.
_OLD_PATHS_PROGRAM = """
import importlib, json, sys, warnings
import khepera_gym
from khepera_gym._moved import MOVED
result = {}
for old, new in sorted(MOVED.items(), key=lambda item: item[0].count(".")):  # parents first
    try:
        importlib.import_module(new)
    except ImportError as error:  # an extra this venv lacks
        result[old] = {"missing": str(error)}
        continue
    with warnings.catch_warnings(record=True) as first:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    with warnings.catch_warnings(record=True) as second:
        warnings.simplefilter("always")
        again = importlib.import_module(old)
    result[old] = {
        "same": module is sys.modules[new] and again is module,
        "first": [str(w.message) for w in first if issubclass(w.category, FutureWarning)],
        "second": [str(w.message) for w in second if issubclass(w.category, FutureWarning)],
    }
print(json.dumps(result))
"""


@pytest.fixture(scope="module")
def old_paths() -> dict[str, dict[str, object]]:
    out = subprocess.run(
        [sys.executable, "-c", _OLD_PATHS_PROGRAM], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("old", sorted(_moved.MOVED))
def test_an_old_path_is_its_new_module_and_warns_once(
    old: str, old_paths: dict[str, dict[str, object]]
) -> None:
    outcome = old_paths[old]
    if "missing" in outcome:
        pytest.skip(f"{_moved.MOVED[old]} needs an extra this venv lacks: {outcome['missing']}")
    assert outcome["same"], f"{old} is not the module object of {_moved.MOVED[old]}"
    assert len(outcome["first"]) == 1 and _moved.MOVED[old] in outcome["first"][0]
    assert outcome["second"] == []


def test_a_submodule_of_a_moved_package_moves_with_it() -> None:
    code = (
        "import warnings; warnings.simplefilter('ignore', FutureWarning)\n"
        "import khepera_gym.compare.run as old, khepera_gym.analysis.compare.run as new\n"
        "print(old is new, old.__name__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "khepera_gym.analysis.compare.run"]
    assert _moved.new_path("khepera_gym.sb3.policy") == "khepera_gym.learning.sb3.policy"
    assert _moved.new_path("khepera_gym.compare.stats") == "khepera_gym.tooling.stats"
    assert _moved.new_path("khepera_gym.compare.run") == "khepera_gym.analysis.compare.run"
    assert _moved.new_path("khepera_gym.envs.nav") is None


def test_every_new_path_exists_and_no_old_path_is_a_file() -> None:
    for old, new in _moved.MOVED.items():
        assert _existing(new) == new, f"{old} moved to {new}, which is not a module"
        relative = Path(*old.split("."))
        assert not (ROOT / relative).with_suffix(".py").exists(), old
        assert not (ROOT / relative / "__init__.py").exists(), old


def test_a_recorded_command_with_an_old_module_path_still_runs() -> None:
    # Results files record the command that made them (docs/data/*.json):
    # `python -m khepera_gym.calibrate.study ...` runs the moved module and says where it went.
    result = subprocess.run(
        [sys.executable, "-m", "khepera_gym.calibrate.study", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "--robots" in result.stdout
    assert "moved to khepera_gym.robot.calibrate" in result.stderr


#: The core's registry functions: which tasks, versions, agents, controllers and scoring exist.
REGISTRY_FUNCTIONS = frozenset(
    {"tasks", "task_versions", "task_agents", "task_scoring", "versions", "controllers"}
)


def test_only_the_registry_module_asks_the_core_what_exists() -> None:
    # Issue 51: one reader of the core's registries (khepera_gym/registry.py); every other
    # module asks it, so a task's facts are worked out one way.
    askers = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "registry.py" and path.parent == PACKAGE:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Attribute) or node.attr not in REGISTRY_FUNCTIONS:
                continue
            owner = node.value
            name = owner.id if isinstance(owner, ast.Name) else getattr(owner, "attr", None)
            if name == "_core":
                askers.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} _core.{node.attr}")
    assert not askers, "\n".join(askers)
