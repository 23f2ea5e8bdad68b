"""The network as C: ``policy.c`` and ``policy.h`` of a
:class:`~khepera_gym.robot.export.network.PolicyNetwork` (:func:`policy_c_sources`).

``policy.c`` holds the weights as ``const float`` arrays and
``int policy_step(policy_state *state, const float *observation, float *action)``, with the
policy's memory in ``policy_state``: its frame stack, and for a recurrent policy its LSTM
layers' hidden and cell states (zeros after ``policy_reset``, at an episode's start);
``policy_forward`` is a step from a fresh state; with the policy's σ, ``policy_sample_step``
samples the action as in training (``sampling.c``). Dense layers and LSTM gates add in double
and round once to float. No allocation; libm for tanhf/expf (and sqrt, log, cos to sample) only.
Threading: none.
"""

from __future__ import annotations

import khepera_gym
from khepera_gym.errors import ConfigError
from khepera_gym.robot.export.c_text import c_array, c_double, c_float, load_template
from khepera_gym.robot.export.network import PolicyNetwork

#: C expressions of the activations, of ``{x}`` (and ``{alpha}``).
_C_ACTIVATIONS = {
    "tanh": "tanhf({x})",
    "relu": "({x} > 0.0f ? {x} : 0.0f)",
    "elu": "({x} > 0.0f ? {x} : {alpha} * (expf({x}) - 1.0f))",
    "leaky_relu": "({x} > 0.0f ? {x} : {alpha} * {x})",
    "silu": "({x} / (1.0f + expf(-{x})))",
}


def _policy_constants(network: PolicyNetwork) -> str:
    """The C definitions of the normalisation statistics, weights and action transform."""
    parts = []
    norm = network.normalization
    if norm is not None:
        parts.append(
            "/* VecNormalize statistics: clip((obs - mean) / sqrt(var + epsilon)), in double as\n"
            f" * stable-baselines3 computes it (epsilon {norm.epsilon:g} is in OBS_STD). */\n"
            f"#define OBS_CLIP {c_double(norm.clip)}\n"
            "static const double OBS_MEAN[POLICY_OBS_DIM] = {\n    "
            f"{c_array(c_double(v) for v in norm.mean)}\n}};\n"
            "static const double OBS_STD[POLICY_OBS_DIM] = {\n    "
            f"{c_array(c_double(v) for v in norm.std)}\n}};\n"
        )
    parts += _lstm_constants(network)
    for index, layer in enumerate(network.layers):
        rows = ",\n".join(
            "    {" + c_array((c_float(v) for v in row), indent="     ") + "}"
            for row in layer.weight
        )
        bias = c_array(c_float(v) for v in layer.bias)
        parts.append(
            f"/* Layer {index}: {layer.inputs} -> {layer.outputs}, {layer.activation}. */\n"
            f"static const float LAYER{index}_WEIGHT[{layer.outputs}][{layer.inputs}] = {{\n"
            f"{rows}\n}};\n"
            f"static const float LAYER{index}_BIAS[{layer.outputs}] = {{\n    {bias}\n}};\n"
        )
    transform = network.action
    if transform.is_affine:
        parts.append(
            "/* The action: ACTION_SCALE * output + ACTION_OFFSET (to the action bounds). */\n"
            "static const float ACTION_SCALE[POLICY_ACTION_DIM] = {"
            f"{', '.join(c_float(v) for v in transform.scale)}}};\n"
            "static const float ACTION_OFFSET[POLICY_ACTION_DIM] = {"
            f"{', '.join(c_float(v) for v in transform.offset)}}};\n"
        )
    if transform.low is not None and transform.high is not None:
        parts.append(
            "/* The action's bounds (the action space): it is clipped to them. */\n"
            "static const float ACTION_LOW[POLICY_ACTION_DIM] = {"
            f"{', '.join(c_float(v) for v in transform.low)}}};\n"
            "static const float ACTION_HIGH[POLICY_ACTION_DIM] = {"
            f"{', '.join(c_float(v) for v in transform.high)}}};\n"
        )
    return "\n".join(parts)


def _lstm_constants(network: PolicyNetwork) -> list[str]:
    """The C definitions of the LSTM layers' weights and biases (none without LSTM)."""
    parts = []
    for index, lstm in enumerate(network.lstm):
        gates, hidden = 4 * lstm.hidden_size, lstm.hidden_size
        arrays = []
        for name, matrix in (("INPUT", lstm.weight_input), ("HIDDEN", lstm.weight_hidden)):
            rows = ",\n".join(
                "    {" + c_array((c_float(v) for v in row), indent="     ") + "}" for row in matrix
            )
            arrays.append(
                f"static const float LSTM{index}_WEIGHT_{name}[{gates}][{matrix.shape[1]}] = "
                f"{{\n{rows}\n}};\n"
            )
        for name, bias in (("INPUT", lstm.bias_input), ("HIDDEN", lstm.bias_hidden)):
            values = c_array(c_float(v) for v in bias)
            arrays.append(
                f"static const float LSTM{index}_BIAS_{name}[{gates}] = {{\n    {values}\n}};\n"
            )
        parts.append(
            f"/* LSTM layer {index}: {lstm.inputs} -> {hidden} (hidden and cell state of "
            f"{hidden}); gate rows in torch's order: input, forget, cell, output. */\n"
            + "".join(arrays)
        )
    return parts


