"""Closing the loop with the real robot: log on the bench, calibrate the simulator from the log,
replay it.

The exported policy program logs every control step with ``--log FILE``, and
``khepera-gym robot-program calibrate`` writes a program that drives a scripted manoeuvre on the
bench and logs the same format. ``khepera-gym calibrate`` fits the simulator's parameters to
such logs by replaying them through the simulator, and writes a scenario (each value with its
uncertainty, optionally ranges for domain randomisation) and a report; ``khepera-gym replay``
compares a log with the simulator driven by the same commands. One job a module:

* :mod:`~khepera_gym.robot.calibrate.logformat`: the robot log (CSV, format 1): reading, checking,
  writing;
* :mod:`~khepera_gym.robot.calibrate.schedule`: the calibration manoeuvre as data and its state
  machine (the C program runs the same);
* :mod:`~khepera_gym.robot.calibrate.program`: the calibration program as C
  (``khepera-gym robot-program calibrate``);
* :mod:`~khepera_gym.robot.calibrate.replay`: replays of a log through the simulator, by its
commands
  or along its encoders' path, on the log's times (:mod:`~khepera_gym.robot.calibrate.timing`), and
  the divergence of a replay (:mod:`~khepera_gym.robot.calibrate.divergence`);
* :mod:`~khepera_gym.robot.calibrate.synthetic`: logs made by the simulator with known parameters
(the
  tests' robot), and the real robots' spread;
* :mod:`~khepera_gym.robot.calibrate.independent`: logs of a second model of the robot, written from
  K-Team's manual and sharing no code with the simulator, with the program's state machine
  transcribed from the C (:mod:`~khepera_gym.robot.calibrate.independent_program`);
  :mod:`~khepera_gym.robot.calibrate.study` fits many of them and tabulates how the fit does;
* :mod:`~khepera_gym.robot.calibrate.fit`: the fit (scipy.optimize.least_squares): its two stages in
  :mod:`~khepera_gym.robot.calibrate.geometry` (geometry and sensors, with the infrared curve of
  :mod:`~khepera_gym.robot.calibrate.ir_curve`; results in :mod:`~khepera_gym.robot.calibrate.
  geometry_result`) and :mod:`~khepera_gym.robot.calibrate.drive_fit` (the drive), on the shared
  machinery of :mod:`~khepera_gym.robot.calibrate.solver`; each channel's noise where nothing
  changes (:mod:`~khepera_gym.robot.calibrate.noise`), the uncertainties' statistical and systematic
  parts (:mod:`~khepera_gym.robot.calibrate.uncertainty`) and whether the fit explains the logs
  (:mod:`~khepera_gym.robot.calibrate.goodness`);
* :mod:`~khepera_gym.robot.calibrate.scenario`: the calibrated scenario as TOML;
* :mod:`~khepera_gym.robot.calibrate.report`: the plots and numbers;
* :mod:`~khepera_gym.robot.calibrate.command`: the command lines.

The fit needs scipy (``pip install 'khepera-gym[calibrate]'``); everything else needs only the
package's dependencies. Nothing here has run on a real robot: docs/sim-to-real.md says what is
measured and what is assumed. Units: the robot's own in logs (speed units, pulses, counts, cm),
SI in scenarios. Threading: the calling thread.
"""

from khepera_gym.robot.calibrate.fit import CALIBRATE_EXTRA, Calibration, Estimate, calibrate
from khepera_gym.robot.calibrate.logformat import (
    COLUMNS,
    FORMAT_VERSION,
    LogFormatError,
    RobotLog,
    parse_log,
    read_log,
    write_log,
)
from khepera_gym.robot.calibrate.program import write_calibration_program
from khepera_gym.robot.calibrate.replay import (
    DIVERGENCE_TIMES,
    ReplayComparison,
    command_replay,
    compare_with_simulator,
    odometry_replay,
)
from khepera_gym.robot.calibrate.report import write_calibration_report, write_replay_report
from khepera_gym.robot.calibrate.scenario import calibrated_toml, check_scenario
from khepera_gym.robot.calibrate.synthetic import (
    TrueRobot,
    perturbed_robot,
    synthetic_calibration_log,
    synthetic_command_log,
)

__all__ = [
    "CALIBRATE_EXTRA",
    "COLUMNS",
    "DIVERGENCE_TIMES",
    "FORMAT_VERSION",
    "Calibration",
    "Estimate",
    "LogFormatError",
    "ReplayComparison",
    "RobotLog",
    "TrueRobot",
    "calibrate",
    "calibrated_toml",
    "check_scenario",
    "command_replay",
    "compare_with_simulator",
    "odometry_replay",
    "parse_log",
    "perturbed_robot",
    "read_log",
    "synthetic_calibration_log",
    "synthetic_command_log",
    "write_calibration_program",
    "write_calibration_report",
    "write_log",
    "write_replay_report",
]
