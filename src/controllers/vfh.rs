//! Vector Field Histogram (paper eqs. 8–11, after Ulrich & Borenstein 2000), with the obstacle
//! enlargement and the direction choice of VFH+ (Ulrich & Borenstein 1998), on observations.
//!
//! **Histogram.** It is rebuilt from the current 8 IR and 5 ultrasonic readings at every step
//! (no memory: the controller is stateless). Each reading is an obstacle at its sensor's bearing
//! β and a distance d from the rim: for the IR ring the K-Team response curve inverted (the
//! sensor's own model, [`IrModel::mean_raw`], with the observation's floor `ir_floor_value`),
//! for a sonar its range (a "too close" reading counts as an echo at `us_min_range`, the nearest
//! distance the sensor reports, as the ARGoS and Webots models saturate it; anything nearer is
//! the IR ring's). It adds its magnitude (IR: the proximity p in [0, 1]; sonar: 1 − d/us_range
//! for echoes closer than `us_range`) to every sector within
//!
//! ```text
//! half its beam + γ,   γ = asin(min(1, (r_r + d_s) / (r_r + d)))     (VFH+ eq. 4)
//! ```
//!
//! of β: VFH+'s enlargement, which blocks every direction whose straight path would pass within
//! the robot's radius r_r plus a safety distance d_s of the obstacle (γ = 90° once it is within
//! d_s of the rim). The histogram is then smoothed over neighbouring sectors; sectors under
//! `threshold` are free.
//!
//! **Direction (VFH+ §3.4).** Each free valley at least `min_valley` wide offers candidates: a
//! narrow valley its centre; a wide one each edge `min_valley / 2` inside, and the goal bearing
//! when it lies between them (so a valley wrapping round the robot, one obstacle ahead, offers a
//! left and a right way past it). The robot takes the candidate of least cost
//!
//! ```text
//! Δ(c, goal) + μ2·Δ(c, ahead) + μ3·Δ(c, previous) + switch_penalty·[c on the other side]
//! ```
//!
//! (VFH+ eq. 11 divided by μ1; `heading_weight` = μ2/μ1, `previous_weight` = μ3/μ1). Having no
//! memory, the controller reads its previous direction from the turn rate in the observation's
//! wheel speeds, inverting eq. 9 (θ = asin(ω/ω_max); a saturated turn stands for any direction
//! from 90° to 180° on its side), and a candidate on the other side of the current turn costs
//! `switch_penalty` more. Boxed in (no valley), it turns in place until one opens.
//!
//! **Speed (paper eqs. 8–11).** ω = ω_max·sin(θ_e) (eq. 9, at full rate once the direction is
//! behind); the density straight ahead h'_c, capped at h_m (eq. 11), slows it:
//! v' = v_max(1 − h'_c/h_m) (eq. 10), v = v'(1 − |ω|/ω_max) (eq. 8); near the goal the docking
//! law of eq. 3 caps v.
//!
//! **What changed for real contacts (v2), and why.** On frictional contacts the paper's VFH
//! (histogram without enlargement, goal clamped into the nearest valley) failed the paper's own
//! Fig. 6 scene in 20 of 20 runs and reached 34% of Avoid goals: it steered its shoulder past
//! the wall's end and the box (a graze then holds the robot), and in front of the wall its
//! single wide valley flipped sides with a few degrees of heading. The paper's robot had the
//! margin VFH+ adds (Ulrich & Borenstein 1998): obstacles enlarged by r_r + d_s, with d_s = 15 mm,
//! the distance the robot covers in one control step at v_max (the histogram is a step old when
//! the wheels act). The sonar's reading is a range along its axis (one ray in the model), so it
//! fills only its enlargement (`us_beam_width` 0); a 45° sonar beam at 40 cm blocked 30 cm wide
//! gaps the robot fits through. The IR readings keep the 45° beam that closes the ring's blind
//! zones. The paper's gains (v_max, ω_max, h_m, threshold, k_r) are unchanged.
//! docs/notes/controllers-v2.md has the measurements.
//!
//! **Limits.** With no memory, an obstacle that leaves every beam leaves the histogram: the
//! robot turns back toward the goal and zigzags (the paper's observation), and a thin wall
//! whose end lies between two IR rays is not seen at all (a robot pressed against one reads
//! nothing). With beams narrower than the sensors' 45° spacing the histogram also has blind
//! zones between sensors that look free; `beam_width = 10°` shows the paper's blind-zone
//! behaviour at its worst. VFH+'s hysteresis (two thresholds on the previous binary histogram)
//! and its masked histogram need state or a turning radius; the robot turns on the spot, and
//! the previous-direction cost stands in for the hysteresis.
//!
//! Units: metres, m/s, radians, rad/s; sector bearings in the robot frame (x forward, y left,
//! CCW).

