//! A Python callable as the run's controller: called once per sample period with one reused
//! [`Obs`] (the readings by name), it returns the valve command, or a dict with
//! `valve_command` and logged channels (numbers, the same keys at every sample).

use crate::{py_err, ColumnSink, ControllerError};
use exoleg::control::{ControlOutput, ControlStop, DiscreteController, SampleInput, MAX_LOGGED, N_READINGS, READINGS};
use exoleg::scenario::ResolvedScenario;
use exoleg::sensors::{DEVICE_CHANNELS, DEVICE_READINGS};
use exoleg::sim::{ControllerSource, Simulation};
use exoleg::study::sweep::ControllerFactory;
use exoleg::Error;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// The readings of one sample, by name (SI units; see the README's "Your controller"). One
/// object is reused for every sample of a run: keep the numbers, not the object.
#[pyclass(module = "exoleg._native")]
#[derive(Clone)]
pub struct Obs {
    /// Sample instant (s).
    #[pyo3(get)]
    pub t_s: f64,
    /// Sample period (s).
    #[pyo3(get)]
    pub period_s: f64,
    /// Load cell (N).
    #[pyo3(get)]
    pub force_n: f64,
    /// Its firmware difference (N/s).
    #[pyo3(get)]
    pub force_rate_n_per_s: f64,
    /// Spool LVDT (m; NaN without the sensor).
    #[pyo3(get)]
    pub spool_m: f64,
    /// Piston position (m).
    #[pyo3(get)]
    pub piston_m: f64,
    /// Piston velocity (m/s).
    #[pyo3(get)]
    pub piston_velocity_m_s: f64,
    /// Piston acceleration (m/s^2).
    #[pyo3(get)]
    pub piston_accel_m_s2: f64,
    /// Knee flexion (rad).
    #[pyo3(get)]
    pub knee_rad: f64,
    /// Knee rate (rad/s).
    #[pyo3(get)]
    pub knee_rate_rad_s: f64,
    /// Desired force now (N).
    #[pyo3(get)]
    pub ref_force_n: f64,
    /// Its rate (N/s).
    #[pyo3(get)]
    pub ref_force_rate_n_per_s: f64,
    /// Its second derivative (N/s^2).
    #[pyo3(get)]
    pub ref_force_accel_n_per_s2: f64,
    /// Desired force one sample ahead (N).
    #[pyo3(get)]
    pub next_ref_force_n: f64,
    /// Its rate (N/s).
    #[pyo3(get)]
    pub next_ref_force_rate_n_per_s: f64,
    /// Its second derivative (N/s^2).
    #[pyo3(get)]
    pub next_ref_force_accel_n_per_s2: f64,
    /// The valve command limit (0 = none).
    #[pyo3(get)]
    pub valve_command_limit: f64,
    /// Raw A/D counts (force, spool, piston, knee, piston velocity; None = not quantised).
    #[pyo3(get)]
    pub counts: Counts,
    /// The device's readings (ABI 1.1: `hip_rad` ... `load_pressure_pa`), read by name through
    /// `__getattr__`.
    pub device: [f64; DEVICE_READINGS],
    /// The device's raw A/D counts (`exoleg.Obs.device_channels` order; None = not quantised).
    #[pyo3(get)]
    pub device_counts: Vec<Option<i64>>,
}

/// Raw A/D counts of the five channels (None = not quantised).
pub type Counts = (Option<i64>, Option<i64>, Option<i64>, Option<i64>, Option<i64>);

impl Obs {
    /// Fill from one sample (the fields in the order of `exoleg::control::READINGS`).
    pub fn set(&mut self, s: &SampleInput) {
        let c = s.counts.0;
        let v = s.reading_values();
        let [t_s, period_s, force_n, force_rate_n_per_s, spool_m, piston_m, piston_velocity_m_s, piston_accel_m_s2, knee_rad, knee_rate_rad_s, ref_force_n, ref_force_rate_n_per_s, ref_force_accel_n_per_s2, next_ref_force_n, next_ref_force_rate_n_per_s, next_ref_force_accel_n_per_s2, valve_command_limit] =
            std::array::from_fn(|i| v[i]);
        self.device.copy_from_slice(&v[17..]);
        self.device_counts.clear();
        self.device_counts.extend_from_slice(&s.device_counts.0);
        let (device, device_counts) = (self.device, std::mem::take(&mut self.device_counts));
        *self = Obs {
            t_s,
            period_s,
            force_n,
            force_rate_n_per_s,
            spool_m,
            piston_m,
            piston_velocity_m_s,
            piston_accel_m_s2,
            knee_rad,
            knee_rate_rad_s,
            ref_force_n,
            ref_force_rate_n_per_s,
            ref_force_accel_n_per_s2,
            next_ref_force_n,
            next_ref_force_rate_n_per_s,
            next_ref_force_accel_n_per_s2,
            valve_command_limit,
            counts: (c[0], c[1], c[2], c[3], c[4]),
            device,
            device_counts,
        };
    }

