//! Injected disturbances (MODEL.md section 5, paper Table 2).
//!
//! A [`Signal`] is a sum of terms; each term is a pure function of time (and of the run's
//! seed for the random form), so the same scenario and seed give bit-identical runs and
//! every integrator stage sees a consistent value.
//!
//! Three channels act on the force channel (see [`crate::hydraulics`]):
//! `force_rate` (N/s, on dF_L/dt), `force_accel` (N/s^2, on dx2/dt, where the paper's
//! Eq. 5 puts its `g1 + w1`), `spool` (m/s, on dx_v/dt). The paper's state-dependent
//! uncertainty `g = a*x1 + b*x2` is added to the `force_accel` channel.

use serde::{Deserialize, Serialize};

/// One disturbance term. Units are those of the channel it is added to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Term {
    /// Constant `value` (paper form 1).
    Constant {
        /// Value (channel units).
        value: f64,
    },
    /// Uniform random in `[0, amplitude)`, a new draw every `hold_s` seconds (paper form 2,
    /// `rand(1)`), from the run's seed and this term's position: deterministic.
    Random {
        /// Amplitude (channel units). Default 1.
        #[serde(default = "one")]
        amplitude: f64,
        /// Hold time of each draw (s). Default 0.001 (the paper's sample period). > 0.
        #[serde(default = "default_hold")]
        hold_s: f64,
    },
    /// `amplitude*sin(2*pi*frequency_hz*t + phase_rad)` (paper form 3 with amplitude 1, 1 Hz).
    Sine {
        /// Amplitude (channel units). Default 1.
        #[serde(default = "one")]
        amplitude: f64,
        /// Frequency (Hz). Default 1.
        #[serde(default = "one")]
        frequency_hz: f64,
        /// Phase (rad). Default 0.
        #[serde(default)]
        phase_rad: f64,
    },
    /// `amplitude*exp(-rate_per_s*t)` (paper form 4 with amplitude 1, rate 1 1/s).
    ExpDecay {
        /// Amplitude (channel units). Default 1.
        #[serde(default = "one")]
        amplitude: f64,
        /// Decay rate (1/s). Default 1. >= 0.
        #[serde(default = "one")]
        rate_per_s: f64,
    },
    /// A step of `amplitude` starting at `time_s`.
    Step {
        /// Step height (channel units).
        amplitude: f64,
        /// Step time (s). Default 0.
        #[serde(default)]
        time_s: f64,
    },
}

fn one() -> f64 {
    1.0
}
fn default_hold() -> f64 {
    0.001
}

/// Map (seed, stream, index) to a uniform number in [0, 1): SplitMix64 finaliser, the
/// standard stateless mixer, so a random term can be evaluated at any time in any order.
fn uniform01(seed: u64, stream: u64, index: u64) -> f64 {
    let mut z = seed
        .wrapping_add(stream.wrapping_mul(0xD1B5_4A32_D192_ED03))
        .wrapping_add(index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

impl Term {
    /// Value and time derivative of this term at `t_s`. `stream` separates random terms.
    /// The derivative of the piecewise-constant random and step forms is taken as 0.
    pub fn value_and_rate(&self, t_s: f64, seed: u64, stream: u64) -> (f64, f64) {
        use std::f64::consts::TAU;
        match *self {
            Term::Constant { value } => (value, 0.0),
            Term::Random { amplitude, hold_s } => {
                // Small tolerance so a stage exactly on a hold boundary is not split by rounding.
                let k = ((t_s / hold_s) + 1e-9).floor().max(0.0) as u64;
                (amplitude * uniform01(seed, stream, k), 0.0)
            }
            Term::Sine { amplitude, frequency_hz, phase_rad } => {
                let w = TAU * frequency_hz;
                let a = w * t_s + phase_rad;
                (amplitude * a.sin(), amplitude * w * a.cos())
            }
            Term::ExpDecay { amplitude, rate_per_s } => {
                let v = amplitude * (-rate_per_s * t_s).exp();
                (v, -rate_per_s * v)
            }
            Term::Step { amplitude, time_s } => (if t_s >= time_s { amplitude } else { 0.0 }, 0.0),
        }
    }
}

/// A sum of disturbance terms on one channel.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Signal(pub Vec<Term>);

impl Signal {
    /// Sum of the terms' values and time derivatives at `t_s`. `channel` seeds the random streams.
    pub fn value_and_rate(&self, t_s: f64, seed: u64, channel: u64) -> (f64, f64) {
        self.0.iter().enumerate().fold((0.0, 0.0), |(v, r), (i, term)| {
            let (tv, tr) = term.value_and_rate(t_s, seed, channel * 1000 + i as u64);
            (v + tv, r + tr)
        })
    }

    /// Sum of the terms' values at `t_s`.
    pub fn value(&self, t_s: f64, seed: u64, channel: u64) -> f64 {
        self.value_and_rate(t_s, seed, channel).0
    }
}

/// All injected disturbances of a scenario.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Disturbances {
    /// Terms added to dF_L/dt (N/s).
    pub force_rate: Signal,
    /// Terms added to dx2/dt = d^2F_L/dt^2 (N/s^2): the paper's w.
    pub force_accel: Signal,
    /// Terms added to dx_v/dt (m/s).
    pub spool: Signal,
    /// Coefficient a of the state-dependent g = a*x1 + b*x2 on dx2/dt (1/s^2). Paper: 0.05.
    pub state_gain_force: f64,
    /// Coefficient b of g = a*x1 + b*x2 on dx2/dt (1/s). Paper: 1e-3.
    pub state_gain_force_rate: f64,
}

/// Channel numbers used to seed the random streams of each channel independently.
pub const CHANNEL_FORCE_RATE: u64 = 1;
/// See [`CHANNEL_FORCE_RATE`].
pub const CHANNEL_FORCE_ACCEL: u64 = 2;
/// See [`CHANNEL_FORCE_RATE`].
pub const CHANNEL_SPOOL: u64 = 3;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_is_uniform_and_repeatable() {
        let t = Term::Random { amplitude: 1.0, hold_s: 1e-3 };
        let n = 20_000;
        let mean: f64 = (0..n).map(|k| t.value_and_rate(k as f64 * 1e-3, 7, 0).0).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.01, "mean {mean}");
        assert_eq!(t.value_and_rate(0.0123, 7, 0), t.value_and_rate(0.0123, 7, 0));
        assert_ne!(t.value_and_rate(0.0123, 7, 0), t.value_and_rate(0.0123, 8, 0));
        // held within one hold period
        assert_eq!(t.value_and_rate(0.0120, 7, 0), t.value_and_rate(0.01275, 7, 0));
    }

    #[test]
    fn paper_w_at_zero() {
        let w = Signal(vec![
            Term::Sine { amplitude: 1.0, frequency_hz: 1.0, phase_rad: 0.0 },
            Term::Constant { value: 1.0 },
            Term::ExpDecay { amplitude: 1.0, rate_per_s: 0.1 },
        ]);
        let (v, r) = w.value_and_rate(0.0, 1, 2);
        assert!((v - 2.0).abs() < 1e-12);
        assert!((r - (std::f64::consts::TAU - 0.1)).abs() < 1e-12);
    }
}
