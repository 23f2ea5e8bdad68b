"""The real robot: take a trained policy or a calibration to a Khepera IV.

* ``khepera-gym export`` and ``robot-program`` (:mod:`~khepera_gym.robot.export`): a policy as
  C for the robot's processor or as ONNX, with its parity checks;
* ``khepera-gym calibrate`` and ``replay`` (:mod:`~khepera_gym.robot.calibrate`): the robot
  programs that log a real robot, and the fit of the scenario keys to those logs.

Layer: above the env library, :mod:`khepera_gym.tooling` and :mod:`khepera_gym.learning` (it
exports learned policies) and :mod:`khepera_gym.analysis` (its reports plot trajectories).
"""
