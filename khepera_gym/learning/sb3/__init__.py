"""stable-baselines3 vector environments over the Rust batch: no DummyVecEnv, no subprocesses.

:func:`make_vec_env` gives an SB3 ``VecEnv`` whose rows are the N worlds of one ``_core.Batch``
(of any registered id); :func:`make_formation_vec_env` one whose rows
are the (world, follower) pairs of a Formation batch, so one policy drives every follower
(parameter sharing); :class:`SharedAgentsVecEnv` does the same for the agents of any multi-agent
task whose agents' observations have one length (``SharedAgentsVecEnv("consensus", 16)``).
:func:`load_policy` loads a model saved by ``khepera-gym train``.

SB3 semantics, and how they are met on a batch that autoresets on the *next* step:

* the batch is built without autoreset; when world i ends at step t (terminated or truncated),
  ``step_wait`` reads its statistics and calls ``batch.reset_world(i)`` at once, so step t
  returns the first observation of the new episode, with ``dones[i] = True`` and in
  ``infos[i]``: ``"terminal_observation"`` (the episode's true last observation),
  ``"TimeLimit.truncated"`` (truncated and not terminated), ``"is_success"`` and
  ``"episode_stats"`` (the Gymnasium env's statistics as Python scalars; on the rows of a
  :class:`SharedAgentsVecEnv`, each agent's own, the world's then under
  ``"world_episode_stats"``). Rows that did not end get an empty dict;
* ``reset_world(i)`` without a seed continues world i's own random stream, exactly as a single
  env's ``reset()`` after an episode does: with the same actions, row i of
  ``make_vec_env(id, n, seed=s)`` replays ``gym.make(id)`` reset with seed ``s + i`` and then
  reset without a seed after each episode, bit for bit, whatever ``num_threads``;
* ``seed(s)`` (SB3's convention) seeds world i with ``s + i`` at the next ``reset()`` only; a
  ``reset()`` without a pending seed continues every stream (the very first one draws a base
  seed from the operating system's entropy).

Threading and copies: ``step_wait`` and ``reset`` release the GIL inside the Rust core, which
steps the worlds on its own pool of ``num_threads`` threads; every returned array is fresh.
Units and frames are those of the envs (SI, robot frame x forward, y left). With
``render_mode="rgb_array"``, ``get_images()`` draws one frame per world in software (no display).
"""

from __future__ import annotations

try:
    import stable_baselines3  # noqa: F401
except ImportError as error:  # pragma: no cover - exercised only without the extra
    raise ImportError(
        "khepera_gym.learning.sb3 needs stable-baselines3: pip install 'khepera-gym[sb3]'"
    ) from error

from khepera_gym.learning.sb3.evaluate import (
    Evaluation,
    SuccessEvalCallback,
    evaluate_episodes,
    first_episode_stats,
)
from khepera_gym.learning.sb3.policy import (
    VECNORMALIZE_FILE,
    FrameStackPolicy,
    NormalizedPolicy,
    Predictor,
    RecurrentPolicy,
    algorithm_class,
    algorithm_of,
    as_predictor,
    load_policy,
)
from khepera_gym.learning.sb3.vec_env import (
    FormationFollowersVecEnv,
    KheperaSB3VecEnv,
    SharedAgentsVecEnv,
    make_formation_vec_env,
    make_vec_env,
    resolve_env_id,
    task_of,
)

__all__ = [
    "VECNORMALIZE_FILE",
    "Evaluation",
    "FormationFollowersVecEnv",
    "FrameStackPolicy",
    "KheperaSB3VecEnv",
    "NormalizedPolicy",
    "Predictor",
    "RecurrentPolicy",
    "SharedAgentsVecEnv",
    "SuccessEvalCallback",
    "algorithm_class",
    "algorithm_of",
    "as_predictor",
    "evaluate_episodes",
    "first_episode_stats",
    "load_policy",
    "make_formation_vec_env",
    "make_vec_env",
    "resolve_env_id",
    "task_of",
]
