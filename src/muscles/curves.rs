//! The muscle's mechanics, as OpenSim's `DeGrooteFregly2016Muscle` implements them (De Groote
//! F, Kinney AL, Rao AV, Fregly BJ. Evaluation of direct collocation optimal control problem
//! formulations for solving the muscle redundancy problem. Ann Biomed Eng 44(10):2922-2936,
//! 2016; opensim-core `OpenSim/Actuators/DeGrooteFregly2016Muscle.{h,cpp}`): small pure
//! functions of normalised quantities.
//!
//! ```text
//! active force-length  f_L(l) = sum_i b1i exp(-0.5 (l - b2i)^2 / (b3i + b4i l)^2)   (3 terms)
//! force-velocity       f_V(v) = d1 ln((d2 v + d3) + sqrt((d2 v + d3)^2 + 1)) + d4,  v in [-1, 1]
//! passive              f_PE(l) = (exp(kPE (l - 1)/e0) - exp(kPE (l_min - 1)/e0))
//!                               / (exp(kPE) - exp(kPE (l_min - 1)/e0)),  kPE = 4, e0 = 0.6
//! activation           da/dt = [(f + 1/2) / (tau_a (1/2 + 3a/2)) + (1/2 - f)(1/2 + 3a/2) / tau_d] (e - a),
//!                      f = tanh(b (e - a)) / 2
//! ```
//! `l` is the fibre length over the optimal fibre length, `v` the fibre velocity over `v_max
//! l_opt` (negative shortening). The fibre has a constant height `w = l_opt sin(alpha_opt)`
//! (pennation), and the tendon is rigid here: its length is the slack length, so the fibre's
//! length and velocity follow from the muscle-tendon unit's (`fibre_kinematics`). A compliant
//! tendon would let the fibre work nearer its optimal length in stance (the gastrocnemius and
//! soleus most: their tendons are long, `l_slack / l_opt` 6.5 and 5) and store and return
//! energy, lowering their shortening heat and work; the rigid tendon makes their fibres follow
//! the path's length change in full (README, "The wearer's muscles").

/// The active force-length curve's three terms: b1, b2, b3, b4.
const FL_TERMS: [[f64; 4]; 3] = [
    [0.8150671134243542, 1.055033428970575, 0.162384573599574, 0.063303448465465],
    [0.433004984392647, 0.716775413397760, -0.029947116970696, 0.200356847296188],
    [0.1, 1.0, 0.353553390593274, 0.0],
];
/// The force-velocity curve's d1..d4.
const FV_D: [f64; 4] = [-0.3211346127989808, -8.149, -0.374, 0.8825327733249912];
/// The passive curve's exponential shape.
const K_PE: f64 = 4.0;
/// Fibre strain at one normalised passive force.
pub const PASSIVE_STRAIN_AT_ONE: f64 = 0.6;
/// Shortest normalised fibre length (the passive curve's zero; OpenSim's bound).
pub const MIN_NORM_FIBER_LENGTH: f64 = 0.2;
/// Longest normalised fibre length (OpenSim's bound).
pub const MAX_NORM_FIBER_LENGTH: f64 = 1.8;

/// Activation time constant (s): De Groote et al. 2016, OpenSim's default.
pub const ACTIVATION_TIME_CONSTANT_S: f64 = 0.015;
/// Deactivation time constant (s).
pub const DEACTIVATION_TIME_CONSTANT_S: f64 = 0.060;
/// The tanh smoothing of the switch between them (OpenSim's documentation recommends 10).
pub const ACTIVATION_SMOOTHING: f64 = 10.0;
/// The least activation (OpenSim's static optimisation and Millard's muscle: 0.01).
pub const MIN_ACTIVATION: f64 = 0.01;

/// Active force-length multiplier at normalised fibre length `l` (1 at l = 1).
pub fn active_force_length(l: f64) -> f64 {
    FL_TERMS
        .iter()
        .map(|[b1, b2, b3, b4]| {
            let s = b3 + b4 * l;
            b1 * (-0.5 * (l - b2) * (l - b2) / (s * s)).exp()
        })
        .sum()
}

