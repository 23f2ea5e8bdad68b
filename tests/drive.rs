//! The drive's specification (issue 32): the v2 default, K-Team's speed profile at Acc_Inc 40,
//! and the speed mode. Every figure comes from the firmware's rule (manual §4.14.2: the order
//! ramps by Acc_Inc speed units of 0.678181 mm/s every Acc_Div + 1 periods of 10 ms and never
//! lies between 0 and Min_Speed_Acc) or from constant acceleration, not from the code's output.
//! v1's drive (a plain ramp at 0.203 m/s²) is specified in `tests/dynamics.rs`.
//!
//! Units: metres, seconds; speed units of 0.678181 mm/s where named; accelerometer counts of
//! 1 mg; world frame.

use crate::common;

use _core::motors::{profile_accel, MotorMode};
use _core::robot::units_to_speed;
use _core::sensors::imu::STANDARD_GRAVITY;
use _core::tasks::{Env, TaskKind};
use crate::common::drive;
use rapier2d::math::Vector;

/// A Nav env of the latest defaults in a 12 m arena (room to reach full speed and brake far
/// from any wall), `overrides`, its robot at (-5.5, 0) facing +x.
fn open_floor(overrides: &str) -> Env {
    let text = format!(
        "max_steps = 100000\narena = {{ width = 12.0, height = 12.0 }}\n\
         carry = [\"ir\", \"us\", \"gyro\", \"imu\"]\nimu_accel_noise_sigma = 0.0\n{overrides}"
    );
    let mut env = common::env(TaskKind::Nav, common::scenario("nav", &text), 3).0;
    env.world.place_robot(0, Vector::new(-5.5, 0.0), 0.0);
    env
}

/// The wheel speeds after each substep (the substep's whole, as the body rolls them) and the
/// robot's x after each control step, driving `action` for `steps` steps.
fn run(env: &mut Env, action: [f32; 2], steps: usize) -> (Vec<f32>, Vec<f32>) {
    let mut xs = Vec::new();
    let mut speeds = Vec::new();
    drive(env, &action, steps, |env| {
        xs.push(env.world.robots[0].position.x);
        speeds.push(env.world.robots[0].wheel_speeds[0]);
    });
    (speeds, xs)
}

#[test]
fn test_the_v2_default_is_kteams_profile_at_acc_inc_40() {
    let cfg = common::scenario("nav", "");
    assert_eq!(cfg.motors.mode, MotorMode::Profile);
    assert_eq!((cfg.motors.acc_div, cfg.motors.min_speed_acc), (0, 20));
    // 40 units of 0.678181 mm/s every 10 ms.
    let a = cfg.wheel_accel().max();
    assert!((a - 40.0 * 0.678181e-3 / 0.01).abs() < 1e-5, "{a}");
}

#[test]
fn test_step_response_and_braking_follow_the_profile() {
    // Acc_Inc 40: a = 2.7127 m/s², the order raised every substep h = 25 ms by a·h = 6.8 cm/s,
    // more than the 13.6 mm/s minimum, so from rest v(t) = a·t at the substeps' starts, the
    // full 0.813 m/s after 0.2997 s (12 substeps), and x = a·t·(t + h)/2 while it ramps.
    // Braking from v takes v²/(2a) − v·h/2 (the same staircase down).
    let mut env = open_floor("");
    let a = env.world.drive.wheel_accel_limit;
    let vmax = env.world.drive.max_wheel_speed;
    let h = 0.025;
    let (speeds, xs) = run(&mut env, [1.0, 1.0], 10);
    for (k, v) in speeds.iter().enumerate().take(5) {
        let t = (k + 1) as f32 * 0.05;
        assert!(
            (v - a * t).abs() < 1e-5,
            "step {k}: {v} m/s, theory {}",
            a * t
        );
        let x = xs[k] + 5.5;
        let theory = 0.5 * a * t * (t + h);
        assert!(
            (x - theory).abs() < 1e-5,
            "step {k}: {x} m, theory {theory}"
        );
    }
    // Full speed from the 6th step on: 0.3 s, the profile's 0.813 / a = 0.2997 s.
    assert!(speeds[4] < vmax && speeds[5] == vmax, "{speeds:?}");
    let start = env.world.robots[0].position.x;
    let (stopped, _) = run(&mut env, [0.0, 0.0], 20);
    let braking = env.world.robots[0].position.x - start;
    let theory = vmax * vmax / (2.0 * a) - 0.5 * vmax * h;
    assert!(
        (braking - theory).abs() < 1e-3,
        "braked in {braking} m, theory {theory}"
    );
    assert!((0.10..0.13).contains(&braking), "{braking}");
    assert_eq!(stopped[19], 0.0);
}

