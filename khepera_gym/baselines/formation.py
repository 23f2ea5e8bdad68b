"""The formation baseline of the paper: leader-follower control (eq. 12) of every follower block
of an observation, with the formation shapes of the scenarios."""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy.typing as npt

from khepera_gym import _core
from khepera_gym.baselines.base import FORMATION_SHAPES, BaselinePolicy, Layout, _layout_triples
from khepera_gym.baselines.navigation import Braitenberg, PositionControl
from khepera_gym.errors import ActionError, ConfigError

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib


def formation_offsets(shape: str, r: float, n_followers: int) -> list[tuple[float, float]]:
    """The followers' (r, β) offsets of a formation shape, as the scenarios' ``formation.shape``.

    Computed by the Rust core's formation task (the same float32 numbers as the scenarios):
    "cross" puts follower i at β = (i mod 4) · 90° (ahead, left, behind, right), the next four one
    ``r`` further out; "line" at ±90° (left, right alternately); "wedge" at ±135°; "circle" evenly
    round the leader at ``r``; along a line or wedge further followers go ``r`` further out.

    Args:
        shape: "cross", "line", "wedge" or "circle".
        r: Distance of the nearest followers to the leader (m).
        n_followers: Number of followers K >= 1.

    Returns:
        K pairs (r_i, β_i): metres, radians counter-clockwise from the leader's heading.

    Raises:
        ValueError: Unknown shape, K < 1 or r not > 0.
    """
    if shape not in FORMATION_SHAPES:
        raise ConfigError(f"unknown formation shape {shape!r}; known: {FORMATION_SHAPES}")
    if isinstance(n_followers, bool) or int(n_followers) != n_followers or n_followers < 1:
        raise ConfigError(f"n_followers must be an integer >= 1, got {n_followers!r}")
    r = float(r)
    if not (math.isfinite(r) and r > 0):
        raise ConfigError(f"r must be a finite number > 0, got {r}")
    return [(float(a), float(b)) for a, b in _core.formation_offsets(shape, r, int(n_followers))]


#: Agent names of a PettingZoo formation follower: "follower_<k>".
_FOLLOWER_AGENT = re.compile(r"follower_(\d+)")


