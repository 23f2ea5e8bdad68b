"""The base of the baselines: a controller of the Rust core applied to observations of any batch
shape, its parameters and signature taken from the core (see :mod:`khepera_gym.baselines`)."""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym import _core
from khepera_gym.errors import ActionError, ConfigError

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
        controller: Its name, one of the core's registry (``registry.controllers()`` lists them:
            ``"position_control"``, ...).

    Returns:
        ``(name, default, comment)`` per parameter, in order; the comment gives units and source.
    """
    return [
        (name, default, comment) for name, default, comment in _core.controller_params(controller)
    ]


def _layout_triples(layout: Layout | None) -> list[tuple[str, int, int]] | None:
    """``(name, start, stop)`` triples of a layout dict or of an env's ``obs_layout()``."""
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


#: Names a policy never reads as one of its parameters.
_CLASS_ATTRIBUTES = ("params", "PARAMETERS", "CONTROLLER", "COMPARABLE")


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
    #: Whether ``khepera-gym compare`` offers it by name on the Gymnasium envs (False for a
    #: controller of a PettingZoo-only task).
    COMPARABLE: ClassVar[bool] = True
    #: The tasks (core task names) whose comparison runs it when no policy is named
    #: (``khepera-gym compare --task seek``): a task's default policies are the baselines that
    #: name it, in the order they are defined, each followed by its named variants
    #: (:data:`khepera_gym.learning.policies.VARIANTS`), then uniform random actions.
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
        if name.startswith("_") or name in _CLASS_ATTRIBUTES:
            raise AttributeError(name)
        values = self.params
        if name in values:
            return values[name]
        raise AttributeError(f"{type(self).__name__!r} has no attribute {name!r}")

    def __call__(self, observation: Observation) -> Any:
        """Normalised wheel actions (float32) for one observation (D,), a batch (N, D) or any
        (..., D), shape (..., A) with A = 2 per robot driven; for a PettingZoo dict
        ``{agent: observation}``, a dict of actions.

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


def with_leds(actions: npt.ArrayLike, color: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Wheel actions made into the actions of a world with ``task.led_action``: after each
    agent's two wheel values, its LEDs' red, green, blue (as normalised actions, ``2 c - 1``).

    The baselines steer the wheels only; this lets one run where the agents also set their LEDs,
    with the LEDs held at ``color``.

    Args:
        actions: Wheel actions, shape (..., 2 K) for K agents (a joint action or a batch of them).
        color: RGB in [0, 1], one for every agent (3,) or one per agent (K, 3).

    Returns:
        Actions of shape (..., 5 K), float32.

    Raises:
        ActionError: ``actions`` is not (..., 2 K), or ``color`` is not (3,) or (K, 3) in [0, 1].
    """
    wheels = np.asarray(actions, dtype=np.float32)
    if wheels.ndim == 0 or wheels.shape[-1] % 2:
        raise ActionError(f"actions must have shape (..., 2 K), got {wheels.shape}")
    agents = wheels.shape[-1] // 2
    rgb = np.asarray(color, dtype=np.float32)
    if rgb.shape not in ((3,), (agents, 3)) or not np.all((rgb >= 0.0) & (rgb <= 1.0)):
        raise ActionError(
            f"color must be RGB in [0, 1] of shape (3,) or ({agents}, 3), got {color!r}"
        )
    per_agent = wheels.reshape(*wheels.shape[:-1], agents, 2)
    leds = np.broadcast_to(2.0 * rgb - 1.0, (*per_agent.shape[:-1], 3))
    return np.concatenate([per_agent, leds], axis=-1).reshape(*wheels.shape[:-1], 5 * agents)


__all__ = [
    "BRAITENBERG_WEIGHT_SETS",
    "FORMATION_SHAPES",
    "KHEPERA_AXLE_LENGTH",
    "KHEPERA_MAX_WHEEL_SPEED",
    "BaselinePolicy",
    "Layout",
    "Observation",
    "parameters",
    "with_leds",
]
