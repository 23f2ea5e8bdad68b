"""The docs' facts are checked, not restated: every versioned id a reader meets names the latest
version, or is exempt; the sentences that name the latest version, the benchmark's learners, a
recipe's setting or an enum's members are generated from the code (docgen's ``facts`` blocks);
the issue-53 contradictions stay fixed.

**What is read**: the README, every docs/*.md page, examples/*.py (all of the text: a user copies
the code), and the docstrings of every module of the package.

**What counts as a versioned id** (:func:`versioned_ids`): a task's Gymnasium id with or
without its prefix, a task or PettingZoo family name, then ``-vN`` or ``_vN``, case-insensitive:
``KheperaIV-Nav-v3``, ``Avoid-v2``, ``nav_v3``, ``formation_v1``, ``Multinav-v3``; not when it is
part of a longer word (``mappo-formation-v2``), a link target (``history.md#ppo-on-avoid-v2``)
or a file name (``consensus_v1.png``; a ``.py`` module file still counts). A bare version word,
``v3`` (:func:`bare_versions`), counts when it is the latest's number: a sentence naming the
latest version by number goes stale at the next one. Figures named ``..._vN.png`` count too.

**What is exempt**:

* history: docs/changelog.md and docs/history.md, ``Version History`` sections (pages and
  docstrings);
* pages about versions: docs/dynamics.md, drive.md and fidelity.md, and controllers-v2.md (the
  measurements of the paper's controllers on v2);
* a dated measurement: a paragraph or table holding a date (``2026-11-28``) names the version
  it measured;
* v0, the paper's dynamics, in a paragraph that names the paper (the README's reproduction);
* a versioned PettingZoo module's own name in its own file;
* an example of reading a version from a name, the name followed by an arrow
  (``"KheperaIV-Nav-v0" → 0``), which must name an old version to show it;
* generated blocks (``<!-- generated: NAME -->`` ... ``<!-- end generated: NAME -->``, the
  README's env table), which are checked against the code instead;
* **a pin on purpose, under a marker**: in Markdown an HTML comment on the line before,
  ``<!-- pinned-version: why this version -->``, exempts the paragraph or fenced block that
  follows it; in Python a comment ``# pinned-version: why`` exempts its own line (at the end of
  it) or the lines after it up to the next blank line (on a line of its own). The reason must
  be given.

A failure names file:line, the id, the latest and the fix.
"""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest

import khepera_gym.pettingzoo
from khepera_gym import registry
from khepera_gym.analysis.docgen import facts

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
LATEST = registry.LATEST_VERSION

#: Pages exempt as a whole, with why.
EXEMPT_PAGES = {
    "changelog.md": "history",
    "history.md": "history",
    "dynamics.md": "a page about versions",
    "drive.md": "a page about versions",
    "fidelity.md": "a page about versions",
    "controllers-v2.md": "the measurements of the paper's controllers on v2",
}
#: The marker of a pin on purpose, in Markdown and in Python.
PIN_MD = re.compile(r"^\s*<!-- pinned-version: (?P<why>\S.*?) -->\s*$")
PIN_PY = re.compile(r"#\s*pinned-version: (?P<why>\S.*)$")
#: A name shown mapped to what is read from it (``"KheperaIV-Nav-v0"`` → 0): the name and
#: the arrow.
PARSE_EXAMPLE = re.compile(r"\S+\s*→")
#: A dated measurement's date.
DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")
#: Link targets and figure paths (their text is not prose); figures are checked on their own.
LINK_TARGET = re.compile(r"\]\([^)\s]*\)")
FIGURE = re.compile(r"images/[\w/-]+?_v(?P<version>\d+)\.(?:png|gif|jpg|svg)")
#: The file extensions that make a name a file rather than an id (a .py module file is an id).
FILE_EXTENSIONS = r"png|gif|jpe?g|svg|json|md|toml|onnx|zip|csv|pkl|mp4|c|h"
#: A heading, and the generated blocks' markers.
HEADING = re.compile(r"^(?P<level>#+) (?P<title>.*)$")
GENERATED_START = re.compile(r"^\s*<!-- (?:generated: [a-z0-9-]+|env-table:start) -->\s*$")
GENERATED_END = re.compile(r"^\s*<!-- (?:end generated: [a-z0-9-]+|env-table:end) -->\s*$")


def _id_names() -> list[str]:
    """Every name a versioned id starts with: Gymnasium ids with and without their prefix, task
    names, PettingZoo families; longest first (``KheperaIV-Nav`` before ``Nav``)."""
    names = set()
    for task, info in registry.tasks().items():
        names.add(task)
        if info.env_id is not None:
            names |= {info.env_id, info.env_id.removeprefix("KheperaIV-")}
    names |= {module.family for module in khepera_gym.pettingzoo.module_infos()}
    return sorted(names, key=len, reverse=True)


