//! Determinism specification, for every task and behaviour version of the registry
//! ([`common::every_task_version`]: a new task or version is covered without touching this
//! file): world i of a batch reset with seed s is bit-for-bit a single environment reset with
//! seed s + i, across autoresets; and a batch gives the same results, episode statistics
//! included, at any thread count.

mod common;

use _core::batch::Batch;
use _core::robot::ActionType;
use _core::scenario::{Scenario, Source};
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use common::{every_task_version, scenario_in};
use rand::{Rng, SeedableRng};

/// Nav with short episodes (the tests of seeding itself).
fn scenario() -> Scenario {
    let source = Source {
        file: None,
        overrides: "max_steps = 60".parse().expect("overrides"),
        ..Default::default()
    };
    load_scenario("nav", &source).expect("scenario")
}

/// `steps` joint actions of `len` values, uniform in [-1, 1), from `seed`.
fn random_actions(len: usize, steps: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..steps)
        .map(|_| (0..len).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect()
}

/// A batch of `n` worlds of `kind` on `threads` threads, with autoreset.
fn batch(kind: TaskKind, cfg: &Scenario, n: usize, threads: usize) -> Batch {
    Batch::new(
        kind,
        cfg.clone(),
        n,
        ActionType::Wheels,
        Some(threads),
        true,
    )
    .expect("batch")
}

/// Observations, rewards (as bits) and end flags of every step.
type Trace = Vec<(Vec<f32>, Vec<u32>, Vec<bool>)>;

fn run(batch: &mut Batch, actions: &[Vec<f32>]) -> Trace {
    actions
        .iter()
        .map(|a| {
            batch.step(a).expect("step");
            let o = batch.outcomes();
            (
                batch.obs().to_vec(),
                o.iter().map(|x| x.reward.to_bits()).collect(),
                o.iter().map(|x| x.terminated || x.truncated).collect(),
            )
        })
        .collect()
}

#[test]
fn test_every_task_and_version_world_equals_single_env_with_seed_plus_index() {
    let (n, steps, seed) = (4, 120, 1234u64);
    for (kind, version) in every_task_version() {
        let name = format!("{} v{version}", kind.name());
        let cfg = scenario_in(kind.name(), "max_steps = 40", version);
        let mut worlds = batch(kind, &cfg, n, 2);
        let (od, ad) = (worlds.obs_dim(), worlds.act_dim());
        let acts = random_actions(n * ad, steps, 5);
        worlds.reset(Some(seed));
        let first = worlds.obs().to_vec();
        let trace = run(&mut worlds, &acts);
        let mut ended = 0;
        for i in 0..n {
            let mut single = batch(kind, &cfg, 1, 1);
            single.reset(Some(seed + i as u64));
            assert_eq!(
                single.obs(),
                &first[i * od..(i + 1) * od],
                "{name} world {i} reset"
            );
            for (t, a) in acts.iter().enumerate() {
                single.step(&a[i * ad..(i + 1) * ad]).expect("step");
                let (obs, rewards, done) = &trace[t];
                assert_eq!(
                    single.obs(),
                    &obs[i * od..(i + 1) * od],
                    "{name} world {i} step {t}"
                );
                assert_eq!(
                    single.outcomes()[0].reward.to_bits(),
                    rewards[i],
                    "{name} world {i} step {t}"
                );
                ended += done[i] as usize;
            }
        }
        assert!(
            ended >= n * 2,
            "{name}: too few episode ends ({ended}) to cover autoreset"
        );
    }
}

#[test]
fn test_every_task_and_version_is_identical_at_one_and_two_threads() {
    let (n, steps) = (32, 100);
    for (kind, version) in every_task_version() {
        let cfg = scenario_in(kind.name(), "max_steps = 50", version);
        let mut runs = Vec::new();
        for threads in [1, 2] {
            let mut worlds = batch(kind, &cfg, n, threads);
            let acts = random_actions(n * worlds.act_dim(), steps, 9);
            worlds.reset(Some(3));
            let mut trace = Vec::new();
            for a in &acts {
                worlds.step(a).expect("step");
                let stats: Vec<_> = worlds.episode_stats().copied().collect();
                let agents: Vec<_> = worlds
                    .envs()
                    .iter()
                    .map(|e| e.last_agent_episodes.clone())
                    .collect();
                trace.push((
                    worlds.obs().to_vec(),
                    worlds.outcomes().to_vec(),
                    stats,
                    agents,
                ));
            }
            runs.push(trace);
        }
        assert!(
            runs[0] == runs[1],
            "{} v{version} differs between 1 and 2 threads",
            kind.name()
        );
    }
}

#[test]
fn test_reset_none_continues_streams_and_seed_repeats() {
    let mut batch = batch(TaskKind::Nav, &scenario(), 4, 1);
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
    let mut batch = batch(TaskKind::Nav, &scenario(), 2, 1);
    batch.reset(Some(0));
    let before = batch.obs().to_vec();
    assert!(batch.step(&[0.0, 0.0, f32::NAN, 0.0]).is_err());
    assert!(batch.step(&[0.0, 0.0, 0.0]).is_err());
    assert_eq!(batch.obs(), &before[..]);
}
