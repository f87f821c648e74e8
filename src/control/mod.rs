//! Force controllers (MODEL.md section 4) and their registry.
//!
//! A controller sees only [`Measurement`]s (what sensors give on hardware) and its own
//! nominal model of the hydraulics ([`crate::hydraulics::Coefficients`] computed from the
//! parameters it *assumes*, which may differ from the plant's). It never reads plant internals.
//!
//! Two contracts (`interface`): a continuous-time block [`Controller`] in the style of
//! Drake (`u = h(t, r, y, s)` and `ds/dt = f(t, r, y, s, u)`, integrated with the plant at
//! every solver stage, as the paper's Simulink model did, or advanced once per sample and
//! held by [`Sampled`]), and the sampled [`DiscreteController`] every firmware-style
//! controller implements: `dtznn`, a C plugin ([`plugin`]), any controller from outside the
//! crate.
//!
//! This file is the registry: the kinds of `controller.kind`, the raw `[controller]` section,
//! and the resolved [`ControllerSetup`] (one tagged value per kind, built into a controller
//! when a run starts). A new kind is its own file plus an entry here (and its docs).

mod arbfnn;
mod discretize;
mod dtznn;
mod erl_smc;
mod fdo;
pub mod ideal;
mod interface;
pub mod isolate;
mod knee_pd;
mod open_loop;
mod params;
pub mod plugin;
mod sampled;
pub mod timing;
pub mod wait;
pub mod wire;
mod znn;

pub use arbfnn::*;
pub use discretize::*;
pub use dtznn::*;
pub use erl_smc::*;
pub use fdo::*;
pub use interface::*;
pub use knee_pd::*;
pub use open_loop::*;
pub use params::*;
pub use plugin::{PluginLibrary, PluginParams};
pub use sampled::*;
pub use znn::*;

use crate::sensors::{ChannelId, SensorParams};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

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
    /// A controller in a C shared library (sampled mode only; see [`plugin`]).
    Plugin,
    /// An ideal device (walking runs on the carriage): a massless knee actuator that applies
    /// the data's biological knee moment of one sign directly, up to a bound
    /// (`[controller.ideal]`; the cylinder is disconnected: `actuator.mode = "free"`).
    IdealMoment,
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
            ControllerKind::Plugin => "plugin",
            ControllerKind::IdealMoment => "ideal_moment",
        }
    }

    /// True for the kinds that only run sampled (`controller.sample_period_s > 0`).
    pub fn sampled_only(&self) -> bool {
        matches!(self, ControllerKind::Dtznn | ControllerKind::Plugin)
    }

    /// Whether the controller tracks a desired force (every built-in one but `open_loop`; a
    /// plugin decides for itself).
    pub fn needs_reference(&self) -> bool {
        !matches!(self, ControllerKind::OpenLoop | ControllerKind::Plugin | ControllerKind::IdealMoment)
    }
}

/// `[controller]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerParams {
    /// `znn`, `arbfnn_fdo_znn` (default), `erl_smc`, `open_loop`, or the sampled-only `dtznn`
    /// and `plugin` (a C shared library, `[controller.plugin]`).
    pub kind: ControllerKind,
    /// ZNN design parameter gamma (1/s). Default 100. > 0.
    pub gamma: f64,
    /// ERL-SMC reaching gain k (1/s). Default 100. > 0.
    pub k: f64,
    /// ERL-SMC surface slope delta (1/s). Default 15. > 0.
    pub delta: f64,
    /// ERL-SMC switching gain zeta (N/s^2). Default 10. >= 0.
    pub zeta: f64,
    /// `open_loop`: the constant valve command u (dimensionless; k_s*u is the commanded spool
    /// position in m). Default 0.
    pub open_loop_command: f64,
    /// Controller sample period (s); 0 = continuous (evaluated at every solver stage).
    /// Otherwise a whole multiple of `sim.dt_s`. Default 0.
    pub sample_period_s: f64,
    /// `dtznn`: the delay (samples) the controller assumes in its readings. Default: the
    /// sensors' `sensors.delay_samples`.
    pub delay_samples: Option<usize>,
    /// `dtznn`: internal model of a known periodic reference at this frequency (Hz) in the
    /// disturbance model (two more states); 0 = off. Default 0.
    pub resonator_hz: f64,
    /// RBF network.
    pub rbf: RbfParams,
    /// Disturbance observer: the paper's FDO (`gain`, `exponent`) and dtznn's estimator
    /// (`kind`, `process_noise`). `controller.observer = "fdo"` sets the kind alone.
    #[serde(deserialize_with = "fdo::observer_serde::deserialize")]
    pub observer: ObserverParams,
    /// The model the controller assumes.
    pub nominal: NominalParams,
    /// The leg the controller's gait cascade assumes (its inverse dynamics and the outer
    /// loop's moment arm).
    pub nominal_leg: NominalLeg,
    /// `plugin`: the shared library and its parameters.
    #[serde(skip_serializing_if = "PluginParams::is_unset")]
    pub plugin: PluginParams,
    /// What a sampled controller's stop (a plugin's stop status, a Python controller's
    /// exception) does: `end` (default: the run ends, exit 3) or `failsafe` (the device goes
    /// to `actuator.failsafe` and the run goes on: the controller's reaction to a fault,
    /// scored; the `faults` campaign's).
    pub on_stop: OnStop,
    /// The firmware's modelled computation on the target (s): a sampled controller's command
    /// takes effect this long after its sample instant instead of at it (rounded up to whole
    /// `sim.dt_s` steps). Modelled, never measured: the same run gives the same physics.
    /// Default 0. >= 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub compute_delay_s: f64,
    /// A modelled extra time per sample, uniform in [0, this] from the run's seed (s).
    /// Default 0. >= 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub compute_jitter_s: f64,
    /// The time (s) a sample's modelled computation may take. Default: the sample period.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compute_budget_s: Option<f64>,
    /// What a sample over its budget does: `apply_late` (default: its command takes effect
    /// when it is done), `hold` (its command is dropped, the last one holds) or `stop` (the
    /// controller stops, as `on_stop` says).
    #[serde(skip_serializing_if = "is_default_policy")]
    pub overrun_policy: OverrunPolicy,
    /// `[controller.ideal]`: the ideal device of `kind = "ideal_moment"`.
    #[serde(skip_serializing_if = "ideal::IdealParams::is_default")]
    pub ideal: ideal::IdealParams,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

