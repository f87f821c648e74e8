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
    /// Smoothing velocity eps of the smooth sign tanh(v/eps) (m/s). Default 1e-3 (well below v_s; smaller makes the friction stiff for a 1 ms step). > 0.
    pub smoothing_velocity_m_s: f64,
}

impl Default for FrictionParams {
    fn default() -> Self {
        Self {
            coulomb_n: 4.0,
            static_n: 6.0,
            stribeck_velocity_m_s: 0.01,
            viscous_n_s_per_m: 10_000.0,
            smoothing_velocity_m_s: 1e-3,
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

    /// d F_f / d v (N s/m), analytic.
    pub fn slope_n_s_per_m(&self, v_m_s: f64) -> f64 {
        self.force_and_slope(v_m_s).1
    }

    /// [`Self::force_n`] (N) and [`Self::slope_n_s_per_m`] (N s/m) with one `exp` and one
    /// `tanh` (the same numbers as the two calls).
    pub fn force_and_slope(&self, v_m_s: f64) -> (f64, f64) {
        let (vs, eps) = (self.stribeck_velocity_m_s, self.smoothing_velocity_m_s);
        let e = (-(v_m_s / vs).powi(2)).exp();
        let level = self.coulomb_n + (self.static_n - self.coulomb_n) * e;
        let dlevel = (self.static_n - self.coulomb_n) * e * (-2.0 * v_m_s / (vs * vs));
        let th = (v_m_s / eps).tanh();
        let force = level * th + self.viscous_n_s_per_m * v_m_s;
        (force, dlevel * th + level * (1.0 - th * th) / eps + self.viscous_n_s_per_m)
    }
}

impl FrictionParams {
    /// Friction force (N) and its first and second derivatives with respect to the velocity
    /// (N s/m, N s^2/m^2), analytic.
    pub fn force_and_derivatives(&self, v_m_s: f64) -> (f64, f64, f64) {
        let (vs, eps) = (self.stribeck_velocity_m_s, self.smoothing_velocity_m_s);
        let ds = self.static_n - self.coulomb_n;
        let e = (-(v_m_s / vs).powi(2)).exp();
        let level = self.coulomb_n + ds * e;
        let level1 = ds * e * (-2.0 * v_m_s / (vs * vs));
        let level2 = ds * e * (4.0 * v_m_s * v_m_s / (vs * vs * vs * vs) - 2.0 / (vs * vs));
        let th = (v_m_s / eps).tanh();
        let th1 = (1.0 - th * th) / eps;
        let th2 = -2.0 * th * (1.0 - th * th) / (eps * eps);
        (
            level * th + self.viscous_n_s_per_m * v_m_s,
            level1 * th + level * th1 + self.viscous_n_s_per_m,
            level2 * th + 2.0 * level1 * th1 + level * th2,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_derivative_matches_finite_difference() {
        let f = FrictionParams::default();
        for v in [-0.05, -1e-3, -5e-4, 0.0, 3e-4, 2e-3, 0.02] {
            let h = 1e-7;
            let fd = (f.slope_n_s_per_m(v + h) - f.slope_n_s_per_m(v - h)) / (2.0 * h);
            let (f0, f1, f2) = f.force_and_derivatives(v);
            assert_eq!(f0, f.force_n(v));
            assert!((f1 - f.slope_n_s_per_m(v)).abs() < 1e-9 * f1.abs());
            assert!((fd - f2).abs() < 1e-5 * fd.abs().max(1e3), "v={v}: {f2} vs {fd}");
        }
    }

    #[test]
    fn slope_matches_finite_difference() {
        let f = FrictionParams::default();
        for v in [-0.05, -1e-3, -5e-5, 0.0, 3e-5, 2e-3, 0.02] {
            let h = 1e-8;
            let fd = (f.force_n(v + h) - f.force_n(v - h)) / (2.0 * h);
            assert!((fd - f.slope_n_s_per_m(v)).abs() < 1e-4 * fd.abs().max(1.0), "v={v}");
        }
    }
}
