//! KheperaIV-DroneFollow: the quadcopter of the KH4VREP paper's Fig. 8 follows a Khepera IV
//! (docs/task-design.md §7). Robot 0, the Khepera, drives a closed route of random waypoints
//! (scripted: position control, eqs. 1–4, then Braitenberg avoidance, eqs. 5–7, as the
//! Formation task's leader; the next waypoint once within `waypoint_radius`). The agent is the
//! drone ([`model`]): its action is the normalised horizontal acceleration command (x, y in the
//! world frame; the drone holds its yaw), its autopilot holds the altitude and climbs to search
//! when the robot has been out of view for `search_delay`.
//!
//! Observation (the drone's; no ground truth): `camera_offset` (the robot's offset in image
//! coordinates, the unit disc; 0 when unseen), `seen` (1 or 0), `relative_velocity` (the change
//! of the robot's offset in metres over the last step, m/s, 0 unless seen on both frames),
//! `drone_velocity` (m/s) and `altitude` (m). Reward per step: −‖p_drone − p_robot‖ (horizontal,
//! m) − `unseen_penalty`·[not seen]. Terminated (lost) when the robot has been out of view for
//! `lost_time` s; truncated at `task.max_steps`. Extra statistics: `horizontal_error_rms` (m),
//! `in_view_share`, `altitude_error_rms` (m, against the tracking height). `targets()` gives
//! the drone's horizontal position; `goals()` the robot's current waypoint.
//!
//! With `drone.driver = "agent"` the Khepera is a second agent, `robot`, instead of the script:
//! it observes Nav's blocks toward its current waypoint (sensors, distance, bearing, wheel
//! speeds) and earns Nav's reward toward it (progress, time cost, collision penalty) plus
//! `task.success_bonus` at each waypoint reached; its episode ends with the drone's.
//!
//! Units: metres, seconds, radians; world frame (x right, y up), z up.

pub mod config;
pub mod model;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use super::nav;
use super::{Agent, AgentFacts, Body, Column, Driver, Scoring, Task, TaskInfo};
use crate::config::ConfigTable;
use crate::controllers::position::twist_to_wheels;
use crate::controllers::{Braitenberg, PositionControl};
use crate::draw::{Mark, PALETTE};
use crate::error::Result;
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;
use config::check_section;
pub use config::{DroneConfig, MAX_ROUTE_POINTS};
use model::{Drone, DroneParams};

/// Substeps of the drone's dynamics per control step.
const DRONE_SUBSTEPS: u32 = 4;

/// DroneFollow: a drone follows a Khepera IV driving a route.
pub const DRONE_FOLLOW: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-DroneFollow"),
    summary: "a quadcopter (the agent) follows a Khepera IV driving a route of random waypoints, \
              keeping it in its downward camera's view (paper Fig. 8)",
    schema: TaskSchema {
        name: "dronefollow",
        since: 1,
        defaults: r#"
[task]
max_steps = 800              # 40 s (docs/task-design.md §7)
"#,
        section: Some(Section {
            name: "drone",
            keys: DroneConfig::KEYS,
            check: check_section,
        }),
    },
    scoring: Scoring {
        success: None,
        termination: Some("lost"),
        speed: false,
        columns: &[
            Column {
                stat: "in_view_share",
                header: "in view %",
                scale: 100.0,
                digits: 1,
            },
            Column {
                stat: "horizontal_error_rms",
                header: "horizontal RMS cm",
                scale: 100.0,
                digits: 2,
            },
        ],
        ..Scoring::GOAL
    },
    agents: AgentFacts {
        // The drone is the task's own vehicle, not a robot; with `driver = "agent"` the
        // Khepera joins it as a second agent of another kind.
        alike: false,
        ..AgentFacts::ONE
    },
};

/// Per-world state of the drone-following task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct DroneFollow {
    /// The drone.
    pub drone: Drone,
    params: DroneParams,
    /// Its command (normalised acceleration, world frame).
    pub command: Vector,
    /// The robot's closed route (m).
    pub route: Vec<Vector>,
    /// The waypoint the robot heads for.
    pub next: usize,
    start: Vector,
    start_offset: f32,
    robot_control: PositionControl,
    avoidance: Braitenberg,
    waypoint_radius: f32,
    lost_time: f32,
    unseen_penalty: f32,
    /// The robot's offset in image coordinates, if seen on the last frame.
    pub seen: Option<Vector>,
    previous: Option<Vector>,
    relative_velocity: Vector,
    error_squares: f64,
    altitude_squares: f64,
    in_view: u32,
    frames: u32,
    /// Who drives the robot (saved states from before the key: the script).
    #[serde(default = "scripted")]
    driver: Driver,
    /// The agent-driven robot's distance to its waypoint at the last step (m).
    #[serde(default)]
    prev_distance: f32,
    /// How far the drone flew (horizontally) on the last step (m): its agent's path; read in the
    /// step that sets it, so not saved.
    #[serde(skip)]
    step_travel: f32,
}

fn scripted() -> Driver {
    Driver::Scripted
}

