//! The exoskeleton's own sensors (issue 32): the hip encoder, an IMU on the thigh and one on the
//! shank, heel and forefoot force sensors with a foot switch, force sensors in the thigh and
//! shank cuffs, and the hydraulic pressure transducers. Each reading is a channel of the one
//! readings table ([`crate::control::READINGS`]) on every route, sampled at the controller's
//! sample instants through the same chain as the force loop's channels (noise, A/D, delay),
//! plus what each kind needs. Per sample, in this order:
//!
//! ```text
//! IMU axis   y = AD((1 + s_i) x_i + b_i + w_i + sigma n),  sigma = N_d sqrt(f_imu)
//!            w_i += K sqrt(1/f_imu) n'                     (bias random walk, per IMU sample)
//!            x = R_WS^T (a_W - g_W) (accelerometer), R_WS^T omega_W (gyroscope)
//! foot       y = AD(F + sigma n); y < threshold -> 0;      F: heel / forefoot share of the
//!                                                          vertical ground reaction
//! other      y = AD(x + sigma n)
//! AD         clamp to [-range, range] (saturation), quantise to LSB = 2 range / 2^bits
//! hold       an IMU or the foot sensors update at their own rate (every n-th sample) and
//!            hold their reading in between
//! delay      the run's `sensors.delay_samples`
//! derived    hip rate: the encoder's filtered difference (as the knee's); foot switch: 1
//!            when the heel or the forefoot reads above its threshold
//! ```
//! `a_W` is the mean acceleration of the IMU's mounting point over its last sample period (the
//! change of its velocity divided by the period: the boxcar average an IMU's digital low-pass
//! stands for), so the same IMU reads the same on either leg engine whatever their steps; the
//! first sample reads the segment at rest (zero acceleration). `g_W = (0, 0, -9.81)` m/s^2:
//! an IMU at rest reads +9.81 m/s^2 up. The model is sagittal: the segments turn about the
//! world's y axis, so out-of-plane axes read their noise and bias only (and their share of
//! a rolled or yawed mounting). Noise streams are seeded per channel from the run's seed
//! (independent of the force loop's stream: adding a sensor changes no other reading).

use super::{Differentiator, SensorPreset};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

mod chain;
mod setup;
pub use setup::*;

/// Standard gravity (m/s^2), as the leg models use it.
pub const GRAVITY_M_S2: f64 = 9.81;

/// One IMU's three axes of one kind (accelerometer or gyroscope). Units are the reading's:
/// m/s^2 for the accelerometer, rad/s for the gyroscope. Absent figures are the preset's.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuAxes {
    /// White-noise density (unit/sqrt(Hz)); the per-sample standard deviation is
    /// `noise_density * sqrt(rate_hz)`. >= 0.
    pub noise_density: Option<f64>,
    /// Constant bias per axis (unit).
    pub bias: Option<[f64; 3]>,
    /// Bias random walk (unit/sqrt(s)): the bias moves by `K sqrt(1/rate_hz)` times a standard
    /// normal draw at every IMU sample. >= 0.
    pub bias_random_walk: Option<f64>,
    /// Scale-factor error per axis (fraction: 0.01 reads 1 % high). -0.5..=0.5.
    pub scale_error: Option<[f64; 3]>,
    /// Full scale (unit): readings saturate at +-range. > 0.
    pub range: Option<f64>,
    /// A/D resolution (bits over [-range, range]); 0 or absent with the `ideal` preset: none.
    pub bits: Option<u32>,
}

/// An IMU strapped to a segment (`[sensors.thigh_imu]`, `[sensors.shank_imu]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuParams {
    /// The IMU exists (its readings are NaN otherwise). Default true.
    pub enabled: bool,
    /// Mounting point in the segment's URDF link frame (m; the thigh's frame is at the hip,
    /// the shank's at the knee, x forward, z up along the standing segment). Default: 6 cm in
    /// front of the segment's axis, 40 % (thigh) or 35 % (shank) of the way down the segment
    /// (`[0.06, 0, -0.4 L]`, `[0.06, 0, -0.35 L]`, L the segment's length in the URDF).
    pub xyz_m: Option<[f64; 3]>,
    /// Orientation of the sensor frame in the link frame (rad, URDF roll-pitch-yaw about fixed
    /// x, y, z). Default [0, 0, 0]: x forward, y left, z up along the segment.
    pub rpy_rad: [f64; 3],
    /// Output data rate (Hz): the IMU updates every `sample rate / rate_hz` controller samples
    /// and holds its reading in between; it must divide the controller's sample rate.
    /// Default: the controller's sample rate.
    pub rate_hz: Option<f64>,
    /// The accelerometer (m/s^2, specific force in the sensor frame, gravity included).
    pub accel: ImuAxes,
    /// The gyroscope (rad/s, in the sensor frame).
    pub gyro: ImuAxes,
}

