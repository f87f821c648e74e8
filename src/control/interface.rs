//! The controller contracts: a continuous-time block ([`Controller`], evaluated at every
//! integrator stage) and a sampled one ([`DiscreteController`], called once per sample period
//! on the sensor readings, its output held). Every controller from outside the crate (a Rust
//! trait object, a Python callback, a C plugin) is a [`DiscreteController`].

use crate::hydraulics::Coefficients;
use crate::reference::RefSample;
pub use crate::sensors::{AdcCounts, DeviceCounts, DeviceReadings, Measurement};
use serde::Serialize;

/// What a controller outputs besides the command, for logging.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ControlOutput {
    /// Valve command u.
    pub valve_command: f64,
    /// The controller's estimate of the lumped disturbance on dx2/dt (N/s^2):
    /// `g_hat + D_hat` for ARBFNN-FDO-ZNN, 0 for controllers without an estimator.
    pub disturbance_estimate_n_per_s2: f64,
    /// The RBF network's part of it, `g_hat` (N/s^2).
    pub rbf_output_n_per_s2: f64,
    /// True when the command was clipped by the valve limit: controllers stop adapting
    /// (conditional integration, the anti-windup of the RBF weights).
    pub saturated: bool,
}

/// A force controller. See the module doc for the evaluation contract.
pub trait Controller: Send + Sync {
    /// Short name, as in the scenario's `controller.kind`.
    fn kind(&self) -> &'static str;
    /// Names of the internal states, in order (used in divergence reports and CSV headers).
    fn state_names(&self) -> Vec<String>;
    /// Number of internal states (any number; the loop sizes its state when the controller is
    /// built); called at every stage, so a controller with states should give it without
    /// building the names.
    fn state_len(&self) -> usize {
        self.state_names().len()
    }
    /// Initial internal state from the first measurement.
    fn init(&self, y: &Measurement, r: &RefSample, s: &mut [f64]);
    /// Control output at time `t_s` (pure).
    fn output(&self, t_s: f64, r: &RefSample, y: &Measurement, s: &[f64]) -> ControlOutput;
    /// Time derivative of the internal state (pure). `u` is the output just computed.
    fn derivatives(&self, t_s: f64, r: &RefSample, y: &Measurement, s: &[f64], u: &ControlOutput, ds: &mut [f64]);
    /// [`Self::output`] clipped by `limit`, then [`Self::derivatives`] with it: one integrator
    /// stage. A controller whose output and derivatives share terms computes them once here;
    /// the result must equal the two calls'.
    fn output_and_derivatives(
        &self,
        t_s: f64,
        r: &RefSample,
        y: &Measurement,
        s: &[f64],
        limit: ValveLimit,
        ds: &mut [f64],
    ) -> ControlOutput {
        let o = limit.apply(self.output(t_s, r, y, s));
        self.derivatives(t_s, r, y, s, &o, ds);
        o
    }
    /// Largest local rate (1/s) of the internal state's own dynamics at force rate
    /// `force_rate_n_per_s` (N/s): the loop substeps the continuous controller when it would
    /// outrun the integrator. Default 0 (not stiff).
    fn stiffness_per_s(&self, _force_rate_n_per_s: f64, _s: &[f64]) -> f64 {
        0.0
    }

    /// Sampled mode: advance the internal state over one sample period `ts_s` after the
    /// output `u` was computed from the sample. Default: forward Euler on [`Self::derivatives`],
    /// which is what simple firmware does. `scratch` has the length of `s`.
    #[allow(clippy::too_many_arguments)]
    fn discrete_update(
        &self,
        t_s: f64,
        ts_s: f64,
        r: &RefSample,
        y: &Measurement,
        s: &mut [f64],
        u: &ControlOutput,
        scratch: &mut [f64],
    ) {
        self.derivatives(t_s, r, y, s, u, scratch);
        for (x, d) in s.iter_mut().zip(scratch.iter()) {
            *x += ts_s * d;
        }
    }
}

/// The controller's nominal model: the parts of the paper's Eq. 5 it inverts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NominalModel {
    /// Nominal coefficients n1..n3, tau, k_s.
    pub c: Coefficients,
}

