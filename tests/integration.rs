//! The Rust integration tests, one module per file of `tests/`, built as one test binary.
//!
//! One binary instead of one per file: each binary links the core and rapier2d again (thin LTO
//! in the release profile), which made most of `cargo test --release`'s build time. Cargo's own
//! discovery of `tests/*.rs` is off (`autotests = false` in Cargo.toml), so
//! `every_file_of_tests_is_a_module_here` fails when a new file is left out of the list below.
//!
//! Run one file's tests with its module name: `cargo test --release --test integration drive::`.

mod common;

macro_rules! test_modules {
    ($($name:ident),* $(,)?) => {
        $(mod $name;)*
        /// The modules declared above, by name.
        const MODULES: &[&str] = &[$(stringify!($name)),*];
    };
}

test_modules!(
    camera,
    consensus,
    controllers,
    determinism,
    drive,
    drone,
    dynamics,
    fuzz,
    ground,
    imu,
    layers,
    pathfollow,
    physics,
    platoon,
    rays,
    render,
    sensors,
    split,
    state,
    swarm,
    tasks,
    track,
);

#[test]
fn every_file_of_tests_is_a_module_here() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .expect("tests/ is readable")
        .map(|entry| entry.expect("a directory entry").path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "rs"))
        .filter_map(|path| Some(path.file_stem()?.to_str()?.to_owned()))
        .filter(|stem| stem != "integration")
        .collect();
    files.sort();
    let mut declared: Vec<&str> = MODULES.to_vec();
    declared.sort_unstable();
    assert_eq!(
        files, declared,
        "every tests/*.rs must be listed in tests/integration.rs's test_modules! (Cargo's \
         discovery is off, so a file left out would never run)"
    );
}
