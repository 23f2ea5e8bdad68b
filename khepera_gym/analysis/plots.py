"""Trajectory plots with matplotlib: arena walls, obstacles, goals, robot discs and paths.

The counterpart of the KH4VREP library's ``plot`` (the paper's Table 1): :func:`record_rollout`
(:mod:`khepera_gym.rollout`, re-exported here) runs one seeded episode with a policy and keeps
the poses of every step, the goals, the scene and the episode statistics (a :class:`Rollout`);
:func:`plot_rollouts` draws one or several
rollouts side by side (e.g. the paper's Fig. 6, Braitenberg vs VFH); :func:`plot_trajectories`
draws paths into one axes: one or several robots per episode (a formation: the leader and its
followers, each with its trace), optionally the formation's target points and snapshots of the
robots along the way. A task with a reference to follow (Track's trajectory, PathFollow's path:
the scene's ``"paths"``) is drawn with its reference and the robot's lap instead of a goal.

Works headless: figures are built with matplotlib's object-oriented API (``Figure``), never through
``pyplot``'s global state, so no display or GUI backend is needed and saving uses Agg. World frame:
x right, y up, metres, arena centred at the origin.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from khepera_gym.rollout import Rollout, control_step, record_rollout, rollout_summary

#: Colour of walls and obstacles.
_WALL_COLOUR = "0.25"
#: Drawn thickness of the arena walls when the scene does not give one (m).
_DEFAULT_WALL_THICKNESS = 0.05
#: Colour of the leader of a formation (its followers take the colour cycle C0, C1, ...).
_LEADER_COLOUR = "black"
#: Line width of a thin wall segment in points.
_SEGMENT_WIDTH = 3.0
#: Characters per line of a panel title of :func:`plot_rollouts` (fits a 4.8-inch panel).
_TITLE_WIDTH = 44
#: Colour of a task's reference path (Track, PathFollow).
_REFERENCE_COLOUR = "0.45"


def _xy(value: Any) -> tuple[float, float]:
    x, y = (float(v) for v in value)
    return x, y


def _draw_obstacle(ax: Axes, obstacle: Mapping[str, Any]) -> None:
    """Draws one obstacle of ``_core.Batch.scene()``; kinds: circle, box, segment.

    Everything is a patch or a collection, so ``ax.lines`` holds only the robots' paths.
    """
    kind = obstacle.get("kind")
    centre = obstacle.get("center", obstacle.get("centre"))
    style = {"facecolor": "0.6", "edgecolor": _WALL_COLOUR, "zorder": 2}
    if kind == "circle":
        ax.add_patch(Circle(_xy(centre), float(obstacle["radius"]), **style))
    elif kind == "box":
        if "half_extents" in obstacle:
            half_x, half_y = _xy(obstacle["half_extents"])
        else:
            size_x, size_y = _xy(obstacle["size"])
            half_x, half_y = size_x / 2, size_y / 2
        angle = float(obstacle.get("angle", 0.0))
        corners = np.array(
            [[-half_x, -half_y], [half_x, -half_y], [half_x, half_y], [-half_x, half_y]]
        )
        rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        ax.add_patch(Polygon(corners @ rotation.T + np.array(_xy(centre)), closed=True, **style))
    elif kind == "segment":
        start = obstacle.get("a", obstacle.get("start"))
        end = obstacle.get("b", obstacle.get("end"))
        segment = LineCollection(
            [[_xy(start), _xy(end)]],
            colors=_WALL_COLOUR,
            linewidths=_SEGMENT_WIDTH,
            capstyle="round",
            zorder=2,
        )
        ax.add_collection(segment)
    else:
        raise ValueError(f"cannot draw obstacle of kind {kind!r}: {dict(obstacle)}")


def _draw_arena(ax: Axes, scene: Mapping[str, Any]) -> None:
    """Draws the floor, the walls (or a dashed border for an open floor) and the obstacles."""
    width, height = _xy(scene["arena"])
    thickness = float(scene.get("wall_thickness", _DEFAULT_WALL_THICKNESS))
    if bool(scene.get("walls", True)):
        ax.add_patch(
            Rectangle(
                (-width / 2 - thickness, -height / 2 - thickness),
                width + 2 * thickness,
                height + 2 * thickness,
                facecolor=_WALL_COLOUR,
                zorder=0,
            )
        )
        floor_style: dict[str, Any] = {"facecolor": "white"}
    else:
        floor_style = {"facecolor": "white", "edgecolor": _WALL_COLOUR, "linestyle": "--"}
    ax.add_patch(Rectangle((-width / 2, -height / 2), width, height, zorder=0.5, **floor_style))
    for obstacle in scene.get("obstacles", []):
        _draw_obstacle(ax, obstacle)
    margin = thickness + 0.05
    ax.set_xlim(-width / 2 - margin, width / 2 + margin)
    ax.set_ylim(-height / 2 - margin, height / 2 + margin)


def _draw_robot(
    ax: Axes, pose: npt.NDArray[np.floating], radius: float, colour: Any, alpha: float = 0.35
) -> None:
    x, y = float(pose[0]), float(pose[1])
    ax.add_patch(Circle((x, y), radius, facecolor=colour, edgecolor="black", alpha=alpha, zorder=3))
    if len(pose) >= 3:
        theta = float(pose[2])
        ax.add_collection(
            LineCollection(
                [[(x, y), (x + radius * np.cos(theta), y + radius * np.sin(theta))]],
                colors="black",
                linewidths=1,
                zorder=4,
            )
        )


def _as_robot_paths(trajectory: npt.ArrayLike, index: int) -> npt.NDArray[np.float64]:
    """One episode as an array (T, R, 2 or 3); a single-robot (T, 2 or 3) gets R = 1."""
    path = np.asarray(trajectory, dtype=float)
    if path.ndim == 2:
        path = path[:, None, :]
    if path.ndim != 3 or path.shape[2] not in (2, 3) or len(path) == 0 or path.shape[1] == 0:
        raise ValueError(
            f"trajectory {index} must have shape (T, 2), (T, 3), (T, R, 2) or (T, R, 3) with "
            f"T, R >= 1, got {np.shape(trajectory)}"
        )
    return path


def _snapshot_times(length: int, snapshots: int) -> list[int]:
    """``snapshots`` evenly spaced step indices strictly inside 0..length-1 (no duplicates)."""
    if snapshots <= 0 or length < 3:
        return []
    times = np.linspace(0, length - 1, snapshots + 2).round().astype(int)[1:-1]
    return sorted({int(t) for t in times} - {0, length - 1})


def plot_trajectories(
    trajectories: Sequence[npt.ArrayLike],
    scene: Mapping[str, Any],
    goals: Sequence[npt.ArrayLike] | npt.ArrayLike | None = None,
    ax: Axes | None = None,
    title: str | None = None,
    *,
    targets: Sequence[npt.ArrayLike | None] | None = None,
    leader: int | None = None,
    robot_names: Sequence[str] | None = None,
    snapshots: int = 0,
    labels: Sequence[str] | None = None,
    references: Sequence[npt.ArrayLike] | None = None,
) -> Figure:
    """Plots robot paths in the arena: one or several robots per episode.

    With one robot per episode each episode has its own colour (legend "episode"). With several
    robots (e.g. a formation: ``env.unwrapped.poses()`` of shape (R, 3) recorded every step)
    each robot has its own colour, the same in every episode; robot ``leader`` is drawn thicker
    in black. Robots are drawn as discs (with their heading) at the start and the end, and at
    ``snapshots`` evenly spaced times in between, where a formation's leader is joined to its
    followers by thin lines.

    Args:
        trajectories: One array per episode: (T, 3) (x, y, θ) or (T, 2) (x, y) for one robot,
            (T, R, 3) or (T, R, 2) for R robots; metres, radians.
        scene: ``env.unwrapped.scene()``: "arena" (w, h), "walls", "wall_thickness",
            "robot_radius", "obstacles" (circle, box, segment), "goal_radius".
        goals: Per episode None, one goal (x, y) or several (n_goals, 2) (one per robot, drawn in
            its colour, for several robots with their own goals); or None for no goals at all.
        ax: Axes to draw into; None creates a new figure.
        title: Axes title.
        targets: Per episode None or the formation's target points, (K, 2) at the end or
            (T, K, 2) every step (``formation_targets()``); drawn as crosses in the colours of
            robots 1..K (the followers) at the end and at the snapshots.
        leader: Index of the leader among the R robots (0 in a formation), or None.
        robot_names: Legend labels of the R robots (e.g. ``["leader", "follower_0", ...]``).
        snapshots: Number of intermediate times at which the robots are drawn.
        labels: Legend labels of the episodes (one robot per episode); default their index.
        references: Reference paths to follow, each (P, 2) (m): drawn dashed in grey under the
            robots' paths, labelled "reference" (a scene's ``"paths"``).

    Returns:
        The figure drawn into (save it with ``fig.savefig(path)``).

    Raises:
        ValueError: A trajectory, goal or target list of the wrong shape or length.
    """
    paths = [_as_robot_paths(trajectory, index) for index, trajectory in enumerate(trajectories)]
    multi_robot = any(path.shape[1] > 1 for path in paths)
    if ax is None:
        # Several robots: wider, for the legend right of the arena.
        figure = Figure(figsize=(7.6 if multi_robot else 6, 6), layout="constrained")
        ax = figure.add_subplot()
    else:
        figure = ax.get_figure()
    _draw_arena(ax, scene)
    for index, reference in enumerate(references or []):
        ax.plot(
            *np.asarray(reference, dtype=float).reshape(-1, 2).T,
            linestyle="--",
            color=_REFERENCE_COLOUR,
            linewidth=1.2,
            zorder=1,
            label="reference" if index == 0 else None,
        )
    robot_radius = float(scene.get("robot_radius", 0.0704))
    goal_radius = float(scene.get("goal_radius", 0.05))
    goal_list = [None] * len(paths) if goals is None else list(goals)
    target_list = [None] * len(paths) if targets is None else list(targets)
    label_list = [f"{index}" for index in range(len(paths))] if labels is None else list(labels)
    for name, values in (("goals", goal_list), ("targets", target_list), ("labels", label_list)):
        if len(values) != len(paths):
            raise ValueError(f"got {len(values)} {name} for {len(trajectories)} trajectories")

    def colour_of(episode: int, robot: int) -> Any:
        if not multi_robot:
            return f"C{episode % 10}"
        if robot == leader:
            return _LEADER_COLOUR
        follower_rank = robot - (1 if leader is not None and robot > leader else 0)
        return f"C{follower_rank % 10}"

    for episode, (path, goal, episode_targets) in enumerate(
        zip(paths, goal_list, target_list, strict=True)
    ):
        n_robots = path.shape[1]
        times = _snapshot_times(len(path), snapshots)
        for robot in range(n_robots):
            colour = colour_of(episode, robot)
            if not multi_robot:
                label = label_list[episode]
            elif episode == 0:
                label = robot_names[robot] if robot_names is not None else f"robot {robot}"
            else:
                label = None
            is_leader = robot == leader
            ax.plot(
                path[:, robot, 0],
                path[:, robot, 1],
                color=colour,
                linewidth=2.2 if is_leader else 1.3,
                zorder=5.5 if is_leader else 5,
                label=label,
            )
            for time in (0, *times, len(path) - 1):
                alpha = 0.35 if time in (0, len(path) - 1) else 0.2
                _draw_robot(ax, path[time, robot], robot_radius, colour, alpha)
            ax.scatter(*path[0, robot, :2], s=12, color=colour, zorder=6)
        if leader is not None and n_robots > 1:
            spokes = [
                [tuple(path[time, leader, :2]), tuple(path[time, robot, :2])]
                for time in (0, *times, len(path) - 1)
                for robot in range(n_robots)
                if robot != leader
            ]
            ax.add_collection(LineCollection(spokes, colors="0.5", linewidths=0.6, zorder=3.5))
        if goal is not None:
            goal_points = np.asarray(goal, dtype=float).reshape(-1, 2)
            for index, (goal_x, goal_y) in enumerate(goal_points):
                robot = index if len(goal_points) == n_robots else (leader or 0)
                colour = colour_of(episode, robot)
                ax.add_patch(
                    Circle((goal_x, goal_y), goal_radius, fill=False, color=colour, zorder=6)
                )
                ax.scatter(goal_x, goal_y, marker="*", s=110, color=colour, zorder=6)
        if episode_targets is not None:
            _draw_targets(ax, np.asarray(episode_targets, float), times, episode, colour_of)

    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title is not None:
        ax.set_title(title)
    if multi_robot and paths[0].shape[1] <= 16:
        # Outside the arena, right of it: a formation's legend would hide part of the floor.
        ax.legend(title="robot", loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    elif not multi_robot and labels is not None:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), fontsize="small")
    elif references and len(paths) == 1:
        ax.legend(loc="upper right", fontsize="small")
    elif not multi_robot and 1 < len(paths) <= 10:
        ax.legend(title="episode", loc="upper right", fontsize="small")
    return figure


def _draw_targets(
    ax: Axes, targets: npt.NDArray[np.float64], times: list[int], episode: int, colour_of: Any
) -> None:
    """Draws formation targets (K, 2) or (T, K, 2) as crosses in the followers' colours."""
    if targets.ndim == 2:
        targets = targets[None]
        times = []
    if targets.ndim != 3 or targets.shape[2] != 2:
        raise ValueError(f"targets must have shape (K, 2) or (T, K, 2), got {targets.shape}")
    for time in (*times, len(targets) - 1):
        for follower, (x, y) in enumerate(targets[time]):
            ax.scatter(x, y, marker="x", s=30, color=colour_of(episode, follower + 1), zorder=7)


