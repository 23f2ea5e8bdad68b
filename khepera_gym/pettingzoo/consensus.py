"""The ``consensus_vN`` modules (one a behaviour version, the same env on that version's
dynamics): Khepera IV robots on a communication graph reaching a rendezvous or a
formation from what their neighbours broadcast, one PettingZoo agent per robot. The manual is
:class:`ConsensusParallelEnv`'s docstring. Units are SI (m, s, rad); robot frame x forward,
y left::

    from khepera_gym.pettingzoo import consensus_v3

    env = consensus_v3.parallel_env(n_robots=6, graph="ring", trigger="event")
"""

from __future__ import annotations

from typing import Any, ClassVar

from khepera_gym.config import ConfigArg
from khepera_gym.pettingzoo._parallel import (
    KheperaParallelEnv,
    merge_table_keywords,
)


class ConsensusParallelEnv(KheperaParallelEnv):
    r"""N robots agree on a meeting point or a formation using only their neighbours' messages.

    ## Description

    The KH4VREP paper's future work (§6): multi-agent consensus with event-based communication
    (docs/task-design.md §8). N robots start at random in the 2 m × 2 m walled
    arena. Robot i has an offset c_i: 0 for `consensus.objective = "rendezvous"`, the vertex i
    of a regular polygon of radius `consensus.formation_radius` (0.3 m) for `"formation"` (the
    default). They agree when the displacements z_i = x_i − c_i are equal (a displacement-based
    formation, Ren & Beard 2008): the formation's place and size are fixed, not where it
    settles. Nobody observes another robot's position except through messages.

    **Messages.** A broadcast carries the sender's position estimate x̂_i (its believed position:
    odometry with `task.localization = "odometry"`, else the true one) and goes to its
    neighbours in the graph at that moment. A robot broadcasts when its trigger fires:

    * `consensus.trigger = "periodic"`: every `consensus.period` s (0.05 s, every step);
    * `"event"`: when its estimate is more than `consensus.threshold` (0.01 m) from its last
      broadcast (Dimarogonas, Frazzoli & Johansson, IEEE TAC 57(5), 2012).

    Every robot broadcasts at reset. Each receiver loses a message with probability
    `consensus.drop` (0; drawn per receiver from the world's seed, so `reset(seed=s)` reproduces
    every loss) and gets it `consensus.delay_steps` control steps later (0). A receiver keeps
    each neighbour's last message. The trigger is the robots' radio firmware, a scenario key:
    the action stays the two wheel numbers of every task.

    **Graphs** (`consensus.graph`): `"ring"` (i with i ± 1 mod N, the default), `"line"`,
    `"complete"`, `"geometric"` (robots within `consensus.range` = 1.0 m of each other, by their
    true distance, at every step: the graph changes as they move) or `"edges"` (the undirected
    pairs listed in `consensus.edges`, e.g. `[[0, 1], [2, 3]]`, which is disconnected).

    ## Agents

    `robot_0` .. `robot_{N-1}` (`consensus.n_robots` = 4, 2 to 32), agent k driving robot k.
    Every agent has the same spaces.

    ## Action Space

    `Box(-1, 1, (2,), float32)` per agent: normalised (left, right) wheel speeds,
    1 = 0.813 m/s; `action_type="unicycle"` makes them a normalised (v, ω).

    ## Observation Space

    Per agent `Box(low, high, (17 + 4(N − 1),), float32)` (29 values for 4 robots), in the robot
    frame from the pose the robot believes it has; `env.agent_obs_layout(agent)` names the
    slices:

    | Index    | Name         | Observation                                           | Min  | Max |
    |----------|--------------|-------------------------------------------------------|------|-----|
    | 0-7      | ir           | IR proximity, K-Team order back-left ... back         | 0    | 1   |
    | 8-12     | us           | ultrasonic left, front-left, front, front-right,      | 0    | 1   |
    |          |              | right                                                 |      |     |
    | 13-…     | neighbours   | per other robot j in index order: p_x, p_y (m), age   | -6.8 | 6.8 |
    |          |              | (s), valid. p = x̂_j − c_j + c_i: where j's last      |      |     |
    |          |              | message says this robot should be; the age since it   |      |     |
    |          |              | was sent, at most 10 s; valid = 1 when j is a         |      |     |
    |          |              | neighbour now and a message of it has arrived, else 4 |      |     |
    |          |              | zeros                                                 |      |     |
    | …        | own_drift    | x̂ at its own last broadcast − x̂ now (m): what the   | -2.8 | 2.8 |
    |          |              | event trigger measures                                |      |     |
    | last two | wheel_speeds | left, right wheel speed / 0.813 m/s                   | -1   | 1   |

    ## Rewards

    Shared (the robots cooperate): per step −`consensus.error_weight` (1) · e, with e the RMS
    disagreement sqrt(mean_i ‖z_i − z̄‖²) of the true displacements (m), minus
    `task.collision_penalty` (0.1) for an agent whose robot ends the step in contact.

    ## Starting State

    Robots at rest at random poses, their centres at least a diameter plus
    `obstacles.spawn_clearance` apart and `spawn.wall_margin` from the walls (the multinav
    spawner), from the world's random stream.

    ## Episode End

    No termination (`consensus.tolerance` only defines convergence); truncation after
    `task.max_steps` = 600 steps (30 s), or `max_cycles`. At the end each agent's info holds its
    own `"episode_stats"` (its return, length, success, path length, contacts) and
    `"world_episode_stats"`: the world's common statistics and `"consensus_error_final"` (m),
    `"consensus_error_rms"` (m, over the episode's steps), `"consensus_converge_time"` (s: when
    e fell below `consensus.tolerance` = 3 cm for good, plus for a rendezvous the floor
    r·sqrt(N / (2 · 0.9069)) of N packed discs, 0.10 m for 4; inf if above it at the end) and
    `"messages_per_robot_s"` (broadcasts per robot per second, the reset's included).

    Measured: :class:`khepera_gym.baselines.ConsensusLaw` on every agent of the default scenario
    (4 robots on a ring, formation, periodic every step), 200 episodes seeded 0..199
    (`khepera-gym compare --task consensus --episodes 200`): see the README's consensus table;
    the event trigger at 1 cm reaches a final error of the same order with about an eighth of
    the messages.

    ## Arguments

    ```python
    >>> from khepera_gym.pettingzoo import consensus_v3
    >>> from khepera_gym.baselines import ConsensusLaw
    >>> env = consensus_v3.parallel_env(n_robots=5, trigger="event", threshold=0.02)
    >>> env.possible_agents
    ['robot_0', 'robot_1', 'robot_2', 'robot_3', 'robot_4']
    >>> policy = ConsensusLaw.for_env(env)
    >>> observations, infos = env.reset(seed=0)
    >>> observations, rewards, terminations, truncations, infos = env.step(policy(observations))

    ```

    `n_robots`, `graph`, `objective`, `trigger`, `period`, `threshold`, `drop` and `delay_steps`
    set the `[consensus]` keys of the same names; `config`, `action_type`, `max_cycles`,
    `render_mode`, `frame_size` and further scenario overrides are those of the other
    PettingZoo envs. `env.poses()` gives the robots' poses (N, 3); `env.targets()` each robot's
    last broadcast position (N, 2). Frames draw the graph's links and each robot's last
    broadcast as a cross of its colour. For every agent's arrays at once (many robots, many
    worlds) use ``MultiAgentArrayEnv("consensus", num_envs)`` of
    :mod:`khepera_gym.pettingzoo.arrays`.

    ## Scenario file

    The keys of :class:`khepera_gym.envs.NavEnv`, with `task.max_steps` = 600 and
    `task.collision_penalty` = 0.1, and a `[consensus]` table: `n_robots` (4), `graph` ("ring"),
    `range` (1.0 m, [E]), `edges` ([]), `objective` ("formation"), `formation_radius` (0.3 m),
    `trigger` ("periodic"), `period` (0.05 s, rounded to whole steps), `threshold` (0.01 m,
    [E]), `drop` (0), `delay_steps` (0), `tolerance` (0.03 m), `error_weight` (1). The resolved
    default file is `khepera_gym.default_config("consensus")` (also
    `configs/consensus.toml`). `khepera_gym.errors.ConfigError` names the key when:
    `n_robots` is outside 2..32 or more than the arena fits (the message says how many);
    `graph` or `trigger` or `objective` is unknown; `graph = "edges"` has no pairs, a pair
    names a robot that does not exist or the same robot twice, or `edges` is given for another
    graph; the formation's neighbours would be closer than a diameter plus
    `obstacles.spawn_clearance` (the message gives the least radius) or the polygon leaves the
    arena; `drop` is outside [0, 1); `delay_steps` is above 100; `period`, `range` or
    `tolerance` is not positive; `threshold` is negative; `spawn.start` or `spawn.goal` is
    given.
    """

    TASK: ClassVar[str] = "consensus"
    FAMILY: ClassVar[str] = "consensus"
    #: Keyword arguments that set `[consensus]` keys of the same name.
    KEYS: ClassVar[tuple[str, ...]] = (
        "n_robots",
        "graph",
        "objective",
        "trigger",
        "period",
        "threshold",
        "drop",
        "delay_steps",
    )

    def __init__(
        self, config: ConfigArg = None, max_cycles: int | None = None, **kwargs: Any
    ) -> None:
        given = {key: kwargs.pop(key) for key in self.KEYS if key in kwargs}
        merge_table_keywords(kwargs, "consensus", given)
        super().__init__(config=config, max_cycles=max_cycles, **kwargs)


__all__ = ["ConsensusParallelEnv"]
