//! Sensor specification: each IR sensor reads the K-Team response curve for an obstacle at a
//! known distance, the floor value with nothing in range, and the ultrasonic sensors give
//! whole centimetres and the real codes.

use crate::common;

use std::sync::Arc;

use _core::robot::ActionType;
use _core::scenario::Source;
use _core::sensors::{IR_BEARINGS, US_BEARINGS, US_DISABLED, US_NOTHING, US_TOO_CLOSE};
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use _core::geometry::scene::{Scene, SceneShape};
use rapier2d::math::Vector;

fn env_with(overrides: &str) -> Env {
    let source = Source {
        file: None,
        overrides: overrides.parse().expect("overrides"),
        ..Default::default()
    };
    let cfg = load_scenario("nav", &source).expect("scenario");
    let spawner = Arc::new(Env::spawner(TaskKind::Nav, &cfg).expect("spawner"));
    let mut env = Env::new(TaskKind::Nav, Arc::new(cfg), spawner, ActionType::Wheels).expect("env");
    env.seed(3);
    env
}

/// Puts the robot at the origin facing +x and a wide wall slab `gap` metres from the rim of
/// sensor direction `bearing` (robot frame), then reads the sensors.
fn sense_wall(env: &mut Env, bearing: f32, gap: f32) {
    let radius = env.world.drive.radius;
    let dir = Vector::new(bearing.cos(), bearing.sin());
    let centre = dir * (radius + gap + 0.05);
    let mut scene = Scene::arena(5.0, 5.0, 0.05);
    scene
        .shapes
        .push(SceneShape::rect(centre, Vector::new(0.05, 0.3), bearing));
    env.world.set_scene(scene);
    env.world.place_robot(0, Vector::ZERO, 0.0);
    env.world.sense(true);
}

/// Response curve points (m, raw) from the spec's table.
const CURVE: [(f32, f32); 6] = [
    (0.010, 1012.0),
    (0.030, 979.0),
    (0.050, 492.0),
    (0.080, 254.0),
    (0.120, 163.0),
    (0.200, 111.0),
];

#[test]
fn test_each_ir_reads_response_curve_without_noise() {
    let mut env = env_with("ir_noise_sigma = 0.0");
    for (k, bearing) in IR_BEARINGS.iter().enumerate() {
        for (gap, raw) in CURVE {
            sense_wall(&mut env, *bearing, gap);
            let got = env.world.robots[0].readings.ir.raw[k] as f32;
            assert!(
                (got - raw).abs() <= 1.0,
                "sensor {k} at {gap} m: {got} != {raw}"
            );
            // The other sensors see less (the slab is narrow) or the floor.
            for (j, other) in env.world.robots[0].readings.ir.raw.iter().enumerate() {
                if j != k {
                    assert!((*other as f32) < raw, "sensor {j} sees {other} >= {raw}");
                }
            }
        }
    }
}