def _draw_timed_snapshots(ax: Axes, rollout: Rollout, period: float) -> None:
    """The robot every ``period`` seconds along a single-robot rollout, labelled "5 s", ...;
    a snapshot within a robot radius of the previous one or of the end is left out, so a
    robot that stands still is not drawn over and over."""
    radius = float(rollout.scene.get("robot_radius", 0.0704))
    every = max(1, round(period / rollout.dt))
    last, end = rollout.poses[0, 0, :2], rollout.poses[-1, 0, :2]
    for step in range(every, len(rollout.poses) - 1, every):
        pose = rollout.poses[step, 0]
        if min(np.hypot(*(pose[:2] - last)), np.hypot(*(pose[:2] - end))) < radius:
            continue
        last = pose[:2]
        _draw_robot(ax, pose, radius, "C0", alpha=0.15)
        ax.annotate(
            f"{step * rollout.dt:g} s",
            (float(pose[0]), float(pose[1])),
            xytext=(0, 9),
            textcoords="offset points",
            ha="center",
            fontsize="x-small",
            zorder=7,
        )


def panel_title(heading: str, rollout: Rollout, width: int = _TITLE_WIDTH) -> str:
    """``heading`` over :func:`rollout_summary`, wrapped to ``width`` characters a line."""
    summary = textwrap.fill(rollout_summary(rollout), width)
    return f"{heading}\n{summary}" if heading else summary