VERSIONED_ID = re.compile(
    r"(?<![\w-])(?P<id>(?P<name>" + "|".join(map(re.escape, _id_names())) + r")[-_]v"
    r"(?P<version>\d+))(?![\w-])(?!\.(?:" + FILE_EXTENSIONS + r")\b)",
    re.IGNORECASE,
)
#: A bare version word: "v3", "(v3)", "v3's"; not an id's "-v3", a path's "/v3" nor "v2.52".
BARE_VERSION = re.compile(r"(?<![\w./#-])v(?P<version>\d+)\b(?![.-]\d)")
#: A number followed by "(the default)" or "(the latest)": a sentence that must be generated.
NAMES_THE_DEFAULT = re.compile(r"v\d+`?\s*\((?:the )?(?:default|latest)\b", re.IGNORECASE)


def versioned_ids(text: str) -> list[tuple[str, int]]:
    """The versioned ids of a text: (id as written, version)."""
    return [(m.group("id"), int(m.group("version"))) for m in VERSIONED_ID.finditer(text)]


def bare_versions(text: str) -> list[int]:
    """The bare version words of a text (``v3`` → 3)."""
    return [int(m.group("version")) for m in BARE_VERSION.finditer(text)]


@dataclasses.dataclass
class Line:
    """A line of what a reader reads, with where it is and whether it is exempt."""

    path: Path
    number: int
    text: str
    exempt: str | None = None
    block: str = ""


def markdown_lines(path: Path, text: str) -> list[Line]:
    """A Markdown page's lines, each with its exemption (None when it must be checked) and the
    paragraph or fenced block it belongs to."""
    lines = [Line(path, number, line) for number, line in enumerate(text.splitlines(), 1)]
    section: tuple[int, str] | None = None  # (level, why) of an exempt section
    pinned: str | None = None
    generated = False
    fence: str | None = None
    block: list[Line] = []

    def close_block() -> None:
        joined = "\n".join(line.text for line in block)
        for line in block:
            line.block = joined
            if line.exempt is None and DATE.search(joined):
                line.exempt = "a dated measurement"
        block.clear()

    for line in lines:
        stripped = line.text.strip()
        if fence is None:
            heading = HEADING.match(line.text)
            if heading is not None:
                level = len(heading.group("level"))
                if section is not None and level <= section[0]:
                    section = None
                if "Version History" in heading.group("title"):
                    section = (level, "a Version History")
            if GENERATED_START.match(line.text):
                generated = True
            pin = PIN_MD.match(line.text)
            if pin is not None:
                pinned = f"pinned: {pin.group('why')}"
        if section is not None:
            line.exempt = section[1]
        elif generated:
            line.exempt = "a generated block"
        elif pinned is not None:
            line.exempt = pinned
        if fence is None and GENERATED_END.match(line.text):
            generated = False
        opening = re.match(r"^\s*(`{3,})", line.text)
        if fence is None and opening is not None:
            fence = opening.group(1)
        elif fence is not None and stripped == fence:
            fence = None
            block.append(line)
            close_block()
            pinned = None
            continue
        if fence is None and not stripped:
            close_block()
            pinned = None
            continue
        block.append(line)
    close_block()
    return lines


def python_docstring_lines(path: Path, text: str) -> list[Line]:
    """The lines of a Python file's docstrings (module, classes, functions)."""
    wanted: set[int] = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            first = node.body[0] if node.body else None
            if (
                isinstance(first, ast.Expr)
                and isinstance(first.value, ast.Constant)
                and isinstance(first.value.value, str)
            ):
                wanted |= set(range(first.lineno, (first.end_lineno or 0) + 1))
    return [line for line in python_lines(path, text) if line.number in wanted]


def python_lines(path: Path, text: str) -> list[Line]:
    """A Python file's lines with their exemptions: ``# pinned-version:`` markers, Version
    History sections of docstrings, the file's own module name."""
    lines = [Line(path, number, line) for number, line in enumerate(text.splitlines(), 1)]
    pinned: str | None = None
    history = False
    paragraph: list[Line] = []
    for line in lines:
        stripped = line.text.strip()
        pin = PIN_PY.search(line.text)
        if pin is not None and stripped.startswith("#"):
            pinned = f"pinned: {pin.group('why')}"
        if stripped.startswith("## "):
            history = "Version History" in stripped
        if not stripped:
            pinned = None
            for member in paragraph:
                member.block = "\n".join(m.text for m in paragraph)
            paragraph = []
        else:
            paragraph.append(line)
        if history:
            line.exempt = "a Version History"
        elif pinned is not None:
            line.exempt = pinned
        elif pin is not None:
            line.exempt = f"pinned: {pin.group('why')}"
    for member in paragraph:
        member.block = "\n".join(m.text for m in paragraph)
    return lines


