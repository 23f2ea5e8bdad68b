"""The robot log: one CSV file a run, written on the robot by the exported programs (the policy
program with ``--log FILE``, the calibration program always) and by
:mod:`~khepera_gym.robot.calibrate.synthetic` from the simulator, read by ``khepera-gym calibrate``
and
``khepera-gym replay``.

Format 1, line by line::

    # khepera_gym robot log, format 1
    # program: calibrate                 <- metadata, "# key: value", before the column line
    # control_period_s: 0.05
    # ...
    time,phase,cmd_left,cmd_right,...    <- the columns: COLUMNS, then the policy's obs_i, action_i
    0.0000,rest,0,0,0,0,...              <- one row a control step
    # note: wall_gap_end_m: 0.0123       <- notes the program adds between rows
    ...
    # end: 1234 rows                     <- written when the program stops (also on Ctrl-C)

A row is taken at the start of a control step: the sensors as read then, and the wheel command
the program sent right after reading them. Units are the robot's own (:data:`COLUMNS` says
each), so that a log is what libkhepera returned, converted by nothing.

:func:`read_log` checks everything and raises :class:`LogFormatError` (a
:class:`~khepera_gym.errors.ConfigError`) naming the file, the line and the column of the first
problem: a wrong format version, a missing metadata key or column, a value that is not a finite
number, time that does not increase, a row cut short, or a file without its end line
(truncated). Threading: none.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from khepera_gym.errors import ConfigError

#: The version of the format this module reads and writes.
FORMAT_VERSION = 1
#: The first line, before its version number.
MAGIC = "# khepera_gym robot log, format "
#: Programs that write logs, as the ``program`` metadata names them.
PROGRAMS = ("policy", "calibrate")
#: The phase name of every row of the policy program.
POLICY_PHASE = "policy"


@dataclasses.dataclass(frozen=True)
class Column:
    """One column of the log."""

    name: str
    #: "float", "int" or "name" (an identifier such as a phase name).
    kind: str
    #: What the values are, with their unit.
    meaning: str


def _block(prefix: str, count: int, kind: str, meaning: str) -> list[Column]:
    return [Column(f"{prefix}_{i}", kind, f"{meaning} {i}") for i in range(count)]


#: The columns every log has, in order.
COLUMNS: tuple[Column, ...] = (
    Column("time", "float", "s since the program started, when the sensors were read"),
    Column("phase", "name", "the part of the program (the calibration's phase, or 'policy')"),
    Column("cmd_left", "int", "left wheel command sent with kh4_set_speed, speed units"),
    Column("cmd_right", "int", "right wheel command sent with kh4_set_speed, speed units"),
    Column("speed_left", "int", "left wheel speed measured by kh4_get_speed, speed units"),
    Column("speed_right", "int", "right wheel speed measured by kh4_get_speed, speed units"),
    Column("enc_left", "int", "left encoder of kh4_get_position, pulses"),
    Column("enc_right", "int", "right encoder of kh4_get_position, pulses"),
    *_block("ir", 8, "int", "kh4_proximity_ir ring sensor (K-Team order), raw 0..1023:"),
    *_block("ground", 4, "int", "kh4_proximity_ir ground sensor, raw 0..1023:"),
    *_block("us", 5, "int", "kh4_measure_us sensor (L, FL, F, FR, R), cm or code 0/1000/2000:"),
    Column("acc_x", "float", "accelerometer x (forward), mg, mean of the newest samples"),
    Column("acc_y", "float", "accelerometer y (left), mg, mean of the newest samples"),
    Column("acc_z", "float", "accelerometer z, mg (about -1000 at rest), mean of the newest"),
    Column("gyro_x", "float", "gyroscope x, counts of 0.066 deg/s, mean of the newest samples"),
    Column("gyro_y", "float", "gyroscope y, counts of 0.066 deg/s, mean of the newest samples"),
    Column("gyro_z", "float", "gyroscope z (CCW), counts of 0.066 deg/s, mean of the newest"),
)
#: Prefixes of the policy program's extra columns: its observation and its action.
EXTRA_PREFIXES = ("obs", "action")
#: Metadata every log has, with what it says.
METADATA: Mapping[str, str] = {
    "program": "which program wrote the log: policy or calibrate",
    "khepera_gym": "the version of khepera_gym that generated the program",
    "firmware": "the motor controller's version and revision (kh4_revision), e.g. 'C.3'",
    "control_period_s": "s between two rows, as the program was generated",
    "wheel_radius_m": "m, the wheel radius the program's odometry assumed",
    "axle_length_m": "m, the axle length the program's odometry assumed",
    "motors": "the motor mode the program set: profile (kh4RegSpeedProfile) or speed",
    "acc_inc": "kh4_SetSpeedProfile's acc_inc, speed units (profile only)",
    "acc_div": "kh4_SetSpeedProfile's acc_div",
    "min_speed_acc": "kh4_SetSpeedProfile's min_speed_acc, speed units",
    "min_speed_dec": "kh4_SetSpeedProfile's min_speed_dec, speed units",
    "gyro_samples": "newest samples of kh4_measure_acc/gyro averaged into a row",
}
#: Metadata of one program only.
PROGRAM_METADATA: Mapping[str, Mapping[str, str]] = {
    "policy": {"env_id": "the env the policy was trained on"},
    "calibrate": {
        "wall_distance_m": "m, the gap between the robot's front and the white wall at the start, "
        "as measured by the user",
    },
}
#: The note the calibration program adds after the wall approach (m, or "nan" if not measured).
WALL_GAP_NOTE = "wall_gap_end_m"
#: How the programs write the units line (informational; not read).
UNITS_LINE = (
    "time s; cmd, speed: speed units (pulses per 10 ms, 0.678181 mm/s at 21 mm wheels); "
    "enc: pulses (19456 a wheel turn); ir, ground: raw 0..1023; us: cm (0 too close, 1000 nothing, "
    "2000 off); acc: mg; gyro: counts of 0.066 deg/s"
)
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_META = re.compile(r"^# (?P<key>[A-Za-z_][A-Za-z0-9_]*): (?P<value>.*)$")
_NOTE = re.compile(r"^# note: (?P<key>[A-Za-z_][A-Za-z0-9_]*): (?P<value>.*)$")
_END = re.compile(r"^# end: (?P<rows>\d+) rows$")


class LogFormatError(ConfigError):
    """A robot log that cannot be read: the message names the file, line and column.

    Attributes:
        path: The file.
        line: The line (1-based).
        column: The column (1-based), or None when the problem is the whole line.
        column_name: The column's name, when known.
    """

    def __init__(
        self,
        path: str | Path,
        line: int,
        message: str,
        column: int | None = None,
        column_name: str | None = None,
    ) -> None:
        where = f"{path}, line {line}"
        if column is not None:
            where += f", column {column}" + (f" ({column_name})" if column_name else "")
        super().__init__(f"{where}: {message}")
        self.path = Path(path)
        self.line = line
        self.column = column
        self.column_name = column_name


@dataclasses.dataclass(frozen=True)
class Note:
    """A ``# note: key: value`` line the program wrote after row ``after`` (-1: before any)."""

    after: int
    key: str
    value: str


