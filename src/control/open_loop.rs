//! No feedback: a constant valve command (`controller.kind = "open_loop"`).

use super::{ControlOutput, Controller, Measurement};
use crate::reference::RefSample;

/// No feedback: a constant valve command. No internal state.
pub struct OpenLoop {
    /// The valve command u (dimensionless; k_s*u is the commanded spool position in m).
    pub valve_command: f64,
}

impl Controller for OpenLoop {
    fn kind(&self) -> &'static str {
        "open_loop"
    }
    fn state_names(&self) -> Vec<String> {
        Vec::new()
    }
    fn init(&self, _y: &Measurement, _r: &RefSample, _s: &mut [f64]) {}
    fn output(&self, _t: f64, _r: &RefSample, _y: &Measurement, _s: &[f64]) -> ControlOutput {
        ControlOutput { valve_command: self.valve_command, ..Default::default() }
    }
    fn derivatives(&self, _t: f64, _r: &RefSample, _y: &Measurement, _s: &[f64], _u: &ControlOutput, _ds: &mut [f64]) {}
}