impl Default for ImuParams {
    fn default() -> Self {
        Self {
            enabled: true,
            xyz_m: None,
            rpy_rad: [0.0; 3],
            rate_hz: None,
            accel: ImuAxes::default(),
            gyro: ImuAxes::default(),
        }
    }
}

/// The foot's force sensors and switch (`[sensors.foot]`): a heel and a forefoot sensing
/// element under the sole (FSRs behind load spreaders).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FootParams {
    /// The sensors exist (NaN readings otherwise). Default true.
    pub enabled: bool,
    /// Sample rate (Hz), as [`ImuParams::rate_hz`]. Default: the controller's.
    pub rate_hz: Option<f64>,
    /// Activation threshold (N): a force below it reads 0 (an FSR does not conduct). >= 0.
    /// Default: the preset's (0 for `ideal`).
    pub threshold_n: Option<f64>,
    /// Noise standard deviation (N). >= 0.
    pub noise_std: Option<f64>,
    /// Saturation (N): readings are clamped to [0, range]. > 0.
    pub range: Option<f64>,
    /// A/D resolution (bits over [-range, range]).
    pub bits: Option<u32>,
    /// The heel sensor's position along the foot (m, x in the foot's link frame). Default: the
    /// rearmost contact point of the foot's collision shapes.
    pub heel_x_m: Option<f64>,
    /// The forefoot sensor's position (m, x in the foot's link frame). Default: the foremost
    /// contact point.
    pub forefoot_x_m: Option<f64>,
}

impl Default for FootParams {
    fn default() -> Self {
        Self {
            enabled: true,
            rate_hz: None,
            threshold_n: None,
            noise_std: None,
            range: None,
            bits: None,
            heel_x_m: None,
            forefoot_x_m: None,
        }
    }
}

/// Planar kinematics of a segment's link frame at one instant: the frame's origin, its turn
/// about the world's +y axis (as cos and sin), the origin's velocity and the angular velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentState {
    /// Origin (m, world x forward and z up).
    pub origin_m: [f64; 2],
    /// cos and sin of the frame's rotation about world +y (a forward-flexed thigh turns about
    /// -y: its angle is negative).
    pub cos_sin: (f64, f64),
    /// Velocity of the origin (m/s, x and z).
    pub velocity_m_s: [f64; 2],
    /// Angular velocity about world +y (rad/s).
    pub omega_rad_s: f64,
}

impl Default for SegmentState {
    fn default() -> Self {
        Self { origin_m: [0.0; 2], cos_sin: (1.0, 0.0), velocity_m_s: [0.0; 2], omega_rad_s: 0.0 }
    }
}

impl SegmentState {
    /// The segment's angle (rad): its link frame's forward turn from upright (about -y), the
    /// sagittal angle the columns `thigh_angle_deg`, `shank_angle_deg` report.
    pub fn angle_rad(&self) -> f64 {
        -self.cos_sin.1.atan2(self.cos_sin.0)
    }

    /// `u` (m, in the link frame's x and z) in world axes.
    fn rotate(&self, u: [f64; 2]) -> [f64; 2] {
        let (c, s) = self.cos_sin;
        [u[0] * c + u[1] * s, -u[0] * s + u[1] * c]
    }

    /// World position (m) and velocity (m/s) of the point `u` (m, link frame x and z).
    pub fn point(&self, u: [f64; 2]) -> ([f64; 2], [f64; 2]) {
        let r = self.rotate(u);
        let w = self.omega_rad_s;
        (
            [self.origin_m[0] + r[0], self.origin_m[1] + r[1]],
            [self.velocity_m_s[0] + w * r[1], self.velocity_m_s[1] - w * r[0]],
        )
    }

    /// A world point (m) in the link frame (x, z).
    pub fn to_local(&self, p: [f64; 2]) -> [f64; 2] {
        let (c, s) = self.cos_sin;
        let d = [p[0] - self.origin_m[0], p[1] - self.origin_m[1]];
        [d[0] * c - d[1] * s, d[0] * s + d[1] * c]
    }
}