class LeaderFollower(BaselinePolicy):
    r"""Leader-follower formation control (paper §3.5, eq. 12) for every follower of a Formation
    observation (and the leader's Nav block when the leader is an agent).

    Follower k holds the offset :math:`(r_k, \beta_k)` from the leader's pose (eq. 12):

    .. math::
        x_p = x_L + r \cos(\beta + \theta_L), \qquad y_p = y_L + r \sin(\beta + \theta_L),

    computed in the follower's own frame from its ``leader_offset`` and ``leader_heading``
    observations. It drives to that point with position control (eqs. 1-4, its own ``vmax``,
    ``wmax``, ``kr``, ``stop_radius``), plus with ``feedforward`` the leader's forward speed
    projected on its heading (:math:`v_L \cos(\theta_L - \theta) \max(0, \cos \alpha)`) so it
    does not trail a moving target, then with ``avoidance`` the Braitenberg block (eqs. 5-7).
    ``shape=None`` uses the observation's own ``target_offset`` (eq. 12 as the scenario
    defines it) instead of offsets of its own: it fits any formation and any number of
    followers, and a single follower block (PettingZoo).

    Args:
        shape: "cross" (the paper's Fig. 7), "line", "wedge", "circle" (offsets as the
            scenarios' ``formation.shape``, see :func:`formation_offsets`), or None to follow
            the observation's ``target_offset``. Ignored when ``beta`` is given.
        r: Distance of the nearest followers to the leader (m); with ``beta`` a float or one
            distance per angle.
        beta: Explicit angles :math:`\beta_k` (radians, counter-clockwise from the leader's
            heading), one per follower.
        n_followers: Number of followers K for a ``shape``; None: 4 (or ``len(beta)``).
        avoidance: True for the default :class:`Braitenberg` block, False for none, or a
            :class:`Braitenberg` whose weights, ``smax`` and threshold are used.
        leader: Policy of the leader's Nav block when the leader is an agent
            (:class:`PositionControl`, :class:`Braitenberg` or :class:`VFH`); None for
            ``PositionControl()``.
        layout: The layout of one follower's block (an env's agent layout); None: the default
            Formation scenario's.
        **params: The Rust controller's other parameters (``vmax``, ``wmax``, ``kr``,
            ``stop_radius``, ``feedforward``, ``axle_length``, ``max_wheel_speed``; listed
            below with their defaults).

    Raises:
        ValueError: Unknown shape, inconsistent ``beta``/``r``/``n_followers``, or a bad
            parameter. Acting on an observation with another number of followers than the
            offsets raises ActionError.
    """

    CONTROLLER: ClassVar[str] = "leader_follower"
    #: Parameters that the arguments above set (not passed through ``**params``).
    _DERIVED = ("offsets", "avoidance", "weights", "smax", "threshold")

    def __init__(
        self,
        shape: str | None = "cross",
        r: float | Sequence[float] = 0.5,
        beta: Sequence[float] | None = None,
        n_followers: int | None = None,
        avoidance: bool | Braitenberg = True,
        leader: BaselinePolicy | None = None,
        *,
        layout: Layout | None = None,
        **params: Any,
    ) -> None:
        derived = sorted(set(params) & set(self._DERIVED))
        if derived:
            raise ConfigError(
                f"LeaderFollower sets {derived} from shape/r/beta/avoidance; give those instead"
            )
        self.offsets = _leader_follower_offsets(shape, r, beta, n_followers)
        self.shape = None if beta is not None else shape
        if leader is None:
            leader = PositionControl()
        if not isinstance(leader, BaselinePolicy):
            raise ConfigError(
                "leader must be a PositionControl, Braitenberg or VFH policy, got "
                f"{type(leader).__name__}"
            )
        self.leader = leader
        if avoidance is True:
            avoidance = Braitenberg()
        elif avoidance is False or avoidance is None:
            avoidance = None
        elif not isinstance(avoidance, Braitenberg):
            raise ConfigError(
                f"avoidance must be True, False or a Braitenberg policy, got {avoidance!r}"
            )
        self.avoidance = avoidance
        self._layout = _layout_triples(layout)
        self._given = dict(params)
        self._policy = self._make_policy(self.offsets)
        # Single-follower policies for PettingZoo dicts (agent "follower_k" gets offset k).
        self._follower_policies = (
            None if self.offsets is None else [self._make_policy([o]) for o in self.offsets]
        )

    def _make_policy(self, offsets: list[tuple[float, float]] | None) -> _core.Policy:
        params: dict[str, Any] = dict(self._given)
        params["offsets"] = [] if offsets is None else [list(o) for o in offsets]
        params["avoidance"] = self.avoidance is not None
        if self.avoidance is not None:
            for name in ("weights", "smax", "threshold"):
                params[name] = self.avoidance.params[name]
        return _core.Policy(self.CONTROLLER, params, self._layout, self.leader._policy)

    @property
    def params(self) -> dict[str, Any]:
        """Every parameter of the Rust controller: given, set from the arguments, or default."""
        values = super().params
        values["offsets"] = [] if self.offsets is None else [list(o) for o in self.offsets]
        values["avoidance"] = self.avoidance is not None
        return values

    @classmethod
    def for_env(cls, env: Any, **kwargs: Any) -> LeaderFollower:  # type: ignore[override]
        """A LeaderFollower with the formation of an environment's scenario.

        Reads ``formation.shape``, ``n_followers``, ``spacing`` and ``offsets`` from
        ``env.unwrapped.config_toml()`` (a single, vector or PettingZoo Formation env), so the
        followers compute the same eq. 12 targets as the environment, and reads its followers'
        blocks by the env's own layout.

        Args:
            env: The environment.
            **kwargs: Further arguments of :class:`LeaderFollower` (``vmax``, ``leader``, ...).

        Raises:
            ValueError: The environment has no ``[formation]`` table.
        """
        unwrapped = getattr(env, "unwrapped", env)
        config_toml = unwrapped.config_toml()
        followers = [a for a in unwrapped.agent_layouts() if a.startswith("follower_")]
        if followers and "layout" not in kwargs:
            kwargs["layout"] = unwrapped.agent_layouts()[followers[0]]
        formation = tomllib.loads(config_toml).get("formation")
        if formation is None:
            raise ConfigError("the environment's scenario has no [formation] table")
        if formation["shape"] == "custom":
            r = [float(o[0]) for o in formation["offsets"]]
            beta = [float(o[1]) for o in formation["offsets"]]
            return cls(r=r, beta=beta, **kwargs)
        return cls(
            shape=formation["shape"],
            r=float(formation["spacing"]),
            n_followers=int(formation["n_followers"]),
            **kwargs,
        )

    def _act_dict(self, observations: Mapping[str, npt.ArrayLike]) -> dict[str, Any]:
        """Per-agent actions: "leader" by the leader policy, "follower_k" with offset k."""
        actions: dict[str, Any] = {}
        for agent, observation in observations.items():
            if agent == "leader":
                actions[agent] = self.leader(observation)
                continue
            policy = self._policy
            if self._follower_policies is not None:
                match = _FOLLOWER_AGENT.fullmatch(agent)
                if match is None or int(match.group(1)) >= len(self._follower_policies):
                    raise ActionError(
                        f"agent {agent!r} is not one of follower_0..follower_"
                        f"{len(self._follower_policies) - 1} of this policy's offsets"
                    )
                policy = self._follower_policies[int(match.group(1))]
            actions[agent] = self._act(policy, observation)
        return actions

    def __repr__(self) -> str:
        arguments = {
            "offsets": self.offsets,
            "avoidance": self.avoidance,
            "leader": self.leader,
            **self._given,
        }
        return f"LeaderFollower({', '.join(f'{k}={v!r}' for k, v in arguments.items())})"


