"""Facts the hand-written pages state, generated from the code: short blocks written into the
README and the docs pages between markers, so that a sentence naming the latest version, the
benchmark's learners, a recipe's setting or an enum's members cannot drift from the source.

A block is the text between ``<!-- generated: NAME -->`` and ``<!-- end generated: NAME -->``
(each marker on a line of its own, indented as the block is, e.g. inside a list item); NAME is
a key of :data:`FRAGMENTS`. ``python -m khepera_gym.analysis.docgen --readme`` rewrites every
block of the README and of docs/*.md (:func:`refresh`), and ``tests/test_docs_facts.py`` fails
while one differs from what the code says.

This is a tool of the repository, not part of the package's API.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from khepera_gym import registry

#: A generated block: its start marker (with its indentation), its name, its text, its end.
BLOCK = re.compile(
    r"^(?P<indent>[ \t]*)<!-- generated: (?P<name>[a-z0-9-]+) -->\n"
    r"(?P<body>.*?)"
    r"^(?P=indent)<!-- end generated: (?P=name) -->$",
    re.MULTILINE | re.DOTALL,
)


def _names(items: list[str]) -> str:
    """``a``, ``b`` and ``c`` as Markdown code, joined as an English list."""
    coded = [f"`{item}`" for item in items]
    if len(coded) <= 1:
        return "".join(coded)
    return ", ".join(coded[:-1]) + " and " + coded[-1]


def _titles(tasks: list[str]) -> str:
    """Tasks by their Gymnasium name without the prefix (Nav, Avoid), else their name."""
    info = registry.tasks()
    words = []
    for task in tasks:
        env_id = info[task].env_id
        words.append(env_id.removeprefix("KheperaIV-") if env_id else task.capitalize())
    if len(words) <= 1:
        return "".join(words)
    return ", ".join(words[:-1]) + " and " + words[-1]


def behaviour_versions() -> str:
    """One line per behaviour version, oldest first, the latest marked as what an id without
    ``-vN`` takes (the README's list)."""
    lines = []
    latest = registry.LATEST_VERSION
    for version in registry.versions():
        mark = " (the latest: what an id without `-vN` takes)" if version.number == latest else ""
        lines.append(f"- **v{version.number}**{mark}: {version.title}.")
    return "\n".join(lines)


def suite_learners() -> str:
    """Which learners the shipped suite (configs/benchmark.toml) runs on which tasks, and which
    learners it does not run at all (training.md)."""
    from khepera_gym.learning.benchmark.learners import LEARNERS
    from khepera_gym.learning.benchmark.suite import load_suite

    suite = load_suite()
    runs: dict[str, list[str]] = {name: [] for name in LEARNERS}
    for task, entry in suite.items():
        for name in entry.learners:
            runs[name].append(task)
    used = [f"`{name}` on {_titles(tasks)}" for name, tasks in runs.items() if tasks]
    unused = [name for name, tasks in runs.items() if not tasks]
    text = f"The shipped suite runs {'; '.join(used)}."
    if unused:
        text += (
            f" It runs no {_names(unused)}: `--learners` (or a suite file of your own, "
            "`--suite`) runs any learner on a task it fits."
        )
    return text


def recipe_normalisation() -> str:
    """Which PPO tables of the latest ids normalise observations (training.md)."""
    from khepera_gym.learning.recipes import load_hyperparams
    from khepera_gym.registration import latest_ids

    normalised, raw = [], []
    for task, env_id in latest_ids().items():
        table = load_hyperparams("ppo", env_id)
        (normalised if table.get("normalize", False) else raw).append(task)
    text = (
        "The PPO tables the latest ids train with normalise the observations "
        f"(`normalize = true`) on {_titles(normalised) or 'no task'}"
    )
    verb = "feeds" if len(raw) == 1 else "feed"
    text += f"; {_titles(raw)} {verb} them raw (they are bounded already)." if raw else "."
    return text


def multi_agent_tasks() -> list[str]:
    """The tasks whose default scenario has several agents, in registry order (TorchRL's agent
    groups, BenchMARL's tasks)."""
    return [task for task, info in registry.tasks().items() if info.several_agents]


def torchrl_tasks() -> str:
    """The tasks TorchRL's env takes, and those with agent groups (training.md)."""
    tasks = [f'"{task}"' for task in registry.task_names()]
    groups = [f'"{task}"' for task in multi_agent_tasks()]
    return (
        f"Its task is one of the core's: {_names(tasks)} "
        "(`khepera_gym.learning.torchrl.tasks()`); those of several agents, whose keys are in "
        f"agent groups, are {_names(groups)} (`multi_agent_tasks()`)."
    )


def benchmarl_tasks() -> str:
    """The members of BenchMARL's ``KheperaTask`` (training.md): one per multi-agent task."""
    members = [task.upper() for task in multi_agent_tasks()]
    return (
        "`khepera_gym.learning.torchrl.benchmarl.KheperaTask` has a member for each multi-agent "
        f"task of the core: {_names(members)}."
    )


#: Every generated block a page may hold, by the name its markers give.
FRAGMENTS: dict[str, Callable[[], str]] = {
    "behaviour-versions": behaviour_versions,
    "suite-learners": suite_learners,
    "recipe-normalisation": recipe_normalisation,
    "torchrl-tasks": torchrl_tasks,
    "benchmarl-tasks": benchmarl_tasks,
}


def _indented(text: str, indent: str) -> str:
    return "".join(f"{indent}{line}\n" if line else "\n" for line in text.splitlines())


def blocks(text: str) -> list[tuple[str, str, str]]:
    """The generated blocks of a page: (name, indentation, text as written, unindented)."""
    found = []
    for match in BLOCK.finditer(text):
        indent = match.group("indent")
        body = "\n".join(line.removeprefix(indent) for line in match.group("body").splitlines())
        found.append((match.group("name"), indent, body.strip()))
    return found


def refreshed(text: str) -> str:
    """A page's text with every generated block rewritten from the code.

    Raises:
        KeyError: A block names no fragment of :data:`FRAGMENTS`.
    """

    def replace(match: re.Match[str]) -> str:
        name, indent = match.group("name"), match.group("indent")
        body = _indented(FRAGMENTS[name](), indent)
        return f"{indent}<!-- generated: {name} -->\n{body}{indent}<!-- end generated: {name} -->"

    return BLOCK.sub(replace, text)


def refresh(root: Path) -> list[Path]:
    """Rewrites the generated blocks of the README and docs/*.md under ``root``; returns the
    files that changed."""
    changed = []
    for page in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        text = page.read_text(encoding="utf-8")
        new = refreshed(text)
        if new != text:
            page.write_text(new, encoding="utf-8")
            changed.append(page)
    return changed


__all__ = ["BLOCK", "FRAGMENTS", "blocks", "multi_agent_tasks", "refresh", "refreshed"]
