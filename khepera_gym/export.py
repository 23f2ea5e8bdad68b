"""``khepera-gym export``: a trained policy as ONNX, or as plain C for the real Khepera IV.

A policy network is first reduced to a small description, :class:`PolicyNetwork`: the
observation normalisation (``VecNormalize`` statistics: mean, variance, epsilon, clip), a list
of dense layers with their activations, and the transform of the network's output into an
action (an affine map and a clip to the action bounds). Both writers work from that one
description, so the ONNX file and the C code compute the same function:

* :func:`build_onnx` makes an ONNX graph with ``onnx.helper`` (opset :data:`ONNX_OPSET`; input
  ``"observation"`` (N, obs_dim) float32, output ``"action"`` (N, action_dim)), checked with
  ``onnx.checker``; it needs the ``export`` extra (onnx, onnxruntime).
* :func:`write_c` writes ``policy.c``/``policy.h`` (weights as ``const float`` arrays,
  ``int policy_forward(const float *observation, float *action)``, no allocation, libm for
  tanhf/expf only), ``observation.c``/``.h`` (the simulator's normalisation of the raw IR and
  ultrasonic readings, wheel speeds and goal into the observation vector of the env the policy
  was trained on, with the scenario's constants baked in), ``wheel_command.c``/``.h`` (the action
  to ``kh4_set_speed`` units, as the simulator turns actions into wheel speeds), the template
  program ``khepera_policy_main.c`` (libkhepera: sensors, dead reckoning, policy, wheel speeds
  every control period), ``export_check.c`` (runs the exported code on rows of numbers, for
  parity checks on a PC or on the robot), a Makefile and a README.

Supported models (:data:`SUPPORTED_MODELS`): stable-baselines3 PPO and A2C (``MlpPolicy``, the
deterministic action is the Gaussian mean clipped to the action space), SAC and TD3 (the actor,
tanh-squashed and rescaled to the action bounds; DDPG is a TD3), with the ``VecNormalize``
statistics when a ``vecnormalize.pkl`` lies next to the model; and Ray RLlib PPO checkpoints of
the new API stack with the default torch MLP RLModule (the mean of its Gaussian, then RLlib's
action normalisation and clipping). Anything else raises :class:`~khepera_gym.errors.ConfigError`
naming these.

:func:`export_policy` does the whole job and, with ``check=True`` (the command's default),
measures the exported files against the Python policy on observations recorded from seeded env
rollouts: the ONNX file with onnxruntime, the C code compiled with the system C compiler.

Units: the observation is the simulator's (SI units, normalised sensors); wheel commands are
K-Team speed units of 0.678181 mm/s. Threading: everything runs in the calling thread.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import importlib.resources
import json
import math
import re
import shutil
import string
import subprocess
import sys
import tempfile
import textwrap
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

import khepera_gym
from khepera_gym.errors import ConfigError, KheperaError

#: What :func:`describe_policy` accepts, for error messages and the documentation.
SUPPORTED_MODELS = (
    "stable-baselines3 PPO or A2C with MlpPolicy (a model.zip, the loaded model, or "
    "khepera_gym.sb3.load_policy's result)",
    "stable-baselines3 SAC or TD3 (DDPG) with MlpPolicy",
    "a Ray RLlib PPO checkpoint directory (new API stack, default torch MLP RLModule) or its "
    "loaded RLModule",
)
#: Output formats of :func:`export_policy`.
FORMATS = ("c", "onnx")
#: Install hint for the ONNX writer and checker.
EXPORT_EXTRA = "pip install 'khepera-gym[export]'"
#: ONNX operator set of the exported graph: every operator used exists in this form since
#: opset 13, and older runtimes (as on small robots) load it.
ONNX_OPSET = 13
#: ONNX IR version written (7 goes with opset 13; older runtimes reject newer IR versions).
ONNX_IR_VERSION = 7
#: Largest absolute difference between an exported policy's action and the Python policy's that
#: the checks accept.
PARITY_TOLERANCE = 1e-5
#: Largest difference between the C observation and the simulator's (float32 rounding of the
#: goal bearing's sine and cosine; the sensor blocks match exactly).
OBSERVATION_TOLERANCE = 1e-6
#: Flags of the native build of ``export_check`` in the export's check (the tests add -Wextra
#: -Werror: the code is warning-free C99 with gcc).
C_FLAGS = ("-O2", "-std=c99", "-Wall")
#: Raw IR reading of an obstacle touching the sensor (src/sensors/ir.rs, IR_MAX_RAW).
IR_MAX_RAW = 1023.0
#: One ``kh4_set_speed`` unit in mm/s (src/robot.rs, khepera4_spec.md §1).
MM_S_PER_SPEED_UNIT = 0.678181
#: Largest closed-loop ``kh4_set_speed`` command (about 813 mm/s; khepera4_spec.md §1, the
#: serial protocol's ``D,l,r`` takes ±1200).
MAX_SPEED_UNITS = 1200
#: Encoder pulses per wheel turn: 128 × 4 (quadrature) × 38:1 (khepera4_spec.md §1).
PULSES_PER_WHEEL_TURN = 19456
#: Files written next to the exported code.
LAYOUT_FILE = "obs_layout.json"
SCENARIO_FILE = "scenario.toml"
MANIFEST_FILE = "export.json"
ONNX_FILE = "policy.onnx"
#: Template files shipped in khepera_gym/export_templates/.
_TEMPLATES = "export_templates"
#: Observation blocks the C observation builder computes from the robot's own readings; any
#: other block is an input passed through unchanged.
_GOAL_BLOCKS = ("goal_distance", "goal_bearing_sin", "goal_bearing_cos")
_SENSOR_BLOCKS = {"ir": 8, "us": 5, "wheel_speeds": 2}


# ----------------------------------------------------------------------------------------------
# The description both writers share.


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


#: Activations the writers implement.
ACTIVATIONS = ("identity", "tanh", "relu", "elu", "leaky_relu", "silu")


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
    """A deterministic policy as normalisation → dense layers → action transform."""

    #: Where it came from, e.g. "stable-baselines3 PPO".
    source: str
    obs_dim: int
    action_dim: int
    normalization: ObservationNormalization | None
    layers: tuple[DenseLayer, ...]
    action: ActionTransform

    def __post_init__(self) -> None:
        width = self.obs_dim
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

    @property
    def max_width(self) -> int:
        """The widest vector of the forward pass."""
        return max([self.obs_dim, *(layer.outputs for layer in self.layers)])


def _unsupported(what: str) -> ConfigError:
    supported = "; ".join(SUPPORTED_MODELS)
    return ConfigError(f"cannot export {what}: supported are {supported}")


# ----------------------------------------------------------------------------------------------
# Extraction: SB3 and RLlib models to a PolicyNetwork.


def describe_policy(model: Any, normalizer: Any = None) -> PolicyNetwork:
    """The :class:`PolicyNetwork` of a supported model.

    Args:
        model: A stable-baselines3 model, :func:`khepera_gym.sb3.load_policy`'s result, a path to
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
    if isinstance(model, _RllibPolicy):
        return _describe_rllib_module(model.module, model.action_config)
    module_name = type(model).__module__
    if module_name == "khepera_gym.sb3" and type(model).__name__ == "NormalizedPolicy":
        return _describe_sb3(model.model, model.normalizer)
    if module_name.startswith("stable_baselines3"):
        return _describe_sb3(model, normalizer)
    if module_name.startswith("ray.rllib"):
        return _describe_rllib_module(model, _RllibActionConfig())
    raise _unsupported(f"a {type(model).__module__}.{type(model).__qualname__}")