/// Force-velocity multiplier at normalised fibre velocity `v` (0 at -1, 1 at 0, 1.794 at 1).
pub fn force_velocity(v: f64) -> f64 {
    let [d1, d2, d3, d4] = FV_D;
    let x = d2 * v + d3;
    d1 * (x + (x * x + 1.0).sqrt()).ln() + d4
}

/// The passive curve's offset and its denominator (computed once).
static PASSIVE: std::sync::LazyLock<(f64, f64)> = std::sync::LazyLock::new(|| {
    let offset = (K_PE * (MIN_NORM_FIBER_LENGTH - 1.0) / PASSIVE_STRAIN_AT_ONE).exp();
    (offset, K_PE.exp() - offset)
});

/// Passive fibre force multiplier at normalised fibre length `l` (0 at 0.2, 1 at 1.6).
pub fn passive_force_length(l: f64) -> f64 {
    let (offset, denominator) = *PASSIVE;
    ((K_PE * (l - 1.0) / PASSIVE_STRAIN_AT_ONE).exp() - offset) / denominator
}

/// Activation's rate (1/s) at activation `a` under excitation `e`, with the time constants
/// `tau_a_s`, `tau_d_s` (s) and the smoothing `b`.
pub fn activation_rate(e: f64, a: f64, tau_a_s: f64, tau_d_s: f64, b: f64) -> f64 {
    let f = 0.5 * (b * (e - a)).tanh();
    let z = 0.5 + 1.5 * a;
    ((f + 0.5) / (tau_a_s * z) + (0.5 - f) * z / tau_d_s) * (e - a)
}

/// A fibre's state from its muscle-tendon unit's with a rigid tendon.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Fibre {
    /// Normalised fibre length l_M / l_opt.
    pub length_norm: f64,
    /// Fibre velocity over l_opt (1/s, shortening negative).
    pub velocity_per_s: f64,
    /// cos of the pennation angle.
    pub cos_pennation: f64,
}

/// The fibre of a unit of length `l_mt_m` (m) and lengthening rate `v_mt_m_s` (m/s) with a
/// rigid tendon of `l_slack_m` (m), optimal fibre length `l_opt_m` (m) and pennation
/// `alpha_opt_rad` at the optimum: constant fibre height `w = l_opt sin(alpha_opt)`,
/// `l_M = sqrt((l_MT - l_slack)^2 + w^2)`, `v_M = v_MT cos(alpha)`. The fibre's length along
/// the tendon is floored at a tenth of the optimum (a path shorter than its tendon).
pub fn fibre_kinematics(l_mt_m: f64, v_mt_m_s: f64, l_slack_m: f64, l_opt_m: f64, alpha_opt_rad: f64) -> Fibre {
    fibre_with_height(l_mt_m, v_mt_m_s, l_slack_m, l_opt_m, l_opt_m * alpha_opt_rad.sin())
}

