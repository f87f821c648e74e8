//! From a knee trajectory to a desired actuator force: the outer loop of the cascade.
//!
//! ```text
//! F_d(t) = F_id(t) + F_f(v_d(t)) + F_pd
//! F_id(t) = tau_id(q_d, qd_d, qdd_d, hip(t)) / (dL/dq)(q_d)       (Fourier fit over a stride)
//! F_f(v_d)  friction at v_d = dL/dq(q_d) qd_d, added analytically with its time derivatives
//! F_pd    = [k_p (q_d - q) + k_d (qd_d - qd)] / (dL/dq)(q)      (held between updates)
//! ```
//! `tau_id` is the inverse dynamics of the URDF leg's closed chain reduced to the knee
//! (gravity, inertia, velocity terms, and hip motion when the hip is driven), so `F_id` is the
//! force the cylinder must deliver for the leg to follow the trajectory. It is tabulated over
//! one stride and fitted with a periodic Fourier series, so its first and second time
//! derivatives (needed by the force controllers) are analytic and smooth. The seal friction
//! is not fitted (its `tanh(v / 1 mm/s)` is a near-step at every velocity reversal that no
//! Fourier series follows): it is added in closed form, with `dF_f/dt = F_f1(v) v1` and
//! `d2F_f/dt2 = F_f2(v) v1^2 + F_f1(v) v2`, where F_f1, F_f2 are its derivatives in the
//! velocity, `v1 = L2 qd^2 + L1 qdd`, `v2 = L3 qd^3 + 3 L2 qd qdd + L1 qddd`, and L1, L2, L3
//! the first three derivatives of the cylinder length in the knee angle. The PD part's
//! derivatives are taken as zero (it is updated once per step or sample). The PD itself is a
//! controller (`control::KneePd`).

use super::{FourierSeries, GaitReference, RefSample, WalkingData};
use crate::error::{Error, Result};
use crate::hydraulics::FrictionParams;
use crate::leg::{knee_inverse_dynamics, moment_arm_at, moment_arm_curvature_at, moment_arm_slope_at, LegSpec};
use std::sync::Arc;

/// Harmonics of the Fourier fit of the inverse-dynamics force over one stride.
const FF_HARMONICS: usize = 48;
/// Samples of the inverse-dynamics force over one stride.
const FF_SAMPLES: usize = 1024;

/// Desired cylinder force along a gait trajectory.
#[derive(Debug, Clone)]
pub struct KneeForceReference {
    /// The knee (and hip) trajectory.
    pub gait: GaitReference,
    id_fit: Arc<FourierSeries>,
    model: Arc<LegSpec>,
    friction: FrictionParams,
    drive_hip: bool,
    stance: Option<Arc<WalkingData>>,
}

impl KneeForceReference {
    /// The Fourier fit of the inverse-dynamics force `tau_id / (dL/dq)` over a stride (the
    /// expensive part, shared by every run with the same leg, gait and hip motion).
    /// `with_hip`: include the hip trajectory in the inverse dynamics (the thigh follows it).
    /// `assist`: on the carriage, the walking data and the assistance fraction: the fitted
    /// force is then `(1 - w) F_id + w F_assist` with the stance weight `w` and
    /// `F_assist = -fraction * M_knee,data / (dL/dq)(q_d)` (the data's extensor moment as a
    /// flexion-positive torque over the moment arm).
    pub fn inverse_dynamics_fit(
        gait: &GaitReference,
        model: &LegSpec,
        with_hip: bool,
        assist: Option<(&WalkingData, f64)>,
    ) -> Result<FourierSeries> {
        let stride = gait.stride_s;
        let mut t = Vec::with_capacity(FF_SAMPLES);
        let mut f = Vec::with_capacity(FF_SAMPLES);
        for i in 0..FF_SAMPLES {
            let ti = i as f64 * stride / FF_SAMPLES as f64;
            let k = gait.knee_at(ti);
            let h = if with_hip { gait.hip_at(ti) } else { RefSample::default() };
            let tau =
                knee_inverse_dynamics(model, (h.value, h.rate, h.accel), (k.value, k.rate, k.accel)).map_err(|e| {
                    Error::input("reference", "reference", format!("inverse dynamics at t = {ti:.4} s: {e}"))
                })?;
            let arm = moment_arm_at(model, k.value);
            let f_id = tau / arm;
            t.push(ti);
            f.push(match assist {
                None => f_id,
                Some((w, fraction)) => {
                    let pct = w.pct_at(ti);
                    let weight = w.stance_weight_at_pct(pct);
                    let f_assist = -fraction * w.knee_moment_at_pct(pct) / arm;
                    (1.0 - weight) * f_id + weight * f_assist
                }
            });
        }
        Ok(FourierSeries::fit(&t, &f, stride, FF_HARMONICS))
    }

    /// The reference from a fit made by [`Self::inverse_dynamics_fit`] with the same gait,
    /// model and hip motion, and the seal friction to add. `drive_hip`: the plant's thigh
    /// follows the hip trajectory kinematically. `stance`: on the carriage, the walking data
    /// whose stance weight gates the outer loop (it acts in swing only).
    pub fn new(
        gait: GaitReference,
        model: Arc<LegSpec>,
        friction: FrictionParams,
        drive_hip: bool,
        id_fit: Arc<FourierSeries>,
        stance: Option<Arc<WalkingData>>,
    ) -> Self {
        Self { gait, id_fit, model, friction, drive_hip, stance }
    }

    /// Whether the outer loop is gated by the stance (carriage).
    pub fn stance_gated(&self) -> bool {
        self.stance.is_some()
    }

    /// Weight of the outer loop at `t_s`: 1, or on the carriage 1 - the stance weight.
    pub fn outer_loop_weight(&self, t_s: f64) -> f64 {
        self.stance.as_ref().map_or(1.0, |w| 1.0 - w.stance_weight_at_pct(w.pct_at(t_s)))
    }

    /// The seal friction along the trajectory, `F_f(v_d(t))` (N), with its first two time
    /// derivatives.
    pub fn friction_at(&self, t_s: f64) -> RefSample {
        let (q, qd, qdd, qddd) = self.gait.knee_jerk_at(t_s);
        let m = &self.model;
        let (l1, l2, l3) = (moment_arm_at(m, q), moment_arm_slope_at(m, q), moment_arm_curvature_at(m, q));
        let v = l1 * qd;
        let v1 = l2 * qd * qd + l1 * qdd;
        let v2 = l3 * qd * qd * qd + 3.0 * l2 * qd * qdd + l1 * qddd;
        let (f, f1, f2) = self.friction.force_and_derivatives(v);
        RefSample { value: f, rate: f1 * v1, accel: f2 * v1 * v1 + f1 * v2 }
    }

    /// Whether the hip is driven along the trial's hip angle.
    pub fn drives_hip(&self) -> bool {
        self.drive_hip
    }

    /// Feedforward force F_ff = F_id + F_f (N) and its first two time derivatives at `t_s`.
    pub fn feedforward_at(&self, t_s: f64) -> RefSample {
        let (value, rate, accel) = self.id_fit.eval(t_s);
        let f = self.friction_at(t_s);
        RefSample { value: value + f.value, rate: rate + f.rate, accel: accel + f.accel }
    }
}