def _own_module(path: Path) -> str | None:
    """A versioned PettingZoo module's own name (``formation_v1``) for its file."""
    return path.stem if re.fullmatch(r"[a-z_]+_v\d+", path.stem) else None


def problems(lines: list[Line]) -> list[str]:
    """What the facts test reports for these lines: one message a stale id, bare latest
    version, sentence naming the default, or figure of an older version."""
    found = []
    for line in lines:
        where = f"{line.path.relative_to(ROOT) if line.path.is_relative_to(ROOT) else line.path}"
        where += f":{line.number}"
        text = LINK_TARGET.sub("]()", line.text)
        if NAMES_THE_DEFAULT.search(text) and line.exempt != "a generated block":
            found.append(
                f"{where}: names the default or latest version by number; write the id "
                "without its version, or generate the sentence (docgen's facts blocks)"
            )
        if line.exempt is not None:
            continue
        for figure in FIGURE.finditer(line.text):
            version = int(figure.group("version"))
            if version != LATEST:
                found.append(
                    f"{where}: shows {figure.group(0)}, a figure of v{version} (the latest is "
                    f"v{LATEST}): make it on v{LATEST}, or date the caption with the version it "
                    "shows, or mark it <!-- pinned-version: why -->"
                )
        text = FIGURE.sub("", text)
        # How a version is read from a name ("KheperaIV-Nav-v0" → 0): an example of parsing,
        # which must name an old version to show it.
        text = PARSE_EXAMPLE.sub("→", text)
        for name, version in versioned_ids(text):
            if version == LATEST or name == _own_module(line.path):
                continue
            if version == 0 and "paper" in line.block.lower():
                continue
            found.append(
                f"{where}: {name} is not the latest (v{LATEST}): write the id without its "
                f"version (or the v{LATEST} module), or mark a pin on purpose with "
                "<!-- pinned-version: why --> (# pinned-version: why in Python) on the line before"
            )
        for version in bare_versions(VERSIONED_ID.sub("", text)):
            if version == LATEST:
                found.append(
                    f"{where}: names the latest version by number (v{version}), which goes "
                    "stale at the next one: say 'the latest', or generate the sentence "
                    "(docgen's facts blocks)"
                )
    return found


def _read_pages() -> list[Line]:
    lines = []
    for page in [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]:
        if page.name in EXEMPT_PAGES:
            continue
        lines += markdown_lines(page, page.read_text(encoding="utf-8"))
    return lines


def _read_python() -> list[Line]:
    lines = []
    for path in sorted((ROOT / "examples").glob("*.py")):
        lines += python_lines(path, path.read_text(encoding="utf-8"))
    for path in sorted((ROOT / "khepera_gym").rglob("*.py")):
        lines += python_docstring_lines(path, path.read_text(encoding="utf-8"))
    return lines


# --- the pattern itself -------------------------------------------------------------------------


def test_the_versioned_id_pattern_finds_ids_and_module_names_and_nothing_else() -> None:
    text = (
        'gym.make("KheperaIV-Nav-v3"); Avoid-v2\'s table; from khepera_gym.pettingzoo import '
        "formation_v1; nav_v3 and Multinav-v3; khepera_gym/KheperaIV-Seek-v1 (RLlib's name); "
        "formation_v2.parallel_env(); the file pettingzoo/platoon_v1.py"
    )
    assert versioned_ids(text) == [
        ("KheperaIV-Nav-v3", 3),
        ("Avoid-v2", 2),
        ("formation_v1", 1),
        ("nav_v3", 3),
        ("Multinav-v3", 3),
        ("KheperaIV-Seek-v1", 1),
        ("formation_v2", 2),
        ("platoon_v1", 1),
    ]
    not_ids = (
        "images/consensus_v1.png, bench_v1_2026-11-27.json, history.md#ppo-on-avoid-v2 (in a "
        "link), mappo-formation-v2, KheperaIV-Nav (unversioned), formation_vN, pistonball_v6, "
        "Cargo v2, khepera_gym_v2, navigation-v1"
    )
    assert versioned_ids(not_ids) == []


def test_a_name_shown_mapped_to_its_version_is_an_example_of_parsing(tmp_path: Path) -> None:
    old = f"KheperaIV-Nav-v{LATEST - 1}"
    parsing = Line(tmp_path / "x.py", 1, f'an id\'s own ("{old}" → {LATEST - 1})')
    example = Line(tmp_path / "x.py", 2, f'an id such as "{old}"')
    assert problems([parsing]) == []
    assert [p.split(": ", 1)[1].split(" ")[0] for p in problems([example])] == [old]


def test_the_bare_version_pattern_finds_version_words_only() -> None:
    assert bare_versions("v3's drive; (v2) and v0. In v1") == [3, 2, 0, 1]
    assert bare_versions("Nav-v3, nav_v3, Ray v2.52, docs/v3/, #v3, kv3, v3x") == []


