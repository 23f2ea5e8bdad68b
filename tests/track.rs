//! The tracking task (KheperaIV-Track): references stay inside the arena and within the robot's
//! limits, bad references are configuration errors naming the key, Kanayama's controller
//! converges as its linearised closed loop says, position control chasing the reference lags by
//! v_r over its bandwidth, and the task is deterministic and restorable like the others.

mod common;

use _core::batch::Batch;
use _core::controllers::Policy;
use _core::robot::ActionType;
use _core::scenario::{Scenario, Source};
use _core::tasks::{load_scenario, TaskKind};

fn scenario(overrides: &str) -> Scenario {
    common::scenario("track", overrides)
}

fn policy(name: &str, cfg: &Scenario) -> Policy {
    let layout = TaskKind::Track
        .agents(cfg)
        .expect("agents")
        .remove(0)
        .layout;
    Policy::new(name, &Default::default(), &layout).expect("policy")
}

/// One episode per world (seeds `seed + i`) under `policy`: each world's position error after
/// every step (m) and its episode statistics (extra: rms, max, iae, converge time).
struct Run {
    errors: Vec<Vec<f32>>,
    extra: Vec<[f32; 4]>,
    terminated: Vec<bool>,
}

fn run(cfg: &Scenario, policy: &Policy, n: usize, seed: u64) -> Run {
    let mut batch = Batch::new(
        TaskKind::Track,
        cfg.clone(),
        n,
        ActionType::Wheels,
        Some(2),
        true,
    )
    .expect("batch");
    batch.reset(Some(seed));
    let mut errors = vec![Vec::new(); n];
    let mut extra = vec![None; n];
    let mut terminated = vec![false; n];
    while extra.iter().any(Option::is_none) {
        let actions = policy
            .act_batch(batch.obs(), batch.obs_dim())
            .expect("actions");
        batch.step(&actions).expect("step");
        let outcomes = batch.outcomes().to_vec();
        for (i, env) in batch.envs().iter().enumerate() {
            if extra[i].is_some() {
                continue;
            }
            let o = outcomes[i];
            if o.terminated || o.truncated {
                extra[i] = Some(env.last_episode.extra);
                terminated[i] = o.terminated;
            } else {
                let goal = env.goals()[0];
                errors[i].push((goal - env.world.robots[0].position).length());
            }
        }
    }
    Run {
        errors,
        extra: extra.into_iter().flatten().collect(),
        terminated,
    }
}

/// Largest and smallest reference speed over a lap (m/s), from the observed feed-forward.
fn speed_range(cfg: &Scenario) -> (f32, f32) {
    let mut batch = Batch::new(
        TaskKind::Track,
        cfg.clone(),
        1,
        ActionType::Wheels,
        Some(1),
        true,
    )
    .expect("batch");
    let layout = TaskKind::Track
        .agents(cfg)
        .expect("agents")
        .remove(0)
        .layout;
    let rates = layout.find("reference_rates").expect("rates").start;
    batch.reset(Some(0));
    let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
    for _ in 0..batch.envs()[0].cfg.task.max_steps {
        let v = batch.obs()[rates] * cfg.robot.max_wheel_speed.bounds().0;
        lo = lo.min(v);
        hi = hi.max(v);
        batch.step(&[0.0, 0.0]).expect("step");
        if batch.outcomes()[0].truncated || batch.outcomes()[0].terminated {
            break;
        }
    }
    (lo, hi)
}

/// Kanayama's law linearised about zero error: the along-track error decays at rate K_x, the
/// cross-track loop s² + v_r K_θ s + v_r² K_y is critically damped with ω_n = v_r √K_y. With
/// the slowest rate λ = min(K_x, v_r,min √K_y), an error starting at E0 stays within
/// E0 (1 + λt) e^{−λt}; E0 sums the start offset, the heading offset's drift v_r sin(e_θ)/λ
/// and the lag of a standing start under the motor's acceleration limit, v_r²/(2a). A sampled
/// controller adds at most the reference's travel in one step, v_r,max·dt.
fn kanayama_envelope(cfg: &Scenario, t: f32) -> f32 {
    let (kx, ky) = (1.0f32, 44.44f32); // KanayamaParams defaults
    let (v_min, v_max) = speed_range(&{
        let mut c = cfg.clone();
        c.task.max_steps = 4000;
        c
    });
    let lambda = kx.min(v_min * ky.sqrt());
    // track.start_offset (m) and start_heading_offset (45 degrees)
    let (offset, heading) = (0.2f32, std::f32::consts::FRAC_PI_4);
    let accel = cfg.motors.accel(&cfg.robot).bounds().0;
    let e0 = offset + v_max * heading.sin() / lambda + v_max * v_max / (2.0 * accel);
    e0 * (1.0 + lambda * t) * (-lambda * t).exp() + v_max * cfg.physics.dt
}

