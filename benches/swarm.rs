//! Throughput of one world of many robots (the swarm scale of issue 16): world-steps/s and
//! robot-steps/s of MultiNav worlds of 4 to 1,024 robots with IR, sonar and contacts, in arenas
//! scaled to keep the same density. `cargo bench --bench swarm` prints figures, asserts nothing.
//! `cargo bench --bench swarm -- 1000` runs only that robot count.

use std::time::Instant;

use _core::batch::Batch;
use _core::robot::ActionType;
use _core::scenario::Source;
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use rand::{Rng, SeedableRng};

fn main() {
    let only: Option<usize> = std::env::args().skip(1).find_map(|a| a.parse().ok());
    let threads: usize = std::env::var("SWARM_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(2);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    for robots in [4usize, 16, 32, 100, 300, 1000] {
        if only.is_some_and(|n| n != robots) {
            continue;
        }
        // 4 robots in the default 2 m × 2 m arena; the side grows with √robots.
        let side = 2.0 * (robots as f32 / 4.0).sqrt();
        let worlds = (1024 / robots).max(1);
        let text =
            format!("n_robots = {robots}\nwidth = {side}\nheight = {side}\nmax_steps = 100000");
        let source = Source {
            overrides: text.parse().expect("toml"),
            ..Default::default()
        };
        let cfg = load_scenario("multinav", &source).expect("scenario");
        let mut batch = Batch::new(
            TaskKind::MultiNav,
            cfg,
            worlds,
            ActionType::Wheels,
            Some(threads),
            true,
        )
        .expect("batch");
        batch.reset(Some(0));
        let actions: Vec<Vec<f32>> = (0..16)
            .map(|_| {
                (0..worlds * batch.act_dim())
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect()
            })
            .collect();
        for a in actions.iter().take(5) {
            batch.step(a).expect("step");
        }
        let start = Instant::now();
        let mut steps = 0usize;
        while start.elapsed().as_secs_f64() < 3.0 {
            batch.step(&actions[steps % actions.len()]).expect("step");
            steps += 1;
        }
        let world_steps = (steps * worlds) as f64 / start.elapsed().as_secs_f64();
        println!(
            "robots {robots:5}  worlds {worlds:4}  threads {threads}  {world_steps:10.0} world-steps/s  \
             {:10.0} robot-steps/s  {:8.1}x real time",
            world_steps * robots as f64,
            world_steps / worlds as f64 * 0.05
        );
    }
}
