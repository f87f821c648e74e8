//! A Python callable as the run's controller: called once per sample period with one reused
//! [`Obs`] (the readings by name), it returns the valve command, or a dict with
//! `valve_command` and logged channels (numbers, the same keys at every sample).

use crate::obs::{read_command, Obs};
use crate::{py_err, ColumnSink, ControllerError};
use exoleg::control::{ControlOutput, ControlStop, DiscreteController, SampleInput, MAX_LOGGED};
use exoleg::scenario::ResolvedScenario;
use exoleg::sim::{ControllerSource, Simulation};
use exoleg::study::sweep::ControllerFactory;
use exoleg::Error;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

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
        ControlStop::crash(msg)
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
                let e = self.fail(py, s.t_s, ControllerError::new_err(m.clone()));
                return Err(ControlStop::command(e.message));
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
    baseline: Option<crate::stepwise::MetabolicsSummary>,
) -> PyResult<(String, ColumnSink)> {
    let error = Arc::new(Mutex::new(None));
    let ctrl = PyController::new(py, controller, error.clone())?;
    let sim = Simulation::build(sc.model.clone(), ControllerSource::Discrete(Box::new(ctrl))).map_err(py_err)?;
    let r = crate::stepwise::drive(py, sc, sim, out, baseline, |session| {
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