def load_model(path: str | Path) -> tuple[Any, Any]:
    """Loads an SB3 ``.zip`` (and ``vecnormalize.pkl`` beside it) or an RLlib checkpoint.

    Returns:
        (model, normalizer or None); for RLlib the model is an :class:`_RllibPolicy`.

    Raises:
        ConfigError: The path is neither (the message lists what is supported).
        ImportError: stable-baselines3 or ray is missing.
    """
    path = Path(path)
    if path.is_dir():
        return _load_rllib(path), None
    if not path.is_file():
        raise ConfigError(f"{path}: no such model file or checkpoint directory")
    if path.suffix != ".zip":
        raise _unsupported(f"{path} (not an SB3 .zip nor an RLlib checkpoint directory)")
    import pickle

    try:
        stable_baselines3 = importlib.import_module("stable_baselines3")
        from khepera_gym import sb3
    except ImportError as error:
        raise ImportError(
            f"{path} is a stable-baselines3 model: pip install 'khepera-gym[sb3]'"
        ) from error
    try:
        algorithm = sb3.algorithm_of(path)
    except KheperaError as error:
        raise _unsupported(f"{path} ({error})") from error
    model_class = getattr(stable_baselines3, algorithm)
    model = model_class.load(path, device="cpu")
    stats_path = path.parent / sb3.VECNORMALIZE_FILE
    normalizer = None
    if stats_path.exists():
        with stats_path.open("rb") as stats_file:
            normalizer = pickle.load(stats_file)
    return model, normalizer


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


def _dense_layers(modules: Iterable[Any], where: str) -> list[DenseLayer]:
    """Linear layers and activations, in forward order, as dense layers.

    Raises:
        ConfigError: A module is neither a Linear layer nor a supported activation.
    """
    from torch import nn

    layers: list[DenseLayer] = []
    for module in modules:
        if isinstance(module, nn.Sequential):
            layers.extend(_dense_layers(module, where))
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


def _check_spaces(observation_space: Any, action_space: Any, what: str) -> tuple[int, int]:
    if not isinstance(observation_space, gym.spaces.Box) or len(observation_space.shape) != 1:
        raise _unsupported(f"{what} with observation space {observation_space}")
    if not isinstance(action_space, gym.spaces.Box) or len(action_space.shape) != 1:
        raise _unsupported(f"{what} with action space {action_space} (continuous Box needed)")
    return int(observation_space.shape[0]), int(action_space.shape[0])


def _describe_sb3(model: Any, normalizer: Any) -> PolicyNetwork:
    from stable_baselines3 import A2C, PPO, SAC, TD3
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor
    from torch import nn

    name = f"stable-baselines3 {type(model).__name__}"
    if not isinstance(model, (PPO, A2C, SAC, TD3)):
        raise _unsupported(f"a {name} model")
    obs_dim, action_dim = _check_spaces(model.observation_space, model.action_space, name)
    policy = model.policy
    low = model.action_space.low.astype(np.float32)
    high = model.action_space.high.astype(np.float32)
    if isinstance(model, (PPO, A2C)):
        if not isinstance(policy, ActorCriticPolicy) or not isinstance(
            policy.pi_features_extractor, FlattenExtractor
        ):
            raise _unsupported(f"a {name} with {type(policy).__name__}")
        if policy.use_sde:
            raise _unsupported(f"a {name} trained with gSDE (use_sde=True)")
        modules = [*policy.mlp_extractor.policy_net, policy.action_net]
        ones = np.ones(action_dim, np.float32)
        action = ActionTransform(ones, np.zeros(action_dim, np.float32), low, high)
    else:
        actor = policy.actor
        if not isinstance(actor.features_extractor, FlattenExtractor):
            raise _unsupported(f"a {name} with {type(policy).__name__}")
        if getattr(actor, "use_sde", False):
            raise _unsupported(f"a {name} trained with gSDE (use_sde=True)")
        # SAC: the mode of the tanh-squashed Gaussian; TD3's actor ends with Tanh itself.
        modules = [*actor.latent_pi, actor.mu, nn.Tanh()] if isinstance(model, SAC) else [*actor.mu]
        # SB3's unscale_action: low + 0.5 * (y + 1) * (high - low).
        scale = (0.5 * (high - low)).astype(np.float32)
        action = ActionTransform(scale, (low + scale).astype(np.float32), None, None)
    layers = _dense_layers(modules, f"the {name} policy")
    if isinstance(model, (SAC, TD3)) and (not layers or layers[-1].activation != "tanh"):
        raise _unsupported(f"a {name} whose actor does not end in tanh")
    return PolicyNetwork(
        source=name,
        obs_dim=obs_dim,
        action_dim=action_dim,
        normalization=_sb3_normalization(normalizer, obs_dim),
        layers=tuple(layers),
        action=action,
    )


def _sb3_normalization(normalizer: Any, obs_dim: int) -> ObservationNormalization | None:
    if normalizer is None or not getattr(normalizer, "norm_obs", False):
        return None
    stats = normalizer.obs_rms
    if isinstance(stats, dict):
        raise _unsupported("a VecNormalize with dict observations")
    mean = np.asarray(stats.mean, np.float64)
    variance = np.asarray(stats.var, np.float64)
    if mean.shape != (obs_dim,) or variance.shape != (obs_dim,):
        raise ConfigError(
            f"the VecNormalize statistics have shape {mean.shape}, the policy takes ({obs_dim},)"
        )
    return ObservationNormalization(
        mean, variance, float(normalizer.epsilon), float(normalizer.clip_obs)
    )


@dataclasses.dataclass(frozen=True)
class _RllibActionConfig:
    """RLlib's module-to-env action handling (``NormalizeAndClipActions``); RLlib's defaults."""

    normalize_actions: bool = True
    clip_actions: bool = False


@dataclasses.dataclass
class _RllibPolicy:
    """An RLModule loaded from a checkpoint with its action handling, for inference."""

    module: Any
    action_config: _RllibActionConfig
    #: The env the algorithm was configured with (a string id), if any.
    env_id: str | None
    #: Its ``env_config`` (``gym.make`` keyword arguments for a registered id).
    env_config: dict[str, Any] = dataclasses.field(default_factory=dict)

    def predict(
        self, observation: npt.NDArray[np.float32], deterministic: bool = True
    ) -> npt.NDArray[np.float32]:
        """RLlib's deterministic actions for observations (N, obs_dim) or (obs_dim,)."""
        import torch
        from ray.rllib.utils.spaces.space_utils import clip_action, unsquash_action

        batch = np.atleast_2d(np.asarray(observation, np.float32))
        with torch.no_grad():
            out = self.module.forward_inference({"obs": torch.from_numpy(batch)})
        dist_class = self.module.get_inference_action_dist_cls()
        dist = dist_class.from_logits(out["action_dist_inputs"])
        if deterministic:
            dist = dist.to_deterministic()
        actions = dist.sample().numpy()
        space = self.module.action_space
        if self.action_config.normalize_actions:
            actions = unsquash_action(actions, space)
        elif self.action_config.clip_actions:
            actions = clip_action(actions, space)
        actions = np.asarray(actions, np.float32)
        return actions if np.ndim(observation) > 1 else actions[0]


#: Connectors of RLlib's default env-to-module pipeline; any other changes the observation.
_RLLIB_PLAIN_CONNECTORS = frozenset(
    {
        "AddObservationsFromEpisodesToBatch",
        "AddTimeDimToBatchAndZeroPad",
        "AddStatesFromEpisodesToBatch",
        "AgentToModuleMapping",
        "BatchIndividualItems",
        "NumpyToTensor",
    }
)


def _import_rllib() -> Any:
    try:
        from ray.rllib.core.rl_module.rl_module import RLModule
    except ImportError as error:
        raise ImportError(
            "exporting an RLlib checkpoint needs Ray RLlib: pip install 'khepera-gym[rllib]' "
            "(or pip install 'ray[rllib]')"
        ) from error
    return RLModule


