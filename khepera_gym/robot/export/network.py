"""The policy network as the exporter sees it: :class:`PolicyNetwork`, the one description the
ONNX writer and the C writer both work from, so the two compute the same function.

A policy is reduced to the observation normalisation (``VecNormalize`` statistics: mean,
variance, epsilon, clip), the number of observations it acts on (``frame_stack``: its last n,
normalised, oldest first, as SB3's ``VecFrameStack`` outside ``VecNormalize`` feeds them), the
LSTM layers of a recurrent policy (sb3-contrib's ``RecurrentPPO``: a hidden and a cell state
carried from step to step, zeros at an episode's start), a list of dense layers with their
activations, and the transform of the network's output into an action (an affine map and a clip
to the action bounds). Weights are float32 as in torch; the normalisation is float64 as
stable-baselines3 computes it.

This module also says what the exporter supports (:data:`SUPPORTED_MODELS`, the message of
:func:`unsupported_model`) and how to install what it needs (:data:`EXPORT_EXTRA`).
Threading: plain immutable data, no threads.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from khepera_gym.errors import ConfigError, KheperaError

#: What :func:`khepera_gym.robot.export.describe_policy` accepts, for error messages and the manual.
SUPPORTED_MODELS = (
    "stable-baselines3 PPO or A2C with MlpPolicy (a model.zip, the loaded model, or "
    "khepera_gym.learning.sb3.load_policy's result)",
    "sb3-contrib RecurrentPPO with MlpLstmPolicy (its LSTM state carried between steps)",
    "stable-baselines3 SAC or TD3 (DDPG) with MlpPolicy",
    "a Ray RLlib PPO checkpoint directory (new API stack, default torch MLP RLModule) or its "
    "loaded RLModule",
)
#: Install hint for the ONNX writer and checker.
EXPORT_EXTRA = "pip install 'khepera-gym[export]'"
#: Activations the writers implement.
ACTIVATIONS = ("identity", "tanh", "relu", "elu", "leaky_relu", "silu")


def unsupported_model(what: str) -> ConfigError:
    """The error for a model the exporter cannot handle; its message lists what it can."""
    supported = "; ".join(SUPPORTED_MODELS)
    return ConfigError(f"cannot export {what}: supported are {supported}")


@dataclasses.dataclass(frozen=True)
class ObservationNormalization:
    """``VecNormalize``'s observation transform: ``clip((obs - mean) / sqrt(var + epsilon))``.

    Computed in float64 as SB3 does, then rounded to float32.
    """

    mean: npt.NDArray[np.float64]
    variance: npt.NDArray[np.float64]
    epsilon: float
    clip: float

    @property
    def std(self) -> npt.NDArray[np.float64]:
        """``sqrt(variance + epsilon)``, the divisor."""
        return np.sqrt(self.variance + self.epsilon)


@dataclasses.dataclass(frozen=True)
class DenseLayer:
    """``activation(weight @ x + bias)``; ``weight`` has shape (outputs, inputs), float32.

    ``activation`` is "identity", "tanh", "relu", "elu" (``alpha``), "leaky_relu" (slope
    ``alpha``) or "silu".
    """

    weight: npt.NDArray[np.float32]
    bias: npt.NDArray[np.float32]
    activation: str = "identity"
    alpha: float = 0.0

    @property
    def inputs(self) -> int:
        """Input width."""
        return int(self.weight.shape[1])

    @property
    def outputs(self) -> int:
        """Output width."""
        return int(self.weight.shape[0])


@dataclasses.dataclass(frozen=True)
class LstmLayer:
    """One LSTM layer as ``torch.nn.LSTM`` computes it, from input ``x``, hidden state ``h`` and
    cell state ``c`` (H values each) to the next ``h`` and ``c``::

        z = weight_input @ x + bias_input + weight_hidden @ h + bias_hidden   (4 H values)
        i, f, g, o = sigmoid(z[0:H]), sigmoid(z[H:2H]), tanh(z[2H:3H]), sigmoid(z[3H:4H])
        c' = f * c + i * g;  h' = o * tanh(c')

    ``h'`` is also the layer's output. Gates in torch's order (input, forget, cell, output);
    weights (4 H, inputs) and (4 H, H), biases (4 H,), float32. A layer without biases has them
    zero.
    """

    weight_input: npt.NDArray[np.float32]
    weight_hidden: npt.NDArray[np.float32]
    bias_input: npt.NDArray[np.float32]
    bias_hidden: npt.NDArray[np.float32]

    def __post_init__(self) -> None:
        hidden = self.hidden_size
        shapes = {
            "weight_input": (self.weight_input.shape, (4 * hidden, self.inputs)),
            "weight_hidden": (self.weight_hidden.shape, (4 * hidden, hidden)),
            "bias_input": (self.bias_input.shape, (4 * hidden,)),
            "bias_hidden": (self.bias_hidden.shape, (4 * hidden,)),
        }
        for name, (shape, expected) in shapes.items():
            if tuple(shape) != expected or hidden < 1:
                raise KheperaError(f"LSTM {name} has shape {tuple(shape)}, not {expected}")

    @property
    def inputs(self) -> int:
        """Input width."""
        return int(self.weight_input.shape[1])

    @property
    def hidden_size(self) -> int:
        """H: the width of the hidden and of the cell state, and of the output."""
        return int(self.weight_hidden.shape[1])

    def arrays(self) -> tuple[npt.NDArray[np.float32], ...]:
        """The weights and biases."""
        return (self.weight_input, self.weight_hidden, self.bias_input, self.bias_hidden)


@dataclasses.dataclass(frozen=True)
class ActionTransform:
    """The network output ``y`` to an action: ``scale * y + offset``, then clipped to
    ``[low, high]`` when those are set (float32)."""

    scale: npt.NDArray[np.float32]
    offset: npt.NDArray[np.float32]
    low: npt.NDArray[np.float32] | None
    high: npt.NDArray[np.float32] | None

    @property
    def is_affine(self) -> bool:
        """False when the scale is 1 and the offset 0."""
        return bool(np.any(self.scale != 1.0) or np.any(self.offset != 0.0))


@dataclasses.dataclass(frozen=True)
class PolicyNetwork:
    """A deterministic policy as normalisation → frame stack → LSTM layers → dense layers →
    action transform.

    ``obs_dim`` is the width of one observation (what the env gives and the normalisation
    statistics cover); the first layer takes ``frame_stack`` of them (:attr:`input_dim`): each
    observation is normalised as it arrives, the stack holds the last ``frame_stack`` ones, oldest
    first, and zeros before an episode's first observation. A recurrent policy's ``lstm`` layers
    (none for the others) come first; their hidden and cell states are the policy's memory
    besides the stack, zeros before an episode's first observation (as SB3's ``episode_start``
    resets them); the last one's hidden state feeds the dense layers.

    Raises:
        KheperaError: The layers do not chain from ``obs_dim`` to ``action_dim`` or use an
            activation the writers do not implement.
        ConfigError: A weight is NaN or infinite.
    """

    #: Where it came from, e.g. "stable-baselines3 PPO".
    source: str
    obs_dim: int
    action_dim: int
    normalization: ObservationNormalization | None
    layers: tuple[DenseLayer, ...]
    action: ActionTransform
    #: Observations the network acts on (1: the current one only).
    frame_stack: int = 1
    #: The standard deviation of the policy's Gaussian around the action before its clip, one
    #: per action value (float32), when it does not depend on the observation (PPO's and A2C's
    #: ``log_std``): what sampling its actions as in training needs. None for a policy whose
    #: noise the writers cannot reproduce (SAC's state-dependent σ, TD3, RLlib).
    action_std: npt.NDArray[np.float32] | None = None
    #: LSTM layers before the dense ones (a recurrent policy), all of one hidden size.
    lstm: tuple[LstmLayer, ...] = ()

    def __post_init__(self) -> None:
        if isinstance(self.frame_stack, bool) or not isinstance(self.frame_stack, int):
            raise KheperaError(f"frame_stack must be an int, got {self.frame_stack!r}")
        if self.frame_stack < 1:
            raise KheperaError(f"frame_stack must be >= 1, got {self.frame_stack}")
        width = self.input_dim
        for index, lstm in enumerate(self.lstm):
            if lstm.inputs != width:
                raise KheperaError(f"LSTM layer {index} takes {lstm.inputs} inputs, not {width}")
            if lstm.hidden_size != self.lstm[0].hidden_size:
                raise KheperaError("the LSTM layers must have one hidden size")
            if not all(np.all(np.isfinite(array)) for array in lstm.arrays()):
                raise ConfigError(f"LSTM layer {index} of the {self.source} policy has NaN/inf")
            width = lstm.hidden_size
        for index, layer in enumerate(self.layers):
            if layer.inputs != width:
                raise KheperaError(f"layer {index} takes {layer.inputs} inputs, not {width}")
            if layer.activation not in ACTIVATIONS:
                raise KheperaError(f"layer {index}: unknown activation {layer.activation!r}")
            if not (np.all(np.isfinite(layer.weight)) and np.all(np.isfinite(layer.bias))):
                raise ConfigError(f"layer {index} of the {self.source} policy has NaN/inf weights")
            width = layer.outputs
        if width != self.action_dim:
            raise KheperaError(f"the network gives {width} values, not {self.action_dim}")
        if self.action_std is not None:
            std = np.asarray(self.action_std)
            if std.shape != (self.action_dim,):
                raise KheperaError(f"action_std has shape {std.shape}, not ({self.action_dim},)")
            if not (np.all(np.isfinite(std)) and np.all(std > 0.0)):
                raise ConfigError(
                    f"the {self.source} policy's action noise must be finite and > 0, got {std}"
                )

    @property
    def input_dim(self) -> int:
        """The first layer's width: ``frame_stack`` observations."""
        return self.obs_dim * self.frame_stack

    @property
    def lstm_hidden_size(self) -> int:
        """H of the LSTM layers (0 without any)."""
        return self.lstm[0].hidden_size if self.lstm else 0

    @property
    def recurrent(self) -> bool:
        """Whether the policy carries an LSTM state between steps."""
        return bool(self.lstm)

    @property
    def max_width(self) -> int:
        """The widest vector of the forward pass."""
        widths = [self.input_dim, *(layer.outputs for layer in self.layers)]
        return max([*widths, self.lstm_hidden_size])


__all__ = [
    "ACTIVATIONS",
    "EXPORT_EXTRA",
    "SUPPORTED_MODELS",
    "ActionTransform",
    "DenseLayer",
    "LstmLayer",
    "ObservationNormalization",
    "PolicyNetwork",
    "unsupported_model",
]