/// The leg's segments for the device's sensors: the hip (thigh relative to the pelvis body)
/// and the thigh, shank and foot link frames.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LegKinematics {
    /// Hip flexion (rad) and its rate (rad/s): the thigh relative to the pelvis body (the
    /// carriage's pelvis does not pitch: its tilt is taken off the data's hip flexion); 0 for a
    /// welded thigh.
    pub hip: (f64, f64),
    /// The thigh's link frame.
    pub thigh: SegmentState,
    /// The shank's.
    pub shank: SegmentState,
    /// The foot's (the shank's when the ankle does not move... or the leg has no foot link).
    pub foot: SegmentState,
}

/// Where the ground's vertical reaction acts along the foot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FootLoad {
    /// Vertical ground reaction on the foot (N, up).
    pub vertical_n: f64,
    /// Centre of pressure along the foot (m, x in the foot's link frame); 0 without contact.
    pub cop_x_m: f64,
}

impl FootLoad {
    /// The heel and forefoot shares (N) for sensors at `heel_x_m` and `forefoot_x_m` along the
    /// foot: the lever rule on the centre of pressure (all on the heel behind it, all on the
    /// forefoot ahead of it).
    pub fn split(&self, heel_x_m: f64, forefoot_x_m: f64) -> (f64, f64) {
        if self.vertical_n == 0.0 {
            return (0.0, 0.0);
        }
        let f = ((self.cop_x_m - heel_x_m) / (forefoot_x_m - heel_x_m)).clamp(0.0, 1.0);
        let fore = self.vertical_n * f;
        (self.vertical_n - fore, fore)
    }
}

/// What the device's sensors measure at one instant: the plant's and the cylinder's truth.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DeviceTruth {
    /// The leg's segments (None on the bench).
    pub leg: Option<LegKinematics>,
    /// The ground's reaction on the foot (zero in the air; None on the bench).
    pub foot: Option<FootLoad>,
    /// Normal force the thigh cuff carries (N, positive pressing the thigh forward; NaN on the
    /// bench).
    pub thigh_cuff_force_n: f64,
    /// Normal force the shank cuff carries (N, positive pressing the shank forward).
    pub shank_cuff_force_n: f64,
    /// Cap-side (A) chamber pressure (Pa).
    pub pressure_a_pa: f64,
    /// Rod-side (B) chamber pressure (Pa).
    pub pressure_b_pa: f64,
    /// Supply pressure (Pa).
    pub supply_pressure_pa: f64,
    /// Load pressure `F_L / A_eff` (Pa), `A_eff = (A1 + A2) / 2`.
    pub load_pressure_pa: f64,
}

/// The device's readings of one sample (SI units; NaN for a sensor the run does not have).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DeviceReadings {
    /// Hip encoder (rad).
    pub hip_rad: f64,
    /// Its filtered difference (rad/s).
    pub hip_rate_rad_s: f64,
    /// Thigh accelerometer, sensor frame x, y, z (m/s^2).
    pub thigh_accel_m_s2: [f64; 3],
    /// Thigh gyroscope (rad/s).
    pub thigh_gyro_rad_s: [f64; 3],
    /// Shank accelerometer (m/s^2).
    pub shank_accel_m_s2: [f64; 3],
    /// Shank gyroscope (rad/s).
    pub shank_gyro_rad_s: [f64; 3],
    /// Heel force (N).
    pub heel_force_n: f64,
    /// Forefoot force (N).
    pub forefoot_force_n: f64,
    /// Foot switch: 1 when the heel or the forefoot reads above its threshold, else 0.
    pub foot_contact: f64,
    /// Thigh cuff force (N).
    pub thigh_cuff_force_n: f64,
    /// Shank cuff force (N).
    pub shank_cuff_force_n: f64,
    /// Chamber A pressure (Pa).
    pub pressure_a_pa: f64,
    /// Chamber B pressure (Pa).
    pub pressure_b_pa: f64,
    /// Supply pressure (Pa).
    pub supply_pressure_pa: f64,
    /// Load pressure (Pa).
    pub load_pressure_pa: f64,
}

impl Default for DeviceReadings {
    fn default() -> Self {
        Self::from_values(&[f64::NAN; DEVICE_READINGS])
    }
}

/// Number of device readings ([`DeviceReadings::values`]).
pub const DEVICE_READINGS: usize = 23;

