"""The command lines of the loop back from the robot:

* ``khepera-gym robot-program calibrate --out DIR`` writes the calibration program
  (:func:`~khepera_gym.robot.calibrate.program.write_calibration_program`);
* ``khepera-gym calibrate LOG.csv [LOG2.csv ...] --out calibrated.toml`` fits the simulator to
  the logs (:func:`~khepera_gym.robot.calibrate.fit.calibrate`) and writes the scenario
  (:func:`~khepera_gym.robot.calibrate.scenario.calibrated_toml`) and a report
  (:func:`~khepera_gym.robot.calibrate.report.write_calibration_report`); a fit the simulator does
  not explain (:mod:`~khepera_gym.robot.calibrate.goodness`) writes the report only and exits with
  :data:`POOR_FIT_STATUS`, unless ``--accept-poor-fit``;
* ``khepera-gym replay LOG.csv --config calibrated.toml`` replays a log's commands in the
  simulator and reports the divergence after 1, 5 and 10 s and over each moving phase of a
  calibration log (:func:`~khepera_gym.robot.calibrate.replay.compare_with_simulator`); it warns
  when the scenario's step is not the one its drive was fitted at, and of gaps in the log's time.

Every log is read and checked before anything is computed, and every output is computed (and
the scenario loaded by the simulator) before anything is written: a malformed log, or a fit that
gives a scenario the simulator refuses, writes nothing. Threading: the calling thread.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from khepera_gym.config import parse_key_values, tomllib
from khepera_gym.registration import resolve_env_id, task_of
from khepera_gym.robot.calibrate.fit import calibrate
from khepera_gym.robot.calibrate.logformat import read_log
from khepera_gym.robot.calibrate.program import PROGRAMS, write_calibration_program
from khepera_gym.robot.calibrate.replay import compare_with_simulator
from khepera_gym.robot.calibrate.report import write_calibration_report, write_replay_report
from khepera_gym.robot.calibrate.scenario import (
    calibrated_toml,
    check_scenario,
    dotted,
    fitted_step,
    table_rows,
)
from khepera_gym.robot.calibrate.timing import time_gaps
from khepera_gym.robot.export.motors import DRIVE_CHOICES
from khepera_gym.tooling.provenance import command_line


def add_program_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``khepera-gym robot-program``."""
    parser.add_argument("program", choices=PROGRAMS, help="which program: calibrate")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument(
        "--env", default="KheperaIV-Nav", help="the env whose drive to calibrate (KheperaIV-Nav)"
    )
    parser.add_argument("--config", default=None, help="its scenario (name or TOML path)")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario override"
    )
    parser.add_argument(
        "--drive",
        choices=DRIVE_CHOICES,
        default="trained",
        help="the motor controller's setting: the scenario's drive exactly (default), or its "
        "nominal firmware setting",
    )


def run_program_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym robot-program``."""
    written = write_calibration_program(
        args.out,
        env_id=args.env,
        config=args.config,
        drive=args.drive,
        **parse_key_values(args.set, "--set"),
    )
    print(f"wrote the calibration program for {written.env_id} to {written.out_dir}:")
    for path in written.files:
        print(f"  {path.name}")
    print(f"motors: {written.motors.note}; the program calls {written.motors.call()}")
    print(
        f"{len(written.phases)} phases, every {written.control_period * 1000:g} ms; build it with "
        f"`make robot` (README.md), run it as ./khepera_calibrate WALL_DISTANCE_M LOG.csv"
    )
    return 0


def add_calibrate_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``khepera-gym calibrate``."""
    parser.add_argument("logs", nargs="+", type=Path, help="logs of the calibration program")
    parser.add_argument(
        "--out", type=Path, required=True, help="the calibrated scenario to write (TOML)"
    )
    parser.add_argument(
        "--report",
        type=Path,
        default=None,
        help="the report's folder (plots, report.json, report.md); default: beside --out, "
        "named after it with _report",
    )
    parser.add_argument(
        "--randomise",
        type=float,
        default=None,
        metavar="K",
        help="write [value - K sigma, value + K sigma] ranges (domain randomisation) for the keys "
        "that take them",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario key of the simulator being calibrated (e.g. substeps=4); written too",
    )
    parser.add_argument(
        "--accept-poor-fit",
        action="store_true",
        help="write the scenario even if the simulator does not explain the logs (exit 0)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


#: The exit status of a fit the simulator does not explain (the report is written, not the
#: scenario, unless --accept-poor-fit).
POOR_FIT_STATUS = 3


def run_calibrate_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym calibrate``: reads and checks every log, fits, checks the scenario,
    then writes the report and, unless the fit is poor (and not accepted), the scenario."""
    logs = [read_log(path) for path in args.logs]
    base = dotted(parse_key_values(args.set, "--set"))
    calibration = calibrate(logs, base, progress=not args.quiet)
    text = calibrated_toml(calibration, randomise=args.randomise, base=base, command=command_line())
    out: Path = args.out
    check_scenario(text, str(out))
    report_dir = args.report if args.report is not None else out.with_name(out.stem + "_report")
    poor = bool(calibration.goodness.poor) and not args.accept_poor_fit
    if not poor:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text, encoding="utf-8")
    files = write_calibration_report(calibration, report_dir)
    width = max(len(key) for key, _, _ in table_rows(calibration))
    for key, value, _ in table_rows(calibration):
        print(f"  {key:<{width}}  {value}")
    for channel in calibration.goodness.channels:
        print(
            f"  {channel.name}: reduced chi-square {channel.chi2:.3f} against the noise where "
            f"nothing changes (poor above {channel.limit:.2f}): {channel.verdict()}"
        )
    for warning in calibration.warnings():
        print(f"warning: {warning}")
    print(calibration.goodness.summary())
    if poor:
        print(
            f"the calibration FAILED: {out} not written; the report is in {report_dir} "
            "(--accept-poor-fit writes the scenario anyway)",
            file=sys.stderr,
        )
        return POOR_FIT_STATUS
    print(f"wrote {out} and the report in {report_dir} ({len(files)} files)")
    return 0


def add_replay_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``khepera-gym replay``."""
    parser.add_argument(
        "log", type=Path, help="a robot log (the policy program's or the calibration's)"
    )
    parser.add_argument(
        "--config",
        default=None,
        help="the scenario to replay in (e.g. calibrated.toml); a policy's log needs its start "
        "pose (spawn.start) and the bench's obstacles",
    )
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario override"
    )
    parser.add_argument(
        "--env",
        default=None,
        help="the env whose task the scenario is for (default: the log's env, or Nav)",
    )
    parser.add_argument("--out", type=Path, default=None, help="the plots' folder (beside the log)")
    parser.add_argument("--seed", type=int, default=0, help="the simulator's seed (0)")


