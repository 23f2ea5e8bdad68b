"""Threads and processes: batches stepped from two Python threads at once give the results they
give one after the other, and envs work in forked worker processes after the parent's rayon pool
has run."""

from __future__ import annotations

import multiprocessing
import threading

import gymnasium as gym
import numpy as np
from conftest import LATEST, random_actions

from khepera_gym import _core


def _run_batch(task: str, seed: int, steps: int) -> list[np.ndarray]:
    batch = _core.Batch(task, 64, num_threads=2)
    actions = random_actions(seed, steps, (64, batch.act_dim))
    trace = [batch.reset(seed)]
    for action in actions:
        obs, rewards, *_ = batch.step(action)
        trace += [obs, rewards]
    return trace


def test_two_batches_stepped_from_two_threads_match_sequential_runs() -> None:
    jobs = [("nav", 1, 150), ("avoid", 2, 150)]
    sequential = [_run_batch(*job) for job in jobs]
    threaded: list[list[np.ndarray] | None] = [None, None]

    def work(index: int) -> None:
        threaded[index] = _run_batch(*jobs[index])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for expected, got in zip(sequential, threaded, strict=True):
        assert got is not None
        for a, b in zip(expected, got, strict=True):
            np.testing.assert_array_equal(a, b)


def _child_rollout(queue: multiprocessing.Queue) -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=32, num_threads=2)
    obs, _ = envs.reset(seed=5)
    for action in random_actions(0, 20, (32, 2)):
        obs, *_ = envs.step(action)
    queue.put(obs)


def test_envs_work_in_a_forked_child_after_the_parents_pool_ran() -> None:
    parent = gym.make_vec(LATEST["nav"], num_envs=32, num_threads=2)  # starts a rayon pool here
    obs, _ = parent.reset(seed=5)
    for action in random_actions(0, 20, (32, 2)):
        obs, *_ = parent.step(action)
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_child_rollout, args=(queue,))
    child.start()
    child_obs = queue.get(timeout=60)
    child.join(timeout=60)
    assert child.exitcode == 0
    np.testing.assert_array_equal(child_obs, obs)


def test_async_vector_env_of_our_single_envs_matches_the_native_batch() -> None:
    envs = gym.vector.AsyncVectorEnv(
        [lambda: gym.make(LATEST["avoid"]) for _ in range(2)], context="fork"
    )
    native = gym.make_vec(LATEST["avoid"], num_envs=2, num_threads=1)
    a, _ = envs.reset(seed=9)
    b, _ = native.reset(seed=9)
    np.testing.assert_array_equal(a, b)
    for action in random_actions(3, 10, (2, 2)):
        a, *_ = envs.step(action)
        b, *_ = native.step(action)
        np.testing.assert_array_equal(a, b)
    envs.close()
