"""Resets by mask and the DISABLED autoreset mode of the native vector envs.

``reset(options={"reset_mask": mask})`` resets exactly the masked worlds, each as a full reset
would (world i with seed s + i), and leaves the others bit for bit as they were; with
``autoreset_mode=AutoresetMode.DISABLED`` nothing else resets a world, and stepping a world that
ended raises until it is reset. Gymnasium's own SyncVectorEnv is the reference for the semantics.
The tests that hold for every env run over every registered id of every version
(``conftest.ALL_IDS``).
"""

from __future__ import annotations

import copy
import pickle
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import ALL_IDS, LATEST, random_actions
from gymnasium.vector import AutoresetMode

from khepera_gym.envs import NavEnv
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.vector import KheperaVectorEnv, NavVectorEnv

#: Short episodes, so that several end within the compared steps.
SHORT_EPISODE = 25
MODES = [AutoresetMode.NEXT_STEP, AutoresetMode.DISABLED]
#: Worlds of the envs that replay :data:`FORCED_RESETS`.
NUM_WORLDS = 5
#: Masked resets forced at these steps, on top of the resets of worlds that ended: step →
#: (worlds, seed), the seed an int, None (streams continue) or a list of one seed per world.
#: World 4 is never among them.
FORCED_RESETS: dict[int, tuple[list[int], Any]] = {
    7: ([1, 3], 500),
    31: ([0], None),
    44: ([2, 3], [None, 9, 10, 2**64 - 1, 3]),
    60: ([0, 1, 2], 2**64 - 2),  # seeds wrap at 2**64 as in a full reset
}


def _mask(num_envs: int, worlds: list[int]) -> np.ndarray:
    mask = np.zeros(num_envs, dtype=bool)
    mask[worlds] = True
    return mask


def _world_seed(seed: Any, world: int) -> int | None:
    """The seed a full reset with ``seed`` gives world ``world``."""
    if seed is None or isinstance(seed, list):
        return None if seed is None else seed[world]
    return (seed + int(world)) % 2**64


def _disabled_env(num_envs: int = 4, **kwargs: Any) -> gym.vector.VectorEnv:
    return gym.make_vec(
        LATEST["nav"],
        num_envs=num_envs,
        num_threads=2,
        autoreset_mode=AutoresetMode.DISABLED,
        **kwargs,
    )


# --- the mode --------------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_autoreset_mode_defaults_to_next_step_and_is_shown_in_metadata(env_id: str) -> None:
    default = gym.make_vec(env_id, num_envs=2)
    disabled = gym.make_vec(env_id, num_envs=2, autoreset_mode=AutoresetMode.DISABLED)
    by_value = gym.make_vec(env_id, num_envs=2, autoreset_mode="Disabled")
    assert default.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert default.unwrapped.autoreset_mode is AutoresetMode.NEXT_STEP
    assert default.unwrapped._batch.autoreset
    for envs in (disabled, by_value):
        assert envs.metadata["autoreset_mode"] is AutoresetMode.DISABLED
        assert envs.unwrapped.autoreset_mode is AutoresetMode.DISABLED
        assert not envs.unwrapped._batch.autoreset
    # The instance's metadata is its own: the class and the next env keep NEXT_STEP.
    assert type(disabled).metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert gym.make_vec(env_id, num_envs=2).metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert disabled.spec.kwargs["autoreset_mode"] is AutoresetMode.DISABLED
    for envs in (default, disabled, by_value):
        envs.close()


@pytest.mark.parametrize("bad_mode", [AutoresetMode.SAME_STEP, "SameStep", "disabled", None, 1])
def test_unsupported_autoreset_mode_raises_config_error_listing_the_modes(bad_mode: Any) -> None:
    with pytest.raises(ConfigError, match=r"autoreset_mode must be one of .*NEXT_STEP.*DISABLED"):
        KheperaVectorEnv(2, autoreset_mode=bad_mode)