fn is_default_policy(p: &OverrunPolicy) -> bool {
    *p == OverrunPolicy::ApplyLate
}

/// `controller.overrun_policy`: what a sample whose modelled computation exceeds
/// `controller.compute_budget_s` does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OverrunPolicy {
    /// Its command takes effect when it is done, late.
    #[default]
    ApplyLate,
    /// Its command is dropped; the last one holds.
    Hold,
    /// The controller stops (`controller.on_stop`: the run ends, or the failsafe).
    Stop,
}

/// `controller.on_stop`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OnStop {
    /// The run ends (exit 3).
    #[default]
    End,
    /// The device goes to its fail-safe state; the run goes on.
    Failsafe,
}

impl Default for ControllerParams {
    fn default() -> Self {
        Self {
            kind: ControllerKind::ArbfnnFdoZnn,
            gamma: 100.0,
            k: 100.0,
            delta: 15.0,
            zeta: 10.0,
            open_loop_command: 0.0,
            sample_period_s: 0.0,
            delay_samples: None,
            resonator_hz: 0.0,
            rbf: RbfParams::default(),
            observer: ObserverParams::default(),
            nominal: NominalParams::default(),
            nominal_leg: NominalLeg::default(),
            plugin: PluginParams::default(),
            on_stop: OnStop::End,
            compute_delay_s: 0.0,
            compute_jitter_s: 0.0,
            compute_budget_s: None,
            overrun_policy: OverrunPolicy::ApplyLate,
            ideal: Default::default(),
        }
    }
}

/// The controller of a run, resolved: one tagged value per kind with what building it needs.
#[derive(Debug, Clone)]
pub enum ControllerSetup {
    /// Plain ZNN with design parameter gamma (1/s).
    Znn {
        /// gamma (1/s).
        gamma: f64,
    },
    /// ARBFNN-FDO-ZNN.
    ArbfnnFdoZnn {
        /// gamma (1/s).
        gamma: f64,
        /// The RBF network.
        rbf: RbfParams,
        /// The observer.
        observer: ObserverParams,
    },
    /// ERL-SMC with reaching gain k (1/s), surface slope delta (1/s), switching gain zeta
    /// (N/s^2).
    ErlSmc {
        /// k (1/s).
        k: f64,
        /// delta (1/s).
        delta: f64,
        /// zeta (N/s^2).
        zeta: f64,
    },
    /// A constant valve command.
    OpenLoop {
        /// u (dimensionless).
        valve_command: f64,
    },
    /// dtznn, designed (gains computed once at resolve; every run clones it).
    Dtznn(Box<DtZnn>),
    /// A C plugin: the loaded library and the parameters of its instances.
    Plugin(Arc<plugin::PluginSetup>),
}

/// What resolving a controller needs besides its section.
pub struct SetupContext<'a> {
    /// The controller's nominal model.
    pub nominal: NominalModel,
    /// The sensors (dtznn's Kalman design reads their noise).
    pub sensors: &'a SensorParams,
    /// The valve command limit.
    pub limit: ValveLimit,
    /// The loaded plugin library (`controller.kind = "plugin"`).
    pub plugin: Option<Arc<PluginLibrary>>,
    /// The run's seed (passed to plugins).
    pub seed: u64,
}

