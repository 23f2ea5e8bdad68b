//! Views of the core's data as Python values, for the `Batch` class's inspection methods: the
//! raw sensor readings (`sensor_readings`), a world's geometry (`scene`) and frame (`frame`),
//! and the statistics of the episodes that just ended, the world's (`episode_stats`) and each
//! agent's own (`agent_episode_stats`), each a dict of NumPy arrays or plain values.
//!
//! Units: the real robot's for sensor readings (each sensor's raw units, wheel speeds m/s,
//! encoders pulses, gyro rad/s); metres and radians for geometry, in the world frame (arena
//! centred at the origin, angles CCW). Threading and copies: called by `Batch`'s methods with
//! the GIL held (no `py.detach`: these are small copies; but a frame is drawn with the GIL
//! released); every array is freshly allocated and filled from the core's data, never a view
//! of its buffers, and nothing here keeps a Python object.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rapier2d::math::Vector;

use super::errors::to_py;
use crate::batch::Batch as CoreBatch;
use crate::draw::Mark;
use crate::error::Error;
use crate::geometry::scene::Geometry;
use crate::render::{render_view, View};
use crate::robot::PULSES_PER_WHEEL_TURN;
use crate::sensors::{ChannelValues, Readout};
use crate::tasks::{AgentStats, Env, EpisodeStats};

/// Statistics of the episodes that ended on the last step, one array entry per world (valid
/// where an episode ended): "return", "length", "success", "path_length" (m), "collisions",
/// then the task's extra statistics by name.
pub fn episode_stats<'py>(py: Python<'py>, batch: &CoreBatch) -> PyResult<Bound<'py, PyDict>> {
    let stats: Vec<_> = batch.episode_stats().copied().collect();
    let d = PyDict::new(py);
    let f32s = |f: fn(&EpisodeStats) -> f32| PyArray1::from_iter(py, stats.iter().map(f));
    let i64s = |f: fn(&EpisodeStats) -> i64| PyArray1::from_iter(py, stats.iter().map(f));
    d.set_item("return", f32s(|s| s.ret))?;
    d.set_item("length", i64s(|s| s.length as i64))?;
    d.set_item(
        "success",
        PyArray1::from_iter(py, stats.iter().map(|s| s.success)),
    )?;
    d.set_item("path_length", f32s(|s| s.path_length))?;
    d.set_item("collisions", i64s(|s| s.collisions as i64))?;
    let names = batch.envs()[0].kind().extra_stats();
    for (k, name) in names.iter().enumerate() {
        d.set_item(
            *name,
            PyArray1::from_iter(py, stats.iter().map(|s| s.extra[k])),
        )?;
    }
    Ok(d)
}

/// Each agent's own statistics, shape (N, n_agents) per entry: "return" (its rewards summed),
/// "length" (steps it took part in), "success" (as its task defines it for one agent),
/// "path_length" (m, its robot's or vehicle's) and "collisions" (steps its robot was in
/// contact). `running`: the running episodes' (an agent that has left holds its final ones,
/// until the world is reset); else the last episodes that ended (valid where one ended).
pub fn agent_episode_stats<'py>(
    py: Python<'py>,
    batch: &CoreBatch,
    running: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let stats: Vec<AgentStats> = batch
        .envs()
        .iter()
        .flat_map(|e| {
            let agents = if running {
                &e.agent_stats
            } else {
                &e.last_agent_episodes
            };
            agents.iter().copied()
        })
        .collect();
    let shape = [batch.len(), batch.envs()[0].agent_stats.len()];
    let d = PyDict::new(py);
    let f32s = |f: fn(&AgentStats) -> f32| PyArray1::from_iter(py, stats.iter().map(f));
    let i64s = |f: fn(&AgentStats) -> i64| PyArray1::from_iter(py, stats.iter().map(f));
    d.set_item("return", f32s(|s| s.ret).reshape(shape)?)?;
    d.set_item("length", i64s(|s| s.length as i64).reshape(shape)?)?;
    let success = PyArray1::from_iter(py, stats.iter().map(|s| s.success));
    d.set_item("success", success.reshape(shape)?)?;
    d.set_item("path_length", f32s(|s| s.path_length).reshape(shape)?)?;
    d.set_item("collisions", i64s(|s| s.collisions as i64).reshape(shape)?)?;
    Ok(d)
}

