"""Observation layouts of the tasks, as defined once in the Rust core (src/tasks/).

``obs_layout("nav")`` maps each named block of the flat observation vector to its slice, in order,
so that ``obs[..., layout["goal_distance"]]`` picks that block out of one observation or a batch.
"""

from __future__ import annotations

import functools

from khepera_gym import _core


@functools.cache
def _layout_items(task: str) -> tuple[tuple[str, int, int], ...]:
    return tuple((name, int(start), int(stop)) for name, start, stop in _core.obs_layout(task))


def obs_layout(task: str) -> dict[str, slice]:
    """Observation layout of a task as an ordered mapping name → slice.

    Args:
        task: Task name: "nav" (later "avoid", "formation").

    Returns:
        A new dict (callers may modify it) whose slices cover ``0..obs_dim`` contiguously.

    Raises:
        KheperaError: The task is unknown.
    """
    return {name: slice(start, stop) for name, start, stop in _layout_items(task)}


__all__ = ["obs_layout"]