def test_same_step_error_points_to_gymnasiums_sync_vector_env() -> None:
    with pytest.raises(ConfigError, match="vectorization_mode='sync'"):
        gym.make_vec(LATEST["nav"], num_envs=2, autoreset_mode=AutoresetMode.SAME_STEP)


def test_disabled_mode_survives_pickling_and_deepcopy() -> None:
    envs = _disabled_env(3, max_steps=3)
    envs.reset(seed=0)
    for _ in range(3):
        envs.step(np.zeros((3, 2), np.float32))
    for clone in (pickle.loads(pickle.dumps(envs)), copy.deepcopy(envs)):
        assert clone.metadata["autoreset_mode"] is AutoresetMode.DISABLED
        with pytest.raises(KheperaError, match="world 0"):
            clone.step(np.zeros((3, 2), np.float32))
        clone.close()
    envs.close()


# --- stepping a finished world ------------------------------------------------------------


def test_stepping_a_finished_world_in_disabled_mode_raises_and_steps_nothing() -> None:
    num_envs = 4
    envs = _disabled_env(num_envs, max_steps=3)
    zeros = np.zeros((num_envs, 2), np.float32)
    with pytest.raises(KheperaError, match="never started"):
        envs.step(zeros)  # no reset yet
    envs.reset(seed=3)
    for _ in range(3):
        _, _, terminations, truncations, _ = envs.step(np.full((num_envs, 2), 0.5, np.float32))
    assert (terminations | truncations).all()
    poses, state = envs.unwrapped.poses(), envs.unwrapped.get_state()
    with pytest.raises(KheperaError, match="world 0: the episode has ended") as caught:
        envs.step(zeros)
    assert type(caught.value) is KheperaError  # not an input error
    np.testing.assert_array_equal(envs.unwrapped.poses(), poses)
    assert envs.unwrapped.get_state() == state  # nothing was stepped

    envs.reset(options={"reset_mask": _mask(num_envs, [0, 1, 3])})
    with pytest.raises(KheperaError, match="world 2: the episode has ended"):
        envs.step(zeros)
    envs.reset(options={"reset_mask": _mask(num_envs, [2])})
    _, rewards, terminations, truncations, _ = envs.step(zeros)
    assert not (terminations | truncations).any()
    assert np.count_nonzero(rewards) == num_envs  # real steps (an autoreset would give 0)
    envs.close()


def test_next_step_mode_still_autoresets_finished_worlds() -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=2, max_steps=2)
    first, _ = envs.reset(seed=8)
    zeros = np.zeros((2, 2), np.float32)
    envs.step(zeros)
    _, _, _, truncations, _ = envs.step(zeros)
    assert truncations.all()
    observations, rewards, terminations, truncations, _ = envs.step(zeros)  # the autoreset
    assert not (terminations | truncations).any() and not rewards.any()
    assert not np.array_equal(observations, first)  # streams continued: new episodes
    envs.close()


