//! The path-following task (KheperaIV-PathFollow): paths stay inside the arena and within the
//! wheels at the desired speed, bad paths are configuration errors naming the key, the three
//! path followers complete a lap without leaving the path and settle as their laws say, progress
//! and the cross-track sign are what the geometry says, obstacles on the path are met, and the
//! task is deterministic like the others.

use crate::common;

use _core::batch::Batch;
use _core::controllers::Policy;
use _core::robot::ActionType;
use _core::scenario::Scenario;
use _core::tasks::TaskKind;

fn scenario(overrides: &str) -> Scenario {
    common::scenario("pathfollow", overrides)
}

fn config_error(overrides: &str) -> (String, String) {
    common::config_error("pathfollow", overrides)
}

fn layout(cfg: &Scenario) -> _core::obs::ObsLayout {
    TaskKind::PathFollow
        .agents(cfg)
        .expect("agents")
        .remove(0)
        .layout
}

fn policy(name: &str, cfg: &Scenario) -> Policy {
    Policy::new(name, &Default::default(), &layout(cfg)).expect("policy")
}

/// One episode per world (seeds `seed + i`) under `policy`.
struct Run {
    /// |d| after every step (m), from the observation (ground-truth localisation).
    errors: Vec<Vec<f32>>,
    /// Episode statistics: extra (rms, max, iae, converge time), success, length, collisions.
    extra: Vec<[f32; 4]>,
    success: Vec<bool>,
    length: Vec<u32>,
    collisions: Vec<u32>,
}

fn run(cfg: &Scenario, policy: &Policy, n: usize, seed: u64) -> Run {
    let mut batch = Batch::new(
        TaskKind::PathFollow,
        cfg.clone(),
        n,
        ActionType::Wheels,
        Some(2),
        true,
    )
    .expect("batch");
    let d = layout(cfg).find("cross_track_error").expect("d").start;
    let od = batch.obs_dim();
    batch.reset(Some(seed));
    let mut errors = vec![Vec::new(); n];
    let mut stats = vec![None; n];
    while stats.iter().any(Option::is_none) {
        let actions = policy.act_batch(batch.obs(), od).expect("actions");
        batch.step(&actions).expect("step");
        let outcomes = batch.outcomes().to_vec();
        for (i, env) in batch.envs().iter().enumerate() {
            if stats[i].is_some() {
                continue;
            }
            let o = outcomes[i];
            if o.terminated || o.truncated {
                stats[i] = Some(env.last_episode);
            } else {
                errors[i].push(batch.obs()[i * od + d].abs());
            }
        }
    }
    let stats: Vec<_> = stats.into_iter().flatten().collect();
    Run {
        errors,
        extra: stats.iter().map(|s| s.extra).collect(),
        success: stats.iter().map(|s| s.success).collect(),
        length: stats.iter().map(|s| s.length).collect(),
        collisions: stats.iter().map(|s| s.collisions).collect(),
    }
}

/// Samson's law, kinematic model: V = d² + θ̃²/k_d never grows (its derivative is
/// −2 k_θ |v| θ̃² / k_d), so |d| ≤ √V(0) from the worst start (d0 = start_offset, θ̃0 =
/// start_heading_offset); linearised (ω_n = 1 rad/s, ζ = 0.7 at 0.15 m/s) it decays as
/// e^{−ζ ω_n t}, from when the robot has reached its speed (v_d / a after the start at rest).
fn samson_bounds(cfg: &Scenario) -> (f32, f32) {
    let (kd, zeta, wn) = (44.44f32, 0.7f32, 1.0f32); // SamsonParams defaults and their design
    let v = 0.15f32;
    let a = cfg.wheel_accel().bounds().0;
    let v0 = (0.1f32.powi(2) + std::f32::consts::FRAC_PI_4.powi(2) / kd).sqrt();
    (v0, v0 * (-zeta * wn * (5.0 - v / a)).exp())
}