def _connector_specs(path: Path) -> list[tuple[str, dict[str, Any]]]:
    """(class name, kwargs) of the connectors in a pipeline's ``class_and_ctor_args.pkl``."""
    import pickle

    with path.open("rb") as spec_file:
        spec = pickle.load(spec_file)
    _, kwargs = spec["ctor_args_and_kwargs"]
    return [(cls.__name__, dict(kw)) for cls, _, kw in kwargs.get("connectors", [])]


def _load_rllib(path: Path) -> _RllibPolicy:
    """An RLlib checkpoint: an algorithm's directory or one RLModule's."""
    module_dir = path
    action_config = _RllibActionConfig()
    env_id, env_config = None, {}
    if (path / "rllib_checkpoint.json").exists() and (path / "learner_group").is_dir():
        modules = path / "learner_group" / "learner" / "rl_module"
        candidates = sorted(p for p in modules.iterdir() if (p / "module_state.pkl").exists())
        if [p.name for p in candidates] != ["default_policy"]:
            raise _unsupported(
                f"{path}: an RLlib checkpoint of modules {[p.name for p in candidates]} "
                "(one single-agent 'default_policy' module is needed)"
            )
        module_dir = candidates[0]
        _import_rllib()
        runner = path / "env_runner"
        to_module = runner / "env_to_module_connector" / "class_and_ctor_args.pkl"
        if to_module.exists():
            extra = [n for n, _ in _connector_specs(to_module) if n not in _RLLIB_PLAIN_CONNECTORS]
            if extra:
                raise _unsupported(
                    f"{path}: an RLlib policy whose observations pass through {extra}"
                )
        to_env = runner / "module_to_env_connector" / "class_and_ctor_args.pkl"
        if to_env.exists():
            for name, kwargs in _connector_specs(to_env):
                if name == "NormalizeAndClipActions":
                    action_config = _RllibActionConfig(
                        bool(kwargs.get("normalize_actions", True)),
                        bool(kwargs.get("clip_actions", False)),
                    )
        env_id, env_config = _rllib_env(path)
    elif not (path / "module_state.pkl").exists():
        raise _unsupported(f"{path} (a directory that is not an RLlib checkpoint)")
    rl_module = _import_rllib()
    module = rl_module.from_checkpoint(module_dir)
    return _RllibPolicy(module, action_config, env_id, env_config)


def _rllib_env(path: Path) -> tuple[str | None, dict[str, Any]]:
    """The env id (when a string) and ``env_config`` an RLlib algorithm checkpoint was
    configured with."""
    import pickle

    try:
        with (path / "class_and_ctor_args.pkl").open("rb") as spec_file:
            spec = pickle.load(spec_file)
        config = spec["ctor_args_and_kwargs"][0][0]
    except (OSError, KeyError, IndexError, TypeError, pickle.UnpicklingError):
        return None, {}
    get = config.get if isinstance(config, dict) else lambda key: getattr(config, key, None)
    env, env_config = get("env"), get("env_config")
    return (env if isinstance(env, str) else None), dict(env_config or {})


def _describe_rllib_module(module: Any, action_config: _RllibActionConfig) -> PolicyNetwork:
    name = f"RLlib {type(module).__name__}"
    encoder = getattr(module, "encoder", None)
    head = getattr(module, "pi", None)
    if encoder is None or head is None or not hasattr(module, "get_inference_action_dist_cls"):
        raise _unsupported(f"an {name} (not RLlib's default PPO module)")
    if module.is_stateful():
        raise _unsupported(f"an {name} with memory (LSTM)")
    obs_dim, action_dim = _check_spaces(module.observation_space, module.action_space, name)
    dist_name = module.get_inference_action_dist_cls().__name__
    if dist_name != "TorchDiagGaussian":
        raise _unsupported(f"an {name} with a {dist_name} action distribution")
    actor = getattr(encoder, "actor_encoder", None) or getattr(encoder, "encoder", None)
    parts = [getattr(getattr(part, "net", None), "mlp", None) for part in (actor, head)]
    if any(part is None for part in parts):
        raise _unsupported(f"an {name} whose encoder or head is not RLlib's MLP")
    layers = _dense_layers(parts, f"the {name}")
    last = layers[-1]
    if last.outputs == 2 * action_dim and last.activation == "identity":
        # TorchDiagGaussian's inputs are (mean, log_std); the deterministic action is the mean.
        layers[-1] = DenseLayer(last.weight[:action_dim].copy(), last.bias[:action_dim].copy())
    elif last.outputs != action_dim:
        raise _unsupported(f"an {name} whose head gives {last.outputs} values")
    space = module.action_space
    low = space.low.astype(np.float32)
    high = space.high.astype(np.float32)
    ones, zeros = np.ones(action_dim, np.float32), np.zeros(action_dim, np.float32)
    if action_config.normalize_actions:
        # RLlib's unsquash_action: low + (y + 1) * (high - low) / 2, then clipped.
        scale = ((high - low) / 2.0).astype(np.float32)
        action = ActionTransform(scale, (low + scale).astype(np.float32), low, high)
    elif action_config.clip_actions:
        action = ActionTransform(ones, zeros, low, high)
    else:
        action = ActionTransform(ones, zeros, None, None)
    return PolicyNetwork(name, obs_dim, action_dim, None, tuple(layers), action)


# ----------------------------------------------------------------------------------------------
# The robot side: what the observation holds and the scenario's constants.


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
    layout: tuple[tuple[str, int, int], ...]
    action_type: str
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

    @property
    def has_goal(self) -> bool:
        """Whether the observation has Nav's goal blocks."""
        return any(name in _GOAL_BLOCKS for name, _, _ in self.layout)

    @property
    def extra_blocks(self) -> list[tuple[str, int, int]]:
        """Blocks the robot cannot compute itself (passed in unchanged)."""
        known = set(_SENSOR_BLOCKS) | set(_GOAL_BLOCKS)
        return [block for block in self.layout if block[0] not in known]


def _toml_loads(text: str) -> dict[str, Any]:
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        try:
            import tomli as tomllib
        except ImportError as error:
            raise ImportError(f"reading the scenario needs tomli: {EXPORT_EXTRA}") from error
    return tomllib.loads(text)


def robot_interface(env: gym.Env[Any, Any], obs_dim: int, env_id: str) -> RobotInterface:
    """The :class:`RobotInterface` of a khepera_gym env for a policy taking ``obs_dim`` values.

    Raises:
        ConfigError: The policy's observation matches neither the env's nor one agent's block,
            or it is the joint observation of several robots.
    """
    unwrapped = env.unwrapped
    full = [(name, s.start, s.stop) for name, s in unwrapped.obs_layout().items()]
    total = full[-1][2]
    agents = list(dict.fromkeys(name.split("/", 1)[0] for name, _, _ in full if "/" in name))
    agent = None
    if agents:
        own = [b for b in full if b[0].startswith(agents[0] + "/")]
        base = own[0][1]
        layout = tuple((name.split("/", 1)[1], s - base, e - base) for name, s, e in own)
        agent = agents[0]
        if layout[-1][2] != obs_dim:
            joint = (
                " (the joint observation of several robots: export a policy shared by "
                "the robots, trained on one robot's block)"
                if obs_dim == total
                else ""
            )
            raise ConfigError(
                f"the policy takes {obs_dim} observation values; {env_id}'s agents have "
                f"{layout[-1][2]} each{joint}"
            )
    else:
        layout = tuple(full)
        if total != obs_dim:
            raise ConfigError(
                f"the policy takes {obs_dim} observation values but {env_id} gives {total}: "
                "pass the env (and scenario) it was trained on"
            )
    scenario_toml = unwrapped.config_toml()
    scenario = _toml_loads(scenario_toml)
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
        task=str(getattr(unwrapped, "TASK", "")),
        agent=agent,
        layout=layout,
        action_type=str(getattr(unwrapped, "action_type", "wheels")),
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


