"""One hostile case from a seed and an index, reproducibly, over every public entry point.

A case is a dict: ``kind`` (what is called), ``target`` (a registered Gymnasium id or a
PettingZoo module, from the registries), and the arguments. Kinds:

* ``make``: ``gym.make(id, **overrides)``, scenario keys of the id's task and version;
* ``file``: the same keys written to a TOML file, ``gym.make(id, config=path)``;
* ``vector``: ``gym.make_vec(id, num_envs=..., num_threads=..., render_worlds=...,
  frame_size=..., autoreset_mode=..., max_episode_steps=..., **overrides)``;
* ``pettingzoo``: ``module.parallel_env(**keywords)``: the wrapper's own keywords (its
  constructor's parameters), its table keyword (``formation=...``) and scenario keys;
* ``array``: ``module.array_env(num_envs, **keywords)`` of the modules that have one;
* ``reset``, ``scene``, ``state``, ``action``, ``render``: a default env of a face (single,
  vector, PettingZoo) given a hostile seed and reset options, world index, saved state, action,
  or frame size.

Values come from :mod:`.schema` (the core's declared domains) and from lists of values that
break naive code; about half are meant to be accepted.
"""

from __future__ import annotations

import functools
import inspect
import random
from typing import Any

import numpy as np

from khepera_gym import pettingzoo as pettingzoo_package
from khepera_gym.registration import registered_ids

from .schema import GARBAGE, SPECIAL_NUMBERS, key_value, task_keys

#: Case kinds and their weights in a campaign.
KINDS = {
    "make": 28,
    "file": 14,
    "vector": 12,
    "pettingzoo": 14,
    "array": 4,
    "reset": 8,
    "scene": 5,
    "state": 5,
    "action": 5,
    "render": 5,
}
#: The sections every task shares; any other is a task's own table (``[formation]``).
SHARED = frozenset(
    (
        "robot",
        "motors",
        "arena",
        "obstacles",
        "spawn",
        "sensors",
        "task",
        "physics",
        "odometry",
        "floor",
    )
)
#: Faces an env-level case may use.
FACES = ("single", "vector", "pettingzoo")

#: Integers and near-integers for counts (num_envs, n_robots, ...).
COUNTS = (0, 1, 2, 3, 4, 8, -1, 2.5, 3.0, "2", True, None, 2**20, 2**20 + 1, 10**6, 2**64)
#: Seeds: valid ones and every kind of invalid one.
SEEDS = (
    None,
    0,
    1,
    7,
    2**32,
    2**63,
    2**64 - 1,
    2**64,
    -1,
    1.5,
    "3",
    b"3",
    [1, 2],
    (0,),
    True,
    np.int64(5),
    np.uint64(2**64 - 1),
    np.float64(2.0),
    np.array(3),
    object,
)


@functools.cache
def gym_ids() -> tuple[tuple[str, str, int], ...]:
    """(id, task, version) of every registered Gymnasium id."""
    out = []
    for task, ids in registered_ids().items():
        for env_id in ids:
            out.append((env_id, task, int(env_id.rsplit("-v", 1)[1])))
    return tuple(out)


@functools.cache
def pettingzoo() -> tuple[Any, ...]:
    """Every PettingZoo module of khepera_gym (``khepera_gym.pettingzoo.module_infos``)."""
    return tuple(pettingzoo_package.module_infos())


def pettingzoo_module(name: str) -> Any:
    return next(m for m in pettingzoo() if m.name == name)


@functools.cache
def own_keywords(module_name: str) -> tuple[str, ...]:
    """The named keywords of a PettingZoo module's env class (its own and its bases')."""
    names: list[str] = []
    for cls in pettingzoo_module(module_name).env_class.__mro__:
        init = cls.__dict__.get("__init__")
        if init is None:
            continue
        for param in inspect.signature(init).parameters.values():
            if param.name != "self" and param.kind in (
                param.POSITIONAL_OR_KEYWORD,
                param.KEYWORD_ONLY,
            ):
                names.append(param.name)
        names += list(getattr(cls, "KEYS", ()))
    return tuple(dict.fromkeys(names))