impl ControllerSetup {
    /// Resolve `[controller]`: the setup of its kind. Errors name the key and the problem.
    pub fn resolve(p: &ControllerParams, cx: SetupContext) -> Result<Self, (String, String)> {
        Ok(match p.kind {
            ControllerKind::Znn => ControllerSetup::Znn { gamma: p.gamma },
            ControllerKind::ArbfnnFdoZnn => {
                ControllerSetup::ArbfnnFdoZnn { gamma: p.gamma, rbf: p.rbf.clone(), observer: p.observer.clone() }
            }
            ControllerKind::ErlSmc => ControllerSetup::ErlSmc { k: p.k, delta: p.delta, zeta: p.zeta },
            ControllerKind::OpenLoop => ControllerSetup::OpenLoop { valve_command: p.open_loop_command },
            // The cylinder is disconnected: its valve rests at centre.
            ControllerKind::IdealMoment => ControllerSetup::OpenLoop { valve_command: 0.0 },
            ControllerKind::Dtznn => {
                let sensors = SensorModel {
                    force_sd_n: cx.sensors.reading_sd(ChannelId::Force).unwrap_or(0.0),
                    spool_sd_m: cx.sensors.reading_sd(ChannelId::Spool),
                };
                let settings = DtZnnSettings {
                    gamma: p.gamma,
                    period_s: p.sample_period_s,
                    delay_samples: p.delay_samples.unwrap_or(cx.sensors.delay_samples),
                    process_noise: p.observer.process_noise,
                    resonator_hz: p.resonator_hz,
                    estimator: p.observer.kind,
                    sensors,
                    limit: cx.limit,
                };
                let d = DtZnn::new(cx.nominal, settings)
                    .map_err(|m| ("controller".to_string(), format!("dtznn design: {m}")))?;
                ControllerSetup::Dtznn(Box::new(d))
            }
            ControllerKind::Plugin => {
                let lib =
                    cx.plugin.ok_or_else(|| ("controller.plugin.library".to_string(), "not loaded".to_string()))?;
                let info = plugin::HostInfo {
                    period_s: p.sample_period_s,
                    limit: cx.limit,
                    nominal: cx.nominal,
                    seed: cx.seed,
                };
                ControllerSetup::Plugin(Arc::new(plugin::PluginSetup::new(lib, &p.plugin, info)?))
            }
        })
    }

    /// Whether the controller tracks a desired force (see [`ControllerKind::needs_reference`]).
    pub fn needs_reference(&self) -> bool {
        !matches!(self, ControllerSetup::OpenLoop { .. } | ControllerSetup::Plugin(_))
    }

    /// The continuous-time controller of this setup with its nominal model (`dtznn` and
    /// plugins are sampled only: validation refuses them in continuous mode, and here they
    /// are the plain ZNN law dtznn derives from).
    pub fn continuous(&self, nominal: NominalModel) -> Box<dyn Controller> {
        match self {
            ControllerSetup::Znn { gamma } => Box::new(Znn::new(nominal, *gamma, None)),
            ControllerSetup::ArbfnnFdoZnn { gamma, rbf, observer } => {
                Box::new(Znn::new(nominal, *gamma, Some((RbfNetwork::new(rbf.clone()), Fdo::new(observer.clone())))))
            }
            ControllerSetup::ErlSmc { k, delta, zeta } => Box::new(ErlSmc::new(nominal, *k, *delta, *zeta)),
            ControllerSetup::OpenLoop { valve_command } => Box::new(OpenLoop { valve_command: *valve_command }),
            ControllerSetup::Dtznn(d) => Box::new(Znn::new(nominal, d.gamma(), None)),
            ControllerSetup::Plugin(_) => Box::new(OpenLoop { valve_command: 0.0 }),
        }
    }

    /// The sampled controller of this setup: the firmware controllers themselves, a plugin
    /// instance, or a continuous one run as firmware ([`Sampled`]) within `limit`.
    pub fn discrete(&self, nominal: NominalModel, limit: ValveLimit) -> Result<Box<dyn DiscreteController>, String> {
        Ok(match self {
            ControllerSetup::Dtznn(d) => Box::new((**d).clone()),
            ControllerSetup::Plugin(p) => match p.isolation() {
                Some(limits) => Box::new(isolate::IsolatedPlugin::spawn(p.clone(), limits)?),
                None => Box::new(p.instance()?),
            },
            _ => Box::new(Sampled::new(self.continuous(nominal), limit)),
        })
    }
}
