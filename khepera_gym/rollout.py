"""Seeded episodes: the one loop that runs them on a Rust batch, for every tool that needs
episodes (the comparison tool, the trajectory recorder, the video recorder, SB3 evaluation), and
the recorded episode (:class:`Rollout`) that plots and the comparison tool use.

:func:`run_episodes` plays one episode in every world of a ``_core.Batch`` (world i seeded
``seed + i``, so N worlds play the N episodes seeded ``seed .. seed + N - 1``, the same ones as
single envs reset with those seeds), calling back after every step so that the caller records
what it needs (poses, frames, actions). It works on any env's batch: with autoreset (vector envs)
a finished world is reset by the next step; without (single envs, SB3, PettingZoo) it is reset
here, so the other worlds can go on.

Threading: the batch releases the GIL while stepping; callbacks run in the caller's thread.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from khepera_gym import _core

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

#: A policy on joint observations: (N, obs_dim) float32 → (N, act_dim) actions.
BatchPolicy = Callable[[npt.NDArray[np.float32]], npt.ArrayLike]
#: Called after every step: (step, observations, rewards, ended, done): ``ended`` marks the worlds
#: whose first episode ended at this step, ``done`` those that ended before it. Observations are
#: the step's, before any finished world is reset.
StepCallback = Callable[
    [
        int,
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
    ],
    None,
]


def run_episodes(
    batch: _core.Batch,
    act: BatchPolicy,
    seed: int | None,
    *,
    on_reset: Callable[[npt.NDArray[np.float32]], None] | None = None,
    on_step: StepCallback | None = None,
    max_steps: int | None = None,
) -> list[dict[str, Any] | None]:
    """One episode in every world of ``batch``.

    Args:
        batch: The env's ``_core.Batch`` (``env.unwrapped._batch``).
        act: Maps the joint observations of every world, (N, obs_dim), to actions (N, act_dim).
            Worlds whose episode ended still get an action; it is ignored. A stateful policy
            (one with a ``reset()`` method, e.g. a frame-stacked model) is reset first.
        seed: World i is reset with ``seed + i``; None continues every world's stream.
        on_reset: Called with the first observations, after the reset.
        on_step: Called after every step (see :data:`StepCallback`).
        max_steps: Stop after this many steps even if some episodes have not ended.

    Returns:
        Each world's statistics of its episode (Python scalars: "return", "length", "success",
        "path_length", "collisions", and the task's own), None for a world cut short by
        ``max_steps``.
    """
    n = batch.num_worlds
    reset = getattr(act, "reset", None)
    if callable(reset):
        reset()
    observations = batch.reset(seed)
    if on_reset is not None:
        on_reset(observations)
    stats: list[dict[str, Any] | None] = [None] * n
    done = np.zeros(n, dtype=bool)
    step = 0
    while not done.all() and (max_steps is None or step < max_steps):
        actions = np.ascontiguousarray(act(observations), dtype=np.float32).reshape(n, -1)
        observations, rewards, terminations, truncations = batch.step(actions)
        step += 1
        finished = terminations | truncations
        ended = finished & ~done
        # count_nonzero: cheap on the small arrays of this hot loop.
        if np.count_nonzero(ended):
            episode = batch.episode_stats()
            for world in np.flatnonzero(ended):
                stats[world] = {name: values[world].item() for name, values in episode.items()}
        if on_step is not None:
            on_step(step, observations, rewards, ended, done)
        done |= ended
        if not batch.autoreset and np.count_nonzero(finished) and not done.all():
            # Without autoreset a finished world refuses to step: start its next episode (its
            # actions are ignored from now on) so that the others can go on.
            observations = observations.copy()
            for world in np.flatnonzero(finished):
                observations[world] = batch.reset_world(int(world))
    return stats


@dataclass
class Rollout:
    """One recorded episode: what :func:`plot_rollouts` draws and the comparison tool saves.

    Attributes:
        poses: Ground-truth poses at reset and after every step, shape (T + 1, R, 3): x, y (m),
            θ (rad), robots in the env's order (a formation's leader first).
        goals: Goal positions of the episode, shape (n_goals, 2) (m).
        scene: The world's geometry (``env.unwrapped.scene()``) at reset.
        stats: The episode's ``episode_stats`` ("success", "length", "path_length", ...); empty
            if the recording stopped before the episode ended.
        targets: A formation's follower targets (eq. 12) at reset and after every step,
            shape (T + 1, K, 2), or None for other tasks.
        dt: Control step (s), so that step t is at time t · dt.
        label: What produced it, e.g. the policy's name (used as a panel title).
        seed: The reset seed, if known.
        actions: The action of every step, shape (T, A), when recorded.
        rewards: The reward of every step, shape (T,), when recorded.
        ir_raw: Raw IR readings (0..1023) at reset and after every step, (T + 1, R, 8).
        us_cm: Ultrasonic readings (cm or codes 0/1000/2000), (T + 1, R, 5).
        env_id: The environment's id, when known.
        config: The resolved scenario (TOML text), when known.
        goal_trace: The goals at reset and after every step, (T + 1, n_goals, 2) (m), when
            recorded: a goal that moves, such as Track's reference point, leaves its path.

    :meth:`save` writes all of it to one compressed ``.npz`` file and :meth:`load` reads it back,
    so a run can be replayed or plotted later without simulating it again.
    """

    poses: np.ndarray
    goals: np.ndarray
    scene: dict[str, Any]
    stats: dict[str, Any] = field(default_factory=dict)
    targets: np.ndarray | None = None
    dt: float = 0.05
    label: str = ""
    seed: int | None = None
    actions: np.ndarray | None = None
    rewards: np.ndarray | None = None
    ir_raw: np.ndarray | None = None
    us_cm: np.ndarray | None = None
    env_id: str = ""
    config: str = ""
    goal_trace: np.ndarray | None = None

    _ARRAYS: ClassVar[tuple[str, ...]] = (
        "poses",
        "goals",
        "targets",
        "actions",
        "rewards",
        "ir_raw",
        "us_cm",
        "goal_trace",
    )

    def save(self, path: str | Path) -> Path:
        """Writes the rollout to a compressed ``.npz`` (arrays, plus scene, stats and metadata
        as JSON)."""
        path = Path(path)
        arrays = {
            name: getattr(self, name) for name in self._ARRAYS if getattr(self, name) is not None
        }
        meta = {
            "scene": self.scene,
            "stats": {k: (v.item() if hasattr(v, "item") else v) for k, v in self.stats.items()},
            "dt": self.dt,
            "label": self.label,
            "seed": self.seed,
            "env_id": self.env_id,
            "config": self.config,
        }
        np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
        return path if path.suffix == ".npz" else path.with_suffix(path.suffix + ".npz")

    @classmethod
    def load(cls, path: str | Path) -> Rollout:
        """Reads a rollout written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            arrays = {name: data[name] for name in cls._ARRAYS if name in data.files}
        return cls(
            scene=meta["scene"],
            stats=meta["stats"],
            dt=meta["dt"],
            label=meta["label"],
            seed=meta["seed"],
            env_id=meta["env_id"],
            config=meta["config"],
            **arrays,
        )

    @property
    def n_robots(self) -> int:
        """Number of robots R."""
        return int(self.poses.shape[1])

    @property
    def duration(self) -> float:
        """Simulated time of the recording (s)."""
        return (len(self.poses) - 1) * self.dt

    def turning(self, robot: int = 0, deadband: float = 0.01) -> tuple[float, int]:
        """How much a robot turned: (total heading change in rad, turn-direction reversals).

        A reversal is a step whose heading change has the opposite sign of the previous step
        that turned by more than ``deadband`` rad (0.01 rad per 0.05 s step = 0.2 rad/s); a
        zigzagging robot has many, a smooth path few.
        """
        change = np.diff(np.unwrap(self.poses[:, robot, 2]))
        signs = np.sign(change[np.abs(change) > deadband])
        return float(np.abs(change).sum()), int(np.count_nonzero(np.diff(signs)))


