"""``khepera-gym export``: the exported C and ONNX policies compute the Python policy's actions,
the C observation builder reproduces the simulator's observation from the raw readings, the C
wheel command reproduces the simulator's wheel speeds in K-Team units, the robot program template
is valid C, and bad input fails with messages that say what to do.

Parity is measured on observations recorded from seeded env rollouts (a heuristic driving, with
a share of random actions), with freshly initialised networks whose output layer is scaled up so
that their actions span the action space and get clipped: parity needs no trained policy, but it
does need actions that are not all near zero. The C code is compiled with the system compiler
(``cc -O2 -std=c99 -Wall -Wextra -Werror``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import pytest

pytest.importorskip(
    "stable_baselines3", reason="needs the sb3 extra: pip install 'khepera-gym[sb3]'"
)
pytest.importorskip("onnx", reason="needs the export extra: pip install 'khepera-gym[export]'")

import onnx
import torch
from conftest import LATEST
from stable_baselines3 import A2C, DQN, PPO, SAC, TD3
from stable_baselines3.common.vec_env import VecNormalize
from torch import nn

import khepera_gym
from khepera_gym import cli
from khepera_gym.baselines import Braitenberg
from khepera_gym.envs import avoid_heuristic, formation_follower_heuristic, nav_heuristic
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.learning.sb3 import NormalizedPolicy, make_formation_vec_env, make_vec_env
from khepera_gym.robot import export

#: The parity the exported policies must reach (issue 17): max abs action error.
ACTION_TOLERANCE = 1e-5
#: The C observation against the simulator's float32 observation.
OBSERVATION_TOLERANCE = 1e-6
#: Flags of the test build: warning-free C99.
C_FLAGS = ("-O2", "-std=c99", "-Wall", "-Wextra", "-Werror")
#: Seeds of the recorded rollouts.
SEEDS = (0, 1, 2)
#: Steps recorded per episode at most.
STEPS = 150

#: K-Team's libkhepera interface as the generated programs use it (tests/fake_libkhepera/khepera/
#: khepera.h: its declarations, constants and return conventions, written from K-Team's headers).
FAKE_LIBKHEPERA = Path(__file__).resolve().parent / "fake_libkhepera"


# A fake robot behind those declarations: fixed sensor readings, wheels turning at (300, -200)
# speed units, encoders that do not move; it logs the commands and ultrasonic measurements it
# gets to standard error. Its calls return 0, as K-Team's do when they succeed.
FAKE_ROBOT = """
#include <stdio.h>
#include <khepera/khepera.h>

static knet_dev_t device;

static void put_u16(char *buffer, int index, int value)
{
    buffer[2 * index] = (char)(value & 0xff);
    buffer[2 * index + 1] = (char)((value >> 8) & 0xff);
}

int kh4_init(int argc, char *argv[]) { (void)argc; (void)argv; return 0; }
knet_dev_t *knet_open(const char *name, int bus, int argc, char *argv[])
{
    (void)name; (void)bus; (void)argc; (void)argv;
    return &device;
}
int kh4_SetMode(int mode, knet_dev_t *d)
{
    (void)d;
    fprintf(stderr, "set_mode %d\\n", mode);
    return 0;
}
int kh4_SetSpeedProfile(char accinc, char accdiv, char mindacc, char mindec, int max_speed,
                        knet_dev_t *d)
{
    (void)d;
    fprintf(stderr, "set_profile %d %d %d %d %d\\n", (unsigned char)accinc, (unsigned char)accdiv,
            (unsigned char)mindacc, (unsigned char)mindec, max_speed);
    return 0;
}
int kh4_set_speed(int left, int right, knet_dev_t *d)
{
    (void)d;
    fprintf(stderr, "set_speed %d %d\\n", left, right);
    return 0;
}
int kh4_get_speed(int *left, int *right, knet_dev_t *d)
{
    (void)d;
    *left = 300;
    *right = -200;
    return 0;
}
int kh4_get_position(int *left, int *right, knet_dev_t *d)
{
    (void)d;
    *left = 5000;
    *right = -7000;
    return 0;
}
int kh4_ResetEncoders(knet_dev_t *d) { (void)d; return 0; }
int kh4_proximity_ir(char *buffer, knet_dev_t *d)
{
    int i;
    (void)d;
    for (i = 0; i < 12; ++i) {
        put_u16(buffer, i, i < 8 ? 100 + 60 * i : 900); /* the ring, then the ground sensors */
    }
    return 0;
}
int kh4_measure_us(char *buffer, knet_dev_t *d)
{
    static const int codes[5] = {25, 1000, 80, 2000, 0};
    int i;
    (void)d;
    fprintf(stderr, "measure_us\\n");
    for (i = 0; i < 5; ++i) {
        put_u16(buffer, i, codes[i]);
    }
    return 0;
}
int kh4_activate_us(char mask, knet_dev_t *d)
{
    (void)d;
    fprintf(stderr, "activate_us %d\\n", mask);
    return 0;
}
int kh4_SetRGBLeds(char lr, char lg, char lb, char rr, char rg, char rb, char br, char bg, char bb,
                   knet_dev_t *d)
{
    (void)d;
    fprintf(stderr, "set_leds %d %d %d %d %d %d %d %d %d\\n", lr, lg, lb, rr, rg, rb, br, bg, bb);
    return 0;
}
/* The IMU: 10 samples an axis, newest first; x, y at rest, z gravity (-1000 mg, raw << 4), and
 * the gyroscope still but for 5 counts on z. */
int kh4_measure_acc(char *buffer, knet_dev_t *d)
{
    int i;
    (void)d;
    for (i = 0; i < 30; ++i) {
        put_u16(buffer, i, i < 20 ? 0 : (-1000 * 16) & 0xffff);
    }
    return 0;
}
int kh4_measure_gyro(char *buffer, knet_dev_t *d)
{
    int i;
    (void)d;
    for (i = 0; i < 30; ++i) {
        put_u16(buffer, i, i < 20 ? 0 : 5);
    }
    return 0;
}
int kh4_revision(char *buffer, knet_dev_t *d)
{
    (void)d;
    buffer[0] = (char)0x23; /* version C, revision 3 */
    return 0;
}
"""


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def compile_check(out_dir: Path) -> Path:
    """``export_check`` built from the exported sources with the test flags."""
    sources = [str(out_dir / name) for name in ("export_check.c", *export.C_SOURCES)]
    binary = out_dir / "export_check_test"
    subprocess.run(
        ["cc", *C_FLAGS, "-o", str(binary), *sources, "-lm"],
        check=True,
        capture_output=True,
        text=True,
    )
    return binary


def run_check(binary: Path, mode: str, rows: npt.ArrayLike) -> npt.NDArray[Any]:
    """The check program's output rows for input rows (floats exact to float32)."""
    text = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in np.atleast_2d(rows)) + "\n"
    result = subprocess.run(
        [str(binary), mode], input=text, capture_output=True, text=True, check=True
    )
    values = np.array([[float(v) for v in line.split()] for line in result.stdout.splitlines()])
    return values.astype(np.float32)