@dataclasses.dataclass
class RobotLog:
    """A robot log in memory: its metadata, notes and columns.

    Attributes:
        metadata: The header's ``key: value`` pairs, as text.
        columns: The column names, in order.
        values: Every numeric column as a float64 array (ints exactly).
        phases: The phase of every row.
        notes: The ``# note:`` lines, in order.
        path: The file it was read from, if any (for messages).
    """

    metadata: dict[str, str]
    columns: tuple[str, ...]
    values: dict[str, npt.NDArray[np.float64]]
    phases: npt.NDArray[np.str_]
    notes: list[Note] = dataclasses.field(default_factory=list)
    path: Path | None = None

    def __len__(self) -> int:
        return len(self.phases)

    @property
    def name(self) -> str:
        """The file name, or "<log>"."""
        return str(self.path) if self.path is not None else "<log>"

    @property
    def program(self) -> str:
        """The program that wrote it ("policy" or "calibrate")."""
        return self.metadata["program"]

    @property
    def period(self) -> float:
        """The control period (s)."""
        return float(self.metadata["control_period_s"])

    def number(self, key: str) -> float:
        """A metadata value as a float."""
        return float(self.metadata[key])

    def stack(self, *names: str) -> npt.NDArray[np.float64]:
        """Columns side by side, shape (rows, len(names))."""
        return np.stack([self.values[name] for name in names], axis=1)

    @property
    def time(self) -> npt.NDArray[np.float64]:
        return self.values["time"]

    @property
    def commands(self) -> npt.NDArray[np.float64]:
        """(rows, 2): the wheel commands sent (speed units)."""
        return self.stack("cmd_left", "cmd_right")

    @property
    def speeds(self) -> npt.NDArray[np.float64]:
        """(rows, 2): the measured wheel speeds (speed units)."""
        return self.stack("speed_left", "speed_right")

    @property
    def encoders(self) -> npt.NDArray[np.float64]:
        """(rows, 2): the encoders (pulses)."""
        return self.stack("enc_left", "enc_right")

    @property
    def ir(self) -> npt.NDArray[np.float64]:
        """(rows, 8): the ring's raw values."""
        return self.stack(*(f"ir_{i}" for i in range(8)))

    @property
    def us(self) -> npt.NDArray[np.float64]:
        """(rows, 5): the ultrasonic readings (cm or codes)."""
        return self.stack(*(f"us_{i}" for i in range(5)))

    @property
    def gyro_z(self) -> npt.NDArray[np.float64]:
        """(rows,): the yaw rate (counts of 0.066 °/s)."""
        return self.values["gyro_z"]

    def extra(self, prefix: str) -> npt.NDArray[np.float64]:
        """(rows, k): the policy's ``obs_i`` or ``action_i`` columns (k = 0 if none)."""
        names = [c for c in self.columns if c.startswith(prefix + "_")]
        if not names:
            return np.zeros((len(self), 0))
        return self.stack(*names)

    def select(self, rows: npt.NDArray[np.bool_] | slice) -> RobotLog:
        """A log of some rows only (same metadata and notes)."""
        return dataclasses.replace(
            self,
            values={k: v[rows] for k, v in self.values.items()},
            phases=self.phases[rows],
        )


