//! IMU specification (issue 15), on the v1 defaults (the v2 profile's reading is in
//! `tests/drive.rs`): the accelerometer reads gravity on z, 0 horizontally at
//! constant speed, the speed profile's acceleration while the wheels ramp, the centripetal
//! acceleration on a circle, and a spike when a wall stops the robot; noise as configured.
//! Thresholds come from kinematics and the sensor's resolution (1 mg), not from the code.
//!
//! Units: metres, seconds; accelerometer counts of 1 mg; robot frame x forward, y left.

use crate::common;

use _core::sensors::imu::STANDARD_GRAVITY;
use _core::tasks::{Env, TaskKind};

/// A Nav env whose robot carries the IMU, starts at (`x`, 0) facing +x, and `overrides`.
fn env_at(x: f32, overrides: &str) -> Env {
    let text = format!(
        "max_steps = 100000\ncarry = [\"ir\", \"us\", \"gyro\", \"imu\"]\n\
         start = [{x}, 0.0, 0.0]\ngoal = [0.8, 0.8]\n{overrides}"
    );
    common::env(TaskKind::Nav, common::scenario_in("nav", &text, 1), 5).0
}

/// [`env_at`] x = -0.8.
fn env_with(overrides: &str) -> Env {
    env_at(-0.8, overrides)
}

/// Steps `env` `steps` times with `action`; returns each step's accelerometer counts.
fn run(env: &mut Env, action: [f32; 2], steps: usize) -> Vec<[i32; 3]> {
    let mut obs = vec![0.0; env.obs_dim()];
    (0..steps)
        .map(|_| {
            env.step(&action, &mut obs);
            env.done = false;
            env.world.robots[0].readings.imu.accel_raw
        })
        .collect()
}

/// Acceleration (m/s²) as whole counts of 1 mg.
fn milli_g(a: f32) -> f32 {
    a / STANDARD_GRAVITY * 1000.0
}

const NOISELESS: &str = "imu_accel_noise_sigma = 0.0\nimu_gyro_noise_sigma = 0.0";

#[test]
fn test_at_rest_it_reads_minus_one_g_on_z_and_nothing_else() {
    let mut env = env_with(NOISELESS);
    for reading in run(&mut env, [0.0, 0.0], 20) {
        assert_eq!(reading, [0, 0, -1000]);
    }
}

#[test]
fn test_ramp_constant_speed_and_a_wall() {
    // Both wheels at half speed: 0.4065 m/s, reached along K-Team's speed profile (0.2035 m/s²)
    // in 2 s from rest, then held until the wall at x = 1 stops the robot.
    let mut env = env_with(NOISELESS);
    let profile = env.world.drive.wheel_accel_limit;
    let speed = 0.5 * env.world.drive.max_wheel_speed;
    let dt = env.world.dt();
    let readings = run(&mut env, [0.5, 0.5], 140);
    let ramp_steps = (speed / profile / dt) as usize;
    // While the wheels ramp (away from its first and last step, where the mean velocities of
    // two steps differ by less than a full step's ramp), x reads the profile within a count.
    for r in &readings[2..ramp_steps - 1] {
        assert!((r[0] as f32 - milli_g(profile)).abs() <= 1.0, "{r:?}");
        assert_eq!(r[1], 0);
    }
    // At constant speed on a straight line, nothing horizontally.
    let x_at = |steps: usize| -0.8 + speed * (steps as f32 * dt - 0.5 * speed / profile);
    let free: Vec<usize> = (ramp_steps + 2..readings.len())
        .filter(|&k| x_at(k + 1) < 1.0 - env.world.drive.radius - 0.05)
        .collect();
    assert!(free.len() > 10);
    for &k in &free {
        assert_eq!(readings[k][..2], [0, 0], "step {k}");
    }
    // The wall takes the speed within a step or two: the two readings around the impact add
    // up to at least -v/dt, so one of them reads at least v/(2 dt) of deceleration.
    let worst = readings.iter().map(|r| r[0]).min().unwrap_or(0) as f32;
    assert!(
        worst <= -milli_g(speed / (2.0 * dt)) + 1.0,
        "the impact read only {worst} mg"
    );
    assert!(env.world.robots[0].position.x > 0.9);
}

#[test]
fn test_a_circle_reads_the_centripetal_acceleration_on_y() {
    // Wheels (0.3, 0.5) of full speed at once: v = 0.325 m/s, ω = 1.54 rad/s on a 0.21 m
    // circle around (0, 0.21): a = v·ω = 51 mg toward the centre (left). The mean velocities
    // of two steps are v·sinc(ω dt / 2) long and ω·dt apart, so the reading's size is
    // v·ω·sinc²(ω dt / 2), 0.05 % below v·ω here: within the count. Its direction is the
    // robot's left up to the tyres' slip angle, which carries the centripetal force (a few
    // degrees at most at 0.05 g [E]); with the kinematic drive (no slip) it is exactly left.
    let mut env = env_at(0.0, &format!("{NOISELESS}\nwheel_accel_limit = inf"));
    let speeds = [0.3, 0.5].map(|a| a * env.world.drive.max_wheel_speed);
    let v = 0.5 * (speeds[0] + speeds[1]);
    let w = (speeds[1] - speeds[0]) / env.world.drive.axle_length;
    let readings = run(&mut env, [0.3, 0.5], 60);
    // The body takes a step or two to reach its wheels' speed (the tyres' grip is finite).
    for r in &readings[3..] {
        let size = (r[0] as f32).hypot(r[1] as f32);
        assert!((size - milli_g(v * w)).abs() <= 1.0, "{r:?}");
        assert!(
            (r[0] as f32).atan2(r[1] as f32).abs() < 3f32.to_radians(),
            "{r:?}"
        );
    }
    let mut env = env_at(
        0.0,
        &format!("{NOISELESS}\nwheel_accel_limit = inf\ndrive = \"kinematic\""),
    );
    for r in &run(&mut env, [0.3, 0.5], 60)[1..] {
        assert_eq!(r[0], 0, "{r:?}");
        assert!((r[1] as f32 - milli_g(v * w)).abs() <= 1.0, "{r:?}");
    }
}

#[test]
fn test_noise_has_the_configured_spread() {
    // 2 mg Gaussian per reading, quantised to 1 mg: a standard deviation of
    // √(2² + 1/12) = 2.02 mg; 400 readings put the sample's within ±10 % of it (4 standard
    // errors of 2.5 %).
    let mut env = env_with("imu_accel_noise_sigma = 0.002");
    let z: Vec<f32> = run(&mut env, [0.0, 0.0], 400)
        .iter()
        .map(|r| r[2] as f32)
        .collect();
    let mean = z.iter().sum::<f32>() / z.len() as f32;
    let var = z.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / (z.len() - 1) as f32;
    let expected = (4.0f32 + 1.0 / 12.0).sqrt();
    assert!(
        (var.sqrt() - expected).abs() < 0.1 * expected,
        "{}",
        var.sqrt()
    );
    assert!((mean + 1000.0).abs() < 0.5, "{mean}");
}
