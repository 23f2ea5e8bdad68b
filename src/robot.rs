//! The Khepera IV's body, differential drive and speed units.
//!
//! Numbers come from docs/robot.md §1 (K-Team user manual 3.0). Units are SI: metres,
//! seconds, radians. Robot frame: x forward, y left, angles counter-clockwise. World state is f32.

use crate::config::{limits, Domain, Param};
use crate::error::{Error, Result};
use crate::motors::MotorsConfig;
pub use crate::motors::MM_S_PER_SPEED_UNIT;

/// Body radius (m): 140.8 mm diameter in the mechanical drawing.
pub const BODY_RADIUS: f32 = 0.0704;
/// Wheel radius (m): 42 mm diameter.
pub const WHEEL_RADIUS: f32 = 0.021;
/// Distance between the wheels (m), `KH4_WHEELS_DISTANCE`.
pub const AXLE_LENGTH: f32 = 0.1054;
/// Largest closed-loop wheel speed (m/s): about 1200 speed units.
pub const MAX_WHEEL_SPEED: f32 = 0.813;
/// Smallest controlled wheel speed (m/s); the real PID cannot hold less, so smaller commands give 0.
pub const MIN_WHEEL_SPEED: f32 = 0.003;
/// Encoder pulses per wheel revolution: 128 × 4 (quadrature) × 38:1 gearbox.
pub const PULSES_PER_WHEEL_TURN: f64 = 19456.0;

crate::config_table! {
    /// `[robot]`: the Khepera IV's body and drive (robot.md §1). Entries typed [`Param`] may be
    /// `[low, high]` ranges, drawn at every reset (domain randomisation).
    pub struct RobotConfig {
        /// body radius (m): 140.8 mm diameter (K-Team manual fig. 8.1)
        radius: f32 = 0.0704 => Domain::range(limits::BODY_PART, limits::LENGTH),
        /// m: 42 mm wheels (K-Team manual §4.14)
        wheel_radius: f32 = 0.021 => Domain::range(limits::BODY_PART, limits::LENGTH),
        /// wheel separation (m), KH4_WHEELS_DISTANCE; may be a [low, high] range
        axle_length: Param = 0.1054 => Domain::range(limits::BODY_PART, limits::LENGTH),
        /// m/s, closed-loop limit (about 1200 speed units, manual §4.14.1); may be a range
        max_wheel_speed: Param = 0.813 => Domain::POSITIVE.at_most(limits::SPEED),
        /// m/s; smaller commands give 0 (the real PID's floor, manual §4.14.1)
        min_wheel_speed: f32 = 0.003 => Domain::NON_NEGATIVE.at_most(limits::SPEED),
        /// m/s^2 per wheel, the acceleration of motors.mode = "ramp" only (v0: inf = none; v1: 0.2034543, K-Team's default profile rate, 3 speed units of 0.678 mm/s per 10 ms, manual §4.14.2); the other modes set theirs in [motors]; may be a finite range
        wheel_accel_limit: Param = 0.2034543 => Domain::POSITIVE.at_most(limits::ACCEL).or_inf(),
        /// s, first-order lag of each wheel behind its order (the PID's response), in every drive mode (0 = none) [E]
        motor_time_constant: f32 = 0.0 => Domain::NON_NEGATIVE.at_most(limits::TIME),
        /// kg [E]: K-Team's usual figure; Webots uses 0.606; may be a range
        mass: Param = 0.54 => Domain::POSITIVE.at_most(limits::MASS),
        /// tyre-floor friction coefficient, each wheel carrying half the weight (the ball casters little) [E: Webots' default contact friction 1]; may be a range
        tyre_friction: Param = 1.0 => Domain::NON_NEGATIVE.at_most(limits::FRICTION),
        /// infrared reflectance of the shell relative to white paper (1 = K-Team's curve) [E]
        shell_reflectance: f32 = 1.0 => Domain::NON_NEGATIVE.at_most(limits::REFLECTANCE),
        /// RGB in [0, 1] the camera sees of a robot: its top LEDs (3 RGB LEDs, 6 bits a colour, robot.md §6) [E: green]
        led_color: [f32; 3] = [0.0, 0.8, 0.0] => Domain::UNIT,
    }
}

