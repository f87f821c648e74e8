//! Firmware-style controllers: run once per sample period on sampled, held readings.

use super::{ControlOutput, Controller, Measurement, MAX_CONTROLLER_STATES};
use crate::reference::RefSample;

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

/// What a sampled controller gets at each sample instant.
#[derive(Debug, Clone, Copy)]
pub struct SampleInput<'a> {
    /// Sample instant t_k (s).
    pub t_s: f64,
    /// Sample period (s).
    pub period_s: f64,
    /// The readings (after noise, A/D, delay and differences).
    pub y: &'a Measurement,
    /// Desired force and derivatives at t_k.
    pub r: RefSample,
    /// Desired force and derivatives at t_{k+1} (one-step preview of a known reference).
    pub r_next: RefSample,
}

/// A controller that runs once per sample period and holds its output (zero-order hold).
pub trait DiscreteController: Send {
    /// Short name, as in `controller.kind`.
    fn kind(&self) -> &'static str;
    /// One sample: read, compute, advance the internal state; returns the output to hold
    /// (already within the valve limit).
    fn update(&mut self, s: &SampleInput) -> ControlOutput;
    /// The first non-finite internal state with its name, if any (divergence reports).
    fn first_non_finite(&self) -> Option<(String, f64)>;
    /// Design figures computed at start (gains, poles) for `summary.json`; None if none.
    fn design(&self) -> Option<serde_json::Value> {
        None
    }
}

/// A continuous-time controller run as firmware: at each sample its output is computed from
/// the readings and held, and its state advances by [`Controller::discrete_update`].
pub struct Sampled {
    ctrl: Box<dyn Controller>,
    state: [f64; MAX_CONTROLLER_STATES],
    names: Vec<String>,
    limit: ValveLimit,
    started: bool,
}

impl Sampled {
    /// Wrap a continuous controller with the valve limit it must respect.
    pub fn new(ctrl: Box<dyn Controller>, limit: ValveLimit) -> Self {
        let names = ctrl.state_names();
        Self { ctrl, state: [0.0; MAX_CONTROLLER_STATES], names, limit, started: false }
    }
}

impl DiscreteController for Sampled {
    fn kind(&self) -> &'static str {
        self.ctrl.kind()
    }

    fn update(&mut self, s: &SampleInput) -> ControlOutput {
        if !self.started {
            self.ctrl.init(s.y, &s.r, &mut self.state);
            self.started = true;
        }
        let n = self.names.len();
        let out = self.limit.apply(self.ctrl.output(s.t_s, &s.r, s.y, &self.state[..n]));
        self.ctrl.discrete_update(s.t_s, s.period_s, &s.r, s.y, &mut self.state[..n], &out);
        out
    }

    fn first_non_finite(&self) -> Option<(String, f64)> {
        let n = self.names.len();
        let i = self.state[..n].iter().position(|v| !v.is_finite())?;
        Some((self.names[i].clone(), self.state[i]))
    }
}