def test_the_marker_pins_the_next_paragraph_or_block_only(tmp_path: Path) -> None:
    stale = f"KheperaIV-Nav-v{LATEST - 1}"
    page = (
        f"Train on `{stale}`.\n\n"
        "<!-- pinned-version: the run the history page reports -->\n"
        f"```bash\nkhepera-gym train --env {stale}\n```\n\n"
        "<!-- pinned-version: the paper's table -->\n"
        f"The paper's numbers are `{stale}`'s,\nall of them.\n\n"
        f"And `{stale}` again.\n"
    )
    found = problems(markdown_lines(tmp_path / "page.md", page))
    assert [message.split(":")[1] for message in found] == ["1", "12"]
    assert all(stale in message and "pinned-version" in message for message in found)
    # A marker without a reason is no marker.
    unmarked = page.replace(
        "<!-- pinned-version: the paper's table -->", "<!-- pinned-version: -->"
    )
    assert len(problems(markdown_lines(tmp_path / "page.md", unmarked))) == 3


def test_a_synthetic_page_with_stale_ids_fails_and_its_exemptions_pass(tmp_path: Path) -> None:
    old = LATEST - 1
    page = (
        f'# Guide\n\nRun `gym.make("KheperaIV-Avoid-v{old}")` and `formation_v{old}`.\n\n'
        f"On v{LATEST} the robot grips.\n\n"
        f"About 1.7 million steps/s: `KheperaIV-Nav-v{LATEST}` (the default).\n\n"
        f"Measured on 2026-11-28 on `KheperaIV-Nav-v{old}`.\n\n"
        "The paper's Fig. 6 on its own dynamics: `KheperaIV-Avoid-v0`.\n\n"
        f"```{{figure}} images/paper_fig6_braitenberg_vs_vfh_v{old}.png\n```\n\n"
        f"## Version History\n\n* v{old}: `KheperaIV-Nav-v{old}`.\n\n## After\n\n"
        f"`Seek-v{old}` again.\n"
    )
    found = problems(markdown_lines(tmp_path / "page.md", page))
    lines = sorted(int(message.split(":")[1]) for message in found)
    # The two stale ids, the bare latest, "(the default)", the old figure, the last stale id;
    # the dated measurement, the paper's v0 and the Version History pass.
    assert lines == [3, 3, 5, 7, 13, 22], found
    assert f"latest (v{LATEST})" in found[0] and "page.md:3" in found[0]


def test_a_python_file_pins_with_a_comment_and_exempts_its_own_module_name(
    tmp_path: Path,
) -> None:
    old = LATEST - 1
    source = (
        f'"""An example on formation_v{old} and KheperaIV-Nav-v{old}."""\n\n'
        f'ENV = "KheperaIV-Nav-v{old}"  # pinned-version: the figure docs/images shows\n'
        f"# pinned-version: the v{old} figure\n"
        f'OTHER = "KheperaIV-Avoid-v{old}"\n\n'
        f'LAST = "KheperaIV-Seek-v{old}"\n'
    )
    path = tmp_path / f"formation_v{old}.py"
    found = problems(python_lines(path, source))
    assert sorted(int(message.split(":")[1]) for message in found) == [1, 7], found


# --- the documentation as it is ------------------------------------------------------------------


def test_every_versioned_id_in_the_docs_is_the_latest_or_exempt() -> None:
    found = problems(_read_pages())
    assert not found, "\n".join(found)


def test_every_versioned_id_in_the_examples_and_docstrings_is_the_latest_or_exempt() -> None:
    found = problems(_read_python())
    assert not found, "\n".join(found)


def test_docstring_examples_make_the_unversioned_id() -> None:
    """An env's manual (what ``help()`` shows) makes its id without the version: it runs the
    latest and stays true at the next version."""
    made = re.compile(r"gym\.make(?:_vec)?\(\s*\"(?P<id>[^\"]+)\"")
    checked = 0
    for path in sorted((ROOT / "khepera_gym" / "envs").glob("*.py")):
        for line in python_docstring_lines(path, path.read_text(encoding="utf-8")):
            for match in made.finditer(line.text):
                checked += 1
                assert not re.search(r"-v\d+$", match.group("id")), (
                    f"{path.relative_to(ROOT)}:{line.number}: {match.group('id')}: write the id "
                    "without its version"
                )
    assert checked >= 20


# --- generated sentences ------------------------------------------------------------------------


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


def test_every_generated_block_is_what_the_code_says() -> None:
    """Refresh them with ``python -m khepera_gym.analysis.docgen --readme``."""
    seen = set()
    for page in _pages():
        for name, _indent, body in facts.blocks(page.read_text(encoding="utf-8")):
            assert name in facts.FRAGMENTS, f"{page.name}: unknown generated block {name!r}"
            assert body == facts.FRAGMENTS[name]().strip(), (
                f"{page.name}: the generated block {name!r} differs from the code: run "
                "`python -m khepera_gym.analysis.docgen --readme`"
            )
            seen.add(name)
    assert seen == set(facts.FRAGMENTS), f"blocks no page holds: {set(facts.FRAGMENTS) - seen}"


