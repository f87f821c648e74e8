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
use crate::leg::{knee_inverse_dynamics, moment_arm_at, moment_arm_curvature_at, LegSpec};
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
    assist_fit: Option<Arc<FourierSeries>>,
}

impl KneeForceReference {
    /// The Fourier fit of the inverse-dynamics force `tau_id / (dL/dq)` over a stride (the
    /// expensive part, shared by every run with the same leg, gait and hip motion).
    /// `with_hip`: include the hip trajectory in the inverse dynamics (the thigh follows it).
    pub fn inverse_dynamics_fit(gait: &GaitReference, model: &LegSpec, with_hip: bool) -> Result<FourierSeries> {
        Self::fit_over_stride(gait, |ti| {
            let k = gait.knee_at(ti);
            let h = if with_hip { gait.hip_at(ti) } else { RefSample::default() };
            let tau =
                knee_inverse_dynamics(model, (h.value, h.rate, h.accel), (k.value, k.rate, k.accel)).map_err(|e| {
                    Error::input("reference", "reference", format!("inverse dynamics at t = {ti:.4} s: {e}"))
                })?;
            Ok(tau / moment_arm_at(model, k.value))
        })
    }

    /// On the carriage, the Fourier fit of the stance assistance over a stride,
    /// `F_assist = -fraction * M_knee,data / (dL/dq)(q_d)` (the data's extensor moment as a
    /// flexion-positive torque over the moment arm).
    pub fn assist_fit(
        gait: &GaitReference,
        model: &LegSpec,
        walking: &WalkingData,
        fraction: f64,
    ) -> Result<FourierSeries> {
        Self::fit_over_stride(gait, |ti| {
            let arm = moment_arm_at(model, gait.knee_at(ti).value);
            Ok(-fraction * walking.knee_moment_at_pct(walking.pct_at(ti)) / arm)
        })
    }

    fn fit_over_stride(gait: &GaitReference, f: impl Fn(f64) -> Result<f64>) -> Result<FourierSeries> {
        let stride = gait.stride_s;
        let t: Vec<f64> = (0..FF_SAMPLES).map(|i| i as f64 * stride / FF_SAMPLES as f64).collect();
        let v = t.iter().map(|&ti| f(ti)).collect::<Result<Vec<f64>>>()?;
        Ok(FourierSeries::fit(&t, &v, stride, FF_HARMONICS))
    }

    /// The reference from a fit made by [`Self::inverse_dynamics_fit`] with the same gait,
    /// model and hip motion, and the seal friction to add. `drive_hip`: the plant's thigh
    /// follows the hip trajectory kinematically. `stance`: on the carriage, the walking data
    /// and the assistance fit ([`Self::assist_fit`]; None: no assistance): the stance weight
    /// then blends the feedforward from the inverse dynamics (swing) to the assistance
    /// (stance) and gates the outer loop (it acts in swing only).
    pub fn new(
        gait: GaitReference,
        model: Arc<LegSpec>,
        friction: FrictionParams,
        drive_hip: bool,
        id_fit: Arc<FourierSeries>,
        stance: Option<(Arc<WalkingData>, Option<Arc<FourierSeries>>)>,
    ) -> Self {
        let (stance, assist_fit) = match stance {
            Some((w, a)) => (Some(w), a),
            None => (None, None),
        };
        Self { gait, id_fit, assist_fit, model, friction, drive_hip, stance }
    }

    /// The walking data whose stance gates the outer loop (carriage), if any.
    pub fn stance_gate(&self) -> Option<&WalkingData> {
        self.stance.as_deref()
    }

    /// The seal friction along the trajectory, `F_f(v_d(t))` (N), with its first two time
    /// derivatives.
    pub fn friction_at(&self, t_s: f64) -> RefSample {
        let (q, qd, qdd, qddd) = self.gait.knee_jerk_at(t_s);
        let m = &self.model;
        // One evaluation of the cylinder's triangle for L' and L'' (the same values the
        // single-purpose functions give).
        let (_, l1, l2) = crate::leg::geometry::cylinder_kinematics_at(m, q);
        let l3 = moment_arm_curvature_at(m, q);
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

    /// Feedforward force F_ff = F_id + F_f (N) and its first two time derivatives at `t_s`;
    /// on the carriage with the stance weight `w` (and its rates):
    /// `F_ff = (1 - w) F_id + w F_assist + F_f`.
    pub fn feedforward_at(&self, t_s: f64, stance_weight: Option<RefSample>) -> RefSample {
        self.feedforward_from(&self.feedforward_parts(t_s), stance_weight)
    }

    /// The parts of [`Self::feedforward_at`] that depend on the time alone (the Fourier series
    /// and the friction): what a loop may keep for an instant it asks about again.
    pub fn feedforward_parts(&self, t_s: f64) -> FeedforwardParts {
        // The pair gives the same bits as the single evaluation (tested in `gait`).
        let (id, assist) = match &self.assist_fit {
            Some(f) => self.id_fit.eval_pair(f, t_s),
            None => (self.id_fit.eval(t_s), (0.0, 0.0, 0.0)),
        };
        FeedforwardParts { id, assist, friction: self.friction_at(t_s) }
    }

    /// [`Self::feedforward_at`] from its time's `parts`.
    pub fn feedforward_from(&self, parts: &FeedforwardParts, stance_weight: Option<RefSample>) -> RefSample {
        let weighted = stance_weight.filter(|_| self.stance.is_some());
        let (mut value, mut rate, mut accel) = parts.id;
        let b = match (weighted, &self.assist_fit) {
            (Some(_), Some(_)) => parts.assist,
            _ => (0.0, 0.0, 0.0),
        };
        if let Some(w) = weighted {
            let (d0, d1, d2) = (b.0 - value, b.1 - rate, b.2 - accel);
            accel += w.value * d2 + 2.0 * w.rate * d1 + w.accel * d0;
            rate += w.value * d1 + w.rate * d0;
            value += w.value * d0;
        }
        let f = parts.friction;
        RefSample { value: value + f.value, rate: rate + f.rate, accel: accel + f.accel }
    }
}

/// The time-only parts of the feedforward at one instant (see
/// [`KneeForceReference::feedforward_parts`]): the inverse-dynamics and assistance series'
/// values with two time derivatives (N, N/s, N/s^2) and the seal friction's.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FeedforwardParts {
    id: (f64, f64, f64),
    assist: (f64, f64, f64),
    friction: RefSample,
}
