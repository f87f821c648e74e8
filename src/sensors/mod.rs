//! What the controller sees: ideal signals (continuous mode) or the sampled sensor chain of
//! a digital controller (sampled mode).
//!
//! Sampled chain, per channel and per sample (all seeded, deterministic):
//!
//! ```text
//! reading = quantise(truth + N(0, noise_std^2))      // A/D: `bits` over [-range, +range]
//! delayed = reading from `delay_samples` samples ago  // transport + processing delay
//! rate    = low-pass((delayed_k - delayed_{k-1}) / Ts) // firmware derivative
//! ```
//! The load-cell rate x2 and the piston velocity and acceleration are such filtered
//! differences. x2 is never rebuilt from the nominal model (that would hide exactly the
//! disturbances the observer exists to see).

mod hold;
pub use hold::*;

use crate::control::Measurement;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// A/D converter presets for the quantisation of every channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorPreset {
    /// No quantisation.
    Ideal,
    /// 32-bit converters (the paper's experiment).
    Adc32,
    /// 16-bit converters (a realistic embedded board).
    Adc16,
}

impl SensorPreset {
    /// Bits of the preset (None = no quantisation).
    pub fn bits(&self) -> Option<u32> {
        match self {
            SensorPreset::Ideal => None,
            SensorPreset::Adc32 => Some(32),
            SensorPreset::Adc16 => Some(16),
        }
    }
}

/// One measured channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChannelParams {
    /// The sensor exists. Default true. Only the spool LVDT and the piston-velocity sensor may
    /// be switched off: without the spool sensor `dtznn` estimates the spool from its commands;
    /// without the velocity sensor the velocity is the filtered difference of the position.
    pub enabled: bool,
    /// Standard deviation of additive Gaussian noise (channel unit). Default 0. >= 0.
    pub noise_std: f64,
    /// A/D resolution in bits; absent = the preset's. 0 = no quantisation.
    pub bits: Option<u32>,
    /// Full scale: readings are clamped to and quantised over [-range, +range] (channel
    /// unit); absent = the channel's default (force 5000 N, spool 0.02 m, piston 0.2 m, knee
    /// pi rad, piston velocity 1 m/s: every shipped scenario fits). A reading that clips is
    /// counted and reported. > 0.
    pub range: Option<f64>,
}

impl Default for ChannelParams {
    fn default() -> Self {
        Self { enabled: true, noise_std: 0.0, bits: None, range: None }
    }
}

/// Default full scales of the channels force (N), spool (m), piston (m), knee (rad), piston
/// velocity (m/s).
pub const DEFAULT_RANGES: [f64; 5] = [5000.0, 0.02, 0.2, std::f64::consts::PI, 1.0];
/// Channel names, in the order of [`DEFAULT_RANGES`].
pub const CHANNELS: [&str; 5] = ["force", "spool", "piston", "knee", "piston_velocity"];

/// Sensor parameters (scenario section `[sensors]`). Only used in sampled mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// Quantisation preset: `ideal` (default), `adc32`, `adc16`.
    pub preset: SensorPreset,
    /// Measurement delay in whole samples. Default 0.
    pub delay_samples: usize,
    /// Cut-off of the first-order low-pass on differentiated signals (Hz); 0 = raw difference.
    pub derivative_cutoff_hz: f64,
    /// Load cell (N).
    pub force: ChannelParams,
    /// Valve spool LVDT (m).
    pub spool: ChannelParams,
    /// Piston position (m).
    pub piston: ChannelParams,
    /// Knee angle encoder (rad).
    pub knee: ChannelParams,
    /// Piston velocity sensor (m/s).
    pub piston_velocity: ChannelParams,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            preset: SensorPreset::Ideal,
            delay_samples: 0,
            derivative_cutoff_hz: 0.0,
            force: ChannelParams::default(),
            spool: ChannelParams::default(),
            piston: ChannelParams::default(),
            knee: ChannelParams::default(),
            piston_velocity: ChannelParams::default(),
        }
    }
}

impl SensorParams {
    /// True when any effect beyond sampling is configured (noise, quantisation, delay, filter).
    pub fn has_effects(&self) -> bool {
        let ch = [&self.force, &self.spool, &self.piston, &self.knee, &self.piston_velocity];
        self.preset != SensorPreset::Ideal
            || self.delay_samples > 0
            || self.derivative_cutoff_hz > 0.0
            || ch.iter().any(|c| c.noise_std > 0.0 || c.bits.unwrap_or(0) > 0 || !c.enabled)
    }

