"""Comparison of policies on the same seeded episodes: the ``khepera-gym compare`` command.

For one task or scenario and several policies, :func:`compare` runs N episodes per policy on the
native vector env: N worlds reset once with ``reset(seed=s)`` (world i seeded s + i), each
running exactly one episode (the episode that follows its autoreset is discarded), so every
policy meets the same start poses, goals and obstacles. It summarises, per policy, with 95%
confidence intervals:

* success rate (Wilson score interval);
* mean and 95th percentile of the time to the goal (s, successful episodes only), mean path
  length (m, successful episodes only), mean number of steps in contact per episode, the
  share of episodes with any contact (Wilson), and for formations the mean formation error (m);
  the intervals of means and percentiles are percentile bootstraps with a fixed seed, so a
  comparison is deterministic.

It writes the per-episode results as CSV and JSON and draws the first worlds' trajectories
side by side, one panel per policy, in the style of the paper's Figs. 6 and 7
(:func:`khepera_gym.plot.plot_rollouts`). Policies are named:

* ``position_control``, ``braitenberg``, ``braitenberg_kteam`` (K-Team's weights), ``vfh``:
  :mod:`khepera_gym.baselines` on Nav/Avoid observations;
* ``leader_follower``: :class:`khepera_gym.baselines.LeaderFollower` with the scenario's
  formation (Formation task);
* ``random``: uniform actions in [-1, 1] from a generator seeded with the comparison's seed;
* ``sb3:path/to/model.zip``: a stable-baselines3 model, loaded with ``--algo``'s class or by
  trying PPO, SAC, TD3, A2C and DQN in turn, acting deterministically (needs the ``sb3`` extra).

Command line (``khepera-gym compare --help``)::

    khepera-gym compare --task avoid --policy braitenberg vfh --episodes 200 --out results/
    khepera-gym compare --task avoid --config paper_fig6 --policy braitenberg vfh --episodes 20

``khepera-gym demo`` (:func:`demo`) runs it on the paper's scenes and the three tasks.

Units: seconds and metres (formation errors in the table in cm). Threading: the vector env
steps its worlds on its own rayon pool (``--num-threads``, all cores by default) with the GIL
released; policies run in the calling thread between steps.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import statistics
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from khepera_gym import baselines
from khepera_gym.errors import KheperaError
from khepera_gym.plot import Rollout, control_step, panel_title, plot_rollouts

#: Registered id of each task name of ``--task``.
TASK_IDS = {
    "nav": "KheperaIV-Nav-v0",
    "avoid": "KheperaIV-Avoid-v0",
    "formation": "KheperaIV-Formation-v0",
}
#: Policies acting on Nav/Avoid observations (one robot, goal distance and bearing).
NAV_POLICIES = ("position_control", "braitenberg", "braitenberg_kteam", "vfh")
#: Policies acting on Formation observations (followers' blocks).
FORMATION_POLICIES = ("leader_follower",)
#: Every policy name (besides ``sb3:path.zip``).
POLICY_NAMES = (*NAV_POLICIES, *FORMATION_POLICIES, "random")
#: Prefix of a stable-baselines3 model file among the policies.
SB3_PREFIX = "sb3:"
#: stable-baselines3 algorithms tried in turn to load a model without ``--algo``.
SB3_ALGORITHMS = ("PPO", "SAC", "TD3", "A2C", "DQN")
#: Policies compared when none is given.
DEFAULT_POLICIES = {
    "nav": ("position_control", "braitenberg", "vfh", "random"),
    "avoid": ("position_control", "braitenberg", "braitenberg_kteam", "vfh", "random"),
    "formation": ("leader_follower", "random"),
}
#: Confidence level of every interval.
CONFIDENCE = 0.95
#: Bootstrap resamples of an interval of a mean or percentile.
BOOTSTRAP_RESAMPLES = 2000
#: Seed of the bootstrap generator (fixed: the same results give the same intervals).
BOOTSTRAP_SEED = 0
#: Percentile of the time to goal in the table.
TIME_PERCENTILE = 95.0
#: Resolution of the saved plots (dots per inch).
PLOT_DPI = 100

Policy = Callable[[npt.NDArray[np.float32]], npt.ArrayLike]


# --- statistics ------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A statistic with its confidence interval; NaN everywhere when there is no data.

    Attributes:
        value: The estimate.
        low: Lower bound of the interval.
        high: Upper bound of the interval.
        n: Number of samples it is computed from.
    """

    value: float
    low: float
    high: float
    n: int

    def format(self, scale: float = 1.0, digits: int = 2) -> str:
        """``"value [low, high]"`` with every number multiplied by ``scale``; "–" without data."""
        if self.n == 0 or math.isnan(self.value):
            return "–"
        value, low, high = (x * scale for x in (self.value, self.low, self.high))
        return f"{value:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"

    def to_json(self) -> dict[str, float | int | None]:
        """A JSON-ready dict; NaN becomes None."""
        return {
            name: None if isinstance(x, float) and math.isnan(x) else x
            for name, x in dataclasses.asdict(self).items()
        }


