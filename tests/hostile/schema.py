"""Scenario keys as hostile input: every key of a task's default file with the domain the core
declares after its comment (``allowed: finite, > 0, <= 1000``), and values drawn for it.

Nothing here lists keys by hand: the keys, defaults and domains come from
``_core.default_config(task, version)``, read by the docs' own parser
(:func:`khepera_gym.analysis.docgen.scenario.parse_keys`), so a new key or task is fuzzed as soon as
it is declared. A drawn value is either meant to be accepted (inside the domain: a bound, the
default, a random value) or not (just beyond a bound, NaN, an infinity, a huge number, a wrong
type or length); the campaign does not rely on which, since whether a scenario builds also
depends on the other keys: it checks that the outcome is an env that works or a typed error.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import random
import re
from typing import Any

from khepera_gym import registry
from khepera_gym.analysis.docgen.scenario import parse_keys

#: Numbers that break naive code: signed zeros, subnormals, float32's edge, huge, infinite.
SPECIAL_NUMBERS = (
    0.0,
    -0.0,
    -1.0,
    5e-324,
    1e-45,
    1e-30,
    1e6,
    1e10,
    1e19,
    1e20,
    3.4e38,
    3.5e38,
    1e300,
    math.inf,
    -math.inf,
    math.nan,
    -1,
    2**31,
    2**32,
    2**63,
    2**64,
    -(2**63) - 1,
)
#: Values of every other kind.
GARBAGE = ("", "x", "nan", "1", True, None, [], {}, {"a": 1}, [1, "a"], [[1, 2], [3]], b"\x00")


@dataclasses.dataclass(frozen=True)
class Domain:
    """A key's domain as the default file writes it, read back."""

    low: float | None = None
    low_inclusive: bool = True
    high: float | None = None
    high_inclusive: bool = True
    infinite: bool = False
    whole: bool = False
    #: The key's own length (``[f32; 3]``).
    entries: int | None = None
    #: Each entry's length (``Vec<[f32; 2]>``).
    entry_numbers: int | None = None
    min_entries: int = 0
    max_entries: int | None = None
    #: The fields of a list of tables (``floor.lines``), by name.
    fields: tuple[tuple[str, Domain], ...] = ()


def parse_domain(text: str) -> Domain:
    """Reads what the core writes after ``allowed:`` (see ``Domain::describe`` in Rust)."""
    if text.startswith("each entry: "):
        fields = []
        for part in text[len("each entry: ") :].split("; "):
            name, _, rest = part.partition(" (")
            fields.append((name, parse_domain(rest.rstrip(")"))))
        return Domain(fields=tuple(fields))
    values: dict[str, Any] = {}
    for part in (p.strip() for p in text.split(", ") if p.strip()):
        number = r"(-?[0-9.e+-]+|inf)"
        if part == "finite or inf":
            values["infinite"] = True
        elif part == "whole":
            values["whole"] = True
        elif m := re.fullmatch(rf"(>=|>) {number}", part):
            values["low"], values["low_inclusive"] = float(m[2]), m[1] == ">="
        elif m := re.fullmatch(rf"(<=|<) {number}", part):
            values["high"], values["high_inclusive"] = float(m[2]), m[1] == "<="
        elif m := re.fullmatch(r"entries of (\d+) numbers", part):
            values["entry_numbers"] = int(m[1])
        elif m := re.fullmatch(r"(\d+) entries", part):
            values["entries"] = int(m[1])
        elif m := re.fullmatch(r"at most (\d+) entries", part):
            values["max_entries"] = int(m[1])
        elif m := re.fullmatch(r"at least (\d+) entries", part):
            values["min_entries"] = int(m[1])
        elif m := re.fullmatch(r"(\d+) to (\d+) entries", part):
            values["min_entries"], values["max_entries"] = int(m[1]), int(m[2])
    return Domain(**values)


@dataclasses.dataclass(frozen=True)
class ScenarioKey:
    """One key of a task's scenario in one version."""

    section: str
    name: str
    default: Any
    comment: str
    domain: Domain
    #: Words of its comment: the choices of a string key are among them.
    words: tuple[str, ...]

    @property
    def dotted(self) -> str:
        return f"{self.section}.{self.name}"


@functools.cache
def task_keys(task: str, version: int) -> tuple[ScenarioKey, ...]:
    """Every key of ``task``'s default scenario in ``version``, with its domain."""
    keys = []
    for key in parse_keys(registry.default_config(task, version)):
        words = tuple(sorted(set(re.findall(r"[a-z][a-z_0-9]+", key.comment))))
        keys.append(
            ScenarioKey(
                key.section, key.name, key.value, key.comment, parse_domain(key.allowed), words
            )
        )
    return tuple(keys)


