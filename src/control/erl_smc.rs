//! Exponential-reaching-law sliding-mode control, the paper's baseline (Eq. 50).

use super::{ControlOutput, Controller, Measurement, NominalModel};
use crate::reference::RefSample;

/// ERL-SMC. The paper omits its sliding function; MODEL.md fixes it as
/// ```text
/// e = x_d - x1,  s = e_dot + delta*e,  s_dot = -k*s - zeta*tanh(s)
/// u = tau/(n1*k_s) * [xd_ddot + n3*x2 + n2*xc_ddot + n1*x3/tau + delta*e_dot + k*s + zeta*tanh(s)]
/// ```
/// No internal state.
pub struct ErlSmc {
    model: NominalModel,
    k: f64,
    delta: f64,
    zeta: f64,
}

impl ErlSmc {
    /// Reaching gain `k` (1/s), surface slope `delta` (1/s), switching gain `zeta` (N/s^2).
    pub fn new(model: NominalModel, k: f64, delta: f64, zeta: f64) -> Self {
        Self { model, k, delta, zeta }
    }
}

impl Controller for ErlSmc {
    fn kind(&self) -> &'static str {
        "erl_smc"
    }
    fn state_names(&self) -> Vec<String> {
        Vec::new()
    }
    fn init(&self, _y: &Measurement, _r: &RefSample, _s: &mut [f64]) {}

    fn output(&self, _t_s: f64, r: &RefSample, y: &Measurement, _s: &[f64]) -> ControlOutput {
        let e = r.value - y.force_n;
        let e_dot = r.rate - y.force_rate_n_per_s;
        let s = e_dot + self.delta * e;
        let accel = r.accel + self.delta * e_dot + self.k * s + self.zeta * s.tanh();
        ControlOutput { valve_command: self.model.invert(accel, y), ..Default::default() }
    }

    fn derivatives(&self, _t: f64, _r: &RefSample, _y: &Measurement, _s: &[f64], _u: &ControlOutput, _ds: &mut [f64]) {}
}
