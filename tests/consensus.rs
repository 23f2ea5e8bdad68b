//! consensus_v1 specification (issue 16, item 3): the consensus law converges on connected
//! graphs and not across a disconnected one (each component keeps its own average); the
//! event-triggered trigger sends fewer messages than the periodic one for the same final error
//! bound; messages arrive after their delay and are dropped at their rate, reproducibly per seed;
//! the geometric graph links exactly the robots within range; bad keys are config errors naming
//! them. Thresholds come from the message model and consensus theory (Olfati-Saber & Murray
//! 2004; Dimarogonas et al. 2012), not from runs.
//!
//! Units: metres, seconds; per agent the observation is ir (8), us (5), neighbours (4 per other
//! robot: p_x, p_y, age, valid), own_drift (2), wheel_speeds (2).

use crate::common;

use _core::controllers::Policy;
use _core::error::Error;
use _core::scenario::{Scenario, Source};
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use rapier2d::math::Vector;

const DT: f32 = 0.05;
const TOLERANCE: f32 = 0.03;

fn scenario(overrides: &str) -> Scenario {
    common::scenario("consensus", overrides)
}

fn env(overrides: &str, seed: u64) -> (Env, Vec<f32>) {
    common::env(TaskKind::Consensus, scenario(overrides), seed)
}

fn law(cfg: &Scenario, params: &str) -> Policy {
    let layout = TaskKind::Consensus
        .agents(cfg)
        .expect("agents")
        .remove(0)
        .layout;
    Policy::new("consensus", &params.parse().expect("params"), &layout).expect("policy")
}

/// Runs one episode with the law on every agent; returns its extra statistics by name.
fn episode(overrides: &str, params: &str, seed: u64) -> Vec<(&'static str, f32)> {
    let (mut env, mut obs) = env(overrides, seed);
    let policy = law(&env.cfg, params);
    let per_agent = policy.obs_dim();
    while !env.done {
        let action = policy.act_batch(&obs, per_agent).expect("act");
        env.step(&action, &mut obs);
    }
    env.extra_stats(&env.last_episode)
}

fn stat(stats: &[(&str, f32)], name: &str) -> f32 {
    stats.iter().find(|(n, _)| *n == name).expect("stat").1
}

#[test]
fn test_the_law_converges_on_connected_graphs() {
    // Connected graphs: the disagreement of the displacements goes to zero (Olfati-Saber &
    // Murray 2004, Thm. 1); within the 30 s episode it must fall below the task's tolerance.
    for graph in ["ring", "line", "complete"] {
        for seed in 0..6 {
            let stats = episode(&format!("graph = \"{graph}\""), "", seed);
            let error = stat(&stats, "consensus_error_final");
            assert!(
                error < TOLERANCE,
                "{graph}, seed {seed}: final error {error} m"
            );
            assert!(stat(&stats, "consensus_converge_time").is_finite());
        }
    }
}