impl RobotConfig {
    /// Checks what the keys' domains cannot (each value alone is checked by its declaration):
    /// the floor of commands below the speed limit. The error names `origin` and the key.
    pub fn validate(&self, origin: &str) -> Result<()> {
        if self.min_wheel_speed >= self.max_wheel_speed.bounds().0 {
            return Err(Error::config(
                origin,
                "robot.min_wheel_speed",
                format!(
                    "must be below robot.max_wheel_speed ({:?}), got {}",
                    self.max_wheel_speed, self.min_wheel_speed
                ),
            ));
        }
        Ok(())
    }
}

/// How an action's two numbers are read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActionType {
    /// Normalised (left, right) wheel speeds in [-1, 1], scaled by the maximum wheel speed.
    Wheels,
    /// Normalised (v, ω) in [-1, 1]: v scaled by the maximum wheel speed, ω by the in-place
    /// yaw rate limit 2·v_max/axle; wheels that would exceed the limit are scaled down together.
    Unicycle,
}

impl ActionType {
    /// Parses `"wheels"` or `"unicycle"`.
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "wheels" => Some(Self::Wheels),
            "unicycle" => Some(Self::Unicycle),
            _ => None,
        }
    }

    /// The name [`ActionType::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Self::Wheels => "wheels",
            Self::Unicycle => "unicycle",
        }
    }
}

/// Drive parameters of one robot, taken from the scenario's `[robot]` table.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct Drive {
    /// Body radius (m).
    pub radius: f32,
    /// Wheel radius (m).
    pub wheel_radius: f32,
    /// Wheel separation (m).
    pub axle_length: f32,
    /// Wheel speed limit (m/s).
    pub max_wheel_speed: f32,
    /// Commands below this magnitude give 0 (m/s).
    pub min_wheel_speed: f32,
    /// Wheel acceleration limit (m/s²); infinite for none.
    pub wheel_accel_limit: f32,
    /// Time constant (s) of each wheel's first-order lag behind its speed profile; 0 for none.
    #[serde(default)]
    pub motor_time_constant: f32,
    /// The speed profile's smallest nonzero order (m/s, `motors.min_speed_acc`): a smaller order
    /// is raised to it, and the order jumps between it and 0; 0 outside profile mode.
    pub min_order: f32,
}

impl Drive {
    /// Drive parameters from validated `[robot]` and `[drive]` tables.
    /// Ranges (domain randomisation) start at their low end until `World::randomise`.
    pub fn from_config(cfg: &RobotConfig, drive: &MotorsConfig) -> Self {
        Self {
            radius: cfg.radius,
            wheel_radius: cfg.wheel_radius,
            axle_length: cfg.axle_length.bounds().0,
            max_wheel_speed: cfg.max_wheel_speed.bounds().0,
            min_wheel_speed: cfg.min_wheel_speed,
            wheel_accel_limit: drive.accel(cfg.wheel_accel_limit).bounds().0,
            motor_time_constant: cfg.motor_time_constant,
            min_order: drive.min_order(),
        }
    }

    /// Largest yaw rate (rad/s), turning in place at full wheel speed.
    pub fn max_yaw_rate(&self) -> f32 {
        2.0 * self.max_wheel_speed / self.axle_length
    }

    /// Wheel speed commands (m/s) for a normalised action. Finite values outside [-1, 1] are
    /// clipped; commands under the controller's floor become 0.
    pub fn wheel_command(&self, action: [f32; 2], kind: ActionType) -> [f32; 2] {
        let a0 = action[0].clamp(-1.0, 1.0);
        let a1 = action[1].clamp(-1.0, 1.0);
        let [left, right] = match kind {
            ActionType::Wheels => [a0 * self.max_wheel_speed, a1 * self.max_wheel_speed],
            ActionType::Unicycle => {
                let v = a0 * self.max_wheel_speed;
                let w = a1 * self.max_yaw_rate();
                let half = 0.5 * w * self.axle_length;
                let (l, r) = (v - half, v + half);
                let peak = l.abs().max(r.abs());
                let scale = if peak > self.max_wheel_speed {
                    self.max_wheel_speed / peak
                } else {
                    1.0
                };
                [l * scale, r * scale]
            }
        };
        [self.floor(left), self.floor(right)]
    }

