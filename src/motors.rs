//! `[motors]`: how the robot's motor controller (the dsPIC) makes the wheels follow their speed
//! orders, as a choice the real robot can be set to.
//!
//! The Khepera IV's firmware has two modes a program drives in (K-Team Khepera IV User Manual
//! 3.0, §4.14; docs/drive.md):
//! * **profile** (`kh4_SetMode(kh4RegSpeedProfile)`): the order given to the wheels' PID ramps
//!   toward each new speed by `acc_inc` speed units every `acc_div + 1` control periods of 10 ms,
//!   and a nonzero order never lies below `min_speed_acc` units. The firmware computes the ramp,
//!   so the simulator can follow it exactly: `kh4_SetSpeedProfile(acc_inc, acc_div,
//!   min_speed_acc, min_speed_dec, max_speed)` sets the same numbers on the robot.
//! * **speed** (`kh4_SetMode(kh4RegSpeed)`): the PID follows each order "as quick as possible, in
//!   an abrupt way" (§4.14.1). Its acceleration is limited only by the motors and the tyres; no
//!   measurement of it is published, so `speed_accel` is an estimate [E].
//!
//! A third mode, **ramp**, is a plain acceleration limit (`robot.wheel_accel_limit`) with no
//! firmware counterpart: the drive of the behaviour versions before v2 (v0: none; v1: K-Team's
//! default ramp, 0.203 m/s², without the profile's minimum speed).
//!
//! Units: K-Team speed units (0.678181 mm/s each) where a key says so, otherwise SI (m/s²).
//! The firmware's ramp changes the order in steps every 10 ms; the simulator ramps at their
//! average rate, which puts the wheel at most one step (e.g. 40 units = 27 mm/s at Acc_Inc 40)
//! and 10 ms from the firmware's staircase, about 0.14 mm of travel per ramp [D].

use serde::{Deserialize, Serialize};
use toml::{Table, Value};

use crate::config::{self, limits, ConfigTable, Domain, Param};
use crate::error::{Error, Result};

/// The motor controller's period (s): the PID and the profile run every 10 ms
/// (`KH4_TIME_BTWN`, manual §4.14).
pub const CONTROL_PERIOD_S: f32 = 0.01;
/// One speed unit in m/s.
/// One `kh4_set_speed` unit in mm/s (pulses per 10 ms): K-Team manual §4.14, the unit of every
/// speed and of the profile's increments.
pub const MM_S_PER_SPEED_UNIT: f32 = 0.678181;

const SPEED_UNIT: f32 = MM_S_PER_SPEED_UNIT / 1000.0;
/// The firmware's range of a profile parameter (one byte, `kh4_SetSpeedProfile`'s `char`s).
const BYTE_MAX: u32 = 255;

/// Which of the firmware's modes drives the wheels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MotorMode {
    /// K-Team's speed profile (`kh4RegSpeedProfile`): a ramp set in the firmware's units.
    Profile,
    /// K-Team's speed mode (`kh4RegSpeed`): the PID without a ramp, motor-limited [E].
    Speed,
    /// A plain acceleration limit, `robot.wheel_accel_limit` (the drive of v0 and v1).
    Ramp,
}

impl MotorMode {
    /// The name the scenario file uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Profile => "profile",
            Self::Speed => "speed",
            Self::Ramp => "ramp",
        }
    }
}

crate::config_table! {
    /// `[motors]`: the motor controller's mode and its settings (K-Team manual §4.14).
    pub struct MotorsConfig {
        /// "profile": K-Team's speed profile (kh4RegSpeedProfile), exact; "speed": K-Team's speed mode (kh4RegSpeed), acceleration estimated [E]; "ramp": robot.wheel_accel_limit, a plain limit the robot cannot be set to (v0, v1)
        mode: MotorMode = "profile",
        /// a named setting of the keys below, as real programs set them (khepera_gym.motor_presets() lists them); "" = none; given with any of them it is an error
        preset: String = "",
        /// profile: speed units (0.678 mm/s) added to the order every acc_div + 1 periods of 10 ms: 40 = 2.71 m/s^2, 10 = 0.678 (K-Team's Braitenberg demo), 3 = 0.203 (K-Team's default) (firmware range 1..255, manual §4.14.2); may be a [low, high] range
        acc_inc: Param = 40 => Domain::range(1.0, BYTE_MAX as f64),
        /// profile: periods of 10 ms between two increments, minus one (0..255, manual §4.14.2)
        acc_div: u32 = 0 => Domain::range(0.0, BYTE_MAX as f64),
        /// profile: speed units; an order below it is raised to it, and the ramp starts from it and drops to 0 from it (1..255, manual §4.14.2 and its figure; default 20 = 13.6 mm/s)
        min_speed_acc: u32 = 20 => Domain::range(1.0, BYTE_MAX as f64),
        /// profile: speed units; the final speed of position mode (manual §4.14.3): not simulated, set on the robot by export (0..255)
        min_speed_dec: u32 = 1 => Domain::range(0.0, BYTE_MAX as f64),
        /// speed: the wheels' acceleration limit in speed mode (m/s^2) [E: no measurement found; Webots' Khepera IV motor allows 130.45 rad/s^2 x 0.021 m = 2.74]; may be a [low, high] range
        speed_accel: Param = 2.74 => Domain::POSITIVE.at_most(limits::ACCEL),
    }
}