    fn values(&self) -> [f64; N_READINGS] {
        let mut v = [0.0; N_READINGS];
        v[17..].copy_from_slice(&self.device);
        v[..17].copy_from_slice(&[
            self.t_s,
            self.period_s,
            self.force_n,
            self.force_rate_n_per_s,
            self.spool_m,
            self.piston_m,
            self.piston_velocity_m_s,
            self.piston_accel_m_s2,
            self.knee_rad,
            self.knee_rate_rad_s,
            self.ref_force_n,
            self.ref_force_rate_n_per_s,
            self.ref_force_accel_n_per_s2,
            self.next_ref_force_n,
            self.next_ref_force_rate_n_per_s,
            self.next_ref_force_accel_n_per_s2,
            self.valve_command_limit,
        ]);
        v
    }
}

impl Default for Obs {
    fn default() -> Self {
        Self {
            t_s: 0.0,
            period_s: 0.0,
            force_n: 0.0,
            force_rate_n_per_s: 0.0,
            spool_m: 0.0,
            piston_m: 0.0,
            piston_velocity_m_s: 0.0,
            piston_accel_m_s2: 0.0,
            knee_rad: 0.0,
            knee_rate_rad_s: 0.0,
            ref_force_n: 0.0,
            ref_force_rate_n_per_s: 0.0,
            ref_force_accel_n_per_s2: 0.0,
            next_ref_force_n: 0.0,
            next_ref_force_rate_n_per_s: 0.0,
            next_ref_force_accel_n_per_s2: 0.0,
            valve_command_limit: 0.0,
            counts: Default::default(),
            device: [f64::NAN; DEVICE_READINGS],
            device_counts: Vec::with_capacity(DEVICE_CHANNELS.len()),
        }
    }
}

#[pymethods]
impl Obs {
    /// The reading names, in the order of [`Obs::array`].
    #[classattr]
    fn fields() -> Vec<&'static str> {
        READINGS.iter().map(|r| r.name).collect()
    }

    /// The readings as a numpy float64 vector, in the order of `Obs.fields`.
    fn array<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        numpy::PyArray1::from_slice_bound(py, &self.values())
    }

    /// The device's A/D channels, in the order of `Obs.device_counts`.
    #[classattr]
    fn device_channels() -> Vec<&'static str> {
        DEVICE_CHANNELS.iter().map(|c| c.reading).collect()
    }

    /// The device's readings by name (`obs.thigh_gyro_y_rad_s`, ...).
    fn __getattr__(&self, name: &str) -> PyResult<f64> {
        match READINGS[17..].iter().position(|r| r.name == name) {
            Some(i) => Ok(self.device[i]),
            None => Err(pyo3::exceptions::PyAttributeError::new_err(format!(
                "'Obs' has no reading `{name}` (Obs.fields lists them)"
            ))),
        }
    }

    /// A copy that later samples do not change.
    fn copy(&self) -> Obs {
        self.clone()
    }

    fn __repr__(&self) -> String {
        let parts: Vec<String> =
            READINGS.iter().map(|r| r.name).zip(self.values()).map(|(n, v)| format!("{n}={v}")).collect();
        format!("Obs({})", parts.join(", "))
    }
}

/// What a Python controller returned, as a command and its logged values.
pub struct Command {
    pub output: ControlOutput,
    pub log: Option<Vec<(String, f64)>>,
}

