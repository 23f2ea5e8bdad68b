"""Ray RLlib PPO checkpoints to the exporter's
:class:`~khepera_gym.robot.export.network.PolicyNetwork`.

Supported: checkpoints of RLlib's new API stack (an algorithm's directory with one single-agent
``default_policy`` module, or one RLModule's directory) with the default torch MLP RLModule of
PPO and a diagonal Gaussian action distribution. The deterministic action is the mean of that
Gaussian, then RLlib's module-to-env handling (``NormalizeAndClipActions``: unsquashed from
[-1, 1] to the action bounds by default, or clipped). A checkpoint whose env-to-module pipeline
changes the observation (e.g. a mean-std filter) is refused. The env id and ``env_config`` the
algorithm was configured with are read back, so the export knows the env.

ray is imported when a checkpoint is loaded (the ``rllib`` extra). Threading: none.
"""

from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym.robot.export.network import (
    ActionTransform,
    DenseLayer,
    PolicyNetwork,
    unsupported_model,
)
from khepera_gym.robot.export.torch_layers import check_spaces, dense_layers

#: Install hint for loading an RLlib checkpoint.
RLLIB_EXTRA = "pip install 'khepera-gym[rllib]'"


@dataclasses.dataclass(frozen=True)
class RllibActionConfig:
    """RLlib's module-to-env action handling (``NormalizeAndClipActions``); RLlib's defaults."""

    normalize_actions: bool = True
    clip_actions: bool = False


@dataclasses.dataclass
class RllibPolicy:
    """An RLModule loaded from a checkpoint with its action handling, for inference."""

    module: Any
    action_config: RllibActionConfig
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
    """RLlib's ``RLModule`` class; ImportError naming the pip command without ray."""
    try:
        from ray.rllib.core.rl_module.rl_module import RLModule
    except ImportError as error:
        raise ImportError(
            f"exporting an RLlib checkpoint needs Ray RLlib: {RLLIB_EXTRA} "
            "(or pip install 'ray[rllib]')"
        ) from error
    return RLModule


def _connector_specs(path: Path) -> list[tuple[str, dict[str, Any]]]:
    """(class name, kwargs) of the connectors in a pipeline's ``class_and_ctor_args.pkl``."""
    with path.open("rb") as spec_file:
        spec = pickle.load(spec_file)
    _, kwargs = spec["ctor_args_and_kwargs"]
    return [(cls.__name__, dict(kw)) for cls, _, kw in kwargs.get("connectors", [])]


def load_rllib(path: Path) -> RllibPolicy:
    """An RLlib checkpoint: an algorithm's directory or one RLModule's.

    Raises:
        ConfigError: Not a checkpoint, several modules, or an observation-changing connector.
        ImportError: ray is not installed (the message names the pip command).
    """
    module_dir = path
    action_config = RllibActionConfig()
    env_id, env_config = None, {}
    if (path / "rllib_checkpoint.json").exists() and (path / "learner_group").is_dir():
        modules = path / "learner_group" / "learner" / "rl_module"
        candidates = sorted(p for p in modules.iterdir() if (p / "module_state.pkl").exists())
        if [p.name for p in candidates] != ["default_policy"]:
            raise unsupported_model(
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
                raise unsupported_model(
                    f"{path}: an RLlib policy whose observations pass through {extra}"
                )
        to_env = runner / "module_to_env_connector" / "class_and_ctor_args.pkl"
        if to_env.exists():
            for name, kwargs in _connector_specs(to_env):
                if name == "NormalizeAndClipActions":
                    action_config = RllibActionConfig(
                        bool(kwargs.get("normalize_actions", True)),
                        bool(kwargs.get("clip_actions", False)),
                    )
        env_id, env_config = _rllib_env(path)
    elif not (path / "module_state.pkl").exists():
        raise unsupported_model(f"{path} (a directory that is not an RLlib checkpoint)")
    rl_module = _import_rllib()
    module = rl_module.from_checkpoint(module_dir)
    return RllibPolicy(module, action_config, env_id, env_config)


def _rllib_env(path: Path) -> tuple[str | None, dict[str, Any]]:
    """The env id (when a string) and ``env_config`` an RLlib algorithm checkpoint was
    configured with."""
    try:
        with (path / "class_and_ctor_args.pkl").open("rb") as spec_file:
            spec = pickle.load(spec_file)
        config = spec["ctor_args_and_kwargs"][0][0]
    except (OSError, KeyError, IndexError, TypeError, pickle.UnpicklingError):
        return None, {}
    get = config.get if isinstance(config, dict) else lambda key: getattr(config, key, None)
    env, env_config = get("env"), get("env_config")
    return (env if isinstance(env, str) else None), dict(env_config or {})


def describe_rllib_module(module: Any, action_config: RllibActionConfig) -> PolicyNetwork:
    """The :class:`PolicyNetwork` of RLlib's default PPO RLModule with its action handling.

    Raises:
        ConfigError: Another module, a recurrent one, another action distribution.
    """
    name = f"RLlib {type(module).__name__}"
    encoder = getattr(module, "encoder", None)
    head = getattr(module, "pi", None)
    if encoder is None or head is None or not hasattr(module, "get_inference_action_dist_cls"):
        raise unsupported_model(f"an {name} (not RLlib's default PPO module)")
    if module.is_stateful():
        raise unsupported_model(f"an {name} with memory (LSTM)")
    obs_dim, action_dim = check_spaces(module.observation_space, module.action_space, name)
    dist_name = module.get_inference_action_dist_cls().__name__
    if dist_name != "TorchDiagGaussian":
        raise unsupported_model(f"an {name} with a {dist_name} action distribution")
    actor = getattr(encoder, "actor_encoder", None) or getattr(encoder, "encoder", None)
    parts = [getattr(getattr(part, "net", None), "mlp", None) for part in (actor, head)]
    if any(part is None for part in parts):
        raise unsupported_model(f"an {name} whose encoder or head is not RLlib's MLP")
    layers = dense_layers(parts, f"the {name}")
    last = layers[-1]
    if last.outputs == 2 * action_dim and last.activation == "identity":
        # TorchDiagGaussian's inputs are (mean, log_std); the deterministic action is the mean.
        layers[-1] = DenseLayer(last.weight[:action_dim].copy(), last.bias[:action_dim].copy())
    elif last.outputs != action_dim:
        raise unsupported_model(f"an {name} whose head gives {last.outputs} values")
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


def is_rllib_module(model: Any) -> bool:
    """Whether ``model`` is a loaded RLlib RLModule (checked by module: ray need not be
    installed)."""
    return type(model).__module__.startswith("ray.rllib")


__all__ = [
    "RLLIB_EXTRA",
    "RllibActionConfig",
    "RllibPolicy",
    "describe_rllib_module",
    "is_rllib_module",
    "load_rllib",
]