def _z(confidence: float) -> float:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    return statistics.NormalDist().inv_cdf(0.5 + confidence / 2)


def wilson_interval(successes: int, n: int, confidence: float = CONFIDENCE) -> Estimate:
    """A rate with its Wilson score interval.

    With p = successes / n and z the normal quantile of the confidence level, the interval is
    ``(p + z²/2n ± z·sqrt(p(1 - p)/n + z²/4n²)) / (1 + z²/n)``; unlike the normal approximation
    it stays inside [0, 1] and is not empty at p = 0 or 1.

    Args:
        successes: Number of successes, 0 <= successes <= n.
        n: Number of trials (0 gives NaN).
        confidence: Confidence level.

    Returns:
        The rate and its interval.
    """
    if not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, got {successes} of {n}")
    if n == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    z = _z(confidence)
    p = successes / n
    denominator = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    # Exactly 0 (1) for no (all) successes, where rounding would leave a residue.
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return Estimate(p, low, high, n)


def bootstrap_interval(
    values: npt.ArrayLike,
    statistic: str = "mean",
    confidence: float = CONFIDENCE,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Estimate:
    """A mean or percentile with its percentile-bootstrap interval.

    The sample is resampled with replacement ``resamples`` times by a generator seeded with
    ``seed``; the interval holds the central ``confidence`` share of the resampled statistics.

    Args:
        values: The sample (NaN values are dropped).
        statistic: "mean", "median" or "pNN" (a percentile, e.g. "p95").
        confidence: Confidence level.
        resamples: Number of bootstrap resamples.
        seed: Seed of the resampling generator.

    Returns:
        The statistic of the sample and its interval (NaN for an empty sample; a point
        interval for one value).
    """
    sample = np.asarray(values, dtype=float).ravel()
    sample = sample[~np.isnan(sample)]
    if statistic == "mean":

        def compute(x: np.ndarray, axis: int | None = None) -> Any:
            return np.mean(x, axis=axis)
    elif statistic == "median" or statistic.startswith("p"):
        q = 50.0 if statistic == "median" else float(statistic[1:])

        def compute(x: np.ndarray, axis: int | None = None) -> Any:
            return np.percentile(x, q, axis=axis)
    else:
        raise ValueError(f"statistic must be 'mean', 'median' or 'pNN', got {statistic!r}")
    _z(confidence)
    if sample.size == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    value = float(compute(sample))
    rng = np.random.default_rng(seed)
    draws = compute(sample[rng.integers(0, sample.size, (resamples, sample.size))], axis=1)
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(draws, [tail, 100 - tail])
    return Estimate(value, float(min(low, value)), float(max(high, value)), int(sample.size))


# --- policies ------------------------------------------------------------------------------


class RandomPolicy:
    """Uniform actions in [-1, 1] from a seeded generator (a reproducible lower baseline).

    Args:
        act_dim: Action length per observation.
        seed: Seed of the generator.
    """

    def __init__(self, act_dim: int, seed: int) -> None:
        self.act_dim = int(act_dim)
        self._rng = np.random.default_rng(seed)

    def __call__(self, observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """Actions of shape (N, act_dim) for observations (N, D), or (act_dim,) for (D,)."""
        shape = np.shape(observation)[:-1]
        return self._rng.uniform(-1.0, 1.0, (*shape, self.act_dim)).astype(np.float32)


class SB3Policy:
    """A stable-baselines3 model as a policy: ``model.predict(obs, deterministic=True)``.

    A model whose observation is one follower's block (parameter sharing, e.g. trained on
    ``khepera_gym.sb3.make_formation_vec_env``) acts on a joint Formation observation of K
    blocks one block at a time, its actions joined in follower order.

    Args:
        model: Anything with SB3's ``predict`` (a model, or ``khepera_gym.sb3.load_policy``'s
            result, which normalises observations when the model was trained under
            ``VecNormalize``).
        path: The model file, for messages.
    """

    def __init__(self, model: Any, path: str) -> None:
        self.model = model
        self.path = path
        space = getattr(model, "observation_space", None)
        shape = getattr(space, "shape", None)
        #: Observation length the model takes (None if it does not say).
        self.obs_dim: int | None = int(shape[0]) if shape and len(shape) == 1 else None

    def __call__(self, observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """The model's deterministic actions for observations (N, D) (or one (D,))."""
        array = np.asarray(observation, dtype=np.float32)
        dim = self.obs_dim
        if dim is not None and array.shape[-1] != dim and array.shape[-1] % dim == 0:
            blocks = array.reshape(-1, dim)  # world-major, then follower
            action, _ = self.model.predict(blocks, deterministic=True)
            return np.asarray(action, dtype=np.float32).reshape(*array.shape[:-1], -1)
        action, _ = self.model.predict(array, deterministic=True)
        return np.asarray(action, dtype=np.float32)


def load_sb3_policy(path: str | Path, algo: str | None = None) -> SB3Policy:
    """Loads a stable-baselines3 model file as a policy (on the CPU).

    Without ``algo`` the model is loaded by ``khepera_gym.sb3.load_policy`` (which reads the
    algorithm from the zip and applies the ``VecNormalize`` statistics saved next to it by
    ``khepera-gym train``); if that cannot tell the algorithm, PPO, SAC, TD3, A2C and DQN are
    tried in turn. With ``algo`` that class's ``load`` is used on the bare model.

    Args:
        path: The ``.zip`` saved by ``model.save`` or ``khepera-gym train``.
        algo: The algorithm class ("PPO", "SAC", ...), or None.

    Returns:
        The policy (deterministic actions).

    Raises:
        ImportError: stable-baselines3 is not installed (``pip install khepera-gym[sb3]``).
        FileNotFoundError: No such file.
        ValueError: Unknown ``algo``, or no algorithm could load the file.
    """
    try:
        import stable_baselines3
    except ImportError as error:
        raise ImportError(
            f"policy '{SB3_PREFIX}{path}' needs stable-baselines3, which is not installed: "
            "pip install khepera-gym[sb3]"
        ) from error
    if not Path(path).is_file():
        raise FileNotFoundError(f"policy '{SB3_PREFIX}{path}': no such model file")
    failures = []
    if algo is None:
        try:
            from khepera_gym.sb3 import load_policy
        except ImportError as error:
            failures.append(f"khepera_gym.sb3: {error}")
        else:
            try:
                return SB3Policy(load_policy(path), str(path))
            except KheperaError as error:
                failures.append(str(error))
    names = SB3_ALGORITHMS if algo is None else (algo.upper(),)
    for name in names:
        algorithm = getattr(stable_baselines3, name, None)
        if algorithm is None:
            raise ValueError(
                f"unknown stable-baselines3 algorithm {algo!r}; known: {SB3_ALGORITHMS}"
            )
        try:
            model = algorithm.load(str(path), device="cpu")
        except Exception as error:  # any failure means "not this algorithm"
            failures.append(f"{name}: {type(error).__name__}: {error}")
            continue
        return SB3Policy(model, str(path))
    raise ValueError(f"cannot load {path} as a stable-baselines3 model: " + "; ".join(failures))


def make_policy(
    name: str, env: gym.vector.VectorEnv, seed: int = 0, algo: str | None = None
) -> Policy:
    """The policy of a name for an environment (see the module docstring for the names).

    Args:
        name: A policy name or ``sb3:path.zip``.
        env: The (vector) environment it will drive: its task decides which names fit, a
            formation's shape is read from its scenario, the random policy's action length
            from its action space.
        seed: Seed of the ``random`` policy.
        algo: stable-baselines3 algorithm of an ``sb3:`` model (None: try them in turn).

    Returns:
        A callable mapping a batch of observations (N, D) to actions (N, A).

    Raises:
        ValueError: Unknown name, or a policy that does not fit the task.
        ImportError: ``sb3:`` without stable-baselines3 installed.
    """
    task = getattr(env.unwrapped, "task", None)
    if name.startswith(SB3_PREFIX):
        return load_sb3_policy(name[len(SB3_PREFIX) :], algo)
    if name not in POLICY_NAMES:
        raise ValueError(
            f"unknown policy {name!r}; known: {', '.join(POLICY_NAMES)} or sb3:path/to/model.zip"
        )
    if name == "random":
        return RandomPolicy(env.single_action_space.shape[0], seed)
    fits = FORMATION_POLICIES if task == "formation" else NAV_POLICIES
    if name not in fits:
        raise ValueError(
            f"policy {name!r} does not act on {task!r} observations; for this task use one of "
            f"{', '.join((*fits, 'random'))} or sb3:path/to/model.zip"
        )
    if name == "leader_follower":
        # An agent leader (formation.leader = "agent") drives like the scripted one.
        return baselines.LeaderFollower.for_env(env, leader=baselines.Braitenberg())
    return {
        "position_control": baselines.PositionControl,
        "braitenberg": baselines.Braitenberg,
        "braitenberg_kteam": lambda: baselines.Braitenberg(weights="kteam"),
        "vfh": baselines.VFH,
    }[name]()


# --- running episodes --------------------------------------------------------------------------


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


@dataclasses.dataclass
class PolicySummary:
    """A policy's statistics over its episodes, each with its 95% confidence interval."""

    policy: str
    episodes: int
    success_rate: Estimate
    time_to_goal_mean: Estimate
    time_to_goal_p95: Estimate
    path_length_mean: Estimate
    contact_steps_mean: Estimate
    contact_rate: Estimate
    formation_error_mean: Estimate | None

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            name: value.to_json() if isinstance(value, Estimate) else value
            for name, value in ((f.name, getattr(self, f.name)) for f in dataclasses.fields(self))
        }


def summarize(policy: str, results: Sequence[EpisodeResult]) -> PolicySummary:
    """The statistics of one policy's episodes (see the module docstring)."""
    successes = [r for r in results if r.success]
    times = [r.time_to_goal for r in successes]
    formation = [r.formation_error_mean for r in results if r.formation_error_mean is not None]
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
    )


def run_policy(
    env: gym.vector.VectorEnv,
    name: str,
    policy: Policy,
    seed: int,
    record_worlds: int = 1,
    progress: bool = True,
    description: str = "",
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

    Returns:
        One result per world in world order, and one :class:`Rollout` per recorded world.
    """
    n = env.num_envs
    unwrapped = env.unwrapped
    record = max(0, min(record_worlds, n))
    has_targets = hasattr(unwrapped, "formation_targets")
    dt = control_step(env)
    observations, _ = env.reset(seed=seed)
    goals = unwrapped.goals()[:record]
    scenes = [unwrapped.scene(i) for i in range(record)]
    poses = [unwrapped.poses()[:record]]
    targets = [unwrapped.formation_targets()[:record]] if has_targets else []
    ended_at = np.zeros(n, dtype=np.int64)
    results: list[EpisodeResult | None] = [None] * n
    stats_of: list[dict[str, Any]] = [{} for _ in range(record)]
    done = np.zeros(n, dtype=bool)
    step = 0
    bar = tqdm(total=n, desc=description or name, unit="episode", disable=not progress, leave=False)
    with bar:
        while not done.all():
            observations, _, terminations, truncations, infos = env.step(policy(observations))
            step += 1
            if record and not done[:record].all():
                poses.append(unwrapped.poses()[:record])
                if has_targets:
                    targets.append(unwrapped.formation_targets()[:record])
            ended = (terminations | truncations) & ~done
            if not ended.any():
                continue
            stats = infos["episode_stats"]
            for world in np.flatnonzero(ended):
                episode = {key: stats[key][world].item() for key in stats if key[0] != "_"}
                results[world] = _episode_result(name, int(world), seed, episode, dt)
                ended_at[world] = step
                if world < record:
                    stats_of[world] = episode
            done |= ended
            bar.update(int(ended.sum()))
    pose_array = np.array(poses)
    target_array = np.array(targets) if has_targets else None
    rollouts = [
        Rollout(
            poses=pose_array[: ended_at[i] + 1, i],
            goals=np.asarray(goals[i]),
            scene=scenes[i],
            stats=stats_of[i],
            targets=None if target_array is None else target_array[: ended_at[i] + 1, i],
            dt=dt,
            label=name,
            seed=seed + i,
        )
        for i in range(record)
    ]
    return [r for r in results if r is not None], rollouts


def _episode_result(
    name: str, world: int, seed: int, episode: dict[str, Any], dt: float
) -> EpisodeResult:
    success = bool(episode["success"])
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
    )


# --- the comparison ---------------------------------------------------------------------------


@dataclasses.dataclass
class Comparison:
    """Results of :func:`compare`: per-episode results, summaries and recorded rollouts."""

    env_id: str
    config: str | None
    label: str
    seed: int
    episodes: int
    dt: float
    results: dict[str, list[EpisodeResult]]
    summaries: list[PolicySummary]
    rollouts: dict[str, list[Rollout]]

    @property
    def is_formation(self) -> bool:
        """Whether the results have formation errors."""
        return any(s.formation_error_mean is not None for s in self.summaries)


def resolve_env_id(task: str | None = None, env_id: str | None = None) -> str:
    """The registered id of ``--task`` or ``--env`` (an unversioned id gets its latest version).

    Raises:
        ValueError: Neither or both given, an unknown task, or an id that is not registered.
    """
    if (task is None) == (env_id is None):
        raise ValueError("give either a task (nav, avoid, formation) or an env id, not both")
    if task is not None:
        if task not in TASK_IDS:
            raise ValueError(f"unknown task {task!r}; known: {', '.join(TASK_IDS)}")
        return TASK_IDS[task]
    assert env_id is not None
    if env_id in gym.registry:
        return env_id
    versions = sorted(
        (spec.version, spec.id)
        for spec in gym.registry.values()
        if spec.name == env_id and spec.namespace is None and spec.version is not None
    )
    if not versions:
        known = ", ".join(sorted(i for i in gym.registry if i.startswith("KheperaIV-")))
        raise ValueError(f"environment {env_id!r} is not registered; known: {known}")
    return versions[-1][1]


def _label(env_id: str, config: str | None) -> str:
    """File-name label: the config's name (a path's stem) or the task's short name."""
    if config is not None:
        return Path(str(config)).stem
    return env_id.split("-")[1].lower() if env_id.count("-") >= 2 else env_id


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
) -> Comparison:
    """Runs every policy on the same N seeded episodes and summarises them.

    Args:
        env_id: Registered id (e.g. ``"KheperaIV-Avoid-v0"``).
        policies: Policy names (see the module docstring) or ``sb3:path.zip``.
        episodes: N, the number of worlds (one episode each) per policy.
        seed: World i is reset with seed + i, for every policy.
        config: Scenario name or TOML path (e.g. ``"paper_fig6"``).
        num_threads: Threads of the vector env (None: all cores).
        record_worlds: How many of the first worlds to record for plots.
        progress: Show progress bars.
        algo: stable-baselines3 algorithm of ``sb3:`` policies.

    Returns:
        The :class:`Comparison`.

    Raises:
        ValueError: No policies, N < 1, duplicate or unknown policies, or a policy that does
            not fit the task.
        ImportError: An ``sb3:`` policy without stable-baselines3.
        KheperaError: A bad scenario (ConfigError) or a policy error.
    """
    if not policies:
        raise ValueError("give at least one policy")
    if len(set(policies)) != len(policies):
        raise ValueError(f"a policy is listed twice: {list(policies)}")
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    env = gym.make_vec(env_id, num_envs=episodes, config=config, num_threads=num_threads)
    try:
        # Every policy is built (sb3 models loaded) before anything runs: errors come first.
        built = {name: make_policy(name, env, seed, algo) for name in policies}
        results, rollouts = {}, {}
        for name, policy in built.items():
            results[name], rollouts[name] = run_policy(
                env, name, policy, seed, record_worlds, progress, f"{_label(env_id, config)} {name}"
            )
        dt = control_step(env)
    finally:
        env.close()
    return Comparison(
        env_id=env_id,
        config=None if config is None else str(config),
        label=_label(env_id, config),
        seed=seed,
        episodes=episodes,
        dt=dt,
        results=results,
        summaries=[summarize(name, results[name]) for name in policies],
        rollouts=rollouts,
    )