# ----------------------------------------------------------------------------------------------
# ONNX.


def _import_onnx() -> Any:
    try:
        import onnx
    except ImportError as error:
        raise ImportError(f"writing ONNX needs the onnx package: {EXPORT_EXTRA}") from error
    return onnx


def build_onnx(network: PolicyNetwork, metadata: Mapping[str, str] | None = None) -> Any:
    """The ONNX ``ModelProto`` of ``network``, checked with ``onnx.checker``.

    Input ``"observation"`` float32 (N, obs_dim), output ``"action"`` float32 (N, action_dim).
    The normalisation runs in float64 (as SB3's does), the rest in float32.

    Raises:
        ImportError: onnx is not installed (the message names the pip command).
    """
    onnx = _import_onnx()
    from onnx import TensorProto, helper, numpy_helper

    nodes: list[Any] = []
    initializers: list[Any] = []

    def constant(name: str, values: npt.ArrayLike, dtype: Any = np.float32) -> str:
        initializers.append(numpy_helper.from_array(np.asarray(values, dtype), name))
        return name

    def node(op: str, inputs: list[str], output: str, **attributes: Any) -> str:
        nodes.append(helper.make_node(op, inputs, [output], name=output, **attributes))
        return output

    current = "observation"
    norm = network.normalization
    if norm is not None:
        current = node("Cast", [current], "observation_f64", to=TensorProto.DOUBLE)
        current = node("Sub", [current, constant("obs_mean", norm.mean, np.float64)], "centred")
        current = node("Div", [current, constant("obs_std", norm.std, np.float64)], "scaled")
        current = node("Max", [current, constant("obs_low", [-norm.clip], np.float64)], "lower")
        current = node("Min", [current, constant("obs_high", [norm.clip], np.float64)], "upper")
        current = node("Cast", [current], "normalized", to=TensorProto.FLOAT)
    for index, layer in enumerate(network.layers):
        weight = constant(f"layer{index}_weight", layer.weight)
        bias = constant(f"layer{index}_bias", layer.bias)
        current = node("Gemm", [current, weight, bias], f"layer{index}_linear", transB=1)
        out = f"layer{index}_{layer.activation}"
        if layer.activation == "tanh":
            current = node("Tanh", [current], out)
        elif layer.activation == "relu":
            current = node("Relu", [current], out)
        elif layer.activation == "elu":
            current = node("Elu", [current], out, alpha=layer.alpha)
        elif layer.activation == "leaky_relu":
            current = node("LeakyRelu", [current], out, alpha=layer.alpha)
        elif layer.activation == "silu":
            gate = node("Sigmoid", [current], f"layer{index}_gate")
            current = node("Mul", [current, gate], out)
    transform = network.action
    if transform.is_affine:
        current = node("Mul", [current, constant("action_scale", transform.scale)], "scaled_action")
        current = node("Add", [current, constant("action_offset", transform.offset)], "shifted")
    if transform.low is not None and transform.high is not None:
        current = node("Max", [current, constant("action_low", transform.low)], "above_low")
        current = node("Min", [current, constant("action_high", transform.high)], "action")
    else:
        current = node("Identity", [current], "action")
    graph = helper.make_graph(
        nodes,
        "khepera_gym_policy",
        [helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["N", network.obs_dim])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["N", network.action_dim])],
        initializer=initializers,
    )
    model = helper.make_model(
        graph,
        producer_name="khepera_gym",
        producer_version=khepera_gym.__version__,
        opset_imports=[helper.make_opsetid("", ONNX_OPSET)],
        ir_version=ONNX_IR_VERSION,
    )
    model.doc_string = f"{network.source} policy exported by khepera_gym"
    for key, text in (metadata or {}).items():
        model.metadata_props.add(key=key, value=text)
    onnx.checker.check_model(model, full_check=True)
    return model


def onnx_actions(path: str | Path, observations: npt.NDArray[np.float32]) -> npt.NDArray[Any]:
    """Runs an exported ONNX policy with onnxruntime on observations (N, obs_dim).

    Raises:
        ImportError: onnxruntime is not installed (the message names the pip command).
    """
    try:
        import onnxruntime
    except ImportError as error:
        raise ImportError(f"running ONNX needs onnxruntime: {EXPORT_EXTRA}") from error
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    batch = np.ascontiguousarray(observations, dtype=np.float32)
    return np.asarray(session.run(["action"], {"observation": batch})[0])


# ----------------------------------------------------------------------------------------------
# C.


def _c_float(value: float) -> str:
    """A float32 literal that reads back as exactly ``np.float32(value)``."""
    number = float(np.float32(value))
    if not math.isfinite(number):
        raise ConfigError(f"cannot write the non-finite value {number} as a C constant")
    text = f"{number:.9g}"
    if not any(mark in text for mark in ".en"):
        text += ".0"
    return text + "f"


def _c_double(value: float) -> str:
    """A double literal that reads back as exactly ``value``."""
    if not math.isfinite(value):
        raise ConfigError(f"cannot write the non-finite value {value} as a C constant")
    text = f"{value:.17g}"
    return text if any(mark in text for mark in ".en") else text + ".0"


def _c_array(values: Iterable[str], indent: str = "    ", per_line: int = 6) -> str:
    """Comma-separated values, ``per_line`` to a line."""
    items = list(values)
    lines = [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]
    return (",\n" + indent).join(lines)


def _indices(start: int, stop: int, dash: str) -> str:
    """A block's indices: "13", or "0-7" for a longer one."""
    return str(start) if stop - start == 1 else f"{start}{dash}{stop - 1}"


def _c_name(name: str) -> str:
    return re.sub(r"\W", "_", name)


def _template(name: str) -> string.Template:
    """A file of khepera_gym/export_templates/ ($-placeholders, see string.Template)."""
    text = importlib.resources.files("khepera_gym").joinpath(_TEMPLATES, name).read_text("utf-8")
    return string.Template(text)


#: C expressions of the activations, of ``{x}`` (and ``{alpha}``).
_C_ACTIVATIONS = {
    "tanh": "tanhf({x})",
    "relu": "({x} > 0.0f ? {x} : 0.0f)",
    "elu": "({x} > 0.0f ? {x} : {alpha} * (expf({x}) - 1.0f))",
    "leaky_relu": "({x} > 0.0f ? {x} : {alpha} * {x})",
    "silu": "({x} / (1.0f + expf(-{x})))",
}