#: policy.c's LSTM layer (only in a recurrent policy's: an unused static function would warn).
_LSTM_LAYER = """
static float sigmoid(float x)
{
    return 1.0f / (1.0f + expf(-x));
}

/* One LSTM layer, torch.nn.LSTM's equations: the gates from the input and the layer's hidden
 * state (each accumulated in double as dense() does and rounded once to float), then the new
 * cell state c = f c + i g and hidden state h = o tanh(c), also written to `output`. */
static void lstm_layer(const float *weight_input, const float *weight_hidden,
                       const float *bias_input, const float *bias_hidden, int inputs,
                       const float *input, float *hidden, float *cell, float *output)
{
    float gates[4 * POLICY_LSTM_HIDDEN];
    int o;
    int i;
    for (o = 0; o < 4 * POLICY_LSTM_HIDDEN; ++o) {
        const float *row_input = weight_input + o * inputs;
        const float *row_hidden = weight_hidden + o * POLICY_LSTM_HIDDEN;
        double sum = (double)bias_input[o] + (double)bias_hidden[o];
        for (i = 0; i < inputs; ++i) {
            sum += (double)row_input[i] * (double)input[i];
        }
        for (i = 0; i < POLICY_LSTM_HIDDEN; ++i) {
            sum += (double)row_hidden[i] * (double)hidden[i];
        }
        gates[o] = (float)sum;
    }
    for (o = 0; o < POLICY_LSTM_HIDDEN; ++o) {
        const float input_gate = sigmoid(gates[o]);
        const float forget_gate = sigmoid(gates[POLICY_LSTM_HIDDEN + o]);
        const float candidate = tanhf(gates[2 * POLICY_LSTM_HIDDEN + o]);
        const float output_gate = sigmoid(gates[3 * POLICY_LSTM_HIDDEN + o]);
        cell[o] = forget_gate * cell[o] + input_gate * candidate;
        hidden[o] = output_gate * tanhf(cell[o]);
        output[o] = hidden[o];
    }
}
"""


def _lstm_steps(network: PolicyNetwork, source: str, target: str) -> tuple[list[str], str, str]:
    """The statements of ``policy_output`` that run the LSTM layers on ``source`` (their
    states updated in ``state``), and the buffers (source, target) after them."""
    lines = []
    for index, lstm in enumerate(network.lstm):
        offset = index * lstm.hidden_size
        lines += [
            f"    lstm_layer(&LSTM{index}_WEIGHT_INPUT[0][0], &LSTM{index}_WEIGHT_HIDDEN[0][0],",
            f"               LSTM{index}_BIAS_INPUT, LSTM{index}_BIAS_HIDDEN, {lstm.inputs}, "
            f"{source},",
            f"               state->lstm_hidden + {offset}, state->lstm_cell + {offset}, "
            f"{target});",
        ]
        source, target = target, source
    return lines, source, target


def _state_fields(network: PolicyNetwork) -> dict[str, str]:
    """policy.h's LSTM declarations and policy.c's reset of the LSTM state."""
    if not network.recurrent:
        return {"lstm_state": "", "lstm_reset": "", "lstm_layer": ""}
    return {
        "lstm_state": (
            "    /* The LSTM layers' hidden and cell states, layer after layer (zeros before the\n"
            "     * episode's first observation). */\n"
            "    float lstm_hidden[POLICY_LSTM_LAYERS * POLICY_LSTM_HIDDEN];\n"
            "    float lstm_cell[POLICY_LSTM_LAYERS * POLICY_LSTM_HIDDEN];\n"
        ),
        "lstm_reset": (
            "    for (i = 0; i < POLICY_LSTM_LAYERS * POLICY_LSTM_HIDDEN; ++i) {\n"
            "        state->lstm_hidden[i] = 0.0f;\n"
            "        state->lstm_cell[i] = 0.0f;\n"
            "    }\n"
        ),
        "lstm_layer": _LSTM_LAYER,
    }


