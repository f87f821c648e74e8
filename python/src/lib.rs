// PyO3 0.22's #[pyfunction] expansion trips clippy's useless_conversion on PyResult returns.
#![allow(clippy::useless_conversion)]

//! `exoleg._native`: the Rust side of the Python package. Scenarios and overrides come in as
//! data (JSON text of Python dicts, or a path), never as guessed TOML. Runs without a Python
//! controller release the GIL and run on a worker thread while the calling thread watches for
//! Ctrl-C; a run with a Python controller holds the GIL and checks for signals as it goes.
//! The Python layer (`pysrc/exoleg/__init__.py`) wraps the results.

mod controller;
mod crew;
mod obs;
mod stepwise;
mod vector;

use exoleg::record::{Layout, RecordSink, Row};
use exoleg::study::{compare, robustness, shard, sweep};
use exoleg::{Error, Resources, Scenario};
use numpy::PyArray1;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

create_exception!(exoleg, ExoError, PyException, "Any exoleg failure (writing outputs, criteria).");
create_exception!(
    exoleg,
    ScenarioError,
    PyValueError,
    "Bad input: the message names the file, the key and the problem."
);
create_exception!(
    exoleg,
    DivergedError,
    PyRuntimeError,
    "A run diverged, became too stiff, or its controller stopped it; the message names the state or the controller and the time."
);
create_exception!(
    exoleg,
    ControllerError,
    ExoError,
    "The Python controller failed (raised, or returned something that is not a command); the message names the simulated time, and the original exception is the cause."
);

/// An exoleg error as the Python exception of its class.
pub(crate) fn py_err(e: Error) -> PyErr {
    let msg = e.to_string();
    match e {
        Error::Input { .. } | Error::Read { .. } => ScenarioError::new_err(msg),
        Error::Diverged { .. } | Error::Stiff { .. } | Error::ControllerStopped { .. } => DivergedError::new_err(msg),
        Error::Interrupted => PyKeyboardInterrupt::new_err(msg),
        _ => ExoError::new_err(msg),
    }
}

/// Run `f`, turning a Rust panic into an `ExoError` (a panic must never reach Python as
/// `PanicException`, which `except Exception` does not catch).
pub(crate) fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
        .unwrap_or_else(|p| Err(ExoError::new_err(format!("internal error (a panic): {}", sweep::panic_message(&p)))))
}

/// The scenario: a path, TOML text, a JSON object (a Python dict), or the embedded default,
/// with overrides as a JSON array of `[key, value]` pairs.
pub(crate) fn load(
    path: Option<String>,
    toml_text: Option<String>,
    scenario_json: Option<String>,
    overrides_json: Option<String>,
) -> Result<Scenario, Error> {
    let overrides: Vec<(String, serde_json::Value)> = match overrides_json {
        None => Vec::new(),
        Some(t) => serde_json::from_str(&t)
            .map_err(|e| Error::input("overrides", "", format!("expected {{key: value}}: {e}")))?,
    };
    let base = match (path, toml_text, scenario_json) {
        (Some(p), _, _) => Scenario::load(Some(Path::new(&p)), &[])?,
        (None, Some(t), _) => Scenario::from_toml_str("<python scenario>", &t, &[])?,
        (None, None, Some(j)) => {
            let v: serde_json::Value = serde_json::from_str(&j)
                .map_err(|e| Error::input("<python scenario>", "", format!("not a scenario: {e}")))?;
            Scenario::from_json("<python scenario>", Some(v), Vec::new())?
        }
        (None, None, None) => Scenario::load(None, &[])?,
    };
    base.with_values(overrides)
}

/// The columns of a run, filled as it goes (one copy of the data, handed to numpy as is).
#[derive(Default)]
pub(crate) struct ColumnSink {
    pub names: Vec<String>,
    pub columns: Vec<Vec<f64>>,
    layout: Layout,
    buf: Vec<f64>,
    capacity: usize,
}

impl ColumnSink {
    /// Columns with room for `rows` rows each.
    pub fn with_capacity(rows: usize) -> Self {
        Self { capacity: rows, ..Default::default() }
    }

    /// The columns as numpy arrays, in a dict by name (no copy).
    pub fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let d = PyDict::new_bound(py);
        for (n, c) in self.names.into_iter().zip(self.columns) {
            d.set_item(n, PyArray1::from_vec_bound(py, c))?;
        }
        Ok(d)
    }
}

