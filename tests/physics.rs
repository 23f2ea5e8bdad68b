//! Physics specification: a robot never leaves the arena, turns in place about its centre, and
//! drives straight at the commanded speed. Uses the core directly (no Python).

use crate::common;

use _core::scenario::Source;
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use crate::common::drive;
use rapier2d::math::Vector;

fn nav_env(overrides: &str) -> Env {
    nav_env_version(overrides, None)
}

/// A Nav env with behaviour `version`'s defaults (None: the latest); v0's kinematic drive is what
/// the exact-kinematics tests below specify.
fn nav_env_version(overrides: &str, version: Option<u32>) -> Env {
    let source = Source {
        file: None,
        overrides: overrides.parse().expect("overrides"),
        version,
    };
    let cfg = load_scenario("nav", &source).expect("scenario");
    common::env(TaskKind::Nav, cfg, 7).0
}

#[test]
fn test_full_speed_into_walls_never_leaves_arena() {
    // 10 s at full speed against walls, from several headings, including shallow angles
    // (sliding) and corners.
    for heading_deg in [0.0f32, 30.0, 45.0, 89.0, 135.0, -60.0] {
        let mut env = nav_env("max_steps = 100000");
        env.world
            .place_robot(0, Vector::new(0.3, -0.2), heading_deg.to_radians());
        let radius = env.world.drive.radius;
        let mut touched = false;
        drive(&mut env, &[1.0, 1.0], 200, |env| {
            let p = env.world.robots[0].position;
            // The body may sink into a wall by at most rapier's allowed error (1 mm).
            assert!(
                p.x.abs() <= 1.0 - radius + 0.002 && p.y.abs() <= 1.0 - radius + 0.002,
                "heading {heading_deg}: robot at {p:?} is through a wall"
            );
            touched |= env.world.robots[0].in_contact;
        });
        assert!(touched, "heading {heading_deg}: never reported contact");
    }
}

#[test]
fn test_robot_slides_along_wall_at_shallow_angle() {
    // v0: frictionless walls (v1's friction is specified in tests/dynamics.rs).
    let mut env = nav_env_version("max_steps = 100000", Some(0));
    env.world
        .place_robot(0, Vector::new(-0.5, 0.85), 10f32.to_radians());
    drive(&mut env, &[0.5, 0.5], 30, |_| {});
    let p = env.world.robots[0].position;
    // It kept moving along +x while held at the wall (y = 1 - radius).
    assert!(p.x > 0.0, "did not slide: {p:?}");
    assert!((p.y - (1.0 - env.world.drive.radius)).abs() < 0.01, "{p:?}");
}

#[test]
fn test_turning_in_place_keeps_centre_fixed() {
    // v0: the wheels at full speed from the first step (tests/dynamics.rs ramps them).
    let mut env = nav_env_version("max_steps = 100000", Some(0));
    let start = Vector::new(0.1, -0.3);
    env.world.place_robot(0, start, 0.4);
    let mut turned = 0.0f32;
    drive(&mut env, &[-1.0, 1.0], 100, |env| {
        let p = env.world.robots[0].position;
        assert!((p - start).length() < 1e-3, "centre drifted to {p:?}");
        turned += env.world.robots[0].yaw_rate * env.world.dt();
    });
    // 2·0.813/0.1054 rad/s for 5 s
    let expected = 2.0 * 0.813 / 0.1054 * 5.0;
    assert!(
        (turned - expected).abs() / expected < 1e-3,
        "{turned} vs {expected}"
    );
}

#[test]
fn test_straight_driving_covers_v_times_t() {
    for v in [0.05f32, 0.2, 0.5, 0.813] {
        // v0: at speed from the first step.
        let mut env = nav_env_version("max_steps = 100000", Some(0));
        env.world.place_robot(0, Vector::new(-0.9, 0.0), 0.0);
        let a = v / 0.813;
        drive(&mut env, &[a, a], 20, |_| {});
        let dx = env.world.robots[0].position.x + 0.9;
        assert!((dx - v).abs() <= 0.01 * v, "v = {v}: travelled {dx} in 1 s");
    }
}

#[test]
fn test_acceleration_limit_ramps_speed() {
    // v1's drive: a plain ramp at robot.wheel_accel_limit (tests/drive.rs specifies v2's).
    let mut env = nav_env_version("max_steps = 100000\nwheel_accel_limit = 1.0", Some(1));
    env.world.place_robot(0, Vector::new(-0.9, 0.0), 0.0);
    drive(&mut env, &[1.0, 1.0], 4, |_| {});
    // 0.2 s at 1 m/s² → 0.2 m/s, 0.02 m travelled
    let r = &env.world.robots[0];
    assert!(
        (r.wheel_speeds[0] - 0.2).abs() < 1e-5,
        "{:?}",
        r.wheel_speeds
    );
    assert!(
        (r.position.x + 0.9 - 0.0225).abs() < 2e-3,
        "{:?}",
        r.position
    );
}

