//! DroneFollow specification (issue 16): the drone's thrust never exceeds its tilt limit, its
//! autopilot holds and changes altitude as a first-order system, the PD pursuit keeps the
//! scripted Khepera in view on its routes, and bad keys are config errors naming them.
//! Thresholds come from the model's equations and the PD's linear theory.
//!
//! Units: metres, seconds, radians; world frame. Observation: camera_offset 0-1, seen 2,
//! relative_velocity 3-4, drone_velocity 5-6, altitude 7.

use crate::common;

use _core::controllers::Policy;
use _core::error::Error;
use _core::scenario::{Scenario, Source};
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use rand::{Rng, SeedableRng};

const DT: f32 = 0.05;
const G: f32 = 9.80665;

fn scenario(overrides: &str) -> Scenario {
    common::scenario("dronefollow", overrides)
}

fn env(overrides: &str, seed: u64) -> (Env, Vec<f32>) {
    common::env(TaskKind::DroneFollow, scenario(overrides), seed)
}

fn pursuit(cfg: &Scenario) -> Policy {
    let layout = TaskKind::DroneFollow
        .agents(cfg)
        .expect("agents")
        .remove(0)
        .layout;
    Policy::new("drone_pursuit", &Default::default(), &layout).expect("policy")
}

#[test]
fn test_the_thrust_never_exceeds_the_tilt_limit() {
    // Between two steps with the command held, v1 = T/c + (v0 − T/c)·e^(−c·dt): the thrust T
    // the velocities imply must stay within a_max = g·tan(15°) = 2.63 m/s², however large the
    // command (it is clamped to length 1).
    let (mut env, mut obs) = env("", 1);
    let a_max = G * 0.2618f32.tan();
    let c = a_max / 1.0;
    let decay = (-c * DT).exp();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    let mut largest = 0.0f32;
    for _ in 0..200 {
        let v0 = [obs[5], obs[6]];
        let action = [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
        env.step(&action, &mut obs);
        env.done = false;
        let thrust: Vec<f32> = (0..2)
            .map(|k| c * (obs[5 + k] - v0[k] * decay) / (1.0 - decay))
            .collect();
        largest = largest.max(thrust[0].hypot(thrust[1]));
    }
    assert!(largest <= a_max * 1.001, "thrust {largest} > {a_max}");
    assert!(
        largest > 0.9 * a_max,
        "the test never asked for much: {largest}"
    );
}

#[test]
fn test_the_altitude_follows_its_reference_as_a_first_order_system() {
    // A drone that does not move loses the robot; its reference becomes the search height
    // once the robot has been out of view for search_delay, and back when it is seen again
    // (the footprint widens as it climbs, so it may find the robot before reaching 1.5 m).
    // Each step z → z_ref + (z − z_ref)·e^(−dt/τ), τ = 0.3 s, z_ref set by the last frame.
    let (mut env, mut obs) = env("lost_time = 100.0\nmax_steps = 400", 3);
    assert_eq!(obs[7], 0.5);
    let (track, search, delay, tau) = (0.5f32, 1.5f32, 0.5f32, 0.3f32);
    let mut unseen_for = if obs[2] > 0.5 { 0.0 } else { DT };
    let mut climbed = false;
    for _ in 0..300 {
        let reference = if unseen_for >= delay - 1e-4 {
            search
        } else {
            track
        };
        let z = obs[7];
        env.step(&[0.0, 0.0], &mut obs);
        let expected = reference + (z - reference) * (-DT / tau).exp();
        assert!((obs[7] - expected).abs() < 1e-5, "{} vs {expected}", obs[7]);
        unseen_for = if obs[2] > 0.5 { 0.0 } else { unseen_for + DT };
        climbed |= obs[7] > 0.8;
    }
    assert!(
        climbed,
        "the robot never left the view long enough to climb"
    );
}

#[test]
fn test_pd_pursuit_keeps_the_robot_in_view_on_its_routes() {
    // The robot drives at 0.15 m/s and turns at up to 1 rad/s: it accelerates by at most
    // about 0.15 m/s² (Braitenberg swerves aside), so the critically damped PD (ω_n = 2 rad/s)
    // lags by a_robot / k_p ≈ 4 cm at most, far inside the 0.29 m footprint at 0.5 m. Over 10
    // routes of 40 s the robot is never out of view and the RMS horizontal error stays under
    // 5 cm (the 0.1 m start offset decays within about 2 s).
    let cfg = scenario("");
    let policy = pursuit(&cfg);
    for seed in 0..10 {
        let (mut env, mut obs) = env("", 100 + seed);
        let mut action = [0.0f32; 2];
        loop {
            let act = policy.act_batch(&obs, obs.len()).expect("act");
            action.copy_from_slice(&act);
            let outcome = env.step(&action, &mut obs);
            assert!(obs[2] > 0.5, "seed {seed}: the robot left the view");
            if outcome.terminated || outcome.truncated {
                break;
            }
        }
        let stats = env.extra_stats(&env.last_episode);
        let value = |name: &str| {
            stats
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, v)| *v)
                .expect("statistic")
        };
        assert_eq!(env.last_episode.length, 800, "seed {seed}");
        assert_eq!(value("in_view_share"), 1.0);
        assert!(
            value("horizontal_error_rms") < 0.05,
            "seed {seed}: {stats:?}"
        );
        assert!(
            value("altitude_error_rms") < 1e-6,
            "seed {seed}: it never climbed"
        );
    }
}

#[test]
fn test_bad_keys_are_config_errors_naming_them() {
    for (overrides, key) in [
        ("tilt_max = 2.0", "drone.tilt_max"),
        ("fov = 0.0", "drone.fov"),
        ("speed_max = -1.0", "drone.speed_max"),
        ("search_altitude = 0.2", "drone.search_altitude"),
        ("start_offset = 1.0", "drone.start_offset"),
        ("route_points = 1", "drone.route_points"),
    ] {
        let source = Source {
            file: None,
            overrides: overrides.parse().expect("overrides"),
            version: None,
        };
        match load_scenario("dronefollow", &source) {
            Err(Error::Config { key: got, .. }) => assert_eq!(got, key, "{overrides}"),
            other => panic!("{overrides}: expected a config error, got {other:?}"),
        }
    }
}
