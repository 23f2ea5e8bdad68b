//! Rendering specification: frames have the requested size, the robot's pixels move with the
//! robot, and the same state renders to the same frame.

use std::sync::Arc;

use _core::render::render;
use _core::robot::ActionType;
use _core::scenario::Source;
use _core::tasks::load_scenario;
use _core::tasks::{Env, TaskKind};
use rapier2d::math::Vector;

fn env() -> Env {
    let cfg = load_scenario("nav", &Source::default()).expect("scenario");
    let spawner = Arc::new(Env::spawner(TaskKind::Nav, &cfg).expect("spawner"));
    let mut env = Env::new(TaskKind::Nav, Arc::new(cfg), spawner, ActionType::Wheels).expect("env");
    let mut obs = vec![0.0; 18];
    env.seed(0);
    env.reset(&mut obs);
    env
}

/// Mean pixel position of the robot's body colour (the first palette entry).
fn robot_pixel(frame: &[u8], width: usize) -> (f32, f32) {
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for (i, px) in frame.chunks_exact(3).enumerate() {
        let blue = px[2] > 150 && px[0] < 80 && px[1] > 90 && px[1] < 150;
        if blue {
            sx += (i % width) as f32;
            sy += (i / width) as f32;
            n += 1.0;
        }
    }
    assert!(n > 50.0, "robot not found in the frame");
    (sx / n, sy / n)
}

#[test]
fn test_frames_have_the_requested_size_and_are_reproducible() {
    let env = env();
    let frame = render(&env, 320, 240);
    assert_eq!(frame.len(), 320 * 240 * 3);
    assert_eq!(frame, render(&env, 320, 240));
}

#[test]
fn test_robot_pixels_follow_the_robot() {
    let mut env = env();
    env.world.place_robot(0, Vector::new(-0.5, -0.5), 0.0);
    env.world.sense(true);
    let (x0, y0) = robot_pixel(&render(&env, 400, 400), 400);
    env.world.place_robot(0, Vector::new(0.5, 0.5), 0.0);
    env.world.sense(true);
    let (x1, y1) = robot_pixel(&render(&env, 400, 400), 400);
    // 1 m right and 1 m up: ~190 px at 400 px for a 2.1 m wide view; y grows downwards.
    assert!((x1 - x0 - 190.0).abs() < 6.0, "dx {}", x1 - x0);
    assert!((y0 - y1 - 190.0).abs() < 6.0, "dy {}", y0 - y1);
}