def _policy_constants(network: PolicyNetwork) -> str:
    """The C definitions of the normalisation statistics, weights and action transform."""
    parts = []
    norm = network.normalization
    if norm is not None:
        parts.append(
            "/* VecNormalize statistics: clip((obs - mean) / sqrt(var + epsilon)), in double as\n"
            f" * stable-baselines3 computes it (epsilon {norm.epsilon:g} is in OBS_STD). */\n"
            f"#define OBS_CLIP {_c_double(norm.clip)}\n"
            "static const double OBS_MEAN[POLICY_OBS_DIM] = {\n    "
            f"{_c_array(_c_double(v) for v in norm.mean)}\n}};\n"
            "static const double OBS_STD[POLICY_OBS_DIM] = {\n    "
            f"{_c_array(_c_double(v) for v in norm.std)}\n}};\n"
        )
    for index, layer in enumerate(network.layers):
        rows = ",\n".join(
            "    {" + _c_array((_c_float(v) for v in row), indent="     ") + "}"
            for row in layer.weight
        )
        bias = _c_array(_c_float(v) for v in layer.bias)
        parts.append(
            f"/* Layer {index}: {layer.inputs} -> {layer.outputs}, {layer.activation}. */\n"
            f"static const float LAYER{index}_WEIGHT[{layer.outputs}][{layer.inputs}] = {{\n"
            f"{rows}\n}};\n"
            f"static const float LAYER{index}_BIAS[{layer.outputs}] = {{\n    {bias}\n}};\n"
        )
    transform = network.action
    if transform.is_affine:
        parts.append(
            "/* The action: ACTION_SCALE * output + ACTION_OFFSET (to the action bounds). */\n"
            "static const float ACTION_SCALE[POLICY_ACTION_DIM] = {"
            f"{', '.join(_c_float(v) for v in transform.scale)}}};\n"
            "static const float ACTION_OFFSET[POLICY_ACTION_DIM] = {"
            f"{', '.join(_c_float(v) for v in transform.offset)}}};\n"
        )
    if transform.low is not None and transform.high is not None:
        parts.append(
            "/* The action's bounds (the action space): it is clipped to them. */\n"
            "static const float ACTION_LOW[POLICY_ACTION_DIM] = {"
            f"{', '.join(_c_float(v) for v in transform.low)}}};\n"
            "static const float ACTION_HIGH[POLICY_ACTION_DIM] = {"
            f"{', '.join(_c_float(v) for v in transform.high)}}};\n"
        )
    return "\n".join(parts)


def _policy_forward(network: PolicyNetwork) -> str:
    """The statements of ``policy_forward``: normalisation, layers, action transform."""
    lines = ["    for (i = 0; i < POLICY_OBS_DIM; ++i) {"]
    if network.normalization is not None:
        lines += [
            "        double value = ((double)observation[i] - OBS_MEAN[i]) / OBS_STD[i];",
            "        value = value < -OBS_CLIP ? -OBS_CLIP : value;",
            "        value = value > OBS_CLIP ? OBS_CLIP : value;",
            "        buffer_a[i] = (float)value;",
        ]
    else:
        lines.append("        buffer_a[i] = observation[i];")
    lines.append("    }")
    source, target = "buffer_a", "buffer_b"
    for index, layer in enumerate(network.layers):
        lines.append(
            f"    dense(&LAYER{index}_WEIGHT[0][0], LAYER{index}_BIAS, {layer.inputs}, "
            f"{layer.outputs}, {source}, {target});"
        )
        if layer.activation != "identity":
            x = f"{target}[i]"
            expression = _C_ACTIVATIONS[layer.activation].format(x=x, alpha=_c_float(layer.alpha))
            lines += [
                f"    for (i = 0; i < {layer.outputs}; ++i) {{",
                f"        {x} = {expression};",
                "    }",
            ]
        source, target = target, source
    lines += [
        "    for (i = 0; i < POLICY_ACTION_DIM; ++i) {",
        f"        float value = {source}[i];",
    ]
    if network.action.is_affine:
        lines.append("        value = ACTION_SCALE[i] * value + ACTION_OFFSET[i];")
    if network.action.low is not None:
        lines += [
            "        if (value < ACTION_LOW[i]) {",
            "            value = ACTION_LOW[i];",
            "        } else if (value > ACTION_HIGH[i]) {",
            "            value = ACTION_HIGH[i];",
            "        }",
        ]
    lines += ["        action[i] = value;", "    }"]
    return "\n".join(lines)


def policy_c_sources(network: PolicyNetwork, provenance: str) -> dict[str, str]:
    """``policy.h`` and ``policy.c`` of ``network`` (file name → text)."""
    widths = [network.obs_dim, *(layer.outputs for layer in network.layers)]
    fields = {
        "source": network.source,
        "version": khepera_gym.__version__,
        "provenance": provenance,
        "obs_dim": network.obs_dim,
        "action_dim": network.action_dim,
        "widths": " -> ".join(str(width) for width in widths),
        "max_width": network.max_width,
        "constants": _policy_constants(network),
        "forward": _policy_forward(network),
    }
    return {name: _template(name).substitute(fields) for name in ("policy.h", "policy.c")}


def _input_fields(robot: RobotInterface) -> list[tuple[str, str, int, str]]:
    """Fields of ``observation_inputs``: (C name, C type, count, comment), in row order."""
    names = {name for name, _, _ in robot.layout}
    fields = []
    if "ir" in names:
        fields.append(
            (
                "ir_raw",
                "uint16_t",
                8,
                "kh4_proximity_ir's first 8 values: the ring in K-Team "
                "order (back-left, left, front-left, front, front-right, right, back-right, back), "
                "0..1023",
            )
        )
    if "us" in names:
        fields.append(
            (
                "us_cm",
                "int16_t",
                5,
                "kh4_measure_us: left, front-left, front, front-right, "
                "right, in cm, or 0 (too close), 1000 (nothing in range), 2000 (disabled)",
            )
        )
    if "wheel_speeds" in names:
        fields.append(
            (
                "wheel_speeds",
                "float",
                2,
                "left, right wheel speeds (m/s): wheel_units_to_speed() of kh4_get_speed's units",
            )
        )
    if robot.has_goal:
        fields.append(
            (
                "robot_pose",
                "float",
                3,
                "x, y (m) and heading (rad, counter-clockwise) of the "
                "robot, e.g. by dead reckoning",
            )
        )
        fields.append(("goal", "float", 2, "x, y (m) of the goal, in the frame of robot_pose"))
    for name, start, stop in robot.extra_blocks:
        fields.append(
            (
                _c_name(name),
                "float",
                stop - start,
                f"the observation's {name} block, as the "
                "simulator defines it (the env's documentation)",
            )
        )
    return fields


def _wrap_comment(text: str, indent: str) -> str:
    """A ``/* ... */`` comment of ``text`` wrapped to 100 columns."""
    lines = textwrap.wrap(text, 100 - len(indent) - 3)
    return "\n".join(
        indent + ("/* " if i == 0 else "   ") + line + (" */" if i == len(lines) - 1 else "")
        for i, line in enumerate(lines)
    )


def _observation_statement(name: str, start: int, stop: int) -> str:
    """The C statement of ``observation_build`` filling one block."""
    target = f"observation[{start}]"
    if name == "ir":
        source = "observation_ir(inputs->ir_raw[i])"
    elif name == "us":
        source = "observation_us(inputs->us_cm[i])"
    elif name == "wheel_speeds":
        source = "clamp(inputs->wheel_speeds[i] / OBSERVATION_MAX_WHEEL_SPEED, -1.0f, 1.0f)"
    elif name == "goal_distance":
        return (
            f"    {target} = distance < OBSERVATION_ARENA_DIAGONAL ? distance"
            " : OBSERVATION_ARENA_DIAGONAL;"
        )
    elif name in ("goal_bearing_sin", "goal_bearing_cos"):
        axis, fallback = ("1", "0.0f") if name.endswith("sin") else ("0", "1.0f")
        return (
            f"    {target} = distance > 0.0f ? clamp(local[{axis}] / distance, -1.0f, 1.0f)"
            f" : {fallback};"
        )
    else:
        source = f"inputs->{_c_name(name)}[i]"
    return (
        f"    for (int i = 0; i < {stop - start}; ++i) {{\n"
        f"        observation[{start} + i] = {source};\n    }}"
    )


