//! Swarm specification (issues 16 and 54): worlds of up to 10,000 robots spawn without overlaps
//! and step with finite observations; finding neighbours through the grid gives the very results of
//! looking at every robot; too many robots for the arena is a configuration error that says how
//! many fit.
//!
//! Units: metres; world frame.

use crate::common;

use _core::robot::ActionType;
use _core::error::Error;
use _core::scenario::{scene, Scenario, Source};
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use rand::{Rng, SeedableRng};

/// The built-in `swarm` scene with `overrides`, loaded as multinav's scenario.
fn swarm_scenario(overrides: &str) -> Result<Scenario, Error> {
    let source = Source {
        file: Some((
            scene("swarm").expect("the swarm scene is built in"),
            "swarm",
        )),
        overrides: overrides.parse().expect("overrides"),
        version: None,
    };
    load_scenario("multinav", &source)
}

/// A multinav env on the built-in `swarm` scene with `overrides`, seeded and reset.
fn swarm(overrides: &str, seed: u64) -> Env {
    let cfg = swarm_scenario(overrides).expect("scenario");
    common::env(TaskKind::MultiNav, cfg, seed).0
}

/// Steps `env` with random actions from `seed`; returns every step's observation.
fn run(env: &mut Env, steps: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let n = env.world.robots.len();
    let mut obs = vec![0.0; env.obs_dim()];
    (0..steps)
        .map(|_| {
            let action: Vec<f32> = (0..2 * n).map(|_| rng.random_range(-0.2..1.0)).collect();
            env.step(&action, &mut obs);
            obs.clone()
        })
        .collect()
}

#[test]
fn test_a_world_of_1024_robots_spawns_apart_and_steps_with_finite_observations() {
    let mut env = swarm("n_robots = 1024", 1);
    let robots = &env.world.robots;
    assert_eq!(robots.len(), 1024);
    // Spawned at least two radii + obstacles.spawn_clearance (5 cm) apart.
    let least = 2.0 * env.world.drive.radius + 0.05;
    for (i, a) in robots.iter().enumerate() {
        for b in &robots[i + 1..] {
            assert!((a.position - b.position).length() >= least - 1e-5);
        }
    }
    for obs in run(&mut env, 20, 2) {
        assert!(obs.iter().all(|v| v.is_finite()));
    }
}

/// The env with `overrides` and `seed`, run `steps` steps through the grid, and the
/// observations of that run and of a twin's through the plain loops (seeded alike).
fn through_grid_and_plain(
    overrides: &str,
    seed: u64,
    steps: usize,
) -> (Env, Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let mut grid = swarm(overrides, seed);
    let mut plain = swarm(overrides, seed);
    plain.world.grid_min_robots = usize::MAX;
    let a = run(&mut grid, steps, seed + 1);
    let b = run(&mut plain, steps, seed + 1);
    (grid, a, b)
}

#[test]
fn test_the_grid_gives_the_results_of_looking_at_every_robot() {
    // A crowded 100-robot world (6 m arena: 2.8 robots per m²), so that sensors see robots and
    // contacts happen; once through the grid, once through the plain loops.
    let overrides = "n_robots = 100\nwidth = 6.0\nheight = 6.0";
    let (grid, a, b) = through_grid_and_plain(overrides, 3, 120);
    assert!(a == b, "the grid changed the trajectory");
    let touched = grid.world.robots.iter().filter(|r| r.in_contact).count();
    let seen = a.last().expect("steps")[..8].iter().any(|&ir| ir > 0.05);
    assert!(
        touched > 0 || seen,
        "the test world never brought robots near each other"
    );
}

