//! Dynamics specification of the v1 defaults (issue 13; `KheperaIV-*-v1`, whose behaviour stays
//! as it was), the contact tests also on v2 (its own drive is specified in `tests/drive.rs`):
//! contacts with friction and a drive
//! bounded by the tyres' grip, the motors' speed profile, encoders, odometry, the gyroscope,
//! sonar timing and acceptance, IR reflectance, and action/observation delays. Every threshold
//! comes from the physics named in the test (rigid-body impact with Coulomb friction, constant
//! acceleration, the sensors' datasheet figures), not from what the code outputs.
//!
//! Units: metres, seconds, radians; world frame, arena centred at the origin.

use crate::common;

use std::cell::Cell;
use std::f32::consts::FRAC_PI_2;

use _core::scenario::LATEST_VERSION;
use _core::tasks::{load_scenario, Env, TaskKind};
use crate::common::drive;
use rapier2d::math::Vector;

thread_local! {
    /// The behaviour version this test thread's envs take (v1 unless [`on_versions`] says).
    static VERSION: Cell<u32> = const { Cell::new(1) };
}

/// Runs `test` on v1's defaults, then on every later version's: the contacts' physics is
/// specified for all of them (v2 changes the drive and rapier's contact prediction, v3 who solves
/// a robot's contacts with the scene, not what a contact does).
fn on_versions(test: impl Fn(u32)) {
    for version in 1..=LATEST_VERSION {
        // Shown with a failing test's output: which version failed.
        eprintln!("behaviour version {version}");
        VERSION.set(version);
        test(version);
    }
    VERSION.set(1);
}

/// An env of `task` with the current version's defaults (v1 unless [`on_versions`] runs it)
/// and `overrides`, seeded and reset.
fn env_of(task: TaskKind, overrides: &str, seed: u64) -> Env {
    let version = VERSION.get();
    common::env(
        task,
        common::scenario_in(task.name(), overrides, version),
        seed,
    )
    .0
}

fn nav(overrides: &str) -> Env {
    env_of(
        TaskKind::Nav,
        &format!("max_steps = 100000\n{overrides}"),
        7,
    )
}

const V: f32 = 0.4; // m/s, the wall sweep's wheel speed
const MU: f32 = 0.7; // the default shell-wall friction (ARGoS)

/// Drives one robot at `V` with heading `alpha` (from the top wall, y = 1) into that wall, with
/// instant wheels (so it meets the wall at `V`) and control steps of `dt` (short ones resolve
/// the impact). Returns the poses (x, y, heading) after each step.
fn wall_run(alpha_deg: f32, friction: f32, seconds: f32, dt: f32) -> Vec<(f32, f32, f32)> {
    let mut env = nav(&format!(
        "motors.mode = \"ramp\"\nwheel_accel_limit = inf\ndt = {dt}\nfriction = {friction}"
    ));
    let start_gap = 0.03; // m between the shell and the wall
    let radius = env.world.drive.radius;
    env.world.place_robot(
        0,
        Vector::new(-0.5, 1.0 - radius - start_gap),
        alpha_deg.to_radians(),
    );
    let a = V / env.world.drive.max_wheel_speed;
    let steps = (seconds / env.world.dt()).round() as usize;
    let mut poses = Vec::with_capacity(steps);
    drive(&mut env, &[a, a], steps, |env| {
        let r = &env.world.robots[0];
        poses.push((r.position.x, r.position.y, r.heading));
    });
    poses
}

/// Index of the step in which the wall stopped the robot's approach (within 5 mm of the wall,
/// its speed toward it fell below half of `V sin a`).
fn impact_step(poses: &[(f32, f32, f32)], alpha_deg: f32, dt: f32) -> usize {
    let approach = V * alpha_deg.to_radians().sin() * dt;
    let near = 1.0 - 0.0704 - 0.005;
    (1..poses.len())
        .find(|&k| poses[k].1 > near && poses[k].1 - poses[k - 1].1 < 0.5 * approach)
        .expect("never reached the wall")
}