impl DroneFollow {
    /// The drone agent's observation blocks.
    pub fn drone_blocks(cfg: &DroneConfig) -> ObsLayout {
        let v = cfg.speed_max;
        ObsLayout::new(vec![
            Block::new("camera_offset", 2, -1.0, 1.0),
            Block::new("seen", 1, 0.0, 1.0),
            Block::new("relative_velocity", 2, -4.0 * v, 4.0 * v),
            Block::new("drone_velocity", 2, -v, v),
            Block::new("altitude", 1, 0.0, cfg.search_altitude),
        ])
    }

    /// Where the camera sees the robot and how it moved since the last frame.
    fn look(&mut self, robot: Vector, dt: f32) {
        self.seen = self.drone.sees(robot, &self.params);
        let metres = self.seen.map(|o| o * self.drone.footprint(&self.params));
        self.relative_velocity = match (metres, self.previous) {
            (Some(now), Some(before)) => (now - before) / dt,
            _ => Vector::ZERO,
        };
        self.previous = metres;
        self.drone
            .update_search(self.seen.is_some(), dt, &self.params);
    }

    /// The agent-driven robot's reward: Nav's toward its waypoint ([`nav::progress_reward`],
    /// `distance` from it now, the bonus when it `reached` it); the next waypoint is then current.
    fn robot_reward(&mut self, world: &World, cfg: &Scenario, distance: f32, reached: bool) -> f32 {
        let robot = &world.robots[0];
        let reward =
            nav::progress_reward(cfg, self.prev_distance, distance, reached, robot.in_contact);
        self.prev_distance = if reached {
            (self.route[self.next] - robot.position).length()
        } else {
            distance
        };
        reward
    }
}