    /// The channels with their dotted key prefix (for validation messages), in the order of
    /// [`CHANNELS`].
    pub fn channels(&self) -> [(&'static str, &ChannelParams); 5] {
        [
            ("sensors.force", &self.force),
            ("sensors.spool", &self.spool),
            ("sensors.piston", &self.piston),
            ("sensors.knee", &self.knee),
            ("sensors.piston_velocity", &self.piston_velocity),
        ]
    }

    /// Standard deviation of a channel's reading (noise and quantisation, LSB/sqrt(12)), in
    /// its unit; None if the channel is switched off.
    pub fn reading_sd(&self, channel: usize) -> Option<f64> {
        let (_, c) = self.channels()[channel];
        c.enabled.then(|| {
            let adc = Adc::new(c, self.preset, DEFAULT_RANGES[channel]);
            (adc.noise_std * adc.noise_std + adc.lsb * adc.lsb / 12.0).sqrt()
        })
    }
}

/// True plant signals at one instant (what ideal sensors would read).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Truth {
    /// Load force F_L (N).
    pub force_n: f64,
    /// dF_L/dt (N/s).
    pub force_rate_n_per_s: f64,
    /// Spool position (m).
    pub spool_m: f64,
    /// Piston position (m).
    pub piston_m: f64,
    /// Piston velocity (m/s).
    pub piston_velocity_m_s: f64,
    /// Piston acceleration (m/s^2).
    pub piston_accel_m_s2: f64,
    /// Knee angle (rad), 0 on the bench.
    pub knee_rad: f64,
    /// Knee rate (rad/s), 0 on the bench.
    pub knee_rate_rad_s: f64,
}

impl Truth {
    /// The ideal measurement: every signal exact, derivatives exact.
    pub fn ideal(&self) -> Measurement {
        Measurement {
            force_n: self.force_n,
            force_rate_n_per_s: self.force_rate_n_per_s,
            spool_m: self.spool_m,
            piston_m: self.piston_m,
            piston_velocity_m_s: self.piston_velocity_m_s,
            piston_accel_m_s2: self.piston_accel_m_s2,
            knee_rad: self.knee_rad,
            knee_rate_rad_s: self.knee_rate_rad_s,
        }
    }
}

/// Backward difference with optional first-order low-pass, at a fixed sample period.
#[derive(Debug, Clone, Default)]
struct Differentiator {
    prev: Option<f64>,
    out: f64,
}

impl Differentiator {
    /// Next filtered difference. At the first sample there is no previous reading: the
    /// firmware is taken to start from the true rate `initial` (the plant is not assumed at
    /// rest: gait runs start moving).
    fn update(&mut self, x: f64, ts: f64, alpha: f64, initial: f64) -> f64 {
        match self.prev {
            None => self.out = initial,
            Some(p) => self.out += alpha * ((x - p) / ts - self.out),
        }
        self.prev = Some(x);
        self.out
    }
}

/// A resolved A/D channel.
#[derive(Debug, Clone)]
struct Adc {
    noise_std: f64,
    /// Quantisation step (unit); 0 = none.
    lsb: f64,
    range: f64,
}

impl Adc {
    fn new(c: &ChannelParams, preset: SensorPreset, default_range: f64) -> Self {
        let bits = c.bits.or(preset.bits()).unwrap_or(0);
        let range = c.range.unwrap_or(default_range);
        let lsb = if bits == 0 { 0.0 } else { 2.0 * range / 2f64.powi(bits as i32) };
        Self { noise_std: c.noise_std, lsb, range }
    }

    /// A reading and whether it clipped at the full scale.
    fn read(&self, x: f64, rng: &mut ChaCha8Rng) -> (f64, bool) {
        let n: f64 = if self.noise_std > 0.0 {
            {
                let z: f64 = StandardNormal.sample(rng);
                self.noise_std * z
            }
        } else {
            0.0
        };
        let v = x + n;
        if self.lsb > 0.0 {
            ((v.clamp(-self.range, self.range) / self.lsb).round() * self.lsb, v.abs() > self.range)
        } else {
            (v, false)
        }
    }
}

/// The sampled sensor chain. Holds the previous samples for the differences and the delay line.
#[derive(Debug, Clone)]
pub struct SampledSensors {
    period_s: f64,
    alpha: f64,
    adc: [Adc; 5],
    enabled: [bool; 5],
    clipped: [usize; 5],
    rng: ChaCha8Rng,
    delay: usize,
    line: VecDeque<[f64; 5]>,
    d_force: Differentiator,
    d_piston: Differentiator,
    d_piston_vel: Differentiator,
    d_knee: Differentiator,
}

