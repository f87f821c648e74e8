//! One FMU instance as safe Rust: the FMI 2.0 co-simulation state machine over a
//! [`Simulation`] whose controller is outside (the master). The C entry points
//! (`fmu/src/lib.rs`) are a thin shell over this.
//!
//! Timing: the FMU's internal step is `sim.dt_s`. The readings are sampled at the scenario's
//! sample instants (`controller.sample_period_s`, set to `sim.dt_s` when packaging a
//! continuous-controller scenario), and the valve command is latched there too (the
//! firmware's DAC): a master whose communication step equals the sample period sees every
//! sample and commands every sample, exactly like a controller inside `exoleg run`.

use super::variables::{nominal_values, variables, Causality, Role, VarType, Variable};
use super::{guid_of, RESOURCE_SCENARIO};
use crate::control::ControlOutput;
use crate::record::{Layout, NullSink};
use crate::scenario::{Resources, Scenario};
use crate::sim::Simulation;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where the instance is in FMI's state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// After `fmi2Instantiate` (or `fmi2Reset`).
    Instantiated,
    /// Between `fmi2EnterInitializationMode` and `fmi2ExitInitializationMode`.
    Initializing,
    /// Stepping.
    Running,
    /// After `fmi2Terminate`.
    Terminated,
    /// A step failed (diverged, stiff, bad command): only reset or free.
    Failed,
}

/// A refused call: what to log, and whether the instance is unusable (`fmi2Fatal`).
#[derive(Debug, Clone, PartialEq)]
pub struct FmiError {
    /// The message for the logger.
    pub message: String,
}

impl FmiError {
    fn new(message: impl Into<String>) -> Self {
        Self { message: message.into() }
    }
}

impl From<crate::Error> for FmiError {
    fn from(e: crate::Error) -> Self {
        Self::new(e.to_string())
    }
}

/// Result of an FMU call.
pub type FmiResult<T> = std::result::Result<T, FmiError>;

/// The running simulation with the values the master reads.
struct Run {
    sim: Simulation,
    layout: Layout,
    /// The readings of the latest sample (the order of [`crate::control::READINGS`]).
    readings: [f64; crate::control::N_READINGS],
    /// The step whose sample is taken.
    sampled_at: Option<usize>,
    /// The time-series row at a step, once asked for.
    truth: Option<(usize, Vec<f64>)>,
    nominal: [f64; 5],
}

/// One FMU instance.
pub struct Slave {
    base: Scenario,
    layout: Layout,
    vars: Vec<Variable>,
    by_ref: HashMap<(VarType, u32), usize>,
    /// Current values of the parameters and the input, by variable index.
    values: Vec<f64>,
    nominal: [f64; 5],
    stop_time_s: Option<f64>,
    phase: Phase,
    run: Option<Run>,
}

/// A `file://` URI (FMI's `fmuResourceLocation`) as a path.
pub fn uri_to_path(uri: &str) -> FmiResult<PathBuf> {
    let rest = uri
        .strip_prefix("file://localhost/")
        .map(|r| format!("/{r}"))
        .or_else(|| uri.strip_prefix("file://").map(str::to_string))
        .or_else(|| uri.strip_prefix("file:").map(str::to_string))
        .ok_or_else(|| FmiError::new(format!("fmuResourceLocation `{uri}` is not a file:// URI")))?;
    let bytes = rest.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = rest.get(i + 1..i + 3).and_then(|h| u8::from_str_radix(h, 16).ok());
            let b = hex.ok_or_else(|| FmiError::new(format!("fmuResourceLocation `{uri}`: bad %-escape")))?;
            out.push(b);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    let s = String::from_utf8(out).map_err(|_| FmiError::new(format!("fmuResourceLocation `{uri}` is not UTF-8")))?;
    Ok(PathBuf::from(s))
}

impl Slave {
    /// `fmi2Instantiate`: read the scenario in `resources`, build the run once to know its
    /// variables, and check them and the scenario against `guid`. Returns the instance and the
    /// scenario's warnings.
    pub fn instantiate(resources: &Path, guid: &str) -> FmiResult<(Slave, Vec<String>)> {
        let (slave, warnings, expected) = Self::open(resources)?;
        if guid != expected {
            return Err(FmiError::new(format!(
                "GUID {guid} does not match the FMU's resources and library ({expected}): modelDescription.xml, \
                 resources/{RESOURCE_SCENARIO} and the library come from different FMUs or exoleg builds"
            )));
        }
        Ok((slave, warnings))
    }

