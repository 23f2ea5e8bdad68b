"""Things saved with khepera_gym 0.1.0's layout load and behave the same after the package was
laid out in layers (0.2.0).

``tests/data/before_0_2/`` was written by the commit before the redesign (707870a): a pickled
native vector env, a pickled PettingZoo env, a pickled SB3 ``VecEnv`` (whose class lived at
``khepera_gym.sb3.vec_env``, now ``khepera_gym.learning.sb3.vec_env``) and a model saved by
``khepera-gym train`` with its ``vecnormalize.pkl``; ``expected.json`` holds what each did next
then (observations after fixed actions, the model's actions on fixed observations).
"""

from __future__ import annotations

import json
import pickle
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data" / "before_0_2"

# The fixtures were saved with NumPy 2 (the NumPy of `make test`), whose pickles name
# numpy._core; NumPy 1.x (the floors leg has 1.24) cannot read any NumPy 2 pickle, ours or not.
pytestmark = pytest.mark.skipif(
    np.lib.NumpyVersion(np.__version__) < "2.0.0",
    reason="fixtures pickled with NumPy 2, which NumPy 1.x cannot read",
)
EXPECTED = json.loads((DATA / "expected.json").read_text())
#: The same actions, as torch computes them on any CPU. Its matrix products sum in an order
#: that depends on the CPU's vector width, so a float32 output can differ by the roundings of
#: its sums, not by a fraction of itself (an Intel Xeon with AVX-512 FP16 put one action of
#: -0.00334 a relative 1.1e-6 from what an AMD EPYC saved). Worst case, a sum of n terms rounds
#: within n * 2^-24 of the sum of their magnitudes. This model (18 inputs, normalised and
#: clipped at 10; two tanh layers of 64; row sums of |weights| at most 3.4, 9.8 and 0.082):
#: layer 1 within 18 * 6e-8 * 34 = 3.6e-5, layer 2 within 64 * 6e-8 * 9.8 = 3.7e-5 plus 9.8
#: times layer 1's (tanh's slope is at most 1), the action within 0.082 times that plus its
#: own 64 * 6e-8 * 0.082: about 3.3e-5 in all.
SAME_ACTIONS = {"rtol": 0.0, "atol": 5e-5}


def test_a_pickled_vector_env_continues_as_it_did() -> None:
    envs = pickle.loads((DATA / "nav_vector_env.pkl").read_bytes())
    observations = envs.step(np.full((4, 2), 0.5, dtype=np.float32))[0]
    assert np.array_equal(observations, np.asarray(EXPECTED["nav_vector_env_next_obs"], np.float32))


def test_a_pickled_pettingzoo_env_continues_as_it_did() -> None:
    env = pickle.loads((DATA / "formation_v3_parallel_env.pkl").read_bytes())
    assert type(env).__module__ == "khepera_gym.pettingzoo.formation_v3"
    actions = {agent: np.array([0.3, 0.4], dtype=np.float32) for agent in env.agents}
    observations = env.step(actions)[0]
    for agent, expected in EXPECTED["formation_v3_next_obs"].items():
        assert np.array_equal(observations[agent], np.asarray(expected, np.float32))


def test_a_pickled_sb3_vec_env_loads_through_its_old_module_path() -> None:
    pytest.importorskip("stable_baselines3")
    already = "khepera_gym.sb3.vec_env" in sys.modules
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        venv = pickle.loads((DATA / "sb3_vec_env.pkl").read_bytes())
    moved = [str(w.message) for w in caught if issubclass(w.category, FutureWarning)]
    assert already or any("khepera_gym.learning.sb3" in message for message in moved), moved
    assert type(venv).__module__ == "khepera_gym.learning.sb3.vec_env"
    venv.step_async(np.zeros((2, 2), dtype=np.float32))
    observations = venv.step_wait()[0]
    assert np.array_equal(observations, np.asarray(EXPECTED["sb3_vec_env_next_obs"], np.float32))


def test_a_model_saved_by_train_loads_and_acts_as_it_did() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from khepera_gym.learning.sb3.policy import INFERENCE_OBJECTS, load_policy

    probe = np.load(DATA / "probe_obs.npy")
    # Saved on Python 3.11; the floors leg loads it on 3.10, where SB3's cloudpickled training
    # schedules would not load: acting needs none of them.
    model = PPO.load(DATA / "ppo_nav" / "model.zip", device="cpu", custom_objects=INFERENCE_OBJECTS)
    np.testing.assert_allclose(
        model.predict(probe, deterministic=True)[0], EXPECTED["ppo_nav_actions"], **SAME_ACTIONS
    )
    policy = load_policy(DATA / "ppo_nav" / "model.zip")  # with its vecnormalize.pkl
    np.testing.assert_allclose(
        policy.predict(probe, deterministic=True)[0],
        EXPECTED["ppo_nav_policy_actions"],
        **SAME_ACTIONS,
    )