def recording_of(
    env_id: str,
    heuristic: Callable[[npt.NDArray[np.float32]], npt.NDArray[np.float32]],
    obs_dim: int | None = None,
    **config: Any,
) -> tuple[export.Recording, export.RobotInterface]:
    """Observations and raw inputs of seeded rollouts of ``env_id`` driven by ``heuristic``."""
    env = gym.make(env_id, **config)
    try:
        if obs_dim is None:
            obs_dim = int(env.observation_space.shape[0])
        robot = export.robot_interface(env, obs_dim, env_id)
        recording = export.record_rollouts(env, robot, heuristic, seeds=SEEDS, steps=STEPS)
    finally:
        env.close()
    return recording, robot


@pytest.fixture(scope="module")
def nav_recording() -> export.Recording:
    return recording_of(LATEST["nav"], nav_heuristic)[0]


def scale_output_layer(module: nn.Module, factor: float) -> None:
    """Scales a freshly initialised output layer so that the actions span the action space."""
    with torch.no_grad():
        module.weight.mul_(factor)
        module.bias.uniform_(-0.5, 0.5)


def assert_actions_span_the_space(actions: npt.NDArray[Any]) -> None:
    """The reference actions are not degenerate: they vary, and some are clipped or squashed
    near the bounds, so parity is tested over the whole range."""
    assert np.std(actions) > 0.2, np.std(actions)
    assert np.mean(np.abs(actions) > 0.95) > 0.05
    assert np.mean(np.abs(actions) < 0.9) > 0.05