def test_refreshing_a_stale_block_rewrites_it_in_place() -> None:
    stale = (
        "Before.\n\n  <!-- generated: behaviour-versions -->\n  - **v0**: wrong.\n"
        "  <!-- end generated: behaviour-versions -->\n\nAfter.\n"
    )
    fresh = facts.refreshed(stale)
    assert fresh.startswith("Before.\n\n  <!-- generated: behaviour-versions -->\n")
    assert fresh.endswith("  <!-- end generated: behaviour-versions -->\n\nAfter.\n")
    assert facts.blocks(fresh) == [
        ("behaviour-versions", "  ", facts.FRAGMENTS["behaviour-versions"]())
    ]


def test_the_readme_names_every_behaviour_version_in_a_line_each() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for version in registry.versions():
        lines = [
            line for line in readme.splitlines() if line.startswith(f"- **v{version.number}**")
        ]
        assert len(lines) == 1, f"README: v{version.number} has {len(lines)} lines"
        assert version.title in lines[0]
    latest = [line for line in readme.splitlines() if "the latest" in line and "- **v" in line]
    assert latest == [next(line for line in readme.splitlines() if f"**v{LATEST}**" in line)]


def test_the_benchmark_learners_the_training_page_names_are_the_learners() -> None:
    from khepera_gym.learning.benchmark.learners import LEARNERS

    page = (DOCS / "training.md").read_text(encoding="utf-8")
    bullet = page.split("- **The learners**:", 1)[1].split("\n- **", 1)[0]
    prose = bullet.split("<!-- generated:", 1)[0]
    # The learners are the backquoted algorithm names (ppo, sac, ...; not `benchmarl`, the extra).
    named = set(re.findall(r"`([a-z_]*(?:ppo|sac|td3|a2c|dqn|ddpg|masac|maddpg))`", prose))
    assert named == set(LEARNERS)
    assert "generated: suite-learners" in bullet


def test_the_torchrl_tables_rows_are_its_multi_agent_tasks_with_their_sizes() -> None:
    pytest.importorskip("torchrl")
    from khepera_gym.learning.torchrl import KheperaTorchEnv, multi_agent_tasks

    assert facts.multi_agent_tasks() == multi_agent_tasks()
    page = (DOCS / "training.md").read_text(encoding="utf-8")
    rows = {}
    for line in page.splitlines():
        match = re.match(r'^\| `"(?P<task>[a-z]+)"` \|.*?`observation` \[N, K, (?P<d>\d+)\]', line)
        if match:
            rows[match.group("task")] = int(match.group("d"))
    assert sorted(rows) == sorted(multi_agent_tasks())
    for task, size in rows.items():
        env = KheperaTorchEnv(task, 1, seed=0)
        group = next(iter(env.group_map))
        assert env.observation_spec[group, "observation"].shape[-1] == size, task
        env.close()


def test_the_benchmarl_enum_is_the_generated_list() -> None:
    pytest.importorskip("benchmarl")
    from khepera_gym.learning.torchrl.benchmarl import KheperaTask

    assert [task.name.lower() for task in KheperaTask] == facts.multi_agent_tasks()


# --- the issue-53 contradictions stay fixed ----------------------------------------------------


def _sentences(text: str) -> list[str]:
    """A page's sentences, from its paragraphs (table rows left out), whitespace joined."""
    sentences = []
    for paragraph in re.split(r"\n\s*\n", text):
        prose = " ".join(li for li in paragraph.splitlines() if not li.lstrip().startswith("|"))
        sentences += [" ".join(s.split()) for s in re.split(r"(?<=\.)\s+(?=[A-Z*(])", prose)]
    return sentences


def _profile_claims(text: str) -> list[str]:
    """The sentences of a text that say a version drives on K-Team's speed profile while that
    version's ``motors.mode`` is not ``"profile"`` (v1: ``"ramp"``, a plain limit at the
    profile's rate), unless the sentence says it is a ramp."""
    from khepera_gym.config import tomllib

    modes = {
        version: tomllib.loads(registry.default_config("nav", version))["motors"]["mode"]
        for version in registry.task_versions("nav")
    }
    says_profile = re.compile(
        r"(?:drives? on|follows?) (?:the |K-Team's )?(?:default )?(?:speed )?profile"
        r"|the profile of §1"
    )
    names_version = re.compile(r"\b(?:v|[Vv]ersion )(?P<version>\d+)\b")
    wrong = []
    for sentence in _sentences(text):
        if not says_profile.search(sentence) or "ramp" in sentence:
            continue
        named = {int(m.group("version")) for m in names_version.finditer(sentence)}
        if any(modes.get(version, "profile") != "profile" for version in named):
            wrong.append(sentence)
    return wrong


