"""Reference tables from the registries: tasks and versions, what each version changed, scenes,
sensors, baselines with their parameters, and the policy names of ``khepera-gym compare``.

Each fragment is Markdown that a hand-written page includes (``{include}``); see
:func:`fragments` for the names.
"""

from __future__ import annotations

import inspect

from khepera_gym import pettingzoo, registry
from khepera_gym.analysis.docgen.envs import baselines, env_pages
from khepera_gym.analysis.docgen.markdown import code, escape_cell, link_citations, table
from khepera_gym.analysis.docgen.scenario import header, key_histories
from khepera_gym.baselines import BaselinePolicy, parameters
from khepera_gym.learning.policies import DEFAULT_POLICIES, POLICY_NAMES, VARIANTS


def tasks_table() -> str:
    """Every task of the core with its versions, its ids or modules and its default file's
    description."""
    pages = {page.task: page for page in env_pages()}
    rows = []
    for task in registry.task_names():
        page = pages.get(task)
        names = [] if page is None else [*page.ids, *(m.name for m in page.modules)]
        rows.append(
            [
                code(task),
                ", ".join(f"v{v}" for v in registry.task_versions(task)),
                ", ".join(code(n) for n in names) or "–",
                escape_cell(header(task).split(". ")[0].split(": ", 1)[-1]),
            ]
        )
    return table(["Task", "Versions", "Ids and modules", "What"], rows)


def version_changes_table() -> str:
    """Every key whose default differs between versions, with the tasks where it does."""
    latest = registry.LATEST_VERSION
    versions = list(range(latest + 1))
    changes: dict[tuple[str, tuple[str, ...]], list[str]] = {}
    for task in registry.task_names():
        if len(registry.task_versions(task)) < 2:
            continue
        for history in key_histories(task):
            if history.changed:
                texts = tuple(history.by_version.get(v, "–") for v in versions)
                changes.setdefault((history.latest.dotted, texts), []).append(task)
    rows = [
        [code(key), *(code(text) if text != "–" else "–" for text in texts), ", ".join(tasks)]
        for (key, texts), tasks in changes.items()
    ]
    single = [t for t in registry.task_names() if len(registry.task_versions(t)) == 1]
    note = (
        "\n\nTasks that exist in one version only: "
        + ", ".join(f"`{t}` (v{registry.task_versions(t)[0]})" for t in single)
        + "."
        if single
        else ""
    )
    return table(["Key", *(f"v{v}" for v in versions), "Tasks"], rows) + note


def scenes_table() -> str:
    """The built-in scenes and what each is."""
    rows = [[code(name), escape_cell(summary)] for name, summary in registry.scenes().items()]
    return table(["Scene (`config=`)", "What"], rows)


def sensors_table() -> str:
    """The sensor registry: block size, default, keys."""
    rows = []
    for sensor in registry.sensors():
        default = "observed" if sensor.observed else "carried" if sensor.carried else "–"
        rows.append(
            [
                code(sensor.name),
                str(sensor.values),
                default,
                ", ".join(code(f"sensors.{key}") for key in sensor.keys) or "–",
            ]
        )
    return table(["Sensor", "Block values", "Nav default", "Keys"], rows)


def _all_baselines() -> list[type[BaselinePolicy]]:
    classes: list[type[BaselinePolicy]] = []
    for task in registry.task_names():
        classes += [cls for cls in baselines(task) if cls not in classes]
    return classes


def baselines_reference() -> str:
    """Each baseline: what it is (its docstring's first paragraph), its task and its parameters
    as the core declares them."""
    controllers = registry.controllers()
    parts = []
    for cls in _all_baselines():
        doc = inspect.cleandoc(cls.__doc__ or "").split("\n\n", 1)[0]
        rows = [
            [code(name), code(repr(default)), escape_cell(comment)]
            for name, default, comment in parameters(cls.CONTROLLER)
        ]
        parts.append(
            f"### `{cls.__name__}`\n\n"
            f"`khepera_gym.baselines.{cls.__name__}`, controller {code(cls.CONTROLLER)}, on "
            f"{code(controllers[cls.CONTROLLER])} observations. {escape_cell(doc)}\n\n"
            + table(["Parameter", "Default", "Meaning"], rows)
        )
    return link_citations("\n\n".join(parts))


def policies_table() -> str:
    """The policy names ``khepera-gym compare`` and ``render`` take."""
    rows = []
    for name in POLICY_NAMES:
        controller, params = VARIANTS.get(name, (name, {}))
        cls = next((c for c in _all_baselines() if controller == c.CONTROLLER), None)
        what = "uniform random actions (seeded)" if cls is None else code(cls.__name__)
        if params:
            what += " with " + ", ".join(code(f"{k}={v!r}") for k, v in params.items())
        tasks = [task for task, names in DEFAULT_POLICIES.items() if name in names]
        rows.append([code(name), what, ", ".join(code(t) for t in tasks) or "–"])
    rows.append([code("sb3:PATH.zip"), "a stable-baselines3 model (the `sb3` extra)", "–"])
    return table(["Policy", "What", "Compared by default on"], rows)


def pettingzoo_table(prefix: str = "generated/envs/") -> str:
    """The PettingZoo modules: task, default agents, page."""
    pages = {page.task: page for page in env_pages()}
    rows = []
    for module in pettingzoo.module_infos():
        env = module.module.parallel_env()
        agents = env.possible_agents
        shown = ", ".join(code(a) for a in agents[:4]) + (", …" if len(agents) > 4 else "")
        env.close()
        page = pages[module.task]
        rows.append(
            [
                code(f"khepera_gym.pettingzoo.{module.name}"),
                code(module.task),
                f"v{module.version}",
                shown,
                f"[{page.title}]({prefix}{page.slug}.md)",
            ]
        )
    return table(["Module", "Task", "Version", "Agents (default)", "Page"], rows)


def fragments() -> dict[str, str]:
    """The fragments by name (written to ``docs/generated/<name>.md``)."""
    return {
        "tasks": tasks_table() + "\n",
        "version-changes": version_changes_table() + "\n",
        "scenes": scenes_table() + "\n",
        "sensors": sensors_table() + "\n",
        "baselines": baselines_reference() + "\n",
        "policies": policies_table() + "\n",
        "pettingzoo-table": pettingzoo_table() + "\n",
    }


__all__ = [
    "baselines_reference",
    "fragments",
    "pettingzoo_table",
    "policies_table",
    "scenes_table",
    "sensors_table",
    "tasks_table",
    "version_changes_table",
]
