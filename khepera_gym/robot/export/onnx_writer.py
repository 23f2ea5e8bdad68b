"""The ONNX writer: :func:`build_onnx` makes the ONNX graph of a
:class:`~khepera_gym.robot.export.network.PolicyNetwork` with ``onnx.helper``, and
:func:`onnx_actions` runs an exported file with onnxruntime (the check).

The graph has input ``"observation"`` float32 (N, frame_stack * obs_dim) and output ``"action"``
float32 (N, action_dim), operator set :data:`ONNX_OPSET` and IR version :data:`ONNX_IR_VERSION` (so
older runtimes, as on small robots, load it), and is checked with ``onnx.checker``. The
normalisation runs in float64 as stable-baselines3's does, the layers in float32.

A policy trained on stacked observations (``frame_stack`` n > 1) takes its last n raw
observations, oldest first; each is normalised in the graph. Before an episode's first
observation the stack holds what normalises to zero, as in training: the normalisation's mean
(zeros without one). :func:`onnx_inputs` builds these rows from an episode's observations.

A recurrent policy's graph (LSTM layers, ONNX's ``LSTM`` operator) also takes its state,
inputs ``"lstm_hidden"`` and ``"lstm_cell"`` float32 (layers, N, hidden), and gives the next one,
outputs ``"next_lstm_hidden"`` and ``"next_lstm_cell"``: the caller feeds each step's outputs back
into the next step, and zeros at an episode's start (SB3's ``episode_start``).
:func:`onnx_sequence_actions` runs a graph so over consecutive observations.

onnx and onnxruntime come with the ``export`` extra and are imported when called.
Threading: onnxruntime uses its own thread pool inside ``run``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym
from khepera_gym.robot.export.network import EXPORT_EXTRA, PolicyNetwork

#: ONNX operator set of the exported graph: every operator used exists in this form since
#: opset 13, and older runtimes (as on small robots) load it.
ONNX_OPSET = 13
#: ONNX IR version written (7 goes with opset 13; older runtimes reject newer IR versions).
ONNX_IR_VERSION = 7
#: The exported file's name.
ONNX_FILE = "policy.onnx"


def import_onnx() -> Any:
    """The onnx module; ImportError naming the pip command without it."""
    try:
        import onnx
    except ImportError as error:
        raise ImportError(f"writing ONNX needs the onnx package: {EXPORT_EXTRA}") from error
    return onnx


#: The recurrent state's inputs and outputs (hidden, cell) of a recurrent policy's graph.
STATE_INPUTS = ("lstm_hidden", "lstm_cell")
STATE_OUTPUTS = ("next_lstm_hidden", "next_lstm_cell")
#: torch's gate blocks (input, forget, cell, output) in ONNX's LSTM order (input, output,
#: forget, cell).
_ONNX_GATE_ORDER = (0, 3, 1, 2)


def _onnx_gates(array: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """torch's gate rows (4 H, ...) in ONNX's order."""
    blocks = np.split(np.asarray(array, np.float32), 4, axis=0)
    return np.concatenate([blocks[k] for k in _ONNX_GATE_ORDER], axis=0)


def _lstm_nodes(
    network: PolicyNetwork,
    current: str,
    constant: Callable[..., str],
    node: Callable[..., str],
    nodes: list[Any],
) -> str:
    """Appends the LSTM layers' nodes (ONNX's ``LSTM`` operator, one time step: each layer's
    state sliced from :data:`STATE_INPUTS`, the next ones joined into :data:`STATE_OUTPUTS`) and
    returns the last layer's output (N, hidden); ``current`` itself without LSTM layers."""
    from onnx import helper

    states: dict[str, list[str]] = {name: [] for name in STATE_OUTPUTS}
    layers = len(network.lstm)
    for index, lstm in enumerate(network.lstm):
        hidden = lstm.hidden_size
        axis0 = constant("axis0", [0], np.int64) if index == 0 else "axis0"
        sequence = node("Unsqueeze", [current, axis0], f"lstm{index}_sequence")
        initial = list(STATE_INPUTS)
        if layers > 1:  # this layer's (1, N, H) of the (layers, N, H) state
            start = constant(f"lstm{index}_start", [index], np.int64)
            stop = constant(f"lstm{index}_stop", [index + 1], np.int64)
            initial = [
                node("Slice", [name, start, stop, axis0], f"lstm{index}_{name}")
                for name in STATE_INPUTS
            ]
        weight = constant(f"lstm{index}_weight", _onnx_gates(lstm.weight_input)[None])
        recurrence = constant(f"lstm{index}_recurrence", _onnx_gates(lstm.weight_hidden)[None])
        bias = np.concatenate([_onnx_gates(lstm.bias_input), _onnx_gates(lstm.bias_hidden)])
        outputs = [f"lstm{index}_all", f"lstm{index}_hidden", f"lstm{index}_cell"]
        nodes.append(
            helper.make_node(
                "LSTM",
                [
                    sequence,
                    weight,
                    recurrence,
                    constant(f"lstm{index}_bias", bias[None]),
                    "",
                    *initial,
                ],
                outputs,
                name=f"lstm{index}",
                hidden_size=hidden,
            )
        )
        states[STATE_OUTPUTS[0]].append(outputs[1])
        states[STATE_OUTPUTS[1]].append(outputs[2])
        current = node("Squeeze", [outputs[1], axis0], f"lstm{index}_output")
    for name, parts in states.items():
        if parts:
            nodes.append(
                helper.make_node("Concat", parts, [name], name=name, axis=0)
                if len(parts) > 1
                else helper.make_node("Identity", parts, [name], name=name)
            )
    return current