# --- masked resets ---------------------------------------------------------------------------


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_masked_reset_leaves_unmasked_worlds_bit_for_bit_unchanged(
    env_id: str, mode: AutoresetMode
) -> None:
    """Two envs step the same actions; one also resets some worlds by mask: every other world
    goes on exactly as in the run without those resets (world 4 is never masked)."""
    num_envs, seed, steps = NUM_WORLDS, 21, 80
    runs = [
        gym.make_vec(env_id, num_envs=num_envs, max_steps=SHORT_EPISODE, autoreset_mode=mode)
        for _ in range(2)
    ]
    reference, masked = runs
    actions = random_actions(seed, steps, (num_envs, *reference.single_action_space.shape))
    # Each run's current observations, as its last step or reset returned them.
    current = [envs.reset(seed=seed)[0] for envs in runs]
    touched = np.zeros(num_envs, dtype=bool)  # worlds of `masked` reset by a forced mask
    for step in range(steps):
        if step in FORCED_RESETS:
            worlds, forced_seed = FORCED_RESETS[step]
            forced = _mask(num_envs, worlds)
            options = {"reset_mask": forced}
            observations, infos = masked.reset(seed=forced_seed, options=options)
            assert infos == {}
            assert options["reset_mask"] is forced  # options are not modified
            np.testing.assert_array_equal(forced, _mask(num_envs, worlds))
            touched |= forced
            # The unmasked rows of a masked reset are the worlds' current observations.
            np.testing.assert_array_equal(observations[~touched], current[1][~touched])
            np.testing.assert_array_equal(observations[~touched], current[0][~touched])
            current[1] = observations
        outputs = [envs.step(actions[step]) for envs in runs]
        untouched = ~touched
        for reference_array, masked_array in zip(outputs[0][:4], outputs[1][:4], strict=True):
            np.testing.assert_array_equal(
                masked_array[untouched], reference_array[untouched], err_msg=f"step {step}"
            )
        np.testing.assert_array_equal(
            masked.unwrapped.poses()[untouched], reference.unwrapped.poses()[untouched]
        )
        for run, (envs, (observations, _, terminations, truncations, _)) in enumerate(
            zip(runs, outputs, strict=True)
        ):
            current[run] = observations
            ended = terminations | truncations
            if mode is AutoresetMode.DISABLED and ended.any():
                # Worlds that ended are reset by mask in both runs alike (streams continue).
                current[run] = envs.reset(options={"reset_mask": ended})[0]
    assert touched[:4].all() and not touched[4]
    for envs in runs:
        envs.close()


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_masked_world_equals_single_env_reset_with_seed_plus_index(
    env_id: str, mode: AutoresetMode
) -> None:
    """World i of the vector env and a single env replay the same actions through episode ends
    and forced masked resets: whenever world i is reset by mask with seed s (or a sequence, or
    None), the single env is reset with s + i (its entry, or None), and they stay bit for bit
    equal, observations, rewards, flags and episode statistics alike."""
    num_envs, seed, steps = NUM_WORLDS, 1234, 90
    envs = gym.make_vec(env_id, num_envs=num_envs, max_steps=SHORT_EPISODE, autoreset_mode=mode)
    singles = [gym.make(env_id, max_steps=SHORT_EPISODE).unwrapped for _ in range(num_envs)]
    actions = random_actions(seed, steps, (num_envs, *envs.single_action_space.shape))
    observations, _ = envs.reset(seed=seed)
    for index, env in enumerate(singles):
        np.testing.assert_array_equal(observations[index], env.reset(seed=seed + index)[0])
    single_ended = np.zeros(num_envs, dtype=bool)
    episodes_ended = masked_resets = 0
    for step in range(steps):
        reset_now = np.zeros(num_envs, dtype=bool)
        reset_seed: Any = None
        if mode is AutoresetMode.DISABLED:
            reset_now |= single_ended  # the caller resets the worlds that ended
        if step in FORCED_RESETS:
            worlds, reset_seed = FORCED_RESETS[step]
            reset_now |= _mask(num_envs, worlds)
        if reset_now.any():
            observations, _ = envs.reset(seed=reset_seed, options={"reset_mask": reset_now})
            for index in np.flatnonzero(reset_now):
                expected, _ = singles[index].reset(seed=_world_seed(reset_seed, index))
                np.testing.assert_array_equal(observations[index], expected)
                single_ended[index] = False
                masked_resets += 1
        observations, rewards, terminations, truncations, infos = envs.step(actions[step])
        for index, env in enumerate(singles):
            context = f"step {step}, world {index}"
            if single_ended[index]:  # NEXT_STEP: the batch resets this world, ignores its action
                expected, _ = env.reset()
                expected_reward, expected_terminated, expected_truncated = 0.0, False, False
                single_ended[index] = False
            else:
                expected, expected_reward, expected_terminated, expected_truncated, info = env.step(
                    actions[step, index]
                )
                single_ended[index] = expected_terminated or expected_truncated
                if single_ended[index]:
                    episodes_ended += 1
                    assert infos["_episode_stats"][index], context
                    for key, value in info["episode_stats"].items():
                        assert infos["episode_stats"][key][index] == value, (context, key)
            np.testing.assert_array_equal(observations[index], expected, err_msg=context)
            assert rewards[index] == np.float32(expected_reward), context
            assert terminations[index] == expected_terminated, context
            assert truncations[index] == expected_truncated, context
    assert episodes_ended >= num_envs and masked_resets >= len(FORCED_RESETS)
    envs.close()
    for env in singles:
        env.close()