#[test]
fn test_the_grid_gives_the_camera_and_sonar_images_of_looking_at_every_robot() {
    // The grid lists the robots near a robot cell by cell, not in robot order; what the sonars
    // and the camera make of the robot they meet (its surface normal, its LEDs) must not
    // depend on that order.
    let overrides = "n_robots = 100\nwidth = 6.0\nheight = 6.0\n\
                     carry = [\"ir\", \"us\", \"gyro\", \"camera\"]\n\
                     observe = [\"ir\", \"us\", \"camera\"]";
    let (grid, a, b) = through_grid_and_plain(overrides, 5, 60);
    assert!(a == b, "the grid changed the trajectory or the images");
    // Robot 0's camera saw robots: a pixel (r, g, b, depth / range, after the IR ring and the
    // sonars) with something in range that is not a wall (the scene has no obstacles).
    assert!(grid.world.scene.shapes.is_empty());
    let walls = grid.world.scene.wall_color;
    let camera = 8 + 5;
    let robots_seen = a.iter().any(|obs| {
        obs[camera..camera + 4 * 32]
            .chunks(4)
            .any(|px| px[3] < 0.99 && px[..3].iter().zip(walls).any(|(v, w)| (v - w).abs() > 1e-3))
    });
    assert!(robots_seen, "the camera never saw a robot");
}

#[test]
fn test_too_many_robots_for_the_arena_says_how_many_fit() {
    let source = Source {
        file: None,
        overrides: "n_robots = 1024".parse().expect("overrides"),
        version: None,
    };
    let err = load_scenario("multinav", &source)
        .expect_err("1,024 robots in a 2 m arena")
        .to_string();
    assert!(err.contains("multinav.n_robots"), "{err}");
    assert!(err.contains("fits about"), "{err}");
    let source = Source {
        file: None,
        overrides: "n_robots = 10001\nwidth = 200.0\nheight = 200.0"
            .parse()
            .expect("overrides"),
        version: None,
    };
    let err = load_scenario("multinav", &source)
        .expect_err("past the limit, though the arena would hold them")
        .to_string();
    assert!(
        err.contains("multinav.n_robots: must be >= 1, <= 10000, got 10001"),
        "{err}"
    );
}