def build_onnx(network: PolicyNetwork, metadata: Mapping[str, str] | None = None) -> Any:
    """The ONNX ``ModelProto`` of ``network``, checked with ``onnx.checker``.

    Input ``"observation"`` float32 (N, input_dim: ``frame_stack`` observations), output
    ``"action"`` float32 (N, action_dim); for a recurrent policy also the state in and out
    (:data:`STATE_INPUTS`, :data:`STATE_OUTPUTS`: float32 (layers, N, hidden)). The
    normalisation runs in float64 (as SB3's does), the rest in float32.

    Raises:
        ImportError: onnx is not installed (the message names the pip command).
    """
    onnx = import_onnx()
    from onnx import TensorProto, helper, numpy_helper

    nodes: list[Any] = []
    initializers: list[Any] = []

    def constant(name: str, values: npt.ArrayLike, dtype: Any = np.float32) -> str:
        initializers.append(numpy_helper.from_array(np.asarray(values, dtype), name))
        return name

    def node(op: str, inputs: list[str], output: str, **attributes: Any) -> str:
        nodes.append(helper.make_node(op, inputs, [output], name=output, **attributes))
        return output

    current = "observation"
    norm = network.normalization
    stack = network.frame_stack
    if norm is not None:
        mean, std = np.tile(norm.mean, stack), np.tile(norm.std, stack)  # the same for each frame
        current = node("Cast", [current], "observation_f64", to=TensorProto.DOUBLE)
        current = node("Sub", [current, constant("obs_mean", mean, np.float64)], "centred")
        current = node("Div", [current, constant("obs_std", std, np.float64)], "scaled")
        current = node("Max", [current, constant("obs_low", [-norm.clip], np.float64)], "lower")
        current = node("Min", [current, constant("obs_high", [norm.clip], np.float64)], "upper")
        current = node("Cast", [current], "normalized", to=TensorProto.FLOAT)
    current = _lstm_nodes(network, current, constant, node, nodes)
    for index, layer in enumerate(network.layers):
        weight = constant(f"layer{index}_weight", layer.weight)
        bias = constant(f"layer{index}_bias", layer.bias)
        current = node("Gemm", [current, weight, bias], f"layer{index}_linear", transB=1)
        out = f"layer{index}_{layer.activation}"
        if layer.activation == "tanh":
            current = node("Tanh", [current], out)
        elif layer.activation == "relu":
            current = node("Relu", [current], out)
        elif layer.activation == "elu":
            current = node("Elu", [current], out, alpha=layer.alpha)
        elif layer.activation == "leaky_relu":
            current = node("LeakyRelu", [current], out, alpha=layer.alpha)
        elif layer.activation == "silu":
            gate = node("Sigmoid", [current], f"layer{index}_gate")
            current = node("Mul", [current, gate], out)
    transform = network.action
    if transform.is_affine:
        current = node("Mul", [current, constant("action_scale", transform.scale)], "scaled_action")
        current = node("Add", [current, constant("action_offset", transform.offset)], "shifted")
    if transform.low is not None and transform.high is not None:
        current = node("Max", [current, constant("action_low", transform.low)], "above_low")
        current = node("Min", [current, constant("action_high", transform.high)], "action")
    else:
        current = node("Identity", [current], "action")
    inputs = [
        helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["N", network.input_dim])
    ]
    outputs = [
        helper.make_tensor_value_info("action", TensorProto.FLOAT, ["N", network.action_dim])
    ]
    if network.recurrent:
        shape = [len(network.lstm), "N", network.lstm_hidden_size]
        inputs += [helper.make_tensor_value_info(n, TensorProto.FLOAT, shape) for n in STATE_INPUTS]
        outputs += [
            helper.make_tensor_value_info(n, TensorProto.FLOAT, shape) for n in STATE_OUTPUTS
        ]
    graph = helper.make_graph(
        nodes, "khepera_gym_policy", inputs, outputs, initializer=initializers
    )
    model = helper.make_model(
        graph,
        producer_name="khepera_gym",
        producer_version=khepera_gym.__version__,
        opset_imports=[helper.make_opsetid("", ONNX_OPSET)],
        ir_version=ONNX_IR_VERSION,
    )
    model.doc_string = f"{network.source} policy exported by khepera_gym"
    for key, text in (metadata or {}).items():
        model.metadata_props.add(key=key, value=text)
    onnx.checker.check_model(model, full_check=True)
    return model