impl RecordSink for ColumnSink {
    fn start(&mut self, layout: &Layout) -> exoleg::Result<()> {
        self.layout = layout.clone();
        self.names = layout.names();
        self.columns = self.names.iter().map(|_| Vec::with_capacity(self.capacity)).collect();
        Ok(())
    }
    fn row(&mut self, row: &Row) -> exoleg::Result<()> {
        self.buf.clear();
        row.values_into(&self.layout, &mut self.buf);
        for (c, v) in self.columns.iter_mut().zip(&self.buf) {
            c.push(*v);
        }
        Ok(())
    }
}

/// Run `work` on a worker thread with the GIL released while this thread watches for Ctrl-C
/// (and SIGTERM, through Python's handlers): on a signal, `cancel` is set, the work stops at
/// its next check, and the signal's exception is raised.
pub(crate) fn interruptible<T: Send>(
    py: Python<'_>,
    cancel: &Arc<AtomicBool>,
    work: impl FnOnce() -> Result<T, Error> + Send,
) -> PyResult<T> {
    let mut signal: Option<PyErr> = None;
    let out = py.allow_threads(|| {
        std::thread::scope(|s| {
            let main = std::thread::current();
            let h = s.spawn(move || {
                let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
                main.unpark();
                r
            });
            while !h.is_finished() {
                std::thread::park_timeout(std::time::Duration::from_millis(50));
                if signal.is_none() && !h.is_finished() {
                    if let Err(e) = Python::with_gil(|py| py.check_signals()) {
                        cancel.store(true, Ordering::Relaxed);
                        signal = Some(e);
                    }
                }
            }
            h.join()
        })
    });
    if let Some(e) = signal {
        return Err(e);
    }
    match out {
        Ok(Ok(Ok(v))) => Ok(v),
        Ok(Ok(Err(e))) => Err(py_err(e)),
        Ok(Err(p)) | Err(p) => {
            Err(ExoError::new_err(format!("internal error (a panic): {}", sweep::panic_message(&p))))
        }
    }
}

/// What a finished run gives Python: summary JSON, the columns (numpy, by name), the
/// scenario as run (TOML).
pub(crate) type RunOut<'py> = (String, Bound<'py, PyDict>, String);

/// Run one scenario in memory (with the scenario's controller, or `controller`, a Python
/// callable called once per sample period). With `out`, also write the outputs as `exoleg
/// run --out` does.
#[pyfunction]
#[pyo3(signature = (path=None, toml_text=None, scenario_json=None, overrides_json=None, controller=None, out=None, baseline=false))]
#[allow(clippy::too_many_arguments)]
fn run<'py>(
    py: Python<'py>,
    path: Option<String>,
    toml_text: Option<String>,
    scenario_json: Option<String>,
    overrides_json: Option<String>,
    controller: Option<PyObject>,
    out: Option<String>,
    baseline: bool,
) -> PyResult<RunOut<'py>> {
    let own = controller.is_none();
    let (sc, base) = py
        .allow_threads(|| {
            let s = load(path, toml_text, scenario_json, overrides_json)?;
            if own {
                s.own_controller()?;
            }
            let res = Resources::new();
            let base = if baseline { Some(exoleg::study::baseline_metabolics(&s, &res)?) } else { None };
            Ok::<_, exoleg::Error>((s.resolve(&res)?, base))
        })
        .map_err(py_err)?;
    let scenario_toml = toml::to_string(&sc.file).map_err(|e| ExoError::new_err(e.to_string()))?;
    let (summary, cols) = match controller {
        Some(c) => guard(|| controller::run_with_callback(py, &sc, c, out.as_deref(), base))?,
        None => {
            let cancel = Arc::new(AtomicBool::new(false));
            interruptible(py, &cancel, || stepwise::run_model(&sc, out.as_deref(), Some(cancel.clone()), base))?
        }
    };
    Ok((summary, cols.into_dict(py)?, scenario_toml))
}

/// What the controller of a scenario is told (the C plugin's `ExolegInfo`), as JSON.
#[pyfunction]
#[pyo3(signature = (path=None, toml_text=None, scenario_json=None, overrides_json=None))]
fn controller_info(
    py: Python<'_>,
    path: Option<String>,
    toml_text: Option<String>,
    scenario_json: Option<String>,
    overrides_json: Option<String>,
) -> PyResult<String> {
    let sc = py
        .allow_threads(|| load(path, toml_text, scenario_json, overrides_json)?.resolve(&Resources::new()))
        .map_err(py_err)?;
    Ok(stepwise::info_json(&sc.model).to_string())
}