/// A scenario file's own reference: 8 points on a 0.5 m circle, 2.5 s apart (about 0.16 m/s).
fn waypoints_file() -> String {
    let points: Vec<String> = (0..=8)
        .map(|k| {
            let a = std::f32::consts::TAU * k as f32 / 8.0;
            format!("[{}, {}, {}]", 2.5 * k as f32, 0.5 * a.cos(), 0.5 * a.sin())
        })
        .collect();
    format!(
        "[track]\nreference = \"waypoints\"\nwaypoints = [{}]\n",
        points.join(", ")
    )
}

fn scenario_file(text: &str) -> Scenario {
    let source = Source {
        file: Some((text, "waypoints.toml")),
        ..Default::default()
    };
    load_scenario("track", &source).expect("scenario")
}

#[test]
fn test_kanayama_converges_on_circle_lemniscate_and_waypoints_within_the_linear_envelope() {
    for reference in ["circle", "lemniscate", "waypoints"] {
        let cfg = if reference == "waypoints" {
            scenario_file(&waypoints_file())
        } else {
            scenario(&format!("reference = \"{reference}\""))
        };
        let transient = 5.0; // track.transient
        let bound = kanayama_envelope(&cfg, transient);
        let r = run(&cfg, &policy("kanayama", &cfg), 100, 100);
        assert!(r.terminated.iter().all(|t| !t), "{reference}: lost");
        let rms: Vec<f32> = r.extra.iter().map(|e| e[0]).collect();
        let max: Vec<f32> = r.extra.iter().map(|e| e[1]).collect();
        let converge: Vec<f32> = r.extra.iter().map(|e| e[3]).collect();
        let worst = max.iter().cloned().fold(0.0, f32::max);
        println!(
            "{reference}: kanayama RMS after {transient} s mean {:.4} m, worst {:.4} m; max error worst {worst:.4} m \
             (bound {bound:.4}); converged below 2 cm after {:.2} s on average, {:.2} s at worst",
            rms.iter().sum::<f32>() / rms.len() as f32,
            rms.iter().cloned().fold(0.0, f32::max),
            converge.iter().sum::<f32>() / converge.len() as f32,
            converge.iter().cloned().fold(0.0, f32::max),
        );
        assert!(
            worst <= bound,
            "{reference}: max error {worst} beyond {bound}"
        );
        // The envelope falls below the 2 cm radius at t_c; every episode converges by then.
        let t_c = (0..2000)
            .map(|k| k as f32 * 0.05)
            .find(|t| kanayama_envelope(&cfg, *t) < 0.02)
            .expect("the envelope decays");
        for (i, c) in converge.iter().enumerate() {
            assert!(
                c.is_finite() && *c <= t_c,
                "{reference} world {i}: converged at {c} > {t_c}"
            );
        }
    }
}

#[test]
fn test_position_chase_lags_the_circle_by_speed_over_bandwidth() {
    // Started on the reference at rest; eq. 3 inside k_r gives v = d v_max / k_r, so holding
    // v_r needs d = v_r k_r / v_max (PositionParams defaults: k_r = 0.15 m, v_max = 0.3 m/s).
    let cfg = scenario("start_offset = 0.0\nstart_heading_offset = 0.0");
    let r = run(&cfg, &policy("position_chase", &cfg), 20, 5);
    let expected = 0.15 * 0.15 / 0.3;
    for (i, errors) in r.errors.iter().enumerate() {
        let tail = &errors[errors.len() / 2..];
        let lag = tail.iter().sum::<f32>() / tail.len() as f32;
        if i == 0 {
            println!("position_chase steady lag on the circle {lag:.4} m (v_r k_r / v_max = {expected:.4} m)");
        }
        assert!(
            lag > expected / 1.25 && lag < expected * 1.25,
            "world {i}: lag {lag} vs {expected}"
        );
    }
}

