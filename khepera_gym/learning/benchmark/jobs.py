"""What the benchmark's learners share: a training run to do (:class:`Job`), what a learner hands
back (:class:`Trained`), and which rows a task has (its Gymnasium id, its PettingZoo module, its
agents). Kept apart from the learners so that the SB3 learners and BenchMARL's
(:mod:`khepera_gym.learning.benchmark.marl`) both build on it without importing each other.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from khepera_gym import _core, registry

#: Statistics of one evaluation: statistic → the mean over its episodes.
Means = dict[str, float]


@dataclasses.dataclass
class Trained:
    """What a learner hands back: the policy and how the training went."""

    #: Acts on rows: ``predict(rows, deterministic)`` → actions; ``reset()`` if it has memory.
    policy: Any
    #: Environment steps trained (summed over worlds).
    timesteps: int
    #: Wall time of training alone (s), evaluations excluded.
    train_seconds: float
    #: Wall time of the evaluations while training (s).
    eval_seconds: float
    #: The evaluations while training: (steps, training seconds so far, means).
    history: list[tuple[int, float, Means]]
    #: The recipe as used (the hyperparameter table with overrides).
    recipe: dict[str, Any]
    #: Files written (the model), name → path.
    files: dict[str, str]
    #: The policy sampling its actions, if the learner has a distribution to sample.
    sample: Callable[[int], Any] | None = None


@dataclasses.dataclass(frozen=True)
class Job:
    """One training run to do.

    Attributes:
        task, version: The core's task and the behaviour version trained on.
        seed: The training seed.
        out_dir: Where the run's files go.
        timesteps: Overrides the recipe's ``n_timesteps`` (None: the recipe's).
        overrides: Overrides of recipe keys.
        eval_episodes: Episodes of each evaluation while training.
        eval_points: Evaluations while training (evenly spaced, the last at the end).
        device: Torch device.
        num_threads: Threads of the Rust batches (None: all cores).
        on_evaluation: Called after each evaluation while training with (steps, training
            seconds, means): ``khepera-gym tune`` reports them to its scheduler, which may stop
            the trial.
        progress: Whether the learner may show its own progress (BenchMARL's bar); False: it
            prints nothing.
    """

    task: str
    version: int
    seed: int
    out_dir: Path
    timesteps: int | None = None
    overrides: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    eval_episodes: int = 50
    eval_points: int = 10
    device: str = "cpu"
    num_threads: int | None = None
    on_evaluation: Callable[[int, float, Means], None] | None = None
    progress: bool = True


def agents_of(task: str) -> list[tuple[str, int]]:
    """The agents of a task's default scenario: (name, observation length)."""
    agents = _core.Batch(task, 1, num_threads=1).agents()
    return [(name, stop - start) for name, _, start, stop, _ in agents]


def shares_rows(task: str) -> bool:
    """Whether one policy can drive every agent of the task: several agents, one length."""
    agents = agents_of(task)
    return len(agents) > 1 and len({length for _, length in agents}) == 1


def gym_id(task: str, version: int) -> str | None:
    """The task's Gymnasium id of that version, or None (a PettingZoo-only task)."""
    env_id = registry.task(task).env_id
    return None if env_id is None else f"{env_id}-v{version}"


def module_of(task: str, version: int) -> str | None:
    """The task's PettingZoo module of that version, or None."""
    from khepera_gym.pettingzoo import FAMILIES

    families = [family for family, cls in FAMILIES.items() if task == cls.TASK]
    return f"{families[0]}_v{version}" if families else None


__all__ = ["Job", "Means", "Trained", "agents_of", "gym_id", "module_of", "shares_rows"]
