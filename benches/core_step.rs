//! Throughput of the Rust core alone (no Python): env-steps/s of each task's batch with random
//! actions, per thread count. `cargo bench --bench core_step` prints figures and asserts nothing.
//! `cargo bench --bench core_step -- nav` runs only the tasks whose name contains "nav";
//! `CORE_STEP_VERSION=0` measures behaviour version 0's defaults (the latest otherwise);
//! `CORE_STEP_OVERRIDES='substeps = 8'` overrides scenario keys (TOML);
//! `KHEPERA_GYM_SIMD=portable` (or `avx2`, `avx512`) runs the kernels on that vector path (the
//! widest this CPU has otherwise). The path is printed first.

use std::time::Instant;

use _core::batch::Batch;
use _core::robot::ActionType;
use _core::scenario::Source;
use _core::simd;
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use rand::{Rng, SeedableRng};

fn main() {
    // `core_step avoid 256 1` runs only matching cases (task name, worlds, threads).
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let filter = args.first().cloned();
    let only_n: Option<usize> = args.get(1).and_then(|a| a.parse().ok());
    let only_t: Option<usize> = args.get(2).and_then(|a| a.parse().ok());
    if let Ok(name) = std::env::var("KHEPERA_GYM_SIMD") {
        let path = simd::Path::parse(&name).expect("KHEPERA_GYM_SIMD");
        simd::force(path).expect("KHEPERA_GYM_SIMD");
    }
    println!("vector path: {}", simd::path().name());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let cases = [
        (TaskKind::Nav, 256usize, 1usize),
        (TaskKind::Nav, 1024, 1),
        (TaskKind::Nav, 1024, 2),
        (TaskKind::Nav, 4096, 2),
        (TaskKind::Avoid, 256, 1),
        (TaskKind::Avoid, 1024, 1),
        (TaskKind::Avoid, 1024, 2),
        (TaskKind::Formation, 256, 1),
        (TaskKind::Formation, 1024, 1),
        (TaskKind::Formation, 1024, 2),
        (TaskKind::MultiNav, 1024, 2),
    ];
    for (kind, n, threads) in cases {
        if filter.as_deref().is_some_and(|f| !kind.name().contains(f))
            || only_n.is_some_and(|x| x != n)
            || only_t.is_some_and(|x| x != threads)
        {
            continue;
        }
        let version = std::env::var("CORE_STEP_VERSION")
            .ok()
            .and_then(|v| v.parse().ok());
        let overrides = std::env::var("CORE_STEP_OVERRIDES")
            .ok()
            .map(|t| t.parse().expect("CORE_STEP_OVERRIDES is TOML"))
            .unwrap_or_default();
        let source = Source {
            version,
            overrides,
            ..Default::default()
        };
        let cfg = load_scenario(kind.name(), &source).expect("scenario");
        let mut batch =
            Batch::new(kind, cfg, n, ActionType::Wheels, Some(threads), true).expect("batch");
        let robots = batch.envs()[0].world.robots.len();
        batch.reset(Some(0));
        let actions: Vec<Vec<f32>> = (0..64)
            .map(|_| {
                (0..n * batch.act_dim())
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect()
            })
            .collect();
        for a in actions.iter().take(10) {
            batch.step(a).expect("step");
        }
        // KG_BENCH_STEPS=k runs exactly k steps (for instruction counts under valgrind).
        let fixed: Option<usize> = std::env::var("KG_BENCH_STEPS")
            .ok()
            .and_then(|v| v.parse().ok());
        let start = Instant::now();
        let mut steps = 0usize;
        while fixed.map_or(start.elapsed().as_secs_f64() < 2.0, |k| steps < k) {
            batch.step(&actions[steps % actions.len()]).expect("step");
            steps += 1;
        }
        let rate = (steps * n) as f64 / start.elapsed().as_secs_f64();
        println!(
            "{:10} robots {robots}  worlds {n:5}  threads {threads}  {rate:12.0} env-steps/s  \
             {:12.0} robot-steps/s",
            kind.name(),
            rate * robots as f64
        );
    }
}
