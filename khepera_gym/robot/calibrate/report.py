"""The reports of ``khepera-gym calibrate`` and ``khepera-gym replay``: plots and numbers.

:func:`write_calibration_report` writes, into a folder:

* ``drive.png``: the measured wheel speeds against the simulated ones (the logged commands
  replayed with the fitted drive) over the steps and turns, and their residuals;
* ``gyro.png``: the gyroscope against the simulated yaw rate of the encoders' path, and the
  residuals' histogram;
* ``ir.png``: the infrared readings near the wall against their distance (by the encoders), the
  fitted curve and K-Team's, and the residuals against distance;
* ``us.png``: the front ultrasonic sensor against the wall's distance, with the fitted offset;
* ``report.json`` and ``report.md``: the verdict (a poor fit says so first), every value with
  its uncertainty and its statistical and systematic parts ("not identified" where the logs
  cannot tell), each channel's residuals against the noise the log shows where nothing changes
  (count, RMS, reduced chi-square and where it becomes poor, the runs test and the lag-1
  autocorrelation of structure, outliers), the step the drive was fitted at, the warnings (time
  gaps, outliers, values at a bound of the search or not identified, changes made to write a
  value) and the profile's scan, with where they come from (date, commit, machine, command).

:func:`write_replay_report` writes ``replay.png`` (the trajectory by odometry against the
simulated one, the wheel speeds and the infrared readings over time) and ``replay.json`` (the
divergence after 1, 5 and 10 s and, for a calibration log, over each moving phase).

Figures are built with matplotlib's object-oriented API (no display needed). Units: as the
logs' for readings; m, s, °/s in the plots' axes. Threading: the calling thread.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

import khepera_gym.robot.calibrate.replay as rp
from khepera_gym.analysis.plots import plot_trajectories
from khepera_gym.robot.calibrate.fit import WALL_PHASES, Calibration, Estimate
from khepera_gym.robot.calibrate.goodness import ChannelFit
from khepera_gym.robot.calibrate.scenario import table_rows
from khepera_gym.tooling.provenance import provenance

#: The report's numbers file.
REPORT_JSON = "report.json"
#: The replay's numbers file.
REPLAY_JSON = "replay.json"


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _estimate_dict(estimate: Estimate) -> dict[str, Any]:
    def clean(value: Any) -> Any:
        if isinstance(value, list):
            return [_finite(v) for v in value]
        return _finite(float(value))

    return {
        "key": estimate.key,
        "value": clean(estimate.value),
        "sigma": clean(estimate.sigma),
        "sigma_stat": clean(estimate.sigma_stat),
        "sigma_sys": clean(estimate.sigma_sys),
        "identified": estimate.identified,
        "unit": estimate.unit,
        "how": estimate.how,
        "flags": list(estimate.flags),
    }


def _channel(channel: ChannelFit, residuals: np.ndarray) -> dict[str, Any]:
    residuals = residuals[np.isfinite(residuals)]
    return {
        "count": channel.count,
        "mean": _finite(float(np.mean(residuals))) if len(residuals) else None,
        "rms": _finite(channel.rms),
        "expected_rms": _finite(channel.expected),
        "reduced_chi2": _finite(channel.chi2),
        "poor_above": _finite(channel.limit),
        "runs_z": _finite(channel.runs_z),
        "lag1": _finite(channel.lag1),
        "outliers": channel.outliers,
        "verdict": channel.verdict(),
    }


#: The report's names of the channels, with the residuals each holds.
CHANNELS = {
    "gyroscope": "gyro_deg_s",
    "infrared": "ir_raw",
    "ultrasonic": "us_m",
    "final gap": "wall_gap_m",
    "wheel speeds": "wheel_speed_units",
}


def calibration_numbers(calibration: Calibration) -> dict[str, Any]:
    """The report's numbers (JSON-ready)."""
    g, d = calibration.geometry, calibration.drive
    residuals = {
        "gyroscope": g.residuals["gyro"],
        "infrared": g.residuals["ir"],
        "ultrasonic": g.residuals["us"],
        "final gap": g.residuals["gap"],
        "wheel speeds": d.residuals,
    }
    noise = {**g.noise, "speed": d.noise}
    return {
        "meta": provenance(),
        "logs": [
            {"file": log.name, "rows": len(log), "metadata": log.metadata}
            for log in calibration.logs
        ],
        "verdict": "poor" if calibration.goodness.poor else "good",
        "summary": calibration.goodness.summary(),
        "parameters": [_estimate_dict(e) for e in calibration.estimates()],
        "derived": [_estimate_dict(g.ir_gain), _estimate_dict(g.ir_scale)],
        "residuals": {
            CHANNELS[c.name]: _channel(c, residuals[c.name]) for c in calibration.goodness.channels
        },
        "noise_where_nothing_changes": {
            name: {
                "sigma": _finite(n.sigma),
                "error": _finite(n.error),
                "count": n.count,
                "outliers": n.outliers,
                "source": n.source,
            }
            for name, n in noise.items()
        },
        "drive_fitted_at": {"physics_dt_s": d.dt, "substeps": d.substeps, "step_s": d.step},
        "warnings": calibration.warnings(),
        "acc_inc_scan_chi2": {str(k): v for k, v in d.profile.items()},
        "motors_set_by_the_program": calibration.motors,
    }