#[test]
fn test_ir_noise_is_gaussian_around_curve() {
    let mut env = env_with("ir_noise_sigma = 10.0");
    let (mut sum, mut sum2, n) = (0.0f64, 0.0f64, 2000);
    for _ in 0..n {
        sense_wall(&mut env, 0.0, 0.06);
        let v = env.world.robots[0].readings.ir.raw[3] as f64;
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / n as f64;
    let sd = (sum2 / n as f64 - mean * mean).sqrt();
    assert!((mean - 380.0).abs() < 1.5, "mean {mean}");
    assert!((sd - 10.0).abs() < 1.0, "sd {sd}");
}

#[test]
fn test_nothing_in_range_reads_floor_value() {
    let mut env = env_with("ir_noise_sigma = 0.0\nir_floor_value = 100.0");
    env.world.place_robot(0, Vector::ZERO, 0.3);
    env.world.sense(true);
    assert_eq!(env.world.robots[0].readings.ir.raw, [100; 8]);
}

#[test]
fn test_ultrasonic_centimetres_and_codes() {
    let mut env = env_with("us_noise_sigma = 0.0");
    // Front sensor (index 2): a slab at 1.234 m from the rim.
    sense_wall(&mut env, US_BEARINGS[2], 1.234);
    assert_eq!(env.world.robots[0].readings.us.code[2], 123);
    // Too close.
    sense_wall(&mut env, US_BEARINGS[2], 0.10);
    assert_eq!(env.world.robots[0].readings.us.code[2], US_TOO_CLOSE);
    // Arena is 2 m: from the centre, the side walls are ~0.93 m away, so move the robot into a
    // 5 m arena to have nothing in range.
    let mut big = env_with("us_noise_sigma = 0.0\nwidth = 5.0\nheight = 5.0");
    big.world
        .set_scene(Scene::arena(5.0, 5.0, 0.05));
    big.world.place_robot(0, Vector::ZERO, 0.0);
    big.world.sense(true);
    assert_eq!(big.world.robots[0].readings.us.code, [US_NOTHING; 5]);
    // Disabled sensors.
    let mut off = env_with("us_enabled = [true, false, true, true, false]");
    off.world.place_robot(0, Vector::ZERO, 0.0);
    off.world.sense(true);
    assert_eq!(off.world.robots[0].readings.us.code[1], US_DISABLED);
    assert_eq!(off.world.robots[0].readings.us.code[4], US_DISABLED);
    assert!(
        off.world.robots[0].readings.us.code[2] > 80
            && off.world.robots[0].readings.us.code[2] < 100
    );
}

#[test]
fn test_sonar_beams_see_what_a_cast_against_every_robot_sees() {
    // The sonar skips robots behind it and robots farther than a radius from all five beam
    // lines (they cannot be met); its rays must still stop exactly where a cast against every
    // other robot stops. 300 random layouts of 24 robots crowded around robot 0.
    use rand::{Rng, SeedableRng};
    let source = Source {
        file: None,
        // Any incidence echoes (the acceptance cone is another test's).
        overrides: "n_robots = 25\nwidth = 6.0\nheight = 6.0\nus_noise_sigma = 0.0\n\
                    us_acceptance = 1.5707963267948966"
            .parse()
            .expect("overrides"),
        ..Default::default()
    };
    let cfg = load_scenario("multinav", &source).expect("scenario");
    let mut env = common::build(TaskKind::MultiNav, cfg);
    env.seed(3);
    let radius = env.world.drive.radius;
    let cast_range = 2.0 + 0.01; // us_max_range + 1 cm, as the sensor casts
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut hits = 0;
    for _ in 0..300 {
        let heading: f32 = rng.random_range(-3.2..3.2);
        env.world.place_robot(0, Vector::new(0.0, 0.0), heading);
        for i in 1..25 {
            // Rings from touching the rim to beyond the range; overlaps do not matter here.
            let d: f32 = rng.random_range(2.0 * radius..2.4);
            let a: f32 = rng.random_range(-3.2..3.2);
            env.world
                .place_robot(i, Vector::new(d * a.cos(), d * a.sin()), 0.0);
        }
        env.world.sense(true);
        let others: Vec<Vector> = env.world.robots[1..].iter().map(|r| r.position).collect();
        let scene = &env.world.scene;
        for (k, bearing) in US_BEARINGS.iter().enumerate() {
            let (s, c) = (heading + bearing).sin_cos();
            let dir = Vector::new(c, s);
            let want = scene
                .cast_hit(
                    dir * radius,
                    dir,
                    cast_range,
                    scene.shapes.iter(),
                    &others,
                    &[],
                    radius,
                )
                .map_or(cast_range, |h| h.distance);
            let got = env.world.robots[0].readings.us.hit[k];
            if want < cast_range {
                hits += 1;
            }
            // Directions rounded apart by an ulp move a grazing hit by microns; a robot
            // wrongly skipped moves it by centimetres or to no echo (readings are in cm).
            assert!((got - want).abs() <= 1e-4, "beam {k}: {got} against {want}");
        }
    }
    assert!(hits > 300, "too few hits to test anything: {hits}");
}