def plot_rollouts(
    rollouts: Sequence[Rollout],
    titles: Sequence[str] | None = None,
    *,
    ncols: int | None = None,
    panel_size: float = 4.8,
    snapshots: int = 3,
    snapshot_period: float | None = 5.0,
    suptitle: str | None = None,
) -> Figure:
    """Draws rollouts side by side, one panel each, in the style of the paper's Figs. 6 and 7.

    A single-robot rollout shows its path with the robot at the start, the end and every
    ``snapshot_period`` seconds (labelled with the time, so panels compare speeds), the goal
    and the obstacles; on a task with a reference (the scene's ``"paths"``: Track, PathFollow)
    the reference, dashed, instead of the goal, and the robot's lap; a formation shows one
    trace per robot (the leader in black), the robots and their targets at ``snapshots``
    intermediate times, joined to the leader.

    Args:
        rollouts: The rollouts (e.g. one per policy on the same seed).
        titles: One title per panel; default each rollout's label and :func:`rollout_summary`.
        ncols: Panels per row (default all in one row, at most 4).
        panel_size: Width and height of a panel (inches).
        snapshots: Intermediate snapshots of a formation.
        snapshot_period: Seconds between the snapshots of a single robot (None: none).
        suptitle: Title of the whole figure.

    Returns:
        The figure (save it with ``fig.savefig(path)``).

    Raises:
        ValueError: No rollouts, or a title count that does not match.
    """
    if not rollouts:
        raise ValueError("plot_rollouts needs at least one rollout")
    if titles is None:
        titles = [panel_title(r.label, r) for r in rollouts]
    if len(titles) != len(rollouts):
        raise ValueError(f"got {len(titles)} titles for {len(rollouts)} rollouts")
    ncols = min(len(rollouts), 4) if ncols is None else max(1, ncols)
    nrows = -(-len(rollouts) // ncols)
    multi_robot = any(r.n_robots > 1 for r in rollouts)
    width = panel_size * (1.3 if multi_robot else 1.0)
    height = (panel_size + 0.6) * nrows + (0.3 if suptitle else 0.0)
    figure = Figure(figsize=(width * ncols, height), layout="constrained")
    axes = figure.subplots(nrows, ncols, squeeze=False).ravel()
    for ax, rollout, title in zip(axes, rollouts, titles, strict=False):
        if rollout.n_robots > 1 and rollout.targets is None:  # several robots, own goals
            plot_trajectories(
                [rollout.poses],
                rollout.scene,
                goals=[rollout.goals],
                ax=ax,
                title=title,
                robot_names=[f"robot_{i}" for i in range(rollout.n_robots)],
            )
        elif rollout.n_robots > 1:  # a formation, leader first
            k = rollout.n_robots - 1
            plot_trajectories(
                [rollout.poses],
                rollout.scene,
                goals=[rollout.goals[:1]],
                ax=ax,
                title=title,
                targets=[rollout.targets],
                leader=0,
                robot_names=["leader"] + [f"follower_{i}" for i in range(k)],
                snapshots=snapshots,
            )
        else:
            references = rollout.scene.get("paths") or None
            plot_trajectories(
                [rollout.poses[:, 0]],
                rollout.scene,
                # A reference's moving point is no goal to reach: the reference is drawn instead.
                goals=None if references else [rollout.goals[0]],
                ax=ax,
                title=title,
                references=references,
                labels=["robot"] if references else None,
            )
            if snapshot_period:
                _draw_timed_snapshots(ax, rollout, snapshot_period)
    for ax in axes[len(rollouts) :]:
        ax.set_axis_off()
    if suptitle is not None:
        figure.suptitle(suptitle)
    return figure


__all__ = [
    "Rollout",
    "control_step",
    "panel_title",
    "plot_rollouts",
    "plot_trajectories",
    "record_rollout",
    "rollout_summary",
]