#[test]
fn test_every_follower_completes_a_lap_on_every_path_without_leaving_it() {
    for path in ["circle", "lemniscate", "square", "spline"] {
        let cfg = scenario(&format!("path = \"{path}\""));
        for name in ["samson", "pure_pursuit", "waypoint_switching"] {
            let r = run(&cfg, &policy(name, &cfg), 16, 1);
            for i in 0..16 {
                assert!(r.success[i], "{path} {name} {i}: no lap");
                assert_eq!(r.collisions[i], 0, "{path} {name} {i}");
                let worst = r.errors[i].iter().copied().fold(0.0, f32::max);
                assert!(worst < 0.3, "{path} {name} {i}: {worst}");
            }
        }
    }
}

#[test]
fn test_samson_stays_within_its_lyapunov_bound_and_settles_on_smooth_paths() {
    // On v1's drive: its settling bound starts the linearised decay once the robot has reached
    // its speed (v_d / a = 0.74 s at 0.203 m/s²). On v2's 2.71 m/s² that start is at 0.06 s and
    // the nonlinear turn out of the 45° start error, which the linearisation leaves out, takes
    // longer: the lemniscate settled 3 % above the bound. The Lyapunov bound holds on v2 too.
    for path in ["circle", "lemniscate", "spline"] {
        let v2 = scenario(&format!("path = \"{path}\""));
        let (bound, _) = samson_bounds(&v2);
        let r = run(&v2, &policy("samson", &v2), 16, 3);
        for i in 0..16 {
            let worst = r.errors[i].iter().copied().fold(0.0, f32::max);
            assert!(worst <= bound, "v2 {path} {i}: |d| {worst} > {bound}");
            assert!(
                r.extra[i][3].is_finite(),
                "v2 {path} {i}: never converged below 2 cm"
            );
        }
        let cfg = common::scenario_in("pathfollow", &format!("path = \"{path}\""), 1);
        let (bound, settled) = samson_bounds(&cfg);
        let r = run(&cfg, &policy("samson", &cfg), 16, 3);
        for i in 0..16 {
            let worst = r.errors[i].iter().copied().fold(0.0, f32::max);
            assert!(worst <= bound, "{path} {i}: |d| {worst} > {bound}");
            // path_error_max: after the 5 s transient.
            assert!(
                r.extra[i][1] <= settled,
                "{path} {i}: {} > {settled}",
                r.extra[i][1]
            );
            assert!(
                r.extra[i][3].is_finite(),
                "{path} {i}: never converged below 2 cm"
            );
        }
    }
}

#[test]
fn test_samson_overshoots_square_corners_the_limit_of_smooth_controllers() {
    // κ = 0 on the legs: at a corner the law learns of the turn only from the error, with
    // θ̃ = π/2 and |d| < 0.3 m (not lost) it turns at ω ≤ k_θ v π/2 + k_d v 0.3, and while
    // θ̃ falls from π/2 to 0 the robot moves beyond the new leg by ∫ v sin θ̃ dt ≥ v / ω_max.
    let (kd, ktheta, v) = (44.44f32, 9.33f32, 0.15f32);
    let overshoot = v / (ktheta * v * std::f32::consts::FRAC_PI_2 + kd * v * 0.3);
    let cfg = scenario("path = \"square\"");
    let r = run(&cfg, &policy("samson", &cfg), 16, 5);
    for i in 0..16 {
        assert!(
            r.extra[i][1] >= overshoot,
            "{i}: {} < {overshoot}",
            r.extra[i][1]
        );
    }
    // On the circle, with its curvature fed forward, it settles far below that.
    let circle = scenario("path = \"circle\"");
    let r = run(&circle, &policy("samson", &circle), 16, 5);
    assert!(r.extra.iter().all(|e| e[1] < overshoot));
}

#[test]
fn test_waypoint_switching_cuts_inside_the_chords_of_its_waypoints() {
    // On the circle (R = 0.6 m) the robot heads for a waypoint from where it switched, at most
    // waypoint_spacing + waypoint_radius = 0.3 m before it: settled, it stays within that chord's
    // sagitta, c²/(8R) = 1.9 cm, of the path.
    // On v1's drive, whose slow profile smooths the turn at each switch; on v2 the robot turns
    // sharper and swings up to 10 % past the sagitta (the lap test covers v2).
    let cfg = common::scenario_in("pathfollow", "path = \"circle\"", 1);
    let sagitta = (0.2f32 + 0.1).powi(2) / (8.0 * 0.6);
    let r = run(&cfg, &policy("waypoint_switching", &cfg), 16, 7);
    for i in 0..16 {
        assert!(
            r.extra[i][1] <= sagitta,
            "{i}: {} > {sagitta}",
            r.extra[i][1]
        );
    }
    // It slows toward every waypoint (eq. 3 inside k_r): its laps take longer than Samson's.
    let samson = run(&cfg, &policy("samson", &cfg), 16, 7);
    for i in 0..16 {
        assert!(r.length[i] > samson.length[i], "{i}");
    }
}