def observation_c_sources(robot: RobotInterface) -> dict[str, str]:
    """``observation.h``/``.c``: the simulator's observation from raw readings (name → text)."""
    fields = _input_fields(robot)
    names = {name for name, _, _ in robot.layout}
    randomised = "".join(
        f"\n * {key} is a range {list(bounds)} in the scenario (domain randomisation): its "
        "midpoint is used."
        for key, bounds in robot.randomised.items()
    )
    where = robot.env_id + (f" (one robot's block, as {robot.agent}'s)" if robot.agent else "")
    header = {
        "where": where,
        "version": khepera_gym.__version__,
        "layout": "\n".join(
            f" *   {_indices(start, stop, '-'):<7} {name}" for name, start, stop in robot.layout
        ),
        "obs_dim": robot.obs_dim,
        "input_count": sum(count for _, _, count, _ in fields),
        "has_ir": int("ir" in names),
        "has_us": int("us" in names),
        "has_wheel_speeds": int("wheel_speeds" in names),
        "has_goal": int(robot.has_goal),
        "extra_inputs": len(robot.extra_blocks),
        "randomised": randomised,
        "ir_floor_value": _c_float(robot.ir_floor_value),
        "us_max_range": _c_float(robot.us_max_range),
        "max_wheel_speed": _c_float(robot.max_wheel_speed),
        "arena_diagonal": _c_float(robot.arena_diagonal),
        "fields": "\n".join(
            f"{_wrap_comment(comment + '.', '    ')}\n    {c_type} {name}[{count}];"
            for name, c_type, count, comment in fields
        ),
    }
    source = {
        "build": "\n".join(_observation_statement(*block) for block in robot.layout),
        "from_row": "\n".join(
            f"    for (int i = 0; i < {count}; ++i) {{\n"
            f"        inputs->{name}[i] = ({c_type})row[next++];\n    }}"
            for name, c_type, count, _ in fields
        ),
        "clear": "\n".join(
            f"    for (int i = 0; i < {stop - start}; ++i) {{\n"
            f"        inputs->{_c_name(name)}[i] = 0.0f;\n    }}"
            for name, start, stop in robot.extra_blocks
        ),
    }
    return {
        "observation.h": _template("observation.h").substitute(header),
        "observation.c": _template("observation.c").substitute(source),
    }


def robot_c_sources(robot: RobotInterface, network: PolicyNetwork) -> dict[str, str]:
    """The wheel command, the template program and its constants, the check program, the
    Makefile (name → text)."""
    if network.action_dim != 2:
        raise ConfigError(
            f"the policy gives {network.action_dim} action values; one robot takes 2 (its wheels)"
        )
    unicycle = robot.action_type == "unicycle"
    wheel_fields = {
        "action_type": robot.action_type,
        "env_id": robot.env_id,
        "action_meaning": "normalised (v, omega): v by the wheel speed limit, omega by 2 limit /"
        " axle; wheels over the limit are scaled down together."
        if unicycle
        else "normalised (left, right) wheel speeds, 1 = the wheel speed limit.",
        "unicycle": int(unicycle),
        "max_wheel_speed": _c_float(robot.max_wheel_speed),
        "min_wheel_speed": _c_float(robot.min_wheel_speed),
        "axle_length": _c_float(robot.axle_length),
        "mm_s_per_unit": _c_float(MM_S_PER_SPEED_UNIT),
        "max_units": MAX_SPEED_UNITS,
    }
    config_fields = {
        "control_period": _c_double(robot.control_period),
        "goal_radius": _c_double(robot.goal_radius),
        "axle_length": _c_double(robot.axle_length),
        "metres_per_pulse": _c_double(2.0 * math.pi * robot.wheel_radius / PULSES_PER_WHEEL_TURN),
        "us_mask": sum(1 << i for i, on in enumerate(robot.us_enabled) if on),
    }
    return {
        "wheel_command.h": _template("wheel_command.h").substitute(wheel_fields),
        "wheel_command.c": _template("wheel_command.c").template,
        "khepera_policy_config.h": _template("khepera_policy_config.h").substitute(config_fields),
        "khepera_policy_main.c": _template("khepera_policy_main.c").template,
        "export_check.c": _template("export_check.c").template,
        "Makefile": _template("Makefile").template,
    }


