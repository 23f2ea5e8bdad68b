"""What the ``khepera-gym`` command checks of its arguments before it simulates anything.

Each subcommand checks its arguments first (an env id, counts, seeds, an output file's format
and folder), so that a mistake costs no simulation: the output folder is created then, and a
file that cannot be written is reported at once. The errors are :class:`ConfigError` with a
message saying what to change; :func:`run_command` turns them, and the other errors a user can
cause (a missing file or extra), into one line on stderr and a non-zero exit status, never a
traceback. Part of the tools layer: imports the faces, never the reverse.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.registration import resolve_env_id

#: Largest seed (exclusive): a world's random stream is seeded with a 64-bit integer.
SEED_LIMIT = 2**64
#: What a user can cause: wrong arguments (ConfigError and the rest of KheperaError), a file
#: that cannot be read or written (OSError), an extra that is not installed (ImportError).
USER_ERRORS: tuple[type[BaseException], ...] = (KheperaError, OSError, ImportError)


def env_id(value: str) -> str:
    """The registered khepera_gym id ``value`` names (an unversioned id: its latest version).

    Raises:
        ConfigError: Not a khepera_gym id; the message suggests the nearest one.
    """
    return resolve_env_id(value)


def at_least(value: float | None, minimum: float, option: str) -> None:
    """Checks a count or size given on the command line (None: not given, nothing to check).

    Raises:
        ConfigError: ``value`` is below ``minimum``.
    """
    if value is not None and value < minimum:
        raise ConfigError(f"{option} must be >= {minimum}, got {value}")


def all_at_least(values: Sequence[float] | None, minimum: float, option: str) -> None:
    """:func:`at_least` for each of several values of one option."""
    for value in values or ():
        at_least(value, minimum, option)


def seed(value: int | None, option: str = "--seed") -> None:
    """Checks a seed: an integer in [0, 2**64) (None: not given).

    Raises:
        ConfigError: Negative or too large.
    """
    if value is not None and not 0 <= value < SEED_LIMIT:
        raise ConfigError(f"{option} must be in [0, 2**64), got {value}")


def output_folder(path: str | os.PathLike[str], option: str) -> Path:
    """Creates the folder ``path`` (and its parents) if needed and checks it can be written.

    Raises:
        ConfigError: It cannot be created (the reason is named), is a file, or is read-only.
    """
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"{option} {folder} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ConfigError(
            f"{option}: cannot create the folder {folder}: {error.strerror or error}"
        ) from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(f"{option}: cannot write into the folder {folder}")
    return folder


def output_file(path: str | os.PathLike[str], suffixes: Sequence[str], option: str) -> Path:
    """Checks an output file before it is made: its format (by suffix, one of ``suffixes``) and
    its folder (created if needed, and writable).

    Raises:
        ConfigError: Another suffix, a folder in its place, or a folder that cannot be written.
    """
    file = Path(path)
    if file.suffix.lower() not in suffixes:
        known = " or ".join(suffixes)
        got = f"{file.suffix!r}" if file.suffix else "no suffix"
        raise ConfigError(f"{option} {file}: use {known} (the suffix sets the format), got {got}")
    if file.is_dir():
        raise ConfigError(f"{option} {file} is a folder; give a file name ending in {suffixes[0]}")
    output_folder(file.parent if str(file.parent) else ".", option)
    return file


def input_file(path: str | os.PathLike[str] | None, option: str) -> None:
    """Checks that a file given on the command line exists (None: not given).

    Raises:
        ConfigError: No such file.
    """
    if path is not None and not Path(path).is_file():
        raise ConfigError(f"{option}: no such file {path}")


def did_you_mean(name: str, known: Sequence[str]) -> str:
    """The end of a message refusing ``name``: the nearest of ``known`` if one is near (in any
    case), then every one, ``did you mean 'nav'? known: nav, avoid, ...``."""
    lowered = {choice.lower(): choice for choice in known}
    near = difflib.get_close_matches(name.lower(), list(lowered), n=1, cutoff=0.6)
    hint = f"did you mean {lowered[near[0]]!r}? " if near else ""
    return f"{hint}known: {', '.join(known)}"


def one_line(error: BaseException) -> str:
    """An error's message on one line (a ConfigError from a scenario file may span several)."""
    text = " ".join(str(error).split())
    return text or type(error).__name__


def run_command(command: str, run: Callable[[], int]) -> int:
    """Runs a subcommand; a user error (:data:`USER_ERRORS`) exits with one line on stderr,
    ``khepera-gym <command>: <message>``, and status 1.

    Raises:
        SystemExit: On a user error.
    """
    try:
        return run()
    except USER_ERRORS as error:
        raise SystemExit(f"khepera-gym {command}: {one_line(error)}") from None


__all__ = [
    "SEED_LIMIT",
    "USER_ERRORS",
    "all_at_least",
    "at_least",
    "did_you_mean",
    "env_id",
    "input_file",
    "one_line",
    "output_file",
    "output_folder",
    "run_command",
    "seed",
]