/// [`fibre_kinematics`] with the fibre's height `w_m = l_opt sin(alpha_opt)` (m) known.
pub fn fibre_with_height(l_mt_m: f64, v_mt_m_s: f64, l_slack_m: f64, l_opt_m: f64, w: f64) -> Fibre {
    let along = (l_mt_m - l_slack_m).max(0.1 * l_opt_m);
    // (sqrt, not hypot: lengths of centimetres cannot overflow, and it is the hot path.)
    let l_m = (along * along + w * w).sqrt();
    let cos = along / l_m;
    Fibre { length_norm: l_m / l_opt_m, velocity_per_s: v_mt_m_s * cos / l_opt_m, cos_pennation: cos }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on each curve against the published equations written out independently here
    /// (the paper's Table 1 constants as OpenSim has them, b11 and d1/d4 as it adjusted them):
    /// 2000 points per curve to 1e-9, and the anchors OpenSim's tests state.
    #[test]
    fn curves_match_their_equations() {
        for i in 0..2000 {
            let l = 0.2 + 1.6 * i as f64 / 1999.0;
            let g =
                |b1: f64, b2: f64, b3: f64, b4: f64| b1 * (-((l - b2).powi(2)) / (2.0 * (b3 + b4 * l).powi(2))).exp();
            let fl = g(0.8150671134243542, 1.055033428970575, 0.162384573599574, 0.063303448465465)
                + g(0.433004984392647, 0.716775413397760, -0.029947116970696, 0.200356847296188)
                + g(0.1, 1.0, 0.5 * 0.5f64.sqrt(), 0.0);
            assert!((active_force_length(l) - fl).abs() < 1e-9, "f_L({l})");
            let pe = ((4.0 * (l - 1.0) / 0.6).exp() - (4.0 * -0.8 / 0.6f64).exp())
                / (4f64.exp() - (4.0 * -0.8 / 0.6f64).exp());
            assert!((passive_force_length(l) - pe).abs() < 1e-9, "f_PE({l})");
            let v = -1.0 + 2.0 * i as f64 / 1999.0;
            let x = -8.149 * v - 0.374;
            let fv = -0.3211346127989808 * (x + (x * x + 1.0).sqrt()).ln() + 0.8825327733249912;
            assert!((force_velocity(v) - fv).abs() < 1e-9, "f_V({v})");
        }
        assert!((active_force_length(1.0) - 1.0).abs() < 1e-4);
        assert!(force_velocity(-1.0).abs() < 1e-4 && (force_velocity(0.0) - 1.0).abs() < 1e-4);
        assert!((force_velocity(1.0) - 1.794).abs() < 1e-3);
        assert!(passive_force_length(0.2).abs() < 1e-15 && (passive_force_length(1.6) - 1.0).abs() < 1e-12);
    }

    /// The curves against OpenSim's own `DeGrooteFregly2016Muscle` (4.6) at 401 lengths and
    /// 401 velocities each (`scripts/opensim-curves`): equal to 1e-12.
    #[test]
    fn curves_match_opensim() {
        let text = include_str!("../../tests/data/muscles/degroote2016_curves.csv");
        let mut n = 0;
        for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            let (l, fl, pe, vel, fv) = (v[1], v[2], v[3], v[4], v[5]);
            assert!((active_force_length(l) - fl).abs() < 1e-12, "f_L({l}): {} vs {fl}", active_force_length(l));
            assert!((passive_force_length(l) - pe).abs() < 1e-12, "f_PE({l})");
            assert!((force_velocity(vel) - fv).abs() < 1e-12, "f_V({vel})");
            n += 1;
        }
        assert_eq!(n, 401);
    }

    /// Activation rises faster than it falls; a step of excitation from rest reaches half in
    /// 9.5 ms with the default constants (b = 10), falls halfway in 26.8 ms.
    #[test]
    fn activation_step_response() {
        let half_time = |e: f64, a0: f64| {
            let (mut a, mut t, h) = (a0, 0.0, 1e-6);
            while (a - a0).abs() < 0.5 * (e - a0).abs() {
                a += h * activation_rate(e, a, 0.015, 0.060, 10.0);
                t += h;
            }
            t
        };
        let (up, down) = (half_time(1.0, 0.0), half_time(0.0, 1.0));
        assert!((up - 0.0095).abs() < 0.0005, "rise {up}");
        assert!((down - 0.0268).abs() < 0.001, "fall {down}");
    }

    /// The rigid tendon's fibre: pennation from a constant height, velocity along it.
    #[test]
    fn fibre_from_the_unit() {
        let f = fibre_kinematics(0.30, -0.2, 0.25, 0.05, 0.4);
        let w = 0.05 * 0.4f64.sin();
        let l = (0.05f64 * 0.05 + w * w).sqrt();
        assert!((f.length_norm - l / 0.05).abs() < 1e-12);
        assert!((f.cos_pennation - 0.05 / l).abs() < 1e-12);
        assert!((f.velocity_per_s - -0.2 * 0.05 / l / 0.05).abs() < 1e-12);
        // At the optimum the pennation is the optimum's.
        let o = fibre_kinematics(0.25 + 0.05 * 0.4f64.cos(), 0.0, 0.25, 0.05, 0.4);
        assert!((o.length_norm - 1.0).abs() < 1e-12 && (o.cos_pennation - 0.4f64.cos()).abs() < 1e-12);
    }
}