    /// Read the scenario in `resources` and build the run once: the instance, the scenario's
    /// warnings and the GUID of this scenario with this library's variables.
    pub fn open(resources: &Path) -> FmiResult<(Slave, Vec<String>, String)> {
        let file = resources.join(RESOURCE_SCENARIO);
        if !resources.is_dir() {
            return Err(FmiError::new(format!(
                "the resources folder {} is missing: unzip the whole FMU (its resources/ hold the scenario)",
                resources.display()
            )));
        }
        let text = crate::scenario::read_capped(&file, crate::scenario::MAX_SCENARIO_FILE_BYTES)?;
        let base = Scenario::load(Some(&file), &[])?;
        let resolved = base.resolve(&Resources::new())?;
        let sim = Simulation::external(resolved.model.clone())?;
        let layout = sim.layout();
        let table = match toml::Value::try_from(&resolved.file) {
            Ok(toml::Value::Table(t)) => t,
            _ => return Err(FmiError::new("the scenario cannot be serialised")),
        };
        let vars = variables(&table, &layout, resolved.model.leg().is_some());
        let guid = guid_of(&text, &vars);
        let by_ref = vars.iter().enumerate().map(|(i, v)| ((v.ty, v.vr), i)).collect();
        let values = vars.iter().map(|v| v.start.unwrap_or(0.0)).collect();
        let nominal = nominal_values(&resolved.model);
        let slave = Slave {
            base,
            layout,
            vars,
            by_ref,
            values,
            nominal,
            stop_time_s: None,
            phase: Phase::Instantiated,
            run: None,
        };
        Ok((slave, resolved.warnings, guid))
    }

    /// The variables (the modelDescription's, in order).
    pub fn variables(&self) -> &[Variable] {
        &self.vars
    }

    /// Where the instance is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Simulated time (s): the start of the next step.
    pub fn time_s(&self) -> f64 {
        self.run.as_ref().map_or(0.0, |r| r.sim.t_s())
    }

    /// `fmi2SetupExperiment`: the start time must be 0; a stop time sets the run's length
    /// (`sim.duration_s`).
    pub fn setup_experiment(&mut self, start_s: f64, stop_s: Option<f64>) -> FmiResult<()> {
        if self.phase != Phase::Instantiated {
            return Err(FmiError::new("fmi2SetupExperiment is allowed only after fmi2Instantiate"));
        }
        if start_s != 0.0 {
            return Err(FmiError::new(format!(
                "the start time must be 0 s (the scenario starts there), got {start_s}"
            )));
        }
        if let Some(s) = stop_s {
            if !(s.is_finite() && s > 0.0) {
                return Err(FmiError::new(format!("the stop time must be a positive number of seconds, got {s}")));
            }
        }
        self.stop_time_s = stop_s;
        self.run = None;
        Ok(())
    }

    /// `fmi2EnterInitializationMode`.
    pub fn enter_initialization_mode(&mut self) -> FmiResult<()> {
        if self.phase != Phase::Instantiated {
            return Err(FmiError::new("fmi2EnterInitializationMode is allowed only after fmi2Instantiate"));
        }
        self.phase = Phase::Initializing;
        Ok(())
    }

    /// `fmi2ExitInitializationMode`: build the run with the parameters set and take the
    /// first sample. Returns the scenario's warnings.
    pub fn exit_initialization_mode(&mut self) -> FmiResult<Vec<String>> {
        if self.phase != Phase::Initializing {
            return Err(FmiError::new("fmi2ExitInitializationMode is allowed only in initialization mode"));
        }
        let warnings = self.ensure_run()?;
        self.phase = Phase::Running;
        Ok(warnings)
    }

    /// The scenario with the parameters the master changed and the stop time.
    fn scenario(&self) -> FmiResult<Scenario> {
        let mut overrides = Vec::new();
        for (v, x) in self.vars.iter().zip(&self.values) {
            if let (Role::Param(key), Some(start)) = (&v.role, v.start) {
                if x.to_bits() != start.to_bits() {
                    let value = match v.ty {
                        VarType::Integer => serde_json::Value::from(*x as i64),
                        VarType::Real => serde_json::Number::from_f64(*x)
                            .map(serde_json::Value::Number)
                            .ok_or_else(|| FmiError::new(format!("{} = {x} is not a number", v.name)))?,
                    };
                    overrides.push((key.to_string(), value));
                }
            }
        }
        if let Some(stop) = self.stop_time_s {
            if Some(stop) != self.base.file.sim.duration_s.into() {
                overrides.push(("sim.duration_s".to_string(), serde_json::Value::from(stop)));
            }
            // `metrics.settle_s` only shapes a run's summary, which an FMU has none of: a stop
            // time shorter than it (a gait scenario's run-in) is the master's to choose.
            if stop <= self.base.file.metrics.settle_s {
                overrides.push(("metrics.settle_s".to_string(), serde_json::Value::from(0.0)));
            }
        }
        Ok(self.base.with_values(overrides)?)
    }

