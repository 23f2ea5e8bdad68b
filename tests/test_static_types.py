"""What a type checker sees of the package (issue 51): a user's script made of every Python snippet
of the README and of docs/getting-started.md (each page one script, its snippets in order, as a
reader runs them), and a script importing every versioned PettingZoo module, every env class and
every native vector env class, check with no error under mypy and basedpyright (pyright, bundled:
the PyPI ``pyright`` package fetches it from npm). Both come with the ``typecheck`` extra, which
``make test`` installs.

A control script that imports a module the package does not have must fail under each: a checker
that cannot see the package would pass the user's scripts without reading them.

mypy runs without its ``var-annotated`` error: Gymnasium types ``Env.render()`` with a type
variable bound to nothing, so mypy asks every Gymnasium user to annotate ``frame = env.render()``,
whatever the env (pyright infers it).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from khepera_gym import pettingzoo, registry
from khepera_gym.envs import ENV_CLASSES
from khepera_gym.vector import VECTOR_ENV_CLASSES

ROOT = Path(__file__).resolve().parents[1]
#: The pages whose snippets make the user's scripts.
PAGES = ("README.md", "docs/getting-started.md")
#: A fenced Python snippet of a Markdown page.
SNIPPET = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)


def _user_scripts() -> dict[str, str]:
    """Each page's snippets as one script, and the script that imports every public module."""
    scripts = {}
    for page in PAGES:
        snippets = SNIPPET.findall((ROOT / page).read_text(encoding="utf-8"))
        assert snippets, f"{page} has no Python snippet"
        name = Path(page).stem.replace("-", "_")
        scripts[f"user_{name}.py"] = "\n".join(snippets)
    lines = []
    modules = pettingzoo.module_infos()
    lines += [f"from khepera_gym.pettingzoo import {m.name}" for m in modules]
    envs = sorted(cls.__name__ for cls in ENV_CLASSES.values())
    vectors = sorted(cls.__name__ for cls in VECTOR_ENV_CLASSES.values())
    lines.append(f"from khepera_gym.envs import {', '.join(envs)}")
    lines.append(f"from khepera_gym.vector import {', '.join(vectors)}")
    lines.append("")
    for m in modules:
        lines.append(f"{m.name}_env: {m.name}.{m.env_class.__name__} = {m.name}.parallel_env()")
        lines.append(f"{m.name}_aec = {m.name}.env()")
        if hasattr(m.module, "array_env"):
            lines.append(f"{m.name}_array = {m.name}.array_env(2)")
    for cls in ENV_CLASSES.values():
        vector = cls.__name__.removesuffix("Env") + "VectorEnv"
        lines.append(f"{cls.__name__.lower()}: {cls.__name__} = {cls.__name__}()")
        lines.append(f"{vector.lower()}: {vector} = {vector}(2)")
    lines.append("targets = formationvectorenv.formation_targets()")
    scripts["every_public_module.py"] = "\n".join(lines) + "\n"
    return scripts


def _write(folder: Path, scripts: dict[str, str]) -> Path:
    folder.mkdir()
    for name, text in scripts.items():
        (folder / name).write_text(text, encoding="utf-8")
    # basedpyright's default level is stricter than a user's: "standard" is pyright's own.
    (folder / "pyrightconfig.json").write_text(json.dumps({"typeCheckingMode": "standard"}))
    return folder


def _mypy(folder: Path) -> subprocess.CompletedProcess[str]:
    pytest.importorskip("mypy", reason="the typecheck extra (make test installs it)")
    command = [
        sys.executable,
        "-m",
        "mypy",
        "--disable-error-code",
        "var-annotated",
        "--no-incremental",
    ]
    command += ["--cache-dir", str(folder / ".mypy_cache"), "."]
    return subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=600)


def _pyright(folder: Path) -> subprocess.CompletedProcess[str]:
    pytest.importorskip("basedpyright", reason="the typecheck extra (make test installs it)")
    command = [sys.executable, "-m", "basedpyright", "--pythonpath", sys.executable, "."]
    return subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=600)


CHECKERS = {"mypy": _mypy, "basedpyright": _pyright}


@pytest.mark.parametrize("checker", CHECKERS)
def test_the_users_scripts_type_check_without_error(checker: str, tmp_path: Path) -> None:
    result = CHECKERS[checker](_write(tmp_path / "scripts", _user_scripts()))
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("checker", CHECKERS)
def test_the_checker_reports_a_module_the_package_does_not_have(
    checker: str, tmp_path: Path
) -> None:
    # A version beyond the core's latest: no such module, so each checker must say so.
    missing = f"formation_v{registry.LATEST_VERSION + 1}"
    folder = _write(
        tmp_path / "control", {"control.py": f"from khepera_gym.pettingzoo import {missing}\n"}
    )
    result = CHECKERS[checker](folder)
    assert result.returncode != 0
    assert missing in result.stdout, result.stdout + result.stderr