#[test]
fn test_wall_impact_slows_the_robot_as_coulomb_friction_predicts() {
    on_versions(|_| {
        // A rigid disc (I = m R^2 / 2) meeting the wall with no bounce loses its normal velocity
        // v sin a (impulse J_n = m v sin a). Friction at the contact point then either slides,
        // removing mu J_n of tangential momentum: u = v (cos a - mu sin a), or, when that would
        // reverse the contact point (tan a >= 1 / (3 mu), 25.5 deg at mu = 0.7), rolls the shell on
        // the wall: u = 2/3 v cos a, spinning it toward the wall at (v cos a - u) 2 / R.
        // Steps of 1 ms: the step after the impact adds little of the tyres' further push.
        let dt = 0.001;
        for alpha_deg in [10.0f32, 20.0, 30.0, 45.0, 60.0, 75.0] {
            let a = alpha_deg.to_radians();
            let poses = wall_run(alpha_deg, MU, 0.6, dt);
            let k = impact_step(&poses, alpha_deg, dt);
            let (x0, _, h0) = poses[k];
            let (x1, _, h1) = poses[k + 1];
            let u = (x1 - x0) / dt;
            let rolls = a.tan() >= 1.0 / (3.0 * MU);
            let predicted = if rolls {
                2.0 / 3.0 * V * a.cos()
            } else {
                V * (a.cos() - MU * a.sin())
            };
            assert!(
                (u - predicted).abs() < 0.02,
                "{alpha_deg} deg: along the wall at {u} m/s after impact, theory {predicted}"
            );
            assert!(
                h1 > h0,
                "{alpha_deg} deg: the heading did not turn toward the wall"
            );
        }
    });
}

#[test]
fn test_robot_pushed_into_a_wall_turns_head_on_and_stalls() {
    on_versions(|_| {
        // Wall friction yaws the robot toward the wall's normal while the tyres slip, until it is
        // head-on and stuck (docs/fidelity.md §3.2): at every angle, within 4 s.
        for alpha_deg in [10.0f32, 30.0, 45.0, 60.0, 75.0] {
            let poses = wall_run(alpha_deg, MU, 4.0, 0.005);
            let end = poses[poses.len() - 1];
            assert!(
                (end.2 - FRAC_PI_2).abs() < 3f32.to_radians(),
                "{alpha_deg} deg: heading {} deg after 4 s",
                end.2.to_degrees()
            );
            let second_ago = poses[poses.len() - 201];
            let drift = ((end.0 - second_ago.0).powi(2) + (end.1 - second_ago.1).powi(2)).sqrt();
            assert!(
                drift < 0.01,
                "{alpha_deg} deg: still moving, {drift} m in the last second"
            );
        }
    });
}

#[test]
fn test_frictionless_wall_keeps_the_tangential_speed_and_the_heading() {
    on_versions(|_| {
        // mu = 0: no tangential impulse and no torque, so u = v cos a and the heading stays.
        let dt = 0.005;
        for alpha_deg in [30.0f32, 60.0] {
            let a = alpha_deg.to_radians();
            let poses = wall_run(alpha_deg, 0.0, 1.0, dt);
            let k = impact_step(&poses, alpha_deg, dt);
            let (x0, _, _) = poses[k + 10];
            let (x1, _, h) = poses[k + 60];
            let u = (x1 - x0) / (50.0 * dt);
            assert!(
                (u - V * a.cos()).abs() < 0.01,
                "{alpha_deg} deg: {u} m/s along a frictionless wall, theory {}",
                V * a.cos()
            );
            assert!(
                (h - a).abs() < 1e-3,
                "{alpha_deg} deg: heading moved to {h}"
            );
        }
    });
}

#[test]
fn test_wall_contact_converges_as_substeps_grow() {
    on_versions(|_| {
        // One second against the wall at 45 deg, with the default 2, 4 and 16 substeps: the end
        // poses agree to a few millimetres (docs/fidelity.md T4: 5 mm).
        let end = |substeps: u32| {
            let mut env = nav(&format!("substeps = {substeps}"));
            env.world.place_robot(
                0,
                Vector::new(-0.5, 1.0 - 0.0704 - 0.02),
                45f32.to_radians(),
            );
            drive(&mut env, &[0.5, 0.5], 20, |_| {});
            let r = &env.world.robots[0];
            (r.position, r.heading)
        };
        let (p16, h16) = end(16);
        for substeps in [2, 4] {
            let (p, h) = end(substeps);
            assert!((p - p16).length() < 0.005, "{substeps}: {p:?} vs {p16:?}");
            assert!((h - h16).abs() < 0.05, "{substeps}: {h} vs {h16}");
        }
    });
}

