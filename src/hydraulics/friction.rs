//! Piston friction: Stribeck + Coulomb + viscous, with a smooth sign.

use serde::{Deserialize, Serialize};

/// Friction parameters (MODEL.md section 1).
///
/// `F_f = [F_C + (F_S - F_C)*exp(-(v/v_s)^2)] * tanh(v/eps) + mu*v`, where `tanh(v/eps)`
/// is the smooth sign that keeps the force continuous at v = 0 (no chatter in a fixed-step
/// integrator). The friction force opposes the piston velocity: the mechanics see
/// `F_L - F_f` along the cylinder axis (the paper writes `F_L + F_f`; with F_f defined with
/// the sign of the velocity that would inject energy, so we take it as the resisting force).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrictionParams {
    /// Coulomb friction F_C (N). Default 4 (paper Table 1). >= 0.
    pub coulomb_n: f64,
    /// Static (breakaway) friction F_S (N). Default 6 (our assumption, 1.5 x F_C). >= F_C.
    pub static_n: f64,
    /// Stribeck velocity v_s (m/s). Default 0.01 (our assumption). > 0.
    pub stribeck_velocity_m_s: f64,
    /// Viscous coefficient mu (N s/m). Default 10000 (paper Table 1). >= 0.
    pub viscous_n_s_per_m: f64,
    /// Smoothing velocity eps of the smooth sign tanh(v/eps) (m/s). Default 1e-4. > 0.
    pub smoothing_velocity_m_s: f64,
}

impl Default for FrictionParams {
    fn default() -> Self {
        Self {
            coulomb_n: 4.0,
            static_n: 6.0,
            stribeck_velocity_m_s: 0.01,
            viscous_n_s_per_m: 10_000.0,
            smoothing_velocity_m_s: 1e-4,
        }
    }
}

impl FrictionParams {
    /// Friction force (N) with the sign of the piston velocity `v_m_s` (it resists the motion).
    pub fn force_n(&self, v_m_s: f64) -> f64 {
        let s = (v_m_s / self.stribeck_velocity_m_s).powi(2);
        let level = self.coulomb_n + (self.static_n - self.coulomb_n) * (-s).exp();
        level * (v_m_s / self.smoothing_velocity_m_s).tanh() + self.viscous_n_s_per_m * v_m_s
    }
}
