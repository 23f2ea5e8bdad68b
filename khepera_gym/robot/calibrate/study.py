"""How ``khepera-gym calibrate`` does on robots it does not contain: the calibration program's
logs from the independent bench model (:mod:`~khepera_gym.robot.calibrate.independent`), for robots
spread across the real robots' spread (:data:`~khepera_gym.robot.calibrate.synthetic.SPREAD`) and
many seeds, each fitted and compared with the truth; a results file (JSON, with the date, commit,
machine and command) and the tables of docs/sim-to-real.md made from it (:func:`markdown`).

Run::

    python -m khepera_gym.robot.calibrate.study --robots 3 --seeds 10 --out study.json
    python -m khepera_gym.robot.calibrate.study --markdown study.json

The truth of each value is what the simulator needs to reproduce the robot
(:meth:`~khepera_gym.robot.calibrate.independent.BenchRobot.simulator_truth`), and for two values
a definition is needed:

* the **infrared curve**: the simulator's curve is 16 points joined by straight lines, the
  robot's is smooth; the truth of a fitted point is the 16-point curve closest (least squares)
  to the robot's noise-free readings at their true distances, over the readings the fit uses
  (its 200 mm point not below the floor value, which the simulator requires).
  Points the fit leaves unidentified are compared with the robot's curve at the point, and not
  counted (they carry no uncertainty);
* the **effective lag**: the simulator's lag that follows the robot best at its step, which no
  parameter of the robot is: the fit's value on :data:`TRUTH_RUNS` logs of the same robot
  without the wheels' ripple (the mean).

A case passes when ``|fitted - truth| <= 2 sigma``. Units: the values'. Threading: the calling
thread (the fits run one after the other).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import khepera_gym.robot.calibrate.ir_curve as ic
import khepera_gym.robot.calibrate.replay as rp
from khepera_gym.robot.calibrate.drive_fit import DriveFit
from khepera_gym.robot.calibrate.fit import WALL_PHASES, calibrate
from khepera_gym.robot.calibrate.independent import (
    BenchRobot,
    BenchRun,
    bench_calibration_run,
    draw_bench_robot,
)
from khepera_gym.robot.calibrate.program import write_calibration_program
from khepera_gym.robot.calibrate.schedule import Phase
from khepera_gym.robot.calibrate.solver import Progress
from khepera_gym.robot.calibrate.synthetic import SPREAD
from khepera_gym.tooling.provenance import provenance

#: Noise-free runs whose fitted lag is the effective lag's truth.
TRUTH_RUNS = 3
#: The gap to the wall at the start (m).
WALL_DISTANCE = 0.5
#: A case passes within this many of its standard uncertainties.
WITHIN = 2.0
#: The named values compared (the scenario keys the TOML writes, but the curve and acc_inc).
KEYS = (
    "robot.wheel_radius",
    "robot.axle_length",
    "robot.motor_time_constant",
    "sensors.gyro_bias",
    "sensors.gyro_noise_sigma",
    "sensors.ir_floor_value",
    "sensors.ir_noise_sigma",
    "sensors.us_offset",
    "sensors.us_noise_sigma",
)


def program_phases(env_id: str = "KheperaIV-Nav") -> tuple[Phase, ...]:
    """The phase table ``khepera-gym robot-program calibrate`` writes for ``env_id``."""
    with tempfile.TemporaryDirectory() as folder:
        return write_calibration_program(folder, env_id=env_id).phases


def spread_robots(count: int, seed: int) -> list[BenchRobot]:
    """``count`` robots across the spread: each value in a different third of its range for
    each of the first three robots (a Latin hypercube), then at random."""
    rng = np.random.default_rng(seed)
    orders = {name: rng.permutation(3) for name in SPREAD}
    return [
        draw_bench_robot(rng, {n: int(o[k]) for n, o in orders.items()} if k < 3 else None)
        for k in range(count)
    ]


def curve_truth(run: BenchRun, robot: BenchRobot, fitted: Sequence[bool]) -> list[float]:
    """The 16-point curve closest to the robot's noise-free readings (see the module's
    docstring); the robot's own value at the points not fitted."""
    log = run.log
    gap = run.wall_x - rp.BODY_RADIUS
    before_spin = np.cumsum(log.phases == "spin") == 0
    rows = np.isin(log.phases, WALL_PHASES) | (before_spin & (log.phases == "rest"))
    distances = rp.wall_ir_distances(run.ir_poses[rows], gap).ravel()
    mean = robot.ir_mean(distances)
    keep = mean < ic.IR_MAX - 3.0 * robot.ir_noise
    basis = ic.curve_basis(distances[keep])
    own = robot.ir_mean(rp.IR_CURVE_MM / 1000.0)
    chosen = np.asarray(fitted, dtype=bool)
    target = mean[keep] - basis[:, -1] * robot.ir_floor - basis[:, :-1][:, ~chosen] @ own[~chosen]
    truth = own.copy()
    truth[chosen] = np.linalg.lstsq(basis[:, :-1][:, chosen], target, rcond=None)[0]
    # The simulator takes no 200 mm point below the floor value: the closest it can hold.
    truth[-1] = max(truth[-1], robot.ir_floor)
    return [float(v) for v in truth]


