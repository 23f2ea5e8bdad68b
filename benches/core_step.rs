//! Throughput of the Rust core alone (no Python): env-steps/s of a Nav batch with random
//! actions, per thread count. `cargo bench --bench core_step` (prints figures, asserts nothing).

use std::time::Instant;

use _core::batch::Batch;
use _core::robot::ActionType;
use _core::scenario::{Scenario, Source};
use _core::tasks::TaskKind;
use rand::{Rng, SeedableRng};

fn main() {
    let cfg = Scenario::load("nav", &Source::default()).expect("nav scenario");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    for (n, threads) in [(1024usize, 1usize), (1024, 2), (4096, 2)] {
        let mut batch = Batch::new(
            TaskKind::Nav,
            cfg.clone(),
            n,
            ActionType::Wheels,
            Some(threads),
            true,
        )
        .expect("batch");
        batch.reset(Some(0));
        let actions: Vec<Vec<f32>> = (0..64)
            .map(|_| (0..2 * n).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect();
        for a in actions.iter().take(10) {
            batch.step(a).expect("step");
        }
        let start = Instant::now();
        let mut steps = 0usize;
        while start.elapsed().as_secs_f64() < 2.0 {
            batch.step(&actions[steps % actions.len()]).expect("step");
            steps += 1;
        }
        let rate = (steps * n) as f64 / start.elapsed().as_secs_f64();
        println!("nav  worlds {n:5}  threads {threads}  {rate:12.0} env-steps/s");
    }
}
