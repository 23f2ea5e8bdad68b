"""stable-baselines3 models to the exporter's :class:`~khepera_gym.export.network.PolicyNetwork`.

Supported: PPO and A2C with ``MlpPolicy`` (the deterministic action is the Gaussian mean, clipped to
the action space, as ``predict(deterministic=True)`` gives it; the Gaussian's σ is kept for
sampled actions), SAC and TD3 (DDPG is a TD3) with
``MlpPolicy`` (the actor, tanh-squashed, rescaled to the action bounds as SB3's ``unscale_action``
does), with the ``VecNormalize`` observation statistics when the model was trained under one, and
its frame stack when it was trained on stacked observations (a
:class:`khepera_gym.sb3.FrameStackPolicy`, as ``load_policy`` gives a ``frame_stack`` run). Zips are
loaded with :func:`khepera_gym.sb3.load_policy` (which also picks up a ``vecnormalize.pkl`` beside
them). stable-baselines3 is imported when called.
Threading: none.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import numpy as np

from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.export.network import (
    ActionTransform,
    ObservationNormalization,
    PolicyNetwork,
    unsupported_model,
)
from khepera_gym.export.torch_layers import check_spaces, dense_layers

#: Install hint for loading an SB3 zip.
SB3_EXTRA = "pip install 'khepera-gym[sb3]'"


def is_sb3_model(model: Any) -> bool:
    """Whether ``model`` is an SB3 algorithm or :class:`khepera_gym.sb3.NormalizedPolicy`
    (checked by module, so that stable-baselines3 need not be installed)."""
    module = type(model).__module__
    wrapped = module.startswith("khepera_gym.sb3") and type(model).__name__ in (
        "NormalizedPolicy",
        "FrameStackPolicy",
    )
    return wrapped or module.startswith("stable_baselines3")


def load_sb3_zip(path: Path) -> tuple[Any, Any]:
    """(model, ``VecNormalize`` or None) of an SB3 zip and the ``vecnormalize.pkl`` beside it;
    the model of a run trained with ``frame_stack`` is its
    :class:`khepera_gym.sb3.FrameStackPolicy` (which holds the statistics too).

    Raises:
        ImportError: stable-baselines3 is not installed (the message names the pip command).
        ConfigError: The zip is not an SB3 model of a known algorithm.
    """
    try:
        importlib.import_module("stable_baselines3")
        from khepera_gym import sb3
    except ImportError as error:
        raise ImportError(f"{path} is a stable-baselines3 model: {SB3_EXTRA}") from error
    try:
        policy = sb3.load_policy(path, device="cpu")
    except KheperaError as error:
        raise unsupported_model(f"{path} ({error})") from error
    if isinstance(policy, sb3.FrameStackPolicy):
        return policy, policy.normalizer
    if isinstance(policy, sb3.NormalizedPolicy):
        return policy.model, policy.normalizer
    return policy, None


def describe_sb3(model: Any, normalizer: Any) -> PolicyNetwork:
    """The :class:`PolicyNetwork` of an SB3 model (or a ``NormalizedPolicy`` or
    ``FrameStackPolicy``, whose statistics win over ``normalizer``).

    Raises:
        ConfigError: Another algorithm or policy class, gSDE, or layers the writers lack.
    """
    frame_stack = 1
    if type(model).__name__ == "FrameStackPolicy":
        frame_stack = int(model.n_stack)
        model, normalizer = model.model, model.normalizer
    if type(model).__name__ == "NormalizedPolicy":
        model, normalizer = model.model, model.normalizer
    from stable_baselines3 import A2C, PPO, SAC, TD3
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor
    from torch import nn

    name = f"stable-baselines3 {type(model).__name__}"
    if not isinstance(model, (PPO, A2C, SAC, TD3)):
        raise unsupported_model(f"a {name} model")
    input_dim, action_dim = check_spaces(model.observation_space, model.action_space, name)
    if input_dim % frame_stack:
        raise ConfigError(
            f"the {name} takes {input_dim} values, not {frame_stack} stacked observations"
        )
    obs_dim = input_dim // frame_stack
    policy = model.policy
    low = model.action_space.low.astype(np.float32)
    high = model.action_space.high.astype(np.float32)
    if isinstance(model, (PPO, A2C)):
        if not isinstance(policy, ActorCriticPolicy) or not isinstance(
            policy.pi_features_extractor, FlattenExtractor
        ):
            raise unsupported_model(f"a {name} with {type(policy).__name__}")
        if policy.use_sde:
            raise unsupported_model(f"a {name} trained with gSDE (use_sde=True)")
        modules = [*policy.mlp_extractor.policy_net, policy.action_net]
        ones = np.ones(action_dim, np.float32)
        action = ActionTransform(ones, np.zeros(action_dim, np.float32), low, high)
        # The Gaussian's σ, one learned number per action value (DiagGaussianDistribution).
        action_std = np.exp(policy.log_std.detach().cpu().numpy()).astype(np.float32)
    else:
        actor = policy.actor
        if not isinstance(actor.features_extractor, FlattenExtractor):
            raise unsupported_model(f"a {name} with {type(policy).__name__}")
        if getattr(actor, "use_sde", False):
            raise unsupported_model(f"a {name} trained with gSDE (use_sde=True)")
        # SAC: the mode of the tanh-squashed Gaussian; TD3's actor ends with Tanh itself.
        modules = [*actor.latent_pi, actor.mu, nn.Tanh()] if isinstance(model, SAC) else [*actor.mu]
        # SB3's unscale_action: low + 0.5 * (y + 1) * (high - low).
        scale = (0.5 * (high - low)).astype(np.float32)
        action = ActionTransform(scale, (low + scale).astype(np.float32), None, None)
        action_std = None
    layers = dense_layers(modules, f"the {name} policy")
    if isinstance(model, (SAC, TD3)) and (not layers or layers[-1].activation != "tanh"):
        raise unsupported_model(f"a {name} whose actor does not end in tanh")
    return PolicyNetwork(
        source=name,
        obs_dim=obs_dim,
        action_dim=action_dim,
        normalization=_sb3_normalization(normalizer, obs_dim),
        layers=tuple(layers),
        action=action,
        frame_stack=frame_stack,
        action_std=action_std,
    )


def _sb3_normalization(normalizer: Any, obs_dim: int) -> ObservationNormalization | None:
    """The statistics of a ``VecNormalize`` that normalises observations, else None."""
    if normalizer is None or not getattr(normalizer, "norm_obs", False):
        return None
    stats = normalizer.obs_rms
    if isinstance(stats, dict):
        raise unsupported_model("a VecNormalize with dict observations")
    mean = np.asarray(stats.mean, np.float64)
    variance = np.asarray(stats.var, np.float64)
    if mean.shape != (obs_dim,) or variance.shape != (obs_dim,):
        raise ConfigError(
            f"the VecNormalize statistics have shape {mean.shape}, the policy takes ({obs_dim},)"
        )
    return ObservationNormalization(
        mean, variance, float(normalizer.epsilon), float(normalizer.clip_obs)
    )


__all__ = ["SB3_EXTRA", "describe_sb3", "is_sb3_model", "load_sb3_zip"]
