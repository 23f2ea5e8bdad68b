//! The platoon task: robot k tracks the reference delayed by k·time_gap, so the robots'
//! reference points are time_gap·v_r apart along the curve; Kanayama's controller on every
//! agent converges as its linearised closed loop says; the robots start near their own
//! reference points without overlapping; bad platoons are configuration errors naming the key;
//! seeds reproduce episodes bit for bit. (World i ≡ seed s + i, thread counts and saved states:
//! tests/tasks.rs and tests/state.rs, which iterate over every task.)

use crate::common;

use _core::batch::Batch;
use _core::controllers::Policy;
use _core::robot::ActionType;
use _core::scenario::{Scenario, Source};
use _core::tasks::{load_scenario, TaskKind};

/// Scenario defaults the bounds use (configs/platoon.toml).
const ROBOTS: usize = 3; // platoon.robots
const TIME_GAP: f32 = 2.0; // s, platoon.time_gap
const SPEED: f32 = 0.15; // m/s, platoon.speed
const RADIUS: f32 = 0.6; // m, platoon.size of the circle
const START_OFFSET: f32 = 0.2; // m, platoon.start_offset
const TRANSIENT: f32 = 5.0; // s, platoon.transient

fn scenario(overrides: &str) -> Scenario {
    common::scenario("platoon", overrides)
}

fn batch(cfg: &Scenario, n: usize) -> Batch {
    Batch::new(
        TaskKind::Platoon,
        cfg.clone(),
        n,
        ActionType::Wheels,
        Some(2),
        true,
    )
    .expect("batch")
}

/// Kanayama's controller on one agent's block (every agent's block has the same layout).
fn kanayama(cfg: &Scenario) -> (Policy, usize) {
    let layout = TaskKind::Platoon
        .agents(cfg)
        .expect("agents")
        .remove(0)
        .layout;
    let policy = Policy::new("kanayama", &Default::default(), &layout).expect("policy");
    (policy, layout.len())
}

/// One episode per world under Kanayama on every agent: each robot's position error after every
/// step [world][robot][step] (m), and whether any robot was lost.
fn run_kanayama(cfg: &Scenario, n: usize, seed: u64) -> (Vec<Vec<Vec<f32>>>, Vec<u32>, bool) {
    let (policy, agent_dim) = kanayama(cfg);
    let mut batch = batch(cfg, n);
    batch.reset(Some(seed));
    let robots = batch.envs()[0].world.robots.len();
    let mut errors = vec![vec![Vec::new(); robots]; n];
    let mut lengths = vec![0u32; n];
    let mut lost = false;
    while lengths.contains(&0) {
        let actions = policy.act_batch(batch.obs(), agent_dim).expect("actions");
        batch.step(&actions).expect("step");
        let outcomes = batch.outcomes().to_vec();
        for (i, env) in batch.envs().iter().enumerate() {
            if lengths[i] > 0 {
                continue;
            }
            if outcomes[i].terminated || outcomes[i].truncated {
                lengths[i] = env.last_episode.length;
                lost |= outcomes[i].terminated;
                continue;
            }
            lost |= env.agent_terminated.iter().any(|t| *t);
            for (k, goal) in env.goals().iter().enumerate() {
                let error = (*goal - env.world.robots[k].position).length();
                errors[i][k].push(error);
            }
        }
    }
    (errors, lengths, lost)
}

#[test]
fn test_kanayama_on_every_robot_converges_on_the_circle_within_the_linear_envelope() {
    // Kanayama's law linearised about zero error (src/controllers/kanayama.rs): the along-track
    // error decays at K_x = 1 s⁻¹ and the cross-track loop s² + v_r K_θ s + v_r² K_y is
    // critically damped with ω_n = v_r √K_y = 1 rad/s at v_r = 0.15 m/s; so with λ = 1 s⁻¹ an
    // error starting at E0 stays within E0 (1 + λt) e^{−λt}. E0 sums the start offset, the
    // heading offset's drift v_r sin(45°)/λ and the lag of a standing start under the wheels'
    // acceleration limit, v_r²/(2a); sampling adds at most the reference's travel in one step.
    // Each robot's reference is the circle's, delayed: the same bound holds for every robot as
    // long as its neighbours keep out of its way (they start apart and converge as it does).
    let cfg = scenario("reference = \"circle\"");
    let accel = cfg.wheel_accel().bounds().0;
    let lambda = 1.0f32;
    let e0 = START_OFFSET
        + SPEED * std::f32::consts::FRAC_PI_4.sin() / lambda
        + SPEED * SPEED / (2.0 * accel);
    let envelope = |t: f32| e0 * (1.0 + lambda * t) * (-lambda * t).exp() + SPEED * cfg.physics.dt;
    let bound = envelope(TRANSIENT);
    let (errors, lengths, lost) = run_kanayama(&cfg, 20, 40);
    assert!(!lost, "a robot was lost");
    // One lap plus the margin: 2π·0.6 / 0.15 + 2 s = 27.13 s → 543 steps, as Track.
    assert!(lengths.iter().all(|l| *l == 543), "{lengths:?}");
    let after = (TRANSIENT / cfg.physics.dt) as usize;
    let mut worst = vec![0.0f32; ROBOTS];
    for world in &errors {
        for (k, e) in world.iter().enumerate() {
            let peak = e[after..].iter().cloned().fold(0.0, f32::max);
            worst[k] = worst[k].max(peak);
        }
    }
    println!("kanayama worst error after {TRANSIENT} s per robot {worst:?} (bound {bound:.4} m)");
    for (k, w) in worst.iter().enumerate() {
        assert!(*w <= bound, "robot {k}: {w} m beyond {bound} m");
    }
}

