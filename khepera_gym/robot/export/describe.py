"""Any supported model, file or object, to the exporter's
:class:`~khepera_gym.robot.export.network.PolicyNetwork`: the dispatch between the stable-baselines3
and the RLlib extraction (:mod:`~khepera_gym.robot.export.from_sb3`,
:mod:`~khepera_gym.robot.export.from_rllib`), loading a model from a path, and the model's own
deterministic actions that the exported files are checked against.

Neither stable-baselines3 nor ray is imported unless a model of theirs is given.
Threading: none.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym.errors import ConfigError
from khepera_gym.robot.export.from_rllib import (
    RllibActionConfig,
    RllibPolicy,
    describe_rllib_module,
    is_rllib_module,
    load_rllib,
)
from khepera_gym.robot.export.from_sb3 import describe_sb3, is_sb3_model, load_sb3_zip
from khepera_gym.robot.export.network import PolicyNetwork, unsupported_model


def load_model(path: str | Path) -> tuple[Any, Any]:
    """Loads an SB3 ``.zip`` (and ``vecnormalize.pkl`` beside it) or an RLlib checkpoint.

    Returns:
        (model, normalizer or None); for RLlib the model is an
        :class:`~khepera_gym.robot.export.from_rllib.RllibPolicy`.

    Raises:
        ConfigError: The path is neither (the message lists what is supported).
        ImportError: stable-baselines3 or ray is missing (the message names the pip command).
    """
    path = Path(path)
    if path.is_dir():
        return load_rllib(path), None
    if not path.is_file():
        raise ConfigError(f"{path}: no such model file or checkpoint directory")
    if path.suffix != ".zip":
        raise unsupported_model(f"{path} (not an SB3 .zip nor an RLlib checkpoint directory)")
    return load_sb3_zip(path)


def as_policy(model: Any) -> Any:
    """A loaded RLModule wrapped with RLlib's default action handling; anything else as is."""
    return RllibPolicy(model, RllibActionConfig(), None) if is_rllib_module(model) else model


@dataclasses.dataclass
class ReferencePolicy:
    """A model's own deterministic actions, the reference the exported files are checked against.

    Calling it maps observations (N, obs_dim), one row per robot, to actions. A policy with
    memory (``stateful``: one trained on stacked observations, or a recurrent one) keeps one
    stack or LSTM state per row between calls; :meth:`reset` empties them (an episode starts).
    """

    act: Callable[[npt.NDArray[np.float32]], npt.NDArray[Any]]
    reset: Callable[[], None]
    stateful: bool = False

    def __call__(self, observations: npt.NDArray[np.float32]) -> npt.NDArray[Any]:
        return self.act(observations)

    def sequence(
        self, observations: npt.NDArray[np.float32], starts: npt.NDArray[np.bool_]
    ) -> npt.NDArray[np.float64]:
        """The actions of one robot's consecutive observations (N, obs_dim), where ``starts``
        marks each episode's first observation (the memory is emptied there)."""
        if not self.stateful:
            return np.asarray(self.act(observations), np.float64)
        actions = []
        self.reset()
        for row, start in zip(observations, starts, strict=True):
            if start:
                self.reset()
            actions.append(np.asarray(self.act(row[None]), np.float64).reshape(-1))
        self.reset()
        return np.array(actions, np.float64)


def reference_actions(model: Any, normalizer: Any = None) -> ReferencePolicy:
    """The model's own deterministic actions (:class:`ReferencePolicy`) on raw observations: an
    SB3 model applies ``normalizer`` first, a ``FrameStackPolicy`` stacks them, a
    ``RecurrentPPO`` (as :class:`khepera_gym.learning.sb3.RecurrentPolicy`) carries its LSTM
    state."""
    model = as_policy(model)
    if isinstance(model, RllibPolicy):
        return ReferencePolicy(lambda obs: model.predict(obs, deterministic=True), _no_memory)
    if is_sb3_model(model):
        from khepera_gym.learning.sb3 import RecurrentPolicy
        from khepera_gym.learning.sb3.policy import is_recurrent

        if is_recurrent(model):
            model = RecurrentPolicy(model, normalizer)
    if normalizer is not None and not hasattr(model, "normalizer"):
        from khepera_gym.learning.sb3 import NormalizedPolicy

        model = NormalizedPolicy(model, normalizer)
    reset = getattr(model, "reset", None)
    return ReferencePolicy(
        lambda obs: model.predict(obs, deterministic=True)[0],
        reset if callable(reset) else _no_memory,
        stateful=callable(reset),
    )


def _no_memory() -> None:
    """The reset of a policy without memory."""


def describe_policy(model: Any, normalizer: Any = None) -> PolicyNetwork:
    """The :class:`PolicyNetwork` of a supported model.

    Args:
        model: A stable-baselines3 model, :func:`khepera_gym.learning.sb3.load_policy`'s result, a
        path to
            an SB3 ``.zip`` (with its ``vecnormalize.pkl`` if one lies next to it) or to an RLlib
            checkpoint directory, or a loaded RLlib RLModule.
        normalizer: The ``VecNormalize`` the SB3 model was trained under, if not given otherwise.

    Raises:
        ConfigError: The model is of an unsupported kind (the message lists the supported ones)
            or has layers the writers do not implement.
        ImportError: The model's library is not installed (the message names the pip command).
    """
    if isinstance(model, (str, Path)):
        model, loaded_normalizer = load_model(model)
        normalizer = normalizer if normalizer is not None else loaded_normalizer
    model = as_policy(model)
    if isinstance(model, RllibPolicy):
        return describe_rllib_module(model.module, model.action_config)
    if is_sb3_model(model):
        return describe_sb3(model, normalizer)
    raise unsupported_model(f"a {type(model).__module__}.{type(model).__qualname__}")


__all__ = [
    "ReferencePolicy",
    "as_policy",
    "describe_policy",
    "load_model",
    "reference_actions",
]
