//! Vector Field Histogram (paper eqs. 8–11, after Ulrich & Borenstein 2000), on observations.
//!
//! A polar histogram of obstacle density is built from the 8 IR and 5 ultrasonic readings: each
//! sensor adds its obstacle magnitude to the sectors around its bearing (IR: the proximity
//! p in [0, 1]; ultrasonic: 1 − d/us_range for echoes closer than `us_range`), and the histogram
//! is smoothed over neighbouring sectors. Sectors under `threshold` are free. Each free valley
//! at least `min_valley` wide offers one direction, the goal bearing clamped `min_valley / 2`
//! inside its edges; the robot takes the one with the lowest VFH+-style cost (angle to the
//! goal, plus `heading_weight` × angle to straight ahead, plus `switch_penalty` for a valley on
//! the other side of its current turn, read from the wheel speeds in the observation), or turns
//! in place when boxed in. Then ω = ω_max·sin(θ_e) (eq. 9, at full rate once the direction is
//! behind); the density straight ahead h'_c, capped at h_m (eq. 11), slows it:
//! v' = v_max(1 − h'_c/h_m) (eq. 10), v = v'(1 − |ω|/ω_max) (eq. 8); near the goal the docking
//! law of eq. 3 caps v.
//!
//! An ultrasonic "too close" reading (an object nearer than the sensor's 25 cm minimum range,
//! observed as 0) counts as an echo at `us_min_range`, the nearest distance the sensor reports,
//! which is how the ARGoS and Webots models of the sensor saturate it; anything nearer is the
//! IR ring's to add. (Counting it as an obstacle at 0 m filled the sector ahead up to h_m
//! whenever something stood 10–25 cm ahead, where the IR proximity is still small, so eq. 10
//! held the robot there for good: the paper's Fig. 6 box.) With an obstacle that close the
//! robot creeps at a fraction of v_max, and eq. 10 stops it once the IR proximity ahead adds
//! the rest of h_m (about 8 cm from the obstacle with the defaults).
//!
//! Each reading fills the sectors within half a `beam_width` of its sensor's bearing; a valley
//! must be `min_valley` wide to be steered into. The histogram is rebuilt from the current
//! readings at every step (no memory), so an obstacle that leaves every beam leaves the
//! histogram: the robot turns away, loses sight of it, turns back toward the goal, sees it
//! again, and zigzags (the paper's observation). With beams narrower than the sensors' 45°
//! spacing (`beam_width` < 45°) the histogram also has blind zones between sensors that look
//! free; the default closes them for the IR ring, and `beam_width = 10°` shows the paper's
//! blind-zone behaviour at its worst.
//!
//! Units: metres, m/s, radians, rad/s; sector bearings in the robot frame (x forward, y left,
//! CCW).

use std::f32::consts::PI;