# --- output ---------------------------------------------------------------------------------


def format_table(comparison: Comparison) -> str:
    """The summary table: one row per policy, estimates with their 95% intervals."""
    columns = [
        ("policy", lambda s: s.policy),
        ("success %", lambda s: s.success_rate.format(100, 1)),
        ("time to goal s", lambda s: s.time_to_goal_mean.format(1, 1)),
        (f"p{TIME_PERCENTILE:g} time s", lambda s: s.time_to_goal_p95.format(1, 1)),
        ("path m", lambda s: s.path_length_mean.format(1, 2)),
        ("contact steps", lambda s: s.contact_steps_mean.format(1, 1)),
        ("contact %", lambda s: s.contact_rate.format(100, 0)),
    ]
    if comparison.is_formation:
        columns.append(
            (
                "formation err cm",
                lambda s: (
                    "–" if s.formation_error_mean is None else s.formation_error_mean.format(100, 1)
                ),
            )
        )
    rows = [[header for header, _ in columns]]
    rows += [[cell(summary) for _, cell in columns] for summary in comparison.summaries]
    widths = [max(len(row[i]) for row in rows) for i in range(len(columns))]

    def line(row: list[str]) -> str:
        return "  ".join(
            cell.ljust(width) if i == 0 else cell.rjust(width)
            for i, (cell, width) in enumerate(zip(row, widths, strict=True))
        )

    config = f', config="{comparison.config}"' if comparison.config else ""
    title = (
        f"{comparison.env_id}{config}: {comparison.episodes} episodes per policy, "
        f"seeds {comparison.seed}..{comparison.seed + comparison.episodes - 1}"
    )
    rule = "-" * len(line(rows[0]))
    notes = (
        "estimate [95% interval]: Wilson for rates, bootstrap for means and percentiles; "
        "time and path over successful episodes"
    )
    if comparison.is_formation:
        notes += (
            "\nformation: success = the leader reached its goal, path summed over the robots, "
            "error = followers' mean distance to their eq. 12 targets"
        )
    return "\n".join([title, rule, line(rows[0]), rule, *map(line, rows[1:]), rule, notes])