impl Task for DroneFollow {
    const EXTRA_STATS: &'static [&'static str] = &[
        "horizontal_error_rms",
        "in_view_share",
        "altitude_error_rms",
    ];

    fn new(cfg: &Scenario) -> Result<Self> {
        let d: DroneConfig = cfg.own()?;
        Ok(Self {
            drone: Drone::default(),
            params: d.params(),
            command: Vector::ZERO,
            route: vec![Vector::ZERO; d.route_points as usize],
            next: 0,
            start: Vector::ZERO,
            start_offset: d.start_offset,
            robot_control: PositionControl {
                vmax: d.robot_vmax,
                wmax: d.robot_wmax,
                kr: 0.15,
                stop_radius: 0.0,
            },
            avoidance: Braitenberg::default(),
            waypoint_radius: d.waypoint_radius,
            lost_time: d.lost_time,
            unseen_penalty: d.unseen_penalty,
            seen: None,
            previous: None,
            relative_velocity: Vector::ZERO,
            error_squares: 0.0,
            altitude_squares: 0.0,
            in_view: 0,
            frames: 0,
            driver: d.driver,
            prev_distance: 0.0,
            step_travel: 0.0,
        })
    }

    fn spawn(_cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Single)
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        let d: DroneConfig = cfg.own()?;
        // The drone is the task's vehicle 0.
        let mut agents = vec![Agent {
            name: "drone".into(),
            body: Body::Vehicle(0),
            layout: Self::drone_blocks(&d),
        }];
        if d.driver == Driver::Agent {
            agents.push(Agent {
                name: "robot".into(),
                body: Body::Robot(0),
                layout: nav::nav_blocks(cfg),
            });
        }
        Ok(agents)
    }

    /// Draws the route (inside the arena, 0.2 m from the walls) and the drone's start offset.
    fn arrange(&mut self, cfg: &Scenario, rng: &mut ChaCha8Rng, _layout: &mut Layout) {
        let hx = (0.5 * cfg.arena.width - 0.2).max(0.05);
        let hy = (0.5 * cfg.arena.height - 0.2).max(0.05);
        for point in &mut self.route {
            *point = Vector::new(rng.random_range(-hx..=hx), rng.random_range(-hy..=hy));
        }
        let angle = rng.random_range(-std::f32::consts::PI..std::f32::consts::PI);
        let radius = self.start_offset * rng.random_range(0.0f32..=1.0).sqrt();
        self.start = Vector::new(angle.cos(), angle.sin()) * radius;
    }

    fn reset(&mut self, world: &World, _layout: &Layout) {
        let robot = world.robots[0].position;
        self.drone = Drone {
            position: robot + self.start,
            velocity: Vector::ZERO,
            altitude: self.params.track_altitude,
            altitude_ref: self.params.track_altitude,
            unseen_for: 0.0,
        };
        self.command = Vector::ZERO;
        self.next = 0;
        self.previous = None;
        self.look(robot, world.dt());
        self.error_squares = 0.0;
        self.altitude_squares = 0.0;
        self.in_view = 0;
        self.frames = 0;
        self.prev_distance = (self.route[0] - robot).length();
    }

    /// The scripted robot: position control toward its waypoint, then Braitenberg avoidance
    /// (nothing when an agent drives it: its action set the wheels).
    fn before_step(&self, world: &mut World) {
        if self.driver == Driver::Agent {
            return;
        }
        let Some(&waypoint) = self.route.get(self.next) else {
            return;
        };
        let local = nav::to_robot_frame(world, 0, waypoint);
        let (v, w) = self
            .robot_control
            .twist(local.length(), local.y.atan2(local.x));
        let mut proximity = [0.0f32; crate::sensors::IR_COUNT];
        if let Some(ir) = &world.sensors.ir {
            for (p, raw) in proximity.iter_mut().zip(world.robots[0].readings.ir.raw) {
                *p = ir.sensor.model.normalise(raw);
            }
        }
        let axle = world.drive.axle_length;
        let wheels = self
            .avoidance
            .apply(twist_to_wheels(v, w, axle), &proximity);
        let vmax = world.drive.max_wheel_speed;
        world.robots[0].wheel_command = wheels.map(|s| s.clamp(-vmax, vmax));
    }

    fn act(&mut self, vehicle: usize, action: [f32; 2]) {
        if vehicle == 0 {
            self.command = Vector::new(action[0], action[1]);
        }
    }

    fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        terminated: &mut [bool],
    ) -> bool {
        let dt = world.dt();
        let h = dt / DRONE_SUBSTEPS as f32;
        let before = self.drone.position;
        for _ in 0..DRONE_SUBSTEPS {
            self.drone.advance(self.command, h, &self.params);
        }
        self.step_travel = (self.drone.position - before).length();
        let robot = world.robots[0].position;
        let distance = (self.route[self.next] - robot).length();
        let reached = distance < self.waypoint_radius;
        if reached {
            self.next = (self.next + 1) % self.route.len();
        }
        if self.driver == Driver::Agent {
            rewards[1] = self.robot_reward(world, cfg, distance, reached);
        }
        self.look(robot, dt);
        let error = (self.drone.position - robot).length();
        let seen = self.seen.is_some();
        rewards[0] = -error - if seen { 0.0 } else { self.unseen_penalty };
        let lost = self.drone.unseen_for > self.lost_time - 1e-4;
        // The robot's episode (when an agent drives it) ends with the drone's.
        terminated.fill(lost);
        self.error_squares += f64::from(error * error);
        let dz = self.drone.altitude - self.params.track_altitude;
        self.altitude_squares += f64::from(dz * dz);
        self.in_view += u32::from(seen);
        self.frames += 1;
        false
    }

    fn vehicle_travel(&self, _vehicle: usize) -> f32 {
        self.step_travel
    }

    fn extra_stats(&self, out: &mut [f32]) {
        let n = f64::from(self.frames.max(1));
        out[0] = (self.error_squares / n).sqrt() as f32;
        out[1] = (f64::from(self.in_view) / n) as f32;
        out[2] = (self.altitude_squares / n).sqrt() as f32;
    }

    /// Agent 0 flies the drone; agent 1 (with `driver = "agent"`) drives the robot.
    fn observe(&self, world: &World, cfg: &Scenario, agent: usize, out: &mut ObsWriter) {
        if agent == 1 {
            nav::observe_robot(world, 0, self.route[self.next], cfg, out);
            return;
        }
        let offset = self.seen.unwrap_or(Vector::ZERO);
        let v = self.params.speed_max;
        out.put(offset.x.clamp(-1.0, 1.0));
        out.put(offset.y.clamp(-1.0, 1.0));
        out.put(if self.seen.is_some() { 1.0 } else { 0.0 });
        out.put(self.relative_velocity.x.clamp(-4.0 * v, 4.0 * v));
        out.put(self.relative_velocity.y.clamp(-4.0 * v, 4.0 * v));
        out.put(self.drone.velocity.x.clamp(-v, v));
        out.put(self.drone.velocity.y.clamp(-v, v));
        out.put(self.drone.altitude.clamp(0.0, self.params.search_altitude));
    }

    fn goals(&self) -> Vec<Vector> {
        self.route.get(self.next).copied().into_iter().collect()
    }

    fn targets(&self, _world: &World) -> Vec<Vector> {
        vec![self.drone.position]
    }

    fn fits(&self, twin: &Self) -> bool {
        self.route.len() == twin.route.len()
    }

    fn draw(&self, _world: &World, cfg: &Scenario, marks: &mut Vec<Mark>) {
        marks.push(Mark::Path {
            points: self.route.clone(),
            colour: [150, 150, 150],
            alpha: 160,
            width: 0.006,
            closed: true,
        });
        if let Some(goal) = self.goals().first() {
            marks.push(nav::goal_mark(*goal, cfg, None));
        }
        let radius = self.drone.footprint(&self.params);
        let footprint: Vec<Vector> = (0..48)
            .map(|k| {
                let a = k as f32 * std::f32::consts::TAU / 48.0;
                self.drone.position + Vector::new(a.cos(), a.sin()) * radius
            })
            .collect();
        let colour = if self.seen.is_some() {
            PALETTE[2]
        } else {
            PALETTE[4]
        };
        marks.push(Mark::Path {
            points: footprint,
            colour,
            alpha: 200,
            width: 0.008,
            closed: true,
        });
        // Larger than a robot, so that it shows above the Khepera it follows.
        marks.push(Mark::Cross {
            position: self.drone.position,
            size: 0.12,
            colour,
        });
    }
}