impl NominalModel {
    /// Nominal spool rate dx3/dt = (k_s*u - x3)/tau (m/s) for command `u` at spool `x3`.
    pub fn spool_rate(&self, u: f64, spool_m: f64) -> f64 {
        (self.c.k_s * u - spool_m) / self.c.tau_s
    }

    /// Nominal dx2/dt without disturbance: n1*dx3/dt - n3*x2 - n2*xc_ddot (N/s^2).
    pub fn force_accel(&self, u: f64, y: &Measurement) -> f64 {
        self.c.n1 * self.spool_rate(u, y.spool_m) - self.c.n3 * y.force_rate_n_per_s - self.c.n2 * y.piston_accel_m_s2
    }

    /// The valve command that makes the nominal dx2/dt equal `accel_wanted` (N/s^2):
    /// `u = tau/(n1*k_s) * [accel_wanted + n3*x2 + n2*xc_ddot + n1*x3/tau]`.
    pub fn invert(&self, accel_wanted: f64, y: &Measurement) -> f64 {
        let c = &self.c;
        c.tau_s / (c.n1 * c.k_s)
            * (accel_wanted + c.n3 * y.force_rate_n_per_s + c.n2 * y.piston_accel_m_s2 + c.n1 * y.spool_m / c.tau_s)
    }
}

/// The valve command limit |u| <= limit (0 = none). Controllers are told when it clips, so
/// they stop adapting (anti-windup).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ValveLimit(pub f64);

impl ValveLimit {
    /// Clip the command and mark the output saturated when it was clipped.
    pub fn apply(&self, mut o: ControlOutput) -> ControlOutput {
        let lim = self.0;
        if lim > 0.0 && o.valve_command.abs() > lim {
            o.valve_command = o.valve_command.clamp(-lim, lim);
            o.saturated = true;
        }
        o
    }
}

/// What a sampled controller gets at each sample instant: the public interface of every
/// controller in the loop (see the README's "Your controller" for the table of readings, with
/// their units, sampling and quantisation).
#[derive(Debug, Clone, Copy)]
pub struct SampleInput {
    /// Sample instant t_k (s).
    pub t_s: f64,
    /// Sample period (s).
    pub period_s: f64,
    /// The readings at t_k, after noise, A/D, delay and the firmware differences.
    pub y: Measurement,
    /// Raw A/D counts of the readings (quantised channels only): `y.<channel> = counts * lsb`.
    pub counts: AdcCounts,
    /// The device's own sensors at t_k (IMUs, hip encoder, foot, cuffs, pressures).
    pub device: DeviceReadings,
    /// Their raw A/D counts.
    pub device_counts: DeviceCounts,
    /// Desired force (N) and its first and second derivatives (N/s, N/s^2) at t_k; on a gait
    /// it includes the cascade's outer knee loop, computed from the same readings.
    pub r: RefSample,
    /// Desired force and derivatives at t_{k+1} = t_k + period_s (one-step preview of a known
    /// reference; the outer knee loop's part is held).
    pub r_next: RefSample,
    /// The valve's command limit |u| <= limit (0 = none): the actuator clips any command to it.
    pub valve_limit: ValveLimit,
}

/// One reading a sampled controller gets, by the name every route uses (the Python `Obs`
/// attribute, the C plugin's `ExolegReadings` field, the FMU's output variable).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReadingInfo {
    /// Name, with its unit in the suffix.
    pub name: &'static str,
    /// SI unit ("" for a pure number).
    pub unit: &'static str,
    /// What it is.
    pub description: &'static str,
}

const fn reading(name: &'static str, unit: &'static str, description: &'static str) -> ReadingInfo {
    ReadingInfo { name, unit, description }
}

/// Number of readings of one sample ([`READINGS`]): the force loop's 17 (ABI 1.0) and the
/// device's 23 (ABI 1.1).
pub const N_READINGS: usize = 17 + crate::sensors::DEVICE_READINGS;

