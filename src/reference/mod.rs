//! Reference trajectories: what the controller is asked to track.
//!
//! Each reference gives its value and its first and second time derivatives analytically
//! (the ZNN and ERL-SMC laws need `x_d`, `dx_d/dt`, `d^2x_d/dt^2`).

mod gait;
mod knee_force;
mod subjects;
mod walking;
pub use gait::*;
pub use knee_force::*;
pub use subjects::{estimated_stride_s, read_subjects, StrideSource, SubjectRow, TrialRow};
pub use walking::*;

use serde::Serialize;
use std::sync::Arc;

/// A reference value and its first two time derivatives at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct RefSample {
    /// Value (N for a force reference, rad for an angle reference).
    pub value: f64,
    /// First time derivative (unit/s).
    pub rate: f64,
    /// Second time derivative (unit/s^2).
    pub accel: f64,
}

/// `offset + amplitude*sin(2*pi*f*t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sine {
    /// Amplitude (unit of the reference).
    pub amplitude: f64,
    /// Frequency (Hz).
    pub frequency_hz: f64,
    /// Phase (rad).
    pub phase_rad: f64,
    /// Constant offset (unit of the reference).
    pub offset: f64,
}

impl Sine {
    /// Value and derivatives at `t_s`.
    pub fn at(&self, t_s: f64) -> RefSample {
        let w = std::f64::consts::TAU * self.frequency_hz;
        let (s, c) = (w * t_s + self.phase_rad).sin_cos();
        RefSample {
            value: self.offset + self.amplitude * s,
            rate: self.amplitude * w * c,
            accel: -self.amplitude * w * w * s,
        }
    }
}

/// The force reference of a run: a sine, or a gait trajectory through the knee cascade's
/// feedforward (the outer PD part is added by the loop, see `control::KneePd`).
#[derive(Debug, Clone)]
pub enum ForceReference {
    /// Desired force directly.
    Sine(Sine),
    /// Knee (and hip) trajectory with the inverse-dynamics feedforward force.
    Gait(Arc<KneeForceReference>),
    /// A constant knee angle (rad), held by the outer loop alone (no feedforward).
    Pose {
        /// Knee flexion to hold (rad).
        knee_rad: f64,
    },
}

impl ForceReference {
    /// The knee trajectory sample (rad) at `t_s`, for gait references.
    pub fn knee_at(&self, t_s: f64) -> Option<RefSample> {
        match self {
            ForceReference::Gait(k) => Some(k.gait.knee_at(t_s)),
            ForceReference::Pose { knee_rad } => Some(RefSample { value: *knee_rad, ..Default::default() }),
            ForceReference::Sine(_) => None,
        }
    }

    /// The driven hip's trajectory (rad) at `t_s`, if the reference drives the hip.
    pub fn hip_at(&self, t_s: f64) -> Option<RefSample> {
        match self {
            ForceReference::Gait(k) if k.drives_hip() => Some(k.gait.hip_at(t_s)),
            _ => None,
        }
    }

    /// Stride time (s) of a gait reference.
    pub fn stride_s(&self) -> Option<f64> {
        match self {
            ForceReference::Gait(k) => Some(k.gait.stride_s),
            ForceReference::Sine(_) | ForceReference::Pose { .. } => None,
        }
    }

    /// The desired force at `t_s` with a held outer-loop force `pd_force_n` (N) added (gait
    /// and pose; a sine has no outer loop). On the carriage the leg's stance weight (from its
    /// detected contact, `human::GaitEvents`; without a detector the data's phase) blends the
    /// feedforward and gates the outer loop by `1 - w`.
    pub fn force_at(&self, t_s: f64, pd_force_n: f64, stance_weight: Option<RefSample>) -> RefSample {
        self.force_from(&self.force_parts(t_s), t_s, pd_force_n, stance_weight)
    }

    /// The parts of [`Self::force_at`] that depend on `t_s` alone (a loop keeps them for an
    /// instant it asks about again: the next sample's preview is the next step's present).
    pub fn force_parts(&self, t_s: f64) -> ForceParts {
        match self {
            ForceReference::Sine(s) => ForceParts::Sine(s.at(t_s)),
            ForceReference::Gait(k) => ForceParts::Gait(k.feedforward_parts(t_s)),
            ForceReference::Pose { .. } => ForceParts::Pose,
        }
    }

    /// [`Self::force_at`] from the `parts` of the same `t_s`.
    pub fn force_from(
        &self,
        parts: &ForceParts,
        t_s: f64,
        pd_force_n: f64,
        stance_weight: Option<RefSample>,
    ) -> RefSample {
        match (self, parts) {
            (ForceReference::Gait(k), ForceParts::Gait(p)) => {
                let w = k.stance_gate().map(|data| {
                    stance_weight.unwrap_or_else(|| RefSample {
                        value: data.stance_weight_at_pct(data.pct_at(t_s)),
                        ..Default::default()
                    })
                });
                let mut r = k.feedforward_from(p, w);
                r.value += pd_force_n * (1.0 - w.map_or(0.0, |w| w.value));
                r
            }
            (ForceReference::Sine(_), ForceParts::Sine(r)) => *r,
            (ForceReference::Pose { .. }, _) => RefSample { value: pd_force_n, ..Default::default() },
            // Parts of another reference: computed afresh.
            (ForceReference::Gait(_) | ForceReference::Sine(_), _) => {
                self.force_from(&self.force_parts(t_s), t_s, pd_force_n, stance_weight)
            }
        }
    }
}

/// What [`ForceReference::force_parts`] keeps of one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ForceParts {
    /// A sine's sample.
    Sine(RefSample),
    /// A gait reference's feedforward parts.
    Gait(FeedforwardParts),
    /// A pose (nothing depends on the time).
    Pose,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_derivatives_match_finite_differences() {
        let s = Sine { amplitude: 200.0, frequency_hz: 2.0, phase_rad: 0.3, offset: 5.0 };
        let (t, h) = (0.137, 1e-6);
        let a = s.at(t);
        let (p, m) = (s.at(t + h), s.at(t - h));
        assert!(((p.value - m.value) / (2.0 * h) - a.rate).abs() < 1e-4 * a.rate.abs().max(1.0));
        assert!(((p.rate - m.rate) / (2.0 * h) - a.accel).abs() < 1e-4 * a.accel.abs().max(1.0));
        assert_eq!(s.at(0.0).rate, 200.0 * std::f64::consts::TAU * 2.0 * 0.3f64.cos());
    }
}
