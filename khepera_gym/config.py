"""Resolution of the ``config=`` argument of the environments into scenario text for the Rust core.

A scenario is a TOML file overlaid by the Rust core on the task's built-in defaults (see
``configs/*.toml``, embedded in the extension, so installed wheels have them). ``config`` may be:

* ``None``: the task's built-in defaults;
* a built-in scenario name: a task's name (its defaults) or a scene (``"paper_fig6"``, ...),
  overlaid on the task's defaults like a file (:func:`khepera_gym.scenes` lists the scenes,
  ``khepera-gym list scenes`` prints them);
* a path (``str`` or ``os.PathLike``) to a ``.toml`` file.

Keys are validated by the Rust core: unknown keys and impossible values raise
:class:`~khepera_gym.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path
from typing import Any

from khepera_gym import _core
from khepera_gym._inputs import check_int
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.registry import LATEST_VERSION, builtin_config_names

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

#: Source name the Rust core uses in messages when no scenario file is given.
BUILT_IN_SOURCE = "<built-in>"

ConfigArg = str | os.PathLike[str] | None


@functools.cache
def _builtin_config_text(name: str) -> str | None:
    try:
        return _core.default_config(name)
    except (KheperaError, ValueError, KeyError):
        return None


def builtin_config_text(name: str) -> str:
    """The TOML text of a built-in scenario.

    Raises:
        ConfigError: ``name`` is not a built-in scenario (the message lists the known names).
    """
    text = _builtin_config_text(name)
    if text is None:
        known = ", ".join(builtin_config_names())
        raise ConfigError(f"unknown built-in scenario {name!r}; known names: {known}")
    return text


def _looks_like_path(config: str) -> bool:
    return config.endswith(".toml") or os.sep in config or "/" in config or os.path.exists(config)


def resolve_config(config: ConfigArg, task: str) -> tuple[str | None, str]:
    """Turn a ``config=`` argument into ``(config_text, config_name)`` for ``_core.Batch``.

    Args:
        config: ``None``, a built-in scenario name, or a path to a TOML file.
        task: The environment's task ("nav", ...); its own built-in name needs no text, as the
            Rust core starts from the task's defaults anyway.

    Returns:
        ``(None, "<built-in>")`` for the task's defaults, else the TOML text and where it came from
        (the file path, or ``"<built-in:NAME>"``), used by the Rust core in error messages.

    Raises:
        ConfigError: Unknown built-in name, a missing or unreadable file, or a wrong argument type.
    """
    if config is None:
        return None, BUILT_IN_SOURCE
    if isinstance(config, str) and not _looks_like_path(config):
        if config == task:
            return None, BUILT_IN_SOURCE
        if _builtin_config_text(config) is None:
            known = ", ".join(builtin_config_names())
            raise ConfigError(
                f"config={config!r} is neither a built-in scenario nor a file; built-in names: "
                f"{known}; or give the path of a .toml file"
            )
        return builtin_config_text(config), f"<built-in:{config}>"
    if isinstance(config, (str, os.PathLike)):
        path = Path(config)
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise ConfigError(f"{os.fspath(path)}: scenario file not found") from None
        except (OSError, ValueError) as error:  # ValueError: not UTF-8, or a NUL in the path
            raise ConfigError(f"{os.fspath(path)}: cannot read scenario file: {error}") from None
        return text, os.fspath(path)
    raise ConfigError(
        f"config must be None, a built-in scenario name or a path to a .toml file, "
        f"got {type(config).__name__}"
    )


def parse_key_values(items: list[str], option: str) -> dict[str, Any]:
    """Command-line items ``KEY=VALUE`` (of ``option``, e.g. ``--set``) as a dict: VALUE read as
    a TOML value (``0.1``, ``true``, ``[1, 2]``, ``"ccw"``, ``{net_arch=[32, 32]}``), or else
    taken as a string (``square``, ``lin_1e-3``). The one parser of every command's overrides.

    Raises:
        ConfigError: An item without ``=`` or with an empty key, or a key given twice.
    """
    values: dict[str, Any] = {}
    for item in items:
        key, equals, text = item.partition("=")
        key = key.strip()
        if not equals or not key:
            raise ConfigError(f"{option} {item!r}: expected KEY=VALUE")
        if key in values:
            raise ConfigError(f"{option}: key {key!r} is given twice")
        try:
            values[key] = tomllib.loads(f"value = {text.strip()}")["value"]
        except tomllib.TOMLDecodeError:
            values[key] = text.strip()
    return values


def toml_value(value: Any, where: str = "TOML") -> str:
    """``value`` (bool, number, string, list or dict of them) written as a TOML value: the
    inverse of what :func:`parse_key_values` reads.

    Raises:
        ConfigError: A value TOML cannot hold (``where`` says what was being written).
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v, where) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v, where)}" for k, v in value.items()) + "}"
    raise ConfigError(f"cannot write {value!r} into {where}")


