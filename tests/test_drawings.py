"""Pictures that say what happened (issue 33): a tracking or path-following panel draws the
reference and the lap, not Nav's goal; a reaching task's panel keeps its goal."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST
from matplotlib.figure import Figure

from khepera_gym.analysis.plots import plot_rollouts
from khepera_gym.baselines import Kanayama, PositionControl, PurePursuit
from khepera_gym.rollout import record_rollout


def goal_stars(figure: Figure) -> int:
    """Markers drawn as stars (the goal's marker) on the figure's first panel; matplotlib's "*"
    is a 10-vertex polygon (11 with its closing vertex)."""
    return sum(
        1
        for collection in figure.axes[0].collections
        if len(paths := collection.get_paths()) == 1 and len(paths[0].vertices) in (10, 11)
    )


@pytest.mark.parametrize(
    ("env_id", "baseline", "outcome"),
    [(LATEST["track"], Kanayama, "RMS error"), (LATEST["pathfollow"], PurePursuit, "lap in")],
)
def test_a_reference_task_panel_draws_the_reference_not_a_goal(
    env_id: str, baseline: type, outcome: str
) -> None:
    env = gym.make(env_id)
    rollout = record_rollout(env, baseline.for_env(env), seed=0)
    env.close()
    reference = np.asarray(rollout.scene["paths"][0], float)
    figure = plot_rollouts([rollout])
    ax = figure.axes[0]
    dashed = [line for line in ax.lines if line.get_linestyle() == "--"]
    assert any(np.allclose(line.get_xydata(), reference[:, :2]) for line in dashed), (
        "the reference path is drawn dashed"
    )
    assert goal_stars(figure) == 0, "a moving reference is no goal to reach"
    assert "reached" not in ax.get_title() and outcome in ax.get_title()


def test_a_reaching_task_panel_keeps_its_goal() -> None:
    env = gym.make(LATEST["nav"])
    rollout = record_rollout(env, PositionControl.for_env(env), seed=0)
    env.close()
    figure = plot_rollouts([rollout])
    assert goal_stars(figure) == 1
    assert "reached in" in figure.axes[0].get_title()
