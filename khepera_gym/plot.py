"""Trajectory plots with matplotlib: arena walls, obstacles, goals, robot discs and paths.

Works headless: figures are built with matplotlib's object-oriented API (``Figure``), never through
``pyplot``'s global state, so no display or GUI backend is needed and saving uses Agg. World frame:
x right, y up, metres, arena centred at the origin.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

#: Colour of walls and obstacles.
_WALL_COLOUR = "0.25"
#: Drawn thickness of the arena walls when the scene does not give one (m).
_DEFAULT_WALL_THICKNESS = 0.05


def _xy(value: Any) -> tuple[float, float]:
    x, y = (float(v) for v in value)
    return x, y


def _draw_obstacle(ax: Axes, obstacle: Mapping[str, Any]) -> None:
    """Draws one obstacle of ``_core.Batch.scene()``; kinds: circle, box, segment."""
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
        start = obstacle.get("start", obstacle.get("a"))
        end = obstacle.get("end", obstacle.get("b"))
        (x0, y0), (x1, y1) = _xy(start), _xy(end)
        ax.plot([x0, x1], [y0, y1], color=_WALL_COLOUR, linewidth=3, zorder=2)
    else:
        raise ValueError(f"cannot draw obstacle of kind {kind!r}: {dict(obstacle)}")


def _draw_arena(ax: Axes, scene: Mapping[str, Any]) -> None:
    width, height = _xy(scene["arena"])
    thickness = float(scene.get("wall_thickness", _DEFAULT_WALL_THICKNESS))
    ax.add_patch(
        Rectangle(
            (-width / 2 - thickness, -height / 2 - thickness),
            width + 2 * thickness,
            height + 2 * thickness,
            facecolor=_WALL_COLOUR,
            zorder=0,
        )
    )
    ax.add_patch(Rectangle((-width / 2, -height / 2), width, height, facecolor="white", zorder=0.5))
    for obstacle in scene.get("obstacles", []):
        _draw_obstacle(ax, obstacle)
    margin = thickness + 0.05
    ax.set_xlim(-width / 2 - margin, width / 2 + margin)
    ax.set_ylim(-height / 2 - margin, height / 2 + margin)


def _draw_robot(ax: Axes, pose: npt.NDArray[np.floating], radius: float, colour: Any) -> None:
    x, y = float(pose[0]), float(pose[1])
    ax.add_patch(Circle((x, y), radius, facecolor=colour, edgecolor="black", alpha=0.35, zorder=3))
    if len(pose) >= 3:
        theta = float(pose[2])
        ax.plot(
            [x, x + radius * np.cos(theta)],
            [y, y + radius * np.sin(theta)],
            color="black",
            linewidth=1,
            zorder=4,
        )


def plot_trajectories(
    trajectories: Sequence[npt.ArrayLike],
    scene: Mapping[str, Any],
    goals: Sequence[npt.ArrayLike] | npt.ArrayLike | None = None,
    ax: Axes | None = None,
    title: str | None = None,
) -> Figure:
    """Plots robot paths in the arena.

    Args:
        trajectories: One array per episode of shape (T, 3) (x, y, θ) or (T, 2) (x, y), in metres.
        scene: ``env.unwrapped.scene()``: "arena" (w, h), "robot_radius", "obstacles",
            "goal_radius".
        goals: One goal (x, y) per trajectory (or an array of shape (len(trajectories), 2)),
            or None.
        ax: Axes to draw into; None creates a new figure.
        title: Axes title.

    Returns:
        The figure drawn into (save it with ``fig.savefig(path)``).
    """
    if ax is None:
        figure = Figure(figsize=(6, 6), layout="constrained")
        ax = figure.add_subplot()
    else:
        figure = ax.get_figure()
    _draw_arena(ax, scene)
    robot_radius = float(scene.get("robot_radius", 0.0704))
    goal_radius = float(scene.get("goal_radius", 0.05))
    colours = [f"C{index % 10}" for index in range(len(trajectories))]
    goal_list = [None] * len(trajectories) if goals is None else list(np.asarray(goals, float))
    if len(goal_list) != len(trajectories):
        raise ValueError(f"got {len(goal_list)} goals for {len(trajectories)} trajectories")

    for index, (trajectory, goal, colour) in enumerate(
        zip(trajectories, goal_list, colours, strict=True)
    ):
        path = np.asarray(trajectory, dtype=float)
        if path.ndim != 2 or path.shape[1] not in (2, 3) or len(path) == 0:
            raise ValueError(
                f"trajectory {index} must have shape (T, 2) or (T, 3), got {path.shape}"
            )
        ax.plot(path[:, 0], path[:, 1], color=colour, linewidth=1.5, zorder=5, label=f"{index}")
        _draw_robot(ax, path[0], robot_radius, colour)
        _draw_robot(ax, path[-1], robot_radius, colour)
        ax.plot(path[0, 0], path[0, 1], "o", color=colour, markersize=4, zorder=6)
        if goal is not None:
            goal_x, goal_y = _xy(np.ravel(goal)[:2])
            ax.add_patch(Circle((goal_x, goal_y), goal_radius, fill=False, color=colour, zorder=6))
            ax.plot(goal_x, goal_y, "*", color=colour, markersize=10, zorder=6)

    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title is not None:
        ax.set_title(title)
    if 1 < len(trajectories) <= 10:
        ax.legend(title="episode", loc="upper right", fontsize="small")
    return figure


__all__ = ["plot_trajectories"]