#[test]
fn test_robot_k_tracks_robot_0s_reference_delayed_by_k_time_gaps() {
    // On any curve robot k's reference point now is robot 0's k·time_gap ago; on the circle,
    // travelled at constant speed, neighbours are time_gap·v_r = 0.30 m apart along the arc.
    for reference in ["circle", "lemniscate"] {
        let cfg = scenario(&format!("reference = \"{reference}\""));
        let mut batch = batch(&cfg, 1);
        batch.reset(Some(3));
        let lag_steps = (TIME_GAP / cfg.physics.dt).round() as usize;
        let mut history = Vec::new();
        let zeros = vec![0.0; batch.act_dim()];
        for step in 0..(ROBOTS * lag_steps + 20) {
            let goals = batch.envs()[0].goals();
            assert_eq!(goals.len(), ROBOTS);
            history.push(goals[0]);
            for (k, goal) in goals.iter().enumerate().skip(1) {
                if step >= k * lag_steps {
                    let earlier = history[step - k * lag_steps];
                    assert!(
                        (*goal - earlier).length() < 1e-5,
                        "{reference} step {step} robot {k}: {goal:?} vs {earlier:?}"
                    );
                }
                if reference == "circle" {
                    let before = goals[k - 1];
                    let cos = before.dot(*goal) / (before.length() * goal.length());
                    let arc = RADIUS * cos.clamp(-1.0, 1.0).acos();
                    assert!((arc - TIME_GAP * SPEED).abs() < 1e-3, "arc {arc}");
                }
            }
            // Standing still the robots are lost after a while; the reference goes on.
            batch.step(&zeros).expect("step");
            if batch.outcomes()[0].terminated || batch.outcomes()[0].truncated {
                break;
            }
        }
    }
}

#[test]
fn test_robots_start_near_their_reference_points_without_overlapping() {
    // Five robots on the lemniscate, and the densest circle platoon (16 robots 1.5 s apart:
    // 0.225 m, a 3.6 m column on the 3.77 m lap). Drawn uniformly, the start distance averages
    // start_offset / 2; redrawing the starts that touch a neighbour lowers it, but a platoon
    // that fell back to starting every robot on its reference point would average 0.
    for (overrides, robots) in [
        ("reference = \"lemniscate\"\nrobots = 5", 5),
        ("robots = 16\ntime_gap = 1.5", 16),
    ] {
        let cfg = scenario(overrides);
        let n = 300;
        let mut batch = batch(&cfg, n);
        batch.reset(Some(11));
        let apart = 2.0 * cfg.robot.radius + cfg.obstacles.spawn_clearance;
        let mut offsets = Vec::new();
        for env in batch.envs() {
            let goals = env.goals();
            let bodies = &env.world.robots;
            assert_eq!(bodies.len(), robots);
            for (k, robot) in bodies.iter().enumerate() {
                let offset = (goals[k] - robot.position).length();
                assert!(offset <= START_OFFSET + 1e-5, "{overrides}: {offset}");
                offsets.push(offset);
                assert_eq!(robot.wheel_speeds, [0.0, 0.0]);
                for other in &bodies[..k] {
                    assert!((other.position - robot.position).length() >= apart - 1e-5);
                }
            }
        }
        let mean = offsets.iter().sum::<f32>() / offsets.len() as f32;
        println!("{overrides}: mean start offset {mean:.4} m");
        assert!(
            mean > START_OFFSET / 4.0,
            "{overrides}: mean start offset {mean}"
        );
    }
}

