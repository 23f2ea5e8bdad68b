//! Camera specification (issue 15): a red pillar shows in the pixels its edges' bearings say, at
//! the geometric depth; a wall hides what is behind it; another robot in front shows its LEDs'
//! colour where it occludes; bad colours and camera keys are config errors naming them.
//!
//! Units: metres, radians; robot frame x forward, y left; pixel 0 is the leftmost.

use crate::common;

use std::sync::Arc;

use _core::error::Error;
use _core::robot::ActionType;
use _core::scenario::Source;
use _core::sensors::camera::CAMERA_AHEAD;
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use _core::geometry::scene::{Scene, SceneShape};
use rapier2d::math::Vector;

const FOV: f32 = 2.287;
const PIXELS: usize = 32;
const RED: [f32; 3] = [1.0, 0.0, 0.0];

/// A multinav world of `robots` robots carrying the camera (one ray per pixel, for exact
/// geometry), in a 4 m arena.
fn env(robots: usize) -> Env {
    env_with(robots, "")
}

/// [`env`] with more scenario overrides (TOML lines).
fn env_with(robots: usize, more: &str) -> Env {
    let text = format!(
        "carry = [\"ir\", \"us\", \"gyro\", \"camera\"]\ncamera_rays_per_pixel = 1\n\
         n_robots = {robots}\nwidth = 4.0\nheight = 4.0\n{more}"
    );
    let source = Source {
        file: None,
        overrides: text.parse().expect("overrides"),
        version: None,
    };
    let cfg = load_scenario("multinav", &source).expect("scenario");
    let mut env = common::build(TaskKind::MultiNav, cfg);
    env.seed(0);
    env
}

/// Pixel i's ray bearing (rad), left to right.
fn bearing(i: usize) -> f32 {
    0.5 * FOV - (i as f32 + 0.5) * FOV / PIXELS as f32
}

/// The pixels whose ray, from the camera, meets a disc of `radius` at `centre` (exact geometry).
fn pixels_on_disc(centre: Vector, radius: f32) -> Vec<usize> {
    let camera = Vector::new(CAMERA_AHEAD, 0.0);
    let to = centre - camera;
    (0..PIXELS)
        .filter(|&i| {
            let dir = Vector::new(bearing(i).cos(), bearing(i).sin());
            let along = to.dot(dir);
            along > 0.0 && (to - dir * along).length() < radius
        })
        .collect()
}

fn scene_with(shapes: Vec<SceneShape>) -> Scene {
    let mut scene = Scene::arena(4.0, 4.0, 0.05);
    scene.shapes = shapes;
    scene
}

#[test]
fn test_a_red_pillar_shows_where_its_bearing_says_at_its_depth() {
    let mut env = env(1);
    let centre = Vector::new(0.8, 0.25);
    let radius = 0.06;
    env.world.set_scene(scene_with(vec![
        SceneShape::circle(centre, radius).with_color(RED)
    ]));
    env.world.place_robot(0, Vector::ZERO, 0.0);
    env.world.sense(true);
    let reading = &env.world.robots[0].readings.camera;
    let red: Vec<usize> = (0..PIXELS).filter(|&i| reading.rgb[i] == RED).collect();
    let expected = pixels_on_disc(centre, radius);
    assert!(!expected.is_empty());
    assert_eq!(red, expected);
    // The middle pixel's depth: the ray's distance to the disc's near side.
    let i = expected[expected.len() / 2];
    let dir = Vector::new(bearing(i).cos(), bearing(i).sin());
    let to = centre - Vector::new(CAMERA_AHEAD, 0.0);
    let along = to.dot(dir);
    let off = (to - dir * along).length();
    let depth = along - (radius * radius - off * off).sqrt();
    assert!(
        (reading.depth[i] - depth).abs() < 1e-4,
        "{} vs {depth}",
        reading.depth[i]
    );
    // Straight ahead the light grey wall, 1.94 m from the camera; at the field's edges (64° off)
    // the walls are beyond the 2 m range: black.
    assert_eq!(reading.rgb[PIXELS / 2 - 1], [0.8, 0.8, 0.8]);
    assert_eq!(reading.rgb[0], [0.0, 0.0, 0.0]);
}

#[test]
fn test_nothing_shows_behind_a_wall() {
    let mut env = env(1);
    let pillar = SceneShape::circle(Vector::new(0.8, 0.0), 0.06).with_color(RED);
    let wall = SceneShape::rect(Vector::new(0.4, 0.0), Vector::new(0.02, 0.5), 0.0);
    env.world.set_scene(scene_with(vec![pillar, wall]));
    env.world.place_robot(0, Vector::ZERO, 0.0);
    env.world.sense(true);
    let reading = &env.world.robots[0].readings.camera;
    assert!(reading.rgb.iter().all(|c| *c != RED));
    // The wall's face is 0.38 m ahead of the centre, 0.32 m ahead of the camera.
    let front = PIXELS / 2;
    assert!((reading.depth[front] - (0.38 - CAMERA_AHEAD) / bearing(front).cos()).abs() < 1e-4);
}