impl SampledSensors {
    /// Sensors sampled every `period_s` seconds, noise drawn from a stream seeded by `seed`.
    pub fn new(p: &SensorParams, period_s: f64, seed: u64) -> Self {
        // Exact discretisation of a first-order low-pass: alpha = 1 - exp(-2*pi*fc*Ts).
        let alpha = if p.derivative_cutoff_hz > 0.0 {
            1.0 - (-std::f64::consts::TAU * p.derivative_cutoff_hz * period_s).exp()
        } else {
            1.0
        };
        Self {
            period_s,
            alpha,
            adc: std::array::from_fn(|i| Adc::new(p.channels()[i].1, p.preset, DEFAULT_RANGES[i])),
            enabled: std::array::from_fn(|i| p.channels()[i].1.enabled),
            clipped: [0; 5],
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5E45_0125),
            delay: p.delay_samples,
            line: VecDeque::with_capacity(p.delay_samples + 1),
            d_force: Differentiator::default(),
            d_piston: Differentiator::default(),
            d_piston_vel: Differentiator::default(),
            d_knee: Differentiator::default(),
        }
    }

    /// Readings that clipped at each channel's full scale so far, by channel name.
    pub fn clipped(&self) -> Vec<(&'static str, usize)> {
        CHANNELS.iter().copied().zip(self.clipped).filter(|(_, n)| *n > 0).collect()
    }

    /// Take one sample of the plant.
    pub fn sample(&mut self, truth: &Truth) -> Measurement {
        let raw = [truth.force_n, truth.spool_m, truth.piston_m, truth.knee_rad, truth.piston_velocity_m_s];
        let mut reading = [f64::NAN; 5];
        for i in 0..5 {
            if self.enabled[i] {
                let (v, clipped) = self.adc[i].read(raw[i], &mut self.rng);
                reading[i] = v;
                self.clipped[i] += usize::from(clipped);
            }
        }
        self.line.push_back(reading);
        // Until the delay line fills, firmware sees its first reading.
        let r = if self.line.len() > self.delay { self.line.pop_front().unwrap_or(reading) } else { self.line[0] };
        let (ts, a) = (self.period_s, self.alpha);
        let force_rate = self.d_force.update(r[0], ts, a, truth.force_rate_n_per_s);
        let (vel, acc) = if self.enabled[4] {
            (r[4], self.d_piston_vel.update(r[4], ts, a, truth.piston_accel_m_s2))
        } else {
            let vel = self.d_piston.update(r[2], ts, a, truth.piston_velocity_m_s);
            (vel, self.d_piston_vel.update(vel, ts, a, truth.piston_accel_m_s2))
        };
        let knee_rate = self.d_knee.update(r[3], ts, a, truth.knee_rate_rad_s);
        Measurement {
            force_n: r[0],
            force_rate_n_per_s: force_rate,
            spool_m: r[1],
            piston_m: r[2],
            piston_velocity_m_s: vel,
            piston_accel_m_s2: acc,
            knee_rad: r[3],
            knee_rate_rad_s: knee_rate,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_noise_and_delay() {
        let p = SensorParams { preset: SensorPreset::Adc16, delay_samples: 2, ..Default::default() };
        let mut s = SampledSensors::new(&p, 1e-3, 1);
        let lsb = 10000.0 / 65536.0;
        let ys: Vec<f64> = (0..5)
            .map(|k| s.sample(&Truth { force_n: 100.0 * k as f64 + 0.05, ..Default::default() }).force_n)
            .collect();
        // Delay of two samples (first reading repeated until the line fills), on the LSB grid.
        assert_eq!(ys[0], ys[1]);
        assert!((ys[2] - 0.05).abs() <= lsb / 2.0 + 1e-12);
        assert!((ys[4] - 200.05).abs() <= lsb / 2.0 + 1e-12);
        assert!(((ys[3] / lsb) - (ys[3] / lsb).round()).abs() < 1e-9);

        let mut p = SensorParams::default();
        p.force.noise_std = 2.0;
        let mut s = SampledSensors::new(&p, 1e-3, 7);
        let xs: Vec<f64> = (0..20000).map(|_| s.sample(&Truth::default()).force_n).collect();
        let sd = (xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64).sqrt();
        assert!((sd - 2.0).abs() < 0.05, "noise sd {sd}");
    }
}