#[test]
fn test_the_law_does_not_converge_across_a_disconnected_graph() {
    // Two components {0, 1} and {2, 3}: the symmetric law keeps each component's mean of
    // z_i = x_i − c_i, so the final error is half the distance between the two initial means,
    // whatever the controller does inside each component.
    // The unicycles' share is measured on v1's drive (within a quarter); v2's faster drive turns
    // the robots sharper and moves the means by up to 30 %: there, only the non-convergence is
    // asserted (below).
    let overrides = "graph = \"edges\"\nedges = [[0, 1], [2, 3]]";
    for seed in 0..8 {
        let stats = episode(overrides, "", seed);
        let (env, _) = env(overrides, seed);
        let p: Vec<Vector> = env.world.robots.iter().map(|r| r.position).collect();
        let r = 0.3f32;
        let z = |i: usize| {
            let a = std::f32::consts::TAU * i as f32 / 4.0;
            p[i] - Vector::new(r * a.cos(), r * a.sin())
        };
        let predicted = ((z(0) + z(1)) * 0.5 - (z(2) + z(3)) * 0.5).length() * 0.5;
        if predicted > 2.0 * TOLERANCE {
            let error = stat(&stats, "consensus_error_final");
            assert!(
                error > TOLERANCE,
                "v2, seed {seed}: converged across components"
            );
        }
    }
    let mut far = 0;
    for seed in 0..8 {
        let cfg = common::scenario_in("consensus", overrides, 1);
        let (mut env, mut obs) = common::env(TaskKind::Consensus, cfg, seed);
        let cfg = env.cfg.clone();
        let r = 0.3f32;
        let offsets: Vec<Vector> = (0..4)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / 4.0;
                Vector::new(r * a.cos(), r * a.sin())
            })
            .collect();
        let z: Vec<Vector> = (0..4)
            .map(|i| env.world.robots[i].position - offsets[i])
            .collect();
        let predicted = ((z[0] + z[1]) * 0.5 - (z[2] + z[3]) * 0.5).length() * 0.5;
        let policy = law(&cfg, "");
        while !env.done {
            let action = policy.act_batch(&obs, policy.obs_dim()).expect("act");
            env.step(&action, &mut obs);
        }
        let error = stat(&env.extra_stats(&env.last_episode), "consensus_error_final");
        // The unicycles and the contacts move the means a little: within a quarter, or 3 cm.
        assert!(
            (error - predicted).abs() < (0.25 * predicted).max(TOLERANCE),
            "seed {seed}: final error {error}, components' means predict {predicted}"
        );
        if predicted > 2.0 * TOLERANCE {
            far += 1;
            assert!(
                error > TOLERANCE,
                "seed {seed}: converged across components"
            );
        }
    }
    assert!(far >= 4, "the seeds hardly tested anything: {far}");
}

#[test]
fn test_event_triggered_sends_fewer_messages_for_the_same_bound() {
    // Periodic broadcast every step sends 20 messages per robot per second (plus the reset's);
    // the event trigger sends only while a robot moves by more than the threshold, and its
    // final disagreement is bounded by about the threshold (Dimarogonas et al. 2012, Thm. 2):
    // both must end below the same bound, the tolerance.
    for seed in 0..6 {
        let periodic = episode("", "", seed);
        let event = episode("trigger = \"event\"\nthreshold = 0.02", "", seed);
        for (name, stats) in [("periodic", &periodic), ("event", &event)] {
            let error = stat(stats, "consensus_error_final");
            assert!(error < TOLERANCE, "{name}, seed {seed}: error {error}");
        }
        let (p, e) = (
            stat(&periodic, "messages_per_robot_s"),
            stat(&event, "messages_per_robot_s"),
        );
        let expected = (1.0 + 600.0) / 30.0;
        assert!(
            (p - expected).abs() < 1e-3,
            "periodic sent {p}/s, not {expected}"
        );
        assert!(
            e < 0.5 * p,
            "seed {seed}: event {e}/s against periodic {p}/s"
        );
    }
}

/// (age, valid) of every linked neighbour slot of every agent.
fn ages(obs: &[f32], per_agent: usize, n: usize) -> Vec<f32> {
    let mut out = Vec::new();
    for a in 0..n {
        let slots = &obs[a * per_agent + 13..a * per_agent + 13 + 4 * (n - 1)];
        for s in slots.chunks_exact(4) {
            if s[3] > 0.5 {
                out.push(s[2]);
            }
        }
    }
    out
}