def test_the_profile_claim_check_catches_the_old_sentences() -> None:
    old_drive = "Behaviour version 1 drives on the profile at `Acc_Inc` 3 (0.203 m/s²)."
    old_fidelity = "**Now**: from v1 on, the wheels follow K-Team's default speed profile."
    assert _profile_claims(f"{old_drive} {old_fidelity}") == [old_drive, old_fidelity]
    assert _profile_claims("From v2 on the wheels follow the profile at Acc_Inc 40.") == []


def test_no_page_says_v1_drives_on_k_teams_profile() -> None:
    """Item 1: v1's wheels ramp at the profile's *rate* (``motors.mode = "ramp"``); v2 on drives
    on the profile, at Acc_Inc 40."""
    for page in ("drive.md", "fidelity.md", "dynamics.md"):
        wrong = _profile_claims((DOCS / page).read_text(encoding="utf-8"))
        assert not wrong, f"{page}: {wrong}"


def test_the_training_page_says_which_tables_normalise() -> None:
    """Item 5: the sentence is generated from the tables."""
    page = (DOCS / "training.md").read_text(encoding="utf-8")
    assert "default tables feed raw observations" not in page
    assert "generated: recipe-normalisation" in page


def test_the_training_page_trains_in_the_recipes_own_shape() -> None:
    """Item 6: a `train` command of the docs that sets --n-envs gives rollouts its table's
    batch_size divides."""
    import shlex

    from khepera_gym.learning.recipes import load_hyperparams
    from khepera_gym.registration import resolve_env_id

    checked = 0
    for page in _pages():
        for line in page.read_text(encoding="utf-8").splitlines():
            if not line.startswith("khepera-gym train "):
                continue
            argv = shlex.split(line.split(" #")[0])
            if "--n-envs" not in argv or "--backend" in argv:
                continue
            env = resolve_env_id(argv[argv.index("--env") + 1])
            algo = argv[argv.index("--algo") + 1] if "--algo" in argv else "ppo"
            table = load_hyperparams(algo, env)
            worlds = int(argv[argv.index("--n-envs") + 1])
            if "batch_size" in table and "n_steps" in table:
                assert worlds * table["n_steps"] % table["batch_size"] == 0, (page.name, line)
            checked += 1
    assert checked >= 0


def test_the_getting_started_make_test_line_names_calibrate() -> None:
    """Item 10 (a): ``make test`` installs the calibrate extra; the guide's line says so (the
    full check is tests/test_docs.py's, against the Makefile)."""
    page = (DOCS / "getting-started.md").read_text(encoding="utf-8")
    line = next(li for li in page.splitlines() if li.startswith("make test    # installs"))
    assert "calibrate" in line


def test_the_readme_env_table_links_each_env_to_its_docs_page() -> None:
    """Item 12: the README links each env's page (which `make docs` writes), not a .py file."""
    from khepera_gym.analysis.docgen.envs import env_pages

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    table = readme.split("<!-- env-table:start -->")[1].split("<!-- env-table:end -->")[0]
    links = re.findall(r"^\| \[[^\]]+\]\(([^)]+)\)", table, re.MULTILINE)
    assert links == [f"docs/generated/envs/{page.slug}.md" for page in env_pages()]


def test_the_demo_runs_every_task_the_docs_name_on_its_latest_version() -> None:
    """Item 4: the demo ran consensus on v1 while the docs said every task's latest; the pages
    say it runs every task with a Gymnasium id and consensus's triggers, on the latest."""
    from khepera_gym.analysis.compare.command import CONSENSUS, demo_runs
    from khepera_gym.analysis.compare.consensus import check_version
    from khepera_gym.registration import latest_ids, task_of

    runs = demo_runs()
    assert {task_of(run[1]) for run in runs} == set(latest_ids())
    for run in runs:
        assert run[1] == latest_ids()[task_of(run[1])], run
    assert check_version(None) == registry.latest_version(CONSENSUS)
    page = (DOCS / "baselines.md").read_text(encoding="utf-8")
    claim = " ".join(page.split("`make demo` (`khepera-gym demo`) runs", 1)[1].split()[:30])
    assert "every task with a Gymnasium id" in claim and "consensus" in claim
    assert "all on the latest version" in claim


def _number(text: str) -> int:
    return int(text.replace(",", ""))


def _prose(page: str) -> str:
    return " ".join((DOCS / page).read_text(encoding="utf-8").split())


def _tables(algo: str) -> dict[str, dict]:
    from khepera_gym.config import tomllib

    return tomllib.loads((ROOT / "configs" / "hyperparams" / f"{algo}.toml").read_text())


