"""``khepera-gym export``: a trained policy as ONNX, or as plain C for the real Khepera IV.

A policy network is first reduced to a small description,
:class:`~khepera_gym.robot.export.network.PolicyNetwork`: the observation normalisation
(``VecNormalize`` statistics), how many observations it acts on (a frame stack), a recurrent
policy's LSTM layers, a list of dense layers with their activations, and the transform of the
network's output into an action. Both writers work from that
one description, so the ONNX file and the C code compute the same function. The package, one job a
module:

* :mod:`~khepera_gym.robot.export.network`: the description, and what is supported;
* :mod:`~khepera_gym.robot.export.describe` (with :mod:`~khepera_gym.robot.export.from_sb3`,
  :mod:`~khepera_gym.robot.export.from_rllib` and :mod:`~khepera_gym.robot.export.torch_layers`): a
  stable-baselines3 model (PPO, A2C, SAC, TD3; sb3-contrib's RecurrentPPO) or a Ray RLlib PPO
  checkpoint to that
  description (:data:`SUPPORTED_MODELS`; anything else raises ConfigError naming these);
* :mod:`~khepera_gym.robot.export.robot`: the robot side, read from the env the policy was trained
on:
  its observation layout (the scenario's observed sensors only) and the scenario's constants;
* :mod:`~khepera_gym.robot.export.onnx_writer`: ``policy.onnx`` (opset 13, checked with
  ``onnx.checker``; the ``export`` extra);
* :mod:`~khepera_gym.robot.export.c_writer`: ``policy.c`` (the network:
  :mod:`~khepera_gym.robot.export.c_policy`), ``observation.c``, ``wheel_command.c``, the libkhepera
  template program, ``export_check.c``, a Makefile and a README (templates in
  ``khepera_gym/robot/export/templates/``, C text by :mod:`~khepera_gym.robot.export.c_text`);
* :mod:`~khepera_gym.robot.export.checks`: the exported files against the Python policy and the
  simulator on seeded rollouts (:func:`khepera_gym.rollout.run_episodes`);
* :mod:`~khepera_gym.robot.export.toolchain`: where the C is built and run: here, or for the robot's
  ARM processor with K-Team's flags, under emulation;
* :mod:`~khepera_gym.robot.export.exporter`: :func:`export_policy`, the whole job;
* :mod:`~khepera_gym.robot.export.command`: the ``khepera-gym export`` command line.

Units: the observation is the simulator's (SI units, normalised sensors); wheel commands are
K-Team speed units of 0.678181 mm/s. Threading: everything runs in the calling thread.
"""

from khepera_gym.robot.export.c_writer import C_SOURCES, ROBOT_HEADERS, ROBOT_SOURCES, write_c
from khepera_gym.robot.export.checks import (
    C_FLAGS,
    OBSERVATION_TOLERANCE,
    PARITY_TOLERANCE,
    Recording,
    compile_check_program,
    input_row,
    record_rollouts,
    run_check_program,
)
from khepera_gym.robot.export.command import add_arguments, run_from_args
from khepera_gym.robot.export.describe import (
    ReferencePolicy,
    describe_policy,
    load_model,
    reference_actions,
)
from khepera_gym.robot.export.exporter import (
    FORMATS,
    LAYOUT_FILE,
    MANIFEST_FILE,
    SCENARIO_FILE,
    ExportResult,
    export_policy,
)
from khepera_gym.robot.export.motors import DRIVE_CHOICES, MotorSetting, motor_setting
from khepera_gym.robot.export.network import (
    ACTIVATIONS,
    EXPORT_EXTRA,
    SUPPORTED_MODELS,
    ActionTransform,
    DenseLayer,
    LstmLayer,
    ObservationNormalization,
    PolicyNetwork,
)
from khepera_gym.robot.export.onnx_writer import (
    ONNX_FILE,
    ONNX_OPSET,
    STATE_INPUTS,
    STATE_OUTPUTS,
    build_onnx,
    onnx_actions,
    onnx_inputs,
    onnx_sequence_actions,
)
from khepera_gym.robot.export.robot import RobotInterface, robot_interface, toml_loads
from khepera_gym.robot.export.toolchain import Target, arm_target, host_target

__all__ = [
    "ACTIVATIONS",
    "C_FLAGS",
    "C_SOURCES",
    "DRIVE_CHOICES",
    "EXPORT_EXTRA",
    "FORMATS",
    "LAYOUT_FILE",
    "MANIFEST_FILE",
    "OBSERVATION_TOLERANCE",
    "ONNX_FILE",
    "ONNX_OPSET",
    "PARITY_TOLERANCE",
    "ROBOT_HEADERS",
    "ROBOT_SOURCES",
    "SCENARIO_FILE",
    "STATE_INPUTS",
    "STATE_OUTPUTS",
    "SUPPORTED_MODELS",
    "ActionTransform",
    "DenseLayer",
    "ExportResult",
    "LstmLayer",
    "MotorSetting",
    "ObservationNormalization",
    "PolicyNetwork",
    "Recording",
    "ReferencePolicy",
    "RobotInterface",
    "Target",
    "add_arguments",
    "arm_target",
    "build_onnx",
    "compile_check_program",
    "describe_policy",
    "export_policy",
    "host_target",
    "input_row",
    "load_model",
    "motor_setting",
    "onnx_actions",
    "onnx_inputs",
    "onnx_sequence_actions",
    "record_rollouts",
    "reference_actions",
    "robot_interface",
    "run_check_program",
    "run_from_args",
    "toml_loads",
    "write_c",
]
