"""Figures of a comparison on a task with a moving reference (Track): the reference and the
robot's actual path, one panel per policy; and each policy's error over time.

The reference is what ``goals()`` reports at reset and after every step (Track: the reference
point p_r(t)), recorded in each :class:`khepera_gym.rollout.Rollout`'s ``goal_trace``. The same
seed gives every policy the same reference (it is drawn at reset from the world's seed, before
any action), so a panel draws, for each recorded world, the longest trace any policy recorded
for it: an episode that ended early (lost) still shows the whole reference when another policy
followed it to the end.

World frame: x right, y up, metres, arena centred at the origin; times in seconds. Figures are
built with matplotlib's object-oriented API (no pyplot, no display).
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt
from matplotlib.figure import Figure

from khepera_gym.analysis.plots import plot_trajectories
from khepera_gym.rollout import Rollout

#: Width and height of one panel (inches).
PANEL_SIZE = 4.8
#: Characters per line of a panel title.
TITLE_WIDTH = 44
#: Lowest error drawn on the log axis of the error plot (m): 0.01 mm; smaller errors are drawn
#: at it.
ERROR_FLOOR = 1e-5


def _reference_of(rollouts: Mapping[str, Sequence[Rollout]], world: int) -> npt.NDArray[np.float64]:
    """The longest goal trace recorded for a world by any policy, (T + 1, 2) (first goal)."""
    traces = [
        r[world].goal_trace
        for r in rollouts.values()
        if len(r) > world and r[world].goal_trace is not None
    ]
    if not traces:
        raise ValueError(f"no rollout of world {world} has a goal trace (goal_trace is None)")
    return np.asarray(max(traces, key=len), dtype=float)[:, 0, :2]


def plot_reference_paths(
    rollouts: Mapping[str, Sequence[Rollout]],
    *,
    error_stat: str | None = "track_error_rms",
    suptitle: str | None = None,
) -> Figure:
    """One panel per policy: each recorded world's reference (dashed) and the robot's path
    (solid, same colour), with the robot at the start and at the end and the reference point
    at the start (a star).

    Args:
        rollouts: Per policy (in panel order), its recorded worlds; world w of every policy is
            the same seeded episode.
        error_stat: Episode statistic quoted per world in the panel title (in mm), if present.
        suptitle: Title of the figure.

    Returns:
        The figure.

    Raises:
        ValueError: No policies or no recorded world.
    """
    names = list(rollouts)
    worlds = min((len(r) for r in rollouts.values()), default=0)
    if not names or worlds == 0:
        raise ValueError("need at least one policy with at least one recorded world")
    references = [_reference_of(rollouts, world) for world in range(worlds)]
    figure = Figure(figsize=(PANEL_SIZE * len(names), PANEL_SIZE + 1.3), layout="constrained")
    axes = figure.subplots(1, len(names), squeeze=False).ravel()
    for ax, name in zip(axes, names, strict=True):
        episodes = rollouts[name][:worlds]
        errors = [
            f"{1000 * r.stats[error_stat]:.1f}"
            for r in episodes
            if error_stat is not None and error_stat in r.stats
        ]
        seeds = ", ".join(str(r.seed) for r in episodes)
        summary = f"seeds {seeds}"
        if errors:
            summary += f": RMS error {', '.join(errors)} mm"
        title = f"{name}\n{textwrap.fill(summary, TITLE_WIDTH)}"
        plot_trajectories(
            [r.poses[:, 0] for r in episodes],
            episodes[0].scene,
            ax=ax,
            title=title,
            labels=[f"seed {r.seed}" for r in episodes],
        )
        legend = ax.get_legend()
        if legend is not None:  # one legend for the figure: the worlds' colours are shared
            legend.remove()
        for world, reference in enumerate(references):
            colour = f"C{world % 10}"
            ax.plot(*reference.T, color=colour, linestyle="--", linewidth=0.9, alpha=0.8)
            ax.scatter(*reference[0], marker="*", s=70, color=colour, zorder=7)
    handles, labels = axes[0].get_legend_handles_labels()
    # One legend, in the last panel's lower margin (the references stay within ±0.6 m): a
    # figure legend "outside" the axes needs matplotlib 3.7, and the floor is 3.6.
    axes[-1].legend(
        handles[:worlds],
        labels[:worlds],
        loc="lower center",
        ncols=min(worlds, 6),
        fontsize="x-small",
        title="robot solid, reference dashed, star: reference at the start",
        title_fontsize="x-small",
    )
    if suptitle is not None:
        figure.suptitle(suptitle)
    return figure


def _held(trace: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Each world's error with its last value held after its episode ended (NaN filled
    forward along time), so an episode lost early keeps counting with its final error."""
    held = np.array(trace, dtype=float)
    for step in range(1, len(held)):
        missing = np.isnan(held[step])
        held[step, missing] = held[step - 1, missing]
    return held


def plot_error_over_time(
    traces: Mapping[str, npt.ArrayLike],
    dt: float,
    *,
    error: str = "tracking error",
    radius: float | None = 0.02,
    title: str | None = None,
) -> Figure:
    """Each policy's error over time: the median over its episodes and the band between the
    quartiles, on a log scale; an episode that ended early keeps its last error.

    Args:
        traces: Per policy, the error of every world at reset and after every step, (T + 1, N)
            in m, NaN once its episode had ended (:attr:`Comparison.error_traces`).
        dt: Control step (s).
        error: What the error is (the axis label).
        radius: The convergence radius drawn as a horizontal line (m), or None.
        title: Axes title.

    Returns:
        The figure.

    Raises:
        ValueError: No policies, or a trace that is not (T + 1, N).
    """
    if not traces:
        raise ValueError("need at least one policy's error trace")
    figure = Figure(figsize=(7.2, 4.2), layout="constrained")
    ax = figure.add_subplot()
    for index, (name, trace) in enumerate(traces.items()):
        values = np.asarray(trace, dtype=float)
        if values.ndim != 2 or len(values) == 0:
            raise ValueError(f"error trace of {name!r} must be (T + 1, N), got {values.shape}")
        held = np.maximum(_held(values), ERROR_FLOOR)
        time = np.arange(len(held)) * dt
        low, median, high = np.nanpercentile(held, [25, 50, 75], axis=1)
        colour = f"C{index % 10}"
        # An explicit `where` (an array): matplotlib 3.6, the floor, fails on the default one.
        band = np.isfinite(low) & np.isfinite(high)
        ax.fill_between(time, low, high, where=band, color=colour, alpha=0.2, linewidth=0)
        ax.plot(time, median, color=colour, label=f"{name} (median, quartiles)")
    if radius is not None:
        ax.axhline(radius, color="0.3", linestyle=":", linewidth=1)
        ax.annotate(
            f"{radius * 100:g} cm",
            (0, radius),
            xytext=(2, 2),
            textcoords="offset points",
            fontsize="small",
            color="0.3",
        )
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{error} (m)")
    ax.legend(fontsize="small", loc="upper right")
    if title is not None:
        ax.set_title(title, fontsize="medium")
    return figure


__all__ = ["ERROR_FLOOR", "PANEL_SIZE", "plot_error_over_time", "plot_reference_paths"]
