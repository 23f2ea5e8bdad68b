"""The robot side of an export: what one robot's observation holds and the scenario's constants
the C code needs (:class:`RobotInterface`), read from the env the policy was trained on.

The observation layout is the env's own (``env.unwrapped``'s agents and their layouts, from the
Rust core), so a scenario that observes fewer sensors (``[sensors] observe = ["ir"]``) gives a
layout without their blocks and the C observation builder follows it. For a policy shared by the
agents of a multi-robot env, the layout is the first agent's block that has the policy's width.

Units: SI (m, m/s, s); wheel commands in K-Team speed units (:data:`MM_S_PER_SPEED_UNIT`).
Threading: none (reads the env in the calling thread).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from khepera_gym.errors import ConfigError, KheperaError

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

#: One ``kh4_set_speed`` unit in mm/s (src/robot.rs, docs/robot.md §1).
MM_S_PER_SPEED_UNIT = 0.678181
#: Largest closed-loop ``kh4_set_speed`` command (about 813 mm/s; docs/robot.md §1, the
#: serial protocol's ``D,l,r`` takes ±1200).
MAX_SPEED_UNITS = 1200
#: Encoder pulses per wheel turn: 128 × 4 (quadrature) × 38:1 (docs/robot.md §1).
PULSES_PER_WHEEL_TURN = 19456
#: Observation blocks the C observation builder computes from the robot's own readings, with
#: their widths (src/sensors/ir.rs, ultrasonic.rs; the body's wheel speeds); with the goal
#: blocks below; any other block is an input passed through unchanged.
MEASURED_BLOCKS = {"ir": 8, "us": 5, "wheel_speeds": 2}
#: Nav's goal blocks, computed from the robot's pose (dead reckoning) and the goal.
GOAL_BLOCKS = ("goal_distance", "goal_bearing_sin", "goal_bearing_cos")


@dataclasses.dataclass(frozen=True)
class RobotInterface:
    """How one robot's observation is built and its action applied, for one env and scenario.

    ``layout`` is the policy's observation layout (name, start, stop); for a policy shared by
    the agents of a multi-robot env it is one agent's block, with the agent prefix removed.
    Scenario values given as ranges (domain randomisation) are replaced by their midpoint and
    listed in ``randomised``.
    """

    env_id: str
    task: str
    #: The agent whose block the layout is ("follower_0"), or None for a single-robot env.
    agent: str | None
    #: The robot that agent drives (0 in a single-robot env; a formation's leader is robot 0).
    robot_index: int
    #: Where the agent's block starts in the env's joint observation.
    offset: int
    layout: tuple[tuple[str, int, int], ...]
    action_type: str
    #: Whether the policy's last three values set the top LEDs (``task.led_action``).
    led_action: bool
    ir_floor_value: float
    us_max_range: float
    us_enabled: tuple[bool, ...]
    max_wheel_speed: float
    min_wheel_speed: float
    axle_length: float
    wheel_radius: float
    #: The arena's diagonal (m), computed in float32 as the simulator does.
    arena_diagonal: float
    goal_radius: float
    control_period: float
    scenario_toml: str
    randomised: Mapping[str, tuple[float, float]]

    @property
    def obs_dim(self) -> int:
        """Length of the policy's observation."""
        return self.layout[-1][2]

    def observes(self, block: str) -> bool:
        """Whether the observation has a block of this name ("ir", "us", ...)."""
        return any(name == block for name, _, _ in self.layout)

    @property
    def has_goal(self) -> bool:
        """Whether the observation has Nav's goal blocks."""
        return any(name in GOAL_BLOCKS for name, _, _ in self.layout)

    @property
    def extra_blocks(self) -> list[tuple[str, int, int]]:
        """Blocks the robot cannot compute itself (passed in unchanged)."""
        known = set(MEASURED_BLOCKS) | set(GOAL_BLOCKS)
        return [block for block in self.layout if block[0] not in known]


def toml_loads(text: str) -> dict[str, Any]:
    """TOML text as a dict (tomllib; tomli before Python 3.11, a dependency there)."""
    return tomllib.loads(text)


