"""The environment pages: one page per task of the core, from its env classes, its manual (the
class docstring), the spaces and layout of a freshly made env and the core's scenario keys.

A task has a page when it has a Gymnasium id (:func:`khepera_gym.registration.registered_ids`)
or a PettingZoo module (:func:`khepera_gym.pettingzoo.module_infos`); the page of a task with
both also holds the PettingZoo module's manual. Nothing lists tasks here.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from khepera_gym import _core, pettingzoo, registry
from khepera_gym.analysis.docgen.markdown import (
    code,
    docstring_markdown,
    escape_cell,
    sections,
    table,
)
from khepera_gym.analysis.docgen.scenario import SOURCE_TAGS, key_histories
from khepera_gym.baselines import BaselinePolicy
from khepera_gym.envs import ENV_CLASSES
from khepera_gym.registration import registered_ids
from khepera_gym.vector import VECTOR_ENV_CLASSES

#: Where the animations of the env pages live, relative to docs/ (made by
#: ``python -m khepera_gym.analysis.docgen.pictures``, with ``animations.json`` saying how).
ANIMATIONS = Path("images") / "envs"
#: The manual's sections whose text the page shows (in this order), then the generated ones.
MANUAL_ORDER = (
    "Description",
    "Agents",
    "Action Space",
    "Observation Space",
    "Rewards",
    "Starting State",
    "Episode End",
    "Arguments",
    "Vectorized environment",
    "Robot model",
    "Sensors",
)


@dataclasses.dataclass(frozen=True)
class EnvPage:
    """What one task's page is made of.

    Attributes:
        task: The core's task.
        ids: Its Gymnasium ids, oldest version first (may be empty).
        modules: Its PettingZoo modules.
        env_class: Its single-env class, or the PettingZoo class of a PettingZoo-only task.
    """

    task: str
    ids: tuple[str, ...]
    modules: tuple[pettingzoo.PettingZooModule, ...]
    env_class: type

    @property
    def slug(self) -> str:
        """The page's file name without ``.md`` (the task's name)."""
        return self.task

    @property
    def title(self) -> str:
        """The Gymnasium id without its version, or the PettingZoo module family."""
        if self.ids:
            return self.ids[-1].rsplit("-v", 1)[0]
        return self.modules[-1].family

    @property
    def manual(self) -> str:
        """The manual: the env class's docstring, or for a PettingZoo-only task the first class
        docstring with sections in its class's ancestry, else its family module's docstring."""
        if self.ids:
            return self.env_class.__doc__ or ""
        for cls in self.env_class.__mro__:
            if "## Description" in (cls.__doc__ or ""):
                return cls.__doc__ or ""
        return _family_module_doc(self.modules[-1])

    @property
    def manual_module(self) -> str:
        """The module whose source holds the manual."""
        if self.ids:
            return self.env_class.__module__
        for cls in self.env_class.__mro__:
            if "## Description" in (cls.__doc__ or ""):
                return cls.__module__
        family = f"khepera_gym.pettingzoo.{self.modules[-1].family}"
        try:
            importlib.import_module(family)
        except ImportError:
            return self.modules[-1].module.__name__
        return family

    @property
    def summary(self) -> str:
        """One line: the manual's first sentence (up to its first full stop or colon)."""
        first = docstring_markdown(self.manual).split("\n\n", 1)[0]
        line = " ".join(first.split())
        ends = [i for i in (line.find(". "), line.find(": ")) if i >= 0]
        return line if not ends else line[: min(ends)] + "."


def _family_module_doc(module: pettingzoo.PettingZooModule) -> str:
    """The docstring of ``khepera_gym.pettingzoo.<family>`` when that module exists (the manual
    shared by its versions), else the versioned module's."""
    try:
        family = importlib.import_module(f"khepera_gym.pettingzoo.{module.family}")
    except ImportError:
        return module.module.__doc__ or ""
    return family.__doc__ or ""