/// Read a controller's return value: a number, or a dict with `valve_command` and logged
/// numbers. Errors say what was wrong.
pub fn read_command(v: &Bound<'_, PyAny>) -> Result<Command, String> {
    if let Ok(f) = v.downcast::<PyFloat>() {
        return Ok(Command { output: ControlOutput::command(f.value()), log: None });
    }
    if v.is_instance_of::<PyInt>() {
        return number(v, "the valve command").map(|x| Command { output: ControlOutput::command(x), log: None });
    }
    if v.hasattr("__float__").unwrap_or(false) && !v.is_instance_of::<PyDict>() {
        if let Ok(x) = v.extract::<f64>() {
            return Ok(Command { output: ControlOutput::command(x), log: None });
        }
    }
    let Ok(d) = v.downcast::<PyDict>() else {
        return Err(format!(
            "it returned {} ({}); expected the valve command (a number) or a dict with `valve_command`",
            v.repr().map_or("?".into(), |r| r.to_string()),
            v.get_type().name().map_or("?".into(), |n| n.to_string())
        ));
    };
    let mut u = None;
    let mut log = Vec::new();
    for (k, x) in d.iter() {
        let key: String = k.extract().map_err(|_| "a key of the returned dict is not a string".to_string())?;
        let shown: String = key.chars().take(80).flat_map(char::escape_default).collect();
        let val = number(&x, &format!("`{shown}` in the returned dict"))?;
        if key == "valve_command" {
            u = Some(val);
        } else {
            log.push((key, val));
        }
    }
    let u = u.ok_or("the returned dict has no `valve_command`")?;
    Ok(Command { output: ControlOutput::command(u), log: Some(log) })
}

/// A returned number as a float; `what` names it. An integer too large for a float (10**400)
/// is said to be one, not "not a number".
fn number(x: &Bound<'_, PyAny>, what: &str) -> Result<f64, String> {
    x.extract::<f64>().map_err(|_| {
        if x.is_instance_of::<PyInt>() {
            let digits = x.str().map_or(0, |s| s.len().unwrap_or(0));
            format!("{what} is an integer of {digits} digits, too large for a float (at most about 1.8e308)")
        } else {
            format!("{what} is not a number")
        }
    })
}

/// A Python callable as a [`DiscreteController`]. A failure keeps the Python exception in
/// `error` for the caller to raise.
pub struct PyController {
    callable: PyObject,
    obs: Py<Obs>,
    error: Arc<Mutex<Option<PyErr>>>,
    log_names: Option<Vec<String>>,
    log: [f64; MAX_LOGGED],
    /// In a study: what stops the whole study when the callback raises KeyboardInterrupt,
    /// SystemExit or another BaseException that is no Exception (the study's cancel flag,
    /// and where the exception is kept to be raised again).
    stop_study: Option<StudyStop>,
}

/// A study's cancel flag and the BaseException that stopped it.
#[derive(Clone)]
pub struct StudyStop {
    pub cancel: Arc<AtomicBool>,
    pub raised: Arc<Mutex<Option<PyErr>>>,
}

impl PyController {
    /// A controller calling `callable`; failures go to `error`.
    pub fn new(py: Python<'_>, callable: PyObject, error: Arc<Mutex<Option<PyErr>>>) -> PyResult<Self> {
        let obs = Py::new(py, Obs::default())?;
        Ok(Self { callable, obs, error, log_names: None, log: [0.0; MAX_LOGGED], stop_study: None })
    }

    fn fail(&self, py: Python<'_>, t: f64, e: PyErr) -> ControlStop {
        if let Some(stop) = self.stop_study.as_ref().filter(|_| !e.is_instance_of::<pyo3::exceptions::PyException>(py))
        {
            *stop.raised.lock().unwrap_or_else(|p| p.into_inner()) = Some(e.clone_ref(py));
            stop.cancel.store(true, Ordering::SeqCst);
        }
        let msg = format!("the Python controller raised at t = {t:.6} s: {e}");
        *self.error.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
        ControlStop { message: msg }
    }

    /// Keep the logged values; the names are fixed by the first sample.
    fn take_log(&mut self, log: Option<Vec<(String, f64)>>) -> Result<(), String> {
        let log = log.unwrap_or_default();
        match &self.log_names {
            None => {
                if log.len() > MAX_LOGGED {
                    return Err(format!("it logs {} channels, at most {MAX_LOGGED}", log.len()));
                }
                let names: Vec<String> = log.iter().map(|(k, _)| k.clone()).collect();
                exoleg::record::check_log_names(&names).map_err(|m| format!("the returned dict's keys: {m}"))?;
                self.log_names = Some(names);
            }
            Some(names) => {
                if names.len() != log.len() || names.iter().zip(&log).any(|(n, (k, _))| n != k) {
                    return Err(format!(
                        "it logged {:?}, but the first sample logged {names:?} (the same keys at every sample)",
                        log.iter().map(|(k, _)| k.as_str()).collect::<Vec<_>>()
                    ));
                }
            }
        }
        for (slot, (_, v)) in self.log.iter_mut().zip(log) {
            *slot = v;
        }
        Ok(())
    }
}

