//! Tests of scenario loading: defaults per version, overrides, errors naming the key, ranges,
//! and the keys' declared domains.

use super::*;

const NAV: TaskSchema = TaskSchema {
    name: "nav",
    since: 0,
    defaults: "",
    section: None,
};

fn overrides(text: &str) -> Table {
    text.parse().expect("test override")
}

#[test]
fn defaults_load_render_and_round_trip() {
    let v0 = NAV
        .load(&Source {
            version: Some(0),
            ..Default::default()
        })
        .expect("nav v0");
    assert_eq!(v0.task.max_steps, 400);
    assert!(v0.robot.wheel_accel_limit.max().is_infinite());
    assert_eq!(v0.physics.drive, DriveModel::Kinematic);
    let v1 = NAV
        .load(&Source {
            version: Some(1),
            ..Default::default()
        })
        .expect("nav v1");
    // v1: the K-Team firmware's speed profile rate, 3 units per 10 ms (docs/robot.md §3), as a ramp.
    assert_eq!(v1.motors.mode, crate::motors::MotorMode::Ramp);
    assert!((v1.motors.accel(&v1.robot).max() - 0.2034543).abs() < 1e-6);
    assert_eq!(v1.physics.drive, DriveModel::Traction);
    let s = NAV.load(&Source::default()).expect("nav");
    assert_eq!(s.task.max_steps, 400);
    // v2: K-Team's profile at Acc_Inc 40, 2.71 m/s^2.
    assert_eq!(s.motors.mode, crate::motors::MotorMode::Profile);
    assert!((s.motors.accel(&s.robot).max() - 2.712724).abs() < 1e-5);
    assert_eq!(s.physics.drive, DriveModel::Traction);
    let e = NAV
        .load(&Source {
            version: Some(LATEST_VERSION + 1),
            ..Default::default()
        })
        .unwrap_err()
        .to_string();
    let expected = format!("version {} does not exist", LATEST_VERSION + 1);
    assert!(e.contains(&expected), "{e}");
    let text = s.to_toml();
    assert!(text.contains("radius = 0.0704\n"), "{text}");
    let back = NAV
        .load(&Source {
            file: Some((&text, "resolved.toml")),
            overrides: Table::new(),
            ..Default::default()
        })
        .expect("round trip");
    assert_eq!(back.to_toml(), text);
    let file = NAV.render_defaults("KheperaIV-Nav", None).expect("render");
    assert!(file.contains("# body radius (m)"), "{file}");
    assert!(file.parse::<Table>().is_ok(), "{file}");
}

#[test]
fn leaf_dotted_and_section_overrides() {
    let src = Source {
        file: None,
        overrides: overrides("goal_radius = 0.1\n\"robot.mass\" = 0.6\nphysics = { substeps = 2 }"),
        ..Default::default()
    };
    let s = NAV.load(&src).expect("overrides");
    assert_eq!(s.task.goal_radius, 0.1);
    assert_eq!(s.robot.mass, Param::Value(0.6));
    assert_eq!(s.physics.substeps, 2);
    assert_eq!(s.physics.dt, 0.05);
}