def env_pages() -> list[EnvPage]:
    """One page per task that has a Gymnasium id or a PettingZoo module, in the core's order."""
    ids = registered_ids()
    modules = pettingzoo.module_infos()
    pages = []
    for task in registry.task_names():
        own = tuple(m for m in modules if m.task == task)
        if task not in ids and not own:
            continue
        env_class = ENV_CLASSES[task] if task in ids else own[-1].env_class
        pages.append(EnvPage(task, tuple(ids.get(task, ())), own, env_class))
    return pages


def baselines(task: str) -> tuple[type[BaselinePolicy], ...]:
    """The baseline classes that act on an agent of the task's default scenario
    (:func:`khepera_gym.baselines.for_task`)."""
    from khepera_gym.baselines import for_task

    return for_task(task)


def _page_link(pages: list[EnvPage]) -> dict[str, str]:
    """Role targets (class and module names) that have a page, to that page's file."""
    links: dict[str, str] = {}
    for page in pages:
        names = [page.env_class.__name__, f"{page.env_class.__module__}.{page.env_class.__name__}"]
        if page.ids:
            names.append(f"khepera_gym.envs.{page.env_class.__name__}")
        for module in page.modules:
            names += [module.module.__name__, f"khepera_gym.pettingzoo.{module.family}"]
        for name in names:
            links[name] = f"{page.slug}.md"
    return links


def animation(task: str, docs_dir: Path) -> dict[str, Any] | None:
    """The animation of a task's page as ``animations.json`` records it, or None."""
    index = docs_dir / ANIMATIONS / "animations.json"
    if not index.is_file():
        return None
    record = json.loads(index.read_text(encoding="utf-8")).get(task)
    if record is None or not (docs_dir / ANIMATIONS / record["file"]).is_file():
        return None
    return record


def _space(space: gym.Space) -> str:
    if isinstance(space, gym.spaces.Box):
        low, high = np.unique(space.low), np.unique(space.high)
        bounds = f"{low[0]:g}, {high[0]:g}" if len(low) == 1 and len(high) == 1 else "low, high"
        return f"Box({bounds}, {space.shape}, {space.dtype})"
    return str(space)


def _bound(values: np.ndarray) -> str:
    lowest, highest = float(values.min()), float(values.max())
    return f"{lowest:.4g}" if lowest == highest else f"{lowest:.4g} … {highest:.4g}"


def _layout_table(batch: _core.Batch, space: gym.spaces.Box) -> str:
    """The first agent's observation blocks with their indices and bounds."""
    agents = batch.agents()
    name, _, start, _, layout = agents[0]
    rows = []
    for block, block_start, block_stop in layout:
        low = space.low[start + block_start : start + block_stop]
        high = space.high[start + block_start : start + block_stop]
        indices = (
            f"{block_start}" if block_stop - block_start == 1 else f"{block_start}–{block_stop - 1}"
        )
        rows.append(
            [code(block), indices, str(block_stop - block_start), _bound(low), _bound(high)]
        )
    text = table(["Block", "Indices", "Values", "Min", "Max"], rows)
    if len(agents) > 1:
        names = ", ".join(code(agent[0]) for agent in agents)
        text = (
            f"Agent {code(name)}'s block; the joint observation holds one block per agent, in the "
            f"order {names} (default scenario; `env.unwrapped.obs_layout()` names every slice, "
            f"prefixed by its agent).\n\n" + text
        )
    return text


def _default_cell(history: Any) -> str:
    text = code(history.latest.text)
    others = [
        f"v{version}: {code(value)}"
        for version, value in history.by_version.items()
        if history.values[version] != history.latest.value
    ]
    return text + (f" ({'; '.join(others)})" if others else "")