/// A named drive: (name, what it sets, where it comes from).
pub struct MotorPreset {
    /// Its name (`motors.preset`).
    pub name: &'static str,
    /// The `[motors]` keys it sets, as TOML.
    pub settings: &'static str,
    /// Who sets it on the real robot.
    pub source: &'static str,
}

/// The drives real programs set on the Khepera IV (docs/drive.md tabulates them).
pub const PRESETS: &[MotorPreset] = &[
    MotorPreset {
        name: "kteam_default",
        settings:
            "mode = \"profile\"\nacc_inc = 3\nacc_div = 0\nmin_speed_acc = 20\nmin_speed_dec = 1",
        source:
            "K-Team's library defaults, kh4_SetSpeedProfile(3, 0, 20, 1, 400) (manual §4.14.2); \
                 ARGoS's real-robot actuator and Buzz set them: 0.203 m/s^2",
    },
    MotorPreset {
        name: "kteam_braitenberg",
        settings:
            "mode = \"profile\"\nacc_inc = 10\nacc_div = 0\nmin_speed_acc = 20\nmin_speed_dec = 1",
        source: "K-Team's Braitenberg demo (khepera4.c) and kh4server's built-in Braitenberg: \
                 0.678 m/s^2",
    },
    MotorPreset {
        name: "khepera_gym_v2",
        settings:
            "mode = \"profile\"\nacc_inc = 40\nacc_div = 0\nmin_speed_acc = 20\nmin_speed_dec = 1",
        source:
            "the default of the v2 and v3 envs: 2.71 m/s^2, the acceleration of Webots' Khepera IV \
                 motor, set on the robot exactly by the exported program",
    },
    MotorPreset {
        name: "speed_mode",
        settings: "mode = \"speed\"\nspeed_accel = 2.74",
        source:
            "K-Team's keyboard drive and kh4server's D command, EPFL's khepera4toolbox, UNED's \
                 Robotic Park: kh4RegSpeed, whose acceleration is estimated [E]",
    },
];

/// The acceleration (m/s²) of K-Team's speed profile: `acc_inc` speed units every
/// `acc_div + 1` periods of 10 ms.
pub fn profile_accel(acc_inc: f32, acc_div: u32) -> f32 {
    acc_inc * SPEED_UNIT / ((acc_div + 1) as f32 * CONTROL_PERIOD_S)
}

/// The profile's `acc_inc` (speed units, not rounded) that gives `accel` m/s² at `acc_div`.
pub fn profile_acc_inc(accel: f32, acc_div: u32) -> f32 {
    accel * (acc_div + 1) as f32 * CONTROL_PERIOD_S / SPEED_UNIT
}

/// Whether two scenario values are the same setting (`40` and `40.0` are).
fn same_value(a: Option<&Value>, b: Option<&Value>) -> bool {
    let number = |v: &Value| match v {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    };
    match (a, b) {
        (Some(a), Some(b)) => match (number(a), number(b)) {
            (Some(x), Some(y)) => x == y,
            _ => a == b,
        },
        (a, b) => a == b,
    }
}

/// The keys of `[motors]` that a preset sets and that only some modes use.
const MODE_KEYS: &[(&str, MotorMode)] = &[
    ("acc_inc", MotorMode::Profile),
    ("acc_div", MotorMode::Profile),
    ("min_speed_acc", MotorMode::Profile),
    ("min_speed_dec", MotorMode::Profile),
    ("speed_accel", MotorMode::Speed),
];

