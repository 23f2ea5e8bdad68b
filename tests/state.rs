//! Saved states: restoring a batch's state and replaying the same actions reproduces the
//! trajectory bit for bit (contacts included), in the same batch or a fresh one; a state that is
//! not one, is corrupt, or comes from another batch is refused with a message saying which, and
//! leaves the batch as it was.

use _core::batch::Batch;
use _core::error::Error;
use _core::robot::ActionType;
use _core::scenario::Source;
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use rand::{Rng, SeedableRng};

fn batch(task: &str, overrides: &str, n: usize) -> Batch {
    let source = Source {
        file: None,
        overrides: overrides.parse().expect("overrides"),
        ..Default::default()
    };
    let cfg = load_scenario(task, &source).expect("scenario");
    let kind = TaskKind::parse(task).expect("task");
    Batch::new(kind, cfg, n, ActionType::Wheels, Some(2), true).expect("batch")
}

/// Actions biased forward, so that robots hit walls, obstacles and each other.
fn actions(seed: u64, n: usize, steps: usize) -> Vec<Vec<f32>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..steps)
        .map(|_| (0..n).map(|_| rng.random_range(-0.3..1.0)).collect())
        .collect()
}

/// Observations, rewards and end flags of every step, as bits; and the number of steps in which
/// some robot was in contact.
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

fn check_replay(task: &str, overrides: &str) {
    let n = 6;
    let mut original = batch(task, overrides, n);
    let act_dim = original.act_dim() * n;
    original.reset(Some(7));
    replay(&mut original, &actions(1, act_dim, 150));
    let state = original.save_state().expect("save");
    let later = actions(2, act_dim, 400);
    let (expected, contacts) = replay(&mut original, &later);
    assert!(contacts > 0, "{task}: the replay should include contacts");

    original
        .load_state(&state)
        .expect("load into the same batch");
    let (again, _) = replay(&mut original, &later);
    assert!(again == expected, "{task}: restored batch diverged");

    let mut fresh = batch(task, overrides, n);
    fresh.load_state(&state).expect("load into a fresh batch");
    assert_eq!(fresh.save_state().expect("save"), state);
    let (fresh_trace, _) = replay(&mut fresh, &later);
    assert!(fresh_trace == expected, "{task}: fresh batch diverged");
}

#[test]
fn test_restored_nav_state_replays_bit_for_bit() {
    check_replay("nav", "max_steps = 120");
}

#[test]
fn test_restored_avoid_state_replays_bit_for_bit_through_contacts() {
    // Random obstacles are re-drawn every episode: the restored scene must be the saved one.
    check_replay("avoid", "max_steps = 90");
}

#[test]
fn test_restored_formation_state_replays_bit_for_bit() {
    check_replay("formation", "max_steps = 120");
}

#[test]
fn test_restored_multinav_state_replays_bit_for_bit() {
    check_replay("multinav", "max_steps = 120");
}

#[test]
fn test_restored_track_state_replays_bit_for_bit() {
    // A spline reference (drawn at each reset) and a wide lost bound, so robots reach the walls.
    check_replay(
        "track",
        "max_steps = 120\nreference = \"spline\"\nlost_distance = 3.0",
    );
}

#[test]
fn test_restored_pathfollow_state_replays_bit_for_bit() {
    // A spline path with obstacles on it (both drawn at each reset) and a wide lost bound.
    check_replay(
        "pathfollow",
        "max_steps = 120\npath = \"spline\"\nobstacle_count = 3\nlost_distance = 0.5",
    );
}

#[test]
fn test_restored_platoon_state_replays_bit_for_bit() {
    // Three robots on a spline, lost robots parked: the per-robot tracking state is restored.
    check_replay(
        "platoon",
        "max_steps = 120\nreference = \"spline\"\nlost_distance = 0.3",
    );
}

#[test]
fn test_state_restores_randomised_robot_parameters() {
    // Domain randomisation draws the drive at every reset: a restored world keeps the saved draw.
    check_replay("nav", "max_steps = 50\nrobot.axle_length = [0.09, 0.12]");
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