impl DeviceReadings {
    /// The readings in the order of the readings table's device part.
    pub fn values(&self) -> [f64; DEVICE_READINGS] {
        let (ta, tg, sa, sg) =
            (self.thigh_accel_m_s2, self.thigh_gyro_rad_s, self.shank_accel_m_s2, self.shank_gyro_rad_s);
        [
            self.hip_rad,
            self.hip_rate_rad_s,
            ta[0],
            ta[1],
            ta[2],
            tg[0],
            tg[1],
            tg[2],
            sa[0],
            sa[1],
            sa[2],
            sg[0],
            sg[1],
            sg[2],
            self.heel_force_n,
            self.forefoot_force_n,
            self.foot_contact,
            self.thigh_cuff_force_n,
            self.shank_cuff_force_n,
            self.pressure_a_pa,
            self.pressure_b_pa,
            self.supply_pressure_pa,
            self.load_pressure_pa,
        ]
    }

    /// The readings from values in the order of [`Self::values`].
    pub fn from_values(v: &[f64; DEVICE_READINGS]) -> Self {
        Self {
            hip_rad: v[0],
            hip_rate_rad_s: v[1],
            thigh_accel_m_s2: [v[2], v[3], v[4]],
            thigh_gyro_rad_s: [v[5], v[6], v[7]],
            shank_accel_m_s2: [v[8], v[9], v[10]],
            shank_gyro_rad_s: [v[11], v[12], v[13]],
            heel_force_n: v[14],
            forefoot_force_n: v[15],
            foot_contact: v[16],
            thigh_cuff_force_n: v[17],
            shank_cuff_force_n: v[18],
            pressure_a_pa: v[19],
            pressure_b_pa: v[20],
            supply_pressure_pa: v[21],
            load_pressure_pa: v[22],
        }
    }
}

/// Which part of the device an A/D channel belongs to (its settings and its update rate).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceKind {
    /// The hip encoder.
    Hip,
    /// An accelerometer axis of the thigh (0) or shank (1) IMU.
    Accel(usize, usize),
    /// A gyroscope axis.
    Gyro(usize, usize),
    /// The heel (0) or forefoot (1) force sensor.
    Foot(usize),
    /// A plain channel: cuffs and pressures.
    Plain,
}

/// One A/D channel of the device: its scenario key, reading, unit, kind and default range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceChannel {
    /// Scenario key under `sensors.` (the settings; for IMU axes the IMU's and kind's table).
    pub key: &'static str,
    /// The reading's name.
    pub reading: &'static str,
    /// SI unit.
    pub unit: &'static str,
    /// What it belongs to.
    pub kind: DeviceKind,
    /// Default full scale (unit).
    pub default_range: f64,
}

const fn ch(key: &'static str, reading: &'static str, unit: &'static str, kind: DeviceKind, r: f64) -> DeviceChannel {
    DeviceChannel { key, reading, unit, kind, default_range: r }
}

/// Accelerometer full scale (m/s^2): +-16 g, the MPU-6000's widest.
pub const ACCEL_RANGE_M_S2: f64 = 16.0 * GRAVITY_M_S2;
/// Gyroscope full scale (rad/s): +-2000 deg/s.
pub const GYRO_RANGE_RAD_S: f64 = 2000.0 * std::f64::consts::PI / 180.0;
/// Foot sensor full scale (N).
pub const FOOT_RANGE_N: f64 = 2000.0;
/// Cuff sensor full scale (N).
pub const CUFF_RANGE_N: f64 = 1000.0;
/// Pressure transducer full scale (Pa): 250 bar.
pub const PRESSURE_RANGE_PA: f64 = 25e6;