# --- values -------------------------------------------------------------------------------------


def _bounds(domain: Domain) -> tuple[float, float]:
    """A finite interval inside the domain to draw from."""
    low = domain.low if domain.low is not None else -1e3
    high = domain.high if domain.high is not None else max(low + 1.0, 1e3)
    return low, high


def number_inside(rng: random.Random, domain: Domain, default: Any, integer: bool) -> Any:
    """A number the domain allows: a bound, the default, near the default, or anywhere."""
    low, high = _bounds(domain)
    choice = rng.random()
    if choice < 0.15 and domain.low is not None and domain.low_inclusive:
        value = low
    elif choice < 0.3 and domain.high is not None and domain.high_inclusive:
        value = high
    elif choice < 0.65 and isinstance(default, (int, float)) and math.isfinite(default):
        value = default * rng.uniform(0.5, 1.5) if default else rng.uniform(low, min(high, 1.0))
    elif choice < 0.85 and low > 0:
        value = math.exp(rng.uniform(math.log(low), math.log(high)))
    else:
        value = rng.uniform(low, high)
    value = min(max(value, low), high)
    if domain.low is not None and not domain.low_inclusive and value <= low:
        value = low + (high - low) * 0.5
    if domain.high is not None and not domain.high_inclusive and value >= high:
        value = low + (high - low) * 0.5
    if integer or domain.whole:
        return round(value)
    return value


def number_outside(rng: random.Random, domain: Domain, integer: bool) -> Any:
    """A number the domain refuses (or an edge of float32 it might not expect)."""
    options: list[Any] = list(SPECIAL_NUMBERS)
    if domain.low is not None:
        step = max(abs(domain.low) * 1e-6, 1e-9)
        options += [domain.low - step, domain.low - 1, domain.low] * 3
    if domain.high is not None:
        step = max(abs(domain.high) * 1e-6, 1e-9)
        options += [domain.high + step, domain.high * 2 + 1, domain.high] * 3
    value = rng.choice(options)
    if integer and isinstance(value, float) and math.isfinite(value) and rng.random() < 0.7:
        return int(value)
    return value


def number(rng: random.Random, domain: Domain, default: Any, valid: bool) -> Any:
    integer = isinstance(default, int) and not isinstance(default, bool)
    if valid:
        return number_inside(rng, domain, default, integer)
    return number_outside(rng, domain, integer)


def closed_curve(rng: random.Random, count: int, timed: bool, radius: float) -> list[list[float]]:
    """A closed loop of ``count`` points (the last repeats the first) around the origin, with
    times first when ``timed`` (``track.waypoints``)."""
    count = max(count, 2)
    points = []
    for i in range(count - 1):
        angle = 2 * math.pi * i / (count - 1)
        r = radius * rng.uniform(0.6, 1.0)
        points.append([r * math.cos(angle), r * math.sin(angle)])
    points.append(list(points[0]))
    if timed:
        period = rng.uniform(5.0, 60.0)
        return [[period * i / (count - 1), *p] for i, p in enumerate(points)]
    return points


def number_list(rng: random.Random, key: ScenarioKey, valid: bool) -> list[Any]:
    """A list of numbers, or of entries of numbers (points), for a list key."""
    d = key.domain
    if d.entry_numbers is not None:
        most = d.max_entries if d.max_entries is not None else 64
        if valid and re.search(r"points|waypoints|offsets", key.name) and rng.random() < 0.6:
            count = rng.choice([4, 5, 8, 16, rng.randint(2, min(most, 200))])
            if key.name == "offsets":
                return [[rng.uniform(0.2, 1.5), rng.uniform(-3.2, 3.2)] for _ in range(count)][
                    : min(most, 16)
                ]
            return closed_curve(rng, count, d.entry_numbers == 3, rng.uniform(0.1, 1.2))
        count = rng.choice([0, 1, 2, 3, 4, rng.randint(0, min(most, 64)), most, most + 1])
        width = d.entry_numbers if valid or rng.random() < 0.6 else rng.choice([1, 3, 4])
        return [
            [number(rng, d, 0.0, valid or rng.random() < 0.7) for _ in range(width)]
            for _ in range(count)
        ]
    size = d.entries
    if size is None:
        size = rng.choice([0, 2, 3, 4]) if not valid else rng.choice([0, 3, 6])
    elif not valid and rng.random() < 0.5:
        size = rng.choice([size - 1, size + 1, 0, size * 2])
    template = key.default[0] if key.default else 0.0
    if isinstance(template, bool):
        return [rng.random() < 0.8 for _ in range(max(size, 0))]
    return [number(rng, d, template, valid or rng.random() < 0.7) for _ in range(max(size, 0))]


