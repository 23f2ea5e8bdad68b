"""The KH4VREP paper's classical controllers as baseline policies on observations.

Farias et al., "A Khepera IV library for robotic control education using V-REP" (IFAC 2017),
§3.3-3.5: :class:`PositionControl` (eqs. 1-4), :class:`Braitenberg` avoidance after it (eqs. 5-7,
Fig. 5), :class:`VFH` (eqs. 8-11) and :class:`LeaderFollower` formation control (eq. 12). Each is
a drop-in policy for the environments created with ``action_type="wheels"``::

    from khepera_gym.baselines import Braitenberg

    policy = Braitenberg(weights="kteam")
    action = policy(obs)                          # one (18,) observation or a batch (N, 18)
    action, state = policy.predict(obs)           # stable-baselines3's signature

All the maths lives in the Rust core (src/controllers/, the code the scripted formation leader
runs inside the simulator), and so do the controllers' parameters: their names (as in the
papers), defaults, units and checks are declared once in Rust, and each class here takes them as
keywords (see ``help(Braitenberg)`` or ``inspect.signature``; :func:`parameters` lists them).
A policy reads the observation of its task's default scenario; for another (other sensors
observed), give ``layout=env.unwrapped.obs_layout()`` and it finds its blocks by name. Units:
metres, seconds, radians; robot frame x forward, y left, angles counter-clockwise. Actions are
normalised (left, right) wheel speeds in [-1, 1]: wheel speeds ``v ∓ ω · axle_length / 2``
divided by ``max_wheel_speed`` and clipped.

Adding a controller: a Rust file in src/controllers/ and a short class here that names it
(``CONTROLLER = "..."``) and says in its docstring what it does.

Threading and copies: a call copies the observations into Rust, releases the GIL while acting
and returns a fresh float32 array. Policies are immutable and hold no state between calls, so one
instance may serve several environments (``predict`` returns ``state`` unchanged).
"""

from __future__ import annotations

import inspect
import math
import numbers
import re
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym import _core
from khepera_gym.errors import ActionError, ConfigError

try:  # Python >= 3.11; without it LeaderFollower.for_env follows the observation's targets.
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    tomllib = None  # type: ignore[assignment]

#: Distance between the wheels of the Khepera IV (m), the Rust core's ``robot::AXLE_LENGTH``.
KHEPERA_AXLE_LENGTH = float(_core.AXLE_LENGTH)
#: Largest wheel speed of the Khepera IV (m/s): a normalised wheel action of 1 stands for it.
KHEPERA_MAX_WHEEL_SPEED = float(_core.MAX_WHEEL_SPEED)
#: Formation shapes of :class:`LeaderFollower` (as ``formation.shape`` of a scenario).
FORMATION_SHAPES = ("cross", "line", "wedge", "circle")
#: Names of the built-in Braitenberg weight matrices (``_core.braitenberg_weights``).
BRAITENBERG_WEIGHT_SETS = ("default", "kteam")

Observation = npt.ArrayLike | Mapping[str, npt.ArrayLike]
#: An observation layout: ``env.unwrapped.obs_layout()`` (name → slice) or an env with one.
Layout = Mapping[str, slice] | Any


def parameters(controller: str) -> list[tuple[str, Any, str]]:
    """The parameters of a controller of the Rust core, as declared there.

    Args:
        controller: Its name: ``"position_control"``, ``"braitenberg"``, ``"vfh"`` or
            ``"leader_follower"`` (``_core.controllers()`` lists them).

    Returns:
        ``(name, default, comment)`` per parameter, in order; the comment gives units and source.
    """
    return [
        (name, default, comment) for name, default, comment in _core.controller_params(controller)
    ]


def _layout_triples(layout: Layout | None) -> list[tuple[str, int, int]] | None:
    """``(name, start, stop)`` triples of a layout dict, an env's ``obs_layout()``, or None."""
    if layout is None:
        return None
    if not isinstance(layout, Mapping):
        unwrapped = getattr(layout, "unwrapped", layout)
        if not hasattr(unwrapped, "obs_layout"):
            raise ConfigError(
                f"layout must be an env's obs_layout() (name -> slice) or an env, got "
                f"{type(layout).__name__}"
            )
        layout = unwrapped.obs_layout()
    triples = []
    for name, block in layout.items():
        if not isinstance(block, slice):
            raise ConfigError(f"layout[{name!r}] must be a slice, got {block!r}")
        triples.append((str(name), int(block.start), int(block.stop)))
    return triples


