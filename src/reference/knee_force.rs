//! From a knee trajectory to a desired actuator force: the outer loop of the cascade.
//!
//! ```text
//! F_d(t) = F_ff(t) + F_pd
//! F_ff(t) = tau_id(q_d, qd_d, qdd_d, hip(t)) / (dL/dq)(q_d) + F_f(v_d),  v_d = dL/dq * qd_d
//! F_pd    = [k_p (q_d - q) + k_d (qd_d - qd)] / (dL/dq)(q)     (held between updates)
//! ```
//! `tau_id` is the inverse dynamics of the URDF leg's closed chain reduced to the knee
//! (gravity, inertia, velocity terms, and hip motion when the hip is driven), so `F_ff` is the
//! force the cylinder must deliver for the leg to follow the trajectory; the friction term
//! adds what the piston seal takes. The inner force loop (ZNN family or ERL-SMC) tracks F_d
//! exactly as in the paper. `F_ff` is tabulated over one stride and fitted with a periodic
//! Fourier series, so its first and second time derivatives (needed by the force controllers)
//! are analytic and smooth. The PD part's derivatives are taken as zero (it is updated once
//! per step or sample). The PD itself is a controller (`control::KneePd`).

use super::{FourierSeries, GaitReference, RefSample};
use crate::error::{Error, Result};
use crate::hydraulics::FrictionParams;
use crate::leg::{knee_inverse_dynamics, moment_arm_at, LegSpec};

/// Harmonics of the Fourier fit of the feedforward force over one stride.
const FF_HARMONICS: usize = 48;
/// Samples of the feedforward force over one stride.
const FF_SAMPLES: usize = 1024;

/// Desired cylinder force along a gait trajectory.
#[derive(Debug, Clone)]
pub struct KneeForceReference {
    /// The knee (and hip) trajectory.
    pub gait: GaitReference,
    ff: FourierSeries,
    drive_hip: bool,
}

impl KneeForceReference {
    /// Build the feedforward from the leg model. `drive_hip`: include the hip trajectory in
    /// the inverse dynamics (the thigh follows it).
    pub fn new(gait: GaitReference, model: &LegSpec, friction: &FrictionParams, drive_hip: bool) -> Result<Self> {
        let stride = gait.stride_s;
        let mut t = Vec::with_capacity(FF_SAMPLES);
        let mut f = Vec::with_capacity(FF_SAMPLES);
        for i in 0..FF_SAMPLES {
            let ti = i as f64 * stride / FF_SAMPLES as f64;
            let k = gait.knee_at(ti);
            let h = if drive_hip { gait.hip_at(ti) } else { RefSample::default() };
            let tau =
                knee_inverse_dynamics(model, (h.value, h.rate, h.accel), (k.value, k.rate, k.accel)).map_err(|e| {
                    Error::input("reference", "reference", format!("inverse dynamics at t = {ti:.4} s: {e}"))
                })?;
            let arm = moment_arm_at(model, k.value);
            t.push(ti);
            f.push(tau / arm + friction.force_n(arm * k.rate));
        }
        let ff = FourierSeries::fit(&t, &f, stride, FF_HARMONICS);
        Ok(Self { gait, ff, drive_hip })
    }

    /// Whether the hip is driven along the trial's hip angle.
    pub fn drives_hip(&self) -> bool {
        self.drive_hip
    }

    /// Feedforward force F_ff (N) and its first two time derivatives at `t_s`.
    pub fn feedforward_at(&self, t_s: f64) -> RefSample {
        let (value, rate, accel) = self.ff.eval(t_s);
        RefSample { value, rate, accel }
    }
}
