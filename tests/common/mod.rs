//! Helpers the integration tests share: every task and behaviour version of the registry, a
//! task's scenario from TOML overrides (the latest defaults, or a version's), an env built from
//! it, seeded and reset, driving it with a constant action, and what a bad override's config
//! error names. Each test file uses some of them.
#![allow(dead_code)]

use std::sync::Arc;

use _core::error::Error;
use _core::robot::ActionType;
use _core::scenario::{Scenario, Source, LATEST_VERSION};
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};

/// Every task of the registry ([`TaskKind::ALL`]) with each of its behaviour versions (its
/// schema's `since` to [`LATEST_VERSION`]): what the cross-cutting tests run over, so that a new
/// task or version is covered without touching them.
pub fn every_task_version() -> Vec<(TaskKind, u32)> {
    TaskKind::ALL
        .iter()
        .flat_map(|&kind| (kind.info().schema.since..=LATEST_VERSION).map(move |v| (kind, v)))
        .collect()
}

/// No scenario file, these TOML overrides, the latest version.
pub fn source(overrides: &str) -> Source<'_> {
    Source {
        file: None,
        overrides: overrides.parse().expect("overrides"),
        version: None,
    }
}

/// `task`'s scenario (its built-in defaults) with `overrides` (TOML).
pub fn scenario(task: &str, overrides: &str) -> Scenario {
    load_scenario(task, &source(overrides)).expect("scenario")
}

/// [`scenario`] with behaviour `version`'s defaults (`Some(1)`: the v1 drive the tests of v1's
/// dynamics specify).
pub fn scenario_in(task: &str, overrides: &str, version: u32) -> Scenario {
    let source = Source {
        version: Some(version),
        ..source(overrides)
    };
    load_scenario(task, &source).expect("scenario")
}

/// An env of `kind` on `cfg` with wheel actions, as built (not seeded, not reset).
pub fn build(kind: TaskKind, cfg: Scenario) -> Env {
    let spawner = Arc::new(Env::spawner(kind, &cfg).expect("spawner"));
    Env::new(kind, Arc::new(cfg), spawner, ActionType::Wheels).expect("env")
}

/// [`build`], seeded with `seed` and reset; and its first observation.
pub fn env(kind: TaskKind, cfg: Scenario, seed: u64) -> (Env, Vec<f32>) {
    let mut env = build(kind, cfg);
    env.seed(seed);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut obs);
    (env, obs)
}

/// Steps `env` with a constant joint `action` for `steps` control steps, ignoring episode ends;
/// calls `each` after every step.
pub fn drive(env: &mut Env, action: &[f32], steps: usize, mut each: impl FnMut(&Env)) {
    let mut obs = vec![0.0; env.obs_dim()];
    for _ in 0..steps {
        env.step(action, &mut obs);
        env.done = false;
        each(env);
    }
}

/// The key and message of the config error `task`'s scenario with `overrides` must raise.
pub fn config_error(task: &str, overrides: &str) -> (String, String) {
    match load_scenario(task, &source(overrides)) {
        Err(Error::Config { key, message, .. }) => (key, message),
        other => panic!("{overrides}: expected a config error, got {other:?}"),
    }
}