def control_step(env: Any) -> float:
    """The scenario's ``physics.dt`` (s) of an env (0.05 s if it cannot be read)."""
    try:
        return float(tomllib.loads(env.unwrapped.config_toml())["physics"]["dt"])
    except (AttributeError, KeyError, TypeError, ValueError):
        return 0.05


def record_rollout(
    env_id_or_env: str | gym.Env,
    policy: Callable[[np.ndarray], Any],
    seed: int,
    config: Any = None,
    max_steps: int | None = None,
    *,
    label: str = "",
    **overrides: Any,
) -> Rollout:
    """Runs one seeded episode and records the poses after every step.

    Args:
        env_id_or_env: A registered id (e.g. ``"KheperaIV-Avoid"``), made with
            ``gym.make(id, config=config, max_steps=max_steps, **overrides)`` and closed
            afterwards, or a single-world env (not closed).
        policy: Maps one observation to one action (a baseline of
            :mod:`khepera_gym.baselines`, a function, ...).
        seed: The episode's seed: world i of a vector env reset with seed s is this episode
            for seed s + i.
        config: Scenario name or TOML path (only with an id).
        max_steps: With an id, the scenario's ``task.max_steps`` (the core truncates there);
            with an env, the recording stops after that many steps (``stats`` stays empty if
            the episode has not ended).
        label: Stored in :attr:`Rollout.label`.
        **overrides: Further scenario keys (only with an id).

    Returns:
        The :class:`Rollout`.

    Raises:
        ValueError: ``config`` or overrides given with an env instance.
    """
    if isinstance(env_id_or_env, str):
        if max_steps is not None:
            overrides["max_steps"] = max_steps
        env = gym.make(env_id_or_env, config=config, **overrides)
        try:
            return record_rollout(env, policy, seed, label=label)
        finally:
            env.close()
    if config is not None or overrides:
        raise ValueError("config and scenario overrides need an env id, not an env instance")
    env = env_id_or_env
    unwrapped = env.unwrapped
    poses, targets, readings, goal_trace = [], [], [], []
    actions: list[np.ndarray] = []
    rewards: list[float] = []

    def record_state() -> None:
        poses.append(unwrapped.poses())
        targets.append(unwrapped.targets())
        goal_trace.append(unwrapped.goals())
        readings.append(unwrapped.sensor_readings())

    def act(observations: np.ndarray) -> np.ndarray:
        action = np.asarray(policy(observations[0]), dtype=np.float32)
        actions.append(action)
        return action[None]

    def on_step(_step: int, _obs: Any, step_rewards: np.ndarray, _ended: Any, _done: Any) -> None:
        rewards.append(float(step_rewards[0]))
        record_state()

    stats = run_episodes(
        unwrapped._batch,
        act,
        seed,
        on_reset=lambda _obs: record_state(),
        on_step=on_step,
        max_steps=max_steps,
    )[0]
    target_array = np.array(targets)
    return Rollout(
        poses=np.array(poses),
        goals=np.asarray(unwrapped.goals()),
        scene=unwrapped.scene(),
        stats=dict(stats or {}),
        targets=target_array if target_array.shape[1] > 0 else None,
        dt=control_step(env),
        label=label,
        seed=seed,
        actions=np.array(actions, dtype=np.float32).reshape(len(actions), -1),
        rewards=np.array(rewards, dtype=np.float32),
        ir_raw=np.array([r["ir_raw"] for r in readings]),
        us_cm=np.array([r["us_cm"] for r in readings]),
        env_id=env.spec.id if env.spec is not None else "",
        config=unwrapped.config_toml(),
        goal_trace=np.array(goal_trace),
    )


