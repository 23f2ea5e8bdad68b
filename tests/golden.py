"""Golden digests: seeded trajectories of every registered env, hashed bit for bit.

A change that must not alter behaviour (a redesign, a speed-up, a new version beside the old
ones) is checked against digests recorded before it: ``tests/test_golden.py`` replays every case
and compares. The cases come from the registries, not from a list kept by hand: every registered
Gymnasium id (single env and native vector env), every PettingZoo module, and the built-in
scenes that exercise other paths (the swarm's grid, split by world and by robot).

Record (only when a change of behaviour is intended, with a new env version)::

    python tests/golden.py --write            # every case
    python tests/golden.py --write --only v2  # the cases whose name contains "v2"

Each digest is SHA-256 over the observations, rewards, terminations, truncations and the true
poses of every step, as raw bytes: any difference in any bit changes it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import khepera_gym
import khepera_gym.pettingzoo
from khepera_gym.config import tomllib
from khepera_gym.registration import registered_ids

#: Where the digests are kept.
GOLDEN_PATH = Path(__file__).parent / "data" / "golden_digests.json"
#: Steps of a single env (several episodes end and reset within them at max_steps = 120).
SINGLE_STEPS = 300
#: Steps of a vector env and of a PettingZoo env.
MULTI_STEPS = 120
#: Episode length for the cases, so that resets happen within the recorded steps.
EPISODE_STEPS = 120


class _Digest:
    """SHA-256 over arrays' dtypes, shapes and bytes."""

    def __init__(self) -> None:
        self._hash = hashlib.sha256()

    def add(self, *values: Any) -> None:
        for value in values:
            array = np.ascontiguousarray(np.asarray(value))
            self._hash.update(f"{array.dtype.str}{array.shape}".encode())
            self._hash.update(array.tobytes())

    def hexdigest(self) -> str:
        return self._hash.hexdigest()


def _actions(space: gym.spaces.Space, rng: np.random.Generator) -> np.ndarray:
    """A uniform action of a Box space from ``rng`` (bounded spaces only)."""
    assert isinstance(space, gym.spaces.Box), space
    low = np.maximum(space.low, -1.0)
    high = np.minimum(space.high, 1.0)
    return rng.uniform(low, high).astype(space.dtype)


def single_env_digest(env_id: str) -> str:
    """A single env reset with seed 7 and stepped with seeded uniform actions, resetting (without
    a seed) after each episode."""
    env = gym.make(env_id, max_steps=EPISODE_STEPS)
    rng = np.random.default_rng(11)
    digest = _Digest()
    obs, _ = env.reset(seed=7)
    digest.add(obs, env.unwrapped.poses())
    for _ in range(SINGLE_STEPS):
        obs, reward, terminated, truncated, _ = env.step(_actions(env.action_space, rng))
        digest.add(obs, np.float64(reward), terminated, truncated, env.unwrapped.poses())
        if terminated or truncated:
            obs, _ = env.reset()
            digest.add(obs, env.unwrapped.poses())
    env.close()
    return digest.hexdigest()


def vector_env_digest(env_id: str) -> str:
    """Three worlds of the native vector env on two threads, seed 5, next-step autoreset."""
    envs = gym.make_vec(env_id, num_envs=3, num_threads=2, max_steps=EPISODE_STEPS)
    rng = np.random.default_rng(13)
    digest = _Digest()
    obs, _ = envs.reset(seed=5)
    digest.add(obs, envs.unwrapped.poses())
    for _ in range(MULTI_STEPS):
        obs, rewards, terminations, truncations, _ = envs.step(_actions(envs.action_space, rng))
        digest.add(obs, rewards, terminations, truncations, envs.unwrapped.poses())
    envs.close()
    return digest.hexdigest()