def write_results(comparison: Comparison, out_dir: Path) -> list[Path]:
    """Writes ``<label>_episodes.csv`` (one row per episode) and ``<label>_results.json``
    (settings, summaries with intervals, and every episode) into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = [dataclasses.asdict(r) for results in comparison.results.values() for r in results]
    csv_path = out_dir / f"{comparison.label}_episodes.csv"
    with csv_path.open("w", newline="") as file:
        writer = csv.DictWriter(
            file, fieldnames=[f.name for f in dataclasses.fields(EpisodeResult)]
        )
        writer.writeheader()
        writer.writerows({k: "" if v is None else v for k, v in row.items()} for row in rows)
    json_path = out_dir / f"{comparison.label}_results.json"
    document = {
        "env_id": comparison.env_id,
        "config": comparison.config,
        "seed": comparison.seed,
        "episodes_per_policy": comparison.episodes,
        "dt": comparison.dt,
        "confidence": CONFIDENCE,
        "summaries": [s.to_json() for s in comparison.summaries],
        "episodes": rows,
    }
    json_path.write_text(json.dumps(document, indent=1, allow_nan=False) + "\n")
    return [csv_path, json_path]


def plot_comparison(comparison: Comparison, out_dir: Path) -> Path | None:
    """Draws the recorded worlds, one row per world and one panel per policy (so the panels
    of a row are the same episode), into ``<label>_trajectories.png``; None if none recorded."""
    names = list(comparison.rollouts)
    worlds = min((len(r) for r in comparison.rollouts.values()), default=0)
    if worlds == 0:
        return None
    rollouts = [comparison.rollouts[name][world] for world in range(worlds) for name in names]
    titles = [panel_title(f"{r.label} (seed {r.seed})", r) for r in rollouts]
    config = f', config="{comparison.config}"' if comparison.config else ""
    figure = plot_rollouts(
        rollouts, titles, ncols=len(names), suptitle=f"{comparison.env_id}{config}"
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{comparison.label}_trajectories.png"
    figure.savefig(path, dpi=PLOT_DPI)
    return path


def report(comparison: Comparison, out_dir: Path | None, plot: bool = True) -> list[Path]:
    """Prints the table, writes the files (with ``out_dir``) and says where they are."""
    print(format_table(comparison))
    paths: list[Path] = []
    if out_dir is not None:
        paths += write_results(comparison, out_dir)
        if plot:
            figure_path = plot_comparison(comparison, out_dir)
            if figure_path is not None:
                paths.append(figure_path)
        for path in paths:
            print(f"saved {path}")
    return paths


# --- command line ---------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the options of ``khepera-gym compare`` to a parser."""
    target = parser.add_mutually_exclusive_group(required=True)
    target.add_argument("--task", choices=sorted(TASK_IDS), help="nav, avoid or formation")
    target.add_argument("--env", help="a registered id, e.g. KheperaIV-Avoid-v0")
    parser.add_argument("--config", help="built-in scenario (e.g. paper_fig6) or TOML path")
    parser.add_argument(
        "--policy",
        nargs="+",
        action="extend",
        metavar="NAME",
        help=f"policies to compare: {', '.join(POLICY_NAMES)} or sb3:path/to/model.zip "
        "(default: those that fit the task)",
    )
    parser.add_argument("--algo", help="stable-baselines3 algorithm of sb3: models (PPO, SAC, ...)")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per policy (100)")
    parser.add_argument("--seed", type=int, default=0, help="world i is reset with seed + i (0)")
    parser.add_argument(
        "--out", type=Path, default=Path("compare_out"), help="output folder (compare_out/)"
    )
    parser.add_argument("--num-threads", type=int, default=None, help="threads (all cores)")
    parser.add_argument(
        "--plot", action=argparse.BooleanOptionalAction, default=True, help="save trajectories"
    )
    parser.add_argument(
        "--plot-worlds", type=int, default=1, help="worlds drawn per policy (first ones, 1)"
    )
    parser.add_argument(
        "--progress", action=argparse.BooleanOptionalAction, default=True, help="progress bars"
    )