#[test]
fn test_ten_thousand_robots_load_and_ten_thousand_and_one_are_refused() {
    // 10,000 robots (MAX_ROBOTS) in a 63 m arena, the swarm scene's density (2.5 per m²).
    let cfg = swarm_scenario("n_robots = 10000\nwidth = 63.0\nheight = 63.0")
        .expect("10,000 robots are allowed");
    assert_eq!(
        _core::tasks::multinav::MAX_ROBOTS,
        10_000,
        "the documented cap"
    );
    // The arena still bounds them: 10,000 robots do not fit in the swarm scene's 20 m arena.
    let err = swarm_scenario("n_robots = 10000")
        .expect_err("10,000 robots in 20 m x 20 m")
        .to_string();
    assert!(err.contains("fits about"), "{err}");
    // And a batch of such worlds beyond the memory bound is refused before it is built.
    let err = match _core::batch::Batch::new(
        TaskKind::MultiNav,
        cfg,
        1 << 20,
        ActionType::Wheels,
        Some(1),
        true,
    ) {
        Ok(_) => panic!("a million worlds of 10,000 robots were built"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("num_envs"), "{err}");
}

#[test]
fn test_a_world_of_10000_robots_spawns_apart_and_steps_with_finite_observations() {
    let mut env = swarm("n_robots = 10000\nwidth = 63.0\nheight = 63.0", 4);
    let robots = &env.world.robots;
    assert_eq!(robots.len(), 10_000);
    // Spawned at least two radii + obstacles.spawn_clearance (5 cm) apart: every pair, checked
    // through a sort along x (a pair closer than `least` is closer than it along x).
    let least = 2.0 * env.world.drive.radius + 0.05;
    let mut centres: Vec<_> = robots.iter().map(|r| r.position).collect();
    centres.sort_by(|a, b| a.x.total_cmp(&b.x));
    for (i, a) in centres.iter().enumerate() {
        for b in centres[i + 1..].iter().take_while(|b| b.x - a.x < least) {
            assert!((*a - *b).length() >= least - 1e-5, "{a:?} {b:?}");
        }
    }
    for obs in run(&mut env, 3, 5) {
        assert!(obs.iter().all(|v| v.is_finite()));
    }
}

/// A batch of `worlds` swarm worlds (`overrides` on the built-in scene) on `threads` threads.
fn batch(overrides: &str, worlds: usize, threads: usize) -> _core::batch::Batch {
    let cfg = swarm_scenario(overrides).expect("scenario");
    let mut batch = _core::batch::Batch::new(
        TaskKind::MultiNav,
        cfg,
        worlds,
        ActionType::Wheels,
        Some(threads),
        true,
    )
    .expect("batch");
    batch.reset(Some(9));
    batch
}

/// Steps `worlds` worlds of `overrides` on one thread and on two with the same random actions
/// and asserts the same observations and poses, bit for bit.
fn same_on_one_thread_or_two(overrides: &str, worlds: usize) {
    let mut one = batch(overrides, worlds, 1);
    let mut two = batch(overrides, worlds, 2);
    assert_eq!(two.num_threads(), 2);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for _ in 0..40 {
        let action: Vec<f32> = (0..worlds * one.act_dim())
            .map(|_| rng.random_range(-0.2..1.0))
            .collect();
        one.step(&action).expect("step");
        two.step(&action).expect("step");
        assert!(one.obs() == two.obs());
    }
    let poses = |b: &_core::batch::Batch| {
        b.envs()
            .iter()
            .flat_map(|env| env.world.robots.iter().map(|r| (r.position, r.heading)))
            .collect::<Vec<_>>()
    };
    assert_eq!(poses(&one), poses(&two));
}

#[test]
fn test_a_swarm_gives_the_same_results_on_one_thread_or_two() {
    // Two threads read one world's robots in parallel; the results may not depend on it.
    same_on_one_thread_or_two("n_robots = 300\nwidth = 11.0\nheight = 11.0", 1);
}

#[test]
fn test_a_batch_of_swarms_gives_the_same_results_on_one_thread_or_two() {
    // Each world of a swarm is a task of its own, and its robots are read in parallel inside
    // it: neither may change the results.
    same_on_one_thread_or_two("n_robots = 100\nwidth = 7.0\nheight = 7.0", 3);
}

#[test]
fn test_a_batch_of_swarms_split_by_robot_gives_the_same_results_on_one_thread_or_two() {
    // Three worlds on two threads: a world's helper thread may run another world's step while
    // it waits for work (`team.rs`); neither may change the results.
    let split = "\n[physics]\nsplit = \"robot\"";
    same_on_one_thread_or_two(&format!("n_robots = 100\nwidth = 7.0\nheight = 7.0{split}"), 3);
}

#[test]
fn test_a_swarm_in_a_pool_writes_the_observations_it_writes_alone() {
    // Inside a batch's pool a swarm's team applies its agents' actions and writes their
    // observations in blocks, each block on whichever thread claims it; a world stepped alone
    // (no pool) runs the blocks in order on its own thread. Both must give the same
    // observation, value for value, at the reset and at every step. 100 robots: one block of
    // 64 agents and a shorter one.
    let overrides = "n_robots = 100\nwidth = 7.0\nheight = 7.0";
    let mut pooled = batch(overrides, 1, 2);
    let cfg = swarm_scenario(overrides).expect("scenario");
    let (mut alone, reset_obs) = common::env(TaskKind::MultiNav, cfg, 9);
    assert!(pooled.obs() == reset_obs.as_slice(), "the reset's observations differ");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    let mut obs = vec![0.0; alone.obs_dim()];
    for step in 0..30 {
        let action: Vec<f32> = (0..pooled.act_dim())
            .map(|_| rng.random_range(-0.2..1.0))
            .collect();
        pooled.step(&action).expect("step");
        alone.step(&action, &mut obs);
        assert!(pooled.obs() == obs.as_slice(), "step {step}: the observations differ");
    }
}