def scenario_table(task: str) -> str:
    """Every scenario key of a task, section by section: default (and where an older version's
    differs, that one), meaning and source tags, from the core's default file."""
    histories = key_histories(task)
    versions = registry.task_versions(task)
    parts = [
        f"Every key of the default scenario of `{task}` "
        f"(`khepera_gym.default_config({task!r})` prints it as TOML). The default is the latest "
        f"version's (v{versions[-1]}); an older version's follows where it differs. Allowed: "
        "the values the core accepts, whether the scenario uses the key or not (anything else "
        "is a `ConfigError` naming the key); `[low, high]` ranges take two such values, the "
        "low one first, and a fixed-size array exactly its entries. Source tags: "
        + "; ".join(f"[{tag}] {meaning}" for tag, meaning in SOURCE_TAGS.items())
        + "."
    ]
    current = None
    rows: list[list[str]] = []
    for history in [*histories, None]:
        section = history.latest.section if history else None
        if section != current and rows:
            parts.append(
                f"### `[{current}]`\n\n"
                + table(["Key", "Default", "Allowed", "Meaning", "Source"], rows)
            )
            rows = []
        if history is None:
            break
        current = section
        key = history.latest
        rows.append(
            [
                code(key.dotted),
                _default_cell(history),
                escape_cell(key.allowed) or "–",
                escape_cell(key.comment) or "–",
                ", ".join(key.tags) or "–",
            ]
        )
    from khepera_gym.analysis.docgen.markdown import link_citations

    return link_citations("\n\n".join(parts))


def version_changes(task: str) -> str:
    """The keys whose default differs between the task's versions (or a sentence saying it has
    one version)."""
    versions = registry.task_versions(task)
    if len(versions) == 1:
        return f"`{task}` exists in version {versions[0]} only."
    changed = [h for h in key_histories(task) if h.changed]
    rows = [
        [code(h.latest.dotted)] + [code(h.by_version.get(v, "–")) for v in versions]
        for h in changed
    ]
    return "Defaults that differ between versions (from the core's default files):\n\n" + table(
        ["Key", *(f"v{v}" for v in versions)], rows
    )


def _facts(page: EnvPage, env: Any, docs_dir: Path) -> str:
    rows = []
    if page.ids:
        rows.append(["Gymnasium ids", ", ".join(code(i) for i in page.ids)])
    if page.modules:
        rows.append(
            [
                "PettingZoo",
                ", ".join(code(f"khepera_gym.pettingzoo.{m.name}") for m in page.modules),
            ]
        )
    rows.append(["Task in the core", code(page.task)])
    if page.ids:
        vector = VECTOR_ENV_CLASSES[page.task]
        rows.append(
            [
                "Classes",
                f"{code(f'khepera_gym.envs.{page.env_class.__name__}')}, vector "
                f"{code(f'khepera_gym.vector.{vector.__name__}')}",
            ]
        )
        rows.append(["Action space", code(_space(env.action_space))])
        rows.append(["Observation space", code(_space(env.observation_space))])
        rows.append(["Make", code(f'gym.make("{page.ids[-1]}")')])
    else:
        agent = env.possible_agents[0]
        rows.append(["Agents (default)", ", ".join(code(a) for a in env.possible_agents)])
        rows.append([f"Action space of `{agent}`", code(_space(env.action_space(agent)))])
        space = env.observation_space(agent)
        rows.append([f"Observation space of `{agent}`", code(_space(space))])
        rows.append(["Make", code(f"{page.modules[-1].name}.parallel_env()")])
    classes = baselines(page.task)
    if classes:
        rows.append(
            [
                "Baselines",
                ", ".join(f"{code(cls.__name__)} ({code(cls.CONTROLLER)})" for cls in classes),
            ]
        )
    rows.append(["Versions", ", ".join(f"v{v}" for v in registry.task_versions(page.task))])
    return table(["", ""], rows)


def _make_env(page: EnvPage) -> tuple[Any, _core.Batch]:
    if page.ids:
        env = gym.make(page.ids[-1])
        return env, env.unwrapped._batch
    env = page.modules[-1].module.parallel_env()
    return env, env.unwrapped._batch


