//! Human-robot interaction force (MODEL.md section 3, paper Eq. 6).
//!
//! `w1 = k_p*(F_L - F_d) + k_d*(dF_L/dt - dF_d/dt)`, injected either
//! - `paper`: added to dx2/dt (N/s^2) as in the paper's Eq. 5, or
//! - `cuff`: as a physical force (N) on the shank at the cuff point, perpendicular to the
//!   shank in the sagittal plane (leg plant only), so it moves the knee.

use serde::{Deserialize, Serialize};

/// Where the interaction force acts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HumanMode {
    /// No interaction force.
    Off,
    /// Added to dx2/dt (the paper's simulation).
    Paper,
    /// A force on the shank at the cuff (leg plant).
    Cuff,
}

/// Interaction parameters (scenario section `[human]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HumanParams {
    /// Injection point. Default `off` on the bench (the paper's case puts the same form in
    /// `disturbance.state_gain_*`).
    pub mode: HumanMode,
    /// Proportional gain k_p (1/s^2 in `paper` mode, dimensionless in `cuff` mode). Default 0.05.
    pub k_p: f64,
    /// Derivative gain k_d (1/s in `paper` mode, s in `cuff` mode). Default 1e-3.
    pub k_d: f64,
    /// Link the cuff is strapped to (cuff mode). Default `shank`.
    pub cuff_link: String,
    /// Cuff point in the cuff link's frame (m). Default [0, 0, -0.2].
    pub cuff_xyz: [f64; 3],
    /// The thigh cuff's point in the thigh's link frame (the knee's parent; m): where the
    /// thigh cuff sensor sits. Default: on the thigh's axis, 40 % of the thigh's length above
    /// the knee.
    pub thigh_cuff_xyz: Option<[f64; 3]>,
}

impl Default for HumanParams {
    fn default() -> Self {
        Self {
            mode: HumanMode::Off,
            k_p: 0.05,
            k_d: 1e-3,
            cuff_link: "shank".into(),
            cuff_xyz: [0.0, 0.0, -0.2],
            thigh_cuff_xyz: None,
        }
    }
}

impl HumanParams {
    /// w1 = k_p*force_error + k_d*force_error_rate, with errors F_L - F_d and their rates.
    pub fn interaction(&self, force_error_n: f64, force_error_rate_n_per_s: f64) -> f64 {
        self.k_p * force_error_n + self.k_d * force_error_rate_n_per_s
    }
}

pub mod body;
pub mod events;
pub mod muscle_wearer;
pub use body::*;
pub use events::{EventParams, GaitEvents};
pub use muscle_wearer::{MuscleWearer, MuscleWearerSetup, WearerInputs};
