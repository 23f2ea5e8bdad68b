"""Loading models trained by ``khepera-gym train``: the SB3 algorithm of a saved zip, its
``VecNormalize`` statistics and its memory (frame stacking, ``VecFrameStack``; or the LSTM state
of sb3-contrib's ``RecurrentPPO``) applied so that ``predict`` takes raw env observations.
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

from khepera_gym.errors import ConfigError, KheperaError

#: File next to a saved model holding its ``VecNormalize`` statistics (``khepera-gym train``).
VECNORMALIZE_FILE = "vecnormalize.pkl"
#: File next to a saved model describing its run (``khepera-gym train``); :func:`load_policy`
#: reads the hyperparameter ``frame_stack`` from it.
RUN_FILE = "run.json"
#: The recurrent algorithm of sb3-contrib that :func:`load_policy` recognises: its zip's
#: ``policy_class`` is a class of this module (its saved ``data`` otherwise looks like PPO's).
RECURRENT_POLICY_MODULE = "sb3_contrib.common.recurrent.policies"
#: Install hint for sb3-contrib (in the sb3 extra).
SB3_CONTRIB_EXTRA = "pip install 'khepera-gym[sb3]'"
#: SB3 algorithms that :func:`load_policy` recognises in a saved zip: (class name, an attribute
#: that only its saved ``data`` has), tried in order after ``RecurrentPPO``.
_ALGORITHM_MARKERS = (
    ("PPO", "clip_range"),
    ("SAC", "target_entropy"),
    ("TD3", "target_policy_noise"),
    ("A2C", "gae_lambda"),
)
_ALGORITHMS = ("RecurrentPPO", *(name for name, _ in _ALGORITHM_MARKERS))


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


def _observation_rows(
    observation: npt.NDArray[np.float32],
    obs_dim: int,
    normalizer: VecNormalize | None,
    takes: str,
) -> tuple[npt.NDArray[np.float32], bool]:
    """Raw observations (obs_dim,) or (N, obs_dim) as (N, obs_dim) rows, normalised with the
    training statistics when there are some, and whether a single one was given.

    Raises:
        ConfigError: Observations of another shape ("TAKES; got observations of shape ...").
    """
    rows = np.asarray(observation, dtype=np.float32)
    single = rows.ndim == 1
    rows = rows.reshape(1, -1) if single else rows
    if rows.ndim != 2 or rows.shape[1] != obs_dim:
        raise ConfigError(f"{takes}; got observations of shape {np.shape(observation)}")
    if normalizer is not None:
        rows = np.asarray(normalizer.normalize_obs(rows), dtype=np.float32)
    return rows, single


class FrameStackPolicy:
    """A model trained on the last ``n_stack`` observations (SB3's ``VecFrameStack``), fed the
    same stack from raw env observations.

    Like ``VecFrameStack``, the stack of a world starts as zeros at its episode's start, and every
    step shifts it by one observation, the newest last: ``[o(t-n+1), ..., o(t)]``. When the model
    was trained under ``VecNormalize`` too, each observation is normalised with the training
    statistics before it enters the stack (``VecFrameStack(VecNormalize(env))``, the order of
    ``khepera-gym train``).

    The stack is state: :meth:`reset` (called by :func:`khepera_gym.rollout.run_episodes` before
    its episodes) empties it, and ``predict``'s ``episode_start`` empties the rows of worlds whose
    episode starts with this observation, as SB3's recurrent policies take it.

    Args:
        model: The loaded SB3 model (its observation has ``n_stack`` times the env's length).
        n_stack: Observations per stack, >= 2.
        normalizer: The ``VecNormalize`` the model was trained under, or None.
    """

    def __init__(
        self, model: BaseAlgorithm, n_stack: int, normalizer: VecNormalize | None = None
    ) -> None:
        if isinstance(n_stack, bool) or not isinstance(n_stack, int) or n_stack < 2:
            raise ConfigError(f"frame_stack must be an integer >= 2 here, got {n_stack!r}")
        shape = model.observation_space.shape
        if shape is None or len(shape) != 1 or shape[0] % n_stack:
            raise ConfigError(
                f"the model's observation {shape} is not {n_stack} stacked observations"
            )
        self.model = model
        self.n_stack = n_stack
        self.normalizer = normalizer
        self.observation_space = model.observation_space
        self.action_space = model.action_space
        #: Length of one env observation.
        self.obs_dim = shape[0] // n_stack
        self._stack: npt.NDArray[np.float32] | None = None

    def reset(self) -> None:
        """Empties every world's stack: the next observation starts an episode."""
        self._stack = None

    def predict(
        self,
        observation: npt.NDArray[np.float32],
        state: tuple[npt.NDArray[Any], ...] | None = None,
        episode_start: npt.NDArray[np.bool_] | None = None,
        deterministic: bool = False,
    ) -> tuple[npt.NDArray[np.float32], tuple[npt.NDArray[Any], ...] | None]:
        """Actions for raw observations (obs_dim,) or (N, obs_dim), stacked with the previous
        ones of the same rows."""
        rows, single = _observation_rows(
            observation,
            self.obs_dim,
            self.normalizer,
            f"the model stacks {self.n_stack} observations of {self.obs_dim} values",
        )
        if self._stack is None or self._stack.shape[0] != rows.shape[0]:
            self._stack = np.zeros((rows.shape[0], self.n_stack * self.obs_dim), np.float32)
        if episode_start is not None:
            self._stack[np.asarray(episode_start, dtype=bool).reshape(-1)] = 0.0
        self._stack[:, : -self.obs_dim] = self._stack[:, self.obs_dim :].copy()
        self._stack[:, -self.obs_dim :] = rows
        stacked = self._stack[0] if single else self._stack.copy()
        actions, _ = self.model.predict(stacked, None, None, deterministic)
        return actions, None


class RecurrentPolicy:
    """An sb3-contrib ``RecurrentPPO`` model, carrying its LSTM state from step to step.

    ``predict`` passes each row's hidden and cell state (``(n_layers, N, H)`` arrays, SB3's
    ``state``) from one call to the next, as SB3's recurrent ``predict`` expects its caller to;
    the state starts at zeros, :meth:`reset` (called by :func:`khepera_gym.rollout.run_episodes`
    before its episodes) zeros every row's, and ``episode_start`` zeros the rows of worlds whose
    episode starts with this observation, as in training. When the model was trained under
    ``VecNormalize``, observations are normalised with the training statistics first.

    A ``state`` passed to ``predict`` (SB3's own convention, e.g. ``evaluate_policy``) is used
    instead of the carried one; the new state is returned and carried either way.

    Args:
        model: The loaded ``RecurrentPPO``.
        normalizer: The ``VecNormalize`` the model was trained under, or None.

    Raises:
        ConfigError: The model's observation is not a flat vector.
    """

    def __init__(self, model: BaseAlgorithm, normalizer: VecNormalize | None = None) -> None:
        shape = model.observation_space.shape
        if shape is None or len(shape) != 1:
            raise ConfigError(f"a recurrent policy on observations of shape {shape}: flat only")
        self.model = model
        self.normalizer = normalizer
        self.observation_space = model.observation_space
        self.action_space = model.action_space
        #: Length of one env observation.
        self.obs_dim = int(shape[0])
        self._state: tuple[npt.NDArray[Any], ...] | None = None

    def reset(self) -> None:
        """Zeros every world's LSTM state: the next observation starts an episode."""
        self._state = None

    def predict(
        self,
        observation: npt.NDArray[np.float32],
        state: tuple[npt.NDArray[Any], ...] | None = None,
        episode_start: npt.NDArray[np.bool_] | None = None,
        deterministic: bool = False,
    ) -> tuple[npt.NDArray[np.float32], tuple[npt.NDArray[Any], ...] | None]:
        """Actions for raw observations (obs_dim,) or (N, obs_dim), and the new LSTM state."""
        rows, single = _observation_rows(
            observation,
            self.obs_dim,
            self.normalizer,
            f"the recurrent model takes observations of {self.obs_dim} values",
        )
        carried = self._state if state is None else state
        if carried is not None and carried[0].shape[1] != rows.shape[0]:
            carried = None  # another number of worlds: they all start
        starts = None
        if episode_start is not None:
            starts = np.asarray(episode_start, dtype=bool).reshape(-1)
        actions, self._state = self.model.predict(rows, carried, starts, deterministic)  # type: ignore[arg-type]
        return (actions[0] if single else actions), self._state


def is_recurrent(model: Any) -> bool:
    """Whether ``model`` is an sb3-contrib ``RecurrentPPO`` (without importing sb3-contrib)."""
    return type(model).__name__ == "RecurrentPPO" and type(model).__module__.startswith(
        "sb3_contrib"
    )


def as_predictor(
    model: BaseAlgorithm, normalizer: VecNormalize | None = None, frame_stack: int = 1
) -> Any:
    """The model as a :class:`Predictor` on raw env observations: with its ``VecNormalize``
    statistics (:class:`NormalizedPolicy`), its frame stacking (:class:`FrameStackPolicy`) or its
    LSTM state (:class:`RecurrentPolicy`) when it was trained with them; the model itself
    otherwise.

    Raises:
        ConfigError: A recurrent model with ``frame_stack`` > 1 (its memory is its LSTM).
    """
    if is_recurrent(model):
        if frame_stack > 1:
            raise ConfigError(
                "a RecurrentPPO model keeps its memory in its LSTM: train it without frame_stack"
            )
        return RecurrentPolicy(model, normalizer)
    if frame_stack > 1:
        return FrameStackPolicy(model, frame_stack, normalizer)
    if normalizer is not None:
        return NormalizedPolicy(model, normalizer)
    return model


def frame_stack_of(path: str | Path) -> int:
    """The ``frame_stack`` hyperparameter in the ``run.json`` next to a model zip (1 without it).

    Raises:
        KheperaError: The run.json is there but unreadable, or its frame_stack is not an
            integer >= 1.
    """
    run_path = Path(path).parent / RUN_FILE
    if not run_path.exists():
        return 1
    try:
        run = json.loads(run_path.read_text(encoding="utf-8"))
        value = run.get("hyperparams", {}).get("frame_stack", 1)
    except (OSError, ValueError, AttributeError) as error:
        raise KheperaError(f"{run_path}: cannot read the run's frame_stack ({error})") from error
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise KheperaError(f"{run_path}: frame_stack must be an integer >= 1, got {value!r}")
    return value


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
    policy_class = data.get("policy_class") if isinstance(data, dict) else None
    if isinstance(policy_class, dict) and policy_class.get("__module__") == RECURRENT_POLICY_MODULE:
        return "RecurrentPPO"
    # The saved attributes tell the algorithms apart (PPO and A2C share their policy class).
    for name, attribute in _ALGORITHM_MARKERS:
        if attribute in data:
            return name
    raise KheperaError(f"{path}: cannot tell which algorithm saved it (known: {_ALGORITHMS})")


def algorithm_class(name: str) -> type[BaseAlgorithm]:
    """The class of an algorithm :func:`algorithm_of` names: stable-baselines3's, or
    sb3-contrib's ``RecurrentPPO``.

    Raises:
        ImportError: sb3-contrib is missing for ``RecurrentPPO`` (the message names the pip
            command).
    """
    if name == "RecurrentPPO":
        try:
            from sb3_contrib import RecurrentPPO
        except ImportError as error:
            raise ImportError(
                f"a RecurrentPPO model needs sb3-contrib: {SB3_CONTRIB_EXTRA}"
            ) from error
        return RecurrentPPO  # type: ignore[no-any-return]
    import stable_baselines3

    return getattr(stable_baselines3, name)  # type: ignore[no-any-return]


def _no_schedule(_progress: float) -> float:
    """A training schedule for a model loaded to act: it never trains."""
    return 0.0


#: What :func:`load_policy` loads in place of a model's training schedules. SB3 saves them as
#: cloudpickled functions, whose code objects do not load on another Python minor version (a
#: model trained on 3.11 acting on 3.10); acting needs none of them.
INFERENCE_OBJECTS: dict[str, Any] = {"lr_schedule": _no_schedule, "clip_range": _no_schedule}


def load_policy(path: str | Path, device: str = "cpu") -> Predictor:
    """Loads a model saved by ``khepera-gym train`` (or any SB3 ``model.save``) for inference.

    The algorithm is read from the zip. When a ``vecnormalize.pkl`` lies next to it (training
    with ``normalize = true``), the result normalises raw observations with those statistics
    (:class:`NormalizedPolicy`); when the ``run.json`` next to it has ``frame_stack`` > 1, it
    stacks the observations as training did (:class:`FrameStackPolicy`, whose ``reset()``
    starts new episodes); an sb3-contrib ``RecurrentPPO`` carries its LSTM state
    (:class:`RecurrentPolicy`, reset the same way); otherwise it is the SB3 model itself. Either
    way ``predict(obs, deterministic=True)`` takes raw env observations, single or batched.
    The training schedules are not loaded (:data:`INFERENCE_OBJECTS`), so a model saved on
    another Python version acts the same; train a loaded model with SB3's own ``load``.

    Args:
        path: The model's ``.zip``.
        device: Torch device for the network ("cpu" by default: these MLPs gain nothing on GPU).

    Raises:
        KheperaError: The file is not an SB3 zip of a known algorithm.
        ImportError: A RecurrentPPO model without sb3-contrib (the message names the pip
            command).
    """
    path = Path(path)
    algorithm = algorithm_class(algorithm_of(path))
    model: BaseAlgorithm = algorithm.load(path, device=device, custom_objects=INFERENCE_OBJECTS)
    stats_path = path.parent / VECNORMALIZE_FILE
    normalizer: VecNormalize | None = None
    if stats_path.exists():
        with stats_path.open("rb") as stats_file:
            normalizer = pickle.load(stats_file)
        normalizer.training = False
    return as_predictor(model, normalizer, frame_stack_of(path))  # type: ignore[no-any-return]


__all__ = [
    "INFERENCE_OBJECTS",
    "RECURRENT_POLICY_MODULE",
    "RUN_FILE",
    "VECNORMALIZE_FILE",
    "FrameStackPolicy",
    "NormalizedPolicy",
    "Predictor",
    "RecurrentPolicy",
    "algorithm_class",
    "algorithm_of",
    "as_predictor",
    "frame_stack_of",
    "is_recurrent",
    "load_policy",
]