def write_c(
    network: PolicyNetwork, robot: RobotInterface, out_dir: str | Path, provenance: str
) -> list[Path]:
    """Writes the C sources and the Makefile into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sources = {
        **policy_c_sources(network, provenance),
        **observation_c_sources(robot),
        **robot_c_sources(robot, network),
    }
    paths = []
    for name, text in sources.items():
        path = out / name
        path.write_text(text, encoding="utf-8")
        paths.append(path)
    return paths


C_SOURCES = ("policy.c", "observation.c", "wheel_command.c")


def compile_check_program(
    out_dir: str | Path, compiler: str = "cc", flags: Sequence[str] = C_FLAGS
) -> Path:
    """Compiles ``export_check`` from the exported sources with the system C compiler.

    Raises:
        KheperaError: The compiler is missing or the sources do not compile (its output).
    """
    out = Path(out_dir)
    binary = out / "export_check"
    command = [
        compiler,
        *flags,
        "-o",
        str(binary),
        *(str(out / name) for name in ("export_check.c", *C_SOURCES)),
        "-lm",
    ]
    try:
        result = subprocess.run(command, capture_output=True, text=True, check=False)
    except FileNotFoundError as error:
        raise KheperaError(f"no C compiler {compiler!r} on PATH") from error
    if result.returncode != 0:
        raise KheperaError(f"{' '.join(command)} failed:\n{result.stderr}")
    return binary


def run_check_program(binary: str | Path, mode: str, rows: npt.ArrayLike) -> npt.NDArray[Any]:
    """Feeds rows to ``export_check MODE`` and parses its output rows: float32 (the C values
    exactly) for "policy" and "observation", integers for "wheels".

    Raises:
        KheperaError: The program failed or printed something else than rows of numbers.
    """
    values = np.atleast_2d(np.asarray(rows, np.float64))
    text = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in values) + "\n"
    result = subprocess.run(
        [str(binary), mode], input=text, capture_output=True, text=True, check=False
    )
    if result.returncode != 0:
        raise KheperaError(f"{binary} {mode} exited with {result.returncode}: {result.stderr}")
    parsed = np.array([[float(v) for v in line.split()] for line in result.stdout.splitlines()])
    return parsed.astype(np.int64 if mode == "wheels" else np.float32)


# ----------------------------------------------------------------------------------------------
# Recording observations and raw readings for the checks.


@dataclasses.dataclass
class Recording:
    """Observations of seeded rollouts with what the robot would have measured at each step."""

    #: Policy observations (N, obs_dim), float32.
    observations: npt.NDArray[np.float32]
    #: Rows of ``observation_inputs`` (N, OBSERVATION_INPUT_COUNT) for ``export_check``.
    input_rows: npt.NDArray[np.float64]


def _robot_index(agent: str | None) -> int:
    """The robot an agent drives: robot 0 in single-robot envs; in Formation the leader is
    robot 0 and "follower_k" is robot k + 1; in MultiNav "robot_k" is robot k."""
    if agent is None or agent == "leader":
        return 0
    kind, _, number = agent.rpartition("_")
    return int(number) + (1 if kind == "follower" else 0)


def input_row(
    robot: RobotInterface,
    readings: Mapping[str, npt.NDArray[Any]],
    pose: npt.ArrayLike,
    goal: npt.ArrayLike,
    observation: npt.NDArray[np.float32],
) -> list[float]:
    """One robot's ``observation_inputs`` as a row: its raw readings, pose and goal, and the
    blocks the robot cannot measure (taken from ``observation``, the policy's own block)."""
    index = _robot_index(robot.agent)
    names = {name for name, _, _ in robot.layout}
    row: list[float] = []
    if "ir" in names:
        row += [float(v) for v in readings["ir_raw"][index]]
    if "us" in names:
        row += [float(v) for v in readings["us_cm"][index]]
    if "wheel_speeds" in names:
        row += [float(v) for v in readings["wheel_speeds"][index]]
    if robot.has_goal:
        row += [float(v) for v in np.asarray(pose)[:3]]
        row += [float(v) for v in np.asarray(goal)[:2]]
    for _, start, stop in robot.extra_blocks:
        row += [float(v) for v in observation[start:stop]]
    return row


def record_rollouts(
    env: gym.Env[Any, Any],
    robot: RobotInterface,
    act: Callable[[npt.NDArray[np.float32]], npt.NDArray[Any]],
    seeds: Sequence[int] = tuple(range(10)),
    steps: int = 150,
    random_fraction: float = 0.3,
) -> Recording:
    """Observations and raw inputs of seeded episodes of ``env`` driven by ``act``.

    ``act`` maps the policy's observations (M, obs_dim) to actions (M, action_dim); for a policy
    shared by the agents it runs on every agent's block. A share ``random_fraction`` of the
    steps take uniform random actions instead (seeded), so the rollouts visit more states.
    """
    rng = np.random.default_rng(seeds[0] if seeds else 0)
    observations: list[npt.NDArray[np.float32]] = []
    rows: list[list[float]] = []
    block = robot.obs_dim
    offset = 0
    if robot.agent is not None:
        layout = env.unwrapped.obs_layout()
        offset = layout[f"{robot.agent}/{robot.layout[0][0]}"].start
    for seed in seeds:
        joint, _ = env.reset(seed=seed)
        for _ in range(steps):
            own = joint[offset : offset + block]
            observations.append(np.array(own, np.float32))
            goals = env.unwrapped.goals()
            goal = goals[0] if len(goals) else np.zeros(2)
            if robot.agent is not None and robot.agent.startswith("robot_") and len(goals) > 1:
                goal = goals[_robot_index(robot.agent)]
            pose = env.unwrapped.poses()[_robot_index(robot.agent)]
            rows.append(input_row(robot, env.unwrapped.sensor_readings(), pose, goal, own))
            if rng.random() < random_fraction:
                action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
            else:
                blocks = np.asarray(joint, np.float32).reshape(-1, block)
                action = np.asarray(act(blocks), np.float32).reshape(env.action_space.shape)
            joint, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    return Recording(np.array(observations, np.float32), np.array(rows, np.float64))


# ----------------------------------------------------------------------------------------------
# The whole export.


@dataclasses.dataclass
class ExportResult:
    """What :func:`export_policy` wrote and measured."""

    out_dir: Path
    files: list[Path]
    network: PolicyNetwork
    robot: RobotInterface
    #: Check figures: "onnx_max_abs_error", "c_max_abs_error", "observation_max_abs_error",
    #: "observations" (rows checked), or a "<name>_skipped" reason.
    checks: dict[str, Any]


def _python_actions(model: Any, normalizer: Any) -> Callable[[npt.NDArray[np.float32]], Any]:
    """The model's own deterministic actions, as the reference of the checks."""
    if isinstance(model, _RllibPolicy):
        return lambda obs: model.predict(obs, deterministic=True)
    if normalizer is not None and not hasattr(model, "normalizer"):
        from khepera_gym.sb3 import NormalizedPolicy

        model = NormalizedPolicy(model, normalizer)
    return lambda obs: model.predict(obs, deterministic=True)[0]


def _env_of(model_path: Path | None, model: Any, env_id: str | None) -> tuple[str, dict[str, Any]]:
    """The env id and scenario overrides a model was trained with (``run.json`` of
    ``khepera-gym train``, or the RLlib config), unless ``env_id`` is given."""
    overrides: dict[str, Any] = {}
    if model_path is not None:
        run_file = model_path.parent / "run.json"
        if run_file.is_file():
            run = json.loads(run_file.read_text(encoding="utf-8"))
            overrides = dict(run.get("hyperparams", {}).get("env_kwargs", {}))
            env_id = env_id or run.get("env_id")
    if env_id is None and isinstance(model, _RllibPolicy) and model.env_id is not None:
        env_id = model.env_id
        overrides = dict(model.env_config)
    if env_id is None:
        raise ConfigError(
            "cannot tell which env the policy was trained on (no run.json next to the model): "
            "pass env_id (--env), and the scenario (--config) if it was not the default"
        )
    return _resolve_env_id(env_id), overrides


def _resolve_env_id(env_id: str) -> str:
    """A registered khepera_gym id; an unversioned one ("KheperaIV-Nav") gets its latest
    version."""
    ours = sorted(spec.id for spec in gym.registry.values() if spec.id.startswith("KheperaIV-"))
    if env_id in ours:
        return env_id
    versions = [c for c in ours if c.rsplit("-v", 1)[0] == env_id.rstrip("-")]
    if not versions:
        raise ConfigError(f"unknown environment {env_id!r}; khepera_gym registers {ours}")
    return max(versions, key=lambda c: int(c.rsplit("-v", 1)[1]))


def export_policy(
    model: Any,
    out_dir: str | Path,
    *,
    formats: Sequence[str] = ("c",),
    env_id: str | None = None,
    config: str | Path | None = None,
    action_type: str | None = None,
    normalizer: Any = None,
    check: bool = True,
    compiler: str = "cc",
    **overrides: Any,
) -> ExportResult:
    """Exports a policy with its observation pipeline for the real robot.

    Writes into ``out_dir``: ``policy.onnx`` (format "onnx"), the C sources (format "c", see
    :func:`write_c`), ``obs_layout.json`` (the policy's observation blocks: name → [start,
    stop)), ``scenario.toml`` (the resolved scenario) and ``export.json`` (what was exported,
    the constants used and the check figures).

    Args:
        model: What :func:`describe_policy` takes (an SB3 model or zip, an RLlib checkpoint...).
        out_dir: Output folder (created).
        formats: Any of "c" and "onnx".
        env_id: The env the policy was trained on; read from ``run.json`` next to an SB3 zip
            (``khepera-gym train``) or from the RLlib checkpoint when None.
        config: Its scenario (built-in name or TOML path), None for the env's default.
        action_type: "wheels" or "unicycle" as in training (None: the env's default).
        normalizer: The SB3 ``VecNormalize`` used in training, if not next to a zip.
        check: Measure the exported files against the Python policy on recorded observations
            (ONNX with onnxruntime; C compiled with ``compiler``, skipped if there is none).
        compiler: The C compiler of the check.
        **overrides: Scenario keys as in training (``max_steps=200``).

    Raises:
        ConfigError: Unsupported model or format, or an env that does not fit the policy.
        ImportError: A needed extra is missing (the message names the pip command).
        KheperaError: A check failed (an exported action differs by more than
            :data:`PARITY_TOLERANCE`).
    """
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or not formats:
        raise ConfigError(f"unknown export formats {unknown or list(formats)}; known: {FORMATS}")
    if "onnx" in formats:
        _import_onnx()
    model_path = Path(model) if isinstance(model, (str, Path)) else None
    if model_path is not None:
        model, loaded_normalizer = load_model(model_path)
        normalizer = normalizer if normalizer is not None else loaded_normalizer
    if type(model).__module__.startswith("ray.rllib"):  # a loaded RLModule: RLlib's defaults
        model = _RllibPolicy(model, _RllibActionConfig(), None)
    network = describe_policy(model, normalizer)
    env_id, trained_overrides = _env_of(model_path, model, env_id)
    env_kwargs: dict[str, Any] = {**trained_overrides, **overrides}
    if config is not None:
        env_kwargs["config"] = str(config)
    if action_type is not None:
        env_kwargs["action_type"] = action_type
    env = gym.make(env_id, **env_kwargs)
    try:
        robot = robot_interface(env, network.obs_dim, env_id)
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        provenance = str(model_path) if model_path is not None else f"a {network.source} model"
        files: list[Path] = []
        layout = {name: [start, stop] for name, start, stop in robot.layout}
        (out / LAYOUT_FILE).write_text(json.dumps(layout, indent=2) + "\n", encoding="utf-8")
        (out / SCENARIO_FILE).write_text(robot.scenario_toml, encoding="utf-8")
        files += [out / LAYOUT_FILE, out / SCENARIO_FILE]
        if "onnx" in formats:
            metadata = {
                "source": network.source,
                "env_id": env_id,
                "obs_layout": json.dumps(layout),
                "khepera_gym_version": khepera_gym.__version__,
            }
            onnx_model = build_onnx(network, metadata)
            (out / ONNX_FILE).write_bytes(onnx_model.SerializeToString())
            files.append(out / ONNX_FILE)
        if "c" in formats:
            files += write_c(network, robot, out, provenance)
            readme = _template("README.md").safe_substitute(
                env_id=env_id,
                source=network.source,
                version=khepera_gym.__version__,
                layout="\n".join(
                    f"| {_indices(start, stop, '–')} | `{name}` |"
                    for name, start, stop in robot.layout
                ),
            )
            (out / "README.md").write_text(readme, encoding="utf-8")
            files.append(out / "README.md")
        checks: dict[str, Any] = {}
        failures: list[str] = []
        if check:
            checks, failures = _check_export(model, normalizer, env, robot, out, formats, compiler)
        manifest = {
            "khepera_gym_version": khepera_gym.__version__,
            "model": provenance,
            "source": network.source,
            "env_id": env_id,
            "env_kwargs": {k: str(v) for k, v in env_kwargs.items()},
            "agent": robot.agent,
            "obs_dim": network.obs_dim,
            "action_dim": network.action_dim,
            "action_type": robot.action_type,
            "layers": [
                {"inputs": x.inputs, "outputs": x.outputs, "activation": x.activation}
                for x in network.layers
            ],
            "vecnormalize": network.normalization is not None,
            "randomised_constants_at_midpoint": {k: list(v) for k, v in robot.randomised.items()},
            "formats": list(formats),
            "checks": checks,
        }
        (out / MANIFEST_FILE).write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
        files.append(out / MANIFEST_FILE)
    finally:
        env.close()
    if failures:
        raise KheperaError(
            f"{out}: the exported {', '.join(failures)} differ from the Python policy and the "
            f"simulator by more than the tolerance: {checks}"
        )
    return ExportResult(out, files, network, robot, checks)


def _check_export(
    model: Any,
    normalizer: Any,
    env: gym.Env[Any, Any],
    robot: RobotInterface,
    out: Path,
    formats: Sequence[str],
    compiler: str,
) -> tuple[dict[str, Any], list[str]]:
    """Check figures, and what exceeds its tolerance."""
    act = _python_actions(model, normalizer)
    recording = record_rollouts(env, robot, act)
    expected = np.asarray(act(recording.observations), np.float64)
    checks: dict[str, Any] = {"observations": len(recording.observations)}
    failures = []
    if "onnx" in formats:
        got = onnx_actions(out / ONNX_FILE, recording.observations)
        checks["onnx_max_abs_error"] = float(np.max(np.abs(got - expected)))
        if checks["onnx_max_abs_error"] > PARITY_TOLERANCE:
            failures.append("ONNX actions")
    if "c" in formats:
        if shutil.which(compiler) is None:
            checks["c_skipped"] = f"no C compiler {compiler!r} on PATH"
        else:
            with tempfile.TemporaryDirectory() as build:
                for name in ("export_check.c", *C_SOURCES):
                    shutil.copy(out / name, build)
                for name in out.glob("*.h"):
                    shutil.copy(name, build)
                binary = compile_check_program(build, compiler)
                got = run_check_program(binary, "policy", recording.observations)
                built = run_check_program(binary, "observation", recording.input_rows)
            checks["c_max_abs_error"] = float(np.max(np.abs(got - expected)))
            checks["observation_max_abs_error"] = float(
                np.max(np.abs(built - recording.observations))
            )
            if checks["c_max_abs_error"] > PARITY_TOLERANCE:
                failures.append("C actions")
            if checks["observation_max_abs_error"] > OBSERVATION_TOLERANCE:
                failures.append("C observations")
    return checks, failures


# ----------------------------------------------------------------------------------------------
# Command line.


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``khepera-gym export``."""
    parser.add_argument(
        "model",
        help="an SB3 model.zip (vecnormalize.pkl and run.json beside it are used) or an "
        "RLlib checkpoint directory",
    )
    parser.add_argument(
        "--format",
        nargs="+",
        choices=FORMATS,
        default=["c"],
        help="c (policy.c, observation.c, a libkhepera program template) and/or onnx (c)",
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="output folder (export/ beside the model)"
    )
    parser.add_argument("--env", default=None, help="env id trained on (from run.json if absent)")
    parser.add_argument("--config", default=None, help="scenario trained on (name or TOML path)")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario override as in training (VALUE in TOML syntax), e.g. ir_floor_value=110",
    )
    parser.add_argument(
        "--action-type", choices=("wheels", "unicycle"), default=None, help="as in training"
    )
    parser.add_argument(
        "--no-check",
        action="store_true",
        help="skip measuring the exported files against the Python policy",
    )
    parser.add_argument("--cc", default="cc", help="C compiler of the check (cc)")


def _parse_override(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` with VALUE in TOML syntax, or a string when it is not TOML.

    Raises:
        ConfigError: No ``=`` or an empty key.
    """
    key, separator, value = text.partition("=")
    if not separator or not key.strip():
        raise ConfigError(f"--set takes KEY=VALUE, got {text!r}")
    try:
        return key.strip(), _toml_loads(f"value = {value.strip()}")["value"]
    except ValueError:  # tomllib.TOMLDecodeError is a ValueError
        return key.strip(), value.strip()


def run_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym export`` with parsed arguments."""
    model = Path(args.model)
    out = args.out if args.out is not None else model.resolve().parent / "export"
    overrides = dict(_parse_override(text) for text in args.set)
    result = export_policy(
        model,
        out,
        formats=args.format,
        env_id=args.env,
        config=args.config,
        action_type=args.action_type,
        check=not args.no_check,
        compiler=args.cc,
        **overrides,
    )
    agent = f" (one agent's block, as {result.robot.agent})" if result.robot.agent else ""
    print(
        f"exported the {result.network.source} policy for {result.robot.env_id}{agent} "
        f"to {result.out_dir}:"
    )
    for path in result.files:
        print(f"  {path.name}")
    for key, bounds in result.robot.randomised.items():
        print(f"note: {key} is a range {list(bounds)} in the scenario; the midpoint is baked in")
    checks = result.checks
    if "observations" in checks:
        print(f"checked on {checks['observations']} observations of seeded rollouts:")
    for key in ("onnx_max_abs_error", "c_max_abs_error", "observation_max_abs_error"):
        if key in checks:
            print(f"  {key.replace('_', ' ')}: {checks[key]:.3g}")
    if "c_skipped" in checks:
        print(f"  C check skipped: {checks['c_skipped']}")
    return 0


__all__ = [
    "FORMATS",
    "SUPPORTED_MODELS",
    "ActionTransform",
    "DenseLayer",
    "ExportResult",
    "ObservationNormalization",
    "PolicyNetwork",
    "Recording",
    "RobotInterface",
    "build_onnx",
    "compile_check_program",
    "describe_policy",
    "export_policy",
    "input_row",
    "load_model",
    "onnx_actions",
    "record_rollouts",
    "robot_interface",
    "run_check_program",
    "write_c",
]
