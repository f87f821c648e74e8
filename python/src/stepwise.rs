//! Runs whose loop the caller owns (`exoleg.Simulation`: reset, step(command), finish) and
//! the plumbing every Python run shares: the sinks (columns for numpy, and with `out` the
//! files `exoleg run` writes) and the summary.

use crate::obs::{read_command, Obs};
use crate::{load, py_err, ColumnSink, ExoError, ScenarioError};
use exoleg::control::SampleInput;
use exoleg::output::OutputDir;
use exoleg::record::{Layout, RecordSink, Row};
use exoleg::scenario::ResolvedScenario;
use exoleg::sim::{ControllerSource, Model, Simulation as CoreSimulation};
use exoleg::study::{RunFiles, SummaryFile};
use exoleg::{Error, Resources, Session};
use pyo3::prelude::*;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// The sinks of a Python run: the columns, and the output files when asked for.
pub struct PySinks {
    pub cols: exoleg::record::EveryNth<ColumnSink>,
    files: Option<RunFiles>,
}

impl RecordSink for PySinks {
    fn start(&mut self, layout: &Layout) -> exoleg::Result<()> {
        self.cols.start(layout)?;
        self.files.as_mut().map_or(Ok(()), |f| f.start(layout))
    }
    fn row(&mut self, row: &Row) -> exoleg::Result<()> {
        self.cols.row(row)?;
        self.files.as_mut().map_or(Ok(()), |f| f.row(row))
    }
}

/// A session and where its files go.
struct Started {
    session: Session<PySinks>,
    dir: Option<OutputDir>,
    /// The controller from outside the scenario (`summary.json`'s `external_controller`).
    external: Option<String>,
    /// The baseline's muscle figures (`exoleg.run(..., baseline=True)`).
    baseline: Option<MetabolicsSummary>,
}

/// A run's baseline muscle figures (`exoleg.run(..., baseline=True)`).
pub type MetabolicsSummary = exoleg::metrics::muscles::MetabolicsSummary;

/// Start a session of `sim` into columns and (with `out`) an output folder being written.
fn start(
    sc: &ResolvedScenario,
    sim: CoreSimulation,
    out: Option<&str>,
    external: Option<String>,
    baseline: Option<MetabolicsSummary>,
) -> Result<Started, Error> {
    let dir =
        out.map(|o| OutputDir::prepare_with_inputs(std::path::Path::new(o), "out", &sc.input_paths())).transpose()?;
    let every = sc.file.output.every_steps;
    let files = dir
        .as_ref()
        .map(|d| {
            RunFiles::create(d.path(), &sc.file.output).map(|f| f.external(external.clone()).baseline(baseline.clone()))
        })
        .transpose()?;
    let cols = exoleg::record::EveryNth::new(ColumnSink::with_capacity(sc.model.steps / every.max(1) + 1), every);
    let sinks = PySinks { cols, files };
    Ok(Started { session: Session::new(sim, sinks)?, dir, external, baseline })
}

/// Finish a session: the summary as `summary.json` holds it, and the files committed.
fn finish(sc: &ResolvedScenario, st: Started) -> Result<(String, ColumnSink), Error> {
    let mut f = st.session.finish()?;
    if let (Some(b), Some(m)) = (&st.baseline, f.summary.wearer.as_mut().and_then(|w| w.metabolics.as_mut())) {
        m.against(b);
    }
    let mut sinks = f.sink;
    let summary_json = match (sinks.files.take(), st.dir) {
        (Some(files), Some(dir)) => {
            let report = files.finish(sc, &exoleg::study::run_title(sc), f.summary, f.design.clone())?;
            dir.commit()?;
            summary_json(sc, &report.summary, f.design, st.external)?
        }
        _ => summary_json(sc, &f.summary, f.design, st.external)?,
    };
    Ok((summary_json, sinks.cols.into_inner()))
}

