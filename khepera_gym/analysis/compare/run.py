"""Running the comparison: every policy on the same N seeded episodes of a native vector env (one
episode per world, run by :func:`khepera_gym.rollout.run_episodes`), the first worlds recorded for
plots, summarised per policy with intervals (what is summarised per task:
:mod:`khepera_gym.analysis.compare.metrics`). On a task with a moving reference (Track) the error of
every world, ‖robot − reference‖, is also kept after every step for the error-vs-time plot.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from khepera_gym import registration, registry
from khepera_gym.analysis.compare.metrics import TaskMetrics, summarize_errors, task_metrics
from khepera_gym.analysis.plots import Rollout, control_step
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import SAMPLED_SUFFIX, SB3_PREFIX, Policy, make_policy
from khepera_gym.registration import latest_ids, task_of
from khepera_gym.rollout import run_episodes
from khepera_gym.tooling.stats import Estimate, bootstrap_interval, wilson_interval

#: Percentile of the time to goal in the table.
TIME_PERCENTILE = 95.0
#: The common episode statistics (every task's); the others are the task's own.
COMMON_STATS = ("return", "length", "success", "path_length", "collisions")


@dataclasses.dataclass
class EpisodeResult:
    """One episode of one policy (a row of the CSV file).

    Attributes:
        policy: The policy's name.
        world: Index of the world in the batch.
        seed: The world's seed (the comparison's seed + world): a single env reset with it
            replays the episode.
        success: The goal was reached (formation: the leader's).
        length: Steps.
        time_to_goal: ``length · dt`` (s) for a success, else None.
        episode_return: Sum of rewards.
        path_length: Distance driven (m; formation: summed over the robots).
        collisions: Steps in contact with something.
        formation_error_mean: Followers' mean distance to their targets (m), formation only.
        formation_error_max: Its largest value (m), formation only.
        terminated: The episode ended by termination (Nav: the goal reached; Track: lost), not
            by truncation.
        mean_speed: ``path_length / (length · dt)`` (m/s); None for multi-robot tasks.
        task_stats: The task's other statistics by name (Track: ``track_error_rms``,
            ``track_error_max`` in m, ``track_iae`` in m·s, ``track_converge_time`` in s, inf
            if it never converged); CSV and JSON give each its own column.
    """

    policy: str
    world: int
    seed: int
    success: bool
    length: int
    time_to_goal: float | None
    episode_return: float
    path_length: float
    collisions: int
    formation_error_mean: float | None = None
    formation_error_max: float | None = None
    terminated: bool = False
    mean_speed: float | None = None
    task_stats: dict[str, float] = dataclasses.field(default_factory=dict)

    def row(self) -> dict[str, Any]:
        """The flat row of the CSV and JSON files: the fields, then each task statistic."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        del fields["task_stats"]
        return {**fields, **self.task_stats}