use std::f32::consts::PI;

use super::{goal_of, non_negative, positive, Controller, GoalBlocks, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::sensors::ir::{IrModel, CURVE_RAW, IR_MAX_RAW};
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
        /// angular width an IR reading fills, centred on its sensor, before enlargement (rad; 45°: the ring's spacing, which closes its blind zones)
        beam_width: f32 = 0.7853981633974483,
        /// angular width a sonar reading fills before enlargement (rad; 0: its range is along its axis) [D: docs/notes/controllers-v2.md]
        us_beam_width: f32 = 0.0,
        /// narrowest free valley the robot steers into (rad; 30°)
        min_valley: f32 = 0.5235987755982988,
        /// weight of "close to straight ahead" against "close to the goal" (VFH+'s μ2/μ1) [S: Ulrich & Borenstein 1998, μ1:μ2:μ3 = 5:2:2]
        heading_weight: f32 = 0.4,
        /// weight of "close to the previous direction", read from the turn rate (VFH+'s μ3/μ1) [S: Ulrich & Borenstein 1998, 5:2:2]
        previous_weight: f32 = 0.4,
        /// extra cost (rad) of a candidate on the other side of the robot's current turn
        switch_penalty: f32 = 0.6,
        /// r_r of VFH+'s enlargement (m): the robot's radius [S: Khepera IV, 140.8 mm across]
        robot_radius: f32 = 0.0704,
        /// d_s of VFH+'s enlargement (m): the clearance kept from obstacles [D: v_max x dt, the way covered in one 50 ms control step at 0.3 m/s]
        safety_distance: f32 = 0.015,
        /// the IR observation's floor (raw count with nothing seen): the scenario's sensors.ir_floor_value
        ir_floor_value: f32 = 100.0,
        /// the IR range (m): the scenario's sensors.ir_range
        ir_range: f32 = 0.25,
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
    /// Angular width (rad) an IR reading fills around its sensor's bearing, before enlargement.
    pub beam_width: f32,
    /// Angular width (rad) a sonar reading fills around its sensor's bearing, before
    /// enlargement.
    pub us_beam_width: f32,
    /// Narrowest valley (rad) the robot will steer into; it aims at least half of it away
    /// from the valley's edges.
    pub min_valley: f32,
    /// Weight of "close to straight ahead" against "close to the goal" when choosing a
    /// direction (VFH+'s μ2/μ1; 0 chooses by the goal alone).
    pub heading_weight: f32,
    /// Weight of "close to the previous direction" (VFH+'s μ3/μ1).
    pub previous_weight: f32,
    /// Extra cost (rad) of a candidate on the other side of the robot's current turn.
    pub switch_penalty: f32,
    /// The robot's radius r_r (m): sensor distances are from its rim.
    pub robot_radius: f32,
    /// r_r + d_s of VFH+ (m): the robot's radius plus the clearance it keeps.
    pub enlargement_radius: f32,
    /// The IR observation's floor (raw count with nothing seen).
    pub ir_floor_value: f32,
    /// The IR range (m).
    pub ir_range: f32,
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
            ("robot_radius", self.robot_radius),
            ("ir_range", self.ir_range),
        ] {
            positive(who, name, v)?;
        }
        for (name, v) in [
            ("stop_radius", self.stop_radius),
            ("heading_weight", self.heading_weight),
            ("us_beam_width", self.us_beam_width),
            ("previous_weight", self.previous_weight),
            ("switch_penalty", self.switch_penalty),
            ("safety_distance", self.safety_distance),
            ("ir_floor_value", self.ir_floor_value),
        ] {
            non_negative(who, name, v)?;
        }
        if self.ir_floor_value >= IR_MAX_RAW {
            return Err(Error::Param(format!(
                "{who}: ir_floor_value must be below {IR_MAX_RAW}, got {}",
                self.ir_floor_value
            )));
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
            us_beam_width: self.us_beam_width,
            min_valley: self.min_valley,
            heading_weight: self.heading_weight,
            previous_weight: self.previous_weight,
            switch_penalty: self.switch_penalty,
            robot_radius: self.robot_radius,
            enlargement_radius: self.robot_radius + self.safety_distance,
            ir_floor_value: self.ir_floor_value,
            ir_range: self.ir_range,
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
        let turn_rate =
            (wheels[1] - wheels[0]) * self.wheels.max_wheel_speed / self.wheels.axle_length;
        let (v, w) = self.vfh.twist(ir, us, d, bearing, turn_rate);
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

    /// Distance (m) from the rim of an IR proximity `p`: the response curve inverted (None:
    /// nothing seen).
    pub fn ir_distance(&self, p: f32) -> Option<f32> {
        if p <= 0.0 {
            return None;
        }
        let ir = IrModel {
            range: self.ir_range,
            floor_value: self.ir_floor_value,
            noise_sigma: 0.0,
            // K-Team's curve: the controller knows no robot's own (sensors.ir_curve).
            curve: CURVE_RAW,
        };
        let raw = ir.floor_value + p.min(1.0) * (IR_MAX_RAW - ir.floor_value);
        let (mut near, mut far) = (0.0f32, ir.range);
        // The mean response falls with distance: bisect for where it reads `raw`.
        for _ in 0..20 {
            let mid = 0.5 * (near + far);
            if ir.mean_raw(Some(mid)) > raw {
                near = mid;
            } else {
                far = mid;
            }
        }
        Some(0.5 * (near + far))
    }

    /// VFH+'s enlargement angle γ = asin((r_r + d_s) / D) of an obstacle `rim_distance` (m) from
    /// the robot's rim (D from its centre); π/2 once it is within r_r + d_s.
    pub fn enlargement(&self, rim_distance: f32) -> f32 {
        let centre = self.robot_radius + rim_distance.max(0.0);
        (self.enlargement_radius / centre).min(1.0).asin()
    }

    /// Adds `magnitude` to every sector within half a beam, enlarged by VFH+'s γ for an
    /// obstacle `rim_distance` away, of `bearing`.
    pub fn add(&self, h: &mut [f32], bearing: f32, magnitude: f32, rim_distance: f32, beam: f32) {
        self.fill(h, bearing, rim_distance, beam, |slot| *slot += magnitude);
    }

    /// Calls `update` on every sector within half a beam, enlarged by VFH+'s γ for an obstacle
    /// `rim_distance` away, of `bearing` (at least its own sector).
    pub fn fill(
        &self,
        h: &mut [f32],
        bearing: f32,
        rim_distance: f32,
        beam: f32,
        mut update: impl FnMut(&mut f32),
    ) {
        let half = 0.5 * beam + self.enlargement(rim_distance);
        for (k, slot) in h.iter_mut().enumerate() {
            if angle_between(self.centre(k), bearing) <= half {
                update(slot);
            }
        }
        // A beam narrower than a sector still fills its own sector.
        if 2.0 * half < 2.0 * PI / self.sectors as f32 {
            update(&mut h[self.sector(bearing)]);
        }
    }

    /// Range magnitude 1 − d/us_range of an obstacle `rim_distance` (m) away (≤ 0: outside).
    pub fn range_magnitude(&self, rim_distance: f32) -> f32 {
        1.0 - rim_distance / self.us_range
    }

    /// Adds an IR proximity `p` seen at `bearing` (its magnitude: the proximity itself).
    pub fn add_ir(&self, h: &mut [f32], bearing: f32, p: f32) {
        if let Some(d) = self.ir_distance(p) {
            self.add(h, bearing, p, d, self.beam_width);
        }
    }

    /// Adds a range reading: an obstacle `rim_distance` (m) from the rim at `bearing`, in a
    /// beam `beam` wide; its magnitude 1 − d/us_range, nothing beyond `us_range`.
    pub fn add_range(&self, h: &mut [f32], bearing: f32, rim_distance: f32, beam: f32) {
        let magnitude = 1.0 - rim_distance / self.us_range;
        if magnitude > 0.0 {
            self.add(h, bearing, magnitude, rim_distance, beam);
        }
    }

    /// The histogram smoothed over neighbouring sectors (weights ¼, ½, ¼).
    pub fn smooth(&self, h: &[f32]) -> Vec<f32> {
        let n = self.sectors;
        (0..n)
            .map(|k| 0.25 * h[(k + n - 1) % n] + 0.5 * h[k] + 0.25 * h[(k + 1) % n])
            .collect()
    }

    /// The smoothed polar histogram of `ir` proximities and `us` normalised readings.
    pub fn histogram(&self, ir: &[f32], us: &[f32]) -> Vec<f32> {
        let mut h = vec![0.0f32; self.sectors];
        for k in 0..IR_COUNT {
            self.add_ir(&mut h, IR_BEARINGS[k], ir[k]);
        }
        for k in 0..US_COUNT {
            // "Too close" (0) saturates at the minimum range, as the ARGoS and Webots models of
            // the sensor report it; nearer obstacles are the IR ring's.
            let distance = (us[k] * self.us_max_range).max(self.us_min_range);
            self.add_range(&mut h, US_BEARINGS[k], distance, self.us_beam_width);
        }
        self.smooth(&h)
    }

    /// The steering direction (rad, robot frame): of VFH+'s candidate directions in the valleys
    /// of free sectors at least `min_valley` wide, the one of least cost, the robot turning at
    /// `turn_rate` (rad/s, CCW); None when no valley is wide enough.
    pub fn steer(&self, h: &[f32], goal_bearing: f32, turn_rate: f32) -> Option<f32> {
        // The previous direction, from eq. 9 inverted: ω = ω_max·sin(θ_e). Eq. 9 turns at full
        // rate for any direction more than 90° off, so a saturated turn rate (the wheels within
        // 5% of it) stands for any direction from 90° to 180° on its side.
        let previous = (turn_rate / self.wmax).clamp(-1.0, 1.0).asin();
        let saturated = turn_rate.abs() >= 0.95 * self.wmax;
        let from_previous = |dir: f32| {
            if saturated && dir * turn_rate > 0.0 && dir.abs() >= 0.5 * PI {
                0.0
            } else {
                angle_between(dir, previous)
            }
        };
        let n = self.sectors;
        let width = 2.0 * PI / n as f32;
        let free: Vec<bool> = h.iter().map(|v| *v < self.threshold).collect();
        if free.iter().all(|f| *f) {
            return Some(goal_bearing);
        }
        // Start scanning just after a blocked sector so valleys do not wrap.
        let first_blocked = free.iter().position(|f| !f)?;
        let mut best: Option<(f32, f32)> = None; // (cost, direction)
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
                            // VFH+'s cost (eq. 11 over μ1): near the goal, near straight ahead
                            // and near the previous direction.
                            let mut cost = angle_between(dir, goal_bearing)
                                + self.heading_weight * angle_between(dir, 0.0)
                                + self.previous_weight * from_previous(dir);
                            // Switching to the other side of the current turn costs extra,
                            // which stops a flip-flop between two ways past an obstacle.
                            if turn_rate * dir < 0.0 && dir.abs() > 0.05 {
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

    /// (v, ω) from one Nav-layout observation's sensors and goal; `turn_rate` is the robot's
    /// current turn rate (rad/s, CCW: right minus left wheel speed over the axle).
    pub fn twist(
        &self,
        ir: &[f32],
        us: &[f32],
        distance: f32,
        goal_bearing: f32,
        turn_rate: f32,
    ) -> (f32, f32) {
        if distance < self.stop_radius {
            return (0.0, 0.0);
        }
        self.twist_in(&self.histogram(ir, us), distance, goal_bearing, turn_rate)
    }

    /// (v, ω) in the smoothed histogram `h` toward a goal `distance` (m) away at `goal_bearing`
    /// (rad), turning at `turn_rate` (rad/s): the direction of least cost, eqs. 8–11 and the
    /// docking law of eq. 3.
    pub fn twist_in(
        &self,
        h: &[f32],
        distance: f32,
        goal_bearing: f32,
        turn_rate: f32,
    ) -> (f32, f32) {
        if distance < self.stop_radius {
            return (0.0, 0.0);
        }
        let Some(heading_error) = self.steer(h, goal_bearing, turn_rate) else {
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

    #[test]
    fn ir_distance_inverts_the_response_curve() {
        let vfh = Vfh::default();
        let ir = IrModel {
            range: 0.25,
            floor_value: 100.0,
            noise_sigma: 0.0,
            curve: CURVE_RAW,
        };
        for d in [0.005f32, 0.02, 0.05, 0.1, 0.15, 0.2] {
            let raw = ir.mean_raw(Some(d));
            let p = (raw - 100.0) / (IR_MAX_RAW - 100.0);
            let back = vfh.ir_distance(p).expect("seen");
            assert!(
                (back - d).abs() < 1e-3,
                "{d} m reads {p}, inverted to {back} m"
            );
        }
        assert_eq!(vfh.ir_distance(0.0), None);
    }

    #[test]
    fn enlargement_is_asin_of_radius_plus_safety_over_distance() {
        let vfh = Vfh::default();
        let r = vfh.robot_radius;
        let rs = vfh.enlargement_radius;
        assert!((rs - (0.0704 + 0.015)).abs() < 1e-6);
        // An obstacle 0.3 m from the rim: γ = asin((r_r + d_s) / (r_r + 0.3)).
        let gamma = vfh.enlargement(0.3);
        assert!((gamma - (rs / (r + 0.3)).asin()).abs() < 1e-6);
        // Within the safety distance of the rim it blocks the whole half-plane toward it.
        assert_eq!(vfh.enlargement(0.01), 0.5 * PI);
    }

    #[test]
    fn an_obstacle_at_the_shoulder_blocks_straight_ahead() {
        // The wall's end 1 cm off the front-left rim (p ≈ 0.95), nothing else seen: the path
        // straight ahead would graze it, so the enlarged histogram blocks it and the robot
        // turns right, away from it, even with the goal ahead and to the left.
        let vfh = Vfh::default();
        let mut ir = [0.0; 8];
        ir[2] = 0.95;
        let h = vfh.histogram(&ir, &[1.0; 5]);
        assert!(
            h[vfh.sector(0.0)] >= vfh.threshold,
            "ahead {}",
            h[vfh.sector(0.0)]
        );
        let (_, w) = vfh.twist(&ir, &[1.0; 5], 1.0, 0.2, 0.0);
        assert!(w < 0.0, "turns toward the obstacle: {w}");
    }

    #[test]
    fn a_turn_toward_one_side_of_an_obstacle_is_kept() {
        // A wall straight ahead seen by the front sonar only: a valley wraps round the robot with
        // a way past on either side. The robot already turning right keeps to the right even
        // with the goal 15° to the left; at rest it takes the goal's side.
        let vfh = Vfh::default();
        let us = [1.0, 1.0, 0.15, 1.0, 1.0]; // an echo 30 cm ahead
        let goal = 15f32.to_radians();
        let (_, turning_right) = vfh.twist(&[0.0; 8], &us, 1.0, goal, -vfh.wmax);
        let (_, at_rest) = vfh.twist(&[0.0; 8], &us, 1.0, goal, 0.0);
        assert!(turning_right < 0.0, "switched sides: {turning_right}");
        assert!(at_rest > 0.0, "not the goal's side: {at_rest}");
    }
}