#[test]
fn test_acceleration_and_braking_follow_the_speed_profile_in_both_motion_paths() {
    // Constant acceleration a, the wheel speed updated at the start of each substep h (then held):
    // from rest v = a t and x = a t (t + h) / 2; from v the robot stops after v^2 / (2 a) - v h / 2
    // (a t^2 / 2 and v^2 / (2 a) as h -> 0). In the arena's middle the step is an exact arc; 3 mm
    // from a wall parallel to its path rapier steps the same motion: both must agree with the
    // formula and each other.
    let run = |y: f32| {
        let mut env = nav("arena = { width = 12.0, height = 12.0 }");
        let a = env.world.drive.wheel_accel_limit;
        env.world.place_robot(0, Vector::new(-5.5, y), 0.0);
        let mut xs = Vec::new();
        drive(&mut env, &[1.0, 1.0], 40, |env| {
            xs.push(env.world.robots[0].position.x)
        });
        let speed = env.world.robots[0].wheel_speeds[0];
        let braking_start = env.world.robots[0].position.x;
        drive(&mut env, &[0.0, 0.0], 200, |_| {});
        let stopped = env.world.robots[0].wheel_speeds;
        (
            a,
            xs,
            speed,
            env.world.robots[0].position.x - braking_start,
            stopped,
        )
    };
    let wall_side = 6.0 - 0.0704 - 0.003;
    let (a, free, v, braking, stopped) = run(0.0);
    let (_, near_wall, v_wall, braking_wall, _) = run(wall_side);
    assert!((a - 0.2034543).abs() < 1e-6, "default profile {a}");
    let (t, h) = (2.0, 0.05 / 2.0); // 40 steps of 50 ms, 2 substeps each (the default)
    assert!(
        (v - a * t).abs() < 1e-4,
        "speed {v} after {t} s, theory {}",
        a * t
    );
    let x = free[39] + 5.5;
    let theory = 0.5 * a * t * (t + h);
    assert!((x - theory).abs() < 1e-4, "{x} m in {t} s, theory {theory}");
    let theory = v * v / (2.0 * a) - 0.5 * v * h;
    assert!(
        (braking - theory).abs() < 1e-3,
        "braked in {braking} m, theory {theory}"
    );
    assert_eq!(stopped, [0.0, 0.0]);
    assert_eq!(v_wall, v);
    for (i, (f, w)) in free.iter().zip(&near_wall).enumerate() {
        assert!((f - w).abs() < 1e-4, "step {i}: arc {f} vs rapier {w}");
    }
    assert!((braking - braking_wall).abs() < 1e-4);
}

#[test]
fn test_one_step_of_full_command_from_rest_stays_under_the_profile() {
    // docs/fidelity.md gap 2: after one 50 ms step of full command, v <= a dt.
    let mut env = nav("");
    drive(&mut env, &[1.0, 1.0], 1, |_| {});
    let a = env.world.drive.wheel_accel_limit;
    let v = env.world.robots[0].wheel_speeds;
    assert!(v[0] <= a * 0.05 + 1e-6 && v[1] <= a * 0.05 + 1e-6, "{v:?}");
}

/// Two robots (multinav with two agents) placed by hand.
fn two_robots(p0: Vector, h0: f32, p1: Vector, h1: f32, overrides: &str) -> Env {
    let mut env = env_of(
        TaskKind::MultiNav,
        &format!(
            "n_robots = 2\nmax_steps = 100000\nmotors.mode = \"ramp\"\nwheel_accel_limit = inf\n\
             {overrides}"
        ),
        3,
    );
    env.world.place_robot(0, p0, h0);
    env.world.place_robot(1, p1, h1);
    env
}

