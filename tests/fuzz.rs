//! Property-based fuzzing (proptest) of the core's two untrusted inputs: scenario TOML and action
//! buffers. Whatever they hold, the core returns a typed error or works: no panic (proptest
//! reports a panic as a failure), no non-finite observation or reward, no observation outside
//! its layout's bounds, and a rejected action buffer leaves every world of the batch exactly as
//! it was (compared through the saved state). Tasks and versions come from the registry
//! (`TaskKind::ALL`, each from the version that added it to the latest).
//!
//! The number of cases per property is proptest's `PROPTEST_CASES` (default here: 64, the CI
//! run). The long run of the closing note:
//! `PROPTEST_CASES=250000 cargo test --release --test integration fuzz:: -- --nocapture`.

use _core::batch::Batch;
use _core::error::Error;
use _core::robot::ActionType;
use _core::scenario::{Source, LATEST_VERSION};
use _core::tasks::load_scenario;
use _core::tasks::TaskKind;
use proptest::prelude::*;
use proptest::test_runner::Config;
use std::sync::atomic::{AtomicU64, Ordering};
use toml::{Table, Value};

/// Every task of the registry ([`TaskKind::ALL`]): a new task is fuzzed without touching this
/// file.
fn tasks() -> Vec<&'static str> {
    TaskKind::ALL.iter().map(|kind| kind.name()).collect()
}

/// Every (task, behaviour version) the registry has.
fn task_versions() -> Vec<(&'static str, u32)> {
    TaskKind::ALL
        .iter()
        .flat_map(|kind| (kind.info().schema.since..=LATEST_VERSION).map(|v| (kind.name(), v)))
        .collect()
}

/// Outcomes so far (scenarios loaded, refused; buffers stepped, refused), printed every 10^4 cases
/// of a property when `FUZZ_STATS` is set: a fuzzer whose inputs are all refused tests little.
static LOADED: AtomicU64 = AtomicU64::new(0);
static REFUSED: AtomicU64 = AtomicU64::new(0);
static STEPPED: AtomicU64 = AtomicU64::new(0);
static REJECTED: AtomicU64 = AtomicU64::new(0);

fn count(counter: &AtomicU64, other: &AtomicU64, what: &str) {
    let n = counter.fetch_add(1, Ordering::Relaxed) + 1;
    let m = other.load(Ordering::Relaxed);
    if std::env::var_os("FUZZ_STATS").is_some() && (n + m).is_multiple_of(10_000) {
        eprintln!("{what}: {n} of {} cases", n + m);
    }
}

fn config() -> Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64);
    Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    }
}

/// Every (dotted key, default value) leaf of a task's defaults.
fn leaves(table: &Table, prefix: &str, out: &mut Vec<(String, Value)>) {
    for (key, value) in table {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match value {
            Value::Table(sub) => leaves(sub, &path, out),
            _ => out.push((path, value.clone())),
        }
    }
}

fn default_leaves(task: &str, version: u32) -> Vec<(String, Value)> {
    let table: Table = TaskKind::parse(task)
        .expect("task")
        .default_config(Some(version))
        .expect("defaults")
        .parse()
        .expect("defaults parse");
    let mut out = Vec::new();
    leaves(&table, "", &mut out);
    out
}

/// Values near a default, at the edges of what a float can be, and of the wrong type.
fn value_for(default: Value) -> BoxedStrategy<Value> {
    let number = match &default {
        Value::Float(f) => *f,
        Value::Integer(i) => *i as f64,
        _ => 1.0,
    };
    let edgy_float = prop_oneof![
        Just(0.0),
        Just(-0.0),
        Just(-1.0),
        Just(1e-9),
        Just(1e30),
        Just(-1e30),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        any::<f64>(),
    ];
    let scaled = (0.0f64..3.0).prop_map(move |k| number * k);
    // Near the default and of its type: most of these should load.
    let plausible = match &default {
        Value::Integer(i) => {
            let i = *i;
            (0i64..=2 * i.max(1)).prop_map(Value::Integer).boxed()
        }
        Value::Float(_) => (0.5f64..1.5)
            .prop_map(move |k| Value::Float(number * k))
            .boxed(),
        _ => Just(default.clone()).boxed(),
    };
    prop_oneof![
        6 => Just(default.clone()),
        12 => plausible,
        2 => scaled.prop_map(Value::Float),
        2 => edgy_float.prop_map(Value::Float),
        1 => any::<i64>().prop_map(Value::Integer),
        1 => (-5i64..50).prop_map(Value::Integer),
        1 => any::<bool>().prop_map(Value::Boolean),
        1 => "[a-z ]{0,6}".prop_map(Value::String),
        2 => (scaled_pair(number)).prop_map(|(a, b)| Value::Array(vec![a.into(), b.into()])),
        1 => prop::collection::vec(any::<f64>(), 0..4)
            .prop_map(|v| Value::Array(v.into_iter().map(Value::Float).collect())),
        1 => Just(Value::Table(Table::new())),
    ]
    .boxed()
}

