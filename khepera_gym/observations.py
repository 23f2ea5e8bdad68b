"""Observation layouts of the tasks, as defined once in the Rust core (src/tasks/).

``obs_layout("nav")`` maps each named block of the flat observation vector to its slice, in order,
so that ``obs[..., layout["goal_distance"]]`` picks that block out of one observation or a batch.
Multi-robot tasks prefix each block with its agent: ``obs_layout("formation")`` has
"follower_0/ir", ..., "follower_3/wheel_speeds" (the default scenario's four followers), and
"multinav" has "robot_0/ir", .... For another scenario (more followers, an agent leader) ask the
env itself: ``env.unwrapped.obs_layout()``.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable

from khepera_gym import _core


@functools.cache
def _layout_items(task: str) -> tuple[tuple[str, int, int], ...]:
    return tuple((name, int(start), int(stop)) for name, start, stop in _core.obs_layout(task))


def layout_dict(items: Iterable[tuple[str, int, int]]) -> dict[str, slice]:
    """``(name, start, stop)`` triples (as the Rust core gives them) as a dict name → slice."""
    return {name: slice(int(start), int(stop)) for name, start, stop in items}


def obs_layout(task: str) -> dict[str, slice]:
    """Observation layout of a task as an ordered mapping name → slice.

    Args:
        task: A task of the Rust core's registry (a name of ``registry.task_names()``, such as
            "nav"; ``khepera-gym list`` prints them), with its default scenario.

    Returns:
        A new dict (callers may modify it) whose slices cover ``0..obs_dim`` contiguously.

    Raises:
        KheperaError: The task is unknown.
    """
    return layout_dict(_layout_items(task))


__all__ = ["layout_dict", "obs_layout"]