def _leader_follower_offsets(
    shape: str | None,
    r: float | Sequence[float],
    beta: Sequence[float] | None,
    n_followers: int | None,
) -> list[tuple[float, float]] | None:
    """(r, β) per follower from LeaderFollower's arguments; None to follow the observation."""
    if beta is None:
        if shape is None:
            if n_followers is not None:
                raise ConfigError(
                    "n_followers needs a shape (or beta); shape=None follows the "
                    "observation's targets, whatever their number"
                )
            return None
        if not isinstance(r, numbers.Real):
            raise ConfigError(f"r must be one distance (m) for shape {shape!r}, got {r!r}")
        return formation_offsets(shape, r, 4 if n_followers is None else n_followers)
    angles = [float(b) for b in beta]
    if not angles:
        raise ConfigError("beta must list at least one angle")
    if n_followers is not None and n_followers != len(angles):
        raise ConfigError(f"n_followers={n_followers} but beta has {len(angles)} angles")
    distances = [float(r)] * len(angles) if isinstance(r, numbers.Real) else [float(x) for x in r]
    if len(distances) != len(angles):
        raise ConfigError(f"r has {len(distances)} distances for {len(angles)} angles in beta")
    for distance, angle in zip(distances, angles, strict=True):
        if not (math.isfinite(distance) and distance > 0):
            raise ConfigError(f"r must be a finite number > 0, got {distance}")
        if not math.isfinite(angle):
            raise ConfigError(f"beta must be finite angles (rad), got {angle}")
    return list(zip(distances, angles, strict=True))


__all__ = ["LeaderFollower", "formation_offsets"]