fn scaled_pair(number: f64) -> impl Strategy<Value = (f64, f64)> {
    (-1.0f64..3.0, -1.0f64..3.0).prop_map(move |(a, b)| (number * a, number * b))
}

/// A scenario document: some of the task's keys set to fuzzed values, maybe an unknown key, maybe
/// random obstacles, written as TOML text (or, sometimes, that text with bytes mangled).
fn scenario_text(task: &'static str, version: u32) -> impl Strategy<Value = String> {
    let keys = default_leaves(task, version);
    let n = keys.len();
    let picks = prop::collection::vec(0..n, 0..5);
    picks
        .prop_flat_map(move |indices| {
            let chosen: Vec<(String, Value)> = indices.iter().map(|&i| keys[i].clone()).collect();
            let values: Vec<BoxedStrategy<Value>> =
                chosen.iter().map(|(_, v)| value_for(v.clone())).collect();
            let names: Vec<String> = chosen.into_iter().map(|(k, _)| k).collect();
            (
                Just(names),
                values,
                prop::option::weighted(0.1, "[a-z]{1,8}"),
                prop_oneof![2 => Just(Vec::new()), 1 => prop::collection::vec(obstacle(), 1..4)],
                prop_oneof![
                    8 => Just(Vec::new()),
                    1 => prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..3),
                ],
            )
        })
        .prop_map(|(names, values, unknown, obstacles, mangles)| {
            let mut table = Table::new();
            for (name, value) in names.iter().zip(values) {
                insert(&mut table, name, value);
            }
            if let Some(key) = unknown {
                insert(&mut table, &format!("task.{key}"), Value::Integer(1));
            }
            if !obstacles.is_empty() {
                insert(&mut table, "obstacles.fixed", Value::Array(obstacles));
            }
            let mut text = toml::to_string(&table).unwrap_or_default().into_bytes();
            for (index, byte) in mangles {
                if !text.is_empty() {
                    let i = index.index(text.len());
                    text[i] = byte;
                }
            }
            String::from_utf8_lossy(&text).into_owned()
        })
}

fn insert(table: &mut Table, dotted: &str, value: Value) {
    let mut parts: Vec<&str> = dotted.split('.').collect();
    let last = parts.pop().unwrap_or_default();
    let mut node = table;
    for part in parts {
        let entry = node
            .entry(part.to_string())
            .or_insert_with(|| Value::Table(Table::new()));
        match entry {
            Value::Table(sub) => node = sub,
            _ => return,
        }
    }
    node.insert(last.to_string(), value);
}

fn obstacle() -> impl Strategy<Value = Value> {
    let coordinate = prop_oneof![12 => -1.0f64..1.0, 1 => any::<f64>()];
    let size = prop_oneof![12 => 0.01f64..0.15, 1 => any::<f64>()];
    (
        prop::sample::select(vec!["box", "circle", "segment", "triangle"]),
        (coordinate.clone(), coordinate.clone()),
        (size.clone(), size),
        coordinate,
    )
        .prop_map(|(kind, (x, y), (a, b), angle)| {
            let mut entry = Table::new();
            entry.insert("kind".into(), kind.into());
            entry.insert("center".into(), Value::Array(vec![x.into(), y.into()]));
            match kind {
                "box" => entry.insert(
                    "half_extents".into(),
                    Value::Array(vec![a.into(), b.into()]),
                ),
                "circle" => entry.insert("radius".into(), a.into()),
                _ => entry.insert("angle".into(), angle.into()),
            };
            Value::Table(entry)
        })
}

fn forward_actions(n: usize) -> impl Strategy<Value = Vec<Vec<f32>>> {
    prop::collection::vec(prop::collection::vec(-1.0f32..1.0, n..=n), 1..6)
}

proptest! {
    #![proptest_config(config())]

    /// A scenario file is loaded or refused with a ConfigError; a loaded one builds a batch whose
    /// worlds step with finite observations.
    #[test]
    fn scenario_toml_loads_or_is_a_config_error(
        (task, version, text) in prop::sample::select(task_versions())
            .prop_flat_map(|(task, version)| {
                (Just(task), Just(version), scenario_text(task, version))
            }),
        seed in any::<u64>(),
    ) {
        check_scenario(task, version, &text, seed)?;
    }

    /// An action buffer of any length and any float bits is stepped or refused with an
    /// ActionError that changes no world.
    #[test]
    fn action_buffer_steps_or_is_refused_untouched(
        task in prop::sample::select(tasks()),
        seed in 0u64..1000,
        prefix in forward_actions(4),
        values in prop::collection::vec(
            prop_oneof![
                40 => -2.0f32..2.0,
                1 => any::<f32>(),
                1 => prop::sample::select(vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX]),
            ],
            0..40,
        ),
        exact_width in prop::bool::weighted(0.8),
    ) {
        check_actions(task, seed, &prefix, &values, exact_width)?;
    }
}