impl DiscreteController for PyController {
    fn kind(&self) -> &str {
        "python"
    }

    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        Python::with_gil(|py| {
            self.obs.borrow_mut(py).set(s);
            let ret = self.callable.call1(py, (self.obs.clone_ref(py),)).map_err(|e| self.fail(py, s.t_s, e))?;
            let cmd = read_command(ret.bind(py))
                .and_then(|c| self.take_log(c.log).map(|_| c.output))
                .map_err(|m| self.fail(py, s.t_s, ControllerError::new_err(m)))?;
            if !cmd.valve_command.is_finite() {
                let m = format!("it returned the valve command {}", cmd.valve_command);
                return Err(self.fail(py, s.t_s, ControllerError::new_err(m)));
            }
            Ok(cmd)
        })
    }

    fn log_names(&self) -> Vec<String> {
        self.log_names.clone().unwrap_or_default()
    }

    fn log_values(&self, out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(self.log) {
            *o = v;
        }
    }
}

/// The Python exception for a failed run with a Python controller: the callback's own
/// exception as the cause of a `ControllerError` naming the time, else the run's error.
pub fn controller_failure(py: Python<'_>, e: Error, error: &Arc<Mutex<Option<PyErr>>>) -> PyErr {
    let cause = error.lock().unwrap_or_else(|p| p.into_inner()).take();
    match (cause, &e) {
        // KeyboardInterrupt, SystemExit: not the controller's failure; they go on as they are.
        (Some(c), _) if !c.is_instance_of::<pyo3::exceptions::PyException>(py) => c,
        (Some(c), Error::ControllerStopped { time_s, .. }) => {
            if c.is_instance_of::<ControllerError>(py) {
                return ControllerError::new_err(format!(
                    "the Python controller at t = {time_s:.6} s: {}",
                    c.value_bound(py)
                ));
            }
            let err = ControllerError::new_err(format!(
                "the Python controller raised {} at t = {time_s:.6} s",
                c.value_bound(py).repr().map_or_else(|_| "an exception".into(), |r| r.to_string())
            ));
            err.set_cause(py, Some(c));
            err
        }
        _ => py_err(e),
    }
}

/// Run `sc` with the Python callable `controller` (the GIL held; signals checked every
/// [`SIGNAL_CHECK_STEPS`] steps). With `out`, the outputs are written as `exoleg run` writes
/// them, or not at all if the run fails.
pub fn run_with_callback(
    py: Python<'_>,
    sc: &ResolvedScenario,
    controller: PyObject,
    out: Option<&str>,
) -> PyResult<(String, ColumnSink)> {
    let error = Arc::new(Mutex::new(None));
    let ctrl = PyController::new(py, controller, error.clone())?;
    let sim = Simulation::build(sc.model.clone(), ControllerSource::Discrete(Box::new(ctrl))).map_err(py_err)?;
    let r = crate::stepwise::drive(py, sc, sim, out, |session| {
        while !session.sim().done() {
            session.step()?;
            if session.sim().steps_taken() % SIGNAL_CHECK_STEPS == 0 && py.check_signals().is_err() {
                return Err(Error::Interrupted);
            }
        }
        Ok(())
    });
    r.map_err(|e| match e {
        Error::Interrupted => py.check_signals().err().unwrap_or_else(|| py_err(Error::Interrupted)),
        e => controller_failure(py, e, &error),
    })
}

/// Steps between two checks for Ctrl-C while a Python controller runs.
pub const SIGNAL_CHECK_STEPS: usize = 1000;

/// A controller factory for a study: every run calls `callable` (with the GIL, one run after
/// the other). A failing callback fails its run, recorded in `runs.jsonl` with the message.
/// A KeyboardInterrupt or SystemExit in the callback stops the whole study (`stop`), and is
/// raised again by the caller.
pub fn factory(callable: PyObject, stop: StudyStop) -> Arc<ControllerFactory> {
    let callable = Arc::new(callable);
    Arc::new(move |_sc: &ResolvedScenario| -> exoleg::Result<Box<dyn DiscreteController>> {
        Python::with_gil(|py| {
            let err = Arc::new(Mutex::new(None));
            PyController::new(py, (*callable).clone_ref(py), err)
                .map(|mut c| {
                    c.stop_study = Some(stop.clone());
                    Box::new(c) as Box<dyn DiscreteController>
                })
                .map_err(|e| Error::Usage(e.to_string()))
        })
    })
}
