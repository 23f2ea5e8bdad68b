"""Writing C text: numbers as C constants that read back exactly, arrays of them, comments
wrapped to the line length, and the files of ``khepera_gym/robot/export/templates/`` with their
``$``-placeholders (``string.Template``). Shared by the policy writer
(:mod:`~khepera_gym.robot.export.c_policy`), the rest of the export
(:mod:`~khepera_gym.robot.export.c_writer`) and the calibration program. Threading: none.
"""

from __future__ import annotations

import importlib.resources
import math
import string
import textwrap
from collections.abc import Iterable

import numpy as np

from khepera_gym.errors import ConfigError


def c_float(value: float) -> str:
    """A float32 literal that reads back as exactly ``np.float32(value)``."""
    number = float(np.float32(value))
    if not math.isfinite(number):
        raise ConfigError(f"cannot write the non-finite value {number} as a C constant")
    text = f"{number:.9g}"
    if not any(mark in text for mark in ".en"):
        text += ".0"
    return text + "f"


def c_double(value: float) -> str:
    """A double literal that reads back as exactly ``value``."""
    if not math.isfinite(value):
        raise ConfigError(f"cannot write the non-finite value {value} as a C constant")
    text = f"{value:.17g}"
    return text if any(mark in text for mark in ".en") else text + ".0"


def c_array(values: Iterable[str], indent: str = "    ", per_line: int = 6) -> str:
    """Comma-separated values, ``per_line`` to a line."""
    items = list(values)
    lines = [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]
    return (",\n" + indent).join(lines)


def load_template(name: str) -> string.Template:
    """A file of khepera_gym/robot/export/templates/ ($-placeholders, see string.Template)."""
    text = importlib.resources.files("khepera_gym.robot.export").joinpath("templates", name)
    return string.Template(text.read_text("utf-8"))


def wrap_comment(text: str, indent: str) -> str:
    """A ``/* ... */`` comment of ``text`` wrapped to 100 columns."""
    lines = textwrap.wrap(text, 100 - len(indent) - 3)
    return "\n".join(
        indent + ("/* " if i == 0 else "   ") + line + (" */" if i == len(lines) - 1 else "")
        for i, line in enumerate(lines)
    )


__all__ = ["c_array", "c_double", "c_float", "load_template", "wrap_comment"]