/// Raw sensor readings of the last observation, in the real robot's units: each carried
/// sensor's channels (shape (N, n_robots, values) or (N, n_robots)), then the body's
/// "wheel_speeds" (m/s), "encoders" (pulses) and "gyro_z" (rad/s); with `localization =
/// "odometry"` also "odometry" (the robot's dead-reckoned x, y in m and heading in rad); with
/// `task.led_action` also "leds" (its top LEDs' red, green, blue levels, 0..63).
pub fn sensor_readings<'py>(py: Python<'py>, batch: &CoreBatch) -> PyResult<Bound<'py, PyDict>> {
    let (n, r) = (batch.len(), batch.envs()[0].world.robots.len());
    let robots = || batch.envs().iter().flat_map(|e| e.world.robots.iter());
    let mut readout = Readout::default();
    for env in batch.envs() {
        for robot in &env.world.robots {
            env.world.sensors.readout(&robot.readings, &mut readout);
        }
    }
    let d = PyDict::new(py);
    for channel in readout.channels {
        let shape: Vec<usize> = if channel.per_robot == 0 {
            vec![n, r]
        } else {
            vec![n, r, channel.per_robot]
        };
        match channel.values {
            ChannelValues::Int(v) => {
                let v: Vec<i32> = v.into_iter().map(|x| x as i32).collect();
                d.set_item(channel.name, PyArray1::from_vec(py, v).reshape(shape)?)?;
            }
            ChannelValues::Real(v) => {
                d.set_item(channel.name, PyArray1::from_vec(py, v).reshape(shape)?)?;
            }
        }
    }
    let wheel_circumference =
        2.0 * std::f64::consts::PI * batch.scenario().robot.wheel_radius as f64;
    let wheels: Vec<f32> = robots().flat_map(|r| r.wheel_speeds).collect();
    d.set_item(
        "wheel_speeds",
        PyArray1::from_vec(py, wheels).reshape([n, r, 2])?,
    )?;
    let encoders: Vec<i64> = robots()
        .flat_map(|r| {
            r.wheel_travel
                .map(|t| (t / wheel_circumference * PULSES_PER_WHEEL_TURN).round() as i64)
        })
        .collect();
    d.set_item(
        "encoders",
        PyArray1::from_vec(py, encoders).reshape([n, r, 2])?,
    )?;
    if batch.scenario().task.localization == crate::scenario::Localization::Odometry {
        // The robot's own dead-reckoned pose (x, y, heading): what its observation is built from.
        let estimate: Vec<f32> = robots()
            .flat_map(|r| {
                [
                    r.odometry.position.x,
                    r.odometry.position.y,
                    r.odometry.heading,
                ]
            })
            .collect();
        d.set_item(
            "odometry",
            PyArray1::from_vec(py, estimate).reshape([n, r, 3])?,
        )?;
    }
    if batch.scenario().task.led_action {
        // What the agents' LED actions set: each robot's top LEDs, 0..63 per colour.
        let leds: Vec<i32> = robots()
            .flat_map(|r| r.led.map(|c| (c * crate::tasks::LED_LEVELS).round() as i32))
            .collect();
        d.set_item("leds", PyArray1::from_vec(py, leds).reshape([n, r, 3])?)?;
    }
    if !d.contains("gyro_z")? {
        // Without a gyroscope model carried (v0), the body's exact yaw rate over the step.
        let gyro: Vec<f32> = robots().map(|r| r.yaw_rate).collect();
        d.set_item("gyro_z", PyArray1::from_vec(py, gyro).reshape([n, r])?)?;
    }
    Ok(d)
}