    /// The dead band (orders under the PID's floor give 0), then the profile's minimum order
    /// (a smaller nonzero order is raised to it; none outside profile mode).
    fn floor(&self, speed: f32) -> f32 {
        if speed.abs() < self.min_wheel_speed {
            0.0
        } else if speed.abs() < self.min_order {
            self.min_order.copysign(speed)
        } else {
            speed
        }
    }

    /// The most a wheel's speed can change over `duration` seconds (m/s): the acceleration
    /// limit's share, plus the profile's jump between rest and its minimum order.
    pub fn max_speed_change(&self, duration: f32) -> f32 {
        self.wheel_accel_limit * duration + self.min_order
    }

    /// Moves the actual wheel speeds toward the commands within the acceleration limit over `dt`.
    /// With a profile's minimum order ([`Drive::min_order`] > 0), a nonzero order below it is
    /// raised to it and the speed never lies strictly between 0 and it: from rest it starts at
    /// the minimum, and toward rest (or through it) it drops from the minimum to 0, as the
    /// figure of manual §4.14.2 shows (its ~50 ms pause at the minimum is not modelled: at most
    /// 13.6 mm/s × 50 ms = 0.7 mm [D]).
    pub fn ramp(&self, actual: [f32; 2], command: [f32; 2], dt: f32) -> [f32; 2] {
        if !self.wheel_accel_limit.is_finite() {
            return command;
        }
        let step = self.wheel_accel_limit * dt;
        if self.min_order <= 0.0 {
            return [
                actual[0] + (command[0] - actual[0]).clamp(-step, step),
                actual[1] + (command[1] - actual[1]).clamp(-step, step),
            ];
        }
        let least = self.min_order;
        let profile = |speed: f32, order: f32| {
            let order = if order != 0.0 && order.abs() < least {
                least.copysign(order)
            } else {
                order
            };
            let ramped = speed + (order - speed).clamp(-step, step);
            if ramped == 0.0 || ramped.abs() >= least {
                ramped
            } else if order == 0.0 || order.signum() != ramped.signum() {
                0.0
            } else {
                least.copysign(order)
            }
        };
        [
            profile(actual[0], command[0]),
            profile(actual[1], command[1]),
        ]
    }

    /// One substep of `h` seconds of the motors: the speed profile moves the setpoints toward
    /// the commands within the acceleration limit, and the wheels follow their setpoints with
    /// the first-order lag `motor_time_constant` (at once when it is 0). Returns the new
    /// (setpoints, wheel speeds).
    pub fn motors(
        &self,
        setpoint: [f32; 2],
        wheels: [f32; 2],
        command: [f32; 2],
        h: f32,
    ) -> ([f32; 2], [f32; 2]) {
        let setpoint = self.ramp(setpoint, command, h);
        if self.motor_time_constant <= 0.0 {
            return (setpoint, setpoint);
        }
        let k = 1.0 - (-h / self.motor_time_constant).exp();
        (
            setpoint,
            [
                wheels[0] + k * (setpoint[0] - wheels[0]),
                wheels[1] + k * (setpoint[1] - wheels[1]),
            ],
        )
    }

    /// Body twist (v forward m/s, ω rad/s CCW) of wheel speeds (left, right).
    pub fn twist(&self, wheels: [f32; 2]) -> (f32, f32) {
        (
            0.5 * (wheels[0] + wheels[1]),
            (wheels[1] - wheels[0]) / self.axle_length,
        )
    }
}

/// Converts a wheel speed in m/s to the real robot's `kh4_set_speed` units (rounded).
pub fn speed_to_units(speed: f32) -> i32 {
    (speed * 1000.0 / MM_S_PER_SPEED_UNIT).round() as i32
}

/// Converts `kh4_set_speed` units to m/s.
pub fn units_to_speed(units: i32) -> f32 {
    units as f32 * MM_S_PER_SPEED_UNIT / 1000.0
}