def extra_columns(prefix: str, count: int) -> list[str]:
    """The names of ``count`` extra columns (``obs_0``, ...)."""
    return [f"{prefix}_{i}" for i in range(count)]


def _kind(name: str) -> str:
    for column in COLUMNS:
        if column.name == name:
            return column.kind
    return "float"


def _format_value(name: str, value: float | str) -> str:
    kind = _kind(name)
    if kind == "name":
        return str(value)
    if kind == "int":
        return str(round(float(value)))
    if name == "time":
        return f"{float(value):.4f}"
    if name.startswith(("acc_", "gyro_")):
        return f"{float(value):.2f}"
    return f"{float(value):.9g}"


def format_log(log: RobotLog) -> str:
    """The text of a log, exactly as the robot programs write it."""
    lines = [f"{MAGIC}{FORMAT_VERSION}"]
    lines += [f"# {key}: {value}" for key, value in log.metadata.items()]
    lines.append(",".join(log.columns))
    notes = sorted(log.notes, key=lambda n: n.after)
    lines += [f"# note: {n.key}: {n.value}" for n in notes if n.after < 0]
    for row in range(len(log)):
        fields = []
        for name in log.columns:
            value = log.phases[row] if name == "phase" else log.values[name][row]
            fields.append(_format_value(name, value))
        lines.append(",".join(fields))
        lines += [f"# note: {n.key}: {n.value}" for n in notes if n.after == row]
    lines.append(f"# end: {len(log)} rows")
    return "\n".join(lines) + "\n"


def write_log(path: str | Path, log: RobotLog) -> Path:
    """Writes ``log`` to ``path`` in the robot's format; returns the path."""
    path = Path(path)
    path.write_text(format_log(log), encoding="utf-8")
    return path


def _required_metadata(program: str) -> list[str]:
    return [*METADATA, *PROGRAM_METADATA.get(program, {})]