def overrides(rng: random.Random, task: str, version: int, count: int | None = None) -> dict:
    """Scenario keys as keyword overrides: dotted names, leaf names or section tables."""
    keys = task_keys(task, version)
    chosen = rng.sample(keys, k=count if count is not None else rng.choice([1, 1, 1, 2, 2, 3, 5]))
    out: dict[str, Any] = {}
    for key in chosen:
        value = key_value(rng, key, valid=rng.random() < 0.7)
        form = rng.random()
        if form < 0.6:
            out[key.dotted] = value
        elif form < 0.8:
            out.setdefault(key.section, {})
            if isinstance(out[key.section], dict):
                out[key.section][key.name] = value
        else:
            out[key.name] = value
    if rng.random() < 0.03:
        out[rng.choice(["nonsense", "robot.nonsense", "task.max_steps.x"])] = 1
    return out


def sections(rng: random.Random, task: str, version: int) -> dict[str, dict[str, Any]]:
    """Scenario keys grouped by section, for a TOML file."""
    out: dict[str, dict[str, Any]] = {}
    for key in rng.sample(task_keys(task, version), k=rng.choice([1, 2, 3, 5])):
        out.setdefault(key.section, {})[key.name] = key_value(rng, key, rng.random() < 0.7)
    return out


def any_of(rng: random.Random, valid: tuple, hostile: tuple = COUNTS) -> Any:
    return rng.choice(valid) if rng.random() < 0.85 else rng.choice(hostile + GARBAGE)


def frame_size(rng: random.Random) -> Any:
    if rng.random() < 0.5:
        return (rng.choice([16, 32, 64]), rng.choice([16, 48]))
    return rng.choice(
        [
            (float("inf"), 16),
            (16.5, 16),
            (0, 0),
            (15, 16),
            (4097, 16),
            (10**9, 10**9),
            (-16, 16),
            ("16", 16),
            (16,),
            (16, 16, 3),
            16,
            "16x16",
            None,
            (np.int32(32), np.int64(32)),
            (True, 16),
        ]
    )


