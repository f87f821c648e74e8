//! Faults (issue 35): what breaks, when, for how long (`[[faults]]` in a scenario). Each block
//! applies the faults that concern it: the sensor chains their sensors' (what the controller
//! reads changes, the truth does not), the cylinder its valve's, leakage and supply faults, the
//! loop the power and controller faults; the loop's clock decides when each is active.
//!
//! ```text
//! target            kinds (parameters)
//! a reading channel dropout (mode: nan | zero | hold), stuck (value; absent: the reading at the
//!   (knee_rad, ...) onset), bias (bias), drift (rate, unit/s), gain (gain), noise (sd), spikes
//!                   (amplitude, probability per sample), saturation (level), delay (samples)
//! valve             stuck (value: spool position, m; absent: where it is), slow (tau_factor)
//! leakage           orifice (area_m2, discharge_coefficient, density_kg_m3): a bypass across
//!                   the piston, Q = C_d A sqrt(2 |p_A - p_B| / rho) sign(p_A - p_B)
//! supply            loss (residual: the fraction of the supply pressure left; tau_s: its time
//!                   constant, 0 = sudden)
//! power             loss: the valve's command goes to 0 (spring-centred spool); with
//!                   `actuator.failsafe = "free"` a bypass valve also opens
//! controller        overrun (samples: each command takes effect that many samples late),
//!                   skip (the controller is not called; the last command holds), lost
//!                   (probability: each sample lost so, the last command holding)
//! ```
//! Onset: `onset_s` (s), or `onset_event = "heel_strike"` with `onset_phase_pct` (% of the
//! stride after the first heel strike at or after `onset_after_s`, default the run-in
//! `metrics.settle_s`). `duration_s` absent: permanent.

use serde::{Deserialize, Serialize};

/// One `[[faults]]` entry as written.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultSpec {
    /// A reading channel (`knee_rad`, `force_n`, `thigh_gyro_y_rad_s`, ...), `valve`, `leakage`,
    /// `supply`, `power` or `controller`.
    pub target: String,
    /// The fault's kind (see the module doc).
    pub kind: String,
    /// Onset time (s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onset_s: Option<f64>,
    /// Onset at a gait event: `heel_strike`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onset_event: Option<String>,
    /// With `onset_event`: the onset this far into the stride after the event (%). 0..100.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onset_phase_pct: Option<f64>,
    /// With `onset_event`: the first event at or after this time (s). Default: the run-in
    /// (`metrics.settle_s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onset_after_s: Option<f64>,
    /// How long the fault lasts (s); absent: to the end of the run. >= 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<f64>,
    /// Sensor dropout: `nan` (default), `zero` or `hold` (the last reading).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode: Option<String>,
    /// Stuck: the value (a sensor's unit; the valve's spool position, m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// Bias step (the sensor's unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias: Option<f64>,
    /// Drift rate (the sensor's unit per s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate: Option<f64>,
    /// Gain (a factor: 1.2 reads 20 % high).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain: Option<f64>,
    /// Noise burst: the added noise's standard deviation (the sensor's unit). >= 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sd: Option<f64>,
    /// Spikes: their amplitude (the sensor's unit; the sign is drawn).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<f64>,
    /// Spikes, lost samples: the probability per sample. 0..=1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probability: Option<f64>,
    /// Saturation: the level the reading clips at (the sensor's unit, +-level). > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<f64>,
    /// Extra delay, overrun: samples. >= 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// Slow valve: the spool's time constant times this. >= 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau_factor: Option<f64>,
    /// Leakage: the orifice's area (m^2). > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub area_m2: Option<f64>,
    /// Leakage: the discharge coefficient (-). Default 0.61. > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub discharge_coefficient: Option<f64>,
    /// Leakage: the oil's density (kg/m^3). Default 870. > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density_kg_m3: Option<f64>,
    /// Supply loss: the fraction of the supply pressure left. Default 0. 0..1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual: Option<f64>,
    /// Supply loss: the pressure's fall time constant (s); 0 (default): sudden. >= 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau_s: Option<f64>,
}

/// How a dropped-out sensor reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dropout {
    /// NaN.
    Nan,
    /// 0.
    Zero,
    /// The last reading before the onset.
    Hold,
}

/// A sensor fault's effect on the reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorFaultKind {
    /// No reading.
    Dropout(Dropout),
    /// A constant (None: the reading at the onset).
    Stuck(Option<f64>),
    /// A step added (unit).
    Bias(f64),
    /// A ramp added (unit/s from the onset).
    Drift(f64),
    /// The reading times this.
    Gain(f64),
    /// Gaussian noise of this sd added (unit).
    Noise(f64),
    /// Spikes of +-amplitude with a probability per sample.
    Spikes {
        /// Amplitude (unit).
        amplitude: f64,
        /// Probability per sample.
        probability: f64,
    },
    /// Clipped at +-level.
    Saturation(f64),
    /// This many samples more delay.
    Delay(usize),
}

