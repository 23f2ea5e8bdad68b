"""The documentation stays true to the code: the env manuals' examples run and their tables
cover the layout and bounds; the defaults they state are the code's; the generated pages
(docs/generated/, ``make docs``) table every id, block and key from the registries; the README's
env table is the generated one; every env page has its animation; the results files render; code
comments cite pages that exist."""

from __future__ import annotations

import doctest
import json
import re
import shutil
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

import khepera_gym
import khepera_gym.baselines
import khepera_gym.registration
import khepera_gym.registry
from khepera_gym import envs
from khepera_gym.config import tomllib
from khepera_gym.envs import (
    ENV_CLASSES,
    FormationEnv,
)

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
MANUAL_SECTIONS = [
    "Description",
    "Action Space",
    "Observation Space",
    "Rewards",
    "Starting State",
    "Episode End",
    "Arguments",
    "Vectorized environment",
    "Robot model",
    "Sensors",
    "Scenario file",
    "Version History",
]
#: (env class, registered id, task) of every manual: every task with a Gymnasium env, from the
#: registry.
MANUALS = [(ENV_CLASSES[task], env_id, task) for task, env_id in LATEST.items()]
MANUAL_IDS = list(LATEST)


def _section(manual: str, name: str) -> str:
    start = manual.index(f"## {name}\n")
    end = manual.find("\n    ## ", start + 1)
    return manual[start : None if end < 0 else end]


def _observation_rows(manual: str) -> list[tuple[range, str, float, float]]:
    """Rows of the Observation Space table: (indices, name, min, max); "0-7" covers 0..7."""
    rows = []
    for line in _section(manual, "Observation Space").splitlines():
        cells = [cell.strip() for cell in line.split("|")[1:-1]]
        match = re.fullmatch(r"(\d+)(?:-(\d+))?", cells[0]) if cells else None
        if match:
            first = int(match.group(1))
            last = int(match.group(2) or first)
            rows.append((range(first, last + 1), cells[1], float(cells[-2]), float(cells[-1])))
    return rows


def _block_layout(task: str) -> dict[str, slice]:
    """The layout the table describes: the whole observation, or one follower's block."""
    layout = khepera_gym.obs_layout(task)
    if task != "formation":
        return layout
    prefix = "follower_0/"
    return {name.removeprefix(prefix): s for name, s in layout.items() if name.startswith(prefix)}


@pytest.mark.parametrize("env_class", [m[0] for m in MANUALS], ids=MANUAL_IDS)
def test_manual_has_every_section_in_order(env_class: type) -> None:
    manual = env_class.__doc__ or ""
    positions = [manual.index(f"## {section}\n") for section in MANUAL_SECTIONS]
    assert positions == sorted(positions)