#[test]
fn test_another_robot_occludes_with_its_leds_colour() {
    let mut env = env(2);
    let centre = Vector::new(1.0, 0.0);
    env.world.set_scene(scene_with(vec![
        SceneShape::circle(centre, 0.3).with_color(RED)
    ]));
    env.world.place_robot(0, Vector::ZERO, 0.0);
    // A robot (disc of 0.0704 m) half way, its LEDs green by default.
    let other = Vector::new(0.4, 0.05);
    env.world.place_robot(1, other, 1.0);
    env.world.sense(true);
    let reading = &env.world.robots[0].readings.camera;
    let hidden = pixels_on_disc(other, env.world.drive.radius);
    assert!(!hidden.is_empty());
    for i in 0..PIXELS {
        if hidden.contains(&i) {
            assert_eq!(reading.rgb[i], [0.0, 0.8, 0.0], "pixel {i}");
        } else if pixels_on_disc(centre, 0.3).contains(&i) {
            assert_eq!(reading.rgb[i], RED, "pixel {i}");
        } else {
            // A wall within range, or nothing.
            let c = reading.rgb[i];
            assert!(
                c == [0.8, 0.8, 0.8] || c == [0.0, 0.0, 0.0],
                "pixel {i}: {c:?}"
            );
        }
    }
}

#[test]
fn test_an_agents_led_action_shows_in_another_robots_camera_at_its_next_observation() {
    // Agent 1 sets its LEDs to (0.5, -1, 1): levels round(0.75 · 63) = 47, 0 and 63 of the real
    // LEDs' 64 (docs/robot.md §6); agent 0 leaves its own at full green. With `action_delay = 1`
    // the colour arrives one step later, like the wheels.
    let other = Vector::new(0.4, 0.05);
    let action = [0.0, 0.0, -1.0, 1.0, -1.0, 0.0, 0.0, 0.5, -1.0, 1.0];
    let set = [47.0 / 63.0, 0.0, 1.0];
    for delay in [0, 1] {
        let mut env = env_with(2, &format!("led_action = true\naction_delay = {delay}"));
        let mut obs = vec![0.0; env.obs_dim()];
        env.reset(&mut obs);
        env.world.set_scene(scene_with(Vec::new()));
        env.world.place_robot(0, Vector::ZERO, 0.0);
        env.world.place_robot(1, other, 1.0);
        let hidden = pixels_on_disc(other, env.world.drive.radius);
        assert!(!hidden.is_empty());
        for step in 0..=delay {
            env.step(&action, &mut obs);
            let seen = if step == delay { set } else { [0.0, 0.8, 0.0] };
            let reading = &env.world.robots[0].readings.camera;
            for &i in &hidden {
                assert_eq!(
                    reading.rgb[i], seen,
                    "delay {delay}, step {step}, pixel {i}"
                );
            }
        }
        // Zero wheel commands from rest: neither robot moved.
        assert_eq!(env.world.robots[1].position, other);
        assert_eq!(env.world.robots[0].led, [0.0, 1.0, 0.0]);
    }
}

#[test]
fn test_led_actions_need_every_agent_to_drive_a_khepera() {
    for overrides in ["led_action = true", "led_action = true\ndriver = \"agent\""] {
        let source = Source {
            file: None,
            overrides: overrides.parse().expect("overrides"),
            version: None,
        };
        let cfg = load_scenario("dronefollow", &source).expect("scenario");
        let spawner = Arc::new(Env::spawner(TaskKind::DroneFollow, &cfg).expect("spawner"));
        let error = Env::new(
            TaskKind::DroneFollow,
            Arc::new(cfg),
            spawner,
            ActionType::Wheels,
        )
        .err()
        .expect("a drone has no LEDs");
        assert!(matches!(error, Error::Config { .. }), "{error}");
        assert!(error.to_string().contains("task.led_action"), "{error}");
    }
}

#[test]
fn test_bad_colours_and_camera_keys_are_config_errors_naming_them() {
    for (task, overrides, key) in [
        ("nav", "wall_color = [0.5, 0.5, 2.0]", "arena.wall_color[2]"),
        ("nav", "led_color = [-0.1, 0.0, 0.0]", "robot.led_color[0]"),
        (
            "nav",
            "fixed = [{kind = \"circle\", center = [0.3, 0.3], radius = 0.1, color = [1.0, 0.0, 1.5]}]",
            "obstacles.fixed[0].color[2]",
        ),
        ("nav", "camera_pixels = 0", "sensors.camera_pixels"),
        ("nav", "camera_fov = 7.0", "sensors.camera_fov"),
        ("seek", "pillar_color = [1.0, 0.0, 9.0]", "seek.pillar_color[2]"),
        ("seek", "goal_radius = 0.1", "task.goal_radius"),
        ("seek", "carry = [\"ir\"]\nobserve = [\"ir\"]", "sensors.carry"),
    ] {
        let source = Source {
            file: None,
            overrides: overrides.parse().expect("overrides"),
            version: None,
        };
        match load_scenario(task, &source) {
            Err(Error::Config { key: got, .. }) => assert_eq!(got, key, "{overrides}"),
            other => panic!("{overrides}: expected a config error, got {other:?}"),
        }
    }
}
