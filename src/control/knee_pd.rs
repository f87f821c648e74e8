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
use std::sync::Arc;

/// Largest torque of the integral term (N m): the knee's effort class; beyond it the integral
/// stops growing (anti-windup).
pub const KNEE_INTEGRAL_LIMIT_NM: f64 = 300.0;

/// Knee PID gains (N m/rad, N m s/rad, N m/(rad s)) and the controller's leg model (its moment
/// arm turns the torque into a cylinder force).
#[derive(Debug, Clone)]
pub struct KneePd {
    /// Proportional gain (N m/rad). >= 0.
    pub kp_nm_per_rad: f64,
    /// Derivative gain (N m s/rad). >= 0.
    pub kd_nm_s_per_rad: f64,
    /// Integral gain (N m/(rad s)). >= 0; 0 leaves the integral out.
    pub ki_nm_per_rad_s: f64,
    /// The controller's leg (`controller.nominal_leg`).
    pub model: Arc<LegSpec>,
}

impl KneePd {
    /// The PD force (N) along the cylinder for a desired knee sample `desired` (rad, rad/s)
    /// and a knee reading `knee_rad`, `knee_rate_rad_s`, plus the integral torque
    /// `ki * integral_rad_s` (N m). 0 when every gain is 0.
    pub fn force_n(&self, desired: &RefSample, knee_rad: f64, knee_rate_rad_s: f64, integral_rad_s: f64) -> f64 {
        if self.kp_nm_per_rad == 0.0 && self.kd_nm_s_per_rad == 0.0 && self.ki_nm_per_rad_s == 0.0 {
            return 0.0;
        }
        let mut tau =
            self.kp_nm_per_rad * (desired.value - knee_rad) + self.kd_nm_s_per_rad * (desired.rate - knee_rate_rad_s);
        if self.ki_nm_per_rad_s > 0.0 {
            tau += self.ki_nm_per_rad_s * integral_rad_s;
        }
        tau / moment_arm_at(&self.model, knee_rad)
    }

    /// The knee-error integral (rad s) after `dt_s` more with error `error_rad`, held where
    /// its torque reaches [`KNEE_INTEGRAL_LIMIT_NM`].
    pub fn integrate(&self, integral_rad_s: f64, error_rad: f64, dt_s: f64) -> f64 {
        if self.ki_nm_per_rad_s == 0.0 {
            return 0.0;
        }
        let lim = KNEE_INTEGRAL_LIMIT_NM / self.ki_nm_per_rad_s;
        (integral_rad_s + error_rad * dt_s).clamp(-lim, lim)
    }
}