def nav_models() -> dict[str, Callable[[], tuple[Any, Any]]]:
    """Tiny untrained SB3 models of the supported kinds: name → () -> (model, normalizer)."""

    def ppo() -> tuple[Any, Any]:
        model = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
        scale_output_layer(model.policy.action_net, 300.0)
        return model, None

    def ppo_gsde() -> tuple[Any, Any]:
        # gSDE's mean action is the same network's; only its noise depends on the state.
        model = PPO(
            "MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64, use_sde=True
        )
        scale_output_layer(model.policy.action_net, 300.0)
        return model, None

    def ppo_vecnormalize() -> tuple[Any, Any]:
        venv = VecNormalize(make_vec_env(LATEST["nav"], 4, seed=0))
        venv.reset()
        rng = np.random.default_rng(0)
        for _ in range(200):  # statistics far from (0, 1), as after training
            venv.step(rng.uniform(-1, 1, (4, 2)).astype(np.float32))
        kwargs = {"net_arch": [32, 32], "activation_fn": nn.ReLU}
        model = PPO("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs=kwargs)
        scale_output_layer(model.policy.action_net, 300.0)
        return model, venv

    def a2c_elu() -> tuple[Any, Any]:
        kwargs = {"net_arch": [32, 16], "activation_fn": nn.ELU}
        model = A2C(
            "MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", policy_kwargs=kwargs
        )
        scale_output_layer(model.policy.action_net, 300.0)
        return model, None

    def sac() -> tuple[Any, Any]:
        kwargs = {"net_arch": [64, 64]}
        model = SAC(
            "MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", policy_kwargs=kwargs
        )
        scale_output_layer(model.policy.actor.mu, 300.0)
        return model, None

    def td3_leaky_relu() -> tuple[Any, Any]:
        kwargs = {"net_arch": [32, 32], "activation_fn": nn.LeakyReLU}
        model = TD3(
            "MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", policy_kwargs=kwargs
        )
        scale_output_layer(model.policy.actor.mu[-2], 80.0)
        return model, None

    return {
        "ppo": ppo,
        "ppo_gsde": ppo_gsde,
        "ppo_vecnormalize": ppo_vecnormalize,
        "a2c_elu": a2c_elu,
        "sac": sac,
        "td3_leaky_relu": td3_leaky_relu,
    }


@pytest.mark.parametrize("kind", list(nav_models()))
def test_c_and_onnx_policies_match_predict_on_recorded_observations(
    kind: str, nav_recording: export.Recording, tmp_path: Path
) -> None:
    model, normalizer = nav_models()[kind]()
    reference = model if normalizer is None else NormalizedPolicy(model, normalizer)
    observations = nav_recording.observations
    expected, _ = reference.predict(observations, deterministic=True)
    assert_actions_span_the_space(expected)

    # With VecNormalize, the model is given as khepera_gym.learning.sb3.load_policy gives it.
    result = export.export_policy(
        reference, tmp_path, formats=("c", "onnx"), env_id=LATEST["nav"], check=False
    )
    assert (result.network.normalization is not None) == (normalizer is not None)
    c_actions = run_check(compile_check(tmp_path), "policy", observations)
    assert c_actions.shape == expected.shape
    assert np.max(np.abs(c_actions - expected)) < ACTION_TOLERANCE

    onnx.checker.check_model(str(tmp_path / export.ONNX_FILE), full_check=True)
    onnx_actions = export.onnx_actions(tmp_path / export.ONNX_FILE, observations)
    assert np.max(np.abs(onnx_actions - expected)) < ACTION_TOLERANCE


def numpy_policy(network: export.PolicyNetwork, observations: npt.NDArray[Any]) -> npt.NDArray[Any]:
    """The network's actions computed with numpy, from its definition."""
    x = observations.astype(np.float64)
    norm = network.normalization
    if norm is not None:
        x = np.clip((x - norm.mean) / np.sqrt(norm.variance + norm.epsilon), -norm.clip, norm.clip)
    x = x.astype(np.float32)
    for layer in network.layers:
        x = x @ layer.weight.T + layer.bias
        if layer.activation == "tanh":
            x = np.tanh(x)
        elif layer.activation == "relu":
            x = np.maximum(x, 0)
        elif layer.activation == "elu":
            x = np.where(x > 0, x, layer.alpha * np.expm1(x))
        elif layer.activation == "leaky_relu":
            x = np.where(x > 0, x, layer.alpha * x)
        elif layer.activation == "silu":
            x = x / (1 + np.exp(-x))
    x = network.action.scale * x + network.action.offset
    if network.action.low is not None:
        x = np.clip(x, network.action.low, network.action.high)
    return x


def test_every_activation_exports_to_c_and_onnx(
    nav_recording: export.Recording, tmp_path: Path
) -> None:
    # A network written by hand (no torch): every activation, statistics far from (0, 1) with
    # some clipped, asymmetric action bounds.
    rng = np.random.default_rng(0)
    widths = [18, 24, 20, 16, 12, 8, 2]
    activations = ["tanh", "relu", "elu", "leaky_relu", "silu", "identity"]
    layers = tuple(
        export.DenseLayer(
            rng.normal(0, 1.5 / np.sqrt(n_in), (n_out, n_in)).astype(np.float32),
            rng.normal(0, 0.3, n_out).astype(np.float32),
            activation,
            {"elu": 0.7, "leaky_relu": 0.05}.get(activation, 0.0),
        )
        for n_in, n_out, activation in zip(widths[:-1], widths[1:], activations, strict=True)
    )
    observations = nav_recording.observations
    normalization = export.ObservationNormalization(
        mean=observations.mean(axis=0) + rng.normal(0, 0.05, 18),
        variance=observations.var(axis=0) * rng.uniform(0.5, 2.0, 18),
        epsilon=1e-8,
        clip=3.0,
    )
    low, high = np.array([-1.0, -0.5], np.float32), np.array([1.0, 0.25], np.float32)
    network = export.PolicyNetwork(
        "hand-written",
        18,
        2,
        normalization,
        layers,
        export.ActionTransform((high - low) / 4, (high + low) / 2, low, high),
    )
    expected = numpy_policy(network, observations)
    assert np.mean((expected == low) | (expected == high)) > 0.05  # some actions are clipped
    assert np.mean((expected > low) & (expected < high)) > 0.5

    (tmp_path / "policy.onnx").write_bytes(export.build_onnx(network).SerializeToString())
    onnx_actions = export.onnx_actions(tmp_path / "policy.onnx", observations)
    assert np.max(np.abs(onnx_actions - expected)) < ACTION_TOLERANCE

    with gym.make(LATEST["nav"]) as env:
        robot = export.robot_interface(env, 18, LATEST["nav"])
    motors = export.motor_setting(export.toml_loads(robot.scenario_toml))
    export.write_c(network, robot, motors, tmp_path, "a test")
    c_actions = run_check(compile_check(tmp_path), "policy", observations)
    assert np.max(np.abs(c_actions - expected)) < ACTION_TOLERANCE


@pytest.mark.parametrize(
    ("env_id", "heuristic", "config"),
    [
        (LATEST["nav"], nav_heuristic, {}),
        (LATEST["avoid"], avoid_heuristic, {}),
        # Other constants than the defaults must be baked in: the IR floor, the ultrasonic range,
        # the wheel speed limit, the arena (its diagonal caps the goal distance).
        (
            LATEST["nav"],
            nav_heuristic,
            {"ir_floor_value": 105.0, "us_max_range": 1.3, "max_wheel_speed": 0.5, "width": 1.5},
        ),
    ],
    ids=["nav", "avoid", "nav_other_constants"],
)
def test_c_observation_matches_simulator_from_raw_readings(
    env_id: str, heuristic: Any, config: dict[str, Any], tmp_path: Path
) -> None:
    recording, robot = recording_of(env_id, heuristic, **config)
    model = PPO("MlpPolicy", gym.make(env_id, **config), seed=0, device="cpu")
    export.export_policy(model, tmp_path, env_id=env_id, check=False, **config)
    built = run_check(compile_check(tmp_path), "observation", recording.input_rows)
    simulated = recording.observations
    assert built.shape == simulated.shape

    layout = dict((name, slice(start, stop)) for name, start, stop in robot.layout)
    # The rollouts saw obstacles with both sensor kinds, moved the wheels and turned.
    assert np.mean(simulated[:, layout["ir"]] > 0) > 0.02
    assert np.mean(simulated[:, layout["us"]] < 1) > 0.2
    assert np.mean(np.abs(simulated[:, layout["wheel_speeds"]]) > 0.1) > 0.5
    assert np.ptp(simulated[:, layout["goal_bearing_sin"]]) > 1.0
    # Sensor blocks: the same float operations as the Rust core, so bit for bit.
    for block in ("ir", "us", "wheel_speeds"):
        np.testing.assert_array_equal(built[:, layout[block]], simulated[:, layout[block]])
    # Goal blocks: sinf/cosf of the heading may differ from Rust's in the last bit.
    assert np.max(np.abs(built - simulated)) < OBSERVATION_TOLERANCE


@pytest.mark.parametrize("action_type", ["wheels", "unicycle"])
def test_c_wheel_command_matches_simulator_wheel_speeds(action_type: str, tmp_path: Path) -> None:
    # The robot's motor controller ramps to a commanded speed by itself; with the simulated ramp
    # off (a plain ramp of no limit, exported at its nominal setting) the simulator's wheel
    # speeds are the commanded ones.
    no_ramp = {"mode": "ramp", "wheel_accel_limit": float("inf")}
    env = gym.make(LATEST["nav"], action_type=action_type, **no_ramp)
    model = PPO("MlpPolicy", env, seed=0, device="cpu")
    export.export_policy(
        model,
        tmp_path,
        env_id=LATEST["nav"],
        action_type=action_type,
        check=False,
        drive="nominal",
        **no_ramp,
    )
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.3, 1.3, (300, 2)).astype(np.float32)
    actions[:20] = rng.uniform(-0.004, 0.004, (20, 2))  # around the controller's floor
    env.reset(seed=0)
    expected = []
    for action in actions:
        env.step(action)
        speeds = env.unwrapped.sensor_readings()["wheel_speeds"][0]
        expected.append([khepera_gym.speed_to_units(float(speed)) for speed in speeds])
    env.close()
    units = run_check(compile_check(tmp_path), "wheels", actions)
    np.testing.assert_array_equal(units, np.array(expected))
    assert np.any(units == 0) and np.max(np.abs(units)) > 1100


