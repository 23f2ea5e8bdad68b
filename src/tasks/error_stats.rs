//! Error statistics of an episode, shared by the tracking, platoon and path-following tasks: the RMS
//! and largest error after a transient, the integral of the absolute error (IAE), and the time
//! the error fell below a radius for good.
//!
//! An episode that ends within the transient (lost) has its RMS and maximum over every step it
//! lasted. Units: the error's (m), seconds.

/// The running sums of one episode.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct ErrorStats {
    iae: f64,
    square_sum: f64,
    samples: u32,
    max: f32,
    square_sum_all: f64,
    max_all: f32,
    steps: u32,
    /// Step of the last error at or above the convergence radius (0: the start), if any.
    last_above: Option<u32>,
    above_now: bool,
}

impl ErrorStats {
    /// Starts an episode whose error at reset is `error` (m).
    pub fn start(error: f32, radius: f32) -> Self {
        let above_now = error >= radius;
        Self {
            above_now,
            last_above: above_now.then_some(0),
            ..Self::default()
        }
    }

    /// Records the error `error` (m) after step `step` (1, 2, ...) of `dt` s; steps from
    /// `transient` s on count in the RMS and maximum.
    pub fn record(&mut self, error: f32, step: u32, dt: f32, transient: f32, radius: f32) {
        let dt = dt as f64;
        self.steps = step;
        self.iae += error as f64 * dt;
        self.square_sum_all += (error as f64).powi(2);
        self.max_all = self.max_all.max(error);
        if step as f64 * dt >= transient as f64 - 1e-9 {
            self.square_sum += (error as f64).powi(2);
            self.samples += 1;
            self.max = self.max.max(error);
        }
        self.above_now = error >= radius;
        if self.above_now {
            self.last_above = Some(step);
        }
    }

    /// The RMS (m, in f64) and largest error (m): after the transient, or over every step if
    /// the episode ended within it.
    pub fn rms_max(&self) -> (f64, f32) {
        if self.samples > 0 {
            ((self.square_sum / self.samples as f64).sqrt(), self.max)
        } else {
            (
                (self.square_sum_all / self.steps.max(1) as f64).sqrt(),
                self.max_all,
            )
        }
    }

    /// Σ error·dt (m·s).
    pub fn iae(&self) -> f64 {
        self.iae
    }

    /// When the error fell below the radius for good (s), for a control step of `dt` s;
    /// infinite if it is above the radius now.
    pub fn converge_time(&self, dt: f32) -> f32 {
        match (self.above_now, self.last_above) {
            (true, _) => f32::INFINITY,
            (false, None) => 0.0,
            // Below the radius since the step after the last one above it.
            (false, Some(k)) => ((k as f64 + 1.0) * dt as f64) as f32,
        }
    }

    /// RMS and maximum (m), IAE (m·s) and convergence time (s; infinite if above the radius
    /// now) for a control step of `dt` s.
    pub fn write(&self, dt: f32, out: &mut [f32]) {
        let (rms, max) = self.rms_max();
        out[0] = rms as f32;
        out[1] = max;
        out[2] = self.iae as f32;
        out[3] = self.converge_time(dt);
    }
}