/// A valve, leakage, supply or power fault (the cylinder's and the loop's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ActuatorFaultKind {
    /// The spool stuck at a position (m; None: where it is at the onset).
    SpoolStuck(Option<f64>),
    /// The spool's time constant times this.
    SpoolSlow(f64),
    /// A bypass orifice across the piston: area (m^2), discharge coefficient, density (kg/m^3).
    Leakage {
        /// Area (m^2).
        area_m2: f64,
        /// Discharge coefficient (-).
        cd: f64,
        /// Density (kg/m^3).
        density_kg_m3: f64,
    },
    /// The supply pressure falls to `residual` of itself with time constant `tau_s` (0:
    /// sudden).
    SupplyLoss {
        /// Fraction left.
        residual: f64,
        /// Time constant (s).
        tau_s: f64,
    },
    /// No power: the valve's command 0, the fail-safe's bypass open when it is "free".
    PowerLoss,
}

/// A controller fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ControllerFaultKind {
    /// Each command takes effect this many samples late.
    Overrun(usize),
    /// The controller is not called; the last command holds.
    Skip,
    /// Each sample is lost with this probability (the controller not called, the last
    /// command holding).
    Lost(f64),
}

/// What a fault does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultKind {
    /// On an A/D channel: 0-4 the force loop's (`sensors::CHANNELS` order), 5-25 the
    /// device's (`sensors::DEVICE_CHANNELS` order).
    Sensor(usize, SensorFaultKind),
    /// On the valve, the cylinder, the supply or the power.
    Actuator(ActuatorFaultKind),
    /// On the controller's timing.
    Controller(ControllerFaultKind),
}

/// When a fault starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Onset {
    /// At this time (s).
    At(f64),
    /// At `phase_pct` % of the stride (s) after the first heel strike at or after `after_s`.
    HeelStrike {
        /// The first heel strike at or after this (s).
        after_s: f64,
        /// This far into the stride after it (%).
        phase_pct: f64,
    },
}

/// A resolved fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fault {
    /// What it does.
    pub kind: FaultKind,
    /// When it starts.
    pub onset: Onset,
    /// How long it lasts (s; infinite: permanent).
    pub duration_s: f64,
}

/// When each fault of a run is active: the onsets, resolved as the run goes (a gait event's
/// when it happens).
#[derive(Debug, Clone, PartialEq)]
pub struct FaultClock {
    onsets: Vec<Option<f64>>,
}

impl FaultClock {
    /// The clock of `faults` at the start of a run.
    pub fn new(faults: &[Fault]) -> Self {
        Self {
            onsets: faults
                .iter()
                .map(|f| match f.onset {
                    Onset::At(t) => Some(t),
                    Onset::HeelStrike { .. } => None,
                })
                .collect(),
        }
    }

    /// A heel strike at `t_s` (s) in a stride of `stride_s` (s): the event onsets waiting for
    /// it are set.
    pub fn heel_strike(&mut self, faults: &[Fault], t_s: f64, stride_s: f64) {
        for (o, f) in self.onsets.iter_mut().zip(faults) {
            if let (None, Onset::HeelStrike { after_s, phase_pct }) = (*o, f.onset) {
                if t_s >= after_s - 1e-12 {
                    *o = Some(t_s + phase_pct / 100.0 * stride_s);
                }
            }
        }
    }

    /// The onset of fault `i` (s), once known.
    pub fn onset(&self, i: usize) -> Option<f64> {
        self.onsets[i]
    }

    /// Whether fault `i` of `faults` is active at `t_s` (s): from its onset for its duration.
    pub fn active(&self, faults: &[Fault], i: usize, t_s: f64) -> bool {
        self.onsets[i].is_some_and(|t0| t_s >= t0 - 1e-12 && t_s < t0 + faults[i].duration_s - 1e-12)
    }

    /// The earliest onset so far (s).
    pub fn first_onset(&self) -> Option<f64> {
        self.onsets.iter().flatten().copied().reduce(f64::min)
    }
}

/// Why a sampled controller stopped under `controller.on_stop = "failsafe"` (the device then
/// in its fail-safe state; `summary.json` `controller_stop.cause`): a deliberate stop is a
/// detection, a crash never is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopCause {
    /// On purpose: a plugin's stop status, the modelled firmware's budget stop
    /// (`controller.overrun_policy = "stop"`), a controller's own `ControlStop::stop`.
    Stop,
    /// Its command is not a number (the loop's guard stops it).
    Command,
    /// It failed: killed by a signal, exited, hung, broke the protocol or lost its link, or
    /// raised an exception. Never a detection; a run whose controller crashed does not pass.
    Crash,
}

impl StopCause {
    /// The word `summary.json` uses.
    pub fn as_str(&self) -> &'static str {
        match self {
            StopCause::Stop => "stop",
            StopCause::Command => "command",
            StopCause::Crash => "crash",
        }
    }

    /// Whether a fault campaign may count the stop as the controller's detection.
    pub fn detects(&self) -> bool {
        *self != StopCause::Crash
    }
}
