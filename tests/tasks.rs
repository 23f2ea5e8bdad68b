//! Task specification for Avoid and Formation: feasible random layouts, the cross formation at
//! reset, and a scripted leader that reaches its goal while followers hold the formation. The
//! determinism of every task and version (world i ≡ seed s + i, thread-count invariance) is
//! specified in `determinism.rs`, from the registry.

use std::sync::Arc;

use _core::controllers::position::twist_to_wheels;
use _core::controllers::PositionControl;
use _core::robot::ActionType;
use _core::scenario::{Scenario, Source};
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use rapier2d::math::Vector;

fn scenario(task: &str, scene: Option<&str>, overrides: &str) -> Scenario {
    scenario_version(task, scene, overrides, None)
}

/// The scenario with behaviour `version`'s defaults (None: the latest).
fn scenario_version(
    task: &str,
    scene: Option<&str>,
    overrides: &str,
    version: Option<u32>,
) -> Scenario {
    let source = Source {
        file: scene.map(|s| (_core::scenario::scene(s).expect("built-in scene"), s)),
        overrides: overrides.parse().expect("overrides"),
        version,
    };
    load_scenario(task, &source).expect("scenario")
}

/// Whether the robot can drive from `a` to `b` among `env`'s obstacles: a flood fill over a
/// 1 cm grid of robot-centre positions that keep clear of everything.
fn reachable(env: &Env, a: Vector, b: Vector) -> bool {
    let scene = &env.world.scene;
    let radius = env.world.drive.radius;
    let cell = 0.01;
    let (w, h) = scene.arena;
    let (nx, ny) = ((w / cell) as i32, (h / cell) as i32);
    let index = |p: Vector| {
        (
            ((p.x + 0.5 * w) / cell).floor() as i32,
            ((p.y + 0.5 * h) / cell).floor() as i32,
        )
    };
    let free = |i: i32, j: i32| {
        let p = Vector::new(
            (i as f32 + 0.5) * cell - 0.5 * w,
            (j as f32 + 0.5) * cell - 0.5 * h,
        );
        scene.clearance(p) > radius
    };
    let (start, goal) = (index(a), index(b));
    let mut seen = vec![false; (nx * ny) as usize];
    let mut stack = vec![start];
    seen[(start.1 * nx + start.0) as usize] = true;
    while let Some((i, j)) = stack.pop() {
        if (i, j) == goal {
            return true;
        }
        for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            let (u, v) = (i + di, j + dj);
            if u < 0 || v < 0 || u >= nx || v >= ny || seen[(v * nx + u) as usize] {
                continue;
            }
            seen[(v * nx + u) as usize] = true;
            if free(u, v) {
                stack.push((u, v));
            }
        }
    }
    false
}

#[test]
fn test_random_obstacles_keep_start_and_goal_clear_and_reachable() {
    let cfg = Arc::new(scenario("avoid", None, ""));
    let spawner = Arc::new(Env::spawner(TaskKind::Avoid, &cfg).expect("spawner"));
    let mut env = Env::new(TaskKind::Avoid, cfg.clone(), spawner, ActionType::Wheels).expect("env");
    let mut obs = vec![0.0; env.obs_dim()];
    let mut full = 0;
    for seed in 0..100 {
        env.seed(seed);
        env.reset(&mut obs);
        let shapes = &env.world.scene.shapes;
        full += (shapes.len() == cfg.obstacles.count as usize) as usize;
        let start = env.world.robots[0].position;
        let goal = env.goals()[0];
        let clear = env.world.drive.radius + cfg.obstacles.spawn_clearance;
        for (k, shape) in shapes.iter().enumerate() {
            assert!(
                shape.distance(start) >= clear - 1e-4,
                "seed {seed}: obstacle {k} on the start"
            );
            assert!(
                shape.distance(goal) >= clear - 1e-4,
                "seed {seed}: obstacle {k} on the goal"
            );
            for other in &shapes[k + 1..] {
                assert!(
                    shape.gap(other) >= cfg.obstacles.min_gap - 1e-4,
                    "seed {seed}: too close"
                );
            }
        }
        assert!(reachable(&env, start, goal), "seed {seed}: goal walled off");
    }
    assert!(full >= 95, "only {full}/100 layouts placed every obstacle");
}

#[test]
fn test_paper_fig7_places_five_robots_in_a_cross() {
    let cfg = Arc::new(scenario("formation", Some("paper_fig7"), ""));
    let spawner = Arc::new(Env::spawner(TaskKind::Formation, &cfg).expect("spawner"));
    let mut env = Env::new(
        TaskKind::Formation,
        cfg.clone(),
        spawner,
        ActionType::Wheels,
    )
    .expect("env");
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut obs);
    let p: Vec<Vector> = env.world.robots.iter().map(|r| r.position).collect();
    let leader = Vector::new(-0.85, 0.0);
    let expected = [
        leader,
        leader + Vector::new(0.5, 0.0),
        leader + Vector::new(0.0, 0.5),
        leader + Vector::new(-0.5, 0.0),
        leader + Vector::new(0.0, -0.5),
    ];
    for (got, want) in p.iter().zip(expected) {
        assert!((*got - want).length() < 1e-5, "{got:?} != {want:?}");
    }
    for (k, target) in env.targets().iter().enumerate() {
        assert!((*target - p[k + 1]).length() < 1e-5);
    }
}

