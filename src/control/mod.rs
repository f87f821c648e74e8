//! Force controllers (MODEL.md section 4) behind one trait.
//!
//! A controller sees only [`Measurement`]s (what sensors give on hardware) and its own
//! nominal model of the hydraulics ([`crate::hydraulics::Coefficients`] computed from the
//! parameters it *assumes*, which may differ from the plant's). It never reads plant internals.
//!
//! Every controller is written as a continuous-time block in the style of Drake:
//! [`Controller::output`] is a pure function `u = h(t, r, y, s)` of its state `s`, and
//! [`Controller::derivatives`] writes `ds/dt = f(t, r, y, s, u)`. The co-simulation loop
//! either integrates `s` together with the plant at every solver stage (continuous mode,
//! as the paper's Simulink model did) or updates it once per sample period with forward
//! Euler and holds `u` (sampled mode, as firmware does).

mod arbfnn;
mod discretize;
mod dtznn;
mod erl_smc;
mod fdo;
mod knee_pd;
mod params;
mod sampled;
mod znn;

pub use arbfnn::*;
pub use discretize::*;
pub use dtznn::*;
pub use erl_smc::*;
pub use fdo::*;
pub use knee_pd::*;
pub use params::*;
pub use sampled::*;
pub use znn::*;

use crate::hydraulics::Coefficients;
use crate::reference::RefSample;
use serde::{Deserialize, Serialize};

/// Largest controller state any controller here needs (ARBFNN-FDO-ZNN: z plus 7 weights).
pub const MAX_CONTROLLER_STATES: usize = 8;

/// What the controller reads from the sensors at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Measurement {
    /// Load force x1 = F_L from the load cell (N).
    pub force_n: f64,
    /// x2 = dF_L/dt (N/s): ideal derivative (continuous) or filtered difference (sampled).
    pub force_rate_n_per_s: f64,
    /// Spool position x3 = x_v from the valve LVDT (m).
    pub spool_m: f64,
    /// Piston position x_c (m).
    pub piston_m: f64,
    /// Piston velocity xc_dot (m/s).
    pub piston_velocity_m_s: f64,
    /// Piston acceleration xc_ddot (m/s^2).
    pub piston_accel_m_s2: f64,
    /// Knee angle (rad) from the joint encoder (0 on the bench).
    pub knee_rad: f64,
    /// Knee angular rate (rad/s): exact (continuous) or a filtered difference (sampled).
    pub knee_rate_rad_s: f64,
}

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
    /// Number of internal states (<= [`MAX_CONTROLLER_STATES`]); called at every stage, so a
    /// controller with states should give it without building the names.
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
    /// which is what simple firmware does.
    fn discrete_update(&self, t_s: f64, ts_s: f64, r: &RefSample, y: &Measurement, s: &mut [f64], u: &ControlOutput) {
        let mut ds = [0.0; MAX_CONTROLLER_STATES];
        let n = s.len();
        self.derivatives(t_s, r, y, s, u, &mut ds[..n]);
        for (x, d) in s.iter_mut().zip(&ds[..n]) {
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

/// Which controller a scenario uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControllerKind {
    /// Plain ZNN, linear activation (paper Eq. 15), no disturbance compensation.
    Znn,
    /// ZNN with adaptive RBF network and fixed-time disturbance observer (paper Eq. 30).
    ArbfnnFdoZnn,
    /// Exponential-reaching-law sliding-mode control (paper Eq. 50), the baseline.
    ErlSmc,
    /// No feedback: the valve command is `controller.open_loop_command` from t = 0 (a valve
    /// step; plant identification and stiffness checks).
    OpenLoop,
    /// Discrete-time ZNN for firmware (sampled mode only): exact ZOH model, Kalman ESO with
    /// delay compensation, one-step reference preview (see [`DtZnn`]).
    Dtznn,
}

impl ControllerKind {
    /// The name used in scenario files.
    pub fn as_str(&self) -> &'static str {
        match self {
            ControllerKind::Znn => "znn",
            ControllerKind::ArbfnnFdoZnn => "arbfnn_fdo_znn",
            ControllerKind::ErlSmc => "erl_smc",
            ControllerKind::OpenLoop => "open_loop",
            ControllerKind::Dtznn => "dtznn",
        }
    }
}

/// Build the continuous-time controller a scenario asks for, with its nominal model.
pub fn build(p: &ControllerParams, model: NominalModel) -> Box<dyn Controller> {
    match p.kind {
        ControllerKind::Znn => Box::new(Znn::new(model, p.gamma, None)),
        ControllerKind::ArbfnnFdoZnn => {
            Box::new(Znn::new(model, p.gamma, Some((RbfNetwork::new(p.rbf.clone()), Fdo::new(p.observer.clone())))))
        }
        ControllerKind::ErlSmc => Box::new(ErlSmc::new(model, p.k, p.delta, p.zeta)),
        ControllerKind::OpenLoop => Box::new(OpenLoop { valve_command: p.open_loop_command }),
        // dtznn is discrete only (validation refuses it in continuous mode); as a continuous
        // block it is the plain ZNN law it is derived from.
        ControllerKind::Dtznn => Box::new(Znn::new(model, p.gamma, None)),
    }
}

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
