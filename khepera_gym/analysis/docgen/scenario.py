"""Scenario keys as the core declares them: each key's default in every version, with the
comment (units, meaning, source) the core writes beside it in its default file.

The default file (``khepera_gym.default_config(task, version)``) is the core's own rendering of
its key declarations; this module reads it back into rows, so a documentation table of the keys
is made from the code and cannot drift from it.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from typing import Any

from khepera_gym import registry
from khepera_gym.config import tomllib

#: A source tag in a comment: [E] estimate, [S] a simulator's value, [C] confirmed by a source,
#: [D] derived by arithmetic, [D/E], optionally with the source after a colon.
SOURCE_TAG = re.compile(r"\[(?P<kind>C|D|S|E|D/E|K|M)(?::[^\]]*)?\]")
#: What each source tag means (the legend of the scenario tables).
SOURCE_TAGS = {
    "C": "confirmed by the source it names (K-Team's manual, libkhepera, a paper)",
    "D": "derived by arithmetic from confirmed values",
    "S": "the value of another simulator's model (Webots, ARGoS, V-REP), not a measurement",
    "E": "an estimate or a design choice, to be tuned",
}
#: What the core writes after a key's comment: the values the key may take (its domain).
ALLOWED = re.compile(r"; allowed: (?P<allowed>.*)$")
_SECTION = re.compile(r"^\[(?P<name>[a-z_]+)\]\s*$")
_KEY = re.compile(r"^(?P<key>[a-z_][a-z0-9_]*)\s*=\s*(?P<rest>.*)$")


@dataclasses.dataclass(frozen=True)
class Key:
    """One scenario key of a task in one version.

    Attributes:
        section: Its table (``"robot"``).
        name: Its name in the table (``"wheel_accel_limit"``).
        value: Its default, as TOML gives it.
        text: The default as the file writes it (``0.2034543``, ``["ir", "us"]``).
        comment: The comment beside it: units, meaning, source.
        allowed: The values it may take, as the core declares them (``finite, > 0, <= 1000``);
            empty for a key without numbers or lengths (a string, a flag).
    """

    section: str
    name: str
    value: Any
    text: str
    comment: str
    allowed: str = ""

    @property
    def dotted(self) -> str:
        """``section.name``, as overrides and messages name it."""
        return f"{self.section}.{self.name}"

    @property
    def tags(self) -> list[str]:
        """Its source tags, in order (``["E"]``, ``["S"]``, ``["D", "E"]``)."""
        kinds: list[str] = []
        for match in SOURCE_TAG.finditer(self.comment):
            for kind in match.group("kind").split("/"):
                if kind not in kinds:
                    kinds.append(kind)
        return kinds


def _split_value(rest: str) -> tuple[str, str]:
    """``value  # comment`` → (value text, comment), trying each ``#`` until the text before it
    is a TOML value (a ``#`` may sit inside a string)."""
    for match in re.finditer("#", rest):
        candidate = rest[: match.start()].rstrip()
        try:
            tomllib.loads(f"x = {candidate}")
        except tomllib.TOMLDecodeError:
            continue
        return candidate, rest[match.end() :].strip()
    return rest.strip(), ""


def parse_keys(text: str) -> list[Key]:
    """The keys of a default scenario file, in file order, with their comments.

    Raises:
        ValueError: A key whose value spans lines (the default files write one line a key).
    """
    values = tomllib.loads(text)
    section = ""
    keys = []
    for line in text.splitlines():
        header = _SECTION.match(line)
        if header:
            section = header.group("name")
            continue
        match = _KEY.match(line)
        if match is None or not section:
            continue
        value_text, comment = _split_value(match.group("rest"))
        allowed = ""
        found = ALLOWED.search(comment)
        if found:
            allowed = found.group("allowed")
            comment = comment[: found.start()]
        try:
            value = values[section][match.group("key")]
        except KeyError:
            raise ValueError(f"cannot read [{section}] {match.group('key')} back") from None
        keys.append(Key(section, match.group("key"), value, value_text, comment, allowed))
    read = {(k.section, k.name) for k in keys}
    declared = {(s, k) for s, table in values.items() for k in table}
    if read != declared:
        raise ValueError(f"keys not on one line each: {sorted(declared - read)}")
    return keys


@functools.cache
def task_keys(task: str, version: int) -> tuple[Key, ...]:
    """The keys of a task's default scenario in a version."""
    return tuple(parse_keys(registry.default_config(task, version)))


def header(task: str, version: int | None = None) -> str:
    """The header comment of a task's default file (what the task is), without the ``#``."""
    lines = []
    for line in registry.default_config(task, version).splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("#").strip())
    return " ".join(lines)


@dataclasses.dataclass(frozen=True)
class KeyHistory:
    """One key of a task across the versions it exists in.

    Attributes:
        latest: The key in the latest version (its comment is the one shown).
        by_version: The default's text in each version that has the key.
    """

    latest: Key
    by_version: dict[int, str]
    values: dict[int, Any]

    @property
    def changed(self) -> bool:
        """Whether some version's default differs from the latest's."""
        return any(value != self.latest.value for value in self.values.values())


def key_histories(task: str) -> list[KeyHistory]:
    """Every key of a task's latest default file with its default in each version."""
    versions = registry.task_versions(task)
    by_version = {version: {k.dotted: k for k in task_keys(task, version)} for version in versions}
    latest = by_version[versions[-1]]
    return [
        KeyHistory(
            latest=key,
            by_version={v: keys[name].text for v, keys in by_version.items() if name in keys},
            values={v: keys[name].value for v, keys in by_version.items() if name in keys},
        )
        for name, key in latest.items()
    ]


__all__ = [
    "ALLOWED",
    "SOURCE_TAG",
    "SOURCE_TAGS",
    "Key",
    "KeyHistory",
    "header",
    "key_histories",
    "parse_keys",
    "task_keys",
]