def parallel_env_digest(make: Callable[..., Any], **kwargs: Any) -> str:
    """A PettingZoo parallel env, seed 3, agents acting with seeded uniform actions (in the
    env's agent order), reset without a seed when every agent is done."""
    env = make(max_steps=EPISODE_STEPS, **kwargs)
    rng = np.random.default_rng(17)
    digest = _Digest()
    observations, _ = env.reset(seed=3)
    digest.add(*[observations[a] for a in env.agents], env.unwrapped.poses())
    for _ in range(MULTI_STEPS):
        if not env.agents:
            observations, _ = env.reset()
            digest.add(*[observations[a] for a in env.agents], env.unwrapped.poses())
        actions = {a: _actions(env.action_space(a), rng) for a in env.agents}
        observations, rewards, terminations, truncations, _ = env.step(actions)
        for agent in sorted(observations):
            digest.add(
                observations[agent],
                np.float64(rewards[agent]),
                terminations[agent],
                truncations[agent],
            )
        digest.add(env.unwrapped.poses())
    env.close()
    return digest.hexdigest()


def swarm_digest(module: Any, split: str) -> str:
    """A 1,000-robot swarm scene (``config="swarm"``) on two threads through the array env,
    40 steps, split by world or by robot."""
    env = module.array_env(config="swarm", split=split, num_threads=2)
    rng = np.random.default_rng(19)
    digest = _Digest()
    obs, _ = env.reset(seed=1)
    digest.add(obs, env.poses())
    shape = (env.num_envs, env.n_agents, env.single_action_space.shape[0])
    for _ in range(40):
        actions = rng.uniform(-1.0, 1.0, shape).astype(np.float32)
        obs, rewards, terminations, truncations, _ = env.step(actions)
        digest.add(obs, rewards, terminations, truncations, env.poses())
    return digest.hexdigest()


def cases() -> Iterator[tuple[str, Callable[[], str]]]:
    """Every golden case: (name, function computing its digest), from the registries."""
    for ids in registered_ids().values():
        for env_id in ids:
            yield f"single:{env_id}", lambda env_id=env_id: single_env_digest(env_id)
            yield f"vector:{env_id}", lambda env_id=env_id: vector_env_digest(env_id)
    for name, module in khepera_gym.pettingzoo.modules().items():
        yield f"parallel:{name}", lambda m=module: parallel_env_digest(m.parallel_env)
        if name.startswith("multinav_") and hasattr(module, "array_env"):
            version = int(name.rpartition("_v")[2])
            defaults = tomllib.loads(khepera_gym.default_config("multinav", version))
            # A world split by robot needs the tyre drive (v0's kinematic drive refuses it).
            traction = defaults["physics"]["drive"] == "traction"
            for split in ("world", "robot") if traction else ("world",):
                yield (
                    f"swarm:{name}:{split}",
                    lambda m=module, s=split: swarm_digest(m, s),
                )


def load() -> dict[str, str]:
    """The recorded digests (empty when none are recorded yet)."""
    if not GOLDEN_PATH.exists():
        return {}
    return json.loads(GOLDEN_PATH.read_text())["digests"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="record into " + str(GOLDEN_PATH))
    parser.add_argument("--only", default="", help="only the cases whose name contains this")
    args = parser.parse_args(argv)
    recorded = load()
    digests = dict(recorded)
    changed = 0
    for name, compute in cases():
        if args.only not in name:
            continue
        digest = compute()
        status = (
            "same" if recorded.get(name) == digest else "NEW" if name not in recorded else "CHANGED"
        )
        changed += status != "same"
        print(f"{status:8s} {name} {digest[:16]}")
        digests[name] = digest
    if args.write:
        GOLDEN_PATH.parent.mkdir(parents=True, exist_ok=True)
        payload = {
            "about": "tests/golden.py: SHA-256 of seeded trajectories of every registered env",
            "khepera_gym": khepera_gym.__version__,
            "digests": dict(sorted(digests.items())),
        }
        GOLDEN_PATH.write_text(json.dumps(payload, indent=1) + "\n")
        print(f"wrote {GOLDEN_PATH}")
    return 1 if changed and not args.write else 0


if __name__ == "__main__":
    sys.exit(main())