fn summary_json(
    sc: &ResolvedScenario,
    summary: &exoleg::metrics::Summary,
    design: Option<serde_json::Value>,
    external: Option<String>,
) -> Result<String, Error> {
    let criteria = exoleg::metrics::check_criteria(&sc.file.criteria, summary);
    serde_json::to_string(&SummaryFile::new(sc, summary, &criteria, design).external(external))
        .map_err(|e| Error::Write { path: "summary.json".into(), message: e.to_string() })
}

/// Run `sim` (whose controller is the Python callable) through `drive`, then finish:
/// (summary JSON, columns). With `out`, the files are written and committed only when
/// everything succeeded.
pub fn drive(
    _py: Python<'_>,
    sc: &ResolvedScenario,
    sim: CoreSimulation,
    out: Option<&str>,
    baseline: Option<MetabolicsSummary>,
    body: impl FnOnce(&mut Session<PySinks>) -> Result<(), Error>,
) -> Result<(String, ColumnSink), Error> {
    let mut st = start(sc, sim, out, Some("python".into()), baseline)?;
    body(&mut st.session)?;
    finish(sc, st)
}

/// Run `sc` with its own controller (no Python involved: runs on a worker thread).
pub fn run_model(
    sc: &ResolvedScenario,
    out: Option<&str>,
    cancel: Option<Arc<AtomicBool>>,
    baseline: Option<MetabolicsSummary>,
) -> Result<(String, ColumnSink), Error> {
    let mut st = start(sc, CoreSimulation::new(sc.model.clone())?, out, None, baseline)?;
    st.session.set_cancel(cancel);
    st.session.run_to_end()?;
    finish(sc, st)
}

/// What a controller of `m` is told (the C plugin's `ExolegInfo`).
pub fn info_json(m: &Model) -> serde_json::Value {
    let c = &m.nominal.c;
    serde_json::json!({
        "sample_period_s": m.sample_period_s,
        "valve_command_limit": m.valve_limit.0,
        "nominal": {"n1": c.n1, "n2": c.n2, "n3": c.n3, "tau_s": c.tau_s, "k_s": c.k_s},
        "seed": m.seed,
        "steps": m.steps,
        "dt_s": m.dt_s,
        "duration_s": m.steps as f64 * m.dt_s,
        "wearer_muscles": m.muscles.is_some(),
    })
}

/// A run whose loop the caller owns: `reset(seed)` reads the first sample, `step(command)`
/// holds the command for one sample period and reads the next, `finish()` records the end
/// and returns (and, with `out`, writes) what `exoleg.run` gives.
///
/// A failure (the run diverged, a non-finite command, a bad command) ends the run where it
/// happened: `step()` raises, the output folder being written is removed, every later
/// `step()` and `finish()` raise saying so (nothing is written), `reset()` starts again.
/// Any thread may use it (the GIL serialises the calls) or drop it (the temporary output
/// folder goes with it).
#[pyclass(module = "exoleg._native")]
pub struct Simulation {
    sc: ResolvedScenario,
    /// The scenario's own seed (`reset()` without one goes back to it).
    seed: u64,
    out: Option<String>,
    run: Option<Started>,
    obs: Py<Obs>,
    last: Option<SampleInput>,
    log_names: Option<Vec<String>>,
    /// Why the run stopped, and when (s).
    failed: Option<(PyErr, f64)>,
}

impl Simulation {
    fn started(&mut self, py: Python<'_>) -> PyResult<&mut Started> {
        if let Some((e, t)) = &self.failed {
            let msg = format!("the run failed at t = {t:.6} s ({}): reset() starts a new one", e.value_bound(py));
            return Err(PyErr::from_type_bound(e.get_type_bound(py), msg));
        }
        self.run.as_mut().ok_or_else(|| ExoError::new_err("finished: call reset() to start again"))
    }