#[test]
fn test_a_slow_profile_starts_and_stops_at_its_minimum_order() {
    // K-Team's default profile (manual §4.14.2's figure): 3 units per 10 ms, minimum 20 units.
    // From rest the order jumps to 20 units, then gains 3 units a period; braking, it drops
    // from at most 20 + 3 units to 0. An order of 10 units is raised to 20.
    let unit = units_to_speed(1);
    let mut env = open_floor("motors.preset = \"kteam_default\"");
    let a = env.world.drive.wheel_accel_limit;
    assert!((a - profile_accel(3.0, 0)).abs() < 1e-7);
    let h = 0.025;
    let (speeds, _) = run(&mut env, [0.2, 0.2], 4);
    // Substeps 1, 2, ...: 20 units, then + a·h each.
    for (k, v) in speeds.iter().enumerate() {
        let theory = 20.0 * unit + (2 * k + 1) as f32 * a * h;
        assert!((v - theory).abs() < 1e-6, "step {k}: {v}, theory {theory}");
    }
    let (speeds, _) = run(&mut env, [0.0, 0.0], 40);
    let last = speeds.iter().rev().find(|v| **v > 0.0).expect("moved");
    assert!(
        *last >= 20.0 * unit - 1e-6,
        "the speed went below the minimum: {last}"
    );
    assert_eq!(speeds[39], 0.0);
    let slow = 10.0 * unit / env.world.drive.max_wheel_speed;
    let (speeds, _) = run(&mut env, [slow, slow], 40);
    assert!((speeds[39] - 20.0 * unit).abs() < 1e-6, "{}", speeds[39]);
}

#[test]
fn test_the_accelerometer_reads_the_profiles_acceleration() {
    // The accelerometer reads the change of the mean velocity of two steps over a step: while
    // the wheels ramp (steps 2 to 5 of the 0.3 s ramp) that is a = 2.7127 m/s² = 276.6 mg,
    // within a count; then nothing at constant speed.
    let mut env = open_floor("");
    let a = env.world.drive.wheel_accel_limit;
    let mut readings = Vec::new();
    drive(&mut env, &[1.0, 1.0], 12, |env| {
        readings.push(env.world.robots[0].readings.imu.accel_raw)
    });
    let expected = a / STANDARD_GRAVITY * 1000.0;
    for r in &readings[1..5] {
        assert!(
            (r[0] as f32 - expected).abs() <= 1.0,
            "{r:?} vs {expected} mg"
        );
        assert_eq!(r[1], 0);
    }
    for r in &readings[8..] {
        assert_eq!(r[..2], [0, 0]);
    }
}

#[test]
fn test_speed_mode_ramps_at_its_estimated_acceleration() {
    // kh4RegSpeed with the [E] motor limit 2.74 m/s² (Webots' motor); no minimum order: a
    // command of 10 units (6.8 mm/s) is held as given.
    let mut env = open_floor("motors.preset = \"speed_mode\"");
    assert!((env.world.drive.wheel_accel_limit - 2.74).abs() < 1e-6);
    let (speeds, _) = run(&mut env, [1.0, 1.0], 2);
    assert!((speeds[0] - 2.74 * 0.05).abs() < 1e-5, "{speeds:?}");
    let slow = units_to_speed(10) / env.world.drive.max_wheel_speed;
    let (speeds, _) = run(&mut env, [slow, slow], 20);
    assert!(
        (speeds[19] - units_to_speed(10)).abs() < 1e-6,
        "{}",
        speeds[19]
    );
}

#[test]
fn test_drive_keys_the_mode_does_not_use_are_config_errors() {
    let (key, message) = common::config_error("nav", "wheel_accel_limit = 0.678");
    assert_eq!(key, "robot.wheel_accel_limit");
    assert!(
        message.contains("motors.acc_inc") && message.contains("10.0"),
        "{message}"
    );
    let (key, _) = common::config_error("nav", "motors.mode = \"speed\"\nacc_inc = 10");
    assert_eq!(key, "motors.acc_inc");
    let (key, _) = common::config_error("nav", "acc_inc = 300");
    assert_eq!(key, "motors.acc_inc");
    // Every version's own defaults load (v1's is a ramp, which v1 ids keep).
    for version in 0..=_core::scenario::LATEST_VERSION {
        common::scenario_in("nav", "", version);
    }
    let v1 = common::scenario_in("nav", "wheel_accel_limit = 0.678", 1);
    assert_eq!(v1.motors.mode, MotorMode::Ramp);
}
