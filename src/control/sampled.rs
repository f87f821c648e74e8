//! A continuous-time controller run as firmware: once per sample period on the readings.

use super::{ControlOutput, ControlStop, Controller, DiscreteController, SampleInput, ValveLimit};

/// A continuous-time controller run as firmware: at each sample its output is computed from
/// the readings and held, and its state advances by [`Controller::discrete_update`].
pub struct Sampled {
    ctrl: Box<dyn Controller>,
    state: Vec<f64>,
    scratch: Vec<f64>,
    names: Vec<String>,
    limit: ValveLimit,
    started: bool,
}

impl Sampled {
    /// Wrap a continuous controller with the valve limit it must respect; its state is sized
    /// here.
    pub fn new(ctrl: Box<dyn Controller>, limit: ValveLimit) -> Self {
        let names = ctrl.state_names();
        let n = names.len();
        Self { ctrl, state: vec![0.0; n], scratch: vec![0.0; n], names, limit, started: false }
    }
}

impl DiscreteController for Sampled {
    fn kind(&self) -> &str {
        self.ctrl.kind()
    }

    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        if !self.started {
            self.ctrl.init(&s.y, &s.r, &mut self.state);
            self.started = true;
        }
        let out = self.limit.apply(self.ctrl.output(s.t_s, &s.r, &s.y, &self.state));
        self.ctrl.discrete_update(s.t_s, s.period_s, &s.r, &s.y, &mut self.state, &out, &mut self.scratch);
        Ok(out)
    }

    fn first_non_finite(&self) -> Option<(String, f64)> {
        let i = self.state.iter().position(|v| !v.is_finite())?;
        Some((self.names[i].clone(), self.state[i]))
    }
}