    /// Build the run (if the parameters changed since) and take the first sample.
    fn ensure_run(&mut self) -> FmiResult<Vec<String>> {
        if self.run.is_some() {
            return Ok(Vec::new());
        }
        let resolved = self.scenario()?.resolve(&Resources::new())?;
        let mut sim = Simulation::external(resolved.model.clone())?;
        let layout = sim.layout();
        if layout != self.layout {
            return Err(FmiError::new("the parameters change the FMU's outputs (the time-series columns)"));
        }
        let readings = sim.sample()?.reading_values();
        self.nominal = nominal_values(&resolved.model);
        self.run = Some(Run { sim, layout, readings, sampled_at: Some(0), truth: None, nominal: self.nominal });
        Ok(resolved.warnings)
    }

    fn var(&self, ty: VarType, vr: u32) -> FmiResult<usize> {
        self.by_ref.get(&(ty, vr)).copied().ok_or_else(|| {
            let t = if ty == VarType::Real { "Real" } else { "Integer" };
            FmiError::new(format!("unknown {t} value reference {vr}"))
        })
    }

    /// `fmi2GetReal` / `fmi2GetInteger` (integers as f64): the values of `vrs` into `out`.
    pub fn get(&mut self, ty: VarType, vrs: &[u32], out: &mut [f64]) -> FmiResult<()> {
        for (vr, o) in vrs.iter().zip(out.iter_mut()) {
            let i = self.var(ty, *vr)?;
            *o = self.value(i)?;
        }
        Ok(())
    }

    fn value(&mut self, i: usize) -> FmiResult<f64> {
        let role = self.vars[i].role.clone();
        let computed = matches!(role, Role::Reading(_) | Role::Truth(_) | Role::Nominal(_));
        if !computed {
            return Ok(self.values[i]);
        }
        match self.phase {
            Phase::Instantiated => {
                return match role {
                    Role::Nominal(j) => Ok(self.nominal[j]),
                    _ => Err(FmiError::new(format!(
                        "{} is computed from fmi2EnterInitializationMode on",
                        self.vars[i].name
                    ))),
                }
            }
            Phase::Initializing => {
                self.ensure_run()?;
            }
            Phase::Running | Phase::Terminated | Phase::Failed => {}
        }
        let Some(run) = self.run.as_mut() else {
            return Err(FmiError::new(format!("{}: no run (the last step failed)", self.vars[i].name)));
        };
        Ok(match role {
            Role::Reading(j) => run.readings[j],
            Role::Nominal(j) => run.nominal[j],
            Role::Truth(j) => {
                let k = run.sim.steps_taken();
                if run.truth.as_ref().is_none_or(|(at, _)| *at != k) {
                    let mut row = Vec::with_capacity(64);
                    run.sim.row_now().values_into(&run.layout, &mut row);
                    run.truth = Some((k, row));
                }
                run.truth.as_ref().map_or(f64::NAN, |(_, row)| row[j])
            }
            _ => unreachable!("computed roles only"),
        })
    }

    /// `fmi2SetReal` / `fmi2SetInteger` (integers as f64).
    pub fn set(&mut self, ty: VarType, vrs: &[u32], values: &[f64]) -> FmiResult<()> {
        for (vr, x) in vrs.iter().zip(values) {
            let i = self.var(ty, *vr)?;
            let v = &self.vars[i];
            match v.causality {
                Causality::Input => {
                    if matches!(self.phase, Phase::Terminated | Phase::Failed) {
                        return Err(FmiError::new(format!("{}: the instance is terminated", v.name)));
                    }
                }
                Causality::Parameter => {
                    if !matches!(self.phase, Phase::Instantiated | Phase::Initializing) {
                        return Err(FmiError::new(format!(
                            "{} is a fixed parameter: set it before fmi2ExitInitializationMode",
                            v.name
                        )));
                    }
                    if !x.is_finite() {
                        return Err(FmiError::new(format!("{} = {x}: a parameter must be a finite number", v.name)));
                    }
                    self.run = None;
                }
                Causality::Output | Causality::CalculatedParameter => {
                    return Err(FmiError::new(format!(
                        "{} is {}: it cannot be set",
                        v.name,
                        if v.causality == Causality::Output { "an output" } else { "a calculated parameter" }
                    )))
                }
            }
            self.values[i] = *x;
        }
        Ok(())
    }