impl MotorsConfig {
    /// Reads `[motors]` from a scenario `table` and resolves it against `defaults` (the version's
    /// default scenario table): a named preset replaces the keys it sets, and a key whose value
    /// differs from its default while the mode does not use it is an error (it would change
    /// nothing). Errors name `origin` and the key.
    pub fn resolve(table: &Table, defaults: &Table, origin: &str) -> Result<Self> {
        let section = |t: &Table, name: &str| match t.get(name) {
            Some(Value::Table(s)) => s.clone(),
            _ => Table::new(),
        };
        let mut drive_table = section(table, "motors");
        let default_drive = section(defaults, "motors");
        let given = |t: &Table, key: &str| !same_value(t.get(key), default_drive.get(key));
        let preset = drive_table
            .get("preset")
            .and_then(Value::as_str)
            .unwrap_or("")
            .to_string();
        if !preset.is_empty() {
            let Some(found) = PRESETS.iter().find(|p| p.name == preset) else {
                let names: Vec<&str> = PRESETS.iter().map(|p| p.name).collect();
                return Err(Error::config(
                    origin,
                    "motors.preset",
                    format!("unknown preset {preset:?}; the presets are {names:?}"),
                ));
            };
            let set = config::parse(found.settings, "<preset>")?;
            for key in ["mode"]
                .into_iter()
                .chain(MODE_KEYS.iter().map(|(k, _)| *k))
            {
                if given(&drive_table, key) {
                    return Err(Error::config(
                        origin,
                        &format!("motors.{key}"),
                        format!(
                            "motors.preset = {preset:?} sets the drive; give the preset or \
                             motors.{key}, not both"
                        ),
                    ));
                }
            }
            for (key, value) in set {
                drive_table.insert(key, value);
            }
            drive_table.insert("preset".into(), Value::String(String::new()));
        }
        config::check_keys(&drive_table, Self::KEYS, origin, "motors")?;
        let motors: MotorsConfig = config::read_table(&drive_table, origin, "motors")?;
        motors.validate(origin)?;
        for (key, mode) in MODE_KEYS {
            if motors.mode != *mode && given(&drive_table, key) {
                return Err(Error::config(
                    origin,
                    &format!("motors.{key}"),
                    format!(
                        "is used only by motors.mode = \"{}\"; this scenario's mode is \"{}\"",
                        mode.name(),
                        motors.mode.name()
                    ),
                ));
            }
        }
        let robot = section(table, "robot");
        let default_robot = section(defaults, "robot");
        let key = "wheel_accel_limit";
        if motors.mode != MotorMode::Ramp && !same_value(robot.get(key), default_robot.get(key)) {
            let hint = match motors.mode {
                MotorMode::Profile => {
                    let accel = robot.get(key).and_then(Value::as_float).unwrap_or(f64::NAN);
                    format!(
                        "set motors.acc_inc instead (speed units per {} ms: {:.1} for {accel} \
                         m/s^2)",
                        (motors.acc_div + 1) * 10,
                        profile_acc_inc(accel as f32, motors.acc_div)
                    )
                }
                _ => "set motors.speed_accel instead".to_string(),
            };
            return Err(Error::config(
                origin,
                "robot.wheel_accel_limit",
                format!(
                    "is the acceleration of motors.mode = \"ramp\"; this scenario's drive is \
                     \"{}\": {hint}, or motors.mode = \"ramp\"",
                    motors.mode.name()
                ),
            ));
        }
        Ok(motors)
    }

    /// Checks what the keys' domains (the firmware's ranges) cannot: a fixed `acc_inc` in whole
    /// speed units, and no preset left after resolution. The error names `origin` and the key.
    pub fn validate(&self, origin: &str) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        let (lo, _) = self.acc_inc.bounds();
        if !self.acc_inc.is_random() && lo.fract() != 0.0 {
            return bad(
                "motors.acc_inc",
                format!("the firmware takes whole speed units, got {lo}"),
            );
        }
        if !self.preset.is_empty() {
            return bad(
                "motors.preset",
                "is resolved when the scenario loads; a resolved drive has none".into(),
            );
        }
        Ok(())
    }

    /// The wheels' acceleration limit (m/s²) this drive gives, a range when randomised:
    /// the profile's rate, the speed mode's estimate, or `ramp_limit` (ramp mode's
    /// `robot.wheel_accel_limit`).
    pub fn accel(&self, ramp_limit: Param) -> Param {
        match self.mode {
            MotorMode::Profile => match self.acc_inc {
                Param::Value(inc) => Param::Value(profile_accel(inc, self.acc_div)),
                Param::Range([lo, hi]) => Param::Range([
                    profile_accel(lo, self.acc_div),
                    profile_accel(hi, self.acc_div),
                ]),
            },
            MotorMode::Speed => self.speed_accel,
            MotorMode::Ramp => ramp_limit,
        }
    }

    /// The profile's smallest nonzero order (m/s): `min_speed_acc` in profile mode, else 0.
    pub fn min_order(&self) -> f32 {
        match self.mode {
            MotorMode::Profile => self.min_speed_acc as f32 * SPEED_UNIT,
            _ => 0.0,
        }
    }

    /// Whether the real robot can be set to exactly this drive: a profile with fixed values
    /// (the speed mode's acceleration is an estimate, and the ramp has no firmware mode).
    pub fn is_exact(&self) -> bool {
        self.mode == MotorMode::Profile && !self.acc_inc.is_random()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_units_give_the_manuals_accelerations() {
        // 3 units of 0.678181 mm/s every 10 ms: K-Team's default, 0.2035 m/s².
        assert!((profile_accel(3.0, 0) - 0.2034543).abs() < 1e-7);
        assert!((profile_accel(10.0, 0) - 0.678181).abs() < 1e-6);
        assert!((profile_accel(40.0, 0) - 2.712724).abs() < 1e-5);
        // Acc_Div 4: every 5 periods (50 ms), manual §4.14.2's example.
        assert!((profile_accel(40.0, 4) - 2.712724 / 5.0).abs() < 1e-6);
        assert!((profile_acc_inc(profile_accel(17.0, 2), 2) - 17.0).abs() < 1e-4);
    }
}
