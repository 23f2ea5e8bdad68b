"""Runs one hostile case in this process and says what happened.

An outcome is a short label and a detail: ``built`` (the env built, reset and stepped with
finite rewards and observations inside its space), ``refused: ConfigError`` (or another error
the case's kind may raise: a ``KheperaError`` subclass, ``MemoryError``), or ``FAIL: ...``
(another exception type, a non-finite reward, an observation outside its space, a frame of the
wrong shape). Crashes, aborts and hangs cannot be seen from here: the campaign runs each case
in a forked process and reports those.
"""

from __future__ import annotations

import math
import os
import struct
import tempfile
import warnings
import zlib
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from khepera_gym.errors import ActionError, ConfigError, KheperaError, StateError

from .cases import pettingzoo_module

#: Steps a built env takes.
STEPS = 12
#: The errors each kind of case may raise (anything else is a failure).
EXPECTED: dict[str, tuple[type[BaseException], ...]] = {
    "make": (ConfigError, MemoryError),
    "file": (ConfigError, MemoryError),
    "vector": (ConfigError, MemoryError),
    "pettingzoo": (ConfigError, MemoryError),
    "array": (ConfigError, MemoryError),
    "reset": (ConfigError,),
    "scene": (ConfigError,),
    "state": (StateError,),
    "action": (ActionError,),
    "render": (ConfigError,),
}


class BrokenPromiseError(Exception):
    """A broken promise: the message says which."""