def draw_case(seed: int, index: int) -> dict[str, Any]:
    """Case ``index`` of a campaign seeded ``seed`` (the same on every run and machine)."""
    rng = random.Random(f"hostile:{seed}:{index}")
    kind = rng.choices(list(KINDS), weights=list(KINDS.values()))[0]
    env_id, task, version = rng.choice(gym_ids())
    case: dict[str, Any] = {"kind": kind, "seed": seed, "index": index, "rng": rng.getrandbits(32)}
    if kind == "make":
        case.update(target=env_id, kwargs=overrides(rng, task, version))
    elif kind == "file":
        case.update(target=env_id, sections=sections(rng, task, version))
        case["mangle"] = rng.choice(["none"] * 8 + ["truncate", "junk", "duplicate", "bytes"])
    elif kind == "vector":
        kwargs = {
            "num_envs": any_of(rng, (1, 2, 3, 4, 8)),
            "num_threads": any_of(rng, (None, 1, 2)),
            "render_worlds": any_of(rng, (1, 2, 4)),
            "autoreset_mode": any_of(rng, ("NextStep", "Disabled"), ("SameStep", 3, None)),
        }
        if rng.random() < 0.3:
            kwargs["frame_size"] = frame_size(rng)
            kwargs["render_mode"] = rng.choice([None, "rgb_array", "rgb", 3])
        if rng.random() < 0.2:
            kwargs["max_episode_steps"] = any_of(rng, (None, 10, 50))
        kwargs = {k: v for k, v in kwargs.items() if rng.random() < 0.8}
        if rng.random() < 0.5:
            kwargs.update(overrides(rng, task, version, 1))
        case.update(target=env_id, kwargs=kwargs)
    elif kind in ("pettingzoo", "array"):
        modules = [
            m for m in pettingzoo() if kind == "pettingzoo" or hasattr(m.module, "array_env")
        ]
        module = rng.choice(modules)
        kwargs = {}
        for name in own_keywords(module.name):
            if rng.random() < 0.2 and not (kind == "array" and name == "max_cycles"):
                kwargs[name] = pettingzoo_keyword(rng, name, module)
        own = [k for k in task_keys(module.task, module.version) if k.section not in SHARED]
        if own and rng.random() < 0.25:
            tables = [{key.name: key_value(rng, key, rng.random() < 0.6)} for key in own[:3]]
            hostile = [5, 0, "cross", [1], None, {}, {"nonsense": 1}, *GARBAGE]
            kwargs[own[0].section] = rng.choice(hostile + tables)
        if rng.random() < 0.5:
            kwargs.update(overrides(rng, module.task, module.version, 1))
        if kind == "array":
            kwargs["num_envs"] = any_of(rng, (1, 2, 3))
            kwargs.pop("render_mode", None)
        case.update(target=module.name, kwargs=kwargs)
    else:
        face = rng.choice(FACES)
        if face == "pettingzoo":
            case["target"] = rng.choice(pettingzoo()).name
        else:
            case["target"] = env_id
        case["face"] = face
        case["num_envs"] = rng.choice([1, 2, 3])
        if kind == "reset":
            case["reset_seed"] = rng.choice(SEEDS)
            case["options"] = rng.choice(
                [None, None, {}, {"reset_mask": None}, 5, "x", [("a", 1)], {"other": 1}]
            )
            if face == "vector" and rng.random() < 0.5:
                case["reset_seed"] = rng.choice(
                    [[0, 1, 2][: case["num_envs"]], [None] * case["num_envs"], [-1, 0, 0], [1.5]]
                )
        elif kind == "scene":
            case["scene_index"] = rng.choice(
                [None, 0, 1, 2, -1, 1.5, "0", True, 2**64, np.int64(1), np.float32(0.0), [0]]
            )
        elif kind == "state":
            case["mangle"] = rng.choice(
                ["none", "truncate", "flip", "append", "empty", "other", "random", "type"]
            )
        elif kind == "action":
            case["action"] = rng.choice(
                ["nan", "inf", "huge", "shape", "strings", "none", "object", "valid", "list"]
            )
        elif kind == "render":
            case["frame_size"] = frame_size(rng)
    return case


def pettingzoo_keyword(rng: random.Random, name: str, module: Any) -> Any:
    """A value for a PettingZoo wrapper's keyword ``name``: the scenario key of the same name
    when the task has one, else a plausible or hostile value by the keyword's role."""
    for key in task_keys(module.task, module.version):
        if key.name == name and key.section not in ("robot", "sensors"):
            return key_value(rng, key, rng.random() < 0.75)
    plausible = {
        "config": (None, module.task, "nosuch", "x.toml", 3),
        "action_type": ("wheels", "unicycle", "legs", 1),
        "max_cycles": (None, 5, 20, 0, -1, 2.5, "10", 2**40),
        "render_mode": (None, "rgb_array", "human2", 0),
        "frame_size": ((32, 32), (0, 32), (float("nan"), 32), "big"),
        "n_followers": (1, 2, 4, 16, 17, 0, -1, 2.5, "4"),
        "n_robots": (1, 2, 4, 32, 33, 1025, 0, -1, 2.5, "4", 10**6),
        "shape": ("cross", "line", "wedge", "circle", "custom", "star", 5),
        "leader": ("scripted", "agent", "nobody", 1),
        "robots": (1, 2, 3, 16, 17, 0, -1, 2.5),
        "time_gap": (1.0, 2.0, 0.0, -1.0, float("nan"), float("inf"), 1e30),
    }
    choices = plausible.get(name)
    if choices is None:
        return rng.choice((None, 1, 0.5, "x", *SPECIAL_NUMBERS[:6]))
    return rng.choice(choices)


__all__ = ["FACES", "KINDS", "draw_case", "gym_ids", "pettingzoo", "pettingzoo_module"]
