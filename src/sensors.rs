//! What the controller sees: ideal signals (continuous mode) or sampled, held readings
//! with derivatives computed the way firmware does (sampled mode).
//!
//! In sampled mode the load-cell derivative x2 and the piston velocity and acceleration are
//! backward differences of the sampled readings, optionally passed through a first-order
//! low-pass (`sensors.derivative_cutoff_hz`, 0 = no filter). x2 is never rebuilt from the
//! nominal model (that would hide exactly the disturbances the observer exists to see).

use crate::control::Measurement;
use serde::{Deserialize, Serialize};

/// Sensor parameters (scenario section `[sensors]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// Cut-off of the first-order low-pass on differentiated signals (Hz); 0 = raw difference.
    pub derivative_cutoff_hz: f64,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            derivative_cutoff_hz: 0.0,
        }
    }
}

/// True plant signals at one instant (what ideal sensors would read).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Truth {
    /// Load force F_L (N).
    pub force_n: f64,
    /// dF_L/dt (N/s).
    pub force_rate_n_per_s: f64,
    /// Spool position (m).
    pub spool_m: f64,
    /// Piston position (m).
    pub piston_m: f64,
    /// Piston velocity (m/s).
    pub piston_velocity_m_s: f64,
    /// Piston acceleration (m/s^2).
    pub piston_accel_m_s2: f64,
}

impl Truth {
    /// The ideal measurement: every signal exact, derivatives exact.
    pub fn ideal(&self) -> Measurement {
        Measurement {
            force_n: self.force_n,
            force_rate_n_per_s: self.force_rate_n_per_s,
            spool_m: self.spool_m,
            piston_m: self.piston_m,
            piston_velocity_m_s: self.piston_velocity_m_s,
            piston_accel_m_s2: self.piston_accel_m_s2,
        }
    }
}

/// Backward difference with optional first-order low-pass, at a fixed sample period.
#[derive(Debug, Clone, Default)]
struct Differentiator {
    prev: Option<f64>,
    out: f64,
}

impl Differentiator {
    fn update(&mut self, x: f64, ts: f64, alpha: f64) -> f64 {
        let raw = self.prev.map_or(0.0, |p| (x - p) / ts);
        self.prev = Some(x);
        self.out += alpha * (raw - self.out);
        self.out
    }
}

/// The sampled sensor chain. Holds the previous samples for the differences.
#[derive(Debug, Clone)]
pub struct SampledSensors {
    period_s: f64,
    alpha: f64,
    d_force: Differentiator,
    d_piston: Differentiator,
    d_piston_vel: Differentiator,
}

impl SampledSensors {
    /// Sensors sampled every `period_s` seconds.
    pub fn new(p: &SensorParams, period_s: f64) -> Self {
        // Exact discretisation of a first-order low-pass: alpha = 1 - exp(-2*pi*fc*Ts).
        let alpha = if p.derivative_cutoff_hz > 0.0 {
            1.0 - (-std::f64::consts::TAU * p.derivative_cutoff_hz * period_s).exp()
        } else {
            1.0
        };
        Self {
            period_s,
            alpha,
            d_force: Differentiator::default(),
            d_piston: Differentiator::default(),
            d_piston_vel: Differentiator::default(),
        }
    }

    /// Take one sample of the plant.
    pub fn sample(&mut self, truth: &Truth) -> Measurement {
        let (ts, a) = (self.period_s, self.alpha);
        let force_rate = self.d_force.update(truth.force_n, ts, a);
        let vel = self.d_piston.update(truth.piston_m, ts, a);
        let acc = self.d_piston_vel.update(vel, ts, a);
        Measurement {
            force_n: truth.force_n,
            force_rate_n_per_s: force_rate,
            spool_m: truth.spool_m,
            piston_m: truth.piston_m,
            piston_velocity_m_s: vel,
            piston_accel_m_s2: acc,
        }
    }
}