def run_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym compare`` from parsed arguments.

    Raises:
        SystemExit: With a message naming the problem (unknown policy, missing extra, ...).
    """
    try:
        env_id = resolve_env_id(args.task, args.env)
        task = next((t for t, i in TASK_IDS.items() if i == env_id), None)
        policies = args.policy or list(DEFAULT_POLICIES.get(task or "", ("random",)))
        comparison = compare(
            env_id,
            policies,
            episodes=args.episodes,
            seed=args.seed,
            config=args.config,
            num_threads=args.num_threads,
            record_worlds=args.plot_worlds if args.plot else 0,
            progress=args.progress,
            algo=args.algo,
        )
    except (ValueError, ImportError, OSError, KheperaError) as error:
        raise SystemExit(f"khepera-gym compare: {error}") from error
    report(comparison, args.out, plot=args.plot)
    return 0


#: The demo's comparisons: (title, env id, config, policies, episodes cap, recorded worlds).
DEMO_RUNS: tuple[tuple[str, str, str | None, tuple[str, ...], int | None, int], ...] = (
    (
        "Paper Fig. 6: Braitenberg vs VFH past a wall and an obstacle",
        TASK_IDS["avoid"],
        "paper_fig6",
        ("braitenberg", "vfh", "position_control"),
        None,
        1,
    ),
    (
        "Paper Fig. 7: cross formation of four LeaderFollower followers past obstacles",
        TASK_IDS["formation"],
        "paper_fig7",
        ("leader_follower",),
        None,
        1,
    ),
    (
        "Nav: drive to a goal in an empty arena",
        TASK_IDS["nav"],
        None,
        DEFAULT_POLICIES["nav"],
        None,
        1,
    ),
    (
        "Avoid: 10 random obstacles, new every episode",
        TASK_IDS["avoid"],
        None,
        DEFAULT_POLICIES["avoid"],
        None,
        2,
    ),
    (
        "Formation: cross of four followers, obstacle-free arena",
        TASK_IDS["formation"],
        None,
        DEFAULT_POLICIES["formation"],
        None,
        1,
    ),
)


def demo(episodes: int = 50, out_dir: Path = Path("demo_out"), progress: bool = True) -> int:
    """Runs the comparison on the paper's scenes and the three tasks; prints the tables.

    Args:
        episodes: Episodes per policy and comparison.
        out_dir: Where the CSV, JSON and PNG files go.
        progress: Show progress bars.

    Returns:
        0.
    """
    saved: list[Path] = []
    for title, env_id, config, policies, cap, worlds in DEMO_RUNS:
        print(f"\n== {title}\n")
        comparison = compare(
            env_id,
            policies,
            episodes=episodes if cap is None else min(episodes, cap),
            config=config,
            record_worlds=worlds,
            progress=progress,
        )
        saved += report(comparison, out_dir)
    print(
        f"\nplots (trajectories of the first worlds, one panel per policy) in {out_dir.resolve()}:"
    )
    for path in saved:
        if path.suffix == ".png":
            print(f"  {path.resolve()}")
    return 0


__all__ = [
    "Comparison",
    "EpisodeResult",
    "Estimate",
    "PolicySummary",
    "RandomPolicy",
    "bootstrap_interval",
    "compare",
    "demo",
    "format_table",
    "load_sb3_policy",
    "make_policy",
    "plot_comparison",
    "resolve_env_id",
    "run_policy",
    "summarize",
    "wilson_interval",
    "write_results",
]