/// Wraps an angle to (-π, π].
pub fn wrap_angle(angle: f32) -> f32 {
    use std::f32::consts::PI;
    let mut a = angle % (2.0 * PI);
    if a > PI {
        a -= 2.0 * PI;
    } else if a <= -PI {
        a += 2.0 * PI;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive() -> Drive {
        Drive {
            radius: BODY_RADIUS,
            wheel_radius: WHEEL_RADIUS,
            axle_length: AXLE_LENGTH,
            max_wheel_speed: MAX_WHEEL_SPEED,
            min_wheel_speed: MIN_WHEEL_SPEED,
            wheel_accel_limit: f32::INFINITY,
            motor_time_constant: 0.0,
            min_order: 0.0,
        }
    }

    #[test]
    fn wheel_actions_scale_clip_and_floor() {
        let d = drive();
        assert_eq!(
            d.wheel_command([1.0, -1.0], ActionType::Wheels),
            [0.813, -0.813]
        );
        assert_eq!(
            d.wheel_command([7.0, -3.0], ActionType::Wheels),
            [0.813, -0.813]
        );
        // 0.003 / 0.813 of full scale is the floor: just under gives 0, just over passes.
        assert_eq!(
            d.wheel_command([0.0036, -0.0036], ActionType::Wheels),
            [0.0, 0.0]
        );
        let over = d.wheel_command([0.0038, 0.0], ActionType::Wheels);
        assert!(over[0] > 0.003);
    }

    #[test]
    fn unicycle_keeps_turn_radius_when_saturated() {
        let d = drive();
        let [l, r] = d.wheel_command([1.0, 0.5], ActionType::Unicycle);
        assert!((r - 0.813).abs() < 1e-6);
        let (v, w) = d.twist([l, r]);
        // requested curvature w/v = 0.5·max_yaw / max_speed
        assert!(((w / v) - 0.5 * d.max_yaw_rate() / 0.813).abs() < 1e-3);
    }

    #[test]
    fn acceleration_limit_ramps() {
        let mut d = drive();
        d.wheel_accel_limit = 2.0;
        assert_eq!(d.ramp([0.0, 0.0], [0.8, -0.8], 0.1), [0.2, -0.2]);
    }

    #[test]
    fn the_profile_jumps_between_rest_and_its_minimum_order() {
        // K-Team's default profile (manual §4.14.2's figure): 3 units per 10 ms, minimum 20.
        let mut d = drive();
        d.wheel_accel_limit = crate::motors::profile_accel(3.0, 0);
        d.min_order = units_to_speed(20);
        let unit = units_to_speed(1);
        let h = 0.01;
        // From rest toward 100 units: straight to 20, then 3 units a period.
        let s = d.ramp([0.0, 0.0], [100.0 * unit, -100.0 * unit], h);
        assert!((s[0] - 20.0 * unit).abs() < 1e-6 && (s[1] + 20.0 * unit).abs() < 1e-6);
        let s = d.ramp(s, [100.0 * unit, -100.0 * unit], h);
        assert!((s[0] - 23.0 * unit).abs() < 1e-6, "{s:?}");
        // An order below the minimum is raised to it.
        let s = d.ramp([0.0, 0.0], [5.0 * unit, 0.0], h);
        assert!((s[0] - 20.0 * unit).abs() < 1e-6 && s[1] == 0.0, "{s:?}");
        // Toward rest: down to the minimum, then 0; through rest: 0, then the other sign's.
        let s = d.ramp([21.0 * unit, 21.0 * unit], [0.0, -50.0 * unit], h);
        assert_eq!(s, [0.0, 0.0]);
        let s = d.ramp(s, [0.0, -50.0 * unit], h);
        assert!(s[0] == 0.0 && (s[1] + 20.0 * unit).abs() < 1e-6, "{s:?}");
    }

    #[test]
    fn speed_units_round_trip() {
        assert_eq!(speed_to_units(0.813), 1199);
        assert!((units_to_speed(1200) - 0.8138).abs() < 1e-4);
    }

    #[test]
    fn wrap_angle_range() {
        use std::f32::consts::PI;
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-5);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-6);
        assert!((wrap_angle(0.5) - 0.5).abs() < 1e-7);
    }
}