def test_c_led_levels_match_the_simulators_leds(tmp_path: Path) -> None:
    env = gym.make(LATEST["nav"], led_action=True)
    model = PPO("MlpPolicy", env, seed=0, device="cpu", n_steps=64)
    export.export_policy(model, tmp_path, env_id=LATEST["nav"], check=False, led_action=True)
    assert "#define KHEPERA_LED_ACTION 1" in (tmp_path / "khepera_policy_config.h").read_text()
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1.3, 1.3, (200, 5)).astype(np.float32)
    # Values on the levels' rounding edges, (k + 1/2) / 63 · 2 − 1, and either side of them.
    edges = ((np.arange(63) + 0.5) / 63 * 2 - 1).astype(np.float32)
    for k, edge in enumerate(edges):
        actions[k, 2:] = [np.nextafter(edge, -2), edge, np.nextafter(edge, 2)]
    env.reset(seed=0)
    expected = []
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        expected.append(env.unwrapped.sensor_readings()["leds"][0])
        if terminated or truncated:
            env.reset()
    env.close()
    levels = run_check(compile_check(tmp_path), "leds", actions[:, 2:]).astype(int)
    np.testing.assert_array_equal(levels, np.array(expected))
    assert levels.min() == 0 and levels.max() == 63


def test_the_action_width_must_be_the_scenarios(tmp_path: Path) -> None:
    lit = PPO(
        "MlpPolicy", gym.make(LATEST["nav"], led_action=True), seed=0, device="cpu", n_steps=64
    )
    with pytest.raises(ConfigError, match="led_action=True"):
        export.export_policy(lit, tmp_path, env_id=LATEST["nav"], check=False)
    plain = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
    with pytest.raises(ConfigError, match=r"takes 5 \(its wheels, then its LEDs"):
        export.export_policy(plain, tmp_path, env_id=LATEST["nav"], check=False, led_action=True)


def test_formation_follower_policy_exports_one_robots_block(tmp_path: Path) -> None:
    venv = make_formation_vec_env(1, seed=0)
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", n_steps=64)
    scale_output_layer(model.policy.action_net, 300.0)
    recording, _ = recording_of(
        LATEST["formation"], formation_follower_heuristic, obs_dim=venv.follower_obs_dim
    )
    result = export.export_policy(model, tmp_path, env_id=LATEST["formation"], check=False)
    assert result.robot.agent == "follower_0"
    assert json.loads((tmp_path / export.LAYOUT_FILE).read_text())["target_offset"] == [13, 15]

    binary = compile_check(tmp_path)
    expected, _ = model.predict(recording.observations, deterministic=True)
    assert_actions_span_the_space(expected)
    actions = run_check(binary, "policy", recording.observations)
    assert np.max(np.abs(actions - expected)) < ACTION_TOLERANCE
    built = run_check(binary, "observation", recording.input_rows)
    np.testing.assert_array_equal(built, recording.observations)  # no goal blocks: all exact
    header = (tmp_path / "observation.h").read_text()
    assert "float leader_offset[2];" in header and "OBSERVATION_EXTRA_INPUTS 4" in header


def robot_program_on_fake_robot(out_dir: Path) -> Path:
    """The exported template program built against the fake robot (test flags)."""
    (out_dir / "fake_robot.c").write_text(FAKE_ROBOT)
    sources = ["khepera_policy_main.c", *export.C_SOURCES, *export.ROBOT_SOURCES, "fake_robot.c"]
    program = out_dir / "khepera_policy"
    subprocess.run(
        ["cc", *C_FLAGS, f"-I{FAKE_LIBKHEPERA}", "-o", str(program)]
        + [str(out_dir / name) for name in sources]
        + ["-lm"],
        check=True,
        capture_output=True,
        text=True,
    )
    return program


def test_robot_program_drives_a_fake_robot_with_the_policys_actions(tmp_path: Path) -> None:
    model, _ = nav_models()["ppo"]()
    export.export_policy(model, tmp_path, env_id=LATEST["nav"], check=False)
    program = robot_program_on_fake_robot(tmp_path)

    # Three steps toward a goal 1 m ahead and 0.5 m to the left of the start pose.
    run = subprocess.run(
        [str(program), "1.0", "0.5", "3"], capture_output=True, text=True, check=True, timeout=10
    )
    steps = [line.split() for line in run.stdout.splitlines()]
    assert [int(step[0]) for step in steps] == [0, 1, 2]
    # The fake robot's readings (fake_robot.c) as observation inputs: the ring's raw values,
    # the ultrasonic codes, the wheel speeds of its speed units, the start pose (its encoders
    # do not move) and the goal.
    ir_raw = [100 + 60 * i for i in range(8)]
    us_cm = [25, 1000, 80, 2000, 0]
    speeds = [np.float32(units) * np.float32(0.678181) / np.float32(1000) for units in (300, -200)]
    row = [*ir_raw, *us_cm, *speeds, 0.0, 0.0, 0.0, 1.0, 0.5]
    observation = run_check(compile_check(tmp_path), "observation", [row])
    expected, _ = model.predict(observation, deterministic=True)
    for step in steps:
        assert [float(v) for v in step[1:4]] == [0.0, 0.0, 0.0]  # pose x, y, heading
        np.testing.assert_allclose([float(step[4]), float(step[5])], expected[0], atol=6e-5)
    # Every command went out in K-Team units; the motors stopped and went idle at the end.
    commands = [line.split() for line in run.stderr.splitlines()]
    units = [[int(step[6]), int(step[7])] for step in steps]
    assert [c for c in commands if c[0] == "set_speed"] == [
        ["set_speed", str(left), str(right)] for left, right in [*units, [0, 0]]
    ]
    assert commands[-1] == ["set_mode", "0"] and ["activate_us", "31"] in commands
    # The motor controller is set as in training before the first command: v2's K-Team speed
    # profile at Acc_Inc 40, Acc_Div 0, minimum 20 units (kh4RegSpeedProfile = 2).
    first_speed = commands.index(["set_speed", *map(str, units[0])])
    assert commands.index(["set_profile", "40", "0", "20", "1", "400"]) < first_speed
    assert commands.index(["set_mode", "2"]) < first_speed
    assert "motors: speed profile, acc_inc 40, acc_div 0, min_speed_acc 20" in run.stderr
    assert commands.count(["measure_us"]) == 3  # once a step
    wheels = run_check(compile_check(tmp_path), "wheels", expected).astype(int)
    assert units[0] == wheels[0].tolist()

    # A goal within the goal radius: it stops at once.
    run = subprocess.run(
        [str(program), "0.01", "0.0"], capture_output=True, text=True, check=True, timeout=10
    )
    assert run.stdout.startswith("goal reached (by odometry) after 0 steps")