def test_the_recipe_settings_the_training_page_quotes_are_the_tables() -> None:
    """Prose that quotes a recipe's setting is checked against configs/hyperparams/."""
    from khepera_gym.learning.recipes import load_hyperparams
    from khepera_gym.registration import latest_ids

    text = _prose("training.md")
    # The single-agent recipes: "(256 worlds x 32 steps), minibatches of 1,024, 4 or 5 epochs
    # and two 64 x 64 networks, observations normalised": every normalising latest table.
    single = re.search(
        r"\((?P<worlds>[\d,]+) worlds x (?P<steps>\d+) steps\), minibatches of (?P<batch>[\d,]+), "
        r"(?P<epochs>\d+(?: or \d+)*) epochs and two (?P<width>\d+) x (?P=width) networks",
        text,
    )
    assert single is not None
    epochs = {int(n) for n in single.group("epochs").split(" or ")}
    shaped = 0
    for env_id in latest_ids().values():
        table = load_hyperparams("ppo", env_id)
        if not table.get("normalize", False):
            continue
        shaped += 1
        assert table["n_envs"] == _number(single.group("worlds")), env_id
        assert table["n_steps"] == int(single.group("steps")), env_id
        assert table["batch_size"] == _number(single.group("batch")), env_id
        assert table["n_epochs"] in epochs, env_id
        width = int(single.group("width"))
        assert table["policy_kwargs"]["net_arch"] == [width, width], env_id
    assert shaped
    # The multi-agent recipes: shared PPO's "(8 worlds x 128 steps, minibatches of 512, 10
    # epochs)", MAPPO's "batches of 8,192 env steps from 32 worlds in minibatches of 512 for 10
    # epochs".
    shared = re.search(
        r"shared PPO trains in formation-followers' shape \((?P<worlds>\d+) worlds x "
        r"(?P<steps>\d+) steps, minibatches of (?P<batch>[\d,]+), (?P<epochs>\d+) epochs\)",
        text,
    )
    assert shared is not None
    for name, table in _tables("ppo").items():
        if name.endswith("-shared") or name == "formation-followers":
            assert table["n_envs"] == int(shared.group("worlds")), name
            assert table["n_steps"] == int(shared.group("steps")), name
            assert table["batch_size"] == _number(shared.group("batch")), name
            assert table["n_epochs"] == int(shared.group("epochs")), name
    mappo = re.search(
        r"MAPPO on batches of (?P<frames>[\d,]+) env steps from (?P<worlds>\d+) worlds in "
        r"minibatches of (?P<batch>[\d,]+) for (?P<epochs>\d+) epochs",
        text,
    )
    assert mappo is not None
    for name, table in _tables("mappo").items():
        assert table["frames_per_batch"] == _number(mappo.group("frames")), name
        assert table["n_envs"] == int(mappo.group("worlds")), name
        assert table["minibatch_size"] == _number(mappo.group("batch")), name
        assert table["n_epochs"] == int(mappo.group("epochs")), name
    steps = re.search(r"\((?P<steps>\d+) gradient steps a batch of (?P<frames>[\d,]+)\)", text)
    assert steps is not None
    table = next(iter(_tables("mappo").values()))
    assert _number(steps.group("frames")) == table["frames_per_batch"]
    gradient_steps = table["frames_per_batch"] // table["minibatch_size"] * table["n_epochs"]
    assert int(steps.group("steps")) == gradient_steps
    # RLlib's Nav recipe: "4096 steps per update, minibatches of 256, 10 epochs, 64-64 tanh".
    rllib = re.search(
        r"(?P<batch>\d+) steps per update, minibatches of (?P<mini>\d+), (?P<epochs>\d+) "
        r"epochs, (?P<width>\d+)-(?P=width) (?P<activation>\w+) networks",
        text,
    )
    assert rllib is not None
    nav = _tables("rllib_ppo")["KheperaIV-Nav"]
    assert nav["train_batch_size_per_learner"] == int(rllib.group("batch"))
    assert nav["minibatch_size"] == int(rllib.group("mini"))
    assert nav["num_epochs"] == int(rllib.group("epochs"))
    width = int(rllib.group("width"))
    assert nav["model"]["fcnet_hiddens"] == [width, width]
    assert nav["model"]["fcnet_activation"] == rllib.group("activation")


def test_each_version_history_line_says_it_once_and_v2_names_its_contact_keys() -> None:
    """Item 9: v0's line read "Initial version. The paper's V-REP dynamics: The KH4VREP paper's
    V-REP-like dynamics: ..."; v2's left out the three contact keys it changed."""
    from khepera_gym.config import tomllib

    for task in registry.task_names():
        for line in registry.history_lines(task):
            assert line.count("V-REP") <= 1, line
            assert line.count("Initial version") <= 1, line
    versions = {version.number: version for version in registry.versions()}
    if 2 not in versions:
        return
    contact_keys = [f"physics.{key}" for key in tomllib.loads(versions[2].before)["physics"]]
    line = next(li for li in registry.history_lines("nav") if li.startswith("* v2:"))
    for key in contact_keys:
        assert f"`{key}`" in line, (key, line)