/// Followers driven by position control toward the target offset in their observation.
fn follower_actions(obs: &[f32], k: usize, max_wheel_speed: f32) -> Vec<f32> {
    let pc = PositionControl {
        vmax: 0.35,
        wmax: 4.0,
        kr: 0.08,
        stop_radius: 0.005,
    };
    (0..k)
        .flat_map(|i| {
            let block = &obs[i * 23..(i + 1) * 23];
            let (x, y) = (block[13], block[14]);
            let (v, w) = pc.twist((x * x + y * y).sqrt(), y.atan2(x));
            twist_to_wheels(v, w, 0.1054).map(|s| (s / max_wheel_speed).clamp(-1.0, 1.0))
        })
        .collect()
}

#[test]
fn test_scripted_leader_reaches_goal_and_followers_hold_formation() {
    // The paper's gains, on the dynamics they were tuned for (v0).
    for (scene, bound) in [(None, 0.1f32), (Some("paper_fig7"), 0.25)] {
        let cfg = Arc::new(scenario_version("formation", scene, "", Some(0)));
        let spawner = Arc::new(Env::spawner(TaskKind::Formation, &cfg).expect("spawner"));
        let mut env = Env::new(
            TaskKind::Formation,
            cfg.clone(),
            spawner,
            ActionType::Wheels,
        )
        .expect("env");
        let mut obs = vec![0.0; env.obs_dim()];
        let mut successes = 0;
        for seed in 0..10 {
            env.seed(seed);
            env.reset(&mut obs);
            loop {
                let a = follower_actions(&obs, 4, 0.813);
                let out = env.step(&a, &mut obs);
                if out.terminated || out.truncated {
                    break;
                }
            }
            let stats = env.last_episode;
            successes += stats.success as usize;
            let (_, error_mean) = env.extra_stats(&stats)[0];
            assert_eq!(TaskKind::Formation.extra_stats()[0], "formation_error_mean");
            assert!(
                error_mean < bound,
                "{scene:?} seed {seed}: mean formation error {error_mean}"
            );
        }
        assert!(
            successes >= 9,
            "{scene:?}: leader reached its goal {successes}/10 times"
        );
    }
}

/// Every task's declared agent facts (`TaskInfo::agents`, which the Python adapters read
/// instead of lists of their own) agree with the agents its default scenario builds, and a
/// task that says its agents end together never ends one agent alone.
#[test]
fn test_agent_facts_match_the_agents_each_task_builds() {
    use _core::tasks::Body;
    for &kind in TaskKind::ALL {
        let facts = kind.info().agents;
        let cfg = Arc::new(scenario(kind.name(), None, ""));
        let agents = kind.agents(&cfg).expect("agents");
        assert_eq!(facts.several, agents.len() > 1, "{}: several", kind.name());
        let robots = agents.iter().all(|a| matches!(a.body, Body::Robot(_)));
        let one_layout = agents.iter().all(|a| a.layout.len() == agents[0].layout.len());
        assert_eq!(facts.alike, robots && one_layout, "{}: alike", kind.name());
        if facts.end_separately {
            assert!(facts.several, "{}: one agent cannot end apart", kind.name());
            continue;
        }
        let spawner = Arc::new(Env::spawner(kind, &cfg).expect("spawner"));
        let mut env = Env::new(kind, cfg.clone(), spawner, ActionType::Wheels).expect("env");
        let mut obs = vec![0.0; env.obs_dim()];
        let width = _core::tasks::action_width(&cfg);
        for seed in 0..3 {
            env.seed(seed);
            env.reset(&mut obs);
            for step in 0..3000 {
                // Full speed ahead with a slow turn: robots reach walls, goals and each other.
                let turn = ((step / 40) % 2) as f32 * 0.6;
                let action: Vec<f32> = (0..agents.len())
                    .flat_map(|_| {
                        let mut a = vec![0.0; width];
                        a[0] = 1.0;
                        a[1] = 1.0 - turn;
                        a
                    })
                    .collect();
                let out = env.step(&action, &mut obs);
                let first = env.agent_terminated[0];
                assert!(
                    env.agent_terminated.iter().all(|&t| t == first),
                    "{} seed {seed} step {step}: an agent ended alone",
                    kind.name()
                );
                if out.terminated || out.truncated {
                    break;
                }
            }
        }
    }
}

