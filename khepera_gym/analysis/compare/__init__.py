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
  comparison is deterministic;
* the mean speed (m/s, path over duration) of single-robot tasks;
* on a task scored by an error to a reference (Track), instead of success and time: the mean
  RMS and largest error after the transient (mm), the IAE (m·s), the share of episodes that
  converged below 2 cm (Wilson), the median converge time (an episode that never converged
  counts as inf: never averaged), and the share lost (terminated).

Which columns a task has is one entry of :data:`TASK_METRICS`
(:mod:`khepera_gym.analysis.compare.metrics`).

It writes the per-episode results as CSV and JSON and draws the first worlds' trajectories
side by side, one panel per policy, in the style of the paper's Figs. 6 and 7
(:func:`khepera_gym.analysis.plots.plot_rollouts`); on Track, the reference and the robot's path of
the first worlds overlaid, one panel per policy, and each policy's error over time
(:mod:`khepera_gym.analysis.compare.reference_plots`). Policies are named:

* ``position_control``, ``braitenberg``, ``braitenberg_kteam`` (K-Team's weights), ``vfh``, and
  ``position_control_slow``, ``braitenberg_slow``, ``vfh_slow`` (cruising at K-Team's demo speed,
  0.136 m/s):
  :mod:`khepera_gym.baselines` on Nav/Avoid observations;
* ``leader_follower``: :class:`khepera_gym.baselines.LeaderFollower` with the scenario's
  formation (Formation task);
* ``kanayama``, ``position_chase``: :class:`khepera_gym.baselines.Kanayama` and
  :class:`khepera_gym.baselines.PositionChase` (Track task);
* ``samson``, ``pure_pursuit``, ``waypoint_switching``: :class:`khepera_gym.baselines.Samson`,
  :class:`~khepera_gym.baselines.PurePursuit` and :class:`~khepera_gym.baselines.WaypointSwitching`
  (PathFollow task);
* ``line_threshold``, ``line_proportional``: :class:`khepera_gym.baselines.LineThreshold` and
  :class:`~khepera_gym.baselines.LineProportional` on the ground sensors (LineFollow task);
* ``drone_pursuit``: :class:`khepera_gym.baselines.DronePursuit` (DroneFollow task);
* ``blob_servo``, ``blob_vfh``: :class:`khepera_gym.baselines.BlobServo` and
  :class:`~khepera_gym.baselines.BlobVFH` on the camera (Seek task);
* ``random``: uniform actions in [-1, 1] from a generator seeded with the comparison's seed;
* ``sb3:path/to/model.zip``: a stable-baselines3 model, loaded with ``--algo``'s class or by
  trying PPO, SAC, TD3, A2C and DQN in turn, acting deterministically (needs the ``sb3`` extra);
  with ``--sample-actions`` it samples its actions from its distribution, torch seeded with
  ``--seed``, and is named ``sb3:path/to/model.zip (sampled)``.

Command line (``khepera-gym compare --help``)::

    khepera-gym compare --task avoid --policy braitenberg vfh --episodes 200 --out results/
    khepera-gym compare --task avoid --config paper_fig6 --policy braitenberg vfh --episodes 20
    khepera-gym compare --task track --set reference=square --episodes 200 --plot-worlds 3

``--set KEY=VALUE`` (repeatable) overrides a scenario key as ``gym.make``'s keywords do; the
output files' label gets ``_key-value`` (``track_reference-square_episodes.csv``).

``khepera-gym demo`` (:func:`demo`) runs it on the paper's scenes and every task.

Units: seconds and metres (formation errors in the table in cm, tracking errors in mm).
Threading: the vector env steps its worlds on its own rayon pool (``--num-threads``, all cores
by default) with the GIL released; policies run in the calling thread between steps.
"""

from khepera_gym.analysis.compare.command import (
    DEMO_RUNS,
    add_arguments,
    demo,
    parse_overrides,
    run_from_args,
)
from khepera_gym.analysis.compare.metrics import TASK_METRICS, TaskMetrics, task_metrics
from khepera_gym.analysis.compare.reference_plots import plot_error_over_time, plot_reference_paths
from khepera_gym.analysis.compare.report import (
    format_table,
    plot_comparison,
    plot_errors,
    report,
    write_results,
)
from khepera_gym.analysis.compare.run import (
    Comparison,
    EpisodeResult,
    PolicySummary,
    compare,
    resolve_env_id,
    run_policy,
    summarize,
)
from khepera_gym.learning.policies import (
    DEFAULT_POLICIES,
    POLICY_NAMES,
    SB3_ALGORITHMS,
    SB3_PREFIX,
    RandomPolicy,
    SB3Policy,
    load_sb3_policy,
    make_policy,
)
from khepera_gym.registration import latest_ids
from khepera_gym.tooling.stats import (
    CONFIDENCE,
    Estimate,
    bootstrap_interval,
    event_time_median,
    wilson_interval,
)

#: Registered id (latest version) of each task name of ``--task``.
TASK_IDS = latest_ids()

__all__ = [
    "CONFIDENCE",
    "DEFAULT_POLICIES",
    "DEMO_RUNS",
    "POLICY_NAMES",
    "SB3_ALGORITHMS",
    "SB3_PREFIX",
    "TASK_IDS",
    "TASK_METRICS",
    "Comparison",
    "EpisodeResult",
    "Estimate",
    "PolicySummary",
    "RandomPolicy",
    "SB3Policy",
    "TaskMetrics",
    "add_arguments",
    "bootstrap_interval",
    "compare",
    "demo",
    "event_time_median",
    "format_table",
    "load_sb3_policy",
    "make_policy",
    "parse_overrides",
    "plot_comparison",
    "plot_error_over_time",
    "plot_errors",
    "plot_reference_paths",
    "report",
    "resolve_env_id",
    "run_from_args",
    "run_policy",
    "summarize",
    "task_metrics",
    "wilson_interval",
    "write_results",
]