@dataclasses.dataclass
class PolicySummary:
    """A policy's statistics over its episodes, each with its 95% confidence interval.

    ``mean_speed`` (m/s) is over the successful episodes of a task with success, over all
    episodes otherwise, None for multi-robot tasks; ``terminated_rate`` is the share of episodes
    ended by a termination that is not a success (Track, PathFollow: lost); ``errors`` holds the
    error columns of a task scored by an error
    (:func:`khepera_gym.analysis.compare.metrics.summarize_errors`), empty otherwise.
    """

    policy: str
    episodes: int
    success_rate: Estimate
    time_to_goal_mean: Estimate
    time_to_goal_p95: Estimate
    path_length_mean: Estimate
    contact_steps_mean: Estimate
    contact_rate: Estimate
    formation_error_mean: Estimate | None
    terminated_rate: Estimate | None = None
    mean_speed: Estimate | None = None
    errors: dict[str, Estimate] = dataclasses.field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (strict JSON: an infinite estimate is the string "inf")."""

        def convert(value: Any) -> Any:
            if isinstance(value, Estimate):
                return value.to_json()
            if isinstance(value, dict):
                return {name: convert(item) for name, item in value.items()}
            return value

        return {f.name: convert(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_json(cls, record: dict[str, Any]) -> PolicySummary:
        """The summary :meth:`to_json` wrote (a results file read back)."""

        def estimate(value: Any) -> Estimate | None:
            return None if value is None else Estimate.from_json(value)

        fields = {f.name for f in dataclasses.fields(cls)}
        values: dict[str, Any] = {}
        for name, value in record.items():
            if name not in fields:
                continue
            if name == "errors":
                values[name] = {k: Estimate.from_json(v) for k, v in value.items()}
            elif isinstance(value, dict):
                values[name] = estimate(value)
            else:
                values[name] = value
        return cls(**values)


def summarize(
    policy: str, results: Sequence[EpisodeResult], metrics: TaskMetrics | None = None
) -> PolicySummary:
    """The statistics of one policy's episodes (see the module docstring).

    Args:
        policy: The policy's name.
        results: Its episodes.
        metrics: What the task reports (:func:`khepera_gym.analysis.compare.metrics.task_metrics`);
            None: the default entry (a task with success, no error statistics).
    """
    metrics = metrics or task_metrics(None)
    successes = [r for r in results if r.success]
    times = [r.time_to_goal for r in successes]
    formation = [r.formation_error_mean for r in results if r.formation_error_mean is not None]
    speed_episodes = successes if metrics.success is not None else results
    speeds = [r.mean_speed for r in speed_episodes if r.mean_speed is not None]
    return PolicySummary(
        policy=policy,
        episodes=len(results),
        success_rate=wilson_interval(len(successes), len(results)),
        time_to_goal_mean=bootstrap_interval(times, "mean"),
        time_to_goal_p95=bootstrap_interval(times, f"p{TIME_PERCENTILE:g}"),
        path_length_mean=bootstrap_interval([r.path_length for r in successes], "mean"),
        contact_steps_mean=bootstrap_interval([r.collisions for r in results], "mean"),
        contact_rate=wilson_interval(sum(r.collisions > 0 for r in results), len(results)),
        formation_error_mean=bootstrap_interval(formation, "mean") if formation else None,
        terminated_rate=wilson_interval(
            sum(r.terminated and not r.success for r in results), len(results)
        ),
        mean_speed=bootstrap_interval(speeds, "mean") if metrics.speed else None,
        errors=summarize_errors(metrics, [r.task_stats for r in results]),
    )


def run_policy(
    env: gym.vector.VectorEnv,
    name: str,
    policy: Policy,
    seed: int,
    record_worlds: int = 1,
    progress: bool = True,
    description: str = "",
    error_trace: list[np.ndarray] | None = None,
) -> tuple[list[EpisodeResult], list[Rollout]]:
    """One episode in every world of a vector env: reset with ``seed``, step until all ended.

    Args:
        env: A native vector env (``gym.make_vec``) of N worlds.
        name: The policy's name (stored in the results).
        policy: Maps observations (N, D) to actions (N, A).
        seed: World i is reset with seed + i.
        record_worlds: The first worlds whose poses are recorded after every step.
        progress: Show a tqdm progress bar of finished episodes.
        description: Progress bar label.
        error_trace: If a list, it receives, at reset and after every step, the distance (m)
            of every world's robot 0 to its first goal (Track: the tracking error), shape
            (N,), NaN for the worlds whose episode had ended.

    Returns:
        One result per world in world order, and one :class:`Rollout` per recorded world (with
        its ``goal_trace``: the goals at reset and after every step).
    """
    unwrapped = env.unwrapped
    batch = unwrapped._batch
    n = batch.num_worlds
    record = max(0, min(record_worlds, n))
    dt = control_step(env)
    ended_at = np.zeros(n, dtype=np.int64)
    terminated = np.zeros(n, dtype=bool)
    poses: list[np.ndarray] = []
    targets: list[np.ndarray] = []
    goal_trace: list[np.ndarray] = []
    bar = tqdm(total=n, desc=description or name, unit="episode", disable=not progress, leave=False)

    def record_errors(running: np.ndarray) -> None:
        if error_trace is not None:
            robot = unwrapped._batch.poses()[:, 0, :2]
            goal = unwrapped._batch.goals()[:, 0, :2]
            error_trace.append(np.where(running, np.hypot(*(robot - goal).T), np.nan))

    def on_step(step: int, _obs: Any, _rewards: Any, ended: Any, done: Any) -> None:
        if record and not done[:record].all():
            poses.append(unwrapped.poses()[:record])
            targets.append(unwrapped.targets()[:record])
            goal_trace.append(unwrapped.goals()[:record])
        record_errors(~done)
        if np.count_nonzero(ended):
            terminated[ended] = batch.last_outputs()[2][ended]
        ended_at[ended] = step
        bar.update(int(np.count_nonzero(ended)))

    goals: list[np.ndarray] = []
    scenes: list[dict[str, Any]] = []

    def on_reset(_obs: Any) -> None:
        goals.extend(unwrapped.goals()[:record])
        scenes.extend(unwrapped.scene(i) for i in range(record))
        poses.append(unwrapped.poses()[:record])
        targets.append(unwrapped.targets()[:record])
        goal_trace.append(unwrapped.goals()[:record])
        record_errors(np.ones(n, dtype=bool))

    with bar:
        stats = run_episodes(batch, policy, seed, on_reset=on_reset, on_step=on_step)
    pose_array = np.array(poses)
    target_array = np.array(targets)
    goal_array = np.array(goal_trace)
    has_targets = target_array.ndim == 4 and target_array.shape[2] > 0
    rollouts = [
        Rollout(
            poses=pose_array[: ended_at[i] + 1, i],
            goals=np.asarray(goals[i]),
            scene=scenes[i],
            stats=dict(stats[i] or {}),
            targets=target_array[: ended_at[i] + 1, i] if has_targets else None,
            goal_trace=goal_array[: ended_at[i] + 1, i],
            dt=dt,
            label=name,
            seed=seed + i,
        )
        for i in range(record)
    ]
    single_robot = unwrapped.n_robots == 1
    results = [
        _episode_result(name, world, seed, episode, dt, bool(terminated[world]), single_robot)
        for world, episode in enumerate(stats)
        if episode is not None
    ]
    return results, rollouts


def _episode_result(
    name: str,
    world: int,
    seed: int,
    episode: dict[str, Any],
    dt: float,
    terminated: bool,
    single_robot: bool,
) -> EpisodeResult:
    success = bool(episode["success"])
    length = int(episode["length"])
    own = ("formation_error_mean", "formation_error_max")
    return EpisodeResult(
        policy=name,
        world=world,
        seed=seed + world,
        success=success,
        length=int(episode["length"]),
        time_to_goal=round(episode["length"] * dt, 6) if success else None,
        episode_return=float(episode["return"]),
        path_length=float(episode["path_length"]),
        collisions=int(episode["collisions"]),
        formation_error_mean=episode.get("formation_error_mean"),
        formation_error_max=episode.get("formation_error_max"),
        terminated=terminated,
        mean_speed=(
            float(episode["path_length"]) / (length * dt) if single_robot and length else None
        ),
        task_stats={
            key: float(value)
            for key, value in episode.items()
            if key not in COMMON_STATS and key not in own
        },
    )


# --- the comparison ---------------------------------------------------------------------------


@dataclasses.dataclass
class Comparison:
    """Results of :func:`compare`: per-episode results, summaries and recorded rollouts.

    ``task`` is the core's task name ("track"), ``overrides`` the scenario keys given to
    :func:`compare`, and ``error_traces`` (tasks with a moving reference) each policy's error
    of every world at reset and after every step, shape (T + 1, N) in m, NaN once its episode
    had ended; ``config_toml`` the resolved scenario.
    """

    env_id: str
    config: str | None
    label: str
    seed: int
    episodes: int
    dt: float
    results: dict[str, list[EpisodeResult]]
    summaries: list[PolicySummary]
    rollouts: dict[str, list[Rollout]]
    task: str | None = None
    overrides: dict[str, Any] = dataclasses.field(default_factory=dict)
    error_traces: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    config_toml: str = ""

    @classmethod
    def from_json(cls, document: dict[str, Any]) -> Comparison:
        """A comparison from its ``<label>_results.json`` (:func:`write_results`): settings and
        summaries, without episodes, rollouts or error traces (enough for its table)."""
        env_id = document["env_id"]
        return cls(
            env_id=env_id,
            config=document.get("config"),
            label=document.get("label", ""),
            seed=int(document["seed"]),
            episodes=int(document["episodes_per_policy"]),
            dt=float(document["dt"]),
            results={},
            summaries=[PolicySummary.from_json(s) for s in document["summaries"]],
            rollouts={},
            task=document.get("task") or task_of(env_id),
            overrides=dict(document.get("overrides") or {}),
        )

    @property
    def is_formation(self) -> bool:
        """Whether the results have formation errors."""
        return any(s.formation_error_mean is not None for s in self.summaries)

    @property
    def metrics(self) -> TaskMetrics:
        """What the task reports (:data:`khepera_gym.analysis.compare.metrics.TASK_METRICS`)."""
        return task_metrics(self.task)

    @property
    def scenario(self) -> str:
        """The config and overrides for titles: ``', config="paper_fig6", reference="square"'``."""
        settings = {} if self.config is None else {"config": self.config}
        settings.update(self.overrides)
        return "".join(
            f', {key}="{value}"' if isinstance(value, str) else f", {key}={value}"
            for key, value in settings.items()
        )


def resolve_env_id(
    task: str | None = None, env_id: str | None = None, version: int | None = None
) -> str:
    """The registered id of ``--task`` (on behaviour ``version``; None: the latest) or
    ``--env`` (an unversioned id gets its latest version).

    Raises:
        ValueError: Neither or both given, an unknown task, a version the task does not exist
            in, a version beside an id, or an id that is not registered.
    """
    if (task is None) == (env_id is None):
        raise ValueError("give either a task (--task) or an env id (--env), not both")
    if task is not None:
        task_ids = latest_ids()
        if task not in task_ids:
            raise ValueError(f"unknown task {task!r}; known: {', '.join(task_ids)}")
        if version is None:
            return task_ids[task]
        versions = registry.task_versions(task)
        if version not in versions:
            known = ", ".join(str(v) for v in versions)
            raise ConfigError(f"{task} has no behaviour version {version!r}; it has {known}")
        return f"{task_ids[task].rsplit('-v', 1)[0]}-v{version}"
    if version is not None:
        raise ConfigError(f"--env {env_id} names its version; do not add --version")
    assert env_id is not None
    try:
        return registration.resolve_env_id(env_id)
    except ConfigError:
        nearest = registration.nearest_id(env_id)
        hint = f"did you mean {nearest!r}? " if nearest is not None else ""
        raise ConfigError(
            f"environment {env_id!r} is not registered; {hint}`khepera-gym list envs` lists "
            "them all"
        ) from None


def _label(env_id: str, config: str | None, overrides: dict[str, Any] | None = None) -> str:
    """File-name label: the config's name (a path's stem) or the task's short name, then each
    scalar override as ``_key-value`` (``track_reference-square``)."""
    if config is not None:
        label = Path(str(config)).stem
    else:
        label = env_id.split("-")[1].lower() if env_id.count("-") >= 2 else env_id
    for key, value in (overrides or {}).items():
        if isinstance(value, (str, int, float, bool)):
            text = f"{key.rsplit('.', 1)[-1]}-{value}"
            label += "_" + "".join(c if c.isalnum() or c in "-." else "_" for c in text)
    return label


def _shown_name(name: str, sample_actions: bool) -> str:
    """A policy's name in the results: an ``sb3:`` model that samples its actions says so."""
    return name + SAMPLED_SUFFIX if sample_actions and name.startswith(SB3_PREFIX) else name


