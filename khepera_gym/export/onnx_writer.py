"""The ONNX writer: :func:`build_onnx` makes the ONNX graph of a
:class:`~khepera_gym.export.network.PolicyNetwork` with ``onnx.helper``, and :func:`onnx_actions`
runs an exported file with onnxruntime (the check).

The graph has input ``"observation"`` float32 (N, frame_stack * obs_dim) and output ``"action"``
float32 (N, action_dim), operator set :data:`ONNX_OPSET` and IR version :data:`ONNX_IR_VERSION` (so
older runtimes, as on small robots, load it), and is checked with ``onnx.checker``. The
normalisation runs in float64 as stable-baselines3's does, the layers in float32.

A policy trained on stacked observations (``frame_stack`` n > 1) takes its last n raw
observations, oldest first; each is normalised in the graph. Before an episode's first
observation the stack holds what normalises to zero, as in training: the normalisation's mean
(zeros without one). :func:`onnx_inputs` builds these rows from an episode's observations.

onnx and onnxruntime come with the ``export`` extra and are imported when called.
Threading: onnxruntime uses its own thread pool inside ``run``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym
from khepera_gym.export.network import EXPORT_EXTRA, PolicyNetwork

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


def build_onnx(network: PolicyNetwork, metadata: Mapping[str, str] | None = None) -> Any:
    """The ONNX ``ModelProto`` of ``network``, checked with ``onnx.checker``.

    Input ``"observation"`` float32 (N, input_dim: ``frame_stack`` observations), output
    ``"action"`` float32 (N, action_dim). The normalisation runs in float64 (as SB3's does), the
    rest in float32.

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
    graph = helper.make_graph(
        nodes,
        "khepera_gym_policy",
        [helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["N", network.input_dim])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["N", network.action_dim])],
        initializer=initializers,
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


def onnx_actions(path: str | Path, observations: npt.NDArray[np.float32]) -> npt.NDArray[Any]:
    """Runs an exported ONNX policy with onnxruntime on input rows (N, input_dim): observations,
    or for a frame-stacked policy the rows of :func:`onnx_inputs`.

    Raises:
        ImportError: onnxruntime is not installed (the message names the pip command).
    """
    try:
        import onnxruntime
    except ImportError as error:
        raise ImportError(f"running ONNX needs onnxruntime: {EXPORT_EXTRA}") from error
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    batch = np.ascontiguousarray(observations, dtype=np.float32)
    return np.asarray(session.run(["action"], {"observation": batch})[0])


__all__ = [
    "ONNX_FILE",
    "ONNX_IR_VERSION",
    "ONNX_OPSET",
    "build_onnx",
    "import_onnx",
    "onnx_actions",
    "onnx_inputs",
]