def _policy_block(
    env: gym.Env[Any, Any], obs_dim: int, env_id: str
) -> tuple[str | None, int, int, tuple[tuple[str, int, int], ...]]:
    """(agent or None, robot index, offset, layout) of the block a policy of ``obs_dim`` reads.

    Raises:
        ConfigError: No agent's block has ``obs_dim`` values.
    """
    batch = env.unwrapped._batch
    agents = batch.agents()  # (name, robot index, start, stop, own layout), in joint order
    if len(agents) == 1:
        _, robot, start, stop, own = agents[0]
        if stop - start != obs_dim:
            raise ConfigError(
                f"the policy takes {obs_dim} observation values but {env_id} gives "
                f"{stop - start}: pass the env (and scenario) it was trained on"
            )
        return None, int(robot), int(start), tuple((n, int(s), int(e)) for n, s, e in own)
    fitting = [agent for agent in agents if agent[3] - agent[2] == obs_dim]
    if not fitting:
        widths = " or ".join(
            str(w) for w in sorted({stop - start for _, _, start, stop, _ in agents})
        )
        joint = (
            " (the joint observation of several robots: export a policy shared by the robots, "
            "trained on one robot's block)"
            if obs_dim == batch.obs_dim
            else ""
        )
        raise ConfigError(
            f"the policy takes {obs_dim} observation values; {env_id}'s agents have {widths} "
            f"each{joint}"
        )
    name, robot, start, _, own = fitting[0]
    return name, int(robot), int(start), tuple((n, int(s), int(e)) for n, s, e in own)


def robot_interface(env: gym.Env[Any, Any], obs_dim: int, env_id: str) -> RobotInterface:
    """The :class:`RobotInterface` of a khepera_gym env for a policy taking ``obs_dim`` values.

    Args:
        env: A single env of khepera_gym (``gym.make``), made with the scenario of training.
        obs_dim: The policy's observation length.
        env_id: Its id, for messages and the generated files.

    Raises:
        ConfigError: The policy's observation matches neither the env's nor one agent's block,
            or it is the joint observation of several robots.
    """
    unwrapped = env.unwrapped
    agent, robot_index, offset, layout = _policy_block(env, obs_dim, env_id)
    for name, start, stop in layout:
        width = MEASURED_BLOCKS.get(name)
        if width is not None and stop - start != width:
            raise KheperaError(
                f"the {name} block has {stop - start} values; the C code reads {width}"
            )
    scenario_toml = unwrapped.config_toml()
    scenario = toml_loads(scenario_toml)
    randomised: dict[str, tuple[float, float]] = {}

    def value(section: str, key: str) -> float:
        raw = scenario[section][key]
        if isinstance(raw, list):
            low, high = float(raw[0]), float(raw[1])
            if high > low:
                randomised[f"{section}.{key}"] = (low, high)
            return 0.5 * (low + high)
        return float(raw)

    width = np.float32(scenario["arena"]["width"])
    height = np.float32(scenario["arena"]["height"])
    return RobotInterface(
        env_id=env_id,
        task=str(unwrapped._batch.task),
        agent=agent,
        robot_index=robot_index,
        offset=offset,
        layout=layout,
        action_type=str(getattr(unwrapped, "action_type", "wheels")),
        led_action=bool(scenario["task"].get("led_action", False)),
        ir_floor_value=value("sensors", "ir_floor_value"),
        us_max_range=value("sensors", "us_max_range"),
        us_enabled=tuple(bool(on) for on in scenario["sensors"]["us_enabled"]),
        max_wheel_speed=value("robot", "max_wheel_speed"),
        min_wheel_speed=value("robot", "min_wheel_speed"),
        axle_length=value("robot", "axle_length"),
        wheel_radius=value("robot", "wheel_radius"),
        arena_diagonal=float(np.sqrt(width * width + height * height)),
        goal_radius=value("task", "goal_radius"),
        control_period=value("physics", "dt"),
        scenario_toml=scenario_toml,
        randomised=randomised,
    )


__all__ = [
    "GOAL_BLOCKS",
    "MAX_SPEED_UNITS",
    "MEASURED_BLOCKS",
    "MM_S_PER_SPEED_UNIT",
    "PULSES_PER_WHEEL_TURN",
    "RobotInterface",
    "robot_interface",
    "toml_loads",
]