class BaselinePolicy:
    """Base of the baselines: a ``_core.Policy`` applied to observations of any batch shape.

    A subclass names its controller in :attr:`CONTROLLER`; its keyword parameters, their defaults
    and its signature come from the Rust core. ``__call__`` takes one observation (D,), a batch
    (N, D) or any (..., D), or a PettingZoo dict ``{agent: observation}``.

    Args:
        *args, **params: The controller's parameters (positionally in their declared order, or
            by name); the rest keep their defaults.
        layout: The layout of the observations it will read (``env.unwrapped.obs_layout()`` or
            the env itself); None for its task's default observation.

    Raises:
        ConfigError: An unknown parameter, a value of the wrong type or an impossible one, or a
            layout that lacks a block the controller reads (the message names it).
    """

    #: The controller's name in the Rust core.
    CONTROLLER: ClassVar[str] = ""
    #: Its parameters: (name, default, comment), from the Rust core.
    PARAMETERS: ClassVar[list[tuple[str, Any, str]]] = []
    _policy: _core.Policy

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if not cls.CONTROLLER or "PARAMETERS" in cls.__dict__:
            return
        cls.PARAMETERS = parameters(cls.CONTROLLER)
        if "__init__" not in cls.__dict__:
            cls.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
                [
                    inspect.Parameter(
                        name, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=default
                    )
                    for name, default, _ in cls.PARAMETERS
                ]
                + [inspect.Parameter("layout", inspect.Parameter.KEYWORD_ONLY, default=None)]
            )
        lines = [
            f"    {name}: {comment} (default {default!r})."
            for name, default, comment in cls.PARAMETERS
        ]
        cls.__doc__ = (cls.__doc__ or "").rstrip() + (
            f"\n\n    Parameters of the Rust controller ``{cls.CONTROLLER}``:\n\n"
            + "\n".join(lines)
            + "\n"
        )

    def __init__(self, *args: Any, layout: Layout | None = None, **params: Any) -> None:
        names = [name for name, _, _ in self.PARAMETERS]
        if len(args) > len(names):
            raise ConfigError(
                f"{type(self).__name__} takes at most {len(names)} positional parameters "
                f"({', '.join(names)}), got {len(args)}"
            )
        for name, value in zip(names, args, strict=False):
            if name in params:
                raise ConfigError(f"{type(self).__name__}: {name} given twice")
            params[name] = value
        self._given = dict(params)
        self._policy = _core.Policy(self.CONTROLLER, params, _layout_triples(layout))

    @classmethod
    def for_env(cls, env: Any, **params: Any) -> BaselinePolicy:
        """The policy reading the observations of ``env`` (a single, vector or PettingZoo env
        of one agent), found by name in its layout.

        Raises:
            ConfigError: The env's observation lacks a block the controller reads.
        """
        return cls(layout=env, **params)

    @property
    def params(self) -> dict[str, Any]:
        """Every parameter's value: the given ones, the defaults for the others."""
        values = {name: default for name, default, _ in self.PARAMETERS}
        values.update(self._given)
        return values

    def __getattr__(self, name: str) -> Any:
        # Parameters read as attributes (policy.vmax); only called for missing attributes.
        if name.startswith("_") or name in ("params", "PARAMETERS", "CONTROLLER"):
            raise AttributeError(name)
        values = self.params
        if name in values:
            return values[name]
        raise AttributeError(f"{type(self).__name__!r} has no attribute {name!r}")

    def __call__(self, observation: Observation) -> Any:
        """Actions for observations.

        Args:
            observation: One observation of shape (D,), a batch (N, D) (or any (..., D)), or a
                PettingZoo dict ``{agent: observation}``. Converted to float32.

        Returns:
            Normalised wheel actions, float32, of shape (A,), (N, A) or (..., A) with A the
            action length for that observation (2 per robot driven); for a dict, a dict of
            per-agent actions.

        Raises:
            ActionError: The observation is not numeric, has the wrong length for this
                controller, or holds NaN/inf (raised by the Rust core, naming the element).
        """
        if isinstance(observation, Mapping):
            return self._act_dict(observation)
        return self._act(self._policy, observation)

    def predict(
        self,
        observation: Observation,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """stable-baselines3's ``predict``: ``(action, state)``; the controllers are deterministic
        and stateless, so ``state`` is returned unchanged and the other arguments are ignored."""
        return self(observation), state

    @staticmethod
    def _act(policy: _core.Policy, observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
        try:
            # Values beyond float32 become inf, which the Rust core reports by element.
            with np.errstate(over="ignore"):
                array = np.asarray(observation, dtype=np.float32)
        except (TypeError, ValueError) as error:
            raise ActionError(
                f"observation must be a numeric array of shape (D,) or (N, D), got {observation!r}"
            ) from error
        if array.ndim == 0:
            raise ActionError(
                f"observation must have shape (D,) or (N, D), got a scalar {observation!r}"
            )
        # C order: the Rust core reads the rows of a contiguous buffer.
        rows = np.ascontiguousarray(array.reshape(-1, array.shape[-1]))
        actions = policy.act(rows)
        return actions.reshape(*array.shape[:-1], actions.shape[-1])

    def _act_dict(self, observations: Mapping[str, npt.ArrayLike]) -> dict[str, Any]:
        """Per-agent actions; all agents share the policy (stacked into one batch)."""
        agents = list(observations)
        if not agents:
            return {}
        actions = self._act(self._policy, np.stack([np.asarray(observations[a]) for a in agents]))
        return dict(zip(agents, actions, strict=True))

    def __repr__(self) -> str:
        arguments = ", ".join(f"{name}={value!r}" for name, value in self._given.items())
        return f"{type(self).__name__}({arguments})"


class PositionControl(BaselinePolicy):
    r"""Position control (paper §3.3, eqs. 1-4, after Vilella et al. 2004): drive to the goal.

    From the goal distance and bearing of a Nav/Avoid observation (``goal_distance``,
    ``goal_bearing_sin``, ``goal_bearing_cos``):

    * eq. 1: :math:`d = \sqrt{(x_p - x_r)^2 + (y_p - y_r)^2}`, the observed ``goal_distance``;
    * eq. 2: :math:`\alpha - \theta`, the goal bearing in the robot frame;
    * eq. 3: :math:`v = v_{max}` if :math:`d > k_r`, else :math:`d \, v_{max} / k_r`;
    * eq. 4: :math:`\omega = \omega_{max} \sin(\alpha - \theta)`;

    and :math:`v = \omega = 0` once :math:`d` < ``stop_radius`` (the library stops at 0.05 m;
    the task succeeds within 0.05 m, so the default stops closer). Obstacles are ignored.
    """

    CONTROLLER: ClassVar[str] = "position_control"


def braitenberg_weights(
    weights: str | npt.ArrayLike = "default", smax: float = 1.0
) -> npt.NDArray[np.float64]:
    """The 2 × 8 weight matrix W of eq. 5 (m/s per unit proximity), divided by ``smax``.

    Args:
        weights: "default" (tuned on KheperaIV-Avoid), "kteam" (K-Team's
            ``braitenbergAvoidance`` demo converted to m/s) or a 2 × 8 array: row 0 the left
            wheel, row 1 the right; columns the IR sensors in K-Team order (back-left, left,
            front-left, front, front-right, right, back-right, back).
        smax: Full scale of the proximity (see :class:`Braitenberg`), > 0.

    Returns:
        A new float64 array of shape (2, 8).

    Raises:
        ValueError: Unknown name, not a finite 2 × 8 matrix, or ``smax`` not > 0.
    """
    if isinstance(weights, str):
        matrix = np.array(_core.braitenberg_weights(weights), dtype=np.float64)
    else:
        try:
            matrix = np.array(weights, dtype=np.float64)
        except (TypeError, ValueError) as error:
            raise ConfigError(f"weights must be a 2 x 8 numeric matrix, got {weights!r}") from error
        if matrix.shape != (2, 8) or not np.all(np.isfinite(matrix)):
            raise ConfigError(
                "weights must be a finite 2 x 8 matrix (rows left, right wheel; columns the IR "
                f"sensors in K-Team order), got shape {matrix.shape}"
            )
    smax = float(smax)
    if not (math.isfinite(smax) and smax > 0):
        raise ConfigError(f"smax must be a finite number > 0, got {smax}")
    return matrix / smax


class Braitenberg(BaselinePolicy):
    r"""Position control followed by Braitenberg avoidance (paper §3.4, eqs. 5-7, Fig. 5).

    The weight matrix W (eq. 5, 2 × 8) maps the IR ring S (eq. 6) to wheel speeds,
    :math:`v_{L,R} = W (1 - S / S_{max})` (eq. 7). Our IR observation already is that term:
    ``ir`` = :math:`p = 1 - S/S_{max}` in [0, 1] (0 nothing within 25 cm, 1 touching), the
    reading normalised by its full scale :math:`S_{max} = 1`. As in Fig. 5 the block sits after
    the control law: while every :math:`p_i` is below ``threshold`` the wheel speeds of
    :class:`PositionControl` pass unchanged; otherwise :math:`W p / s_{max}` is added to them,
    and :math:`(v', \omega')` follow from the differential drive. Within ``stop_radius`` of the
    goal the robot stops.

    ``smax`` rescales the proximity, :math:`p / s_{max}`: the sensors then count as saturated
    at :math:`p = s_{max}` instead of 1 (``smax`` = 1 is eq. 7 as written). It is implemented
    exactly by dividing the weights by ``smax``; ``threshold`` still applies to :math:`p`.
    ``weights="default"`` reaches about 97% of KheperaIV-Avoid goals; ``"kteam"`` (K-Team's
    ``braitenbergAvoidance`` demo converted to m/s per unit proximity) about 70%.
    """

    CONTROLLER: ClassVar[str] = "braitenberg"

    @property
    def effective_weights(self) -> npt.NDArray[np.float64]:
        """The weights of the Rust block: W / smax (m/s per unit proximity), shape (2, 8)."""
        return braitenberg_weights(self.params["weights"], self.params["smax"])


class VFH(BaselinePolicy):
    r"""Vector Field Histogram obstacle avoidance (paper §3.4, eqs. 8-11, after Ulrich and
    Borenstein 2000).

    A polar histogram of ``sectors`` sectors is rebuilt at every step from the 8 IR proximities
    and the 5 ultrasonic readings: each sensor adds its obstacle magnitude (IR: its proximity;
    ultrasonic: :math:`1 - d / \text{us\_range}` for echoes closer than ``us_range``, a "too
    close" reading counting as an echo at the sensor's 25 cm minimum range, the IR ring covering
    what is nearer) to every sector within ``beam_width / 2`` of its bearing, then the histogram is
    smoothed over neighbouring sectors. Sectors under ``threshold`` are free. Each free valley at
    least ``min_valley`` wide offers one direction: the goal bearing clamped ``min_valley / 2``
    inside its edges; the robot takes the one with the lowest VFH+-style cost (angle to the goal
    + ``heading_weight`` × angle to straight ahead, + ``switch_penalty`` rad for a valley on the
    other side of its current turn, read from its wheel speeds, against flip-flopping). Boxed in,
    it turns in place. Eq. 9 is applied at full rate once the direction is behind the robot. With
    :math:`\theta_e` that heading error and :math:`h'_c` the density in the sector straight ahead:

    * eq. 9: :math:`\omega = \omega_{max} \sin(\theta_e)`;
    * eq. 11: :math:`h'_c = \min(h'_c, h_m)`;
    * eq. 10: :math:`v' = v_{max} (1 - h'_c / h_m)`;
    * eq. 8: :math:`v = v' (1 - |\omega| / \omega_{max})`;

    within ``kr`` of the goal :math:`v` is also capped by eq. 3's docking law, and the robot stops
    within ``stop_radius``. The histogram has no memory, so an obstacle that leaves every beam
    leaves the histogram and the robot turns back toward it: it zigzags, as the paper observed.
    Beams narrower than the sensors' 45° spacing leave blind zones between them (the paper's
    explanation); ``beam_width = math.radians(10)`` shows that at its worst.

    The ultrasonic observation is read as distance / ``us_max_range`` (the scenario's
    ``sensors.us_max_range``, 2 m by default).
    """

    CONTROLLER: ClassVar[str] = "vfh"


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
        blocks by the env's own layout. Without ``tomllib``
        (Python 3.10) it follows the observation's ``target_offset`` (``shape=None``).

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
        if tomllib is None:  # pragma: no cover - Python 3.10
            return cls(shape=None, **kwargs)
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


__all__ = [
    "BRAITENBERG_WEIGHT_SETS",
    "FORMATION_SHAPES",
    "KHEPERA_AXLE_LENGTH",
    "KHEPERA_MAX_WHEEL_SPEED",
    "VFH",
    "BaselinePolicy",
    "Braitenberg",
    "LeaderFollower",
    "PositionControl",
    "braitenberg_weights",
    "formation_offsets",
    "parameters",
]