__all__ = [
    "BUILT_IN_SOURCE",
    "builtin_config_names",
    "builtin_config_text",
    "parse_key_values",
    "resolve_config",
    "toml_value",
]


#: Action types understood by the Rust core: normalised (left, right) wheel speeds, or (v, ω).
ACTION_TYPES = ("wheels", "unicycle")
#: Most worlds of one batch (the core's limit; it also refuses a batch whose worlds would need
#: more than 16 GiB, naming the memory, and raises MemoryError when the system refuses it).
MAX_WORLDS = 1 << 20
#: Most threads of a batch's pool.
MAX_THREADS = 1024
#: Scenario key of the episode length (Gymnasium's ``max_episode_steps``, PettingZoo's
#: ``max_cycles``).
MAX_STEPS_KEY = "max_steps"
#: The keyword (not a scenario key) that picks a behaviour version's defaults: the registered
#: ``KheperaIV-Nav-v1`` passes ``version=0``; None or absent: the latest.
VERSION_KEY = "version"


def check_version(version: object) -> int | None:
    """``version`` as an int in ``0..=LATEST_VERSION``, or None (the latest).

    Raises:
        ConfigError: Not an int, or no such version.
    """
    if version is None:
        return None
    if isinstance(version, bool) or not isinstance(version, int):
        raise ConfigError(f"version must be an int, got {type(version).__name__}")
    if not 0 <= version <= LATEST_VERSION:
        raise ConfigError(
            f"behaviour version {version} does not exist; versions are 0..{LATEST_VERSION}"
        )
    return version


def make_batch(
    task: str,
    num_worlds: int,
    config: ConfigArg,
    overrides: dict[str, object],
    *,
    action_type: str = "wheels",
    num_threads: int | None = None,
    autoreset: bool = True,
    episode_steps: tuple[str, int | None] | None = None,
    version: int | None = None,
) -> _core.Batch:
    """The ``_core.Batch`` every env class builds on: checks the action type, merges an
    episode-length argument into the overrides, resolves ``config`` and builds the batch.

    Args:
        task: Task name in the Rust core.
        num_worlds: Worlds in the batch.
        config: None, a built-in scenario name or a TOML path (see :func:`resolve_config`).
        overrides: Scenario keys overriding the file (not modified).
        action_type: "wheels" or "unicycle".
        num_threads: Threads of the batch's pool; None uses every core.
        autoreset: Gymnasium NEXT_STEP autoreset (vector env) or none (single env, SB3, PettingZoo).
        episode_steps: (argument name, value) of an episode-length argument such as
            ``("max_episode_steps", 200)``, merged as ``max_steps``; None or a None value: none.
        version: Behaviour version whose defaults apply (None: the latest); a ``version``
            entry in ``overrides`` (how registered ids pass it through every env class) takes
            precedence.

    Raises:
        ConfigError: Unknown action type, ``num_worlds`` or ``num_threads`` not an int in range
            (1..2**20, 1..1024), both the argument and ``max_steps`` given, or any scenario
            error from the core (which names the memory a batch too large for 16 GiB needs).
        MemoryError: The system refuses the memory the batch needs.
    """
    if not isinstance(action_type, str) or action_type not in ACTION_TYPES:
        raise ConfigError(f"action_type must be one of {ACTION_TYPES}, got {action_type!r}")
    num_worlds = check_int(num_worlds, "num_envs", 1, MAX_WORLDS)
    if num_threads is not None:
        num_threads = check_int(num_threads, "num_threads", 1, MAX_THREADS)
    overrides = dict(overrides)
    version = check_version(overrides.pop(VERSION_KEY, version))
    if episode_steps is not None and episode_steps[1] is not None:
        name, value = episode_steps
        if MAX_STEPS_KEY in overrides:
            raise ConfigError(
                f"give either {name} or {MAX_STEPS_KEY}, not both "
                f"(got {value} and {overrides[MAX_STEPS_KEY]})"
            )
        overrides[MAX_STEPS_KEY] = value
    config_text, config_name = resolve_config(config, task)
    return _core.Batch(
        task,
        num_worlds,
        config_text=config_text,
        config_name=config_name,
        overrides=overrides or None,
        action_type=action_type,
        num_threads=num_threads,
        autoreset=autoreset,
        version=version,
    )