def _solved(task: str) -> str:
    """The task's entry of the learning benchmark: when it is solved, and with what."""
    from khepera_gym.learning.benchmark.suite import load_suite

    entry = load_suite().get(task)
    if entry is None:
        return "## Learning benchmark\n\nThe benchmark's suite has no entry for this task yet."
    conditions = " and ".join(code(c.describe()) for c in entry.criterion)
    return (
        "## Learning benchmark\n\n"
        f"Solved when {conditions} over 200 held-out episodes ({entry.why}); trained with "
        f"{', '.join(code(n) for n in entry.learners)} beside the baselines "
        f"{', '.join(code(n) for n in entry.baselines)}. "
        f"{code(f'khepera-gym benchmark --tasks {task}')} runs it; the recorded results are on "
        "the [results page](../../results.md#learned-per-task)."
    )


def env_page(page: EnvPage, pages: list[EnvPage], docs_dir: Path) -> str:
    """The Markdown of one task's page."""
    links = _page_link(pages)
    manual = docstring_markdown(page.manual, links.get)
    intro, manual_sections = sections(manual)
    env, batch = _make_env(page)
    parts = [f"(env-{page.slug})=\n# {page.title}", intro]
    record = animation(page.task, docs_dir)
    if record is not None:
        caption = record["caption"]
        latest = registry.latest_version(page.task)
        if record.get("version") != latest:
            # An animation made before the latest version says so under the page of the latest.
            caption += (
                f" Recorded on v{record.get('version', '?')}, before v{latest}: "
                "`python -m khepera_gym.analysis.docgen.pictures` records it again."
            )
        parts.append(
            f"```{{figure}} ../../{ANIMATIONS.as_posix()}/{record['file']}\n:alt: {page.title}\n\n"
            f"{caption}\n```"
        )
    parts.append(_facts(page, env, docs_dir))
    for name in MANUAL_ORDER:
        if name in manual_sections:
            parts.append(f"## {name}\n\n{manual_sections[name]}")
    for name, body in manual_sections.items():
        if name not in MANUAL_ORDER and name not in ("Scenario file", "Version History"):
            parts.append(f"## {name}\n\n{body}")
    space = env.observation_space if page.ids else None
    if space is None:
        from gymnasium.spaces import Box

        low, high = batch.obs_bounds()
        space = Box(low, high, dtype=np.float32)
    parts.append("## Observation layout\n\n" + _layout_table(batch, space))
    scenario = manual_sections.get("Scenario file", "")
    parts.append(
        "## Scenario file\n\n" + (scenario + "\n\n" if scenario else "") + scenario_table(page.task)
    )
    parts.append(_solved(page.task))
    history = manual_sections.get("Version History", "")
    parts.append(
        "## Version History\n\n"
        + (history + "\n\n" if history else "")
        + version_changes(page.task)
    )
    for module in page.modules if page.ids else ():
        doc = _family_module_doc(module)
        if module is page.modules[-1] and doc:
            body = docstring_markdown(doc, links.get)
            parts.append(f"## As PettingZoo agents: `{module.name}`\n\n{body}")
    env.close()
    return "\n\n".join(part for part in parts if part) + "\n"


def env_table(pages: list[EnvPage], prefix: str = "") -> str:
    """The table of every env: its ids or modules, what it is, its baselines; rows link to the
    pages at ``prefix + slug + ".md"``."""
    rows = []
    for page in pages:
        names = [code(i) for i in page.ids] + [code(m.name) for m in page.modules]
        rows.append(
            [
                f"[{page.title}]({prefix}{page.slug}.md)",
                ", ".join(names),
                escape_cell(page.summary),
                ", ".join(code(cls.__name__) for cls in baselines(page.task)) or "–",
            ]
        )
    return table(["Environment", "Ids and modules", "What", "Baselines"], rows)


__all__ = [
    "ANIMATIONS",
    "EnvPage",
    "animation",
    "baselines",
    "env_page",
    "env_pages",
    "env_table",
    "scenario_table",
    "version_changes",
]