    /// The run fails with `e`: it stops here, its output folder is removed.
    fn fail(&mut self, py: Python<'_>, e: PyErr) -> PyErr {
        let t = self.run.as_ref().map_or(0.0, |r| r.session.sim().t_s());
        self.run = None;
        self.failed = Some((e.clone_ref(py), t));
        e
    }

    /// Step 1 at the next sample instant (the run is there), into the reused obs.
    fn read(&mut self, py: Python<'_>) -> PyResult<Py<Obs>> {
        let st = self.started(py)?;
        let s = st.session.sample().map_err(py_err)?;
        self.obs.borrow_mut(py).set(&s);
        self.last = Some(s);
        Ok(self.obs.clone_ref(py))
    }

    fn log_values(&mut self, py: Python<'_>, log: Option<Vec<(String, f64)>>) -> PyResult<Vec<f64>> {
        let log = log.unwrap_or_default();
        let names: Vec<String> = log.iter().map(|(k, _)| k.clone()).collect();
        match &self.log_names {
            None => {
                exoleg::record::check_log_names(&names)
                    .map_err(|m| crate::ControllerError::new_err(format!("step(): the command's keys: {m}")))?;
                let st = self.started(py)?;
                st.session.sim_mut().set_log_names(names.clone()).map_err(py_err)?;
                self.log_names = Some(names);
            }
            Some(n) if *n != names => {
                return Err(crate::ControllerError::new_err(format!(
                    "step() logged {names:?}, the first step {n:?}: the same keys at every step"
                )))
            }
            Some(_) => {}
        }
        Ok(log.into_iter().map(|(_, v)| v).collect())
    }
}

#[pymethods]
impl Simulation {
    #[new]
    #[pyo3(signature = (path=None, toml_text=None, scenario_json=None, overrides_json=None, out=None))]
    fn new(
        py: Python<'_>,
        path: Option<String>,
        toml_text: Option<String>,
        scenario_json: Option<String>,
        overrides_json: Option<String>,
        out: Option<String>,
    ) -> PyResult<Self> {
        let sc = py
            .allow_threads(|| load(path, toml_text, scenario_json, overrides_json)?.resolve(&Resources::new()))
            .map_err(py_err)?;
        if sc.model.sample_every.is_none() {
            return Err(ScenarioError::new_err(format!(
                "{}: controller.sample_period_s: a loop you own runs sampled: set it > 0 (e.g. 0.001)",
                sc.source_name
            )));
        }
        // Absolute now: nothing the run loads later moves the outputs.
        let out = out.map(|o| std::path::absolute(&o).map_or(o, |p| p.display().to_string()));
        let seed = sc.model.seed;
        let obs = Py::new(py, Obs::default())?;
        let mut s = Self { sc, seed, out, run: None, obs, last: None, log_names: None, failed: None };
        s.reset(py, None)?;
        Ok(s)
    }

    /// Start (again) from t = 0, with `seed` in place of the scenario's (without one, the
    /// scenario's own); returns the readings of the first sample.
    #[pyo3(signature = (seed=None))]
    fn reset(&mut self, py: Python<'_>, seed: Option<u64>) -> PyResult<Py<Obs>> {
        crate::guard(|| self.reset_inner(py, seed))
    }

    /// Hold `command` (the valve command, or a dict with `valve_command` and logged numbers)
    /// for one sample period; returns the readings of the next sample (the last ones again
    /// once the run is done).
    fn step(&mut self, py: Python<'_>, command: &Bound<'_, PyAny>) -> PyResult<Py<Obs>> {
        crate::guard(|| self.step_inner(py, command))
    }
    /// True when the run has taken all its steps (or failed).
    #[getter]
    fn done(&self) -> bool {
        self.run.as_ref().is_none_or(|r| r.session.sim().done())
    }

    /// Simulated time (s) of the next step (of the failure, after one).
    #[getter]
    fn t_s(&self) -> f64 {
        match (&self.run, &self.failed) {
            (Some(r), _) => r.session.sim().t_s(),
            (None, Some((_, t))) => *t,
            _ => 0.0,
        }
    }

