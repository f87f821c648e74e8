//! The ideal device (`controller.kind = "ideal_moment"`, issue 39): a massless actuator at the
//! knee that applies the data's biological knee moment (the subject's, on the run's gait
//! clock) of one sign, up to a bound, as the ideal assistive devices of simulation studies do
//! (Dembia et al. 2017; Bianco et al. 2022, whose bound was also 1 N m/kg). The cylinder is
//! disconnected (`actuator.mode = "free"`; its links are still worn): a design tool, not a
//! controller of the valve.
//!
//! ```text
//! M_dev(t) = clip(M_data(t), 0, B)        direction = "extension"   (extensor positive)
//!          = clip(M_data(t), -B, 0)       direction = "flexion"
//!          = clip(M_data(t), -B, B)       direction = "both"
//! B = max_nm_per_kg * subject mass
//! ```

use serde::{Deserialize, Serialize};

/// Which sign of the biological moment the device supplies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum IdealDirection {
    /// The extensor moment only.
    Extension,
    /// The flexor moment only.
    Flexion,
    /// Both.
    #[default]
    Both,
}

/// `[controller.ideal]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IdealParams {
    /// `"extension"`, `"flexion"` or `"both"` (default).
    pub direction: IdealDirection,
    /// The bound on the device's moment (N m per kg of the subject). Default 1.0 (Bianco et
    /// al. 2022's knee bound). 0..=5 (0: no moment, the baseline of `exoleg run --baseline`).
    pub max_nm_per_kg: f64,
    /// A step of moment the device adds from `step_at_s` on (N m, extensor positive): the
    /// wearer's reaction to a push (README, "A wearer as strong and as slow as a person").
    /// Default 0. -500..=500.
    pub step_nm: f64,
    /// When the step starts (s). Default 0. 0..=1e6.
    pub step_at_s: f64,
}

impl Default for IdealParams {
    fn default() -> Self {
        Self { direction: IdealDirection::Both, max_nm_per_kg: 1.0, step_nm: 0.0, step_at_s: 0.0 }
    }
}

impl IdealParams {
    /// Whether these are the defaults (left out of a recorded scenario).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// The device's knee moment (N m, extensor positive) from the data's `moment_nm` (extensor
    /// positive) for a subject of `mass_kg`.
    pub fn moment_nm(&self, moment_nm: f64, mass_kg: f64) -> f64 {
        let b = self.max_nm_per_kg * mass_kg;
        match self.direction {
            IdealDirection::Extension => moment_nm.clamp(0.0, b),
            IdealDirection::Flexion => moment_nm.clamp(-b, 0.0),
            IdealDirection::Both => moment_nm.clamp(-b, b),
        }
    }

    /// The step's moment at `t_s` (N m, extensor positive).
    pub fn step_at(&self, t_s: f64) -> f64 {
        if t_s >= self.step_at_s {
            self.step_nm
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sign_up_to_the_bound() {
        let p = |d| IdealParams { direction: d, max_nm_per_kg: 0.5, ..Default::default() };
        assert_eq!(p(IdealDirection::Extension).moment_nm(30.0, 70.0), 30.0);
        assert_eq!(p(IdealDirection::Extension).moment_nm(50.0, 70.0), 35.0);
        assert_eq!(p(IdealDirection::Extension).moment_nm(-20.0, 70.0), 0.0);
        assert_eq!(p(IdealDirection::Flexion).moment_nm(-50.0, 70.0), -35.0);
        assert_eq!(p(IdealDirection::Flexion).moment_nm(20.0, 70.0), 0.0);
        assert_eq!(p(IdealDirection::Both).moment_nm(-20.0, 70.0), -20.0);
    }
}