#[test]
fn test_same_seed_same_episode_bit_for_bit_other_seed_differs() {
    let cfg = scenario("reference = \"spline\"\nmax_steps = 100");
    let (policy, agent_dim) = kanayama(&cfg);
    let trace = |seed: u64| {
        let mut batch = batch(&cfg, 2);
        batch.reset(Some(seed));
        let mut out: Vec<u32> = batch.obs().iter().map(|v| v.to_bits()).collect();
        for _ in 0..100 {
            let actions = policy.act_batch(batch.obs(), agent_dim).expect("actions");
            batch.step(&actions).expect("step");
            out.extend(batch.obs().iter().map(|v| v.to_bits()));
            for env in batch.envs() {
                for r in &env.world.robots {
                    out.extend([r.position.x, r.position.y, r.heading].map(f32::to_bits));
                }
            }
        }
        out
    };
    assert_eq!(trace(5), trace(5));
    assert_ne!(trace(5), trace(6));
}

#[test]
fn test_a_lost_robot_is_terminated_alone_and_parks() {
    // The last robot stands still while the others follow Kanayama: it alone is lost once its
    // reference is lost_distance away; from then on its wheels get zero commands whatever its
    // agent sends (here full speed ahead), and the episode goes on for the others.
    let cfg = scenario(
        "reference = \"circle\"\nstart_offset = 0.0\nstart_heading_offset = 0.0\n\
         lost_distance = 0.15",
    );
    let (policy, agent_dim) = kanayama(&cfg);
    let mut batch = batch(&cfg, 1);
    batch.reset(Some(2));
    let last = 2 * (ROBOTS - 1);
    let mut parked_at = None;
    for _ in 0..200 {
        let mut actions = policy.act_batch(batch.obs(), agent_dim).expect("actions");
        let drive = if parked_at.is_some() { 1.0 } else { 0.0 };
        actions[last] = drive;
        actions[last + 1] = drive;
        batch.step(&actions).expect("step");
        let env = &batch.envs()[0];
        assert!(!batch.outcomes()[0].terminated && !batch.outcomes()[0].truncated);
        assert!(!env.agent_terminated[0] && !env.agent_terminated[1]);
        let position = env.world.robots[ROBOTS - 1].position;
        match parked_at {
            None if env.agent_terminated[ROBOTS - 1] => parked_at = Some(position),
            Some(p) => {
                assert!(env.agent_terminated[ROBOTS - 1]);
                assert_eq!(env.agent_rewards[ROBOTS - 1], 0.0);
                assert_eq!(position, p);
            }
            None => {}
        }
    }
    assert!(parked_at.is_some(), "the last robot was never lost");
}

fn config_error(overrides: &str) -> String {
    let source = Source {
        file: None,
        overrides: overrides.parse().expect("overrides"),
        ..Default::default()
    };
    let built = load_scenario("platoon", &source)
        .and_then(|cfg| Batch::new(TaskKind::Platoon, cfg, 1, ActionType::Wheels, Some(1), true));
    match built {
        Err(_core::error::Error::Config { key, .. }) => key,
        Err(other) => panic!("{overrides}: expected a config error, got {other:?}"),
        Ok(_) => panic!("{overrides}: expected a config error, got a batch"),
    }
}

#[test]
fn test_bad_platoons_are_config_errors_naming_the_key() {
    // 0.5 s × 0.15 m/s = 7.5 cm: reference points closer than a diameter (14.08 cm) + 2 cm.
    assert_eq!(config_error("time_gap = 0.5"), "platoon.time_gap");
    assert_eq!(config_error("time_gap = 0.0"), "platoon.time_gap");
    assert_eq!(config_error("time_gap = nan"), "platoon.time_gap");
    // 13 × 2 s = 26 s, more than the circle's 25.13 s lap.
    assert_eq!(config_error("robots = 13"), "platoon.robots");
    assert_eq!(config_error("robots = 0"), "platoon.robots");
    assert_eq!(
        config_error("robots = 17\ntime_gap = 1.1"),
        "platoon.robots"
    );
    // 1.15 s × 0.15 m/s = 17 cm on average, but the lemniscate slows to about 0.6 of its mean
    // speed near its lobes' ends, where neighbours come closer than a diameter + 2 cm.
    assert!(load_scenario(
        "platoon",
        &Source {
            overrides: "time_gap = 1.15".parse().unwrap(),
            ..Default::default()
        }
    )
    .is_ok());
    assert_eq!(
        config_error("time_gap = 1.15\nreference = \"lemniscate\""),
        "platoon.time_gap"
    );
    // Track's keys are the platoon's, named so.
    assert_eq!(config_error("size = 0.9"), "platoon.size");
    assert_eq!(config_error("speed = 0.6"), "platoon.speed");
    assert_eq!(
        config_error("preview_points = 17"),
        "platoon.preview_points"
    );
    assert_eq!(config_error("platoon.lost = 1.0"), "platoon.lost");
    // Starts are the platoon's: fixed ones would be silently ignored.
    assert_eq!(config_error("spawn.start = [0.0, 0.0, 0.0]"), "spawn.start");
}