def _check_columns(path: str | Path, line: int, names: list[str]) -> None:
    """The column line: every column of format 1 in order, then obs_i and action_i only."""
    base = [column.name for column in COLUMNS]
    for index, expected in enumerate(base):
        got = names[index] if index < len(names) else None
        if got != expected:
            what = f"expected column {expected!r}" + (
                f", found {got!r}" if got is not None else ", but the line ends"
            )
            if expected not in names:
                what = f"missing column {expected!r} (" + what + ")"
            raise LogFormatError(
                path,
                line,
                f"{what}; format {FORMAT_VERSION}'s columns are {', '.join(base)}, then the "
                "policy's obs_i and action_i",
                index + 1,
                expected,
            )
    seen: set[str] = set(base)
    for index in range(len(base), len(names)):
        name = names[index]
        prefix, _, number = name.partition("_")
        if prefix not in EXTRA_PREFIXES or not number.isdigit() or name in seen:
            raise LogFormatError(
                path,
                line,
                f"unexpected column {name!r}: after the {len(base)} columns of format "
                f"{FORMAT_VERSION} only obs_i and action_i may follow, once each",
                index + 1,
                name,
            )
        seen.add(name)


def read_log(path: str | Path) -> RobotLog:
    """Reads and checks a robot log.

    Raises:
        LogFormatError: The first problem found, naming the file, line and column.
        ConfigError: The file cannot be read.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: robot log not found") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ConfigError(f"{path}: cannot read the robot log: {error}") from None
    return parse_log(text, path)


def parse_log(text: str, path: str | Path = "<log>") -> RobotLog:
    """Parses the text of a robot log (see :func:`read_log`)."""
    lines = text.split("\n")
    ended_with_newline = lines[-1] == ""
    if ended_with_newline:
        lines.pop()
    if not lines or not lines[0].startswith(MAGIC):
        first = lines[0][:60] if lines else ""
        raise LogFormatError(
            path,
            1,
            f"not a khepera_gym robot log: the first line must be '{MAGIC}N', got {first!r}",
        )
    version = lines[0][len(MAGIC) :]
    if version != str(FORMAT_VERSION):
        raise LogFormatError(
            path,
            1,
            f"format version {version!r}; this khepera_gym reads format {FORMAT_VERSION} "
            "(regenerate the robot program with this version, or use the version that wrote it)",
        )
    metadata: dict[str, str] = {}
    index = 1
    while index < len(lines) and lines[index].startswith("#"):
        match = _META.match(lines[index])
        if match is None:
            raise LogFormatError(path, index + 1, "expected '# key: value' before the column line")
        if match.group("key") in metadata:
            raise LogFormatError(path, index + 1, f"metadata {match.group('key')!r} given twice")
        metadata[match.group("key")] = match.group("value").strip()
        index += 1
    if index >= len(lines):
        raise LogFormatError(path, index, "truncated: the file ends before its column line")
    program = metadata.get("program")
    if program not in PROGRAMS:
        raise LogFormatError(
            path, 2, f"metadata 'program' must be one of {PROGRAMS}, got {program!r}"
        )
    for key in _required_metadata(program):
        if key not in metadata:
            raise LogFormatError(
                path, index, f"missing metadata '# {key}: ...' ({_required_metadata_doc(key)})"
            )
    for key in ("control_period_s", "wheel_radius_m", "axle_length_m", "gyro_samples"):
        value = _finite(metadata[key])
        if value is None or value <= 0:
            raise LogFormatError(path, 2, f"metadata {key!r} must be a number > 0, got {value!r}")
    column_line = index + 1
    names = lines[index].split(",")
    _check_columns(path, column_line, names)
    columns = tuple(names)
    kinds = [_kind(name) for name in columns]
    rows: list[list[float]] = []
    phases: list[str] = []
    notes: list[Note] = []
    end_rows: int | None = None
    last_time = -math.inf
    for number, line in enumerate(lines[index + 1 :], start=column_line + 1):
        if end_rows is not None:
            raise LogFormatError(path, number, "text after the '# end' line")
        if line.startswith("#"):
            end = _END.match(line)
            if end is not None:
                end_rows = int(end.group("rows"))
                if end_rows != len(rows):
                    raise LogFormatError(
                        path,
                        number,
                        f"the end line counts {end_rows} rows but the file has {len(rows)}",
                    )
                continue
            note = _NOTE.match(line)
            if note is None:
                raise LogFormatError(path, number, "expected '# note: key: value' or '# end'")
            notes.append(Note(len(rows) - 1, note.group("key"), note.group("value").strip()))
            continue
        fields = line.split(",")
        if len(fields) != len(columns):
            message = f"{len(fields)} values for {len(columns)} columns"
            if number == len(lines):
                message += "; the file is truncated (cut in the middle of a row)"
            if len(fields) < len(columns):
                position: int = len(fields) + 1
                raise LogFormatError(path, number, message, position, columns[position - 1])
            raise LogFormatError(path, number, message, len(columns) + 1)
        values: list[float] = []
        for position, (field, name, kind) in enumerate(
            zip(fields, columns, kinds, strict=True), start=1
        ):
            if kind == "name":
                if not _NAME.match(field):
                    raise LogFormatError(
                        path, number, f"{field!r} is not a phase name", position, name
                    )
                phases.append(field)
                continue
            value = _finite(field)
            if value is None:
                raise LogFormatError(
                    path, number, f"{field!r} is not a finite number", position, name
                )
            if kind == "int" and value != int(value):
                raise LogFormatError(
                    path, number, f"{field!r} is not a whole number", position, name
                )
            values.append(value)
        if values[0] <= last_time:
            raise LogFormatError(
                path,
                number,
                f"time goes backwards or stands still: {values[0]} s after {last_time} s",
                1,
                "time",
            )
        last_time = values[0]
        rows.append(values)
    if end_rows is None:
        raise LogFormatError(
            path,
            len(lines),
            "truncated: the log has no '# end: N rows' line (the program did not finish "
            f"writing it); the last complete row is line {column_line + len(rows)}",
        )
    if not ended_with_newline:
        raise LogFormatError(path, len(lines), "truncated: the last line has no line end")
    if not rows:
        raise LogFormatError(path, column_line, "the log has no rows")
    numeric = [name for name in columns if name != "phase"]
    table = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(numeric))
    return RobotLog(
        metadata=metadata,
        columns=columns,
        values={name: table[:, k] for k, name in enumerate(numeric)},
        phases=np.asarray(phases, dtype=np.str_),
        notes=notes,
        path=Path(path),
    )


def _required_metadata_doc(key: str) -> str:
    if key in METADATA:
        return METADATA[key]
    for keys in PROGRAM_METADATA.values():
        if key in keys:
            return keys[key]
    return ""


def _finite(text: str) -> float | None:
    """``text`` as a finite float, or None."""
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def note(log: RobotLog, key: str) -> str | None:
    """The value of the last ``# note:`` of ``key``, or None."""
    found = [n.value for n in log.notes if n.key == key]
    return found[-1] if found else None


def new_log(
    metadata: Mapping[str, object],
    rows: Sequence[Mapping[str, float | str]],
    extra: Sequence[str] = (),
) -> RobotLog:
    """A log from rows given as dicts (column → value), with the columns of format 1 and
    ``extra`` ones; for synthetic logs and tests."""
    columns = tuple([column.name for column in COLUMNS] + list(extra))
    numeric = [name for name in columns if name != "phase"]
    values = {name: np.asarray([float(row[name]) for row in rows]) for name in numeric}
    phases = np.asarray([str(row["phase"]) for row in rows], dtype=np.str_)
    return RobotLog({k: str(v) for k, v in metadata.items()}, columns, values, phases)


__all__ = [
    "COLUMNS",
    "EXTRA_PREFIXES",
    "FORMAT_VERSION",
    "MAGIC",
    "METADATA",
    "POLICY_PHASE",
    "PROGRAMS",
    "PROGRAM_METADATA",
    "UNITS_LINE",
    "WALL_GAP_NOTE",
    "Column",
    "LogFormatError",
    "Note",
    "RobotLog",
    "extra_columns",
    "format_log",
    "new_log",
    "note",
    "parse_log",
    "read_log",
    "write_log",
]