/// A sweep or robustness study into the folder `out` (all runs, or one shard). With a Python
/// `controller`, every run is made with it, one run after the other in this process. Returns
/// the title line and `aggregate.csv`'s text (or, with `plan_only`, the plan's JSON lines).
#[pyfunction]
#[pyo3(signature = (kind, out, path=None, toml_text=None, scenario_json=None, overrides_json=None, grids=Vec::new(), monte_carlo=None, vary=Vec::new(), percent=20.0, samples=64, jobs=0, shard_k_n=None, controller=None, resume=false, matrix=None, observe_strides=exoleg::study::faults::DEFAULT_OBSERVE_STRIDES))]
#[allow(clippy::too_many_arguments)]
fn study(
    py: Python<'_>,
    kind: String,
    out: String,
    path: Option<String>,
    toml_text: Option<String>,
    scenario_json: Option<String>,
    overrides_json: Option<String>,
    grids: Vec<String>,
    monte_carlo: Option<usize>,
    vary: Vec<String>,
    percent: f64,
    samples: usize,
    jobs: usize,
    shard_k_n: Option<(usize, usize)>,
    controller: Option<PyObject>,
    resume: bool,
    matrix: Option<String>,
    observe_strides: f64,
) -> PyResult<(String, String)> {
    let base = py.allow_threads(|| load(path, toml_text, scenario_json, overrides_json)).map_err(py_err)?;
    if controller.is_none() {
        base.own_controller().map_err(py_err)?;
    }
    let cancel = Arc::new(AtomicBool::new(false));
    let stop = controller::StudyStop { cancel: cancel.clone(), raised: Arc::new(std::sync::Mutex::new(None)) };
    let factory = controller.map(|c| controller::factory(c, stop.clone()));
    let args = StudyArgs { grids, monte_carlo, vary, percent, samples, matrix, observe_strides };
    let (base_run, plan, study_kind) =
        py.allow_threads(|| study_plan(&kind, &base, &args, factory.as_deref())).map_err(py_err)?;
    if let Some((k, n)) = shard_k_n {
        shard::parse_shard(&format!("{k}/{n}")).map_err(py_err)?;
    }
    let opts = sweep::RunOptions {
        // A Python controller runs in this process, one run after the other.
        jobs: if factory.is_some() { 1 } else { jobs },
        progress: false,
        shard: shard_k_n.unwrap_or((0, 1)),
        controller: factory,
        cancel: Some(cancel.clone()),
        resume,
    };
    let work = || {
        let done = shard::run_study_into(
            &base_run,
            &base.source_name,
            &plan,
            &study_kind,
            &opts,
            shard_k_n.is_some(),
            false,
            Path::new(&out),
        )?;
        Ok((done.title, done.aggregate.csv()))
    };
    let r = interruptible(py, &cancel, work);
    // A KeyboardInterrupt or SystemExit from the callback stopped the study: raise it.
    let raised = stop.raised.lock().unwrap_or_else(|p| p.into_inner()).take();
    match raised {
        Some(e) if r.is_err() => Err(e),
        _ => r,
    }
}

/// What a study's plan is made from (each kind reads its own).
struct StudyArgs {
    grids: Vec<String>,
    monte_carlo: Option<usize>,
    vary: Vec<String>,
    percent: f64,
    samples: usize,
    /// A fault campaign's matrix file (None: the default for the scenario).
    matrix: Option<String>,
    observe_strides: f64,
}

/// The plan of a sweep, robustness or fault-campaign study, and the scenario its runs start
/// from. A campaign's notes (the valve travel it gives) are printed to standard error.
fn study_plan(
    kind: &str,
    base: &Scenario,
    a: &StudyArgs,
    controller: Option<&sweep::ControllerFactory>,
) -> Result<(Scenario, sweep::Plan, shard::StudyKind), Error> {
    match kind {
        "sweep" => {
            let plan = sweep::plan_from_args(base, &a.grids, a.monte_carlo, &a.vary)?;
            Ok((base.clone(), plan, shard::StudyKind::Sweep))
        }
        "robustness" => {
            let (pinned, plan) = robustness::robustness_plan(base, a.samples, a.percent)?;
            Ok((pinned, plan, shard::StudyKind::Robustness { percent: a.percent }))
        }
        "faults" => {
            let matrix = a.matrix.as_deref().map(|p| exoleg::study::faults::read_matrix(Path::new(p))).transpose()?;
            let res = exoleg::scenario::Resources::new();
            let c = exoleg::study::faults::campaign(base, matrix, a.observe_strides, controller, &res)?;
            for n in &c.notes {
                eprintln!("note: {n}");
            }
            Ok((c.base, c.plan, shard::StudyKind::Faults { layout: c.layout }))
        }
        other => Err(Error::input("exoleg.study", "kind", format!("`{other}`: sweep, robustness or faults"))),
    }
}