def frame_stacked_ppo(n_stack: int) -> Any:
    """An untrained PPO on ``n_stack`` stacked, normalised Nav observations (VecFrameStack
    outside VecNormalize, as ``khepera-gym train`` wraps them), as load_policy gives it back."""
    from stable_baselines3.common.vec_env import VecFrameStack

    from khepera_gym.learning.sb3 import FrameStackPolicy

    normalized = VecNormalize(make_vec_env(LATEST["nav"], 4, seed=0))
    venv = VecFrameStack(normalized, n_stack)
    venv.reset()
    rng = np.random.default_rng(0)
    for _ in range(200):  # statistics far from (0, 1), as after training
        venv.step(rng.uniform(-1, 1, (4, 2)).astype(np.float32))
    kwargs = {"net_arch": [32, 32]}
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", n_steps=64, policy_kwargs=kwargs)
    scale_output_layer(model.policy.action_net, 300.0)
    normalized.training = False
    return FrameStackPolicy(model, n_stack, normalized)


def test_a_frame_stacked_policy_exports_with_its_memory(
    nav_recording: export.Recording, tmp_path: Path
) -> None:
    policy = frame_stacked_ppo(3)
    result = export.export_policy(policy, tmp_path, formats=("c", "onnx"), env_id=LATEST["nav"])
    width = nav_recording.observations.shape[1]
    assert result.network.frame_stack == 3 and result.network.obs_dim == width
    assert result.network.input_dim == 3 * width and result.network.normalization is not None
    # The export's own check ran the C and ONNX policies over whole episodes against the
    # Python FrameStackPolicy (a fresh stack at each episode's start).
    assert result.checks["c_max_abs_error"] < ACTION_TOLERANCE
    assert result.checks["onnx_max_abs_error"] < ACTION_TOLERANCE
    assert json.loads((tmp_path / export.MANIFEST_FILE).read_text())["frame_stack"] == 3

    # The same, here, over the recorded episodes; the stack matters: without memory (each
    # observation from a fresh state) the actions differ by far more than the tolerance.
    observations, starts = nav_recording.observations, nav_recording.starts
    assert starts[0] and 1 < starts.sum() < len(starts)
    expected = export.reference_actions(policy).sequence(observations, starts)
    assert_actions_span_the_space(expected)
    binary = compile_check(tmp_path)
    sequence = run_check(binary, "sequence", np.column_stack([starts, observations]))
    assert np.max(np.abs(sequence - expected)) < ACTION_TOLERANCE
    fresh = run_check(binary, "policy", observations)
    np.testing.assert_array_equal(fresh[starts], sequence[starts])
    assert np.max(np.abs(fresh - expected)) > 0.1
    stacked = export.onnx_inputs(result.network, observations, starts)
    assert stacked.shape == (len(observations), 3 * width)
    got = export.onnx_actions(tmp_path / export.ONNX_FILE, stacked)
    assert np.max(np.abs(got - expected)) < ACTION_TOLERANCE

    # The robot program keeps the stack across control periods: on the fake robot's constant
    # readings, its actions are the Python policy's on that observation repeated.
    program = robot_program_on_fake_robot(tmp_path)
    run = subprocess.run(
        [str(program), "1.0", "0.5", "4"], capture_output=True, text=True, check=True, timeout=10
    )
    actions = np.array([[float(v) for v in line.split()[4:6]] for line in run.stdout.splitlines()])
    ir_raw = [100 + 60 * i for i in range(8)]
    us_cm = [25, 1000, 80, 2000, 0]
    speeds = [np.float32(units) * np.float32(0.678181) / np.float32(1000) for units in (300, -200)]
    row = [*ir_raw, *us_cm, *speeds, 0.0, 0.0, 0.0, 1.0, 0.5]
    observation = run_check(binary, "observation", [row])
    repeated = np.repeat(observation, 4, axis=0)
    starts = np.array([True, False, False, False])
    want = export.reference_actions(policy).sequence(repeated, starts)
    np.testing.assert_allclose(actions, want, atol=6e-5)  # the program prints 4 decimals
    assert np.max(np.abs(want[2] - want[0])) > 1e-3  # the stack filling changes the action


def test_robot_program_sets_the_leds_a_led_policy_asks_for(tmp_path: Path) -> None:
    env = gym.make(LATEST["nav"], led_action=True)
    model = PPO("MlpPolicy", env, seed=0, device="cpu", n_steps=64)
    scale_output_layer(model.policy.action_net, 300.0)
    export.export_policy(model, tmp_path, env_id=LATEST["nav"], check=False, led_action=True)
    program = robot_program_on_fake_robot(tmp_path)
    run = subprocess.run(
        [str(program), "1.0", "0.5", "2"], capture_output=True, text=True, check=True, timeout=10
    )
    steps = [line.split() for line in run.stdout.splitlines()]
    assert len(steps) == 2 and all(len(step) == 11 for step in steps)
    # The policy's LED values (the fake robot's observation is the same every step) as levels,
    # sent to the three LEDs each step, then all off when the program stops.
    binary = compile_check(tmp_path)
    row = [*[100 + 60 * i for i in range(8)], 25, 1000, 80, 2000, 0]
    speeds = [np.float32(units) * np.float32(0.678181) / np.float32(1000) for units in (300, -200)]
    observation = run_check(binary, "observation", [[*row, *speeds, 0.0, 0.0, 0.0, 1.0, 0.5]])
    action = run_check(binary, "policy", observation)
    levels = run_check(binary, "leds", action[:, 2:]).astype(int)[0].tolist()
    assert [[int(v) for v in step[8:]] for step in steps] == [levels, levels]
    commands = [line.split() for line in run.stderr.splitlines()]
    sent = [[int(v) for v in c[1:]] for c in commands if c[0] == "set_leds"]
    assert sent == [levels * 3, levels * 3, [0] * 9]