#[test]
fn test_lap_time_and_return_follow_from_progress() {
    // Samson on the circle drives at v_d: a lap of L = 2π·0.6 m takes L/v_d plus the start at
    // rest, v_d/(2a); starting up to 0.1 m and 45° off the path changes the closest point's
    // progress rate v cos θ̃ / (1 − κd) by at most ~20% for the first ~2 s (≤ 4% of the lap).
    // Without the speed term (tested below), the return is the progress and error terms'.
    let cfg = scenario("path = \"circle\"\nspeed_weight = 0.0");
    let (dt, a) = (cfg.physics.dt, cfg.wheel_accel().bounds().0);
    let length = std::f32::consts::TAU * 0.6;
    let expected = length / 0.15 + 0.15 / (2.0 * a);
    let r = run(&cfg, &policy("samson", &cfg), 16, 9);
    let mut batch = Batch::new(
        TaskKind::PathFollow,
        cfg.clone(),
        1,
        ActionType::Wheels,
        Some(1),
        true,
    )
    .expect("batch");
    batch.reset(Some(9));
    let samson = policy("samson", &cfg);
    let mut ret = 0.0f64;
    loop {
        let action = samson.act_batch(batch.obs(), batch.obs_dim()).expect("act");
        batch.step(&action).expect("step");
        let o = batch.outcomes()[0];
        ret += o.reward as f64;
        if o.terminated || o.truncated {
            break;
        }
    }
    for i in 0..16 {
        let lap = r.length[i] as f32 * dt;
        assert!(
            (lap - expected).abs() <= 0.05 * expected,
            "{i}: {lap} vs {expected}"
        );
    }
    // Return = 10·progress − Σ|d| − 0.01 per step, progress between L and L + one step's
    // travel (≤ 0.813 m/s · dt); Σ|d| = IAE / dt.
    let (n, iae) = (r.length[0] as f64, r.extra[0][2] as f64);
    let base = -iae / dt as f64 - 0.01 * n;
    let lo = 10.0 * length as f64 + base;
    let hi = 10.0 * (length as f64 + 0.813 * dt as f64) + base;
    assert!(
        ret >= lo - 1e-3 && ret <= hi + 1e-3,
        "{ret} not in [{lo}, {hi}]"
    );
}

#[test]
fn test_cross_track_error_is_signed_left_of_the_direction_of_travel() {
    // On the circle of radius R, the inside is left of a counter-clockwise path: d = R − r;
    // clockwise, d = r − R.
    for (direction, sign) in [("ccw", 1.0f32), ("cw", -1.0)] {
        let cfg = scenario(&format!("direction = \"{direction}\""));
        let d = layout(&cfg).find("cross_track_error").expect("d").start;
        let mut batch = Batch::new(
            TaskKind::PathFollow,
            cfg.clone(),
            20,
            ActionType::Wheels,
            Some(2),
            true,
        )
        .expect("batch");
        batch.reset(Some(11));
        let od = batch.obs_dim();
        for (i, env) in batch.envs().iter().enumerate() {
            let r = env.world.robots[0].position.length();
            let observed = batch.obs()[i * od + d];
            assert!(
                (observed - sign * (0.6 - r)).abs() < 1e-5,
                "{direction} {i}"
            );
            assert!(observed.abs() <= 0.1 + 1e-6, "start offset {observed}");
        }
    }
}