    /// The readings of the last sample.
    #[getter]
    fn obs(&self, py: Python<'_>) -> Py<Obs> {
        self.obs.clone_ref(py)
    }

    /// The true force error F_L - F_d (N) now (not a reading: for rewards and checks).
    #[getter]
    fn force_error_n(&self) -> f64 {
        self.run.as_ref().map_or(f64::NAN, |r| r.session.sim().force_error_n())
    }

    /// The wearer's gross metabolic rate over the last step (W/kg; NaN without the wearer's
    /// muscles or before the first step).
    #[getter]
    fn gross_metabolic_w_per_kg(&self) -> f64 {
        self.run.as_ref().and_then(|r| r.session.sim().gross_metabolic_w_per_kg()).unwrap_or(f64::NAN)
    }

    /// What the controller is told (sample period, valve limit, nominal model), as JSON.
    #[getter]
    fn info_json(&self) -> String {
        info_json(&self.sc.model).to_string()
    }

    /// Record the final state (or the state now, if the run stops early) and return
    /// (summary JSON, columns, scenario TOML); with `out`, the files are written. After a
    /// failure it raises (nothing is written).
    fn finish<'py>(&mut self, py: Python<'py>) -> PyResult<crate::RunOut<'py>> {
        self.started(py)?;
        let st = self.run.take().ok_or_else(|| ExoError::new_err("already finished: call reset() to start again"))?;
        let (summary, cols) = finish(&self.sc, st).map_err(py_err)?;
        let toml = toml::to_string(&self.sc.file).map_err(|e| ExoError::new_err(e.to_string()))?;
        Ok((summary, cols.into_dict(py)?, toml))
    }
}

impl Simulation {
    fn reset_inner(&mut self, py: Python<'_>, seed: Option<u64>) -> PyResult<Py<Obs>> {
        self.run = None;
        self.failed = None;
        self.log_names = None;
        let seed = seed.unwrap_or(self.seed);
        if seed != self.sc.model.seed {
            let mut m: Model = (*self.sc.model).clone();
            m.seed = seed;
            self.sc.model = Arc::new(m);
            self.sc.file.seed = seed;
        }
        let sim = CoreSimulation::build(self.sc.model.clone(), ControllerSource::External).map_err(py_err)?;
        let external = Some("external loop (exoleg.Simulation)".to_string());
        self.run = Some(start(&self.sc, sim, self.out.as_deref(), external, None).map_err(py_err)?);
        self.read(py)
    }

    fn step_inner(&mut self, py: Python<'_>, command: &Bound<'_, PyAny>) -> PyResult<Py<Obs>> {
        self.started(py)?;
        let cmd = read_command(command).map_err(crate::ControllerError::new_err)?;
        if !cmd.output.valve_command.is_finite() {
            let e = crate::ControllerError::new_err(format!(
                "step(): the valve command is {}: the run stops here (finish() writes nothing; reset() starts again)",
                cmd.output.valve_command
            ));
            return Err(self.fail(py, e));
        }
        let log = self.log_values(py, cmd.log)?;
        let st = self.started(py)?;
        if st.session.sim().done() {
            return Err(ExoError::new_err("the run is done: call finish() (or reset())"));
        }
        st.session.sim_mut().set_log(&log);
        let advanced = (|| -> Result<(), Error> {
            st.session.hold(cmd.output)?;
            st.session.advance()?;
            while !st.session.sim().done() && !st.session.sim().is_sample_step() {
                st.session.advance()?;
            }
            Ok(())
        })();
        if let Err(e) = advanced {
            return Err(self.fail(py, py_err(e)));
        }
        if self.run.as_ref().is_some_and(|r| r.session.sim().done()) {
            return Ok(self.obs.clone_ref(py));
        }
        self.read(py).map_err(|e| self.fail(py, e))
    }
}