/// The device's A/D channels, in the order of their counts (`ExolegReadings.device_counts`).
pub const DEVICE_CHANNELS: [DeviceChannel; 21] = [
    ch("hip", "hip_rad", "rad", DeviceKind::Hip, std::f64::consts::PI),
    ch("thigh_imu.accel", "thigh_accel_x_m_s2", "m/s2", DeviceKind::Accel(0, 0), ACCEL_RANGE_M_S2),
    ch("thigh_imu.accel", "thigh_accel_y_m_s2", "m/s2", DeviceKind::Accel(0, 1), ACCEL_RANGE_M_S2),
    ch("thigh_imu.accel", "thigh_accel_z_m_s2", "m/s2", DeviceKind::Accel(0, 2), ACCEL_RANGE_M_S2),
    ch("thigh_imu.gyro", "thigh_gyro_x_rad_s", "rad/s", DeviceKind::Gyro(0, 0), GYRO_RANGE_RAD_S),
    ch("thigh_imu.gyro", "thigh_gyro_y_rad_s", "rad/s", DeviceKind::Gyro(0, 1), GYRO_RANGE_RAD_S),
    ch("thigh_imu.gyro", "thigh_gyro_z_rad_s", "rad/s", DeviceKind::Gyro(0, 2), GYRO_RANGE_RAD_S),
    ch("shank_imu.accel", "shank_accel_x_m_s2", "m/s2", DeviceKind::Accel(1, 0), ACCEL_RANGE_M_S2),
    ch("shank_imu.accel", "shank_accel_y_m_s2", "m/s2", DeviceKind::Accel(1, 1), ACCEL_RANGE_M_S2),
    ch("shank_imu.accel", "shank_accel_z_m_s2", "m/s2", DeviceKind::Accel(1, 2), ACCEL_RANGE_M_S2),
    ch("shank_imu.gyro", "shank_gyro_x_rad_s", "rad/s", DeviceKind::Gyro(1, 0), GYRO_RANGE_RAD_S),
    ch("shank_imu.gyro", "shank_gyro_y_rad_s", "rad/s", DeviceKind::Gyro(1, 1), GYRO_RANGE_RAD_S),
    ch("shank_imu.gyro", "shank_gyro_z_rad_s", "rad/s", DeviceKind::Gyro(1, 2), GYRO_RANGE_RAD_S),
    ch("foot", "heel_force_n", "N", DeviceKind::Foot(0), FOOT_RANGE_N),
    ch("foot", "forefoot_force_n", "N", DeviceKind::Foot(1), FOOT_RANGE_N),
    ch("thigh_cuff", "thigh_cuff_force_n", "N", DeviceKind::Plain, CUFF_RANGE_N),
    ch("shank_cuff", "shank_cuff_force_n", "N", DeviceKind::Plain, CUFF_RANGE_N),
    ch("pressure_a", "pressure_a_pa", "Pa", DeviceKind::Plain, PRESSURE_RANGE_PA),
    ch("pressure_b", "pressure_b_pa", "Pa", DeviceKind::Plain, PRESSURE_RANGE_PA),
    ch("supply_pressure", "supply_pressure_pa", "Pa", DeviceKind::Plain, PRESSURE_RANGE_PA),
    ch("load_pressure", "load_pressure_pa", "Pa", DeviceKind::Plain, PRESSURE_RANGE_PA),
];

/// Raw A/D counts of the device's channels (in [`DEVICE_CHANNELS`] order): `reading = counts *
/// lsb`; None for a channel without quantisation, switched off, or reading NaN.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct DeviceCounts(pub [Option<i64>; 21]);

/// The `device` preset's figures, from typical datasheets (README, "The device's sensors").
pub mod device_preset {
    use super::GRAVITY_M_S2;
    const DEG: f64 = std::f64::consts::PI / 180.0;
    /// MPU-6000 accelerometer noise density, 400 ug/sqrt(Hz) (PS-MPU-6000A-00 rev 3.4, 6.2).
    pub const ACCEL_NOISE_DENSITY: f64 = 400e-6 * GRAVITY_M_S2;
    /// A unit's zero-g offsets within the datasheet's +-50 mg (x, y) / +-80 mg (z) (m/s^2).
    pub const ACCEL_BIAS: [f64; 3] = [0.20, -0.15, 0.30];
    /// Accelerometer bias random walk (m/s^2/sqrt(s)): 2e-4, about 20 ug/sqrt(s) (the datasheet
    /// gives none; Allan-deviation figures of consumer MEMS accelerometers are of this order).
    pub const ACCEL_BIAS_RW: f64 = 2e-4;
    /// A unit's sensitivity errors within the datasheet's +-3 % calibration tolerance.
    pub const ACCEL_SCALE: [f64; 3] = [0.010, -0.008, 0.012];
    /// MPU-6000 gyroscope rate-noise density, 0.005 deg/s/sqrt(Hz) (6.1).
    pub const GYRO_NOISE_DENSITY: f64 = 0.005 * DEG;
    /// A unit's zero-rate offsets (rad/s; 0.5, -0.3, 0.4 deg/s, within +-20 deg/s).
    pub const GYRO_BIAS: [f64; 3] = [0.5 * DEG, -0.3 * DEG, 0.4 * DEG];
    /// Gyroscope bias random walk (rad/s/sqrt(s)): 2e-5, about 4 deg/h/sqrt(s) (of the order of
    /// consumer MEMS gyroscopes' rate random walk; the datasheet gives none).
    pub const GYRO_BIAS_RW: f64 = 2e-5;
    /// Gyroscope sensitivity errors (within +-3 %).
    pub const GYRO_SCALE: [f64; 3] = [-0.010, 0.015, 0.005];
    /// The IMU's A/D word length (16 bits) and output data rate (1 kHz).
    pub const IMU_BITS: u32 = 16;
    /// Hip and knee encoders: 14-bit magnetic (AS5047P class) over a turn.
    pub const ENCODER_BITS: u32 = 14;
    /// Foot sensors: an FSR 402-class element behind a load spreader, read by a 12-bit MCU A/D:
    /// activation threshold (N), noise (N), saturation (N), bits, rate (Hz).
    pub const FOOT: (f64, f64, f64, u32, f64) = (20.0, 5.0, 1500.0, 12, 500.0);
    /// Cuff load cells: noise (N), bits.
    pub const CUFF: (f64, u32) = (0.5, 16);
    /// Pressure transducers, 0.25 % FS accuracy over 250 bar: noise 0.1 % FS (Pa), 12 bits.
    pub const PRESSURE: (f64, u32) = (25e3, 12);
}