#: Fields of each obstacle kind (the comment of ``obstacles.fixed`` says them too).
OBSTACLE_FIELDS = {
    "circle": ("center", "radius"),
    "box": ("center", "half_extents", "angle"),
    "segment": ("a", "b"),
}


def field_value(rng: random.Random, name: str, domain: Domain, valid: bool) -> Any:
    if domain.entries is not None or domain.entry_numbers is not None or domain.max_entries:
        key = ScenarioKey("", name, [], "", domain, ())
        return number_list(rng, key, valid)
    default = 0.5 if domain.low is None or domain.low <= 0.5 else domain.low
    return number(rng, domain, default, valid)


def table_list(rng: random.Random, key: ScenarioKey, valid: bool) -> list[dict[str, Any]]:
    """Entries of a list of tables (``obstacles.fixed``, ``floor.lines``, ...)."""
    fields = dict(key.domain.fields)
    entries = []
    for _ in range(rng.choice([0, 1, 1, 2, 3, 5, rng.randint(0, 40)])):
        entry: dict[str, Any] = {}
        names = list(fields)
        if key.name == "fixed":
            kind = rng.choice([*OBSTACLE_FIELDS, "blob"] if not valid else list(OBSTACLE_FIELDS))
            entry["kind"] = kind
            names = list(OBSTACLE_FIELDS.get(kind, ("center",)))
            names += [n for n in ("reflectance", "color") if rng.random() < 0.3]
        for name in names:
            if name in fields and (valid or rng.random() < 0.9):
                entry[name] = field_value(rng, name, fields[name], valid or rng.random() < 0.6)
        if key.name == "tracks" and rng.random() < 0.5:
            entry["closed"] = rng.random() < 0.5
        if key.name == "arcs" and valid and "start" in entry and "end" in entry:
            entry["start"], entry["end"] = sorted((entry["start"], entry["end"]))
        if not valid and rng.random() < 0.2:
            entry[rng.choice(["extra", "kind", "width"])] = rng.choice(GARBAGE)
        entries.append(entry)
    return entries


def key_value(rng: random.Random, key: ScenarioKey, valid: bool) -> Any:
    """A value for ``key``: meant to be accepted when ``valid``, else meant to be refused."""
    default = key.default
    if not valid and rng.random() < 0.15:
        return rng.choice(GARBAGE)
    if isinstance(default, bool):
        return rng.random() < 0.5 if valid else rng.choice(GARBAGE + SPECIAL_NUMBERS)
    if isinstance(default, (int, float)):
        if isinstance(default, float) and rng.random() < 0.2:
            low, high = sorted(number(rng, key.domain, default, valid) for _ in range(2))
            return (
                [low, high]
                if valid or rng.random() < 0.5
                else [high, low, low][: rng.randint(1, 3)]
            )
        return number(rng, key.domain, default, valid)
    if isinstance(default, str):
        if key.dotted == "floor.image":
            return {"__png__": png_spec(rng, valid)}
        choices = [default, *key.words] if valid else [*key.words, "", "x" * 40, "nan"]
        return rng.choice(choices)
    if isinstance(default, list):
        if key.domain.fields:
            return table_list(rng, key, valid)
        if default and isinstance(default[0], str):
            pool = sorted({*default, *key.words})
            return rng.sample(pool, k=rng.randint(0, min(len(pool), 4)))
        return number_list(rng, key, valid)
    return rng.choice(GARBAGE)


def png_spec(rng: random.Random, valid: bool) -> dict[str, Any]:
    """A floor image the executor writes before the case runs: its size and how it is broken."""
    kind = "valid" if valid else rng.choice(["valid", "huge", "truncated", "garbage", "missing"])
    side = rng.choice([1, 2, 16, 64, 200])
    if kind == "huge":
        side = rng.choice([4097, 65535, 2**31 - 1])
    return {"kind": kind, "width": side, "height": rng.choice([side, 1, 3])}


__all__ = ["Domain", "ScenarioKey", "key_value", "parse_domain", "task_keys"]