def compare(
    env_id: str,
    policies: Sequence[str],
    episodes: int = 100,
    seed: int = 0,
    config: str | None = None,
    num_threads: int | None = None,
    record_worlds: int = 1,
    progress: bool = True,
    algo: str | None = None,
    overrides: dict[str, Any] | None = None,
    before_running: Callable[[], Any] | None = None,
    sample_actions: bool = False,
) -> Comparison:
    """Runs every policy on the same N seeded episodes and summarises them.

    Args:
        env_id: Registered id (e.g. ``"KheperaIV-Avoid"``, the latest version, or one with
            its version).
        policies: Policy names (see the module docstring) or ``sb3:path.zip``.
        episodes: N, the number of worlds (one episode each) per policy.
        seed: World i is reset with seed + i, for every policy.
        config: Scenario name or TOML path (e.g. ``"paper_fig6"``).
        num_threads: Threads of the vector env (None: all cores).
        record_worlds: How many of the first worlds to record for plots.
        progress: Show progress bars.
        algo: stable-baselines3 algorithm of ``sb3:`` policies.
        overrides: Scenario keys overriding the config, as for ``gym.make`` (e.g.
            ``{"wheel_accel_limit": 0.678}``).
        before_running: Called once everything is checked (the env made, every policy built)
            and before the first step: the command line's output folder is made there.
        sample_actions: ``sb3:`` models sample their actions from their distribution (torch
            seeded with ``seed``) instead of acting on its mode; they are then named
            ``"sb3:path.zip (sampled)"`` in the results.

    Returns:
        The :class:`Comparison`.

    Raises:
        ConfigError: No policies, N < 1, duplicate or unknown policies, a policy that does not
            fit the task, sampled actions without an ``sb3:`` model (all also ValueError), or a
            bad scenario or override.
        ImportError: An ``sb3:`` policy without stable-baselines3.
        KheperaError: A policy error.
    """
    if not policies:
        raise ConfigError("give at least one policy")
    if len(set(policies)) != len(policies):
        raise ConfigError(f"a policy is listed twice: {list(policies)}")
    if episodes < 1:
        raise ConfigError(f"episodes must be >= 1, got {episodes}")
    if sample_actions and not any(name.startswith(SB3_PREFIX) for name in policies):
        raise ConfigError(
            "sample_actions (--sample-actions) applies to sb3: models, and none is compared: "
            f"{list(policies)} act deterministically"
        )
    overrides = dict(overrides or {})
    label = _label(env_id, config, overrides)
    env = gym.make_vec(
        env_id, num_envs=episodes, config=config, num_threads=num_threads, **overrides
    )
    task = getattr(env.unwrapped, "task", None)
    metrics = task_metrics(task)
    try:
        # Every policy is built (sb3 models loaded) before anything runs: errors come first.
        built = {
            _shown_name(name, sample_actions): make_policy(name, env, seed, algo, sample_actions)
            for name in policies
        }
        if before_running is not None:
            before_running()
        results, rollouts, traces = {}, {}, {}
        for name, policy in built.items():
            trace: list[np.ndarray] | None = [] if metrics.moving_reference else None
            results[name], rollouts[name] = run_policy(
                env, name, policy, seed, record_worlds, progress, f"{label} {name}", trace
            )
            if trace is not None:
                traces[name] = np.array(trace)
        dt = control_step(env)
        config_toml = env.unwrapped.config_toml()
    finally:
        env.close()
    return Comparison(
        env_id=env_id,
        config=None if config is None else str(config),
        label=label,
        seed=seed,
        episodes=episodes,
        dt=dt,
        results=results,
        summaries=[summarize(name, results[name], metrics) for name in built],
        rollouts=rollouts,
        task=task,
        overrides=overrides,
        error_traces=traces,
        config_toml=config_toml,
    )


__all__ = [
    "COMMON_STATS",
    "TIME_PERCENTILE",
    "Comparison",
    "EpisodeResult",
    "PolicySummary",
    "compare",
    "resolve_env_id",
    "run_policy",
    "summarize",
]