#[test]
fn test_a_stopped_robot_is_not_shoved_faster_than_the_impact_leaves_it() {
    on_versions(|_| {
        // Robot 0 drives at full speed into the side of robot 1, whose wheels are held at 0. The
        // perfectly inelastic impact of equal masses leaves the pair at v / 2; after it, the
        // pusher's tyres push with at most mu m g, which is all the sideways friction of the pushed
        // robot's tyres, so the pushed robot never speeds up again: at most v / 2, never faster than
        // the step before (v0 imposed the pusher's velocity and shoved it along at v / 2 throughout).
        let mut env = two_robots(
            Vector::new(-0.3, 0.0),
            0.0,
            Vector::new(-0.3 + 0.15, 0.0),
            FRAC_PI_2,
            "",
        );
        let v = env.world.drive.max_wheel_speed;
        let dt = env.world.dt();
        let mut speeds = Vec::new();
        let mut last = env.world.robots[1].position;
        drive(&mut env, &[1.0, 1.0, 0.0, 0.0], 20, |env| {
            let p = env.world.robots[1].position;
            speeds.push((p - last).length() / dt);
            last = p;
        });
        let hit = speeds.iter().position(|s| *s > 0.0).expect("never hit");
        for (k, pair) in speeds[hit..].windows(2).enumerate() {
            assert!(
                pair[0] <= 0.5 * v + 0.01,
                "step {}: {} m/s",
                hit + k,
                pair[0]
            );
            if k > 0 {
                assert!(
                    pair[1] <= pair[0] + 1e-3,
                    "step {}: sped up {pair:?}",
                    hit + k
                );
            }
        }
    });
}

#[test]
fn test_two_robots_pushing_head_on_stall() {
    on_versions(|_| {
        // Equal robots with equal grip pushing against each other: neither gains ground.
        let mut env = two_robots(
            Vector::new(-0.2, 0.0),
            0.0,
            Vector::new(0.2, 0.0),
            std::f32::consts::PI,
            "",
        );
        drive(&mut env, &[0.6, 0.6, 0.6, 0.6], 20, |_| {});
        let (a, b) = (env.world.robots[0].position, env.world.robots[1].position);
        drive(&mut env, &[0.6, 0.6, 0.6, 0.6], 20, |_| {});
        let (a2, b2) = (env.world.robots[0].position, env.world.robots[1].position);
        assert!(
            (a2 - a).length() < 0.005 && (b2 - b).length() < 0.005,
            "{a:?}->{a2:?}, {b:?}->{b2:?}"
        );
        assert!((a2.x + b2.x).abs() < 0.005, "not symmetric: {a2:?} {b2:?}");
    });
}

#[test]
fn test_encoders_count_the_wheels_slip_while_stalled() {
    on_versions(|_| {
        // The encoders sit on the motors: against a wall the wheels keep turning (they slip), so
        // the encoders count v t while the body stands still (what the real robot reports).
        let mut env = nav("");
        env.world
            .place_robot(0, Vector::new(0.0, 1.0 - 0.0704 - 0.01), FRAC_PI_2);
        drive(&mut env, &[0.3, 0.3], 100, |_| {}); // reach the wall and the commanded speed
        let (p, travel) = (
            env.world.robots[0].position,
            env.world.robots[0].wheel_travel,
        );
        drive(&mut env, &[0.3, 0.3], 20, |_| {});
        let r = &env.world.robots[0];
        assert!(
            (r.position - p).length() < 1e-3,
            "not stalled: {p:?} -> {:?}",
            r.position
        );
        let counted = r.wheel_travel[0] - travel[0];
        let v = 0.3 * env.world.drive.max_wheel_speed;
        assert!(
            (counted as f32 - v).abs() < 1e-3,
            "encoders counted {counted} m in 1 s"
        );
    });
}

/// Drives a 1 m square (4 straight metres and 4 turns) with `localization = "odometry"` and
/// returns the estimate's position error after each side (m).
fn square_drift(seed: u64) -> Vec<f32> {
    let mut env = env_of(
        TaskKind::Nav,
        "max_steps = 100000\nlocalization = \"odometry\"\narena = { width = 3.0, height = 3.0 }",
        seed,
    );
    env.world.place_robot(0, Vector::new(-0.5, -0.5), 0.0);
    env.world.start_odometry(&env.cfg.clone());
    let mut errors = Vec::new();
    for _ in 0..4 {
        drive(&mut env, &[0.5, 0.5], 30, |_| {}); // ramps up, then cruises
        drive(&mut env, &[0.0, 0.0], 40, |_| {});
        // Turn about 90 degrees in place at 0.1 m/s per wheel (3.8 s with the ramps).
        drive(&mut env, &[-0.123, 0.123], 20, |_| {});
        drive(&mut env, &[0.0, 0.0], 20, |_| {});
        let r = &env.world.robots[0];
        errors.push((r.odometry.position - r.position).length());
    }
    errors
}