    /// The valve command the master set.
    fn command(&self) -> f64 {
        self.vars.iter().position(|v| v.role == Role::ValveCommand).map_or(0.0, |i| self.values[i])
    }

    /// `fmi2DoStep`: advance from `t_s` (the FMU's time) by `h_s`, a whole number of
    /// `sim.dt_s` steps, holding the valve command at each sample instant on the way.
    pub fn do_step(&mut self, t_s: f64, h_s: f64) -> FmiResult<()> {
        if self.phase != Phase::Running {
            return Err(FmiError::new(format!(
                "fmi2DoStep is allowed only after fmi2ExitInitializationMode (the instance is {:?})",
                self.phase
            )));
        }
        let u = self.command();
        let Some(run) = self.run.as_mut() else { return Err(FmiError::new("no run")) };
        let sc = run.sim.model().clone();
        let dt = sc.dt_s;
        let n = step_count(t_s, h_s, dt, run.sim.t_s())?;
        if run.sim.steps_taken() + n > sc.steps {
            return Err(FmiError::new(format!(
                "the step to {} s goes past the run's end at {} s (sim.duration_s, or the stop time given to \
                 fmi2SetupExperiment)",
                t_s + h_s,
                sc.steps as f64 * dt
            )));
        }
        let result = advance(run, n, u);
        if result.is_err() {
            self.phase = Phase::Failed;
        }
        result
    }

    /// `fmi2Terminate`.
    pub fn terminate(&mut self) -> FmiResult<()> {
        if !matches!(self.phase, Phase::Running | Phase::Initializing | Phase::Failed) {
            return Err(FmiError::new(format!("fmi2Terminate in phase {:?}", self.phase)));
        }
        self.phase = Phase::Terminated;
        Ok(())
    }

    /// `fmi2Reset`: back to just instantiated, with the start values.
    pub fn reset(&mut self) {
        self.values = self.vars.iter().map(|v| v.start.unwrap_or(0.0)).collect();
        self.stop_time_s = None;
        self.run = None;
        self.phase = Phase::Instantiated;
    }
}

/// Internal steps in a communication step from `t_s` of `h_s` (FMU time `now_s`, step `dt`).
fn step_count(t_s: f64, h_s: f64, dt: f64, now_s: f64) -> FmiResult<usize> {
    let tol = 1e-6 * dt;
    if !(t_s.is_finite() && (t_s - now_s).abs() <= tol.max(1e-9 * now_s.abs())) {
        return Err(FmiError::new(format!(
            "currentCommunicationPoint {t_s} s is not the FMU's time {now_s} s (steps must follow each other)"
        )));
    }
    if !(h_s.is_finite() && h_s > 0.0) {
        return Err(FmiError::new(format!("the communication step must be positive, got {h_s} s")));
    }
    let n = (h_s / dt).round();
    if n < 1.0 || (n * dt - h_s).abs() > tol || n > 1e12 {
        return Err(FmiError::new(format!(
            "the communication step {h_s} s is not a whole multiple of the FMU's internal step sim.dt_s = {dt} s"
        )));
    }
    Ok(n as usize)
}

/// `n` internal steps holding `u` at the sample instants; the readings of the sample at the
/// end, when it is one.
fn advance(run: &mut Run, n: usize, u: f64) -> FmiResult<()> {
    let sim = &mut run.sim;
    for _ in 0..n {
        if sim.is_sample_step() {
            let k = sim.steps_taken();
            if run.sampled_at != Some(k) {
                run.readings = sim.sample()?.reading_values();
                run.sampled_at = Some(k);
            }
            sim.hold(ControlOutput { valve_command: u, ..Default::default() })?;
        }
        sim.advance(&mut NullSink)?;
    }
    if sim.is_sample_step() {
        run.readings = sim.sample()?.reading_values();
        run.sampled_at = Some(sim.steps_taken());
    }
    Ok(())
}
