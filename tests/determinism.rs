//! Determinism specification: world i of a batch reset with seed s is bit-for-bit a single
//! environment reset with seed s + i, across autoresets; and a batch gives the same results at
//! any thread count.

use _core::batch::Batch;
use _core::robot::ActionType;
use _core::scenario::{Scenario, Source};
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use rand::{Rng, SeedableRng};

fn scenario() -> Scenario {
    let source = Source {
        file: None,
        overrides: "max_steps = 60".parse().expect("overrides"),
        ..Default::default()
    };
    load_scenario("nav", &source).expect("scenario")
}

fn actions(n: usize, steps: usize) -> Vec<Vec<f32>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
    (0..steps)
        .map(|_| (0..2 * n).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect()
}

fn run(batch: &mut Batch, actions: &[Vec<f32>]) -> Vec<(Vec<f32>, Vec<f32>, Vec<bool>)> {
    actions
        .iter()
        .map(|a| {
            batch.step(a).expect("step");
            let o = batch.outcomes();
            (
                batch.obs().to_vec(),
                o.iter().map(|x| x.reward).collect(),
                o.iter().map(|x| x.terminated || x.truncated).collect(),
            )
        })
        .collect()
}

#[test]
fn test_batch_world_equals_single_env_with_seed_plus_index() {
    let (n, steps, seed) = (8, 200, 1234u64);
    let acts = actions(n, steps);
    let mut batch = Batch::new(
        TaskKind::Nav,
        scenario(),
        n,
        ActionType::Wheels,
        Some(2),
        true,
    )
    .expect("batch");
    batch.reset(Some(seed));
    let first = batch.obs().to_vec();
    let trace = run(&mut batch, &acts);
    let mut ended = 0;
    for i in 0..n {
        let mut single = Batch::new(
            TaskKind::Nav,
            scenario(),
            1,
            ActionType::Wheels,
            Some(1),
            true,
        )
        .expect("single");
        single.reset(Some(seed + i as u64));
        assert_eq!(single.obs(), &first[i * 18..(i + 1) * 18]);
        for (t, a) in acts.iter().enumerate() {
            single.step(&a[2 * i..2 * i + 2]).expect("step");
            let (obs, rew, done) = &trace[t];
            assert_eq!(
                single.obs(),
                &obs[i * 18..(i + 1) * 18],
                "world {i} step {t}"
            );
            assert_eq!(single.outcomes()[0].reward.to_bits(), rew[i].to_bits());
            ended += done[i] as usize;
        }
    }
    assert!(
        ended >= n * 2,
        "too few episode ends ({ended}) to cover autoreset"
    );
}

#[test]
fn test_batch_is_identical_at_one_and_two_threads() {
    let (n, steps) = (64, 150);
    let acts = actions(n, steps);
    let mut results = Vec::new();
    for threads in [1, 2] {
        let mut batch = Batch::new(
            TaskKind::Nav,
            scenario(),
            n,
            ActionType::Wheels,
            Some(threads),
            true,
        )
        .expect("batch");
        batch.reset(Some(5));
        results.push(run(&mut batch, &acts));
    }
    assert!(results[0] == results[1]);
}

#[test]
fn test_reset_none_continues_streams_and_seed_repeats() {
    let mut batch = Batch::new(
        TaskKind::Nav,
        scenario(),
        4,
        ActionType::Wheels,
        Some(1),
        true,
    )
    .expect("b");
    batch.reset(Some(1));
    let a = batch.obs().to_vec();
    batch.reset(None);
    let b = batch.obs().to_vec();
    batch.reset(Some(1));
    let c = batch.obs().to_vec();
    assert_ne!(a, b);
    assert_eq!(a, c);
}

#[test]
fn test_bad_actions_change_nothing() {
    let mut batch = Batch::new(
        TaskKind::Nav,
        scenario(),
        2,
        ActionType::Wheels,
        Some(1),
        true,
    )
    .expect("b");
    batch.reset(Some(0));
    let before = batch.obs().to_vec();
    assert!(batch.step(&[0.0, 0.0, f32::NAN, 0.0]).is_err());
    assert!(batch.step(&[0.0, 0.0, 0.0]).is_err());
    assert_eq!(batch.obs(), &before[..]);
}