#[test]
fn test_odometry_drifts_with_distance_and_is_reproducible_per_seed() {
    let a = square_drift(11);
    assert_eq!(a, square_drift(11), "same seed, same drift");
    assert_ne!(a, square_drift(12), "another seed draws other errors");
    assert!(a[3] > 0.002, "no drift after 4 sides: {a:?}");
    assert!(
        a[3] < 0.2,
        "drift beyond the calibration errors' scale: {a:?}"
    );
    let mean_first: f32 = (11..21).map(|s| square_drift(s)[0]).sum::<f32>() / 10.0;
    let mean_last: f32 = (11..21).map(|s| square_drift(s)[3]).sum::<f32>() / 10.0;
    assert!(
        mean_last > mean_first,
        "drift does not grow: {mean_first} -> {mean_last}"
    );
}

#[test]
fn test_odometry_localization_observes_the_believed_goal() {
    // With odometry the goal's distance comes from the estimate, not the true pose.
    let mut env = env_of(
        TaskKind::Nav,
        "max_steps = 100000\nlocalization = \"odometry\"",
        5,
    );
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut obs);
    let goal = env.goals()[0];
    let distance_at = |env: &Env, believed: bool| {
        let r = &env.world.robots[0];
        let p = if believed {
            r.odometry.position
        } else {
            r.position
        };
        (goal - p).length()
    };
    assert!(
        (obs[13] - distance_at(&env, false)).abs() < 1e-5,
        "starts at the true pose"
    );
    for _ in 0..60 {
        env.step(&[0.4, 0.2], &mut obs);
    }
    assert!((obs[13] - distance_at(&env, true)).abs() < 1e-5);
    assert!((distance_at(&env, true) - distance_at(&env, false)).abs() > 1e-4);
}

#[test]
fn test_gyro_reads_the_yaw_rate_in_its_resolution_with_its_noise() {
    // LSM330DLC at 2000 dps: 0.066 deg/s per count [C]; noise sigma 0.2 deg/s [E].
    let mut env = nav("wheel_accel_limit = inf");
    let mut worst = 0.0f32;
    drive(&mut env, &[-0.3, 0.3], 40, |env| {
        let r = &env.world.robots[0];
        let g = r.readings.gyro;
        assert!((g.rate - (g.raw as f32 * 0.066).to_radians()).abs() < 1e-6);
        worst = worst.max((g.rate - r.yaw_rate).abs().to_degrees());
    });
    assert!(worst < 5.0 * 0.2 + 0.066, "gyro off by {worst} deg/s");
}

#[test]
fn test_sonar_ignores_a_wall_beyond_its_acceptance_cone() {
    // Webots' sonar: no echo when the beam meets the surface more than 22.5 deg from its normal.
    for (incidence_deg, echoes) in [(10.0f32, true), (60.0, false)] {
        let mut env = nav("us_noise_sigma = 0.0\narena = { width = 8.0, height = 2.0 }");
        // Facing the top wall (y = 1), 0.6 m below it, tilted by the incidence angle.
        env.world.place_robot(
            0,
            Vector::new(0.0, 0.4),
            FRAC_PI_2 - incidence_deg.to_radians(),
        );
        env.world.sense(true);
        let front = env.world.robots[0].readings.us.code[2];
        if echoes {
            // The ping leaves from the rim, R from the centre along the beam.
            let beam = 0.6 / incidence_deg.to_radians().cos() - 0.0704;
            let expected = (beam * 100.0).round() as i32;
            assert!(
                (front - expected).abs() <= 1,
                "{incidence_deg} deg: {front} cm"
            );
        } else {
            assert_eq!(front, 1000, "{incidence_deg} deg: echo at {front} cm");
        }
    }
}

#[test]
fn test_sonar_refreshes_every_100_ms() {
    // The five sensors take 20 ms each: 100 ms for all, i.e. new values every other 50 ms step.
    let mut env = nav("");
    let mut ages = Vec::new();
    drive(&mut env, &[0.5, 0.5], 8, |env| {
        ages.push(env.world.robots[0].readings.us.age)
    });
    let fresh: Vec<bool> = ages.iter().map(|a| *a == 0.0).collect();
    assert_eq!(
        fresh,
        [false, true, false, true, false, true, false, true],
        "{ages:?}"
    );
}