fn check_scenario(task: &str, version: u32, text: &str, seed: u64) -> Result<(), TestCaseError> {
    let source = Source {
        file: Some((text, "fuzz.toml")),
        overrides: Table::new(),
        version: Some(version),
    };
    let cfg = match load_scenario(task, &source) {
        Ok(cfg) => cfg,
        Err(Error::Config { .. }) => {
            count(&REFUSED, &LOADED, "scenarios refused");
            return Ok(());
        }
        Err(other) => return Err(TestCaseError::fail(format!("{other:?} for\n{text}"))),
    };
    let kind = TaskKind::parse(task).expect("task");
    let (low, high) = kind
        .obs_layout(&cfg)
        .map_err(|e| TestCaseError::fail(format!("{e:?}")))?
        .bounds();
    let mut batch = match Batch::new(kind, cfg, 2, ActionType::Wheels, Some(1), true) {
        Ok(batch) => batch,
        Err(Error::Config { .. } | Error::Memory(_)) => {
            count(&REFUSED, &LOADED, "scenarios refused");
            return Ok(());
        }
        Err(other) => return Err(TestCaseError::fail(format!("{other:?} for\n{text}"))),
    };
    count(&LOADED, &REFUSED, "scenarios loaded");
    batch.reset(Some(seed));
    let actions = vec![0.7f32; batch.len() * batch.act_dim()];
    for _ in 0..5 {
        batch
            .step(&actions)
            .map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
        prop_assert!(
            batch.obs().iter().all(|x| x.is_finite()),
            "non-finite observation for\n{}",
            text
        );
        for (world, row) in batch.obs().chunks(low.len()).enumerate() {
            let outside = (0..row.len()).find(|&i| !(low[i]..=high[i]).contains(&row[i]));
            prop_assert!(
                outside.is_none(),
                "world {} observation {:?} outside its bounds for\n{}",
                world,
                outside,
                text
            );
        }
        prop_assert!(
            batch.outcomes().iter().all(|o| o.reward.is_finite()),
            "non-finite reward for\n{}",
            text
        );
    }
    Ok(())
}

thread_local! {
    static BATCHES: std::cell::RefCell<Vec<(&'static str, Batch)>> = const {
        std::cell::RefCell::new(Vec::new())
    };
}

/// A cached 2-world batch of `task` (building one per case would dominate the run).
fn with_batch<T>(task: &'static str, f: impl FnOnce(&mut Batch) -> T) -> T {
    BATCHES.with(|cell| {
        let mut batches = cell.borrow_mut();
        if !batches.iter().any(|(t, _)| *t == task) {
            let source = Source {
                file: None,
                overrides: "max_steps = 3".parse().expect("overrides"),
                ..Default::default()
            };
            let cfg = load_scenario(task, &source).expect("scenario");
            let kind = TaskKind::parse(task).expect("task");
            let batch = Batch::new(kind, cfg, 2, ActionType::Wheels, Some(1), true).expect("batch");
            batches.push((task, batch));
        }
        let (_, batch) = batches
            .iter_mut()
            .find(|(t, _)| *t == task)
            .expect("cached");
        f(batch)
    })
}

fn check_actions(
    task: &'static str,
    seed: u64,
    prefix: &[Vec<f32>],
    values: &[f32],
    exact_width: bool,
) -> Result<(), TestCaseError> {
    with_batch(task, |batch| {
        batch.reset(Some(seed));
        let width = batch.len() * batch.act_dim();
        for row in prefix {
            let actions: Vec<f32> = row.iter().cycle().take(width).copied().collect();
            batch
                .step(&actions)
                .map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
        }
        // Mostly the right length (cycling the drawn values), else whatever length was drawn.
        let values: Vec<f32> = if exact_width && !values.is_empty() {
            values.iter().cycle().take(width).copied().collect()
        } else {
            values.to_vec()
        };
        let values = values.as_slice();
        let before = batch.save_state().expect("save");
        let valid = values.len() == width && values.iter().all(|x| x.is_finite());
        match batch.step(values) {
            Ok(()) => {
                count(&STEPPED, &REJECTED, "buffers stepped");
                prop_assert!(valid, "accepted {values:?}");
                prop_assert!(batch.obs().iter().all(|x| x.is_finite()));
            }
            Err(Error::Action(message)) => {
                count(&REJECTED, &STEPPED, "buffers refused");
                prop_assert!(!valid, "refused valid {values:?}: {message}");
                prop_assert!(
                    batch.save_state().expect("save") == before,
                    "a refused buffer changed the batch: {message}"
                );
            }
            Err(other) => return Err(TestCaseError::fail(format!("{other:?}"))),
        }
        Ok(())
    })
}