#: The core's refusal of a value outside a string key's members (serde's message).
_VARIANTS = re.compile(r"unknown variant `[^`]*`, expected (?:one of )?(?P<members>.*)$")
#: A member quoted in prose (`ring`, "cross"), or as a value set (`= "ramp"`: `assigned`).
_QUOTED_MEMBER = re.compile(r"(?P<assigned>= )?[`\"](?P<member>[a-z_]+)[`\"]")


def _enum_keys() -> dict[str, tuple[str, ...]]:
    """Every string scenario key of every task with the members the core accepts, asked of the
    core by giving it a value it refuses."""
    from khepera_gym import _core
    from khepera_gym.config import tomllib
    from khepera_gym.errors import ConfigError

    found: dict[str, tuple[str, ...]] = {}
    for task in registry.task_names():
        for section, keys in tomllib.loads(registry.default_config(task)).items():
            for key, value in keys.items():
                if not isinstance(value, str) or f"{section}.{key}" in found:
                    continue
                try:
                    _core.Batch(task, 1, overrides={f"{section}.{key}": "not a member"})
                except ConfigError as error:
                    match = _VARIANTS.search(str(error))
                    if match is not None:
                        members = tuple(re.findall(r"`([^`]+)`", match.group("members")))
                        found[f"{section}.{key}"] = members
    return found


def enum_listings_missing_members(
    text: str, keys: dict[str, tuple[str, ...]]
) -> list[tuple[str, list[str], str]]:
    """The sentences that list a key's members (they name the key and quote at least two of
    its members other than as a value set, and at least half of them in all) but leave some
    out: (key, left out, sentence). ``mode = "ramp"`` and ``mode = "profile"`` in one sentence
    are two values, not a list."""
    wrong = []
    for sentence in _sentences(text):
        found = list(_QUOTED_MEMBER.finditer(sentence))
        quoted = {m.group("member") for m in found}
        listed = {m.group("member") for m in found if not m.group("assigned")}
        for dotted, members in keys.items():
            short = dotted.split(".")[1]
            if dotted not in sentence and not re.search(rf"\b{short}\b", sentence):
                continue
            named = quoted & set(members)
            if (
                len(listed & set(members)) >= 2
                and 2 * len(named) >= len(members)
                and named != set(members)
            ):
                wrong.append((dotted, sorted(set(members) - named), sentence))
    return wrong


def test_the_enum_listing_check_finds_a_listing_that_leaves_a_member_out() -> None:
    keys = {"consensus.graph": ("ring", "line", "complete", "geometric", "edges")}
    full = "A graph: `ring`, `line`, `complete`, `geometric` or your own `edges`."
    short = "A graph: `ring`, `line`, `complete` or `geometric`."
    assert enum_listings_missing_members(full, keys) == []
    assert enum_listings_missing_members(short, keys) == [("consensus.graph", ["edges"], short)]
    # One example, or values set, are not listings; a value set counts as named.
    assert enum_listings_missing_members('The graph `ring` (`graph = "line"`).', keys) == []
    assert enum_listings_missing_members('`graph = "ring"` and `graph = "line"`.', keys) == []
    drawn = '`graph = "edges"`; `ring`, `line`, `complete` or `geometric` fix it.'
    assert enum_listings_missing_members(drawn, keys) == []


def test_every_listing_of_a_keys_members_in_the_docs_and_manuals_is_complete() -> None:
    """Prose that quotes an enum's members (a formation's shapes, a consensus graph, a drive
    mode) names them all, as the core accepts them."""
    from khepera_gym.analysis.docgen.envs import env_pages

    keys = _enum_keys()
    assert {"formation.shape", "consensus.graph", "motors.mode"} <= set(keys)
    texts = [
        (page.name, page.read_text(encoding="utf-8"))
        for page in _pages()
        if page.name not in ("changelog.md", "history.md")
    ]
    texts += [(f"the {page.task} manual", page.manual) for page in env_pages()]
    wrong = [
        f"{name}: lists {key} without {', '.join(missing)}: {sentence}"
        for name, text in texts
        for key, missing, sentence in enum_listings_missing_members(text, keys)
    ]
    assert not wrong, "\n".join(wrong)


def test_the_readme_names_every_extra_of_the_package() -> None:
    """The README's list of extras is pyproject.toml's (getting-started's table is checked in
    tests/test_docs.py)."""
    from khepera_gym.config import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    paragraph = " ".join(readme.split("\nExtras: ", 1)[1].split("\n\n", 1)[0].split())
    listed = re.sub(r"\([^)]*\)", "", paragraph)  # the names, without what each brings
    named = set(re.findall(r"`([a-z0-9_-]+)`", listed))
    assert named == set(extras), paragraph