def _markdown(calibration: Calibration, numbers: dict[str, Any]) -> str:
    lines = [
        "# Calibration report",
        "",
        f"Logs: {', '.join(log.name for log in calibration.logs)}; "
        f"{numbers['meta']['date']}, khepera_gym {numbers['meta']['khepera_gym']}.",
        "",
        f"**{numbers['summary']}.**",
        "",
        "| key | value ± standard uncertainty (statistical, systematic) | from |",
        "|-----|------------------------------|------|",
    ]
    lines += [f"| `{key}` | {value} | {how} |" for key, value, how in table_rows(calibration)]
    lines += [
        "",
        "Each channel's residuals against the noise the log shows where nothing changes:",
        "",
        "| channel | count | RMS | expected RMS | reduced chi-square (poor above) | runs z | "
        "lag-1 | outliers | verdict |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for channel in calibration.goodness.channels:
        lines.append(
            f"| {channel.name} ({channel.unit}) | {channel.count} | {channel.rms:.4g} | "
            f"{channel.expected:.4g} | {channel.chi2:.3f} ({channel.limit:.2f}) | "
            f"{channel.runs_z:+.1f} | {channel.lag1:+.2f} | {channel.outliers} | "
            f"{channel.verdict()} |"
        )
    drive = calibration.drive
    lines += [
        "",
        f"The drive's lag is the simulator's effective lag at physics.dt {drive.dt:g} s and "
        f"{drive.substeps} substeps ({drive.step * 1000:g} ms): fit again for another step.",
    ]
    if numbers["acc_inc_scan_chi2"]:
        scan = ", ".join(f"{k}: {v:.1f}" for k, v in numbers["acc_inc_scan_chi2"].items())
        lines.append(f"Chi-square of each whole acc_inc tried (with its best lag): {scan}.")
    if numbers["warnings"]:
        lines += ["", "Warnings:", ""] + [f"- {w}" for w in numbers["warnings"]]
    lines += ["", "![drive](drive.png)", "![gyro](gyro.png)", "![ir](ir.png)", "![us](us.png)"]
    return "\n".join(lines) + "\n"


def _drive_figure(calibration: Calibration) -> Figure:
    figure = Figure(figsize=(10, 6), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    unit = rp.speed_unit(float(calibration.geometry.wheel_radius.value))
    log, replay = calibration.logs[0], calibration.drive.replays[0]
    steps = ~np.isin(log.phases, ("rest", *WALL_PHASES, "spin"))
    first = int(np.argmax(steps)) if steps.any() else 0
    rows = slice(max(first - 10, 0), len(log))
    time = log.time[rows]
    simulated = replay.wheel_speeds[rows] / unit
    for wheel, name in enumerate(("left", "right")):
        top.plot(
            time, log.speeds[rows, wheel], ".", ms=3, color=f"C{wheel}", label=f"{name}, logged"
        )
        top.plot(
            time, simulated[:, wheel], "-", lw=1, color=f"C{wheel}", label=f"{name}, simulated"
        )
        bottom.plot(
            time, log.speeds[rows, wheel] - simulated[:, wheel], ".", ms=2, color=f"C{wheel}"
        )
    top.plot(time, log.commands[rows, 0], ":", lw=0.8, color="0.4", label="left command")
    top.set_ylabel("wheel speed (speed units)")
    top.legend(fontsize=7, ncol=3)
    top.set_title(f"{log.name}: steps and turns, measured against the replay with the fitted drive")
    bottom.set_ylabel("measured - simulated")
    bottom.set_xlabel("time (s)")
    return figure


def _gyro_figure(calibration: Calibration) -> Figure:
    figure = Figure(figsize=(10, 4.5), layout="constrained")
    left, right = figure.subplots(1, 2, width_ratios=(3, 1))
    log, path = calibration.logs[0], calibration.geometry.paths[0]
    count = rp.GYRO_DEG_S_PER_COUNT
    bias = float(calibration.geometry.gyro_bias.value)
    left.plot(log.time, log.gyro_z * count, ".", ms=2, label="logged")
    left.plot(
        log.time, path.gyro_z * count + bias, "-", lw=0.8, label="simulated (encoders' path) + bias"
    )
    left.set_xlabel("time (s)")
    left.set_ylabel("yaw rate (°/s)")
    left.legend(fontsize=8)
    residuals = calibration.geometry.residuals["gyro"]
    right.hist(residuals, bins=40, color="C2")
    right.set_xlabel("residual (°/s)")
    right.set_title(f"σ {np.std(residuals):.3g} °/s", fontsize=9)
    return figure


def _ir_figure(calibration: Calibration) -> Figure:
    figure = Figure(figsize=(11, 4.5), layout="constrained")
    left, right = figure.subplots(1, 2)
    g = calibration.geometry
    curve = np.asarray(g.ir_curve.value)
    floor = float(g.ir_floor_value.value)
    for k, (log, path) in enumerate(zip(calibration.logs, g.paths, strict=True)):
        rows = np.isin(log.phases, WALL_PHASES)
        distance = rp.wall_ir_distances(path.poses[rows], log.number("wall_distance_m"))
        seen = np.isfinite(distance)
        mm = distance[seen] * 1000.0
        logged = log.ir[rows][seen]
        model = rp.ir_curve_mean(distance[seen], curve, floor)
        label = "logged (all sensors, near the wall)" if k == 0 else None
        left.plot(mm, logged, ".", ms=2, alpha=0.4, color="C0", label=label)
        right.plot(mm, logged - model, ".", ms=2, alpha=0.4, color="C0")
    grid = np.linspace(0.0, 0.25, 501)
    left.plot(grid * 1000, rp.ir_curve_mean(grid, curve, floor), "C3-", label="fitted curve")
    left.plot(
        grid * 1000,
        rp.ir_curve_mean(grid, rp.KTEAM_IR_CURVE, 100.0),
        "k--",
        lw=0.8,
        label="K-Team's (the default)",
    )
    left.set_xlabel("distance to the wall, by the encoders (mm)")
    left.set_ylabel("raw reading")
    left.legend(fontsize=8)
    right.axhline(0.0, color="k", lw=0.5)
    right.set_xlabel("distance (mm)")
    right.set_ylabel("logged - fitted")
    return figure


def _us_figure(calibration: Calibration) -> Figure:
    figure = Figure(figsize=(6, 4.5), layout="constrained")
    ax = figure.subplots()
    offset = float(calibration.geometry.us_offset.value)
    for log, path in zip(calibration.logs, calibration.geometry.paths, strict=True):
        distance = rp.wall_ray_distance(path.poses, log.number("wall_distance_m"))
        rows = np.isin(log.phases, WALL_PHASES) & np.isfinite(distance)
        us = log.us[rows, 2]
        valid = (us > 0) & (us < 1000)
        ax.plot(distance[rows][valid] * 100, us[valid], ".", ms=3, color="C0")
    grid = np.linspace(0.2, 1.0, 50)
    ax.plot(grid * 100, (grid + offset) * 100, "C3-", label=f"distance + {offset * 100:.2f} cm")
    ax.plot(grid * 100, grid * 100, "k--", lw=0.8, label="no offset")
    ax.set_xlim(20, 80)
    ax.set_ylim(20, 80)
    ax.set_xlabel("distance to the wall, by the encoders (cm)")
    ax.set_ylabel("front ultrasonic reading (cm)")
    ax.legend(fontsize=8)
    return figure


def write_calibration_report(calibration: Calibration, out_dir: str | Path) -> list[Path]:
    """Writes the calibration's plots and numbers into ``out_dir``; returns the files."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for name, draw in (
        ("drive.png", _drive_figure),
        ("gyro.png", _gyro_figure),
        ("ir.png", _ir_figure),
        ("us.png", _us_figure),
    ):
        draw(calibration).savefig(out / name, dpi=110)
        files.append(out / name)
    numbers = calibration_numbers(calibration)
    (out / REPORT_JSON).write_text(json.dumps(numbers, indent=2) + "\n", encoding="utf-8")
    (out / "report.md").write_text(_markdown(calibration, numbers), encoding="utf-8")
    return [*files, out / REPORT_JSON, out / "report.md"]


def replay_numbers(comparison: rp.ReplayComparison) -> dict[str, Any]:
    """The replay's numbers (JSON-ready)."""
    return {
        "meta": provenance(),
        "log": {"file": comparison.log.name, "rows": len(comparison.log)},
        "rows_replayed": comparison.replay.rows_replayed,
        "divergence": [
            {
                "time_s": d.time,
                "position_m": _finite(d.position),
                "heading_rad": _finite(d.heading),
            }
            for d in comparison.divergences
        ],
        "phase_divergence": [
            {
                "phase": d.phase,
                "rows": list(d.rows),
                "travel_m": d.travel,
                "turn_rad": d.turn,
                "position_m": _finite(d.position),
                "heading_rad": _finite(d.heading),
            }
            for d in comparison.phase_divergences
        ],
        "wheel_speed_rms_units": _finite(comparison.wheel_rms),
        "ir_rms_raw": _finite(comparison.ir_rms),
    }


def replay_figure(comparison: rp.ReplayComparison) -> Figure:
    """The logged run against the simulated one: trajectory, wheel speeds, infrared readings."""
    figure = Figure(figsize=(13, 5), layout="constrained")
    path_ax, speed_ax, ir_ax = figure.subplots(1, 3, width_ratios=(1.1, 1, 1))
    log, replay = comparison.log, comparison.replay
    plot_trajectories(
        [comparison.logged_path, replay.poses],
        replay.scene,
        ax=path_ax,
        labels=["logged (odometry)", "simulated"],
    )
    both = np.concatenate([comparison.logged_path[:, :2], replay.poses[:, :2]])
    both = both[np.isfinite(both).all(axis=1)]
    low, high = both.min(axis=0) - 0.15, both.max(axis=0) + 0.15
    centre, half = (low + high) / 2, max(float(np.max(high - low)) / 2, 0.2)
    path_ax.set_xlim(centre[0] - half, centre[0] + half)
    path_ax.set_ylim(centre[1] - half, centre[1] + half)
    path_ax.set_title("trajectory", fontsize=10)
    unit = rp.speed_unit(comparison.wheel_radius)
    for wheel, name in enumerate(("left", "right")):
        speed_ax.plot(
            log.time, log.speeds[:, wheel], ".", ms=2, color=f"C{wheel}", label=f"{name}, logged"
        )
        speed_ax.plot(
            log.time,
            replay.wheel_speeds[:, wheel] / unit,
            "-",
            lw=0.8,
            color=f"C{wheel}",
            label=f"{name}, simulated",
        )
    speed_ax.set_xlabel("time (s)")
    speed_ax.set_ylabel("wheel speed (speed units)")
    speed_ax.legend(fontsize=7)
    seen = [
        i for i in range(8) if np.nanmax(log.ir[:, i]) > 300 or np.nanmax(replay.ir[:, i]) > 300
    ]
    for i in seen or [3]:
        ir_ax.plot(log.time, log.ir[:, i], ".", ms=2, color=f"C{i}", label=f"ir_{i}, logged")
        ir_ax.plot(
            log.time, replay.ir[:, i], "-", lw=0.8, color=f"C{i}", label=f"ir_{i}, simulated"
        )
    ir_ax.set_xlabel("time (s)")
    ir_ax.set_ylabel("infrared raw")
    ir_ax.legend(fontsize=7)
    text = "; ".join(
        f"{d.time:g} s: {d.position * 100:.1f} cm, {math.degrees(d.heading):.1f}°"
        if math.isfinite(d.position)
        else f"{d.time:g} s: –"
        for d in comparison.divergences
    )
    figure.suptitle(f"{log.name}: divergence {text}", fontsize=10)
    return figure


def write_replay_report(comparison: rp.ReplayComparison, out_dir: str | Path) -> list[Path]:
    """Writes ``replay.png`` and ``replay.json`` into ``out_dir``; returns them."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    replay_figure(comparison).savefig(out / "replay.png", dpi=110)
    (out / REPLAY_JSON).write_text(
        json.dumps(replay_numbers(comparison), indent=2) + "\n", encoding="utf-8"
    )
    return [out / "replay.png", out / REPLAY_JSON]


__all__ = [
    "REPLAY_JSON",
    "REPORT_JSON",
    "calibration_numbers",
    "replay_figure",
    "replay_numbers",
    "write_calibration_report",
    "write_replay_report",
]
