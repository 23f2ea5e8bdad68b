"""Several Khepera IV robots, each driving to its own goal, as PettingZoo agents: the manual of
the ``multinav_vN`` modules (one a behaviour version, the same env on that version's dynamics).

Every robot is an agent (``robot_0`` .. ``robot_{N-1}``) with the Nav observation (18 values:
IR, ultrasonic, goal distance and bearing, wheel speeds; the table of
:class:`khepera_gym.envs.NavEnv`), the Nav action (``Box(-1, 1, (2,))``, normalised wheel speeds)
and the Nav reward for its own goal. The robots are obstacles to one another: their discs block
each other's sensor rays and rapier resolves their contacts::

    from khepera_gym.pettingzoo import multinav_v3

    env = multinav_v3.parallel_env(n_robots=4)
    observations, infos = env.reset(seed=0)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)

A robot that reaches its goal (within ``task.goal_radius``) is terminated as an agent and leaves
``env.agents``; it parks on its goal (zero wheel commands), still an obstacle for the others.
The episode terminates when every robot has arrived and is truncated after ``max_cycles`` steps
(the scenario's ``task.max_steps``, 600): the remaining agents are then truncated. An agent
leaves with its own ``"episode_stats"`` ("success": its robot arrived); at the episode's end the
remaining ones' infos also hold the world's ``"world_episode_stats"`` ("success": every robot
arrived). ``state()`` is the joint observation. The scenario is configs/multinav.toml: Nav's
keys with Avoid's defaults for
``spawn.min_goal_distance`` (1 m), ``task.max_steps`` (600) and ``task.collision_penalty`` (0.5),
plus ``[multinav] n_robots`` (4, 1 to 10,000 as the arena fits); ``spawn.start`` then lists N poses
``[x, y, heading, ...]`` and ``spawn.goal`` N points ``[x, y, ...]``.

``env(**kwargs)`` is the AEC version (``parallel_to_aec`` with its order-enforcing wrapper), and
``array_env(num_envs, **kwargs)`` steps ``num_envs`` worlds with every agent's data in one array
(:class:`khepera_gym.pettingzoo.arrays.MultiAgentArrayEnv`, for swarms).
"""

from __future__ import annotations

from typing import Any, ClassVar

from khepera_gym.config import ConfigArg
from khepera_gym.pettingzoo._parallel import KheperaParallelEnv, merge_table_keywords


class MultiNavParallelEnv(KheperaParallelEnv):
    """N robots with their own goals as PettingZoo parallel agents.

    Args:
        n_robots: N, 1..10000 (as many as the arena fits; a swarm needs a larger arena, see
            the scene "swarm"); None keeps the scenario's (4 by default).
        config: None, a built-in scenario name or a path to a TOML file.
        max_cycles: Steps before truncation; None keeps the scenario's ``task.max_steps``.
        **kwargs: Further scenario overrides (e.g. ``count=5`` random obstacles), ``action_type``.
    """

    TASK: ClassVar[str] = "multinav"
    FAMILY: ClassVar[str] = "multinav"
    ARRAY_ENV: ClassVar[bool] = True

    def __init__(
        self,
        n_robots: int | None = None,
        config: ConfigArg = None,
        max_cycles: int | None = None,
        **kwargs: Any,
    ) -> None:
        merge_table_keywords(kwargs, "multinav", {"n_robots": n_robots})
        super().__init__(config=config, max_cycles=max_cycles, **kwargs)


__all__ = ["MultiNavParallelEnv"]