/// The runs of a plan, expanded lazily: `len()` and run `i`'s overrides on demand (a plan of
/// 10^6 runs costs no memory until its runs are asked for).
#[pyclass(module = "exoleg._native")]
struct Plan {
    plan: sweep::Plan,
}

#[pymethods]
impl Plan {
    fn __len__(&self) -> usize {
        self.plan.len()
    }

    /// Run `i`'s overrides (`key=value` texts, as in `runs.jsonl`).
    fn sets(&self, i: usize) -> PyResult<Vec<String>> {
        if i >= self.plan.len() {
            return Err(pyo3::exceptions::PyIndexError::new_err(format!("run {i} of {}", self.plan.len())));
        }
        Ok(self.plan.sets(i))
    }
}

/// The plan of a study, without running it.
#[pyfunction]
#[pyo3(signature = (kind, path=None, toml_text=None, scenario_json=None, overrides_json=None, grids=Vec::new(), monte_carlo=None, vary=Vec::new(), percent=20.0, samples=64, matrix=None, observe_strides=exoleg::study::faults::DEFAULT_OBSERVE_STRIDES))]
#[allow(clippy::too_many_arguments)]
fn plan(
    py: Python<'_>,
    kind: String,
    path: Option<String>,
    toml_text: Option<String>,
    scenario_json: Option<String>,
    overrides_json: Option<String>,
    grids: Vec<String>,
    monte_carlo: Option<usize>,
    vary: Vec<String>,
    percent: f64,
    samples: usize,
    matrix: Option<String>,
    observe_strides: f64,
) -> PyResult<Plan> {
    py.allow_threads(|| {
        let base = load(path, toml_text, scenario_json, overrides_json)?;
        let args = StudyArgs { grids, monte_carlo, vary, percent, samples, matrix, observe_strides };
        study_plan(&kind, &base, &args, None).map(|(_, plan, _)| Plan { plan })
    })
    .map_err(py_err)
}

/// Merge shard folders into `out`. Returns the title line and `aggregate.csv`'s text.
#[pyfunction]
fn merge(py: Python<'_>, shards: Vec<String>, out: String) -> PyResult<(String, String)> {
    let cancel = Arc::new(AtomicBool::new(false));
    interruptible(py, &cancel, || {
        let dirs: Vec<PathBuf> = shards.iter().map(PathBuf::from).collect();
        shard::merge(&dirs, Path::new(&out)).map(|m| (m.title, m.aggregate.csv()))
    })
}

/// The paper's eight cases on a base scenario. Returns their results as JSON.
#[pyfunction]
#[pyo3(signature = (path=None, toml_text=None, scenario_json=None, overrides_json=None))]
fn compare_cases(
    py: Python<'_>,
    path: Option<String>,
    toml_text: Option<String>,
    scenario_json: Option<String>,
    overrides_json: Option<String>,
) -> PyResult<String> {
    let cancel = Arc::new(AtomicBool::new(false));
    interruptible(py, &cancel, || {
        let base = load(path, toml_text, scenario_json, overrides_json)?;
        let results = compare::run_cases(&base, &[])?;
        serde_json::to_string(&results).map_err(|e| Error::input("compare", "results", e.to_string()))
    })
}

/// The Python module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ExoError", m.py().get_type_bound::<ExoError>())?;
    m.add("ScenarioError", m.py().get_type_bound::<ScenarioError>())?;
    m.add("DivergedError", m.py().get_type_bound::<DivergedError>())?;
    m.add("ControllerError", m.py().get_type_bound::<ControllerError>())?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(controller_info, m)?)?;
    m.add_function(wrap_pyfunction!(study, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(compare_cases, m)?)?;
    m.add_class::<Plan>()?;
    m.add_class::<obs::Obs>()?;
    m.add_class::<stepwise::Simulation>()?;
    m.add_class::<vector::VecSimulation>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
