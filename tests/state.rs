//! Saved states: restoring a batch's state and replaying the same actions reproduces the
//! trajectory bit for bit (contacts included), in the same batch or a fresh one, for every task
//! and version of the registry ([`common::every_task_version`]); a state that is
//! not one, is corrupt, or comes from another batch is refused with a message saying which, and
//! leaves the batch as it was.

use _core::batch::Batch;
use _core::error::Error;
use _core::robot::ActionType;
use _core::scenario::Source;
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use crate::common::every_task_version;
use rand::{Rng, SeedableRng};

/// A batch of `n` worlds of `task` with `overrides`, behaviour `version` (None: the latest).
fn batch_in(task: &str, overrides: &str, n: usize, version: Option<u32>) -> Batch {
    let source = Source {
        file: None,
        overrides: overrides.parse().expect("overrides"),
        version,
    };
    let cfg = load_scenario(task, &source).expect("scenario");
    let kind = TaskKind::parse(task).expect("task");
    Batch::new(kind, cfg, n, ActionType::Wheels, Some(2), true).expect("batch")
}

fn batch(task: &str, overrides: &str, n: usize) -> Batch {
    batch_in(task, overrides, n, None)
}

/// Actions biased forward, so that robots hit walls, obstacles and each other.
fn actions(seed: u64, n: usize, steps: usize) -> Vec<Vec<f32>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..steps)
        .map(|_| (0..n).map(|_| rng.random_range(-0.3..1.0)).collect())
        .collect()
}

/// Observations, rewards, end flags, poses and episode statistics of every step, as bits; and the
/// number of steps in which some robot was in contact.
fn replay(batch: &mut Batch, actions: &[Vec<f32>]) -> (Vec<Vec<u32>>, usize) {
    let mut trace = Vec::new();
    let mut contacts = 0;
    for a in actions {
        batch.step(a).expect("step");
        let mut bits: Vec<u32> = batch.obs().iter().map(|x| x.to_bits()).collect();
        for o in batch.outcomes() {
            bits.extend([o.reward.to_bits(), o.terminated as u32, o.truncated as u32]);
        }
        for env in batch.envs() {
            for robot in &env.world.robots {
                bits.extend([
                    robot.position.x.to_bits(),
                    robot.position.y.to_bits(),
                    robot.heading.to_bits(),
                ]);
            }
            // The episode statistics, the world's and each agent's.
            let world = [&env.stats, &env.last_episode];
            for stats in world {
                bits.extend([stats.ret.to_bits(), stats.length, stats.success as u32]);
            }
            for agent in env.agent_stats.iter().chain(&env.last_agent_episodes) {
                bits.extend([
                    agent.ret.to_bits(),
                    agent.length,
                    agent.success as u32,
                    agent.path_length.to_bits(),
                    agent.collisions,
                    agent.done as u32,
                ]);
            }
        }
        contacts += batch
            .envs()
            .iter()
            .filter(|e| e.world.robots.iter().any(|r| r.in_contact))
            .count();
        trace.push(bits);
    }
    (trace, contacts)
}

fn check_replay(task: &str, overrides: &str, version: Option<u32>) {
    check_replay_after(task, overrides, version, 150);
}

/// [`check_replay`] with the state saved after `warm_up` steps (0: right after the reset, before
/// any world has met anything, so before a world builds its rapier side).
fn check_replay_after(task: &str, overrides: &str, version: Option<u32>, warm_up: usize) {
    let name = format!("{task} v{version:?} saved after {warm_up} steps");
    let n = 6;
    let mut original = batch_in(task, overrides, n, version);
    let act_dim = original.act_dim() * n;
    original.reset(Some(7));
    replay(&mut original, &actions(1, act_dim, warm_up));
    let state = original.save_state().expect("save");
    let later = actions(2, act_dim, 400);
    let (expected, contacts) = replay(&mut original, &later);
    assert!(contacts > 0, "{name}: the replay should include contacts");

    original
        .load_state(&state)
        .expect("load into the same batch");
    let (again, _) = replay(&mut original, &later);
    assert!(again == expected, "{name}: restored batch diverged");

    let mut fresh = batch_in(task, overrides, n, version);
    fresh.load_state(&state).expect("load into a fresh batch");
    assert_eq!(fresh.save_state().expect("save"), state);
    let (fresh_trace, _) = replay(&mut fresh, &later);
    assert!(fresh_trace == expected, "{name}: fresh batch diverged");
}