#[test]
fn unknown_keys_are_named() {
    let src = Source {
        file: Some(("[task]\ngoal_radios = 0.1\n", "my.toml")),
        overrides: Table::new(),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(
        e.starts_with("my.toml: task.goal_radios: unknown key"),
        "{e}"
    );
    assert!(e.contains("did you mean `goal_radius`?"), "{e}");
    let src = Source {
        file: None,
        overrides: overrides("goal_radios = 0.1"),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(e.contains("<override>: goal_radios"), "{e}");
    assert!(e.contains("did you mean `goal_radius`?"), "{e}");
    let src = Source {
        file: Some(("[sensors]\nir_rnage = 0.3\n", "s.toml")),
        overrides: Table::new(),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(
        e.starts_with("s.toml: sensors.ir_rnage: unknown key"),
        "{e}"
    );
    assert!(e.contains("did you mean `ir_range`?"), "{e}");
}

#[test]
fn wrong_types_and_impossible_values_are_named() {
    let src = Source {
        file: Some(("[robot]\nradius = \"big\"\n", "f.toml")),
        overrides: Table::new(),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(e.starts_with("f.toml: robot.radius"), "{e}");
    let src = Source {
        file: None,
        overrides: overrides("radius = -1.0"),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(e.contains("robot.radius: must be"), "{e}");
    let src = Source {
        file: None,
        overrides: overrides("min_goal_distance = 5.0"),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(e.contains("spawn.min_goal_distance"), "{e}");
    let src = Source {
        file: Some(("[task\n", "broken.toml")),
        overrides: Table::new(),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(e.starts_with("broken.toml: "), "{e}");
    let src = Source {
        file: None,
        overrides: overrides("ir_noise_sigma = \"loud\""),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(e.starts_with("<override>: sensors.ir_noise_sigma"), "{e}");
}

#[test]
fn ranges_are_parameters_and_checked() {
    let src = Source {
        file: None,
        overrides: overrides("mass = [0.5, 0.6]\nir_noise_sigma = [0.0, 20.0]"),
        ..Default::default()
    };
    let s = NAV.load(&src).expect("ranges");
    assert_eq!(s.robot.mass, Param::Range([0.5, 0.6]));
    let src = Source {
        file: None,
        overrides: overrides("mass = [0.6, 0.5]"),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(e.contains("robot.mass"), "{e}");
}

/// Whether a key of type `ty` holds numbers (its domain then matters).
fn holds_numbers(ty: &str) -> bool {
    let ty: String = ty.chars().filter(|c| !c.is_whitespace()).collect();
    ["f32", "u32", "Param", "usize", "f64"]
        .iter()
        .any(|number| ty.contains(number))
        || ["ObstacleSpec", "LineMark", "ArcMark", "TrackMark"]
            .iter()
            .any(|table| ty.contains(table))
}

#[test]
fn every_key_that_holds_numbers_declares_its_domain_and_the_default_file_shows_it() {
    for kind in crate::tasks::TaskKind::ALL {
        let schema = &kind.info().schema;
        for (section, keys) in schema.sections() {
            for key in keys {
                if holds_numbers(key.ty) {
                    assert!(
                        key.domain.is_some(),
                        "{section}.{} ({}) declares no domain",
                        key.name,
                        key.ty
                    );
                    assert!(!key.allowed().is_empty(), "{section}.{}", key.name);
                }
            }
        }
        let text = schema.render_defaults("header", None).expect("render");
        let radius = text
            .lines()
            .find(|l| l.starts_with("radius ="))
            .expect("robot.radius");
        assert!(
            radius.ends_with("; allowed: finite, > 0, <= 1000"),
            "{radius}"
        );
    }
}

#[test]
fn a_value_outside_its_domain_is_an_error_naming_the_key_whether_used_or_not() {
    for (text, key) in [
        ("arena.wall_reflectance = nan", "arena.wall_reflectance"),
        ("arena.wall_reflectance = -1.0", "arena.wall_reflectance"),
        ("floor.image_scale = nan", "floor.image_scale"),
        ("floor.image_origin = [0.0, 0.0, 0.0]", "floor.image_origin"),
        ("robot.led_color = [0.0, 0.5, 0.5, 0.5]", "robot.led_color"),
        (
            "sensors.us_enabled = [true, true, true, true, true, true]",
            "sensors.us_enabled",
        ),
        ("task.progress_weight = 3.4e38", "task.progress_weight"),
        ("robot.mass = [0.5, inf]", "robot.mass"),
        (
            "obstacles.circle_radius = [0.05, nan]",
            "obstacles.circle_radius[1]",
        ),
    ] {
        let (section, rest) = text.split_once('.').expect("dotted");
        let src = Source {
            file: Some((&format!("[{section}]\n{rest}\n"), "f.toml")),
            ..Default::default()
        };
        let e = NAV.load(&src).unwrap_err().to_string();
        assert!(e.starts_with(&format!("f.toml: {key}: ")), "{text}: {e}");
        assert!(e.contains("must "), "{text}: {e}");
    }
    let lines = "[floor]\nlines = [{a = [0.0, 0.0], b = [1.0, 0.0, 2.0], width = 0.02}]\n";
    let src = Source {
        file: Some((lines, "f.toml")),
        ..Default::default()
    };
    let e = NAV.load(&src).unwrap_err().to_string();
    assert!(
        e.starts_with("f.toml: floor.lines[0].b: must have exactly 2 entries, got 3"),
        "{e}"
    );
}