def onnx_inputs(
    network: PolicyNetwork,
    observations: npt.NDArray[np.float32],
    starts: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.float32]:
    """The ONNX graph's input rows (N, input_dim) for one robot's consecutive observations
    (N, obs_dim): row t stacks observations t-n+1 .. t, oldest first, with the pad (the
    normalisation's mean, or zeros) in place of those before the episode's start. ``starts``
    (N,) marks each episode's first observation (None: the first row only).
    """
    rows = np.asarray(observations, np.float32)
    stack = network.frame_stack
    if stack == 1:
        return rows
    norm = network.normalization
    pad = np.zeros(network.obs_dim, np.float32) if norm is None else norm.mean.astype(np.float32)
    begins = np.zeros(len(rows), bool) if starts is None else np.array(starts, bool)
    if len(begins):
        begins[0] = True
    stacked = np.empty((len(rows), network.input_dim), np.float32)
    frames = np.tile(pad, stack)
    for t, (row, begin) in enumerate(zip(rows, begins, strict=True)):
        if begin:
            frames = np.tile(pad, stack)
        frames = np.concatenate([frames[network.obs_dim :], row])
        stacked[t] = frames
    return stacked


def _session(path: str | Path) -> Any:
    """An onnxruntime session of the file on the CPU; ImportError naming the pip command."""
    try:
        import onnxruntime
    except ImportError as error:
        raise ImportError(f"running ONNX needs onnxruntime: {EXPORT_EXTRA}") from error
    return onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])


def onnx_actions(path: str | Path, observations: npt.NDArray[np.float32]) -> npt.NDArray[Any]:
    """Runs an exported ONNX policy with onnxruntime on input rows (N, input_dim): observations,
    or for a frame-stacked policy the rows of :func:`onnx_inputs`. A recurrent policy's graph
    gets a fresh state (zeros) for every row: the actions of episodes' first observations
    (:func:`onnx_sequence_actions` carries the state).

    Raises:
        ImportError: onnxruntime is not installed (the message names the pip command).
    """
    session = _session(path)
    batch = np.ascontiguousarray(observations, dtype=np.float32)
    feeds = {"observation": batch}
    for state in session.get_inputs()[1:]:
        feeds[state.name] = np.zeros((state.shape[0], len(batch), state.shape[2]), np.float32)
    return np.asarray(session.run(["action"], feeds)[0])


def onnx_sequence_actions(
    path: str | Path,
    network: PolicyNetwork,
    observations: npt.NDArray[np.float32],
    starts: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.float32]:
    """The actions of an exported ONNX policy over one robot's consecutive raw observations
    (N, obs_dim), as a robot runs it: frame stacks built by :func:`onnx_inputs`; a recurrent
    policy run step by step, each step's state fed back into the next, zeros where ``starts``
    (N,) marks an episode's first observation (None: the first row only).

    Raises:
        ImportError: onnxruntime is not installed (the message names the pip command).
    """
    rows = onnx_inputs(network, observations, starts)
    if not network.recurrent:
        return np.asarray(onnx_actions(path, rows), np.float32)
    session = _session(path)
    begins = np.zeros(len(rows), bool) if starts is None else np.array(starts, bool)
    shape = (len(network.lstm), 1, network.lstm_hidden_size)
    hidden = cell = np.zeros(shape, np.float32)
    actions = np.empty((len(rows), network.action_dim), np.float32)
    for t, row in enumerate(rows):
        if t == 0 or begins[t]:
            hidden = cell = np.zeros(shape, np.float32)
        feeds = {"observation": row[None], STATE_INPUTS[0]: hidden, STATE_INPUTS[1]: cell}
        action, hidden, cell = session.run(["action", *STATE_OUTPUTS], feeds)
        actions[t] = action[0]
    return actions


__all__ = [
    "ONNX_FILE",
    "ONNX_IR_VERSION",
    "ONNX_OPSET",
    "STATE_INPUTS",
    "STATE_OUTPUTS",
    "build_onnx",
    "import_onnx",
    "onnx_actions",
    "onnx_inputs",
    "onnx_sequence_actions",
]