#[test]
fn test_a_dark_obstacle_reads_lower_on_ir_than_a_white_one() {
    let reading = |reflectance: f32| {
        let mut env = nav(&format!(
            "ir_noise_sigma = 0.0\nfixed = [{{kind = \"box\", center = [0.2, 0.0], \
             half_extents = [0.05, 0.2], angle = 0.0, reflectance = {reflectance}}}]"
        ));
        env.world.place_robot(0, Vector::new(0.0, 0.0), 0.0);
        env.world.sense(true);
        env.world.robots[0].readings.ir.raw[3] // the front sensor
    };
    let (white, dark) = (reading(1.0), reading(0.3));
    // 8 cm from the shell: well above the 100 counts of an empty floor (K-Team's curve).
    assert!(white > 200, "white at 8 cm reads {white}");
    assert!(dark < white, "dark {dark} vs white {white}");
}

#[test]
fn test_action_delay_shifts_the_trajectory_by_k_steps() {
    // Delay k: the wheels receive the action sent k steps earlier (zeros at first).
    let k = 2;
    let actions: Vec<[f32; 2]> = (0..30).map(|i| [0.2 + 0.02 * i as f32, 0.5]).collect();
    let mut plain = nav("");
    let mut delayed = nav(&format!("action_delay = {k}"));
    let mut obs = vec![0.0; plain.obs_dim()];
    let mut plain_poses = Vec::new();
    for i in 0..30 {
        let a = if i < k { [0.0, 0.0] } else { actions[i - k] };
        plain.step(&a, &mut obs);
        plain_poses.push((
            plain.world.robots[0].position,
            plain.world.robots[0].heading,
        ));
    }
    for (i, a) in actions.iter().enumerate() {
        delayed.step(a, &mut obs);
        let r = &delayed.world.robots[0];
        assert_eq!((r.position, r.heading), plain_poses[i], "step {i}");
    }
}

#[test]
fn test_observation_delay_shows_the_world_k_steps_late() {
    let k = 3;
    let mut plain = nav("");
    let mut delayed = nav(&format!("observation_delay = {k}"));
    let mut first = vec![0.0; plain.obs_dim()];
    plain.reset(&mut first);
    let mut first_delayed = vec![0.0; plain.obs_dim()];
    delayed.reset(&mut first_delayed);
    assert_eq!(first, first_delayed);
    let mut history = vec![first.clone()];
    let (mut a, mut b) = (vec![0.0; plain.obs_dim()], vec![0.0; plain.obs_dim()]);
    for i in 0..20 {
        plain.step(&[0.3, 0.6], &mut a);
        delayed.step(&[0.3, 0.6], &mut b);
        history.push(a.clone());
        let shown = if i + 1 >= k {
            &history[i + 1 - k]
        } else {
            &first
        };
        assert_eq!(&b, shown, "step {i}");
    }
}

#[test]
fn test_delays_and_odometry_save_and_restore_bit_for_bit() {
    let overrides = "action_delay = 2\nobservation_delay = 1\nlocalization = \"odometry\"";
    let mut env = nav(overrides);
    let mut obs = vec![0.0; env.obs_dim()];
    let actions: Vec<[f32; 2]> = (0..40).map(|i| [0.5, 0.1 * (i % 7) as f32]).collect();
    for a in &actions[..20] {
        env.step(a, &mut obs);
    }
    let mut state = Vec::new();
    env.save_state(&mut state).expect("save");
    let replay = |env: &mut Env| {
        let mut out = Vec::new();
        let mut o = vec![0.0; env.obs_dim()];
        for a in &actions[20..] {
            env.step(a, &mut o);
            let r = &env.world.robots[0];
            out.push((o.clone(), r.position, r.odometry.position));
        }
        out
    };
    let first = replay(&mut env);
    let mut restored = nav(overrides);
    restored.load_state(&state).expect("load");
    assert_eq!(replay(&mut restored), first);
}

#[test]
fn test_delays_beyond_the_limit_are_config_errors() {
    let source = common::source("observation_delay = 1000000");
    let e = load_scenario("nav", &source).unwrap_err().to_string();
    assert!(
        e.contains("task.observation_delay: must be >= 0, <= 100, got 1000000"),
        "{e}"
    );
}