@pytest.mark.parametrize("mode", MODES)
def test_masked_resets_match_gymnasiums_sync_vector_env(mode: AutoresetMode) -> None:
    """The same masked resets and actions on Gymnasium's SyncVectorEnv over the single env give
    bit for bit the same results, including the rows a masked reset leaves alone."""
    num_envs, seed, steps = NUM_WORLDS, 77, 70
    native = gym.make_vec(
        LATEST["nav"], num_envs=num_envs, max_steps=SHORT_EPISODE, autoreset_mode=mode
    )
    sync = gym.make_vec(
        LATEST["nav"],
        num_envs=num_envs,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        max_steps=SHORT_EPISODE,
    )
    assert sync.metadata["autoreset_mode"] == native.metadata["autoreset_mode"]
    actions = random_actions(seed, steps, (num_envs, 2))
    np.testing.assert_array_equal(native.reset(seed=seed)[0], sync.reset(seed=seed)[0])
    ended = np.zeros(num_envs, dtype=bool)
    for step in range(steps):
        reset_now = ended.copy() if mode is AutoresetMode.DISABLED else np.zeros(num_envs, bool)
        reset_seed: Any = None
        if step in FORCED_RESETS:
            worlds, reset_seed = FORCED_RESETS[step]
            reset_now |= _mask(num_envs, worlds)
            if isinstance(reset_seed, int):
                reset_seed %= 2**64 - num_envs  # SyncVectorEnv passes s + i on, without wrapping
        if reset_now.any():
            native_obs, native_info = native.reset(
                seed=reset_seed, options={"reset_mask": reset_now.copy()}
            )
            sync_obs, sync_info = sync.reset(
                seed=reset_seed, options={"reset_mask": reset_now.copy()}
            )
            np.testing.assert_array_equal(native_obs, sync_obs, err_msg=f"reset at step {step}")
            assert native_info == sync_info == {}
        native_out = native.step(actions[step])
        sync_out = sync.step(actions[step])
        for native_array, sync_array in zip(native_out[:4], sync_out[:4], strict=True):
            np.testing.assert_array_equal(native_array, sync_array, err_msg=f"step {step}")
        ended = native_out[2] | native_out[3]
    native.close()
    sync.close()


def test_all_true_mask_is_a_full_reset() -> None:
    num_envs = 3
    masked, full = _disabled_env(num_envs), _disabled_env(num_envs)
    everything = np.ones(num_envs, dtype=bool)
    # On the first reset too: it starts every world, seeded as a full reset.
    np.testing.assert_array_equal(
        masked.reset(seed=4, options={"reset_mask": everything})[0], full.reset(seed=4)[0]
    )
    masked.step(np.full((num_envs, 2), 0.3, np.float32))
    np.testing.assert_array_equal(
        masked.reset(seed=9, options={"reset_mask": everything})[0], full.reset(seed=9)[0]
    )
    assert masked.unwrapped.get_state() == full.unwrapped.get_state()
    masked.close()
    full.close()


def test_masked_reset_seeds_as_a_full_reset_does_including_wraparound() -> None:
    num_envs, seed = 4, 2**64 - 2  # worlds 2 and 3 get seeds 0 and 1
    full = _disabled_env(num_envs)
    full_observations, _ = full.reset(seed=seed)
    envs = _disabled_env(num_envs)
    envs.reset(seed=5)
    observations, _ = envs.reset(seed=seed, options={"reset_mask": _mask(num_envs, [0, 3])})
    np.testing.assert_array_equal(observations[[0, 3]], full_observations[[0, 3]])
    assert not np.array_equal(observations[1], full_observations[1])  # world 1 kept seed 6's
    single = NavEnv()
    np.testing.assert_array_equal(observations[3], single.reset(seed=1)[0])
    for env in (full, envs, single):
        env.close()


