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

mod device;
mod faults;
mod hold;
pub use device::*;
pub use faults::*;
pub use hold::*;

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
    /// Every sensor with figures from typical datasheets (README, "The device's sensors"):
    /// noise, bias, scale errors, resolution, rates.
    Device,
}

impl SensorPreset {
    /// Bits of the preset for every channel (None = no quantisation, or per channel: `device`).
    pub fn bits(&self) -> Option<u32> {
        match self {
            SensorPreset::Ideal | SensorPreset::Device => None,
            SensorPreset::Adc32 => Some(32),
            SensorPreset::Adc16 => Some(16),
        }
    }

    /// Whether the preset quantises (every channel, or per channel).
    pub fn quantises(&self) -> bool {
        *self != SensorPreset::Ideal
    }

    /// The preset's noise standard deviation (channel unit) and bits of a force-loop channel.
    pub fn channel_figures(&self, c: ChannelId) -> (f64, Option<u32>) {
        match self {
            SensorPreset::Device => match c {
                // A 5 kN load cell on a 16-bit converter, 0.02 % FS noise.
                ChannelId::Force => (1.0, Some(16)),
                // The valve's LVDT, 16 bits.
                ChannelId::Spool => (1e-6, Some(16)),
                // A magnetostrictive position sensor, 16 bits.
                ChannelId::Piston => (1e-5, Some(16)),
                // A 14-bit magnetic encoder (AS5047P class): quantisation only.
                ChannelId::Knee => (0.0, Some(device_preset::ENCODER_BITS)),
                ChannelId::PistonVelocity => (1e-3, Some(16)),
            },
            _ => (0.0, self.bits()),
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
    /// Standard deviation of additive Gaussian noise (channel unit). Default: the preset's (0
    /// but for `device`). >= 0.
    pub noise_std: Option<f64>,
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
        Self { enabled: true, noise_std: None, bits: None, range: None }
    }
}

/// The measured channels, in the order of [`CHANNELS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ChannelId {
    /// Load cell (N).
    Force = 0,
    /// Valve spool LVDT (m).
    Spool = 1,
    /// Piston position (m).
    Piston = 2,
    /// Knee angle encoder (rad).
    Knee = 3,
    /// Piston velocity sensor (m/s).
    PistonVelocity = 4,
}

/// One measured channel: its names, unit and default full scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChannelInfo {
    /// Which channel.
    pub id: ChannelId,
    /// Short name (`sensors.<name>` in scenarios, `<name>` in clip reports).
    pub name: &'static str,
    /// The reading's field in [`Measurement`] and in the controller readings.
    pub reading: &'static str,
    /// SI unit of the reading.
    pub unit: &'static str,
    /// Default full scale: readings are clamped to and quantised over [-range, +range].
    pub default_range: f64,
}

/// The measured channels: one table for names, units and full scales.
pub const CHANNELS: [ChannelInfo; 5] = [
    ChannelInfo { id: ChannelId::Force, name: "force", reading: "force_n", unit: "N", default_range: 5000.0 },
    ChannelInfo { id: ChannelId::Spool, name: "spool", reading: "spool_m", unit: "m", default_range: 0.02 },
    ChannelInfo { id: ChannelId::Piston, name: "piston", reading: "piston_m", unit: "m", default_range: 0.2 },
    ChannelInfo {
        id: ChannelId::Knee,
        name: "knee",
        reading: "knee_rad",
        unit: "rad",
        default_range: std::f64::consts::PI,
    },
    ChannelInfo {
        id: ChannelId::PistonVelocity,
        name: "piston_velocity",
        reading: "piston_velocity_m_s",
        unit: "m/s",
        default_range: 1.0,
    },
];

/// What the controller reads at one instant: ideal signals (continuous mode, and the truth a
/// sampled chain starts from) or the readings after noise, A/D, delay and differences.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Measurement {
    /// Load force x1 = F_L from the load cell (N).
    pub force_n: f64,
    /// x2 = dF_L/dt (N/s): exact (continuous) or a filtered difference (sampled).
    pub force_rate_n_per_s: f64,
    /// Spool position x3 = x_v from the valve LVDT (m); NaN without the sensor.
    pub spool_m: f64,
    /// Piston position x_c from its position at t = 0 (m).
    pub piston_m: f64,
    /// Piston velocity xc_dot (m/s).
    pub piston_velocity_m_s: f64,
    /// Piston acceleration xc_ddot (m/s^2).
    pub piston_accel_m_s2: f64,
    /// Knee flexion (rad) from the joint encoder (0 on the bench).
    pub knee_rad: f64,
    /// Knee flexion rate (rad/s): exact (continuous) or a filtered difference (sampled).
    pub knee_rate_rad_s: f64,
}