#: How a task with a reference reports its episode: its RMS error statistic → (the outcome of a
#: success, of another end), of the episode's seconds. Track never succeeds: its episode ends
#: lost, or at the end of its reference; PathFollow succeeds with a lap.
_REFERENCE_OUTCOMES = {
    "track_error_rms": ("tracked for {:.1f} s", "tracked for {:.1f} s"),
    "path_error_rms": ("lap in {:.1f} s", "no lap in {:.1f} s"),
}


def rollout_summary(rollout: Rollout) -> str:
    """One line on how a rollout ended, e.g. "reached in 11.2 s, path 1.74 m, no contact"; on a
    task with a reference, e.g. "lap in 25.1 s, RMS error 4.2 mm, path 3.77 m, no contact"."""
    stats = rollout.stats
    if not stats:
        return f"{rollout.duration:.1f} s recorded"
    seconds = stats["length"] * rollout.dt
    error = next((name for name in _REFERENCE_OUTCOMES if name in stats), None)
    if error is not None:
        success, failure = _REFERENCE_OUTCOMES[error]
        text = (success if stats.get("success") else failure).format(seconds)
        text += f", RMS error {stats[error] * 1000:.1f} mm"
    else:
        outcome = "reached" if stats.get("success") else "not reached"
        text = f"{outcome} in {seconds:.1f} s"
    if rollout.n_robots == 1 and "path_length" in stats:
        text += f", path {stats['path_length']:.2f} m"
    if "formation_error_mean" in stats:
        text += f", formation error {stats['formation_error_mean'] * 100:.1f} cm"
    contacts = int(stats.get("collisions", 0))
    return text + (f", {contacts} steps in contact" if contacts else ", no contact")


__all__ = [
    "BatchPolicy",
    "Rollout",
    "StepCallback",
    "control_step",
    "record_rollout",
    "rollout_summary",
    "run_episodes",
]
