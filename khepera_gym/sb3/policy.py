"""Loading models trained by ``khepera-gym train``: the SB3 algorithm of a saved zip, and its
``VecNormalize`` statistics applied so that ``predict`` takes raw env observations.
"""

from __future__ import annotations

import json
import pickle
import zipfile
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from khepera_gym.errors import KheperaError

#: File next to a saved model holding its ``VecNormalize`` statistics (``khepera-gym train``).
VECNORMALIZE_FILE = "vecnormalize.pkl"
#: SB3 algorithms that :func:`load_policy` recognises in a saved zip: (class name, an attribute
#: that only its saved ``data`` has), tried in order.
_ALGORITHM_MARKERS = (
    ("PPO", "clip_range"),
    ("SAC", "target_entropy"),
    ("TD3", "target_policy_noise"),
    ("A2C", "gae_lambda"),
)
_ALGORITHMS = tuple(name for name, _ in _ALGORITHM_MARKERS)


class Predictor(Protocol):
    """What :func:`load_policy` returns: SB3's ``predict`` on raw env observations."""

    observation_space: gym.spaces.Space[Any]
    action_space: gym.spaces.Space[Any]

    def predict(
        self,
        observation: npt.NDArray[np.float32],
        state: tuple[npt.NDArray[Any], ...] | None = None,
        episode_start: npt.NDArray[np.bool_] | None = None,
        deterministic: bool = False,
    ) -> tuple[npt.NDArray[np.float32], tuple[npt.NDArray[Any], ...] | None]: ...


class NormalizedPolicy:
    """A model trained under ``VecNormalize``, applying its saved observation statistics.

    ``predict(obs)`` normalises raw env observations with the training statistics (frozen) and
    calls the model's ``predict``, so it takes what the env gives, like an unnormalised model.

    Args:
        model: The loaded SB3 model.
        normalizer: The ``VecNormalize`` whose ``obs_rms`` the model was trained with.
    """

    def __init__(self, model: BaseAlgorithm, normalizer: VecNormalize) -> None:
        self.model = model
        self.normalizer = normalizer
        self.observation_space = model.observation_space
        self.action_space = model.action_space

    def predict(
        self,
        observation: npt.NDArray[np.float32],
        state: tuple[npt.NDArray[Any], ...] | None = None,
        episode_start: npt.NDArray[np.bool_] | None = None,
        deterministic: bool = False,
    ) -> tuple[npt.NDArray[np.float32], tuple[npt.NDArray[Any], ...] | None]:
        """Actions for raw observations of shape (obs_dim,) or (N, obs_dim)."""
        normalized = self.normalizer.normalize_obs(np.asarray(observation, dtype=np.float32))
        return self.model.predict(normalized, state, episode_start, deterministic)  # type: ignore[arg-type]


def algorithm_of(path: str | Path) -> str:
    """The SB3 algorithm class name ("PPO", "SAC", ...) that saved the zip at ``path``.

    Raises:
        KheperaError: The file is not an SB3 zip of a known algorithm.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
    except (OSError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as error:
        raise KheperaError(f"{path}: not a stable-baselines3 model zip ({error})") from error
    # The saved attributes tell the algorithms apart (PPO and A2C share their policy class).
    for name, attribute in _ALGORITHM_MARKERS:
        if attribute in data:
            return name
    raise KheperaError(f"{path}: cannot tell which algorithm saved it (known: {_ALGORITHMS})")


def load_policy(path: str | Path, device: str = "cpu") -> Predictor:
    """Loads a model saved by ``khepera-gym train`` (or any SB3 ``model.save``) for inference.

    The algorithm is read from the zip. When a ``vecnormalize.pkl`` lies next to it (training
    with ``normalize = true``), the result normalises raw observations with those statistics
    (:class:`NormalizedPolicy`); otherwise it is the SB3 model itself. Either way
    ``predict(obs, deterministic=True)`` takes raw env observations, single or batched.

    Args:
        path: The model's ``.zip``.
        device: Torch device for the network ("cpu" by default: these MLPs gain nothing on GPU).

    Raises:
        KheperaError: The file is not an SB3 zip of a known algorithm.
    """
    import stable_baselines3

    path = Path(path)
    algorithm = getattr(stable_baselines3, algorithm_of(path))
    model: BaseAlgorithm = algorithm.load(path, device=device)
    stats_path = path.parent / VECNORMALIZE_FILE
    if stats_path.exists():
        with stats_path.open("rb") as stats_file:
            normalizer: VecNormalize = pickle.load(stats_file)
        normalizer.training = False
        return NormalizedPolicy(model, normalizer)
    return model


__all__ = ["VECNORMALIZE_FILE", "NormalizedPolicy", "Predictor", "algorithm_of", "load_policy"]