#[test]
fn test_references_stay_in_the_arena_and_within_the_wheels_limits() {
    // Every shape and 1,000 seeds of splines: the observed feed-forward, turned into wheel
    // speeds, stays within track.max_wheel_fraction of the wheels' limit, its change within
    // max_accel_fraction of the acceleration limit, and the reference point within the arena.
    for (reference, n) in [
        ("circle", 20),
        ("lemniscate", 20),
        ("square", 20),
        ("spline", 1000),
    ] {
        // Standing still, the robot must not end the lap as lost.
        let cfg = scenario(&format!(
            "reference = \"{reference}\"\nlost_distance = 10.0"
        ));
        let layout = TaskKind::Track
            .agents(&cfg)
            .expect("agents")
            .remove(0)
            .layout;
        let rates = layout.find("reference_rates").expect("rates").start;
        let od = layout.len();
        let vmax = cfg.robot.max_wheel_speed.bounds().0;
        let wmax = 2.0 * vmax / cfg.robot.axle_length.bounds().0;
        let half_axle = 0.5 * cfg.robot.axle_length.bounds().0;
        let amax = cfg.motors.accel(&cfg.robot).bounds().0;
        let dt = cfg.physics.dt;
        let mut batch = Batch::new(
            TaskKind::Track,
            cfg.clone(),
            n,
            ActionType::Wheels,
            Some(2),
            true,
        )
        .expect("batch");
        batch.reset(Some(1));
        let mut finished = vec![false; n];
        let mut previous: Vec<Option<[f32; 2]>> = vec![None; n];
        let (mut peak_speed, mut peak_accel) = (0.0f32, 0.0f32);
        let zeros = vec![0.0; 2 * n];
        for _ in 0..cfg.task.max_steps {
            for (i, env) in batch.envs().iter().enumerate() {
                if finished[i] {
                    continue;
                }
                let p = env.goals()[0];
                assert!(
                    p.x.abs() <= 0.6 + 1e-4 && p.y.abs() <= 0.6 + 1e-4,
                    "{reference} {i}: {p:?}"
                );
                let obs = &batch.obs()[i * od..(i + 1) * od];
                let (v, w) = (obs[rates] * vmax, obs[rates + 1] * wmax);
                let wheels = [v - w * half_axle, v + w * half_axle];
                peak_speed = peak_speed.max(wheels[0].abs().max(wheels[1].abs()));
                if let Some(before) = previous[i] {
                    let a = (wheels[0] - before[0])
                        .abs()
                        .max((wheels[1] - before[1]).abs())
                        / dt;
                    peak_accel = peak_accel.max(a);
                }
                previous[i] = Some(wheels);
            }
            batch.step(&zeros).expect("step");
            for (f, o) in finished.iter_mut().zip(batch.outcomes()) {
                *f |= o.terminated || o.truncated;
            }
            if finished.iter().all(|f| *f) {
                break;
            }
        }
        println!("{reference}: peak reference wheel speed {peak_speed:.3} m/s, accel {peak_accel:.4} m/s^2");
        assert!(
            peak_speed <= 0.5 * vmax + 1e-4,
            "{reference}: wheel speed {peak_speed}"
        );
        if reference != "square" {
            // Sampled at dt instead of T/720: allow the difference between the two samplings.
            assert!(
                peak_accel <= 0.5 * amax * 1.05,
                "{reference}: wheel accel {peak_accel}"
            );
        }
    }
}

fn config_error(overrides: &str) -> String {
    common::config_error("track", overrides).0
}