#[test]
fn test_messages_arrive_after_their_delay_and_are_dropped_at_their_rate() {
    // Broadcasting every step, a message of age d·dt is the one sent d steps ago: with no drop
    // every linked slot shows exactly that age; with drop p it shows it with probability 1 − p
    // (else an older one), never a younger one.
    let delay = 4u32;
    for (drop, seed) in [(0.0f32, 3u64), (0.3, 3), (0.3, 4)] {
        let overrides = format!("drop = {drop}\ndelay_steps = {delay}\ngraph = \"complete\"");
        let (mut env, mut obs) = env(&overrides, seed);
        let policy = law(&env.cfg, "");
        let per_agent = policy.obs_dim();
        let (mut fresh, mut total) = (0usize, 0usize);
        for step in 0..400u32 {
            let action = policy.act_batch(&obs, per_agent).expect("act");
            env.step(&action, &mut obs);
            if step < delay + 1 {
                continue;
            }
            for age in ages(&obs, per_agent, 4) {
                assert!(age >= delay as f32 * DT - 1e-4, "age {age} below the delay");
                total += 1;
                if (age - delay as f32 * DT).abs() < 1e-4 {
                    fresh += 1;
                }
            }
        }
        let share = fresh as f32 / total as f32;
        // 12 slots × 395 steps: 3 standard deviations of a share near 0.7 are 0.013.
        assert!(
            (share - (1.0 - drop)).abs() < 0.03,
            "drop {drop}: {share} of the slots fresh"
        );
    }
    // Reproducible per seed, and the seed matters.
    let run = |seed: u64| {
        let (mut env, mut obs) = env("drop = 0.3\ndelay_steps = 2", seed);
        let policy = law(&env.cfg, "");
        let mut trace = Vec::new();
        for _ in 0..200 {
            let action = policy.act_batch(&obs, policy.obs_dim()).expect("act");
            env.step(&action, &mut obs);
            trace.extend(obs.iter().map(|v| v.to_bits()));
        }
        trace
    };
    assert_eq!(run(7), run(7));
    assert_ne!(run(7), run(8));
}

#[test]
fn test_the_geometric_graph_links_the_robots_within_range() {
    let range = 0.8f32;
    let n = 6usize;
    for seed in 0..5 {
        let (env, obs) = env(
            &format!("graph = \"geometric\"\nrange = {range}\nn_robots = 6"),
            seed,
        );
        let per_agent = obs.len() / n;
        for i in 0..n {
            for (slot, j) in (0..n).filter(|&j| j != i).enumerate() {
                let d = (env.world.robots[i].position - env.world.robots[j].position).length();
                let valid = obs[i * per_agent + 13 + 4 * slot + 3] > 0.5;
                assert_eq!(valid, d <= range, "seed {seed}: robots {i}, {j} at {d} m");
                if valid {
                    // At reset every robot broadcast its true position (ground truth): the slot
                    // is j's position plus the offsets' difference, in i's frame.
                    let p = [
                        obs[i * per_agent + 13 + 4 * slot],
                        obs[i * per_agent + 14 + 4 * slot],
                    ];
                    let a = std::f32::consts::TAU / n as f32;
                    let c =
                        |k: usize| 0.3 * Vector::new((a * k as f32).cos(), (a * k as f32).sin());
                    let expected =
                        env.world.robots[j].position - c(j) + c(i) - env.world.robots[i].position;
                    assert!((p[0].hypot(p[1]) - expected.length()).abs() < 1e-4);
                }
            }
        }
    }
}

#[test]
fn test_bad_keys_are_config_errors_naming_them() {
    let cases = [
        ("n_robots = 1", "consensus.n_robots"),
        ("n_robots = 33", "consensus.n_robots"),
        ("graph = \"star\"", "consensus.graph"),
        ("graph = \"edges\"", "consensus.edges"),
        ("graph = \"edges\"\nedges = [[0, 4]]", "consensus.edges"),
        ("graph = \"edges\"\nedges = [[1, 1]]", "consensus.edges"),
        ("edges = [[0, 1]]", "consensus.edges"),
        ("formation_radius = 0.08", "consensus.formation_radius"),
        ("formation_radius = 0.95", "consensus.formation_radius"),
        ("drop = 1.0", "consensus.drop"),
        ("delay_steps = 101", "consensus.delay_steps"),
        ("period = 0.0", "consensus.period"),
        ("threshold = -0.1", "consensus.threshold"),
        ("trigger = \"sometimes\"", "consensus.trigger"),
        ("range = 0.0", "consensus.range"),
    ];
    for (overrides, key) in cases {
        let source = Source {
            file: None,
            overrides: overrides.parse().expect("toml"),
            version: None,
        };
        match load_scenario("consensus", &source) {
            Err(Error::Config { key: k, .. }) => assert_eq!(k, key, "{overrides}"),
            other => panic!("{overrides}: expected a ConfigError on {key}, got {other:?}"),
        }
    }
}

#[test]
fn test_the_consensus_law_reads_slots_of_the_tasks_width() {
    // The law keeps its own slot width so that controllers need no task; it must be the task's.
    assert_eq!(
        _core::controllers::consensus::SLOT,
        _core::tasks::consensus::SLOT
    );
}