def _policy_forward(network: PolicyNetwork) -> str:
    """The statements of ``policy_step``: the stack's shift, the new observation's
    normalisation, LSTM layers, dense layers, action transform."""
    lines = []
    if network.frame_stack > 1:
        lines += [
            "    /* The stack moves by one observation: the oldest goes. */",
            "    for (i = 0; i < (POLICY_FRAME_STACK - 1) * POLICY_OBS_DIM; ++i) {",
            "        state->frames[i] = state->frames[i + POLICY_OBS_DIM];",
            "    }",
        ]
    lines.append("    for (i = 0; i < POLICY_OBS_DIM; ++i) {")
    if network.normalization is not None:
        lines += [
            "        double value = ((double)observation[i] - OBS_MEAN[i]) / OBS_STD[i];",
            "        value = value < -OBS_CLIP ? -OBS_CLIP : value;",
            "        value = value > OBS_CLIP ? OBS_CLIP : value;",
            "        newest[i] = (float)value;",
        ]
    else:
        lines.append("        newest[i] = observation[i];")
    lines += [
        "    }",
        "    for (i = 0; i < POLICY_FRAME_STACK * POLICY_OBS_DIM; ++i) {",
        "        buffer_a[i] = state->frames[i];",
        "    }",
    ]
    recurrent, source, target = _lstm_steps(network, "buffer_a", "buffer_b")
    lines += recurrent
    for index, layer in enumerate(network.layers):
        lines.append(
            f"    dense(&LAYER{index}_WEIGHT[0][0], LAYER{index}_BIAS, {layer.inputs}, "
            f"{layer.outputs}, {source}, {target});"
        )
        if layer.activation != "identity":
            x = f"{target}[i]"
            expression = _C_ACTIVATIONS[layer.activation].format(x=x, alpha=c_float(layer.alpha))
            lines += [
                f"    for (i = 0; i < {layer.outputs}; ++i) {{",
                f"        {x} = {expression};",
                "    }",
            ]
        source, target = target, source
    lines += [
        "    for (i = 0; i < POLICY_ACTION_DIM; ++i) {",
        f"        float value = {source}[i];",
    ]
    if network.action.is_affine:
        lines.append("        value = ACTION_SCALE[i] * value + ACTION_OFFSET[i];")
    lines += ["        action[i] = value;", "    }"]
    return "\n".join(lines)


def _action_clip(network: PolicyNetwork) -> str:
    """The statements of ``clip_action``: the action to its bounds, when it has some."""
    if network.action.low is None:
        return "    (void)action; /* the action transform ends in the bounds: nothing to clip */"
    return "\n".join(
        [
            "    int i;",
            "    for (i = 0; i < POLICY_ACTION_DIM; ++i) {",
            "        if (action[i] < ACTION_LOW[i]) {",
            "            action[i] = ACTION_LOW[i];",
            "        } else if (action[i] > ACTION_HIGH[i]) {",
            "            action[i] = ACTION_HIGH[i];",
            "        }",
            "    }",
        ]
    )


def _sampling_fields(network: PolicyNetwork) -> dict[str, str]:
    """policy.h's declarations and policy.c's code of sampled actions: the whole of
    ``sampling.c`` when the network knows its Gaussian's σ, else a note."""
    if network.action_std is None:
        note = (
            "#define POLICY_SAMPLES 0 /* this policy's action noise is not exported (only PPO's "
            "and A2C's state-independent σ is): policy_step gives its deterministic action */"
        )
        return {"sampling_api": note, "sampling": ""}
    std = ", ".join(c_float(v) for v in network.action_std)
    return {
        "sampling_api": load_template("sampling.h").template,
        "sampling": load_template("sampling.c").substitute(action_std=std),
    }


def policy_c_sources(network: PolicyNetwork, provenance: str) -> dict[str, str]:
    """``policy.h`` and ``policy.c`` of ``network`` (file name → text)."""
    widths = [network.input_dim, *(lstm.hidden_size for lstm in network.lstm)]
    widths += [layer.outputs for layer in network.layers]
    fields = {
        "source": network.source,
        "version": khepera_gym.__version__,
        "provenance": provenance,
        "obs_dim": network.obs_dim,
        "frame_stack": network.frame_stack,
        "action_dim": network.action_dim,
        "lstm_layers": len(network.lstm),
        "lstm_hidden": network.lstm_hidden_size,
        "kind": ("LSTM then dense layers " if network.recurrent else "dense layers ")
        + " -> ".join(str(width) for width in widths),
        "max_width": network.max_width,
        "constants": _policy_constants(network),
        "forward": _policy_forward(network),
        "clip": _action_clip(network),
        **_sampling_fields(network),
        **_state_fields(network),
    }
    return {name: load_template(name).substitute(fields) for name in ("policy.h", "policy.c")}


def check_sampling(network: PolicyNetwork, seed: int) -> None:
    """Raises ConfigError unless ``network`` can be exported sampling its actions with ``seed``:
    it knows its Gaussian's σ, and ``seed`` is an int in [0, 2^64) (the C generator's state)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**64:
        raise ConfigError(f"the sampling seed must be an integer in [0, 2^64), got {seed!r}")
    if network.action_std is None:
        raise ConfigError(
            f"the {network.source} policy's action noise cannot be exported (only PPO's and "
            "A2C's state-independent σ can, not gSDE's): export it without --sample-actions"
        )


__all__ = ["check_sampling", "policy_c_sources"]