/// The figures of one device A/D channel after the preset and the scenario's explicit values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceFigures {
    /// The sensor exists.
    pub enabled: bool,
    /// White-noise standard deviation per sample of the sensor (unit).
    pub noise_std: f64,
    /// Constant bias (unit).
    pub bias: f64,
    /// Bias random walk per sensor sample (unit).
    pub bias_step: f64,
    /// Scale-factor error (fraction).
    pub scale_error: f64,
    /// A/D bits (0: no quantisation).
    pub bits: u32,
    /// Full scale (unit).
    pub range: f64,
    /// Activation threshold (N; foot sensors; 0 otherwise).
    pub threshold: f64,
}

/// The resolved settings of one device sensor: its figures and how many controller samples it
/// holds each reading.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Adc {
    fig: DeviceFigures,
    lsb: f64,
}

impl Adc {
    fn new(fig: DeviceFigures) -> Self {
        let lsb = if fig.bits == 0 { 0.0 } else { 2.0 * fig.range / 2f64.powi(fig.bits as i32) };
        Self { fig, lsb }
    }

    /// Clamp and quantise `v`: the reading and its counts (None without quantisation).
    fn convert(&self, v: f64) -> (f64, Option<i64>) {
        let r = self.fig.range;
        if self.lsb > 0.0 {
            let counts = (v.clamp(-r, r) / self.lsb).round();
            (counts * self.lsb, Some(counts as i64))
        } else {
            (v.clamp(-r, r), None)
        }
    }
}

/// The device's settings as the chain runs them (built once per run by [`super::SensorParams`]).
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceSetup {
    /// Per channel of [`DEVICE_CHANNELS`].
    pub figures: [DeviceFigures; 21],
    /// Controller samples per update of the thigh IMU, the shank IMU and the foot sensors.
    pub every: [usize; 3],
    /// The IMUs' mounting points (m, link frame x and z) and sensor-to-link rotations.
    pub imu_mount: [([f64; 2], [[f64; 3]; 3]); 2],
    /// Where the heel and forefoot sensors sit along the foot (m, foot frame x).
    pub foot_x_m: (f64, f64),
}

/// The sensor-to-link rotation of URDF roll-pitch-yaw angles (rad): `Rz(yaw) Ry(pitch)
/// Rx(roll)`, rows of the matrix.
pub fn rpy_matrix(rpy: [f64; 3]) -> [[f64; 3]; 3] {
    let (sr, cr) = rpy[0].sin_cos();
    let (sp, cp) = rpy[1].sin_cos();
    let (sy, cy) = rpy[2].sin_cos();
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

/// One IMU's state between its samples: the mounting point's velocity at its last update.
#[derive(Debug, Clone, Copy, Default)]
struct ImuTrack {
    last_velocity: Option<([f64; 2], f64)>,
}

/// The device's sampled chain (see the module doc).
#[derive(Debug, Clone)]
pub struct DeviceSensors {
    setup: DeviceSetup,
    adc: [Adc; 21],
    rngs: Vec<ChaCha8Rng>,
    walk: [f64; 21],
    held: [f64; 21],
    held_counts: [Option<i64>; 21],
    clipped: [usize; 21],
    imu: [ImuTrack; 2],
    samples: usize,
    period_s: f64,
    alpha: f64,
    delay: usize,
    line: VecDeque<([f64; 21], DeviceCounts)>,
    d_hip: Differentiator,
}

#[cfg(test)]
mod tests;