def test_export_follows_a_scenario_that_observes_only_the_ir_ring(tmp_path: Path) -> None:
    # [sensors] observe = ["ir"]: the robots still carry their ultrasonic sensors but the
    # observation has no "us" block, so every index after the IR ring moves; the C observation
    # must follow the env's own layout, and the robot program must not switch the ultrasonic
    # sensors on nor read them.
    config = {"observe": ["ir"]}
    env = gym.make(LATEST["avoid"], **config)
    layout = env.unwrapped.obs_layout()
    assert "us" not in layout and env.observation_space.shape == (13,)
    recording = recording_of(LATEST["avoid"], Braitenberg(layout=env), **config)[0]
    model = PPO("MlpPolicy", env, seed=0, device="cpu", n_steps=64)
    scale_output_layer(model.policy.action_net, 300.0)

    # The export's own check (on its own rollouts) passes.
    result = export.export_policy(
        model, tmp_path, formats=("c", "onnx"), env_id=LATEST["avoid"], **config
    )
    assert result.checks["c_max_abs_error"] < ACTION_TOLERANCE
    assert result.checks["onnx_max_abs_error"] < ACTION_TOLERANCE
    assert result.checks["observation_max_abs_error"] < OBSERVATION_TOLERANCE
    written = json.loads((tmp_path / export.LAYOUT_FILE).read_text())
    assert written == {name: [block.start, block.stop] for name, block in layout.items()}
    header = (tmp_path / "observation.h").read_text()
    assert "#define OBSERVATION_HAS_US 0" in header and "int16_t us_cm" not in header
    # 8 IR values, 2 wheel speeds, the pose (3) and the goal (2).
    assert "#define OBSERVATION_INPUT_COUNT 15 " in header
    assert "#define KHEPERA_US_MASK 0 " in (tmp_path / "khepera_policy_config.h").read_text()

    # The C observation from the raw readings, and the actions, on the recorded rollouts.
    binary = compile_check(tmp_path)
    simulated = recording.observations
    built = run_check(binary, "observation", recording.input_rows)
    assert built.shape == simulated.shape == (len(simulated), 13)
    assert np.mean(simulated[:, layout["ir"]] > 0) > 0.02  # obstacles were seen
    for block in ("ir", "wheel_speeds"):
        np.testing.assert_array_equal(built[:, layout[block]], simulated[:, layout[block]])
    assert np.max(np.abs(built - simulated)) < OBSERVATION_TOLERANCE
    expected, _ = model.predict(simulated, deterministic=True)
    assert_actions_span_the_space(expected)
    assert np.max(np.abs(run_check(binary, "policy", simulated) - expected)) < ACTION_TOLERANCE
    onnx_actions = export.onnx_actions(tmp_path / export.ONNX_FILE, simulated)
    assert np.max(np.abs(onnx_actions - expected)) < ACTION_TOLERANCE

    # On the fake robot: the ultrasonic sensors are switched off and never measured.
    program = robot_program_on_fake_robot(tmp_path)
    run = subprocess.run(
        [str(program), "1.0", "0.5", "2"], capture_output=True, text=True, check=True, timeout=10
    )
    commands = [line.split() for line in run.stderr.splitlines()]
    assert ["activate_us", "0"] in commands and ["measure_us"] not in commands
    assert len(run.stdout.splitlines()) == 2
    env.close()


def test_robot_program_template_compiles_without_goal_inputs(tmp_path: Path) -> None:
    model = PPO("MlpPolicy", make_formation_vec_env(1), seed=0, device="cpu", n_steps=64)
    export.export_policy(model, tmp_path, env_id=LATEST["formation"], check=False)
    compile_only = ["cc", *C_FLAGS, "-c", f"-I{FAKE_LIBKHEPERA}", "-o", str(tmp_path / "o.o")]
    for name in ("khepera_policy_main.c", *export.C_SOURCES, *export.ROBOT_SOURCES):
        subprocess.run(
            [*compile_only, str(tmp_path / name)],
            check=True,
            capture_output=True,
            text=True,
        )
    assert "TODO" in (tmp_path / "khepera_policy_main.c").read_text()


def test_command_exports_a_trained_run_with_its_scenario_and_statistics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # A run directory as `khepera-gym train` leaves it: model.zip, vecnormalize.pkl, run.json
    # whose env_kwargs changed the scenario.
    run = tmp_path / "run"
    run.mkdir()
    overrides = {"ir_floor_value": 110.0}
    venv = VecNormalize(make_vec_env(LATEST["nav"], 2, seed=0, **overrides))
    venv.reset()
    for _ in range(50):
        venv.step(np.full((2, 2), 0.5, np.float32))
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", n_steps=64)
    model.save(run / "model.zip")
    venv.save(str(run / "vecnormalize.pkl"))
    record = {"env_id": LATEST["nav"], "algo": "ppo", "hyperparams": {"env_kwargs": overrides}}
    (run / "run.json").write_text(json.dumps(record))

    status = cli.main(["export", str(run / "model.zip"), "--format", "c", "onnx"])
    assert status == 0
    out = run / "export"
    printed = capsys.readouterr().out
    assert "c max abs error" in printed and "onnx max abs error" in printed
    manifest = json.loads((out / export.MANIFEST_FILE).read_text())
    assert manifest["vecnormalize"] is True and manifest["env_id"] == LATEST["nav"]
    assert manifest["checks"]["c_max_abs_error"] < ACTION_TOLERANCE
    assert manifest["checks"]["onnx_max_abs_error"] < ACTION_TOLERANCE
    assert manifest["checks"]["observation_max_abs_error"] < OBSERVATION_TOLERANCE
    assert "ir_floor_value = 110.0" in (out / export.SCENARIO_FILE).read_text()
    assert "#define OBSERVATION_IR_FLOOR_VALUE 110.0f" in (out / "observation.h").read_text()
    for name in ("policy.c", "policy.h", "observation.c", "khepera_policy_main.c", "Makefile"):
        assert (out / name).is_file()

    # --set overrides the scenario, --env the run's env; --no-check measures nothing.
    other = tmp_path / "other"
    arguments = ["--set", "us_max_range=1.5", "--no-check", "--out", str(other)]
    assert cli.main(["export", str(run / "model.zip"), "--env", LATEST["nav"], *arguments]) == 0
    assert "#define OBSERVATION_US_MAX_RANGE 1.5f" in (other / "observation.h").read_text()
    assert json.loads((other / export.MANIFEST_FILE).read_text())["checks"] == {}