#[test]
fn test_splines_stay_in_the_arena_and_within_the_wheels_at_the_desired_speed() {
    // 1,000 seeds: every point of the drawn path within `size` of the centre, and the
    // curvature the robot meets along a lap (observed while Samson follows it) asks the wheels
    // for at most max_wheel_fraction of their speed at v_d: v_d (1 + |κ| axle / 2).
    let n = 1000;
    let cfg = scenario("path = \"spline\"");
    let kappa = layout(&cfg).find("curvature").expect("curvature").start;
    let vmax = cfg.robot.max_wheel_speed.bounds().0;
    let half_axle = 0.5 * cfg.robot.axle_length.bounds().1;
    let samson = policy("samson", &cfg);
    let mut batch = Batch::new(
        TaskKind::PathFollow,
        cfg.clone(),
        n,
        ActionType::Wheels,
        Some(2),
        true,
    )
    .expect("batch");
    batch.reset(Some(1));
    for (i, env) in batch.envs().iter().enumerate() {
        let mut marks = Vec::new();
        env.task_marks(&mut marks);
        let points = marks
            .iter()
            .find_map(|m| match m {
                _core::draw::Mark::Path { points, .. } => Some(points.clone()),
                _ => None,
            })
            .expect("path mark");
        for p in points {
            assert!(p.length() <= 0.6 + 1e-4, "{i}: {p:?}");
        }
    }
    let od = batch.obs_dim();
    let mut done = vec![false; n];
    let mut peak = 0.0f32;
    while !done.iter().all(|d| *d) {
        for i in (0..n).filter(|i| !done[*i]) {
            peak = peak.max(batch.obs()[i * od + kappa].abs());
        }
        let actions = samson.act_batch(batch.obs(), od).expect("act");
        batch.step(&actions).expect("step");
        for (d, o) in done.iter_mut().zip(batch.outcomes()) {
            *d |= o.terminated || o.truncated;
        }
    }
    let wheel = 0.15 * (1.0 + peak * half_axle);
    assert!(
        wheel <= 0.5 * vmax + 1e-4,
        "curvature {peak}: wheel {wheel}"
    );
}

#[test]
fn test_obstacles_lie_on_the_path_ahead_and_a_blind_follower_meets_them() {
    let cfg = scenario("obstacle_count = 4\nobstacle_offset = 0.0");
    let mut batch = Batch::new(
        TaskKind::PathFollow,
        cfg.clone(),
        16,
        ActionType::Wheels,
        Some(2),
        true,
    )
    .expect("batch");
    batch.reset(Some(13));
    for env in batch.envs() {
        let robot = env.world.robots[0].position;
        let shapes = &env.world.scene.shapes;
        assert_eq!(shapes.len(), 4);
        for s in shapes {
            // On the circle of radius 0.6 m, clear of the robot's start.
            assert!((s.center.length() - 0.6).abs() < 1e-4, "{:?}", s.center);
            assert!((s.center - robot).length() >= 0.0704 + 0.04);
        }
    }
    // Samson does not look at its IR: it drives into them.
    let r = run(&cfg, &policy("samson", &cfg), 16, 13);
    assert!(r.collisions.iter().all(|c| *c > 0), "{:?}", r.collisions);
}

#[test]
fn test_bad_paths_are_config_errors_naming_the_key() {
    for (overrides, key) in [
        ("size = 0.95", "pathfollow.size"),
        (
            "speed = 0.3\nsize = 0.1\nstart_offset = 0.05",
            "pathfollow.speed",
        ),
        (
            "path = \"lemniscate\"\nsize = 0.3\nspeed = 0.35",
            "pathfollow.speed",
        ),
        ("path = \"waypoints\"", "pathfollow.points"),
        (
            "points = [[0.0, 0.0], [0.1, 0.0], [0.0, 0.1], [0.0, 0.0]]",
            "pathfollow.points",
        ),
        (
            "path = \"waypoints\"\npoints = [[0.3, 0.0], [0.0, 0.3], [-0.3, 0.0], [0.0, -0.3]]",
            "pathfollow.points",
        ),
        (
            "path = \"waypoints\"\npoints = [[0.3, 0.0], [0.3, 0.0], [-0.3, 0.0], [0.3, 0.0]]",
            "pathfollow.points",
        ),
        (
            "path = \"waypoints\"\npoints = [[0.9, 0.0], [0.0, 0.3], [-0.3, 0.0], [0.9, 0.0]]",
            "pathfollow.points",
        ),
        ("start_offset = 0.3", "pathfollow.start_offset"),
        ("lost_distance = nan", "pathfollow.lost_distance"),
        ("obstacle_count = 40", "pathfollow.obstacle_count"),
        (
            "size = 0.2\nobstacle_count = 10\nspeed = 0.05",
            "pathfollow.obstacle_count",
        ),
        ("preview_points = 17", "pathfollow.preview_points"),
        ("preview_spacing = 1e30", "pathfollow.preview_spacing"),
        ("waypoint_spacing = 4.0", "pathfollow.waypoint_spacing"),
        (
            "spline_irregularity = 0.6",
            "pathfollow.spline_irregularity",
        ),
        ("path = \"ellipse\"", "pathfollow.path"),
    ] {
        let (got, message) = config_error(overrides);
        assert_eq!(got, key, "{overrides}: {message}");
    }
}

