"""Torch modules to the exporter's dense layers, shared by the SB3 and RLlib extractions.

:func:`dense_layers` walks ``nn.Linear`` layers and activation modules in forward order
(flattening ``nn.Sequential``) and gives dense layers
(:class:`~khepera_gym.robot.export.network.DenseLayer`) with float32 copies of the weights;
:func:`check_spaces` accepts only flat continuous Box spaces. torch is imported when called (it
comes with stable-baselines3 or ray). Threading: none.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

import gymnasium as gym
import numpy as np

from khepera_gym.errors import ConfigError
from khepera_gym.robot.export.network import ACTIVATIONS, DenseLayer, unsupported_model


def _activation_of(module: Any) -> tuple[str, float] | None:
    """(name, alpha) of a torch activation module, ("", 0) for a no-op, None if unknown."""
    from torch import nn

    if isinstance(module, (nn.Identity, nn.Flatten)):
        return ("", 0.0)
    if isinstance(module, nn.Tanh):
        return ("tanh", 0.0)
    if isinstance(module, nn.ReLU):
        return ("relu", 0.0)
    if isinstance(module, nn.ELU):
        return ("elu", float(module.alpha))
    if isinstance(module, nn.LeakyReLU):
        return ("leaky_relu", float(module.negative_slope))
    if isinstance(module, nn.SiLU):
        return ("silu", 0.0)
    return None


def dense_layers(modules: Iterable[Any], where: str) -> list[DenseLayer]:
    """Linear layers and activations, in forward order, as dense layers.

    Args:
        modules: Torch modules in forward order (``nn.Sequential`` ones are flattened).
        where: What they belong to, for error messages ("the stable-baselines3 PPO policy").

    Raises:
        ConfigError: A module is neither a Linear layer nor a supported activation, or an
            activation does not follow a Linear layer.
    """
    from torch import nn

    layers: list[DenseLayer] = []
    for module in modules:
        if isinstance(module, nn.Sequential):
            layers.extend(dense_layers(module, where))
            continue
        if isinstance(module, nn.Linear):
            weight = module.weight.detach().cpu().numpy().astype(np.float32)
            if module.bias is not None:
                bias = module.bias.detach().cpu().numpy().astype(np.float32)
            else:
                bias = np.zeros(weight.shape[0], np.float32)
            layers.append(DenseLayer(weight, bias))
            continue
        activation = _activation_of(module)
        if activation is None:
            raise ConfigError(
                f"cannot export the {type(module).__name__} layer of {where}: the exporters "
                f"implement Linear layers with {', '.join(ACTIVATIONS[1:])} activations"
            )
        name, alpha = activation
        if not name:
            continue
        if not layers or layers[-1].activation != "identity":
            raise ConfigError(f"cannot export {where}: {name} does not follow a Linear layer")
        layers[-1] = dataclasses.replace(layers[-1], activation=name, alpha=alpha)
    return layers


def check_spaces(observation_space: Any, action_space: Any, what: str) -> tuple[int, int]:
    """(obs_dim, action_dim) of flat Box spaces.

    Raises:
        ConfigError: Either space is not a one-dimensional Box (the message lists what is
            supported).
    """
    if not isinstance(observation_space, gym.spaces.Box) or len(observation_space.shape) != 1:
        raise unsupported_model(f"{what} with observation space {observation_space}")
    if not isinstance(action_space, gym.spaces.Box) or len(action_space.shape) != 1:
        raise unsupported_model(f"{what} with action space {action_space} (continuous Box needed)")
    return int(observation_space.shape[0]), int(action_space.shape[0])


__all__ = ["check_spaces", "dense_layers"]
