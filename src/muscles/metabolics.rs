//! Muscle metabolic rate, as OpenSim's probes compute it from a muscle's state
//! (`Umberger2010MuscleMetabolicsProbe`, `Bhargava2004MuscleMetabolicsProbe`, opensim-core
//! 0435b08).
//!
//! - **Umberger 2010** (Umberger BR, Gerritsen KGM, Martin PE. A model of human muscle energy
//!   expenditure. Comput Methods Biomech Biomed Engin 6(2):99-111, 2003; Umberger BR. Stance
//!   and swing phase costs in human walking. J R Soc Interface 7:1329-1340, 2010), as
//!   published: OpenSim's probe with its three later defaults (Uchida et al. 2016: Bhargava's
//!   recruitment, negative work at 4x, no negative total) off. Per kg of muscle, aerobic
//!   factor `S = 1.5`, slow-twitch fraction `r`, `A = u` (excitation; `(u + a)/2` when
//!   deactivating):
//!   ```text
//!   activation + maintenance  S A^0.6 h,  h = 128 (1 - r) + 25 W/kg   (x (0.4 + 0.6 f_L) past l_opt)
//!   shortening                S A^2 (r min(100, -a_slow v) - a_fast v (1 - r)),  v = v_CE / l_opt <= 0
//!   lengthening               S A 0.3 a_slow v,   a_slow = 250 / v_max, a_fast = 153 / v_max
//!                             (both x f_L past l_opt)
//!   work                      -F_CE v_CE / m   (shortening only)
//!   heat floor                activation + maintenance + shortening >= 1 W/kg
//!   ```
//! - **Bhargava 2004** (Bhargava LJ, Pandy MG, Anderson FC. A phenomenological model for
//!   estimating metabolic energy consumption in muscle contraction. J Biomech 37:81-88, 2004),
//!   OpenSim's defaults: activation `m (40 u_s + 133 u_f)`, maintenance
//!   `m f(l) (74 u_s + 111 u_f)` with `u_s = r sin(pi u / 2)`, `u_f = (1 - r)(1 - cos(pi u / 2))`
//!   and `f` piecewise linear through (0, 0.5), (0.5, 0.5), (1, 1), (1.5, 0), (2, 0);
//!   shortening `-0.25 (F_CE + F_PE) v_CE` (0 lengthening); work `-F_CE v_CE` (negative work
//!   counted, the total kept >= 0); the same heat floor of 1 W/kg.
//!
//! The whole body adds a basal rate of 1.2 W/kg (Umberger 2003, standing) to the muscles'.

use serde::{Deserialize, Serialize};

/// Which probe (`wearer.metabolic_model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MetabolicModel {
    /// Umberger et al. 2003/2010, as published.
    #[default]
    Umberger2010,
    /// Bhargava et al. 2004, OpenSim's defaults.
    Bhargava2004,
}

impl MetabolicModel {
    /// The name in scenario files.
    pub fn as_str(&self) -> &'static str {
        match self {
            MetabolicModel::Umberger2010 => "umberger2010",
            MetabolicModel::Bhargava2004 => "bhargava2004",
        }
    }
}

/// The basal rate (W per kg of body mass).
pub const BASAL_W_PER_KG: f64 = 1.2;

/// A person's net metabolic rate (W/kg) from one leg's muscles' rate `leg_w` (W): both legs
/// alike, over the body mass `mass_kg`.
pub fn net_w_per_kg(leg_w: f64, mass_kg: f64) -> f64 {
    2.0 * leg_w / mass_kg
}

/// The gross rate (W/kg): [`net_w_per_kg`] plus [`BASAL_W_PER_KG`].
pub fn gross_w_per_kg(leg_w: f64, mass_kg: f64) -> f64 {
    net_w_per_kg(leg_w, mass_kg) + BASAL_W_PER_KG
}
/// Umberger's aerobic factor.
const AEROBIC: f64 = 1.5;
/// The heat floor (W per kg of muscle).
const HEAT_FLOOR_W_PER_KG: f64 = 1.0;

/// What a probe reads of one muscle at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MuscleState {
    /// Excitation (0..1).
    pub excitation: f64,
    /// Activation (0..1).
    pub activation: f64,
    /// Normalised fibre length.
    pub length_norm: f64,
    /// Fibre velocity (m/s, shortening negative).
    pub velocity_m_s: f64,
    /// Active fibre force (N).
    pub active_force_n: f64,
    /// Passive fibre force (N).
    pub passive_force_n: f64,
    /// The active force-length multiplier at `length_norm`.
    pub force_length: f64,
}

/// The muscle constants a probe needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MuscleConstants {
    /// Mass (kg).
    pub mass_kg: f64,
    /// Slow-twitch fraction.
    pub slow_twitch: f64,
    /// Optimal fibre length (m).
    pub optimal_length_m: f64,
    /// Maximum contraction velocity (l_opt/s).
    pub max_velocity_lopt_per_s: f64,
}

impl MetabolicModel {
    /// The muscle's metabolic rate (W).
    pub fn rate_w(&self, c: &MuscleConstants, s: &MuscleState) -> f64 {
        match self {
            MetabolicModel::Umberger2010 => umberger2010(c, s),
            MetabolicModel::Bhargava2004 => bhargava2004(c, s),
        }
    }
}