#[test]
fn test_bad_references_are_config_errors_naming_the_key() {
    assert_eq!(config_error("size = 0.9"), "track.size"); // outside the arena
    assert_eq!(config_error("speed = 0.6"), "track.speed"); // faster than the wheels allow
    assert_eq!(config_error("size = 0.05\nspeed = 0.2"), "track.speed"); // too sharp a turn
    assert_eq!(config_error("speed = -0.1"), "track.speed");
    assert_eq!(config_error("speed = nan"), "track.speed");
    assert_eq!(config_error("reference = \"heart\""), "track.reference");
    assert_eq!(config_error("preview_points = 17"), "track.preview_points");
    assert_eq!(config_error("preview_step = 0.0"), "track.preview_step");
    assert_eq!(config_error("lost_distance = inf"), "track.lost_distance");
    assert_eq!(
        config_error("spline_irregularity = 0.9"),
        "track.spline_irregularity"
    );
    assert_eq!(
        config_error("start_heading_offset = 4.0"),
        "track.start_heading_offset"
    );
    assert_eq!(config_error("direction = \"up\""), "track.direction");
    let waypoints =
        |points: &str| config_error(&format!("reference = \"waypoints\"\nwaypoints = {points}"));
    let square = "[0, 0.3, 0], [5, 0, 0.3], [10, -0.3, 0], [15, 0, -0.3]";
    assert_eq!(waypoints(&format!("[{square}]")), "track.waypoints"); // not closed
    assert_eq!(
        waypoints("[[0, 0.3, 0], [5, 0, 0.3], [0, 0.3, 0]]"),
        "track.waypoints"
    ); // too few
    let backwards = "[[0, 0.3, 0], [5, 0, 0.3], [4, -0.3, 0], [15, 0, -0.3], [20, 0.3, 0]]";
    assert_eq!(waypoints(backwards), "track.waypoints"); // non-increasing times
    let outside = "[[0, 0.9, 0], [5, 0, 0.9], [10, -0.9, 0], [15, 0, -0.9], [20, 0.9, 0]]";
    assert_eq!(waypoints(outside), "track.waypoints");
    let fast = "[[0, 0.3, 0], [0.5, 0, 0.3], [1, -0.3, 0], [1.5, 0, -0.3], [2, 0.3, 0]]";
    assert_eq!(waypoints(fast), "track.waypoints"); // too fast for the wheels
    assert_eq!(
        waypoints("[[0, 0.3, 0], [5, 0, 0.3], [10, -0.3, 0], [15, 0, -0.3], [20, 0.3, nan]]"),
        "track.waypoints[4][2]"
    );
    // Waypoints with another reference would be silently ignored: refused.
    assert_eq!(
        config_error(&format!("waypoints = [{square}, [20, 0.3, 0]]")),
        "track.waypoints"
    );
    let good = format!("reference = \"waypoints\"\nwaypoints = [{square}, [20, 0.3, 0]]");
    assert!(load_scenario(
        "track",
        &Source {
            file: None,
            overrides: good.parse().unwrap(),
            ..Default::default()
        }
    )
    .is_ok());
}

#[test]
fn test_track_has_no_version_zero() {
    // The task was added with the v1 dynamics: v0 (the paper's older ones) has no Track.
    let source = Source {
        version: Some(0),
        ..Default::default()
    };
    match load_scenario("track", &source) {
        Err(_core::error::Error::Config { key, .. }) => assert_eq!(key, "version"),
        other => panic!("expected a config error, got {other:?}"),
    }
    let latest = Source {
        version: Some(1),
        ..Default::default()
    };
    assert!(load_scenario("track", &latest).is_ok());
}

#[test]
fn test_episode_is_one_period_plus_the_margin_and_lost_terminates() {
    // Circle: 2π·0.6 m at 0.15 m/s = 25.13 s, + 2 s = 542.7 → 543 steps (docs/task-design.md §3).
    let cfg = scenario("");
    let mut batch = Batch::new(
        TaskKind::Track,
        cfg.clone(),
        1,
        ActionType::Wheels,
        Some(1),
        false,
    )
    .expect("batch");
    batch.reset(Some(3));
    let mut steps = 0;
    loop {
        batch.step(&[0.0, 0.0]).expect("step");
        steps += 1;
        let o = batch.outcomes()[0];
        if o.terminated || o.truncated {
            // Standing still, the reference runs away: lost before the end, not a success.
            assert!(o.terminated && !batch.envs()[0].last_episode.success);
            break;
        }
    }
    // Lost once the reference is 0.5 m away: at most (0.5 + 0.2) / 0.15 s of standing still.
    assert!(steps as f32 * 0.05 <= 0.7 / 0.15 + 0.05, "{steps}");
    let policy = policy("kanayama", &cfg);
    batch.reset(Some(3));
    let mut steps = 0;
    loop {
        let a = policy.act_batch(batch.obs(), batch.obs_dim()).expect("act");
        batch.step(&a).expect("step");
        steps += 1;
        let o = batch.outcomes()[0];
        if o.terminated || o.truncated {
            assert!(o.truncated && !o.terminated);
            break;
        }
    }
    assert_eq!(steps, 543);
}