def test_masked_reset_before_the_first_reset_raises() -> None:
    envs = _disabled_env(3)
    with pytest.raises(KheperaError, match="before the first reset"):
        envs.reset(seed=0, options={"reset_mask": np.array([True, False, True])})
    with pytest.raises(KheperaError, match="never started"):  # still no world started
        envs.step(np.zeros((3, 2), np.float32))
    envs.close()


def test_other_reset_options_are_ignored_and_options_must_be_a_dict() -> None:
    envs = _disabled_env(2)
    plain, _ = envs.reset(seed=1)
    with_options, _ = envs.reset(seed=1, options={"something": 1})
    np.testing.assert_array_equal(plain, with_options)
    with pytest.raises(ConfigError, match="takes a dict or None, got list"):
        envs.reset(options=[("reset_mask", np.ones(2, bool))])
    envs.close()


@pytest.mark.parametrize(
    ("bad_mask", "problem"),
    [
        ([True, False, True, False], "must be a numpy array .* got list"),
        ((True, False, True, False), "must be a numpy array .* got tuple"),
        (None, "must be a numpy array .* got NoneType"),
        (np.array([1, 0, 1, 0]), "must have dtype bool, got dtype int64"),
        (np.array([1.0, 0.0, 1.0, 0.0]), "must have dtype bool, got dtype float64"),
        (np.ones((4, 1), bool), r"must have shape \(4,\) \(one per world\), got \(4, 1\)"),
        (np.ones(3, bool), r"must have shape \(4,\) \(one per world\), got \(3,\)"),
        (np.zeros(4, bool), "has no True value"),
    ],
    ids=["list", "tuple", "none", "int", "float", "column", "too-short", "all-false"],
)
def test_bad_reset_mask_raises_config_error_naming_the_problem(bad_mask: Any, problem: str) -> None:
    envs = NavVectorEnv(4, num_threads=1, autoreset_mode=AutoresetMode.DISABLED)
    envs.reset(seed=2)
    envs.step(np.full((4, 2), 0.4, np.float32))
    state = envs.get_state()
    with pytest.raises(
        ConfigError, match=r"reset\(options=\{\"reset_mask\": mask\}\): mask " + problem
    ):
        envs.reset(seed=0, options={"reset_mask": bad_mask})
    assert envs.get_state() == state  # nothing was reset
    envs.close()


def test_gymnasium_episode_statistics_wrapper_follows_masked_resets() -> None:
    """Gymnasium's RecordEpisodeStatistics reads the reset mask after the env's reset; the env
    leaves it in ``options``, so the wrapper's episode lengths and returns are the core's."""
    num_envs, steps = 4, 120
    envs = gym.wrappers.vector.RecordEpisodeStatistics(_disabled_env(num_envs, max_steps=30))
    actions = random_actions(3, steps, (num_envs, 2))
    envs.reset(seed=6)
    episodes = 0
    for step in range(steps):
        _, _, terminations, truncations, infos = envs.step(actions[step])
        ended = terminations | truncations
        if step == 10:
            ended[1] = True  # cut world 1's episode short: its next one starts from 0
        if not ended.any():
            continue
        if "episode" in infos:
            finished = infos["_episode"]
            np.testing.assert_array_equal(
                infos["episode"]["l"][finished], infos["episode_stats"]["length"][finished]
            )
            np.testing.assert_allclose(
                infos["episode"]["r"][finished],
                infos["episode_stats"]["return"][finished],
                rtol=1e-5,
                atol=1e-5,
            )
            episodes += int(np.count_nonzero(finished))
        envs.reset(options={"reset_mask": ended})
    assert episodes >= num_envs
    envs.close()