use super::{goal_of, non_negative, positive, Controller, GoalBlocks, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::sensors::{IR_BEARINGS, IR_COUNT, US_BEARINGS, US_COUNT};

crate::config_table! {
    /// Parameters of the Vector Field Histogram (eqs. 8–11).
    pub struct VfhParams {
        /// histogram sectors around the robot (4..360)
        sectors: usize = 36,
        /// smoothed density under which a sector is free
        threshold: f32 = 0.15,
        /// h_m of eqs. 10-11: the density ahead at which the robot stops
        hm: f32 = 0.6,
        /// v_max (m/s)
        vmax: f32 = 0.3,
        /// ω_max (rad/s)
        wmax: f32 = 3.0,
        /// docking radius k_r of eq. 3 (m)
        kr: f32 = 0.15,
        /// distance to the goal under which the robot stops (m)
        stop_radius: f32 = 0.02,
        /// ultrasonic echoes farther than this add nothing (m)
        us_range: f32 = 0.45,
        /// the ultrasonic observation's full scale (m): the scenario's sensors.us_max_range
        us_max_range: f32 = 2.0,
        /// the ultrasonic minimum range (m): a "too close" reading counts as an echo here
        us_min_range: f32 = 0.25,
        /// angular width a reading fills, centred on its sensor (rad; 45°)
        beam_width: f32 = 0.7853981633974483,
        /// narrowest free valley the robot steers into (rad; 30°)
        min_valley: f32 = 0.5235987755982988,
        /// weight of "close to straight ahead" against "close to the goal" (VFH+'s μ2/μ1)
        heading_weight: f32 = 0.4,
        /// extra cost (rad) of a valley on the other side of the robot's current turn
        switch_penalty: f32 = 0.6,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// VFH parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vfh {
    /// Histogram sectors around the robot.
    pub sectors: usize,
    /// Smoothed density under which a sector is free.
    pub threshold: f32,
    /// h_m: density ahead at which the robot stops (eqs. 10–11).
    pub hm: f32,
    /// v_max (m/s).
    pub vmax: f32,
    /// ω_max (rad/s).
    pub wmax: f32,
    /// Docking radius k_r (m), as in eq. 3.
    pub kr: f32,
    /// Stop distance (m).
    pub stop_radius: f32,
    /// Ultrasonic echoes farther than this (m) add nothing.
    pub us_range: f32,
    /// Ultrasonic full scale of the observation (m): the reading is distance / us_max_range.
    pub us_max_range: f32,
    /// Ultrasonic minimum range (m): a "too close" reading (observation 0) counts as an echo at
    /// this distance, the nearest the sensor reports; the IR ring covers what is nearer.
    pub us_min_range: f32,
    /// Angular width (rad) of the sectors a reading fills, centred on its sensor's bearing.
    pub beam_width: f32,
    /// Narrowest valley (rad) the robot will steer into; it aims at least half of it away
    /// from the valley's edges.
    pub min_valley: f32,
    /// Weight of "close to straight ahead" against "close to the goal" when choosing a valley
    /// (VFH+'s μ2/μ1; 0 chooses by the goal alone).
    pub heading_weight: f32,
    /// Extra cost (rad) of a valley on the other side of the robot's current turn.
    pub switch_penalty: f32,
}

impl Default for Vfh {
    /// The law of the default [`VfhParams`].
    fn default() -> Self {
        // The declared defaults are valid (tested): this cannot fail on user input.
        VfhParams::default()
            .law("vfh")
            .expect("the default VFH parameters are valid")
    }
}

impl VfhParams {
    /// The law of these parameters, checked.
    pub fn law(&self, who: &str) -> Result<Vfh> {
        if !(4..=360).contains(&self.sectors) {
            return Err(Error::Param(format!(
                "{who}: sectors must be in 4..=360, got {}",
                self.sectors
            )));
        }
        for (name, v) in [
            ("threshold", self.threshold),
            ("hm", self.hm),
            ("vmax", self.vmax),
            ("wmax", self.wmax),
            ("kr", self.kr),
            ("us_range", self.us_range),
            ("us_max_range", self.us_max_range),
            ("us_min_range", self.us_min_range),
            ("beam_width", self.beam_width),
            ("min_valley", self.min_valley),
        ] {
            positive(who, name, v)?;
        }
        for (name, v) in [
            ("stop_radius", self.stop_radius),
            ("heading_weight", self.heading_weight),
            ("switch_penalty", self.switch_penalty),
        ] {
            non_negative(who, name, v)?;
        }
        Ok(Vfh {
            sectors: self.sectors,
            threshold: self.threshold,
            hm: self.hm,
            vmax: self.vmax,
            wmax: self.wmax,
            kr: self.kr,
            stop_radius: self.stop_radius,
            us_range: self.us_range,
            us_max_range: self.us_max_range,
            us_min_range: self.us_min_range,
            beam_width: self.beam_width,
            min_valley: self.min_valley,
            heading_weight: self.heading_weight,
            switch_penalty: self.switch_penalty,
        })
    }
}

/// VFH on a Nav-like observation (`ir`, `us`, the goal blocks and `wheel_speeds`).
#[derive(Debug, Clone, PartialEq)]
pub struct VfhPolicy {
    /// The law.
    pub vfh: Vfh,
    /// The drive.
    pub wheels: WheelMap,
    goal: GoalBlocks,
    ir: usize,
    us: usize,
    wheel_speeds: usize,
    obs_dim: usize,
}

impl Controller for VfhPolicy {
    const NAME: &'static str = "vfh";
    const READS: &'static str = "nav";
    type Params = VfhParams;

    fn new(params: &VfhParams, layout: &ObsLayout) -> Result<Self> {
        Ok(Self {
            vfh: params.law(Self::NAME)?,
            wheels: WheelMap::new(Self::NAME, params.axle_length, params.max_wheel_speed)?,
            goal: GoalBlocks::find(layout, Self::NAME)?,
            ir: layout.require("ir", IR_COUNT, Self::NAME)?,
            us: layout.require("us", US_COUNT, Self::NAME)?,
            wheel_speeds: layout.require("wheel_speeds", 2, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let (d, bearing) = goal_of(obs, self.goal);
        let ir = &obs[self.ir..self.ir + IR_COUNT];
        let us = &obs[self.us..self.us + US_COUNT];
        let wheels = &obs[self.wheel_speeds..self.wheel_speeds + 2];
        let (v, w) = self.vfh.twist(ir, us, d, bearing, wheels[1] - wheels[0]);
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}

impl Vfh {
    /// Sector index of a robot-frame bearing.
    fn sector(&self, bearing: f32) -> usize {
        let width = 2.0 * PI / self.sectors as f32;
        let a = (bearing + PI).rem_euclid(2.0 * PI);
        ((a / width) as usize).min(self.sectors - 1)
    }

    fn centre(&self, k: usize) -> f32 {
        let width = 2.0 * PI / self.sectors as f32;
        -PI + (k as f32 + 0.5) * width
    }

    /// Adds `magnitude` to every sector within half a beam of `bearing`.
    fn add(&self, h: &mut [f32], bearing: f32, magnitude: f32) {
        for (k, slot) in h.iter_mut().enumerate() {
            if angle_between(self.centre(k), bearing) <= 0.5 * self.beam_width {
                *slot += magnitude;
            }
        }
        // A beam narrower than a sector still fills its own sector.
        if self.beam_width < 2.0 * PI / self.sectors as f32 {
            h[self.sector(bearing)] += magnitude;
        }
    }

    /// The smoothed polar histogram of `ir` proximities and `us` normalised readings.
    pub fn histogram(&self, ir: &[f32], us: &[f32]) -> Vec<f32> {
        let mut h = vec![0.0f32; self.sectors];
        for k in 0..IR_COUNT {
            self.add(&mut h, IR_BEARINGS[k], ir[k].max(0.0));
        }
        for k in 0..US_COUNT {
            // "Too close" (0) saturates at the minimum range, as the ARGoS and Webots models of
            // the sensor report it; nearer obstacles are the IR ring's.
            let distance = (us[k] * self.us_max_range).max(self.us_min_range);
            let magnitude = (1.0 - distance / self.us_range).max(0.0);
            self.add(&mut h, US_BEARINGS[k], magnitude);
        }
        let n = self.sectors;
        (0..n)
            .map(|k| 0.25 * h[(k + n - 1) % n] + 0.5 * h[k] + 0.25 * h[(k + 1) % n])
            .collect()
    }

    /// The steering direction (rad, robot frame): the goal bearing pulled into the nearest
    /// valley of free sectors at least `min_valley` wide, `min_valley / 2` clear of its edges;
    /// None when no valley is wide enough.
    pub fn steer(&self, h: &[f32], goal_bearing: f32, turning: f32) -> Option<f32> {
        let n = self.sectors;
        let width = 2.0 * PI / n as f32;
        let free: Vec<bool> = h.iter().map(|v| *v < self.threshold).collect();
        if free.iter().all(|f| *f) {
            return Some(goal_bearing);
        }
        // Start scanning just after a blocked sector so valleys do not wrap.
        let first_blocked = free.iter().position(|f| !f)?;
        let mut best: Option<(f32, f32)> = None; // (distance to goal, direction)
        let mut run_start = None;
        for step in 1..=n {
            let k = (first_blocked + step) % n;
            match (free[k], run_start) {
                (true, None) => run_start = Some(step),
                (false, Some(start)) => {
                    let len = step - start;
                    if len as f32 * width >= self.min_valley {
                        // Valley from the start of sector (first_blocked + start) to the end of
                        // sector (first_blocked + step - 1), as angles unwrapped from there.
                        let lo = self.centre((first_blocked + start) % n) - 0.5 * width;
                        let hi = lo + len as f32 * width;
                        let margin = 0.5 * self.min_valley;
                        // VFH+'s candidate directions: a narrow valley's centre; in a wide one,
                        // each edge `margin` inside, and the goal bearing when it lies between
                        // them (the goal unwrapped into [c - π, c + π] around the valley's
                        // centre c). Both edges are candidates, so that a valley wrapping round
                        // the robot (one obstacle ahead) offers a left and a right way past it,
                        // each judged by the cost below.
                        let centre = 0.5 * (lo + hi);
                        let g = centre + crate::robot::wrap_angle(goal_bearing - centre);
                        let candidates = if hi - lo <= 2.0 * margin {
                            [Some(centre), None, None]
                        } else {
                            let (left, right) = (lo + margin, hi - margin);
                            let inside = (left..=right).contains(&g).then_some(g);
                            [Some(left), Some(right), inside]
                        };
                        for dir in candidates.into_iter().flatten() {
                            let dir = crate::robot::wrap_angle(dir);
                            // VFH+'s cost: near the goal, and near straight ahead (which keeps
                            // the robot committed to the valley it is turning into).
                            let mut cost = angle_between(dir, goal_bearing)
                                + self.heading_weight * angle_between(dir, 0.0);
                            // The robot's own turn (from its wheel speeds) is the memory VFH+
                            // keeps as its previous direction: switching sides costs extra,
                            // which stops a flip-flop between two ways past an obstacle.
                            if turning * dir < 0.0 && dir.abs() > 0.05 {
                                cost += self.switch_penalty;
                            }
                            if best.is_none_or(|(c, _)| cost < c) {
                                best = Some((cost, dir));
                            }
                        }
                    }
                    run_start = None;
                }
                _ => {}
            }
        }
        best.map(|(_, dir)| dir)
    }

    /// (v, ω) from one Nav-layout observation's sensors and goal; `turning` is the sign of the
    /// robot's current turn (right minus left wheel speed).
    pub fn twist(
        &self,
        ir: &[f32],
        us: &[f32],
        distance: f32,
        goal_bearing: f32,
        turning: f32,
    ) -> (f32, f32) {
        if distance < self.stop_radius {
            return (0.0, 0.0);
        }
        let h = self.histogram(ir, us);
        let Some(heading_error) = self.steer(&h, goal_bearing, turning) else {
            // Boxed in (no valley wide enough): turn in place until one opens.
            return (0.0, self.wmax);
        };
        // Eq. 9, at full rate once the direction is behind (sin would fall back to 0 there).
        let w = if heading_error.abs() > 0.5 * PI {
            self.wmax * heading_error.signum()
        } else {
            self.wmax * heading_error.sin()
        };
        let hc = h[self.sector(0.0)].min(self.hm); // eq. 11

        let v_prime = self.vmax * (1.0 - hc / self.hm); // eq. 10
        let mut v = v_prime * (1.0 - w.abs() / self.wmax); // eq. 8
        if distance <= self.kr {
            v = v.min(distance * self.vmax / self.kr); // eq. 3 docking
        }
        (v.max(0.0), w)
    }
}

fn angle_between(a: f32, b: f32) -> f32 {
    crate::robot::wrap_angle(a - b).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_space_goes_straight_to_the_goal() {
        let vfh = Vfh::default();
        let (v, w) = vfh.twist(&[0.0; 8], &[1.0; 5], 1.0, 0.3, 0.0);
        assert!((w - 3.0 * 0.3f32.sin()).abs() < 1e-6);
        assert!(v > 0.0 && v < 0.3);
    }

    #[test]
    fn sonar_too_close_with_a_clear_ir_ring_creeps_instead_of_stopping() {
        let vfh = Vfh::default();
        let us = [1.0, 1.0, 0.0, 1.0, 1.0]; // front: closer than the 25 cm minimum range
        let h = vfh.histogram(&[0.0; 8], &us);
        let ahead = h[vfh.sector(0.0)];
        // Saturated at the minimum range: 1 − 0.25/0.45, under h_m but over the threshold.
        assert!(
            (ahead - (1.0 - 0.25 / 0.45)).abs() < 1e-5,
            "density ahead {ahead}"
        );
        let (v, w) = vfh.twist(&[0.0; 8], &us, 1.0, 0.0, 0.0);
        assert!(v > 0.0 && v < 0.3 * vfh.vmax, "v = {v}");
        assert!(w.abs() > 0.1, "does not turn toward a side valley: {w}");
    }

    #[test]
    fn sonar_too_close_and_ir_seeing_the_obstacle_stops() {
        let vfh = Vfh::default();
        let mut ir = [0.0; 8];
        ir[3] = 0.2; // front, about 7 cm
        let (v, _) = vfh.twist(&ir, &[1.0, 1.0, 0.0, 1.0, 1.0], 1.0, 0.0, 0.0);
        assert_eq!(v, 0.0);
    }

    #[test]
    fn obstacle_ahead_slows_and_turns_to_a_free_sector() {
        let vfh = Vfh::default();
        let mut ir = [0.0; 8];
        ir[3] = 0.5; // front
        let us = [1.0, 1.0, 0.1, 1.0, 1.0]; // front echo at 0.2 m
        let (v, w) = vfh.twist(&ir, &us, 1.0, 0.0, 0.0);
        assert!(w.abs() > 0.1, "does not turn: {w}");
        assert!(v < 0.1, "does not slow: {v}");
    }
}