def run_replay_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym replay``."""
    log = read_log(args.log)
    env_id = args.env or log.metadata.get("env_id") or "KheperaIV-Nav"
    task = task_of(resolve_env_id(env_id))
    comparison = compare_with_simulator(
        log,
        config=args.config,
        overrides=parse_key_values(args.set, "--set"),
        task=task,
        seed=args.seed,
    )
    out = args.out if args.out is not None else args.log.with_name(args.log.stem + "_replay")
    files = write_replay_report(comparison, out)
    print(f"{log.name}: {len(log)} rows, {comparison.replay.rows_replayed} replayed in {task}")
    for line in _step_warnings(args.config, comparison.replay.scenario):
        print(f"warning: {line}")
    for gap in time_gaps(log):
        print(f"warning: time gap at {gap.describe(log.period)}")
    print("divergence of the simulated robot from the logged one (odometry):")
    for d in comparison.divergences:
        if math.isfinite(d.position):
            print(
                f"  after {d.time:>4g} s: {d.position * 100:6.1f} cm, "
                f"{math.degrees(d.heading):6.1f}°"
            )
        else:
            print(f"  after {d.time:>4g} s: the log is shorter")
    if comparison.phase_divergences:
        print("over each moving phase (and the rest after it), from a common start:")
        for d in comparison.phase_divergences:
            print(
                f"  {d.phase:<14} travel {d.travel * 100:6.1f} cm, turn "
                f"{math.degrees(d.turn):7.1f}°: up to {d.position * 100:5.2f} cm apart, "
                f"{math.degrees(d.heading):5.2f}°"
            )
    print(
        f"wheel speeds RMS {comparison.wheel_rms:.1f} speed units; infrared RMS "
        f"{comparison.ir_rms:.1f} raw"
    )
    print(f"wrote {', '.join(str(f) for f in files)}")
    return 0


def _step_warnings(config: str | None, scenario: str) -> list[str]:
    """A calibrated scenario replayed at another step than its drive was fitted at."""
    if config is None or not Path(config).is_file():
        return []
    fitted = fitted_step(Path(config).read_text(encoding="utf-8"))
    if fitted is None:
        return []
    physics = tomllib.loads(scenario)["physics"]
    now = (float(physics["dt"]), int(physics["substeps"]))
    if now[0] == fitted[0] and now[1] == fitted[1]:
        return []
    return [
        f"{config}'s drive was fitted at physics.dt {fitted[0]:g} s, {fitted[1]} substeps; this "
        f"replay steps at {now[0]:g} s, {now[1]} substeps: its lag (robot.motor_time_constant) is "
        "an effective one at the fitted step: calibrate again for this one"
    ]


__all__ = [
    "POOR_FIT_STATUS",
    "add_calibrate_arguments",
    "add_program_arguments",
    "add_replay_arguments",
    "run_calibrate_from_args",
    "run_program_from_args",
    "run_replay_from_args",
]