def test_manual_examples_run() -> None:
    # The manuals make the unversioned id (it stays true at the next version); Gymnasium notes
    # that it took the latest, which is all that warning says.
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message=r".*Using the latest versioned environment", category=UserWarning
        )
        results = doctest.testmod(envs, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert results.attempted >= 10  # Nav, Avoid and Formation examples
    assert results.failed == 0


@pytest.mark.parametrize(("env_class", "env_id", "task"), MANUALS, ids=MANUAL_IDS)
def test_manual_observation_table_matches_layout_and_bounds(
    env_class: type, env_id: str, task: str
) -> None:
    rows = _observation_rows(env_class.__doc__ or "")
    layout = _block_layout(task)
    named = {index: name for indices, name, _, _ in rows for index in indices}
    assert sorted(named) == list(range(max(s.stop for s in layout.values())))
    for name, block in layout.items():
        for index in range(block.start, block.stop):
            assert named[index] == name, index
    env = gym.make(env_id)
    low, high = env.observation_space.low, env.observation_space.high
    for indices, name, minimum, maximum in rows:
        for index in indices:
            assert low[index] == pytest.approx(minimum, abs=0.01), (name, index)
            assert high[index] == pytest.approx(maximum, abs=0.01), (name, index)
    env.close()


def test_formation_manual_states_the_agent_leader_block_is_navs() -> None:
    manual = FormationEnv.__doc__ or ""
    assert "Nav block (18 values" in _section(manual, "Observation Space")
    env = gym.make(LATEST["formation"], leader="agent")
    layout = env.unwrapped.obs_layout()
    nav_layout = khepera_gym.obs_layout("nav")
    assert {name.removeprefix("leader/"): s for name, s in layout.items() if "leader/" in name} == (
        nav_layout
    )
    np.testing.assert_array_equal(
        env.observation_space.low[:18], gym.make(LATEST["nav"]).observation_space.low
    )
    env.close()


# --- the defaults the manuals state are the code's ---------------------------------------------

#: A dotted key in backquotes followed by its value: "`task.max_steps` (400" or "` = 0.7".
_STATED_DEFAULT = re.compile(
    r"`(?P<key>[a-z_]+\.[a-z_]+)` (?:\(|= )(?P<approx>≈)?(?P<number>-?\d+(?:\.\d+)?)"
    r"\s*(?P<unit>mm/s|m/s²|m/s|cm|mm|m|s|°)?(?![\w.])"
)
#: Units a manual states a default in, as SI factors (° to radians).
_UNITS = {None: 1.0, "m": 1.0, "s": 1.0, "m/s": 1.0, "m/s²": 1.0, "cm": 0.01, "mm": 0.001}
_UNITS |= {"mm/s": 0.001, "°": np.pi / 180}


def _stated_defaults(text: str) -> list[tuple[str, float, float, int | None]]:
    """The defaults a text states: (key, value in SI, tolerance, version it names or None).

    The tolerance is half a unit of the last digit written ("0.203" matches 0.2034543), 5 % for
    "≈". A version named just before the key ("in v0 (`physics.friction` = 0)") is the version
    the value is of.
    """
    stated = []
    for match in _STATED_DEFAULT.finditer(text):
        number = match.group("number")
        factor = _UNITS[match.group("unit")]
        decimals = len(number.split(".")[1]) if "." in number else 0
        value = float(number) * factor
        tolerance = 0.5 * 10.0**-decimals * factor
        if match.group("approx"):
            tolerance = max(tolerance, 0.05 * abs(value))
        named = re.search(r"\bv(\d+)\W*$", text[max(0, match.start() - 16) : match.start()])
        stated.append(
            (match.group("key"), value, tolerance, int(named.group(1)) if named else None)
        )
    return stated


def _manuals() -> list[tuple[str, str]]:
    """(task, manual) of every env page: the env classes' and the PettingZoo manuals."""
    from khepera_gym.analysis.docgen.envs import env_pages

    return [(page.task, page.manual) for page in env_pages()]


def test_the_stated_default_parser_reads_units_versions_and_precision() -> None:
    text = "It stops within `task.goal_radius` (5 cm). In v0 (`physics.friction` = 0) it slid."
    assert _stated_defaults(text) == [
        ("task.goal_radius", pytest.approx(0.05), pytest.approx(0.005), None),
        ("physics.friction", 0.0, 0.5, 0),
    ]
    assert _stated_defaults("`track.start_heading_offset` (45°")[0][1] == pytest.approx(np.pi / 4)


@pytest.mark.parametrize(("task", "manual"), _manuals(), ids=[t for t, _ in _manuals()])
def test_every_default_a_manual_states_is_the_codes(task: str, manual: str) -> None:
    """A manual that says "`task.max_steps` (400)" or "`physics.friction` = 0.7" says what the
    task's latest version has (or the version the sentence names); the version histories are
    left out (they tell what older versions had)."""
    from khepera_gym.analysis.docgen.scenario import task_keys

    text = manual.split("## Version History")[0]
    versions = khepera_gym.registry.task_versions(task)
    checked = 0
    for key, value, tolerance, version in _stated_defaults(text):
        version = versions[-1] if version is None else version
        defaults = {k.dotted: k.value for k in task_keys(task, version)}
        if key not in defaults or not isinstance(defaults[key], int | float):
            continue
        assert abs(float(defaults[key]) - value) <= tolerance + 1e-9, (
            f"{task} manual: `{key}` stated as {value:g}; v{version}'s default is {defaults[key]}"
        )
        checked += 1
    assert checked or task in ("multinav",), f"{task}: no stated default found to check"


def test_no_manual_copies_a_key_table_any_more() -> None:
    """The key tables are generated on the env pages; the manuals point there."""
    for task, manual in _manuals():
        scenario = manual.split("## Scenario file")[-1].split("## Version History")[0]
        assert "| Key" not in scenario and "|---" not in scenario, task


# --- the generated pages --------------------------------------------------------------------


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """docs/ with its images and results, and the generated pages written into a copy."""
    from khepera_gym.analysis.docgen import write_all

    docs = tmp_path_factory.mktemp("docs")
    shutil.copytree(DOCS / "images", docs / "images")
    shutil.copytree(DOCS / "results", docs / "results")
    write_all(docs)
    return docs / "generated"


def _table_rows(markdown: str) -> list[list[str]]:
    return [
        [cell.strip() for cell in line.strip().strip("|").split(" | ")]
        for line in markdown.splitlines()
        if line.startswith("| `")
    ]


def test_every_task_with_an_id_or_a_module_has_a_page(generated: Path) -> None:
    from khepera_gym.registration import registered_ids

    tasks = set(registered_ids()) | {m.task for m in khepera_gym.pettingzoo.module_infos()}
    assert {path.stem for path in (generated / "envs").glob("*.md")} == tasks
    table = (generated / "env-table.md").read_text(encoding="utf-8")
    for ids in registered_ids().values():
        for env_id in ids:
            assert f"`{env_id}`" in table
            page = generated / "envs" / f"{khepera_gym.registration.task_of(env_id)}.md"
            assert f"`{env_id}`" in page.read_text(encoding="utf-8")


@pytest.mark.parametrize("task", khepera_gym.registry.task_names())
def test_a_page_tables_every_key_with_the_codes_default_in_each_version(
    generated: Path, task: str
) -> None:
    page = generated / "envs" / f"{task}.md"
    if not page.is_file():
        pytest.skip(f"{task} has no page (no id, no PettingZoo module)")
    text = page.read_text(encoding="utf-8").split("## Scenario file")[1].split("\n## ")[0]
    versions = khepera_gym.registry.task_versions(task)
    latest = tomllib.loads(khepera_gym.default_config(task))
    rows = {row[0].strip("`"): row for row in _table_rows(text) if "." in row[0]}
    for section, keys in latest.items():
        for key, value in keys.items():
            row = rows[f"{section}.{key}"]
            default = re.match(r"`([^`]*)`", row[1]).group(1)
            assert tomllib.loads(f"x = {default}")["x"] == value, (section, key)
            for version in versions[:-1]:
                old = tomllib.loads(khepera_gym.default_config(task, version))[section][key]
                if old != value:
                    shown = re.search(rf"v{version}: `([^`]*)`", row[1]).group(1)
                    assert tomllib.loads(f"x = {shown}")["x"] == old, (section, key, version)


@pytest.mark.parametrize(("env_class", "env_id", "task"), MANUALS, ids=MANUAL_IDS)
def test_a_page_tables_the_observation_blocks_with_their_bounds(
    generated: Path, env_class: type, env_id: str, task: str
) -> None:
    text = (generated / "envs" / f"{task}.md").read_text(encoding="utf-8")
    layout = _block_layout(task)
    env = gym.make(env_id)
    for name, block in layout.items():
        indices = f"{block.start}" if block.stop - block.start == 1 else f"{block.start}–"
        line = next(row for row in text.splitlines() if row.startswith(f"| `{name}` |"))
        assert f"| {indices}" in line, (name, line)
        assert f"{env.observation_space.low[block.start]:.4g}" in line, (name, line)
    env.close()


def test_reference_fragments_name_every_scene_sensor_policy_and_baseline(generated: Path) -> None:
    from khepera_gym.learning.policies import POLICY_NAMES

    scenes = (generated / "scenes.md").read_text(encoding="utf-8")
    assert all(f"`{name}`" in scenes for name in khepera_gym.scenes())
    sensors = (generated / "sensors.md").read_text(encoding="utf-8")
    assert all(f"`{s.name}`" in sensors for s in khepera_gym.registry.sensors())
    policies = (generated / "policies.md").read_text(encoding="utf-8")
    assert all(f"`{name}`" in policies for name in POLICY_NAMES)
    baselines = (generated / "baselines.md").read_text(encoding="utf-8")
    for controller, _ in khepera_gym._core.controllers():
        assert f"controller `{controller}`" in baselines
        for name, _, _ in khepera_gym.baselines.parameters(controller):
            assert f"| `{name}` |" in baselines


def test_every_env_page_has_a_small_animation_of_a_baseline() -> None:
    from khepera_gym.analysis.docgen.envs import ANIMATIONS, env_pages

    index = json.loads((DOCS / ANIMATIONS / "animations.json").read_text(encoding="utf-8"))
    for page in env_pages():
        record = index[page.task]
        path = DOCS / ANIMATIONS / record["file"]
        assert path.stat().st_size < 400_000, path
        assert record["policy"] in {cls.__name__ for cls in baselines_of(page.task)}
        # It says the version it shows, one of the task's (an older one: the page says so).
        assert (
            f"_v{record['version']}" in record["env"] or f"-v{record['version']}" in record["env"]
        ), record
        assert record["version"] in khepera_gym.registry.task_versions(page.task), record


def test_an_env_page_says_when_its_animation_is_of_an_older_version(generated: Path) -> None:
    from khepera_gym.analysis.docgen.envs import ANIMATIONS, env_pages

    index = json.loads((DOCS / ANIMATIONS / "animations.json").read_text(encoding="utf-8"))
    for page in env_pages():
        text = (generated / "envs" / f"{page.slug}.md").read_text(encoding="utf-8")
        version = index[page.task]["version"]
        latest = khepera_gym.registry.task_versions(page.task)[-1]
        assert (f"Recorded on v{version}, before v{latest}" in text) == (version != latest)


def baselines_of(task: str) -> tuple[type, ...]:
    from khepera_gym.analysis.docgen.envs import baselines

    return baselines(task)


def test_results_pages_render_every_results_file_with_its_provenance(generated: Path) -> None:
    from khepera_gym.analysis.docgen.results_files import as_typed, kind, load

    files = load(DOCS / "results")
    assert files, "docs/results/ holds no results file"
    text = "".join(path.read_text() for path in generated.glob("results-*.md"))
    for path, document in files:
        assert kind(document) != "unknown", path
        assert document["meta"]["date"][:10] in text, path
        assert as_typed(document["meta"]["command"]) in text, path
    # Commands read as a user types them, not as the source tree they ran from.
    assert "khepera_gym/cli.py" not in text


def test_a_learned_formation_file_renders_against_its_baseline(tmp_path: Path) -> None:
    from khepera_gym.analysis.compare.report import write_formation_learning
    from khepera_gym.analysis.docgen.results import learning_fragment, target_name
    from khepera_gym.analysis.docgen.results_files import kind

    rows = [
        {
            "policy": "MAPPO (BenchMARL)",
            "formation_error_mean": 0.021,
            "formation_error_max": 0.063,
            "success_rate": None,
            "contact_steps": 0.0,
        },
        {
            "policy": "LeaderFollower",
            "formation_error_mean": 0.004,
            "formation_error_max": 0.008,
            "success_rate": 1.0,
            "contact_steps": 0.0,
        },
    ]
    path = write_formation_learning(
        tmp_path / "m.json", "MAPPO (BenchMARL)", 600, 9.0, 50, 7, rows, version=3
    )
    document = json.loads(path.read_text())
    assert kind(document) == "learning" and document["meta"]["command"]
    assert target_name(document).startswith("learning_formation_v3_MAPPO__BenchMARL__")
    text = learning_fragment([(path, document)])
    assert "formation_v3, cross of 4 followers" in text
    assert "| MAPPO (BenchMARL) | 2.1 cm | 6.3 cm | – | 0.0 |" in text
    assert "| LeaderFollower | 0.4 cm | 0.8 cm | 100 | 0.0 |" in text
    # Another training seed is another file, and the page says which seed it was; a file
    # without train_seed takes it from its command line.
    seeded = write_formation_learning(
        tmp_path / "s.json", "MAPPO (BenchMARL)", 600, 9.0, 50, 7, rows, 2, version=3
    )
    document = json.loads(seeded.read_text())
    assert target_name(document).startswith("learning_formation_v3_MAPPO__BenchMARL__seed2_")
    assert "training seed 2" in learning_fragment([(seeded, document)])
    del document["formation_learning"]["train_seed"]
    document["formation_learning"]["method"] = "MAPPO (BenchMARL, one σ per action)"
    assert target_name(document).isascii()  # a file name any checkout can hold
    del document["formation_learning"]["version"]  # as in the files of v2's runs
    document["meta"]["command"] = "python examples/benchmarl_mappo.py --seed 1 --json s.json"
    assert "_seed1_" in target_name(document)
    document["meta"]["command"] = "python examples/benchmarl_mappo.py --json s.json"
    assert "_seed" not in target_name(document)


def test_a_results_file_names_its_command_as_typed() -> None:
    from khepera_gym.tooling.provenance import command_line

    assert command_line(["/venv/bin/khepera-gym", "bench", "--json", "b.json"]) == (
        "khepera-gym bench --json b.json"
    )
    assert command_line(["examples/formation_shared_ppo.py", "--json", "a b.json"]) == (
        "python examples/formation_shared_ppo.py --json 'a b.json'"
    )
    assert command_line(["-c", "--x"]) == "python -c --x"


def test_results_files_of_trained_models_and_stacked_runs_do_not_replace_others() -> None:
    from khepera_gym.analysis.docgen.results import target_name

    meta = {"date": "2026-11-28T00:00:00+00:00"}
    baselines = {"meta": meta, "env_id": "E-v2", "label": "avoid", "summaries": [{"policy": "vfh"}]}
    trained = {**baselines, "summaries": [{"policy": "vfh"}, {"policy": "sb3:run/model.zip"}]}
    assert target_name(baselines) == "compare_E-v2_avoid_2026-11-28.json"
    assert target_name(trained) == "compare_E-v2_avoid_trained_2026-11-28.json"
    sampled = {**baselines, "summaries": [{"policy": "sb3:run/model.zip (sampled)"}]}
    assert target_name(sampled) == "compare_E-v2_avoid_trained_sampled_2026-11-28.json"
    run = {"meta": meta, "env_id": "E-v2", "algo": "ppo", "seed": 0, "final": {}}
    assert target_name({**run, "hyperparams": {}}) == "train_E-v2_ppo_seed0_2026-11-28.json"
    stacked = {**run, "hyperparams": {"frame_stack": 8}}
    assert target_name(stacked) == "train_E-v2_ppo_seed0_stack8_2026-11-28.json"
    # A variant of a shipped table is named, and shown, by what it changed.
    from khepera_gym.analysis.docgen.results import train_fragment

    shipped = {"frame_stack": 8, "learning_rate": 0.0005, "gamma": 0.99}
    variant = {**run, "env_id": "KheperaIV-Avoid-v2", "hyperparams": {**shipped, "gamma": 0.995}}
    assert (
        target_name(variant)
        == "train_KheperaIV-Avoid-v2_ppo_seed0_stack8_gamma0.995_2026-11-28.json"
    )
    assert target_name({**variant, "hyperparams": shipped}).endswith(
        "_seed0_stack8_2026-11-28.json"
    )
    final = {"success_rate": 0.9, "episodes": 100}
    figures = {"final": final, "timesteps": 300_000, "wall_time": 100.0, "steps_per_second": 3e3}
    assert "| gamma 0.995 |" in train_fragment([(Path("r.json"), {**variant, **figures})])


def test_a_hostile_campaign_report_renders_with_its_counts_and_failures() -> None:
    from khepera_gym.analysis.docgen.results import hostile_fragment, target_name
    from khepera_gym.analysis.docgen.results_files import kind

    meta = {"date": "2026-11-28T00:00:00+00:00", "command": "python tests/hostile_campaign.py"}
    by_kind = {"make": {"built": 3, "refused: ConfigError": 5}, "state": {"restored": 2}}
    failure = {"replay": "3:17", "kind": "make", "outcome": "FAIL: TypeError", "detail": ""}
    document = {"meta": meta, "cases": 10, "seed": 3, "seconds": 1.0, "accepted": 5}
    document |= {"refused": 5, "failures": 1, "by_kind": by_kind, "failure_list": [failure]}
    assert kind(document) == "hostile"
    assert target_name(document) == "hostile_10cases_seed3_2026-11-28.json"
    text = hostile_fragment([(Path("h.json"), document)])
    assert "**10 cases, 1 failures**" in text and "`3:17` make: FAIL: TypeError" in text
    assert "| `make` | built 3, refused: ConfigError 5 | 8 |" in text


def test_the_swarm_table_sets_each_robot_step_beside_small_worlds_on_as_many_threads() -> None:
    from khepera_gym.analysis.docgen.throughput import swarm_fragment

    def row(robots: int, split: str, threads: int, rate: float, **more: Any) -> dict[str, Any]:
        worlds = max(1, 1024 // robots)
        return (
            {"robots": robots, "worlds": worlds, "split": split, "threads": threads}
            | {
                "world_steps_per_second": rate / robots,
                "robot_steps_per_second": rate,
                "real_time_factor": rate / robots / worlds * 0.05,
            }
            | more
        )

    meta = {"date": "2026-12-07T00:00:00+00:00", "command": "khepera-gym bench"}
    swarm = [row(4, "world", 1, 2.0e6, version=3), row(4, "world", 2, 3.0e6, version=3)]
    swarm += [row(1000, "robot", 1, 1.6e6, version=3), row(1000, "world", 2, 1.0e6, version=3)]
    text = swarm_fragment([(Path("b.json"), {"meta": meta, "rows": [], "swarm": swarm})])
    lines = [line for line in text.splitlines() if line.startswith("| 1,000 |")]
    # A 1,000-robot row against the 4-robot worlds split by world on its thread count.
    assert "| 1.25× |" in lines[0] and "| 3.00× |" in lines[1]
    assert "Multinav v3." in text
    # A file from before rows named their version timed multinav v1.
    old = [{k: v for k, v in r.items() if k != "version"} for r in swarm]
    text = swarm_fragment([(Path("b.json"), {"meta": meta, "rows": [], "swarm": old})])
    assert "Multinav v1 (until 2026-12-07" in text


# --- README -------------------------------------------------------------------------------------


def test_readme_is_a_short_front_door_whose_links_exist(generated: Path) -> None:
    """A link into docs/generated/ (the env pages, which `make docs` writes) must name a file
    the generator writes."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 300
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme):
        if "://" in target:
            continue
        if target.startswith("docs/generated/"):
            assert (generated / target.removeprefix("docs/generated/")).is_file(), target
        else:
            assert (ROOT / target).exists(), target


def test_readme_env_table_is_the_generated_one() -> None:
    """Refresh it with ``python -m khepera_gym.analysis.docgen --readme`` when the registries
    change."""
    from khepera_gym.analysis.docgen import readme_env_table

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    start = readme.index("<!-- env-table:start -->") + len("<!-- env-table:start -->")
    end = readme.index("<!-- env-table:end -->")
    assert readme[start:end].strip() == readme_env_table().strip(), (
        "the README's env table differs from the registries: run "
        "`python -m khepera_gym.analysis.docgen --readme`"
    )


# --- citations ----------------------------------------------------------------------------------

#: A citation of a research note by the page that holds it now and its section: "robot.md §6",
#: "task-design.md §3", "fidelity.md §3.2".
_CITATION = re.compile(r"(?P<note>robot\.md|task-design\.md|fidelity\.md) §(?P<section>\d+)")
_LABELS = {"robot.md": "spec", "task-design.md": "tasks", "fidelity.md": "fidelity"}
#: The notes' old names ("spec §6", "tasks.md §3"), which name no file a reader can open.
_OLD_CITATION = re.compile(r"\b(?:spec|tasks\.md) §\d")


def test_every_cited_section_of_a_research_note_is_a_section_of_a_docs_page() -> None:
    """Comments and scenario comments cite the notes by section; the pages that hold the notes
    now (docs/robot.md, task-design.md, fidelity.md) keep those numbers as labels."""
    labels = set()
    for page in DOCS.glob("*.md"):
        labels |= set(re.findall(r"^\((?P<label>[a-z]+-\d+)\)=$", page.read_text(), re.M))
    sources = [
        *ROOT.glob("src/**/*.rs"),
        *ROOT.glob("khepera_gym/**/*.py"),
        *ROOT.glob("configs/*.toml"),
    ]
    sources += [*ROOT.glob("tests/*.rs"), *ROOT.glob("tests/*.py")]
    cited = 0
    for path in sources:
        if path.name == Path(__file__).name:
            continue
        text = path.read_text(encoding="utf-8")
        if path.parent.name != "docgen":  # the generator links the old names in pages
            old_names = _OLD_CITATION.findall(text)
            assert not old_names, f"{path.relative_to(ROOT)} cites {old_names}: name the page"
        for match in _CITATION.finditer(text):
            assert f"{_LABELS[match.group('note')]}-{match.group('section')}" in labels, (
                f"{path.relative_to(ROOT)} cites {match.group(0)}, which no docs page holds"
            )
            cited += 1
    assert cited > 50


def test_python_comments_cite_the_docs_pages_not_the_research_folder() -> None:
    for path in [*ROOT.glob("khepera_gym/**/*.py"), *ROOT.glob("tests/*.py")]:
        if path.name == Path(__file__).name or path.parent.name == "docgen":
            continue  # this test and the generator, which links the old citations
        text = path.read_text(encoding="utf-8")
        assert "research/" not in text and "khepera4_spec.md" not in text, path


def test_product_pages_and_manuals_name_no_issue_numbers() -> None:
    """Issue numbers belong to the project's history (the changelog and the history page), not
    to the pages and manuals a user reads."""
    history = {"changelog.md", "history.md"}
    pattern = re.compile(r"\bissues? \d+", re.IGNORECASE)
    for path in sorted(DOCS.glob("*.md")):
        if path.name not in history:
            assert not pattern.search(path.read_text(encoding="utf-8")), path.name
    for task, manual in _manuals():
        assert not pattern.search(manual), task
    assert not pattern.search((ROOT / "README.md").read_text(encoding="utf-8"))


def test_the_guides_quote_no_measured_time_of_their_own() -> None:
    """A time or rate measured on a build goes stale with it: the README and the training guide
    quote none in prose (they link the results page, rendered from the results files, and the
    history); only the install's cost, which no build changes, is stated."""
    duration = re.compile(r"\d[\d,.]*\s?(s|ms|min|minutes|seconds|steps/s|env-steps/s)\b")
    allowed = {"Installing the `sb3` extra takes about 75 s and 5.4 GB"}
    for path in (ROOT / "README.md", DOCS / "training.md", DOCS / "getting-started.md"):
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if duration.search(line) and not any(a in line for a in allowed):
                pytest.fail(f"{path.name}:{number} quotes a measured time: {line.strip()}")


def test_the_guide_names_every_extra_and_what_make_test_installs() -> None:
    # Facts written twice: pyproject.toml's extras and the Makefile's `make test` extras, in
    # getting-started's table and its `make test` line.
    import re

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    page = (ROOT / "docs" / "getting-started.md").read_text()
    rows = set(re.findall(r"^\| `([\w-]+)` \|", page, re.MULTILINE))
    assert rows == set(project["optional-dependencies"])
    makefile = (ROOT / "Makefile").read_text()
    installed = re.search(r"--extras ([\w,]+)\n\ttouch \$@ \$\(BUILT\)", makefile)
    assert installed is not None
    extras = [e for e in installed.group(1).split(",") if e != "test"]
    line = next(li for li in page.splitlines() if li.startswith("make test    # installs"))
    named = re.search(r"installs the (.*) extras too", line)
    assert named is not None
    assert set(re.split(r", | and ", named.group(1))) == set(extras)


def test_the_results_page_shows_commands_and_labels_as_a_user_types_them() -> None:
    # The results files record the machine's paths (/work/..., /tmp/...); the page shows the
    # commands relative to a checkout and each table's model files from their common folder.
    from khepera_gym.analysis.docgen.results import fragments, portable_labels
    from khepera_gym.analysis.docgen.results_files import as_typed

    for name, text in fragments(ROOT / "docs" / "results").items():
        for machine in ("/work/", "/home/", "/tmp/", "khepera_gym/cli.py"):
            assert machine not in text, (name, machine)
    assert as_typed("python /x/khepera_gym/learning/benchmark/random_rows.py --out /y/z") == (
        "python -m khepera_gym.learning.benchmark.random_rows --out z"
    )
    labels = ["vfh", "sb3:/a/runs/s0/model.zip", "sb3:/a/runs/s1/model.zip (sampled)"]
    assert portable_labels(labels) == [
        "vfh",
        "sb3:runs/s0/model.zip",
        "sb3:runs/s1/model.zip (sampled)",
    ]


def test_no_tracked_text_file_keeps_a_merge_conflict() -> None:
    """A merge once left ``<<<<<<<``/``>>>>>>>`` lines in the changelog."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    found = subprocess.run(
        ["git", "grep", "-n", "-I", "-E", r"^(<{7}|>{7})( |$)"],
        cwd=root,
        capture_output=True,
        text=True,
        check=False,
    )
    if found.returncode not in (0, 1):
        pytest.skip(f"not a git checkout: {found.stderr.strip()}")
    assert found.stdout == "", f"merge conflict markers:\n{found.stdout}"


def test_a_learned_formation_recorded_before_v3_names_v2_not_the_latest() -> None:
    """Files of 2026-11-28 before v3 say "formation (latest)", which a reader today takes for v3."""
    from khepera_gym.analysis.docgen.results import learning_fragment

    root = Path(__file__).resolve().parents[1] / "docs" / "results"
    files = [(p, json.loads(p.read_text(encoding="utf-8"))) for p in root.glob("learning_*.json")]
    unversioned = [d for _, d in files if not d["formation_learning"].get("version")]
    assert unversioned, "the check needs a file recorded before v3"
    page = learning_fragment(files)
    assert "(latest)" not in page
    assert page.count("formation v2,") == len(unversioned)