def test_export_check_reports_figures_and_fails_beyond_its_tolerance(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model, _ = nav_models()["ppo"]()
    result = export.export_policy(
        model, tmp_path / "ok", env_id=LATEST["nav"], compiler="no-such-cc"
    )
    assert result.checks["c_skipped"] == "no C compiler 'no-such-cc' on PATH"
    assert result.checks["observations"] > 300

    # float32 sums in another order than torch's cannot all agree to the last bit.
    monkeypatch.setattr(export.checks, "PARITY_TOLERANCE", 0.0)
    with pytest.raises(KheperaError, match="exported C actions differ"):
        export.export_policy(model, tmp_path / "strict", env_id=LATEST["nav"])
    checks = json.loads((tmp_path / "strict" / export.MANIFEST_FILE).read_text())["checks"]
    assert 0 < checks["c_max_abs_error"] < ACTION_TOLERANCE


class ImageEnv(gym.Env[npt.NDArray[np.uint8], npt.NDArray[np.float32]]):
    """A camera-like env, for a CnnPolicy."""

    observation_space = gym.spaces.Box(0, 255, (36, 36, 1), np.uint8)
    action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)


@pytest.mark.parametrize(
    "make_model",
    [
        lambda: DQN("MlpPolicy", gym.make("CartPole-v1"), device="cpu"),
        lambda: PPO("CnnPolicy", ImageEnv(), device="cpu"),
        lambda: object(),
    ],
    ids=["dqn", "cnn_policy", "other_object"],
)
def test_unsupported_model_error_lists_supported_types(
    make_model: Callable[[], Any], tmp_path: Path
) -> None:
    with pytest.raises(ConfigError, match="supported are stable-baselines3 PPO or A2C") as error:
        export.export_policy(make_model(), tmp_path, env_id=LATEST["nav"])
    assert "SAC or TD3" in str(error.value) and "RLlib PPO checkpoint" in str(error.value)


def test_unsupported_files_and_env_mismatch_raise_config_errors(tmp_path: Path) -> None:
    (tmp_path / "weights.pt").write_bytes(b"")
    with pytest.raises(ConfigError, match="supported are"):
        export.export_policy(tmp_path / "weights.pt", tmp_path / "out", env_id=LATEST["nav"])
    with pytest.raises(ConfigError, match="not an RLlib checkpoint"):
        export.export_policy(tmp_path, tmp_path / "out", env_id=LATEST["nav"])
    nav_model = PPO("MlpPolicy", gym.make(LATEST["nav"]), device="cpu")
    with pytest.raises(ConfigError, match="cannot tell which env"):
        export.export_policy(nav_model, tmp_path / "out")
    with pytest.raises(ConfigError, match=r"takes 18 observation values; .* have 23 each"):
        export.export_policy(nav_model, tmp_path / "out", env_id=LATEST["formation"])
    with pytest.raises(ConfigError, match="unknown export formats"):
        export.export_policy(nav_model, tmp_path / "out", env_id=LATEST["nav"], formats=("tflite",))