impl Measurement {
    /// The value of a measured channel.
    pub fn channel(&self, c: ChannelId) -> f64 {
        match c {
            ChannelId::Force => self.force_n,
            ChannelId::Spool => self.spool_m,
            ChannelId::Piston => self.piston_m,
            ChannelId::Knee => self.knee_rad,
            ChannelId::PistonVelocity => self.piston_velocity_m_s,
        }
    }
}

/// Raw A/D counts of one sample, by channel (in [`CHANNELS`] order): the reading is exactly
/// `counts * lsb` with `lsb = 2 * range / 2^bits`; `None` for a channel without quantisation
/// (or switched off).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct AdcCounts(pub [Option<i64>; 5]);

impl AdcCounts {
    /// The counts of one channel.
    pub fn get(&self, c: ChannelId) -> Option<i64> {
        self.0[c as usize]
    }
}

/// Sensor parameters (scenario section `[sensors]`). Only used in sampled mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// Preset: `ideal` (default), `adc32`, `adc16` (quantisation of every channel) or
    /// `device` (datasheet figures for every sensor).
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
    /// Hip encoder (rad): the thigh relative to the pelvis.
    pub hip: ChannelParams,
    /// The thigh's IMU.
    pub thigh_imu: ImuParams,
    /// The shank's IMU.
    pub shank_imu: ImuParams,
    /// The heel and forefoot force sensors and the foot switch.
    pub foot: FootParams,
    /// The thigh cuff's force sensor (N).
    pub thigh_cuff: ChannelParams,
    /// The shank cuff's force sensor (N).
    pub shank_cuff: ChannelParams,
    /// Chamber A (cap side) pressure transducer (Pa).
    pub pressure_a: ChannelParams,
    /// Chamber B (rod side) pressure transducer (Pa).
    pub pressure_b: ChannelParams,
    /// Supply pressure transducer (Pa).
    pub supply_pressure: ChannelParams,
    /// Load pressure (Pa): a differential transducer across the cylinder, `F_L / A_eff`.
    pub load_pressure: ChannelParams,
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
            hip: ChannelParams::default(),
            thigh_imu: ImuParams::default(),
            shank_imu: ImuParams::default(),
            foot: FootParams::default(),
            thigh_cuff: ChannelParams::default(),
            shank_cuff: ChannelParams::default(),
            pressure_a: ChannelParams::default(),
            pressure_b: ChannelParams::default(),
            supply_pressure: ChannelParams::default(),
            load_pressure: ChannelParams::default(),
        }
    }
}

impl SensorParams {
    /// True when any effect beyond sampling is configured (noise, quantisation, delay, filter).
    pub fn has_effects(&self) -> bool {
        self.preset != SensorPreset::Ideal
            || self.delay_samples > 0
            || self.derivative_cutoff_hz > 0.0
            || CHANNELS
                .iter()
                .map(|c| self.channel(c.id))
                .any(|c| c.noise_std.unwrap_or(0.0) > 0.0 || c.bits.unwrap_or(0) > 0 || !c.enabled)
            || self.device_has_effects()
    }

    /// The settings of one channel.
    pub fn channel(&self, c: ChannelId) -> &ChannelParams {
        match c {
            ChannelId::Force => &self.force,
            ChannelId::Spool => &self.spool,
            ChannelId::Piston => &self.piston,
            ChannelId::Knee => &self.knee,
            ChannelId::PistonVelocity => &self.piston_velocity,
        }
    }

    /// Standard deviation of a channel's reading (noise and quantisation, LSB/sqrt(12)), in
    /// its unit; None if the channel is switched off.
    pub fn reading_sd(&self, c: ChannelId) -> Option<f64> {
        let p = self.channel(c);
        p.enabled.then(|| {
            let adc = Adc::new(p, self.preset, c);
            (adc.noise_std * adc.noise_std + adc.lsb * adc.lsb / 12.0).sqrt()
        })
    }

    /// The quantisation step (LSB, channel unit) of a channel; None without quantisation.
    pub fn lsb(&self, c: ChannelId) -> Option<f64> {
        let adc = Adc::new(self.channel(c), self.preset, c);
        (adc.lsb > 0.0).then_some(adc.lsb)
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
    fn new(c: &ChannelParams, preset: SensorPreset, id: ChannelId) -> Self {
        let (noise, preset_bits) = preset.channel_figures(id);
        let bits = c.bits.or(preset_bits).unwrap_or(0);
        let range = c.range.unwrap_or(CHANNELS[id as usize].default_range);
        let lsb = if bits == 0 { 0.0 } else { 2.0 * range / 2f64.powi(bits as i32) };
        Self { noise_std: c.noise_std.unwrap_or(noise), lsb, range }
    }

    /// A reading, whether it clipped at the full scale, and its A/D counts (None without
    /// quantisation).
    fn read(&self, x: f64, rng: &mut ChaCha8Rng) -> (f64, bool, Option<i64>) {
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
            let counts = (v.clamp(-self.range, self.range) / self.lsb).round();
            (counts * self.lsb, v.abs() > self.range, Some(counts as i64))
        } else {
            (v, false, None)
        }
    }
}