def effective_lag(
    robot: BenchRobot, phases: Sequence[Phase], radius: float, speed_noise: float
) -> float:
    """The effective lag's truth: the mean lag fitted on :data:`TRUTH_RUNS` runs without the
    wheels' ripple, each reading weighted as in a log with it (``speed_noise``, the plateaus'
    noise of the robot's logs): the value the fit tends to with ever more such logs."""
    found = []
    for seed in range(TRUTH_RUNS):
        run = bench_calibration_run(
            robot, phases, wall_distance=WALL_DISTANCE, seed=10_000 + seed, speed_ripple=0.0
        )
        drive = DriveFit([run.log], radius, {}, Progress(False), speed_noise).fit()
        found.append(float(drive.motor_time_constant.value))
    return float(np.mean(found))


def _case(key: str, truth: float, estimate: Any, index: int | None = None) -> dict[str, Any]:
    def pick(value: Any) -> float:
        return float(value[index]) if index is not None else float(value)

    fitted, sigma = pick(estimate.value), pick(estimate.sigma)
    identified = bool(estimate.identified[index] if index is not None else estimate.identified)
    ratio = abs(fitted - truth) / sigma if identified and sigma > 0 else math.nan
    return {
        "key": key,
        "truth": truth,
        "fitted": fitted,
        "sigma": sigma if identified else None,
        "sigma_stat": pick(estimate.sigma_stat) if identified else None,
        "sigma_sys": pick(estimate.sigma_sys) if identified else None,
        "identified": identified,
        "ratio": None if math.isnan(ratio) else ratio,
    }