def test_missing_onnx_extra_names_the_pip_command(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = PPO("MlpPolicy", gym.make(LATEST["nav"]), device="cpu")
    monkeypatch.setitem(sys.modules, "onnx", None)
    with pytest.raises(ImportError, match=r"pip install 'khepera-gym\[export\]'"):
        export.export_policy(model, tmp_path, env_id=LATEST["nav"], formats=("onnx",))
    monkeypatch.setitem(sys.modules, "onnxruntime", None)
    with pytest.raises(ImportError, match=r"pip install 'khepera-gym\[export\]'"):
        export.onnx_actions(tmp_path / "policy.onnx", np.zeros((1, 18), np.float32))


def test_missing_sb3_names_the_pip_command(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    PPO("MlpPolicy", gym.make(LATEST["nav"]), device="cpu").save(tmp_path / "model.zip")
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    with pytest.raises(ImportError, match=r"pip install 'khepera-gym\[sb3\]'"):
        export.export_policy(tmp_path / "model.zip", tmp_path / "out", env_id=LATEST["nav"])


def test_missing_ray_names_the_pip_command(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    module = tmp_path / "learner_group" / "learner" / "rl_module" / "default_policy"
    module.mkdir(parents=True)
    (module / "module_state.pkl").write_bytes(b"")
    (tmp_path / "rllib_checkpoint.json").write_text("{}")
    # Ray missing: hide every ray module already imported (with the rllib extra installed, other
    # test modules import ray.rllib at collection, and a loaded submodule imports past a hidden
    # "ray"), as well as "ray" itself.
    for name in [name for name in sys.modules if name.startswith("ray.")] + ["ray"]:
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(ImportError, match=r"pip install 'khepera-gym\[rllib\]'"):
        export.export_policy(tmp_path, tmp_path / "out", env_id=LATEST["nav"])


@pytest.fixture
def local_ray(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """A local Ray instance for one test, shut down after it (RLlib would otherwise start one
    that outlives the test, and tests/test_rllib.py starts its own), with the Algorithm's Tune
    log folder in the test's folder instead of ~/ray_results."""
    ray = pytest.importorskip("ray", reason="needs Ray RLlib (the rllib extra)")
    pytest.importorskip("ray.rllib", reason="needs Ray RLlib (the rllib extra)")
    results = str(tmp_path / "ray_results")
    monkeypatch.setattr("ray.tune.trainable.trainable.DEFAULT_STORAGE_PATH", results)
    monkeypatch.setattr(
        "ray.rllib.algorithms.algorithm.DEFAULT_STORAGE_PATH", results, raising=False
    )
    ray.init(address="local", num_cpus=1, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def test_rllib_ppo_checkpoint_exports_with_parity(
    nav_recording: export.Recording, tmp_path: Path, local_ray: None
) -> None:
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.rllib.core.rl_module.rl_module import RLModule
    from ray.rllib.utils.spaces.space_utils import unsquash_action

    config = (
        PPOConfig()
        .environment(LATEST["nav"])
        .env_runners(num_env_runners=0, rollout_fragment_length=64)
        .training(train_batch_size_per_learner=64, minibatch_size=32, num_epochs=1)
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=[32, 32]))
        .debugging(seed=0)
    )
    algorithm = config.build_algo()
    algorithm.train()
    checkpoint = tmp_path / "checkpoint"
    algorithm.save_to_path(str(checkpoint))
    algorithm.stop()

    # RLlib's own deterministic actions: the module's inference pass, its action distribution
    # made deterministic, then RLlib's action unsquashing (normalize_actions=True by default).
    module = RLModule.from_checkpoint(checkpoint / "learner_group/learner/rl_module/default_policy")
    with torch.no_grad():
        scale_output_layer(module.pi.net.mlp[-1], 50.0)  # the mean's rows too: span the space
        outputs = module.forward_inference({"obs": torch.from_numpy(nav_recording.observations)})
    distribution = module.get_inference_action_dist_cls().from_logits(outputs["action_dist_inputs"])
    raw = distribution.to_deterministic().sample().numpy()
    expected = unsquash_action(raw, module.action_space)
    assert_actions_span_the_space(expected)
    module.save_to_path(str(checkpoint / "learner_group/learner/rl_module/default_policy"))

    # The env id comes from the checkpoint's config.
    result = export.export_policy(checkpoint, tmp_path / "out", formats=("c", "onnx"), check=False)
    assert result.robot.env_id == LATEST["nav"] and result.network.source.startswith("RLlib")
    actions = run_check(compile_check(tmp_path / "out"), "policy", nav_recording.observations)
    assert np.max(np.abs(actions - expected)) < ACTION_TOLERANCE
    onnx_actions = export.onnx_actions(
        tmp_path / "out" / export.ONNX_FILE, nav_recording.observations
    )
    assert np.max(np.abs(onnx_actions - expected)) < ACTION_TOLERANCE


def _program_calls(tmp_path: Path, model: Any, **kwargs: Any) -> list[list[str]]:
    """What the exported program tells the fake robot's motor controller before driving."""
    export.export_policy(model, tmp_path, check=False, **kwargs)
    program = robot_program_on_fake_robot(tmp_path)
    run = subprocess.run(
        [str(program), "1.0", "0.5", "1"], capture_output=True, text=True, check=True, timeout=10
    )
    calls = [line.split() for line in run.stderr.splitlines()]
    return [c for c in calls if c[0] in ("set_profile", "set_mode")]


def test_the_program_sets_the_drive_the_policy_was_trained_with(tmp_path: Path) -> None:
    model = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
    # A preset K-Team program sets (its Braitenberg demo: Acc_Inc 10): the same profile.
    calls = _program_calls(
        tmp_path / "demo", model, env_id=LATEST["nav"], preset="kteam_braitenberg"
    )
    assert calls[:2] == [["set_mode", "0"], ["set_profile", "10", "0", "20", "1", "400"]]
    assert calls[2] == ["set_mode", "2"]
    # The speed mode: kh4RegSpeed (1), no profile.
    calls = _program_calls(tmp_path / "speed", model, env_id=LATEST["nav"], preset="speed_mode")
    assert ["set_mode", "1"] in calls and not any(c[0] == "set_profile" for c in calls)
    manifest = json.loads((tmp_path / "speed" / export.MANIFEST_FILE).read_text())
    assert manifest["motors"]["mode"] == "speed" and "estimate" in manifest["motors"]["note"]


def test_a_drive_the_robot_cannot_be_set_to_needs_its_nominal_setting(tmp_path: Path) -> None:
    v1 = "KheperaIV-Nav-v1"
    model = PPO("MlpPolicy", gym.make(v1), seed=0, device="cpu", n_steps=64)
    # v1's plain 0.203 m/s² ramp is no firmware mode: an error saying what nominal would set.
    with pytest.raises(ConfigError, match=r"ramp.*--drive nominal.*Acc_Inc 3"):
        export.export_policy(model, tmp_path / "v1", env_id=v1, check=False)
    assert not (tmp_path / "v1" / "khepera_policy_main.c").exists()
    calls = _program_calls(tmp_path / "v1", model, env_id=v1, drive="nominal")
    assert ["set_profile", "3", "0", "20", "1", "400"] in calls and ["set_mode", "2"] in calls
    # A profile randomised over a range: the robot runs one; nominal takes the midpoint.
    model = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
    with pytest.raises(ConfigError, match=r"randomised drive.*motors\.acc_inc"):
        export.export_policy(
            model, tmp_path / "dr", env_id=LATEST["nav"], check=False, acc_inc=[20, 60]
        )
    calls = _program_calls(
        tmp_path / "dr", model, env_id=LATEST["nav"], acc_inc=[20, 60], drive="nominal"
    )
    assert ["set_profile", "40", "0", "20", "1", "400"] in calls
    with pytest.raises(ConfigError, match="drive must be one of"):
        export.export_policy(model, tmp_path / "x", env_id=LATEST["nav"], check=False, drive="fast")


@pytest.mark.skipif(
    not os.environ.get("KHEPERA_SDK"),
    reason="set KHEPERA_SDK to K-Team's libkhepera 2.1 (its source tree, e.g. libkhepera-2.1/, "
    "or its install) to compile the programs against K-Team's own headers",
)
def test_every_program_compiles_against_kteams_libkhepera_sdk(tmp_path: Path) -> None:
    """Optional: ``KHEPERA_SDK=/path/to/libkhepera-2.1 pytest tests/test_export.py -k sdk``."""
    import robot_programs as rp
    from test_export_recurrent import recurrent_ppo

    from khepera_gym.robot.calibrate import write_calibration_program

    include = rp.sdk_include(Path(os.environ["KHEPERA_SDK"]), tmp_path / "include")
    # The robot's compiler when there is one; else this PC's, with the robot's unsigned char.
    arm = rp.TARGETS["arm"]
    compiler, flags = (
        (arm.compiler, arm.flags) if arm.missing() is None else ("cc", ("-O2", "-funsigned-char"))
    )
    led = PPO(
        "MlpPolicy", gym.make(LATEST["nav"], led_action=True), seed=0, device="cpu", n_steps=64
    )
    sampled = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
    programs = {
        "plain": (nav_models()["ppo"]()[0], {}),
        "frame_stack": (frame_stacked_ppo(3), {}),
        "recurrent": (recurrent_ppo(1), {}),
        "sampled": (sampled, {"sample_seed": 1}),
        "led_action": (led, {"led_action": True}),
    }
    folders = []
    for name, (model, options) in programs.items():
        export.export_policy(model, tmp_path / name, env_id=LATEST["nav"], check=False, **options)
        folders.append(tmp_path / name)
    write_calibration_program(tmp_path / "calibrate", env_id=LATEST["nav"])
    folders.append(tmp_path / "calibrate")
    compile_only = [compiler, *flags, rp.ROBOT_STD, *rp.WARNINGS, f"-I{include}", "-c"]
    compiled = 0
    for folder in folders:
        for source in sorted(folder.glob("*.c")):
            result = subprocess.run(
                [*compile_only, str(source), "-o", str(tmp_path / "program.o")],
                capture_output=True,
                text=True,
            )
            assert result.returncode == 0, f"{source} against {include}:\n{result.stderr}"
            compiled += 1
    assert compiled == len(programs) * 8 + 4  # each export's 8 C files, calibration's 4