/// The run's sensor faults, the sample's time (s) and each fault's onset while it is active.
pub type FaultHook<'a> = (&'a mut SensorFaults, f64, &'a dyn Fn(usize) -> Option<f64>);

/// The firmware differences' low-pass at `cutoff_hz` (0: none) sampled every `period_s`:
/// the exact discretisation of a first-order low-pass, `alpha = 1 - exp(-2 pi fc Ts)`.
pub fn derivative_alpha(cutoff_hz: f64, period_s: f64) -> f64 {
    if cutoff_hz > 0.0 {
        1.0 - (-std::f64::consts::TAU * cutoff_hz * period_s).exp()
    } else {
        1.0
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
    line: VecDeque<([f64; 5], AdcCounts)>,
    d_force: Differentiator,
    d_piston: Differentiator,
    d_piston_vel: Differentiator,
    d_knee: Differentiator,
}

impl SampledSensors {
    /// Sensors sampled every `period_s` seconds, noise drawn from a stream seeded by `seed`.
    pub fn new(p: &SensorParams, period_s: f64, seed: u64) -> Self {
        let alpha = derivative_alpha(p.derivative_cutoff_hz, period_s);
        Self {
            period_s,
            alpha,
            adc: CHANNELS.map(|c| Adc::new(p.channel(c.id), p.preset, c.id)),
            enabled: CHANNELS.map(|c| p.channel(c.id).enabled),
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
        CHANNELS.iter().map(|c| c.name).zip(self.clipped).filter(|(_, n)| *n > 0).collect()
    }

    /// Take one sample of the plant whose ideal readings are `truth`: the readings the
    /// controller sees and their raw A/D counts.
    pub fn sample(&mut self, truth: &Measurement) -> (Measurement, AdcCounts) {
        self.sample_with(truth, None)
    }

    /// [`Self::sample`] with the run's sensor faults at the sample's time (s) and their
    /// activity (`active(i)`: fault i's onset while it is active), applied after the delay.
    pub fn sample_with(&mut self, truth: &Measurement, faults: Option<FaultHook>) -> (Measurement, AdcCounts) {
        let mut reading = [f64::NAN; 5];
        let mut counts = AdcCounts::default();
        for c in CHANNELS {
            let i = c.id as usize;
            if self.enabled[i] {
                let (v, clipped, n) = self.adc[i].read(truth.channel(c.id), &mut self.rng);
                reading[i] = v;
                counts.0[i] = n;
                self.clipped[i] += usize::from(clipped);
            }
        }
        self.line.push_back((reading, counts));
        // Until the delay line fills, firmware sees its first reading.
        let (mut r, mut counts) = if self.line.len() > self.delay {
            self.line.pop_front().unwrap_or((reading, counts))
        } else {
            self.line[0]
        };
        if let Some((f, t, active)) = faults {
            f.apply(t, 0, &mut r, &mut counts.0, active);
        }
        let (ts, a) = (self.period_s, self.alpha);
        let force_rate = self.d_force.update(r[0], ts, a, truth.force_rate_n_per_s);
        let (vel, acc) = if self.enabled[4] {
            (r[4], self.d_piston_vel.update(r[4], ts, a, truth.piston_accel_m_s2))
        } else {
            let vel = self.d_piston.update(r[2], ts, a, truth.piston_velocity_m_s);
            (vel, self.d_piston_vel.update(vel, ts, a, truth.piston_accel_m_s2))
        };
        let knee_rate = self.d_knee.update(r[3], ts, a, truth.knee_rate_rad_s);
        let y = Measurement {
            force_n: r[0],
            force_rate_n_per_s: force_rate,
            spool_m: r[1],
            piston_m: r[2],
            piston_velocity_m_s: vel,
            piston_accel_m_s2: acc,
            knee_rad: r[3],
            knee_rate_rad_s: knee_rate,
        };
        (y, counts)
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
            .map(|k| s.sample(&Measurement { force_n: 100.0 * k as f64 + 0.05, ..Default::default() }).0.force_n)
            .collect();
        // Delay of two samples (first reading repeated until the line fills), on the LSB grid.
        assert_eq!(ys[0], ys[1]);
        assert!((ys[2] - 0.05).abs() <= lsb / 2.0 + 1e-12);
        assert!((ys[4] - 200.05).abs() <= lsb / 2.0 + 1e-12);
        assert!(((ys[3] / lsb) - (ys[3] / lsb).round()).abs() < 1e-9);

        let mut p = SensorParams::default();
        p.force.noise_std = Some(2.0);
        let mut s = SampledSensors::new(&p, 1e-3, 7);
        let xs: Vec<f64> = (0..20000).map(|_| s.sample(&Measurement::default()).0.force_n).collect();
        let sd = (xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64).sqrt();
        assert!((sd - 2.0).abs() < 0.05, "noise sd {sd}");
    }
}