/// An RGB frame (height, width, 3) uint8 of `env`, `size` = (width, height) pixels, magnified
/// `zoom` times about `center` (m; the arena's centre when None). The GIL is released while
/// drawing.
pub fn frame<'py>(
    py: Python<'py>,
    env: &Env,
    size: (u32, u32),
    zoom: f32,
    center: Option<(f32, f32)>,
) -> PyResult<Bound<'py, PyAny>> {
    let (width, height) = size;
    let bad = |key: &str, message: String| to_py(py, Error::config("<render>", key, message));
    if !(16..=4096).contains(&width) || !(16..=4096).contains(&height) {
        return Err(bad(
            "frame_size",
            format!("frame size must be 16..=4096 pixels a side, got {width}x{height}"),
        ));
    }
    if !(zoom.is_finite() && (1.0..=1000.0).contains(&zoom)) {
        return Err(bad("zoom", format!("must be in [1, 1000], got {zoom}")));
    }
    let centre = center.map_or(Vector::ZERO, |(x, y)| Vector::new(x, y));
    if !(centre.x.is_finite() && centre.y.is_finite()) {
        return Err(bad("center", format!("must be finite, got {center:?}")));
    }
    let view = View { zoom, centre };
    let rgb = py.detach(|| render_view(env, width, height, view));
    Ok(PyArray1::from_vec(py, rgb)
        .reshape([height as usize, width as usize, 3])?
        .into_any())
}

/// Geometry of one world for plots: the arena ("arena": inner (width, height), "walls":
/// whether walled, "wall_thickness"), "robot_radius", "goal_radius", "obstacles": a list of
/// dicts ("circle": center, radius; "box": center, half_extents, angle; "segment": end points
/// a, b), and "paths": the reference paths the task draws (lists of (x, y)), in metres and
/// radians.
pub fn scene<'py>(py: Python<'py>, env: &Env) -> PyResult<Bound<'py, PyDict>> {
    let scene = &env.world.scene;
    let d = PyDict::new(py);
    d.set_item("arena", scene.arena)?;
    d.set_item("walls", scene.walled)?;
    d.set_item("wall_thickness", scene.wall_thickness)?;
    d.set_item("robot_radius", env.cfg.robot.radius)?;
    d.set_item("goal_radius", env.cfg.task.goal_radius)?;
    let obstacles = PyList::empty(py);
    for shape in &scene.shapes {
        let o = PyDict::new(py);
        let c = (shape.center.x, shape.center.y);
        match shape.geometry {
            Geometry::Circle(b) => {
                o.set_item("kind", "circle")?;
                o.set_item("center", c)?;
                o.set_item("radius", b.radius)?;
            }
            Geometry::Box(b) => {
                o.set_item("kind", "box")?;
                o.set_item("center", c)?;
                o.set_item("half_extents", (b.half_extents.x, b.half_extents.y))?;
                o.set_item("angle", shape.angle)?;
            }
            Geometry::Segment(s) => {
                o.set_item("kind", "segment")?;
                o.set_item("a", (s.a.x + c.0, s.a.y + c.1))?;
                o.set_item("b", (s.b.x + c.0, s.b.y + c.1))?;
            }
        }
        obstacles.append(o)?;
    }
    d.set_item("obstacles", obstacles)?;
    // The reference paths the task draws (a tracking task's reference, a path to follow), each
    // a list of (x, y), closed ones ending at their first point.
    let mut marks = Vec::new();
    env.task_marks(&mut marks);
    let paths = PyList::empty(py);
    for mark in &marks {
        if let Mark::Path { points, closed, .. } = mark {
            let ends = points.first().filter(|_| *closed);
            let xy: Vec<(f32, f32)> = points.iter().chain(ends).map(|p| (p.x, p.y)).collect();
            paths.append(xy)?;
        }
    }
    d.set_item("paths", paths)?;
    Ok(d)
}
