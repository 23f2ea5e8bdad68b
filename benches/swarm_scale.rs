//! Throughput of one world of many robots (the swarm scale of issue 16): world-steps/s and
//! robot-steps/s of MultiNav worlds of 4 to 10,000 robots with IR, sonar and contacts, random
//! actions, in arenas scaled to keep multinav's density (4 robots in 2 m x 2 m), then the
//! built-in `swarm` scene (1,000 robots in 20 m x 20 m, 2.5 times as dense). Worlds per batch:
//! 1,024 robots' worth. `cargo bench --bench swarm_scale` prints figures and asserts nothing;
//! `-- 1000` runs only that robot count; `SWARM_THREADS=1` sets the threads (default 2). Every
//! size runs twice: `physics.split = "world"` (the default) and `"robot"` (rapier steps only the
//! robots that can touch something), small worlds too, since a ratio between a swarm split one
//! way and small worlds split the other means little; `SWARM_SPLIT=world` or `=robot` runs only
//! one. `SWARM_STEPS=40` times exactly that many steps instead of 3 s (for counting
//! instructions under `valgrind --tool=cachegrind`, whose figures do not swing with the load).

use std::time::Instant;

use _core::batch::Batch;
use _core::robot::ActionType;
use _core::scenario::{scene, Source};
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use rand::{Rng, SeedableRng};

fn main() {
    let only: Option<usize> = std::env::args().skip(1).find_map(|a| a.parse().ok());
    let threads: usize = std::env::var("SWARM_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(2);
    let only_split = std::env::var("SWARM_SPLIT").ok();
    let fixed_steps: Option<usize> = std::env::var("SWARM_STEPS")
        .ok()
        .and_then(|n| n.parse().ok());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let scaled = [4usize, 16, 32, 100, 300, 1000, 10000].map(|n| (n, false));
    let cases = scaled
        .into_iter()
        .chain([(1000, true)])
        .flat_map(|(robots, built_in)| {
            let splits: &[&str] = &["world", "robot"];
            splits.iter().map(move |&split| (robots, built_in, split))
        });
    for (robots, built_in, split) in cases {
        if only.is_some_and(|n| n != robots) || only_split.as_deref().is_some_and(|s| s != split) {
            continue;
        }
        // 4 robots in the default 2 m × 2 m arena; the side grows with √robots.
        let side = 2.0 * (robots as f32 / 4.0).sqrt();
        let worlds = (1024 / robots).max(1);
        let mut text = if built_in {
            "max_steps = 100000".to_string()
        } else {
            format!("n_robots = {robots}\nwidth = {side}\nheight = {side}\nmax_steps = 100000")
        };
        text.push_str(&format!("\n[physics]\nsplit = \"{split}\""));
        let source = Source {
            file: built_in.then(|| (scene("swarm").expect("built in"), "swarm")),
            overrides: text.parse().expect("toml"),
            ..Default::default()
        };
        let cfg = load_scenario("multinav", &source).expect("scenario");
        let kind = TaskKind::MultiNav;
        let mut batch =
            Batch::new(kind, cfg, worlds, ActionType::Wheels, Some(threads), true).expect("batch");
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
        while match fixed_steps {
            Some(n) => steps < n,
            None => start.elapsed().as_secs_f64() < 3.0,
        } {
            batch.step(&actions[steps % actions.len()]).expect("step");
            steps += 1;
        }
        let world_steps = (steps * worlds) as f64 / start.elapsed().as_secs_f64();
        println!(
            "{:6} robots {robots:5}  worlds {worlds:4}  threads {threads}  split {split:5}  {world_steps:8.0} \
             world-steps/s  {:9.0} robot-steps/s  {:5.1}x real time",
            if built_in { "swarm" } else { "scaled" },
            world_steps * robots as f64,
            world_steps / worlds as f64 * 0.05,
        );
    }
}