fn umberger2010(c: &MuscleConstants, s: &MuscleState) -> f64 {
    let (u, a) = (s.excitation, s.activation);
    let big_a = if u > a { u } else { 0.5 * (u + a) };
    let r = c.slow_twitch;
    let h = 128.0 * (1.0 - r) + 25.0;
    let long = s.length_norm > 1.0;
    let am = AEROBIC * big_a.powf(0.6) * if long { 0.4 * h + 0.6 * h * s.force_length } else { h };
    let v = s.velocity_m_s / c.optimal_length_m;
    let (a_fast, a_slow) = (153.0 / c.max_velocity_lopt_per_s, 100.0 / (c.max_velocity_lopt_per_s / 2.5));
    let mut sh = if v <= 0.0 {
        let slow = (-a_slow * v).min(100.0);
        AEROBIC * big_a * big_a * (slow * r - a_fast * v * (1.0 - r))
    } else {
        AEROBIC * big_a * 0.3 * a_slow * v
    };
    if long {
        sh *= s.force_length;
    }
    let work = if s.velocity_m_s > 0.0 { 0.0 } else { -s.active_force_n.max(0.0) * s.velocity_m_s / c.mass_kg };
    let heat = if am + sh < HEAT_FLOOR_W_PER_KG { HEAT_FLOOR_W_PER_KG } else { am + sh };
    (heat + work) * c.mass_kg
}

/// Bhargava's maintenance length dependence.
fn maintenance_length(l: f64) -> f64 {
    const PTS: [(f64, f64); 5] = [(0.0, 0.5), (0.5, 0.5), (1.0, 1.0), (1.5, 0.0), (2.0, 0.0)];
    if l <= 0.0 {
        return 0.5;
    }
    for w in PTS.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if l <= x1 {
            return y0 + (y1 - y0) * (l - x0) / (x1 - x0);
        }
    }
    0.0
}

fn bhargava2004(c: &MuscleConstants, s: &MuscleState) -> f64 {
    let u = s.excitation;
    let r = c.slow_twitch;
    let half_pi = std::f64::consts::FRAC_PI_2;
    let (us, uf) = (r * (half_pi * u).sin(), (1.0 - r) * (1.0 - (half_pi * u).cos()));
    let m = c.mass_kg;
    let act = m * (40.0 * us + 133.0 * uf);
    let maint = m * maintenance_length(s.length_norm) * (74.0 * us + 111.0 * uf);
    let v = s.velocity_m_s;
    let mut short = if v <= 0.0 { -0.25 * (s.active_force_n + s.passive_force_n) * v } else { 0.0 };
    let work = -s.active_force_n.max(0.0) * v;
    let total = act + maint + short + work;
    if total < 0.0 {
        short -= total;
    }
    let heat = act + maint + short;
    let heat = if heat < HEAT_FLOOR_W_PER_KG * m { HEAT_FLOOR_W_PER_KG * m } else { heat };
    heat + work
}

#[cfg(test)]
mod tests {
    use super::*;

    const C: MuscleConstants =
        MuscleConstants { mass_kg: 0.5, slow_twitch: 0.5, optimal_length_m: 0.1, max_velocity_lopt_per_s: 10.0 };

    fn state(a: f64, l: f64, v: f64, f: f64) -> MuscleState {
        MuscleState {
            excitation: a,
            activation: a,
            length_norm: l,
            velocity_m_s: v,
            active_force_n: f,
            passive_force_n: 0.0,
            force_length: 1.0,
        }
    }

    /// Hand-computed values of the published formulas: isometric at full activation (the
    /// activation and maintenance heat alone), shortening (with work), lengthening, and the
    /// heat floor of a silent muscle.
    #[test]
    fn umberger_by_hand() {
        let h = 128.0 * 0.5 + 25.0; // 89 W/kg
        let iso = MetabolicModel::Umberger2010.rate_w(&C, &state(1.0, 1.0, 0.0, 800.0));
        assert!((iso - 1.5 * h * 0.5).abs() < 1e-9, "{iso}");
        // Shortening at 1 l_opt/s (v = -0.1 m/s): slow 25*1 = 25, fast 15.3*1 = 15.3.
        let sh = MetabolicModel::Umberger2010.rate_w(&C, &state(1.0, 1.0, -0.1, 800.0));
        let want = (1.5 * h + 1.5 * (25.0 * 0.5 + 15.3 * 0.5)) * 0.5 + 800.0 * 0.1;
        assert!((sh - want).abs() < 1e-9, "{sh} vs {want}");
        // Lengthening at 1 l_opt/s: 0.3 * 25 * 1.5 per kg; no negative work.
        let le = MetabolicModel::Umberger2010.rate_w(&C, &state(1.0, 1.0, 0.1, 800.0));
        assert!((le - (1.5 * h + 1.5 * 0.3 * 25.0) * 0.5).abs() < 1e-9, "{le}");
        let quiet = MetabolicModel::Umberger2010.rate_w(&C, &state(0.0, 1.0, 0.0, 0.0));
        assert!((quiet - 0.5).abs() < 1e-12, "the floor: 1 W/kg");
    }

    /// Bhargava's terms by hand at full excitation, isometric at l_opt, and its length
    /// dependence.
    #[test]
    fn bhargava_by_hand() {
        let iso = MetabolicModel::Bhargava2004.rate_w(&C, &state(1.0, 1.0, 0.0, 800.0));
        let want = 0.5 * (40.0 * 0.5 + 133.0 * 0.5) + 0.5 * 1.0 * (74.0 * 0.5 + 111.0 * 0.5);
        assert!((iso - want).abs() < 1e-9, "{iso} vs {want}");
        assert_eq!(maintenance_length(0.25), 0.5);
        assert!((maintenance_length(1.25) - 0.5).abs() < 1e-15 && maintenance_length(1.7) == 0.0);
    }
}