#[test]
fn test_a_scenarios_own_points_make_a_path_the_followers_lap() {
    // A rounded diamond drawn as 8 points: Samson laps it.
    let points: Vec<String> = (0..=8)
        .map(|k| {
            let a = std::f32::consts::TAU * (k % 8) as f32 / 8.0;
            let r = if k % 2 == 0 { 0.6 } else { 0.45 };
            format!("[{:.6}, {:.6}]", r * a.cos(), r * a.sin())
        })
        .collect();
    let cfg = scenario(&format!(
        "path = \"waypoints\"\npoints = [{}]",
        points.join(", ")
    ));
    let r = run(&cfg, &policy("samson", &cfg), 8, 15);
    assert!(r.success.iter().all(|s| *s));
}

#[test]
fn test_the_speed_term_costs_driving_faster_than_desired() {
    // Driving along the circle (wheel speeds v (1 ∓ axle / 2R)) at a constant speed v, once at
    // speed (after v / a ≤ 1.5 s): the closest point moves at v R / (R − d) (cos θ̃ ≈ 1: the
    // start at rest turns the robot a little less than the circle, so it settles a little
    // outside), and the reward with the term minus without is speed_weight·max(0, that − v_d)/v_d.
    let half = 0.5 * 0.1054 / 0.6;
    for v in [0.075f32, 0.15, 0.2] {
        let action = [v * (1.0 - half) / 0.813, v * (1.0 + half) / 0.813];
        let mut rewards = Vec::new();
        let mut offsets = Vec::new();
        for weight in [0.0f32, 0.1] {
            let cfg = scenario(&format!(
                "speed_weight = {weight}\nrandom_start = false\nstart_offset = 0.0\n\
                 start_heading_offset = 0.0\ndirection = \"ccw\""
            ));
            let d = layout(&cfg).find("cross_track_error").expect("d").start;
            let mut batch = Batch::new(
                TaskKind::PathFollow,
                cfg,
                1,
                ActionType::Wheels,
                Some(1),
                true,
            )
            .expect("batch");
            batch.reset(Some(0));
            let (mut r, mut o) = (Vec::new(), Vec::new());
            for _ in 0..60 {
                let before = batch.obs()[d];
                batch.step(&action).expect("step");
                r.push(batch.outcomes()[0].reward);
                o.push(0.5 * (before + batch.obs()[d]));
            }
            rewards.push(r);
            offsets.push(o);
        }
        for k in 40..60 {
            let term = rewards[0][k] - rewards[1][k];
            let along = v * 0.6 / (0.6 - offsets[1][k]);
            let expected = 0.1 * (along - 0.15).max(0.0) / 0.15;
            assert!(
                (term - expected).abs() <= 2e-3,
                "v {v} step {k}: {term} vs {expected} (d {})",
                offsets[1][k]
            );
        }
    }
}

#[test]
fn test_path_followers_read_every_preview_the_task_allows() {
    // The followers size their buffer themselves, so that controllers need no task; every
    // preview a PathFollow scenario may ask for must fit in it.
    let most = _core::tasks::pathfollow::MAX_PREVIEW_POINTS as usize;
    assert!(most <= _core::controllers::MAX_PATH_PREVIEW);
}