def run_study(
    robots: int, seeds: int, seed: int = 0, echo: bool = True, command: str | None = None
) -> dict[str, Any]:
    """Fits ``seeds`` logs of each of ``robots`` robots; returns the results document (its
    ``meta`` naming ``command``, by default this process's)."""
    phases = program_phases()
    document: dict[str, Any] = {
        "meta": provenance(command),
        "settings": {
            "robots": robots,
            "seeds": seeds,
            "seed": seed,
            "within": WITHIN,
            "wall_distance_m": WALL_DISTANCE,
            "phases": len(phases),
        },
        "robots": [],
        "cases": [],
    }
    for number, robot in enumerate(spread_robots(robots, seed)):
        # Each case its own noise: a seed shared by the robots would repeat one draw's luck.
        runs = [
            bench_calibration_run(
                robot, phases, wall_distance=WALL_DISTANCE, seed=case_seed + 1000 * number
            )
            for case_seed in range(seeds)
        ]
        speed_noise = float(
            np.mean([DriveFit([r.log], 0.021, {}, Progress(False)).noise.sigma for r in runs])
        )
        tau = effective_lag(robot, phases, robot.wheel_radius, speed_noise)
        document["robots"].append(
            {
                "robot": number,
                **{k: v for k, v in vars(robot).items() if k != "ir_shape"},
                "ir_shape": list(robot.ir_shape),
                "effective_lag_s": tau,
                "speed_noise_units": speed_noise,
            }
        )
        for case_seed, run in enumerate(runs):
            calibration = calibrate([run.log], progress=False)
            truth = robot.simulator_truth(int(run.log.metadata["gyro_samples"]))
            truth["robot.motor_time_constant"] = tau
            estimates = {e.key: e for e in calibration.estimates()}
            rows = [_case(key, truth[key], estimates[key]) for key in KEYS]
            curve = estimates["sensors.ir_curve"]
            points = curve_truth(run, robot, curve.identified)
            rows += [
                _case(f"sensors.ir_curve[{int(mm)} mm]", points[k], curve, k)
                for k, mm in enumerate(rp.IR_CURVE_MM)
            ]
            verdict = "poor" if calibration.goodness.poor else "good"
            for row in rows:
                row.update({"robot": number, "seed": case_seed + 1000 * number, "verdict": verdict})
            document["cases"] += rows
            if echo:
                worst = max((r["ratio"] or 0.0) for r in rows)
                print(
                    f"robot {number} seed {case_seed}: {verdict}, worst |error|/σ {worst:.2f}",
                    file=sys.stderr,
                )
    document["summary"] = summary(document["cases"])
    return document