def toml_value(value: Any) -> str:
    """TOML for Python values (what TOML cannot say becomes a string)."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return (
            "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        )
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f'"{k}" = {toml_value(v)}' for k, v in value.items()) + "}"
    if isinstance(value, bytes):
        value = value.decode("latin-1")
    text = value if isinstance(value, str) else repr(value)
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def png_bytes(spec: dict[str, Any]) -> bytes:
    """A PNG of ``spec``'s size, or one broken as ``spec["kind"]`` says."""
    width, height = int(spec["width"]), int(spec["height"])

    def chunk(tag: bytes, data: bytes) -> bytes:
        body = tag + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
    signature = b"\x89PNG\r\n\x1a\n"
    if spec["kind"] == "huge":  # a header that claims a huge image, and no data
        return signature + header + chunk(b"IEND", b"")
    rows = b"".join(b"\x00" + bytes((x * 7 + y) % 256 for x in range(width)) for y in range(height))
    data = signature + header + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    if spec["kind"] == "truncated":
        return data[: len(data) // 2]
    if spec["kind"] == "garbage":
        return b"not a png" + data[8:40]
    return data


def materialise(value: Any, folder: Path) -> Any:
    """``value`` with every ``{"__png__": spec}`` replaced by the path of such a file."""
    if isinstance(value, dict):
        if "__png__" in value:
            spec = value["__png__"]
            path = folder / f"floor_{len(list(folder.iterdir()))}.png"
            if spec["kind"] != "missing":
                path.write_bytes(png_bytes(spec))
            return str(path)
        return {k: materialise(v, folder) for k, v in value.items()}
    if isinstance(value, list):
        return [materialise(v, folder) for v in value]
    return value


def check_observation(obs: Any, low: np.ndarray, high: np.ndarray, where: str) -> None:
    obs = np.asarray(obs)
    if obs.dtype != np.float32:
        raise BrokenPromiseError(f"{where}: observation dtype {obs.dtype}")
    if not np.isfinite(obs).all():
        raise BrokenPromiseError(f"{where}: non-finite observation {obs[~np.isfinite(obs)][:4]}")
    if not (np.all(obs >= low) and np.all(obs <= high)):
        bad = np.flatnonzero(~((obs >= low) & (obs <= high)).ravel())[:4]
        raise BrokenPromiseError(f"{where}: observation outside its space at {bad.tolist()}")


def check_reward(reward: Any, where: str) -> None:
    if not np.isfinite(np.asarray(reward, dtype=np.float64)).all():
        raise BrokenPromiseError(f"{where}: non-finite reward {reward}")


def run_single(env: gym.Env, rng: np.random.Generator) -> None:
    space = env.observation_space
    obs, _ = env.reset(seed=int(rng.integers(2**32)))
    check_observation(obs, space.low, space.high, "reset")
    for step in range(STEPS):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, reward, terminated, truncated, _ = env.step(action)
        check_observation(obs, space.low, space.high, f"step {step}")
        check_reward(reward, f"step {step}")
        if terminated or truncated:
            obs, _ = env.reset()
            check_observation(obs, space.low, space.high, "reset after the end")


def run_vector(envs: Any, rng: np.random.Generator) -> None:
    space = envs.single_observation_space
    obs, _ = envs.reset(seed=int(rng.integers(2**32)))
    check_observation(obs, space.low, space.high, "reset")
    disabled = getattr(envs, "autoreset_mode", None) == gym.vector.AutoresetMode.DISABLED
    for step in range(STEPS):
        action = rng.uniform(-1, 1, envs.action_space.shape).astype(np.float32)
        obs, reward, terminated, truncated, _ = envs.step(action)
        check_observation(obs, space.low, space.high, f"step {step}")
        check_reward(reward, f"step {step}")
        ended = np.asarray(terminated) | np.asarray(truncated)
        if disabled and ended.any():
            envs.reset(options={"reset_mask": ended})


def run_parallel(env: Any, rng: np.random.Generator) -> None:
    observations, _ = env.reset(seed=int(rng.integers(2**32)))
    for step in range(STEPS):
        for agent, obs in observations.items():
            space = env.observation_space(agent)
            check_observation(obs, space.low, space.high, f"step {step} {agent}")
        if not env.agents:
            break
        actions = {
            a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in env.agents
        }
        observations, rewards, _, _, _ = env.step(actions)
        check_reward(list(rewards.values()), f"step {step}")


def run_array(env: Any, rng: np.random.Generator) -> None:
    space = env.single_observation_space
    obs, _ = env.reset(seed=int(rng.integers(2**32)))
    for step in range(STEPS):
        check_observation(obs, space.low, space.high, f"step {step}")
        shape = (env.num_envs, env.n_agents, *env.single_action_space.shape)
        obs, rewards, *_ = env.step(rng.uniform(-1, 1, shape).astype(np.float32))
        check_reward(rewards, f"step {step}")


def default_env(case: dict[str, Any], **kwargs: Any) -> tuple[Any, str]:
    """A default env of the case's face (and its kind: single, vector, pettingzoo)."""
    face = case["face"]
    if face == "pettingzoo":
        return pettingzoo_module(case["target"]).module.parallel_env(**kwargs), face
    if face == "vector":
        return gym.make_vec(case["target"], num_envs=case["num_envs"], **kwargs), face
    return gym.make(case["target"], **kwargs), face


def run_built(env: Any, face: str, rng: np.random.Generator) -> None:
    {"single": run_single, "vector": run_vector, "pettingzoo": run_parallel}[face](env, rng)


def hostile_action(kind: str, shape: tuple[int, ...]) -> Any:
    return {
        "nan": np.full(shape, np.nan, np.float32),
        "inf": np.full(shape, np.inf),
        "huge": np.full(shape, 1e300),
        "shape": np.zeros((*shape, 2), np.float32),
        "strings": np.full(shape, "1"),
        "none": None,
        "object": np.full(shape, object(), dtype=object),
        "valid": np.zeros(shape, np.float32),
        "list": np.zeros(shape).tolist(),
    }[kind]


def run_case(case: dict[str, Any]) -> tuple[str, str]:
    """Runs ``case``: (outcome, detail); an outcome starting with ``FAIL`` is a broken
    promise."""
    rng = np.random.default_rng(case["rng"])
    kind = case["kind"]
    with tempfile.TemporaryDirectory(prefix="hostile-") as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        folder = Path(tmp)
        try:
            what = execute(case, kind, folder, rng)
        except BrokenPromiseError as failure:
            return "FAIL: broken promise", str(failure)
        except EXPECTED[kind] as error:
            return f"refused: {type(error).__name__}", str(error)[:300]
        except KheperaError as error:
            return f"FAIL: {type(error).__name__} (expected {_names(kind)})", str(error)[:300]
        except Exception as error:
            return f"FAIL: {type(error).__name__}", str(error)[:300]
        except BaseException as error:  # pyo3's PanicException
            if isinstance(error, (KeyboardInterrupt, SystemExit)):
                raise
            return f"FAIL: {type(error).__name__}", str(error)[:300]
    return what, ""


def _names(kind: str) -> str:
    return " or ".join(c.__name__ for c in EXPECTED[kind])


def execute(case: dict[str, Any], kind: str, folder: Path, rng: np.random.Generator) -> str:
    if kind in ("make", "vector"):
        kwargs = materialise(case["kwargs"], folder)
        if kind == "make":
            env, face = gym.make(case["target"], **kwargs), "single"
        else:
            env, face = gym.make_vec(case["target"], **kwargs), "vector"
        run_built(env, face, rng)
        return "built"
    if kind == "file":
        text = "".join(
            f"[{section}]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in keys.items())
            for section, keys in materialise(case["sections"], folder).items()
        )
        path = folder / "scenario.toml"
        data = text.encode("utf-8", "surrogatepass")
        mangle = case["mangle"]
        if mangle == "truncate":
            data = data[: len(data) // 2]
        elif mangle == "junk":
            data += b"\n[[x]\n= ="
        elif mangle == "duplicate":
            data += data
        elif mangle == "bytes":
            data = b"\xff\xfe" + data
        path.write_bytes(data)
        run_built(gym.make(case["target"], config=str(path)), "single", rng)
        return "built"
    if kind in ("pettingzoo", "array"):
        module = pettingzoo_module(case["target"]).module
        kwargs = materialise(case["kwargs"], folder)
        if kind == "array":
            env = module.array_env(**kwargs)
            run_array(env, rng)
        else:
            run_parallel(module.parallel_env(**kwargs), rng)
        return "built"
    if kind == "render":
        env, face = default_env(case, render_mode="rgb_array", frame_size=case["frame_size"])
        env.reset(seed=0)
        frame = env.render()
        if not (isinstance(frame, np.ndarray) and frame.ndim == 3 and frame.dtype == np.uint8):
            raise BrokenPromiseError(f"render() gave {type(frame).__name__}")
        return "built"
    env, face = default_env(case)
    if kind == "reset":
        if face == "pettingzoo":
            out = env.reset(seed=case["reset_seed"], options=case["options"])
        else:
            out = env.reset(seed=case["reset_seed"], options=case["options"])
        if face != "pettingzoo":
            space = env.single_observation_space if face == "vector" else env.observation_space
            check_observation(out[0], space.low, space.high, "reset")
        run_built(env, face, rng)
        return "reset"
    if kind == "scene":
        scene = (
            env.unwrapped.scene(case["scene_index"])
            if face == "single"
            else env.scene(case["scene_index"])
        )
        if not isinstance(scene, dict):
            raise BrokenPromiseError(f"scene() gave {type(scene).__name__}")
        return "scene"
    if kind == "state":
        target = env.unwrapped if face == "single" else env
        env.reset(seed=1)
        state = target.get_state()
        state = mangle_state(case["mangle"], state, case, rng)
        target.set_state(state)
        run_built(env, face, rng)
        return "restored"
    if kind == "action":
        env.reset(seed=2)
        if face == "pettingzoo":
            agent = env.agents[0]
            actions = {a: np.zeros(env.action_space(a).shape, np.float32) for a in env.agents}
            actions[agent] = hostile_action(case["action"], env.action_space(agent).shape)
            env.step(actions)
        else:
            env.step(hostile_action(case["action"], env.action_space.shape))
        run_built(env, face, rng)
        return "stepped"
    raise BrokenPromiseError(f"unknown case kind {kind}")


def mangle_state(how: str, state: bytes, case: dict[str, Any], rng: np.random.Generator) -> Any:
    if how == "truncate":
        return state[: int(rng.integers(0, len(state)))]
    if how == "flip":
        data = bytearray(state)
        data[int(rng.integers(0, len(data)))] ^= 1 << int(rng.integers(0, 8))
        return bytes(data)
    if how == "append":
        return state + b"\x00\x01"
    if how == "empty":
        return b""
    if how == "other":
        other, _ = default_env({**case, "num_envs": case["num_envs"] + 1})
        other = other.unwrapped if case["face"] == "single" else other
        other.reset(seed=3)
        return other.get_state()
    if how == "random":
        return os.urandom(int(rng.integers(0, 4096)))
    if how == "type":
        return ["not", "bytes"]
    return state


__all__ = ["EXPECTED", "BrokenPromiseError", "run_case", "toml_value"]
