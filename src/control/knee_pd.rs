//! The outer loop of the gait cascade: a PD on the knee angle that turns a knee error into a
//! cylinder force added to the inverse-dynamics feedforward.
//!
//! ```text
//! F_pd = [k_p (q_d - q) + k_d (qd_d - qd)] / (dL/dq)(q)
//! ```
//! It is updated once per step (continuous mode, from the plant's knee state) or once per
//! sample (sampled mode, from the encoder reading) and held in between.

use crate::leg::{moment_arm_at, LegSpec};
use crate::reference::RefSample;

/// Knee PD gains (N m/rad, N m s/rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KneePd {
    /// Proportional gain (N m/rad). >= 0.
    pub kp_nm_per_rad: f64,
    /// Derivative gain (N m s/rad). >= 0.
    pub kd_nm_s_per_rad: f64,
}

impl KneePd {
    /// The PD force (N) along the cylinder for a desired knee sample `desired` (rad, rad/s)
    /// and a knee reading `knee_rad`, `knee_rate_rad_s`. 0 when both gains are 0.
    pub fn force_n(&self, model: &LegSpec, desired: &RefSample, knee_rad: f64, knee_rate_rad_s: f64) -> f64 {
        if self.kp_nm_per_rad == 0.0 && self.kd_nm_s_per_rad == 0.0 {
            return 0.0;
        }
        let tau =
            self.kp_nm_per_rad * (desired.value - knee_rad) + self.kd_nm_s_per_rad * (desired.rate - knee_rate_rad_s);
        tau / moment_arm_at(model, knee_rad)
    }
}
