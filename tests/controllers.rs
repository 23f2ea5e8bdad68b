//! Baseline controllers on observations (paper eqs. 1–12): position control reaches its goal,
//! Braitenberg and VFH get past the paper's Fig. 6 wall and box, VFH reaches most Nav goals,
//! Braitenberg handles random obstacles, leader–follower holds the formation; batched and single
//! actions agree.

use _core::batch::Batch;
use _core::controllers::Policy;
use _core::robot::ActionType;
use _core::scenario::{self, Source};
use _core::tasks::load_scenario;
use _core::tasks::{EpisodeStats, TaskKind};

/// Controller `name` with `params` (TOML), reading the first agent's observation of `task`'s
/// default scenario.
fn policy(name: &str, params: &str, task: TaskKind) -> Policy {
    let cfg = task.scenario(&Source::default()).expect("scenario");
    let layout = task.agents(&cfg).expect("agents").remove(0).layout;
    Policy::new(name, &params.parse().expect("params"), &layout).expect("policy")
}

fn position_control() -> Policy {
    policy(
        "position_control",
        "vmax = 0.3\nwmax = 4.0\nkr = 0.15\nstop_radius = 0.02",
        TaskKind::Nav,
    )
}

fn braitenberg() -> Policy {
    policy("braitenberg", "", TaskKind::Nav)
}

fn vfh() -> Policy {
    policy("vfh", "", TaskKind::Nav)
}

/// Runs `n` worlds (seeds `seed + i`) of `task` for one episode each under `policy`.
fn episodes(task: TaskKind, scene: Option<&str>, policy: &Policy, n: usize) -> Vec<EpisodeStats> {
    let source = Source {
        file: scene.map(|s| (scenario::scene(s).expect("scene"), s)),
        overrides: Default::default(),
        // The paper's controllers with its gains, on the dynamics they were tuned for (v0:
        // wheels at their command within a step, frictionless contacts); the README's tables
        // give their rates on v1.
        version: Some(0),
    };
    let cfg = load_scenario(task.name(), &source).expect("scenario");
    let mut batch = Batch::new(task, cfg, n, ActionType::Wheels, Some(2), true).expect("batch");
    batch.reset(Some(1000));
    let mut result: Vec<Option<EpisodeStats>> = vec![None; n];
    while result.iter().any(Option::is_none) {
        let actions = policy
            .act_batch(batch.obs(), batch.obs_dim())
            .expect("actions");
        batch.step(&actions).expect("step");
        let ended: Vec<bool> = batch
            .outcomes()
            .iter()
            .map(|o| o.terminated || o.truncated)
            .collect();
        for (i, (stats, end)) in batch.episode_stats().zip(ended).enumerate() {
            if end && result[i].is_none() {
                result[i] = Some(*stats);
            }
        }
    }
    result.into_iter().flatten().collect()
}

fn success_rate(stats: &[EpisodeStats]) -> f64 {
    stats.iter().filter(|s| s.success).count() as f64 / stats.len() as f64
}

#[test]
fn test_position_control_reaches_goal_in_nav() {
    let stats = episodes(TaskKind::Nav, None, &position_control(), 200);
    assert!(
        success_rate(&stats) >= 0.99,
        "success {}",
        success_rate(&stats)
    );
}

#[test]
fn test_braitenberg_and_vfh_reach_target_past_fig6_wall_and_box() {
    let (braitenberg, vfh, position_only) = (braitenberg(), vfh(), position_control());
    let b = episodes(TaskKind::Avoid, Some("paper_fig6"), &braitenberg, 1)[0];
    let p = episodes(TaskKind::Avoid, Some("paper_fig6"), &position_only, 1)[0];
    assert!(b.success, "Braitenberg {b:?}");
    assert!(
        !p.success,
        "the wall should stop plain position control: {p:?}"
    );
    // 20 worlds from the same start pose: only the sensor noise differs.
    let v = episodes(TaskKind::Avoid, Some("paper_fig6"), &vfh, 20);
    let reached = v.iter().filter(|s| s.success).count();
    assert!(
        reached >= 18,
        "VFH reached the target in {reached} of 20: {v:?}"
    );
}

#[test]
fn test_braitenberg_succeeds_among_random_obstacles() {
    let stats = episodes(TaskKind::Avoid, None, &braitenberg(), 200);
    assert!(
        success_rate(&stats) >= 0.9,
        "success {}",
        success_rate(&stats)
    );
}

#[test]
fn test_leader_follower_keeps_formation_error_small_without_obstacles() {
    // Eq. 12 offsets of the default cross, computed by the controller from the leader's pose.
    let offsets = [0.0f32, 90.0, 180.0, 270.0]
        .map(|b| format!("[0.5, {}]", b.to_radians()))
        .join(", ");
    let policy = policy(
        "leader_follower",
        &format!(
            "offsets = [{offsets}]\nvmax = 0.35\nwmax = 4.0\nkr = 0.08\nstop_radius = 0.005\n\
             feedforward = true\navoidance = true"
        ),
        TaskKind::Formation,
    )
    .with_leader(position_control())
    .expect("leader");
    let stats = episodes(TaskKind::Formation, None, &policy, 50);
    let at = TaskKind::Formation
        .extra_stats()
        .iter()
        .position(|n| *n == "formation_error_mean")
        .expect("formation_error_mean");
    let mean = stats.iter().map(|s| s.extra[at]).sum::<f32>() / stats.len() as f32;
    assert!(mean < 0.1, "mean formation error {mean}");
    assert!(success_rate(&stats) >= 0.95);
}

#[test]
fn test_vfh_reaches_most_nav_goals_in_an_empty_arena() {
    let stats = episodes(TaskKind::Nav, None, &vfh(), 200);
    assert!(
        success_rate(&stats) >= 0.85,
        "success {}",
        success_rate(&stats)
    );
}

#[test]
fn test_batched_and_single_actions_agree() {
    let cfg = load_scenario("avoid", &Source::default()).expect("scenario");
    let mut batch =
        Batch::new(TaskKind::Avoid, cfg, 16, ActionType::Wheels, Some(1), true).expect("b");
    batch.reset(Some(4));
    let policies = [position_control(), braitenberg(), vfh()];
    for policy in &policies {
        let d = batch.obs_dim();
        let all = policy.act_batch(batch.obs(), d).expect("batched");
        for i in 0..16 {
            let one = policy
                .act_batch(&batch.obs()[i * d..(i + 1) * d], d)
                .expect("single");
            assert_eq!(&all[2 * i..2 * i + 2], &one[..]);
        }
    }
    assert!(policies[0].act_batch(&[f32::NAN; 18], 18).is_err());
    assert!(policies[0].act_batch(&[0.0; 23], 23).is_err());
}
