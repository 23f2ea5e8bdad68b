"""``khepera-gym export`` of a recurrent policy (sb3-contrib's RecurrentPPO): the C program and
the ONNX graph carry the LSTM's hidden and cell state from step to step, reset at an episode's
start, and act as the Python policy (:class:`khepera_gym.learning.sb3.RecurrentPolicy`, SB3's own
``predict`` with its state) does over whole episodes; bad input fails with messages that say
what to do.

As in tests/test_export.py, parity is measured on seeded rollouts with freshly initialised
networks whose output layer is scaled up so that the actions span the action space; the C is
built with ``cc -O2 -std=c99 -Wall -Wextra -Werror``. The reference is SB3's RecurrentPPO
itself (torch's LSTM), not a second implementation of ours.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("sb3_contrib", reason="needs the sb3 extra: pip install 'khepera-gym[sb3]'")
pytest.importorskip("onnx", reason="needs the export extra: pip install 'khepera-gym[export]'")

import onnx
import torch
from conftest import LATEST
from sb3_contrib import RecurrentPPO
from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize
from test_export import (
    ACTION_TOLERANCE,
    assert_actions_span_the_space,
    compile_check,
    recording_of,
    robot_program_on_fake_robot,
    run_check,
    scale_output_layer,
)

from khepera_gym.envs import nav_heuristic
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.learning.sb3 import FrameStackPolicy, RecurrentPolicy, as_predictor, make_vec_env
from khepera_gym.robot import export

pytestmark = pytest.mark.usefixtures("one_torch_thread")

#: The LSTM's hidden size in these tests.
HIDDEN = 16


def recurrent_ppo(n_lstm_layers: int = 1) -> RecurrentPolicy:
    """An untrained RecurrentPPO on normalised Nav observations (statistics far from (0, 1), as
    after training), as ``load_policy`` gives it back, its output layer scaled up."""
    normalized = VecNormalize(make_vec_env(LATEST["nav"], 4, seed=0))
    normalized.reset()
    rng = np.random.default_rng(0)
    for _ in range(200):
        normalized.step(rng.uniform(-1, 1, (4, 2)).astype(np.float32))
    kwargs = {"lstm_hidden_size": HIDDEN, "n_lstm_layers": n_lstm_layers, "net_arch": [32, 32]}
    model = RecurrentPPO(
        "MlpLstmPolicy", normalized, seed=0, device="cpu", n_steps=64, policy_kwargs=kwargs
    )
    scale_output_layer(model.policy.action_net, 300.0)
    with torch.no_grad():  # gates that open and close: the LSTM's whole range is exercised
        for weight in model.policy.lstm_actor.parameters():
            weight.mul_(4.0)
    normalized.training = False
    return RecurrentPolicy(model, normalized)


@pytest.fixture(scope="module")
def nav_recording() -> export.Recording:
    return recording_of(LATEST["nav"], nav_heuristic)[0]


@pytest.fixture(scope="module", params=[1, 2], ids=["one_layer", "two_layers"])
def exported(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, RecurrentPolicy, export.ExportResult]:
    """A recurrent policy exported to C and ONNX, with the export's own check (one torch
    thread: a module's fixture is set up before the tests' one_torch_thread)."""
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        policy = recurrent_ppo(request.param)
        out = tmp_path_factory.mktemp(f"recurrent_{request.param}")
        result = export.export_policy(policy, out, formats=("c", "onnx"), env_id=LATEST["nav"])
    finally:
        torch.set_num_threads(previous)
    return out, policy, result


def test_a_recurrent_policy_exports_with_its_lstm_state(
    exported: tuple[Path, RecurrentPolicy, export.ExportResult],
    nav_recording: export.Recording,
) -> None:
    out, policy, result = exported
    network = result.network
    layers = policy.model.policy.lstm_actor.num_layers
    assert network.recurrent and len(network.lstm) == layers
    assert network.lstm_hidden_size == HIDDEN and network.frame_stack == 1
    assert network.normalization is not None and network.source == "sb3-contrib RecurrentPPO"
    manifest = json.loads((out / export.MANIFEST_FILE).read_text())
    assert manifest["lstm"] == {"layers": layers, "hidden_size": HIDDEN}
    header = (out / "policy.h").read_text()
    assert f"#define POLICY_LSTM_LAYERS {layers}\n" in header
    assert f"#define POLICY_LSTM_HIDDEN {HIDDEN}\n" in header
    # The export's own check ran the C and ONNX policies over its 10 seeded episodes in order,
    # a fresh state at each start, against the Python policy.
    assert result.checks["observations"] > 1000
    assert result.checks["c_max_abs_error"] < ACTION_TOLERANCE
    assert result.checks["onnx_max_abs_error"] < ACTION_TOLERANCE

    # The same, here, over other recorded episodes. The state matters: from a fresh state at
    # every observation the C is off by far more than the tolerance, and the same at starts.
    observations, starts = nav_recording.observations, nav_recording.starts
    assert starts[0] and 1 < starts.sum() < len(starts)
    expected = export.reference_actions(policy).sequence(observations, starts)
    assert_actions_span_the_space(expected)
    binary = compile_check(out)
    sequence = run_check(binary, "sequence", np.column_stack([starts, observations]))
    assert np.max(np.abs(sequence - expected)) < ACTION_TOLERANCE
    fresh = run_check(binary, "policy", observations)
    np.testing.assert_array_equal(fresh[starts], sequence[starts])
    assert np.max(np.abs(fresh - expected)) > 0.1
    got = export.onnx_sequence_actions(out / export.ONNX_FILE, network, observations, starts)
    assert np.max(np.abs(got - expected)) < ACTION_TOLERANCE


def test_the_state_resets_at_an_episode_start_in_c_and_onnx_as_in_python(
    exported: tuple[Path, RecurrentPolicy, export.ExportResult],
    nav_recording: export.Recording,
) -> None:
    out, policy, result = exported
    observations, starts = nav_recording.observations, nav_recording.starts
    # Without the resets (one long episode) the Python policy acts otherwise at the later
    # episodes' starts, and the exported ones do as it does, both ways.
    once = np.zeros_like(starts)
    once[0] = True
    reset = export.reference_actions(policy).sequence(observations, starts)
    carried = export.reference_actions(policy).sequence(observations, once)
    later = starts.copy()
    later[0] = False
    assert np.max(np.abs(reset[later] - carried[later])) > 0.1
    binary = compile_check(out)
    onnx_file = out / export.ONNX_FILE
    for flags, expected in ((starts, reset), (once, carried)):
        c_actions = run_check(binary, "sequence", np.column_stack([flags, observations]))
        assert np.max(np.abs(c_actions - expected)) < ACTION_TOLERANCE
        onnx_actions = export.onnx_sequence_actions(onnx_file, result.network, observations, flags)
        assert np.max(np.abs(onnx_actions - expected)) < ACTION_TOLERANCE


def test_the_onnx_graph_takes_the_state_and_gives_the_next(
    exported: tuple[Path, RecurrentPolicy, export.ExportResult],
    nav_recording: export.Recording,
) -> None:
    out, policy, result = exported
    model = onnx.load(out / export.ONNX_FILE)
    onnx.checker.check_model(model, full_check=True)
    layers = len(result.network.lstm)

    def shapes(values: Any) -> dict[str, list[Any]]:
        return {
            v.name: [d.dim_param or d.dim_value for d in v.type.tensor_type.shape.dim]
            for v in values
        }

    state = [layers, "N", HIDDEN]
    assert shapes(model.graph.input) == {
        "observation": ["N", result.network.obs_dim],
        "lstm_hidden": state,
        "lstm_cell": state,
    }
    assert shapes(model.graph.output) == {
        "action": ["N", 2],
        "next_lstm_hidden": state,
        "next_lstm_cell": state,
    }
    # A batch of robots in one call: each row's state is its own, as SB3's predict carries it.
    import onnxruntime

    session = onnxruntime.InferenceSession(str(out / export.ONNX_FILE))
    rows = nav_recording.observations[:5]
    zeros = np.zeros((layers, len(rows), HIDDEN), np.float32)
    feeds = {"observation": rows, "lstm_hidden": zeros, "lstm_cell": zeros}
    action, hidden, cell = session.run(None, feeds)
    normalized = policy.normalizer.normalize_obs(rows)
    expected, (want_hidden, want_cell) = policy.model.predict(normalized, None, None, True)
    np.testing.assert_allclose(action, expected, atol=ACTION_TOLERANCE)
    np.testing.assert_allclose(hidden, want_hidden, atol=ACTION_TOLERANCE)
    np.testing.assert_allclose(cell, want_cell, atol=ACTION_TOLERANCE)
    feeds = {"observation": rows, "lstm_hidden": hidden, "lstm_cell": cell}
    second = session.run(["action"], feeds)[0]
    expected, _ = policy.model.predict(normalized, (want_hidden, want_cell), None, True)
    np.testing.assert_allclose(second, expected, atol=ACTION_TOLERANCE)
    # onnx_actions gives every row a fresh state.
    np.testing.assert_array_equal(export.onnx_actions(out / export.ONNX_FILE, rows), action)


def test_the_robot_program_carries_the_lstm_state_across_control_periods(tmp_path: Path) -> None:
    policy = recurrent_ppo(1)
    export.export_policy(policy, tmp_path, env_id=LATEST["nav"], check=False)
    out = tmp_path
    # On the fake robot's constant readings its actions are the Python policy's on that
    # observation repeated, which the LSTM state makes change from step to step.
    program = robot_program_on_fake_robot(out)
    run = subprocess.run(
        [str(program), "1.0", "0.5", "6"], capture_output=True, text=True, check=True, timeout=10
    )
    actions = np.array([[float(v) for v in line.split()[4:6]] for line in run.stdout.splitlines()])
    binary = compile_check(out)
    ir_raw = [100 + 60 * i for i in range(8)]
    us_cm = [25, 1000, 80, 2000, 0]
    speeds = [np.float32(units) * np.float32(0.678181) / np.float32(1000) for units in (300, -200)]
    row = [*ir_raw, *us_cm, *speeds, 0.0, 0.0, 0.0, 1.0, 0.5]
    observation = run_check(binary, "observation", [row])
    repeated = np.repeat(observation, 6, axis=0)
    want = export.reference_actions(policy).sequence(repeated, np.arange(6) == 0)
    np.testing.assert_allclose(actions, want, atol=6e-5)  # the program prints 4 decimals
    assert np.max(np.abs(want[1:] - want[0])) > 1e-2


def test_what_a_recurrent_export_cannot_do_is_refused(tmp_path: Path) -> None:
    policy = recurrent_ppo()
    network = export.describe_policy(policy)
    lstm = network.lstm[0]
    # Shapes that do not chain, NaN weights, gSDE, a frame stack on top of the LSTM.
    with pytest.raises(KheperaError, match="LSTM layer 0 takes 18 inputs, not 36"):
        dataclasses.replace(network, frame_stack=2)
    with pytest.raises(KheperaError, match=r"LSTM weight_hidden has shape \(60, 16\), not \(64"):
        dataclasses.replace(lstm, weight_hidden=lstm.weight_hidden[:60])
    poisoned = lstm.bias_input.copy()
    poisoned[3] = np.nan
    with pytest.raises(ConfigError, match=r"LSTM layer 0 .* has NaN/inf"):
        dataclasses.replace(network, lstm=(dataclasses.replace(lstm, bias_input=poisoned),))
    wider = dataclasses.replace(
        lstm,
        weight_input=np.zeros((128, HIDDEN), np.float32),
        weight_hidden=np.zeros((128, 32), np.float32),
        bias_input=np.zeros(128, np.float32),
        bias_hidden=np.zeros(128, np.float32),
    )
    with pytest.raises(KheperaError, match="one hidden size"):
        dataclasses.replace(network, lstm=(lstm, wider))
    env = make_vec_env(LATEST["nav"], 2, seed=0)
    sde = RecurrentPPO("MlpLstmPolicy", env, use_sde=True, n_steps=64, device="cpu")
    with pytest.raises(ConfigError, match=r"gSDE.*supported are"):
        export.describe_policy(sde)
    stacked = RecurrentPPO("MlpLstmPolicy", VecFrameStack(env, 2), n_steps=64, device="cpu")
    with pytest.raises(ConfigError, match="stacked observations"):
        export.describe_policy(FrameStackPolicy(stacked, 2))
    with pytest.raises(ConfigError, match="keeps its memory in its LSTM"):
        as_predictor(stacked, None, frame_stack=2)
    with pytest.raises(ConfigError, match="takes observations of 18 values"):
        policy.predict(np.zeros(17, np.float32))


def test_a_recurrent_policy_exported_sampling_its_actions_draws_around_its_lstm_mean(
    tmp_path: Path, nav_recording: export.Recording
) -> None:
    policy = recurrent_ppo()
    with torch.no_grad():  # a σ that moves the actions
        policy.model.policy.log_std.fill_(np.log(0.3))
    result = export.export_policy(policy, tmp_path, env_id=LATEST["nav"], sample_seed=3)
    assert result.checks["c_max_abs_error"] < ACTION_TOLERANCE  # its mean, over whole episodes
    binary = compile_check(tmp_path)
    observations, starts = nav_recording.observations, nav_recording.starts
    rows = np.column_stack([starts, observations])
    text = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in rows) + "\n"

    def sample() -> np.ndarray:
        run = subprocess.run(
            [str(binary), "sample", "3"], input=text, capture_output=True, text=True, check=True
        )
        return np.array([[float(v) for v in line.split()] for line in run.stdout.splitlines()])

    draws = sample()
    np.testing.assert_array_equal(draws, sample())  # the same seed, the same draws
    mean = export.reference_actions(policy).sequence(observations, starts)
    assert draws.shape == mean.shape and np.std(draws - mean) > 0.1