/// The readings of one sample in the order of [`SampleInput::reading_values`]. The first 17
/// are the force loop's (ABI 1.0); the device's own sensors follow (ABI 1.1). Sensor frames:
/// x forward, y left, z up along the segment with the default mounting.
pub const READINGS: [ReadingInfo; N_READINGS] = [
    reading("t_s", "s", "sample instant"),
    reading("period_s", "s", "sample period"),
    reading("force_n", "N", "load cell"),
    reading("force_rate_n_per_s", "N/s", "the load cell's firmware difference"),
    reading("spool_m", "m", "spool LVDT (NaN without the sensor)"),
    reading("piston_m", "m", "piston position from t = 0"),
    reading("piston_velocity_m_s", "m/s", "piston velocity"),
    reading("piston_accel_m_s2", "m/s2", "filtered difference of the piston velocity"),
    reading("knee_rad", "rad", "knee flexion (encoder)"),
    reading("knee_rate_rad_s", "rad/s", "the encoder's filtered difference"),
    reading("ref_force_n", "N", "desired force at the sample instant (NaN with reference.force = \"none\")"),
    reading("ref_force_rate_n_per_s", "N/s", "its first derivative"),
    reading("ref_force_accel_n_per_s2", "N/s2", "its second derivative"),
    reading("next_ref_force_n", "N", "desired force one sample period ahead"),
    reading("next_ref_force_rate_n_per_s", "N/s", "its first derivative"),
    reading("next_ref_force_accel_n_per_s2", "N/s2", "its second derivative"),
    reading("valve_command_limit", "", "|u| <= limit (0 = none)"),
    reading("hip_rad", "rad", "hip flexion encoder (thigh relative to the pelvis)"),
    reading("hip_rate_rad_s", "rad/s", "the hip encoder's filtered difference"),
    reading("thigh_accel_x_m_s2", "m/s2", "thigh IMU accelerometer x (specific force, gravity included)"),
    reading("thigh_accel_y_m_s2", "m/s2", "thigh IMU accelerometer y"),
    reading("thigh_accel_z_m_s2", "m/s2", "thigh IMU accelerometer z"),
    reading("thigh_gyro_x_rad_s", "rad/s", "thigh IMU gyroscope x"),
    reading("thigh_gyro_y_rad_s", "rad/s", "thigh IMU gyroscope y (sagittal: -d(thigh angle)/dt)"),
    reading("thigh_gyro_z_rad_s", "rad/s", "thigh IMU gyroscope z"),
    reading("shank_accel_x_m_s2", "m/s2", "shank IMU accelerometer x"),
    reading("shank_accel_y_m_s2", "m/s2", "shank IMU accelerometer y"),
    reading("shank_accel_z_m_s2", "m/s2", "shank IMU accelerometer z"),
    reading("shank_gyro_x_rad_s", "rad/s", "shank IMU gyroscope x"),
    reading("shank_gyro_y_rad_s", "rad/s", "shank IMU gyroscope y (sagittal: -d(shank angle)/dt)"),
    reading("shank_gyro_z_rad_s", "rad/s", "shank IMU gyroscope z"),
    reading("heel_force_n", "N", "heel force sensor"),
    reading("forefoot_force_n", "N", "forefoot force sensor"),
    reading("foot_contact", "", "foot switch: 1 when the heel or forefoot reads above its threshold"),
    reading("thigh_cuff_force_n", "N", "thigh cuff force sensor (normal, forward positive)"),
    reading("shank_cuff_force_n", "N", "shank cuff force sensor (normal, forward positive)"),
    reading("pressure_a_pa", "Pa", "chamber A (cap side) pressure"),
    reading("pressure_b_pa", "Pa", "chamber B (rod side) pressure"),
    reading("supply_pressure_pa", "Pa", "supply pressure"),
    reading("load_pressure_pa", "Pa", "load pressure F_L / A_eff"),
];

impl SampleInput {
    /// The readings as numbers, in the order of [`READINGS`].
    pub fn reading_values(&self) -> [f64; N_READINGS] {
        let (y, r, n) = (&self.y, &self.r, &self.r_next);
        let mut v = [0.0; N_READINGS];
        v[..17].copy_from_slice(&[
            self.t_s,
            self.period_s,
            y.force_n,
            y.force_rate_n_per_s,
            y.spool_m,
            y.piston_m,
            y.piston_velocity_m_s,
            y.piston_accel_m_s2,
            y.knee_rad,
            y.knee_rate_rad_s,
            r.value,
            r.rate,
            r.accel,
            n.value,
            n.rate,
            n.accel,
            self.valve_limit.0,
        ]);
        v[17..].copy_from_slice(&self.device.values());
        v
    }
}