/// `steps` seeded random steps (mostly forward) of an Avoid env (seed `seed`), through `step`,
/// which steps the env it is given; returns the observations and how many steps left the robot
/// in contact.
fn avoid_run(
    seed: u64,
    steps: usize,
    mut step: impl FnMut(&mut Env, &[f32], &mut [f32]),
) -> (Vec<Vec<f32>>, usize) {
    use rand::{Rng, SeedableRng};
    let cfg = load_scenario("avoid", &Source::default()).expect("scenario");
    let (mut env, mut obs) = common::env(TaskKind::Avoid, cfg, seed);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut contacts = 0;
    let all = (0..steps)
        .map(|_| {
            let action = [rng.random_range(-0.2..1.0), rng.random_range(-0.2..1.0)];
            step(&mut env, &action, &mut obs);
            env.done = false;
            contacts += usize::from(env.world.robots[0].in_contact);
            obs.clone()
        })
        .collect();
    (all, contacts)
}

#[test]
fn test_worlds_stepped_in_turn_on_one_thread_step_as_each_alone() {
    // Rapier's pipeline (its workspace) is one per thread, shared by every world the thread
    // steps: a world must step the same whichever worlds the thread stepped before. Each world
    // alone, on a thread of its own (a new pipeline)...
    let steps = 400;
    let alone: Vec<_> = [1u64, 2, 3]
        .map(|seed| {
            std::thread::spawn(move || {
                avoid_run(seed, steps, |e, a, o| {
                    e.step(a, o);
                })
            })
        })
        .into_iter()
        .map(|h| h.join().expect("thread"))
        .collect();
    // ...and the three stepped in turn on this one, step by step.
    let cfg = load_scenario("avoid", &Source::default()).expect("scenario");
    let mut others: Vec<Env> = [2u64, 3]
        .map(|seed| common::env(TaskKind::Avoid, cfg.clone(), seed).0)
        .into();
    let mut rngs: Vec<rand_chacha::ChaCha8Rng> =
        [2u64, 3].map(rand::SeedableRng::seed_from_u64).into();
    let mut scratch = vec![0.0; others[0].obs_dim()];
    let mut seen: Vec<Vec<Vec<f32>>> = vec![Vec::new(); others.len()];
    let (first, contacts) = avoid_run(1, steps, |env, action, obs| {
        env.step(action, obs);
        for ((other, rng), seen) in others.iter_mut().zip(&mut rngs).zip(&mut seen) {
            use rand::Rng;
            let a = [rng.random_range(-0.2..1.0), rng.random_range(-0.2..1.0)];
            other.step(&a, &mut scratch);
            other.done = false;
            seen.push(scratch.clone());
        }
    });
    // Mostly forward at random: the robots drive into obstacles and walls and stay there a while.
    let touched = [contacts, alone[1].1, alone[2].1];
    assert!(
        touched.iter().all(|&c| c > 20),
        "steps in contact: {touched:?}"
    );
    assert!(
        first == alone[0].0,
        "stepping other worlds in between changed world 1"
    );
    for (k, seen) in seen.iter().enumerate() {
        assert!(
            *seen == alone[k + 1].0,
            "stepping other worlds in between changed world {}",
            k + 2
        );
    }
}

/// A step's observation and every robot's pose (centre, heading).
type Snapshot = (Vec<f32>, Vec<(Vector, f32)>);

/// Steps `env` with random wheel actions from `seed`; returns every step's [`Snapshot`].
fn random_run(env: &mut Env, steps: usize, seed: u64) -> Vec<Snapshot> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let width = 2 * env.world.robots.len();
    let mut obs = vec![0.0; env.obs_dim()];
    (0..steps)
        .map(|_| {
            let action: Vec<f32> = (0..width).map(|_| rng.random_range(-0.2..1.0)).collect();
            let outcome = env.step(&action, &mut obs);
            if outcome.terminated || outcome.truncated {
                env.reset(&mut obs);
            }
            let poses = env.world.robots.iter().map(|r| (r.position, r.heading));
            (obs.clone(), poses.collect())
        })
        .collect()
}

#[test]
fn test_building_rapier_at_the_first_contact_changes_nothing() {
    // Issue 54: a world builds its rapier side at the first substep that needs it. Built then,
    // or with the world and changed by the episodes' draws of mass and friction (what worlds
    // did before), it steps the same, bit for bit: here twelve robots crossing a 2 m arena,
    // every version, with the mass and the frictions drawn at every reset.
    let overrides = "n_robots = 12\nmax_steps = 150\nrobot.mass = [0.4, 0.7]\n\
                     physics.friction = [0.3, 0.9]\nphysics.robot_friction = [0.2, 0.8]";
    for version in 0..=_core::scenario::LATEST_VERSION {
        let cfg = || common::scenario_in("multinav", overrides, version);
        let mut late = common::build(TaskKind::MultiNav, cfg());
        let mut early = common::build(TaskKind::MultiNav, cfg());
        early.world.build_physics_now();
        assert!(!late.world.physics_built() && early.world.physics_built());
        let mut obs = vec![0.0; late.obs_dim()];
        for env in [&mut late, &mut early] {
            env.seed(3);
            env.reset(&mut obs);
        }
        let a = random_run(&mut late, 400, 4);
        let b = random_run(&mut early, 400, 4);
        assert!(late.world.physics_built(), "v{version}: no substep needed rapier");
        assert!(a == b, "v{version}: building rapier late changed the run");
    }
}

#[test]
fn test_a_nav_world_of_v3_never_builds_rapier() {
    // One robot with its scene contacts solved as a disc's: rapier's sets, most of a world's
    // memory before issue 54, are never built, however often the robot meets the walls.
    let mut env = nav_env("max_steps = 100");
    random_run(&mut env, 600, 1);
    assert!(env.world.robots[0].position.x.is_finite());
    assert!(!env.world.physics_built());
}
