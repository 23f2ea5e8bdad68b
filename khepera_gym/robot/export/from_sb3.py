"""stable-baselines3 models to the exporter's
:class:`~khepera_gym.robot.export.network.PolicyNetwork`.

Supported: PPO and A2C with ``MlpPolicy`` (the deterministic action is the Gaussian mean, clipped to
the action space, as ``predict(deterministic=True)`` gives it; the Gaussian's σ is kept for
sampled actions), SAC and TD3 (DDPG is a TD3) with
``MlpPolicy`` (the actor, tanh-squashed, rescaled to the action bounds as SB3's ``unscale_action``
does), with the ``VecNormalize`` observation statistics when the model was trained under one, and
its frame stack when it was trained on stacked observations (a
:class:`khepera_gym.learning.sb3.FrameStackPolicy`, as ``load_policy`` gives a ``frame_stack`` run);
and sb3-contrib's RecurrentPPO with ``MlpLstmPolicy`` (the actor's LSTM, ``lstm_actor``, then its
dense layers: the Gaussian's mean clipped as PPO's, its state carried by
:class:`khepera_gym.learning.sb3.RecurrentPolicy`). Zips are loaded with
:func:`khepera_gym.learning.sb3.load_policy` (which also picks up a ``vecnormalize.pkl`` beside
them). stable-baselines3 and sb3-contrib are imported when called.
Threading: none.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.robot.export.network import (
    ActionTransform,
    LstmLayer,
    ObservationNormalization,
    PolicyNetwork,
    unsupported_model,
)
from khepera_gym.robot.export.torch_layers import check_spaces, dense_layers

#: Install hint for loading an SB3 zip.
SB3_EXTRA = "pip install 'khepera-gym[sb3]'"


def is_sb3_model(model: Any) -> bool:
    """Whether ``model`` is an SB3 algorithm or :class:`khepera_gym.learning.sb3.NormalizedPolicy`
    (checked by module, so that stable-baselines3 need not be installed)."""
    module = type(model).__module__
    wrapped = module.startswith("khepera_gym.learning.sb3") and type(model).__name__ in (
        "NormalizedPolicy",
        "FrameStackPolicy",
        "RecurrentPolicy",
    )
    return wrapped or module.startswith(("stable_baselines3", "sb3_contrib"))


def load_sb3_zip(path: Path) -> tuple[Any, Any]:
    """(model, ``VecNormalize`` or None) of an SB3 zip and the ``vecnormalize.pkl`` beside it;
    the model of a run trained with ``frame_stack`` is its
    :class:`khepera_gym.learning.sb3.FrameStackPolicy` (which holds the statistics too).

    Raises:
        ImportError: stable-baselines3 is not installed (the message names the pip command).
        ConfigError: The zip is not an SB3 model of a known algorithm.
    """
    try:
        importlib.import_module("stable_baselines3")
        from khepera_gym.learning import sb3
    except ImportError as error:
        raise ImportError(f"{path} is a stable-baselines3 model: {SB3_EXTRA}") from error
    try:
        policy = sb3.load_policy(path, device="cpu")
    except KheperaError as error:
        raise unsupported_model(f"{path} ({error})") from error
    if isinstance(policy, (sb3.FrameStackPolicy, sb3.RecurrentPolicy)):
        return policy, policy.normalizer
    if isinstance(policy, sb3.NormalizedPolicy):
        return policy.model, policy.normalizer
    return policy, None


def describe_sb3(model: Any, normalizer: Any) -> PolicyNetwork:
    """The :class:`PolicyNetwork` of an SB3 model (or a ``NormalizedPolicy``,
    ``FrameStackPolicy`` or ``RecurrentPolicy``, whose statistics win over ``normalizer``), or of
    an sb3-contrib ``RecurrentPPO``.

    Raises:
        ConfigError: Another algorithm or policy class, gSDE, or layers the writers lack.
    """
    frame_stack = 1
    if type(model).__name__ == "FrameStackPolicy":
        frame_stack = int(model.n_stack)
        model, normalizer = model.model, model.normalizer
    if type(model).__name__ in ("NormalizedPolicy", "RecurrentPolicy"):
        model, normalizer = model.model, model.normalizer
    from stable_baselines3 import A2C, PPO, SAC, TD3
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor
    from torch import nn

    from khepera_gym.learning.sb3.policy import is_recurrent

    if is_recurrent(model):
        return _describe_recurrent(model, normalizer, frame_stack)
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
        if policy.squash_output:
            raise unsupported_model(f"a {name} whose actions are squashed (squash_output=True)")
        modules = [*policy.mlp_extractor.policy_net, policy.action_net]
        ones = np.ones(action_dim, np.float32)
        action = ActionTransform(ones, np.zeros(action_dim, np.float32), low, high)
        # The Gaussian's σ, one learned number per action value (DiagGaussianDistribution).
        # gSDE's noise is a function of the state (StateDependentNoiseDistribution): its mean
        # action is the same network's, but its noise is not exported.
        action_std = (
            None
            if policy.use_sde
            else np.exp(policy.log_std.detach().cpu().numpy()).astype(np.float32)
        )
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


def _describe_recurrent(model: Any, normalizer: Any, frame_stack: int) -> PolicyNetwork:
    """The :class:`PolicyNetwork` of an sb3-contrib ``RecurrentPPO``: the actor's LSTM
    (``lstm_actor``), the actor's dense layers and ``action_net``, the Gaussian's mean clipped
    to the action space.

    Raises:
        ConfigError: Another policy class, gSDE, or an LSTM the writers do not implement
            (bidirectional, projected, batch-first or with dropout between layers: sb3-contrib
            makes none of these by default).
    """
    from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor

    name = "sb3-contrib RecurrentPPO"
    policy = model.policy
    if not isinstance(policy, RecurrentActorCriticPolicy) or not isinstance(
        policy.pi_features_extractor, FlattenExtractor
    ):
        raise unsupported_model(f"a {name} with {type(policy).__name__}")
    if policy.use_sde:
        raise unsupported_model(f"a {name} trained with gSDE (use_sde=True)")
    if frame_stack != 1:
        raise unsupported_model(f"a {name} on stacked observations (its memory is its LSTM)")
    obs_dim, action_dim = check_spaces(model.observation_space, model.action_space, name)
    lstm = policy.lstm_actor
    if lstm.bidirectional or lstm.proj_size or lstm.batch_first or lstm.dropout:
        raise unsupported_model(
            f"a {name} whose LSTM is bidirectional, projected, batch-first or has dropout"
        )

    def weights(attribute: str, rows: int) -> npt.NDArray[np.float32]:
        tensor = getattr(lstm, attribute, None)
        if tensor is None:  # bias=False
            return np.zeros(rows, np.float32)
        return tensor.detach().cpu().numpy().astype(np.float32)

    gates = 4 * lstm.hidden_size
    layers = tuple(
        LstmLayer(
            weights(f"weight_ih_l{k}", gates),
            weights(f"weight_hh_l{k}", gates),
            weights(f"bias_ih_l{k}", gates),
            weights(f"bias_hh_l{k}", gates),
        )
        for k in range(lstm.num_layers)
    )
    low = model.action_space.low.astype(np.float32)
    high = model.action_space.high.astype(np.float32)
    modules = [*policy.mlp_extractor.policy_net, policy.action_net]
    ones = np.ones(action_dim, np.float32)
    return PolicyNetwork(
        source=name,
        obs_dim=obs_dim,
        action_dim=action_dim,
        normalization=_sb3_normalization(normalizer, obs_dim),
        layers=tuple(dense_layers(modules, f"the {name} policy")),
        action=ActionTransform(ones, np.zeros(action_dim, np.float32), low, high),
        action_std=np.exp(policy.log_std.detach().cpu().numpy()).astype(np.float32),
        lstm=layers,
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