/// Overrides of a task's replay beyond `max_steps = 120` (every task not listed replays with that
/// alone), so that it crosses episode ends and contacts and draws its random parts at each
/// reset. Names are checked against the registry.
const REPLAY_OVERRIDES: &[(&str, &str)] = &[
    // Random obstacles are re-drawn every episode: the restored scene must be the saved one.
    ("avoid", "max_steps = 90"),
    // A spline reference (drawn at each reset) and a wide lost bound, so robots reach the walls.
    (
        "track",
        "max_steps = 120\nreference = \"spline\"\nlost_distance = 3.0",
    ),
    // A spline path with obstacles on it (both drawn at each reset) and a wide lost bound.
    (
        "pathfollow",
        "max_steps = 120\npath = \"spline\"\nobstacle_count = 3\nlost_distance = 0.5",
    ),
    // Three robots on a spline, lost robots parked: the per-robot tracking state is restored.
    (
        "platoon",
        "max_steps = 120\nreference = \"spline\"\nlost_distance = 0.3",
    ),
    // The Khepera driven by an agent too (random actions reach the walls), the drone's lost
    // time long enough for episodes to run on.
    ("dronefollow", "max_steps = 120\ndriver = \"agent\""),
    // A robot is lost 0.1 m off the line by default, long before it reaches a wall.
    ("linefollow", "max_steps = 120\nlost_distance = 3.0"),
];

#[test]
fn test_replay_overrides_name_registered_tasks() {
    for (task, _) in REPLAY_OVERRIDES {
        assert!(TaskKind::parse(task).is_some(), "{task} is not a task");
    }
}

#[test]
fn test_every_task_and_version_restored_state_replays_bit_for_bit() {
    for (kind, version) in every_task_version() {
        let overrides = REPLAY_OVERRIDES
            .iter()
            .find(|(task, _)| *task == kind.name())
            .map_or("max_steps = 120", |(_, o)| o);
        check_replay(kind.name(), overrides, Some(version));
    }
}

#[test]
fn test_a_state_saved_before_any_contact_replays_bit_for_bit() {
    // A world builds its rapier side at the first substep that needs it; one saved before then
    // is saved as the world it would build, and must go on as the unsaved one does.
    for (kind, version) in every_task_version() {
        let overrides = REPLAY_OVERRIDES
            .iter()
            .find(|(task, _)| *task == kind.name())
            .map_or("max_steps = 120", |(_, o)| o);
        check_replay_after(kind.name(), overrides, Some(version), 0);
    }
}

#[test]
fn test_state_restores_randomised_robot_parameters() {
    // Domain randomisation draws the drive at every reset: a restored world keeps the saved draw.
    check_replay(
        "nav",
        "max_steps = 50\nrobot.axle_length = [0.09, 0.12]",
        None,
    );
}

fn load_error(target: &mut Batch, state: &[u8]) -> String {
    let before = target.save_state().expect("save");
    let message = match target.load_state(state) {
        Err(Error::SavedState(message)) => message,
        other => panic!("expected a state error, got {other:?}"),
    };
    assert_eq!(
        target.save_state().expect("save"),
        before,
        "a refused load changed the batch"
    );
    message
}

#[test]
fn test_foreign_or_corrupt_states_are_refused_and_change_nothing() {
    let mut nav = batch("nav", "", 4);
    nav.reset(Some(3));
    let state = nav.save_state().expect("save");

    let mut target = batch("nav", "", 4);
    target.reset(Some(11));
    assert!(load_error(&mut target, b"hello").contains("not a khepera_gym state"));
    assert!(load_error(&mut target, &state[..state.len() - 10]).contains("corrupt"));
    let mut flipped = state.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x40;
    assert!(load_error(&mut target, &flipped).contains("checksum"));

    let mut avoid = batch("avoid", "", 4);
    assert!(load_error(&mut avoid, &state).contains("\"nav\""));
    let mut eight = batch("nav", "", 8);
    assert!(load_error(&mut eight, &state).contains("4 worlds"));
    let mut other = batch("nav", "goal_radius = 0.2", 4);
    let message = load_error(&mut other, &state);
    assert!(message.contains("goal_radius"), "{message}");
}

#[test]
fn test_state_does_not_grow_with_episodes() {
    // Random obstacles rebuild the scene at every reset; the world must not keep what the
    // previous episodes had (rapier's pending removals grew by ~35 bytes per episode before).
    let mut avoid = batch("avoid", "max_steps = 2", 2);
    avoid.reset(Some(0));
    let actions = vec![0.5f32; avoid.len() * avoid.act_dim()];
    for _ in 0..20 {
        avoid.step(&actions).expect("step");
    }
    let early = avoid.save_state().expect("save").len();
    for _ in 0..2000 {
        avoid.step(&actions).expect("step");
    }
    let late = avoid.save_state().expect("save").len();
    assert!(
        late <= early + 1024,
        "state grew from {early} to {late} bytes over 1000 episodes"
    );
}