def summary(cases: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per value: cases, identified ones, the fraction within WITHIN sigma, the worst ratio."""
    found = []
    for key in dict.fromkeys(c["key"] for c in cases):
        mine = [c for c in cases if c["key"] == key]
        ratios = [c["ratio"] for c in mine if c["ratio"] is not None]
        found.append(
            {
                "key": key,
                "cases": len(mine),
                "identified": len(ratios),
                "within": sum(r <= WITHIN for r in ratios) / len(ratios) if ratios else None,
                "worst": max(ratios) if ratios else None,
            }
        )
    return found


#: The columns of a case in the results file (one list a case, to keep the file small).
CASE_COLUMNS = (
    "robot",
    "seed",
    "key",
    "truth",
    "fitted",
    "sigma",
    "sigma_stat",
    "sigma_sys",
    "identified",
    "ratio",
    "verdict",
)


def _round(value: Any) -> Any:
    return float(f"{value:.7g}") if isinstance(value, float) else value


def results_file(document: dict[str, Any]) -> str:
    """The results document as the file holds it: every case a row of :data:`CASE_COLUMNS`,
    numbers to 7 significant digits."""
    rows = [[_round(case[c]) for c in CASE_COLUMNS] for case in document["cases"]]
    compact = {**document, "cases": {"columns": list(CASE_COLUMNS), "rows": rows}}
    return json.dumps(compact, separators=(",", ":")) + "\n"


def read_results(path: Path) -> dict[str, Any]:
    """A results file (:func:`results_file`) as the document :func:`run_study` returns."""
    document = json.loads(path.read_text(encoding="utf-8"))
    table = document["cases"]
    document["cases"] = [dict(zip(table["columns"], row, strict=True)) for row in table["rows"]]
    return document


def _number(value: float | None, digits: int = 4) -> str:
    if value is None or not math.isfinite(value):
        return "–"
    return f"{value:.{digits}g}"


def markdown(document: dict[str, Any]) -> str:
    """The tables of docs/sim-to-real.md: per value over every case, then per robot."""
    meta = document["meta"]
    settings = document["settings"]
    commit = (meta.get("commit") or {}).get("id", "?")
    lines = [
        f"{settings['robots']} robots × {settings['seeds']} seeds, {meta['date']}, commit "
        f"`{str(commit)[:10]}`, `{meta['command']}`.",
        "",
        "| value | cases | identified | within 2σ | median \\|error\\|/σ | worst | "
        "median σ stat | median σ sys |",
        "|---|---|---|---|---|---|---|---|",
    ]
    cases = document["cases"]
    for row in document["summary"]:
        mine = [c for c in cases if c["key"] == row["key"] and c["ratio"] is not None]
        ratios = [c["ratio"] for c in mine]
        stat = [c["sigma_stat"] for c in mine]
        sys_ = [c["sigma_sys"] for c in mine]
        within = "–" if row["within"] is None else f"{100 * row['within']:.0f} %"
        lines.append(
            f"| `{row['key']}` | {row['cases']} | {row['identified']} | {within} | "
            f"{_number(float(np.median(ratios)) if ratios else None, 2)} | "
            f"{_number(row['worst'], 2)} | "
            f"{_number(float(np.median(stat)) if stat else None, 3)} | "
            f"{_number(float(np.median(sys_)) if sys_ else None, 3)} |"
        )
    for robot in document["robots"]:
        number = robot["robot"]
        lines += [
            "",
            f"Robot {number}: wheels {robot['wheel_radius'] * 1000:.3f} mm, axle "
            f"{robot['axle_length'] * 1000:.2f} mm, motors' lag {robot['motor_tau'] * 1000:.1f} "
            f"ms, infrared gain {robot['ir_gain']:.3f} and scale {robot['ir_scale']:.3f}.",
            "",
            "| value | truth | fitted (mean of seeds) | spread of seeds | median σ (stat, sys) "
            "| median \\|error\\|/σ | within 2σ |",
            "|---|---|---|---|---|---|---|",
        ]
        for key in KEYS:
            mine = [c for c in cases if c["robot"] == number and c["key"] == key]
            lines.append(_robot_row(key, mine))
    return "\n".join(lines) + "\n"


def _robot_row(key: str, mine: Sequence[dict[str, Any]]) -> str:
    fitted = [c["fitted"] for c in mine]
    known = [c for c in mine if c["ratio"] is not None]
    if not known:
        truth, value = _number(mine[0]["truth"]), _number(float(np.mean(fitted)))
        return f"| `{key}` | {truth} | {value} | – | not identified | – | – |"
    ratios = [c["ratio"] for c in known]
    sigma = float(np.median([c["sigma"] for c in known]))
    stat = float(np.median([c["sigma_stat"] for c in known]))
    sys_ = float(np.median([c["sigma_sys"] for c in known]))
    within = sum(r <= WITHIN for r in ratios) / len(ratios)
    return (
        f"| `{key}` | {_number(float(np.mean([c['truth'] for c in mine])))} | "
        f"{_number(float(np.mean(fitted)))} | {_number(float(np.std(fitted)), 2)} | "
        f"{_number(sigma, 2)} ({_number(stat, 2)}, {_number(sys_, 2)}) | "
        f"{_number(float(np.median(ratios)), 2)} | {100 * within:.0f} % |"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line (the module's docstring)."""
    parser = argparse.ArgumentParser(prog="python -m khepera_gym.robot.calibrate.study")
    parser.add_argument("--robots", type=int, default=3)
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0, help="the robots' draw")
    parser.add_argument("--out", type=Path, help="the results file (JSON) to write")
    parser.add_argument("--markdown", type=Path, help="print the tables of a results file")
    args = parser.parse_args(argv)
    if args.markdown is not None:
        print(markdown(read_results(args.markdown)), end="")
        return 0
    if args.out is None:
        parser.error("give --out (to run the study) or --markdown (to print its tables)")
    typed = sys.argv[1:] if argv is None else list(argv)
    command = shlex.join(["python", "-m", "khepera_gym.robot.calibrate.study", *typed])
    document = run_study(args.robots, args.seeds, args.seed, command=command)
    args.out.write_text(results_file(document), encoding="utf-8")
    print(markdown(document), end="")
    return 0


__all__ = [
    "CASE_COLUMNS",
    "KEYS",
    "TRUTH_RUNS",
    "WITHIN",
    "curve_truth",
    "effective_lag",
    "main",
    "markdown",
    "program_phases",
    "read_results",
    "results_file",
    "run_study",
    "spread_robots",
    "summary",
]

if __name__ == "__main__":  # pragma: no cover - the command line
    raise SystemExit(main())