/// Why a sampled controller stops the run (a C plugin's stop status, a failing callback).
#[derive(Debug, Clone, PartialEq)]
pub struct ControlStop {
    /// What the controller said.
    pub message: String,
    /// A deliberate stop, a command that is not a number, or a failure (crash, exception).
    pub cause: StopCause,
}

impl ControlStop {
    /// The controller stops on purpose (a plugin's stop status, your controller's own check):
    /// under `controller.on_stop = "failsafe"` a fault campaign counts it as a detection.
    pub fn stop(message: impl Into<String>) -> Self {
        Self { message: message.into(), cause: StopCause::Stop }
    }

    /// The controller failed (a crash, an `exit()`, a hang, a broken protocol or link, an
    /// exception): never a detection.
    pub fn crash(message: impl Into<String>) -> Self {
        Self { message: message.into(), cause: StopCause::Crash }
    }

    /// The controller's command is not a number.
    pub fn command(message: impl Into<String>) -> Self {
        Self { message: message.into(), cause: StopCause::Command }
    }
}

pub use crate::faults::StopCause;

/// A controller that runs once per sample period on the readings and holds its output
/// (zero-order hold): the built-in firmware controllers, and every controller from outside the
/// crate (put one in a run with [`crate::sim::Simulation::with_controller`] or
/// [`crate::study::RunBuilder`]).
///
/// ```
/// use exoleg::control::{ControlOutput, ControlStop, DiscreteController, SampleInput};
/// /// A proportional force loop (valve command per newton of error).
/// struct P(f64);
/// impl DiscreteController for P {
///     fn kind(&self) -> &str { "p" }
///     fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
///         Ok(ControlOutput::command(self.0 * (s.r.value - s.y.force_n)))
///     }
/// }
/// let sets = ["plant.kind=\"bench\"", "sim.duration_s=0.2", "controller.sample_period_s=0.001"];
/// let sc = exoleg::load(None, &sets).unwrap();
/// let mut sim = exoleg::Simulation::with_controller(sc.model.clone(), Box::new(P(1e-4))).unwrap();
/// while !sim.done() {
///     sim.step(&mut exoleg::record::NullSink).unwrap();
/// }
/// ```
pub trait DiscreteController: Send {
    /// Short name for reports (the built-in ones use their `controller.kind`).
    fn kind(&self) -> &str;
    /// One sample: read, compute, advance the internal state; returns the output to hold. The
    /// actuator clips the command to the valve limit (and marks the output saturated) whatever
    /// the controller returns. An error stops the run (exit 3, the message names the time).
    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop>;
    /// The first non-finite internal state with its name, if any (divergence reports).
    fn first_non_finite(&self) -> Option<(String, f64)> {
        None
    }
    /// Design figures computed at start (gains, poles) for `summary.json`; None if none.
    fn design(&self) -> Option<serde_json::Value> {
        None
    }
    /// Names of the extra channels the controller logs (columns `log_<name>` of
    /// `timeseries.csv`, at most [`MAX_LOGGED`]); fixed for the run.
    fn log_names(&self) -> Vec<String> {
        Vec::new()
    }
    /// The logged values of the last update, in [`Self::log_names`] order.
    fn log_values(&self, _out: &mut [f64]) {}
    /// How many samples the controller flagged with a warning so far (a C plugin's warning
    /// status), and the last warning's text.
    fn warnings(&self) -> (usize, Option<String>) {
        (0, None)
    }

    /// Wall time of each of the controller's computations so far (s): measured, reported in
    /// `summary.json` (`controller_compute`), never fed to the physics. Empty when not
    /// measured (the built-in controllers).
    fn compute_times_s(&self) -> &[f64] {
        &[]
    }

    /// Figures of the link to a controller outside the process (an isolated plugin's round
    /// trips; a hardware-in-the-loop peer's latency, losses and deadlines), if there is one.
    fn link_report(&self) -> Option<serde_json::Value> {
        None
    }
}

pub use crate::record::MAX_LOGGED;

impl ControlOutput {
    /// An output with valve command `u` and nothing else.
    pub fn command(u: f64) -> Self {
        Self { valve_command: u, ..Default::default() }
    }
}
