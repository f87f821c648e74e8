// PyO3 0.22's #[pyfunction] expansion trips clippy's useless_conversion on PyResult returns.
#![allow(clippy::useless_conversion)]

//! `exoleg._native`: the Rust side of the Python package. Every function releases the GIL
//! while it simulates, so Python threads run in parallel. The Python layer
//! (`pysrc/exoleg/__init__.py`) turns the results into dicts and numpy arrays.

use exoleg::study::{compare, robustness, shard, sweep};
use exoleg::{Error, Resources, Scenario};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::{Path, PathBuf};

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
    "A run diverged or became too stiff; the message names the state and the time."
);

fn py_err(e: Error) -> PyErr {
    let msg = e.to_string();
    match e {
        Error::Input { .. } | Error::Read { .. } => ScenarioError::new_err(msg),
        Error::Diverged { .. } | Error::Stiff { .. } => DivergedError::new_err(msg),
        _ => ExoError::new_err(msg),
    }
}

/// The scenario: a file path, TOML text, or the embedded default, with overrides.
fn load(path: Option<String>, toml_text: Option<String>, sets: &[String]) -> Result<Scenario, Error> {
    match (path, toml_text) {
        (Some(p), _) => Scenario::load(Some(Path::new(&p)), sets),
        (None, Some(t)) => Scenario::from_toml_str("<python scenario>", &t, sets),
        (None, None) => Scenario::load(None, sets),
    }
}

/// Run one scenario in memory. Returns (summary JSON, column names, values as little-endian
/// f64 bytes row after row, number of rows, the scenario as run in TOML).
#[pyfunction]
#[pyo3(signature = (path=None, toml_text=None, sets=Vec::new()))]
fn run(
    py: Python<'_>,
    path: Option<String>,
    toml_text: Option<String>,
    sets: Vec<String>,
) -> PyResult<(String, Vec<String>, PyObject, usize, String)> {
    let out = py.allow_threads(|| -> Result<_, Error> {
        let sc = load(path, toml_text, &sets)?.resolve(&Resources::new())?;
        let run = exoleg::study::run_to_memory(&sc)?;
        let toml = toml::to_string(&sc.file).map_err(|e| Error::input(&sc.source_name, "scenario", e.to_string()))?;
        Ok((run, toml))
    });
    let (run, toml) = out.map_err(py_err)?;
    let rows = if run.columns.is_empty() { 0 } else { run.values.len() / run.columns.len() };
    let bytes: Vec<u8> = run.values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let columns = run.columns.iter().map(|c| c.to_string()).collect();
    Ok((run.summary_json.to_string(), columns, PyBytes::new_bound(py, &bytes).into(), rows, toml))
}

/// A sweep or robustness study into the folder `out` (all runs, or one shard). Returns the
/// title line and `aggregate.csv`'s text.
#[pyfunction]
#[pyo3(signature = (kind, out, path=None, toml_text=None, sets=Vec::new(), grids=Vec::new(), monte_carlo=None, vary=Vec::new(), percent=20.0, samples=64, jobs=0, shard_k_n=None, plan_only=false))]
#[allow(clippy::too_many_arguments)]
fn study(
    py: Python<'_>,
    kind: String,
    out: String,
    path: Option<String>,
    toml_text: Option<String>,
    sets: Vec<String>,
    grids: Vec<String>,
    monte_carlo: Option<usize>,
    vary: Vec<String>,
    percent: f64,
    samples: usize,
    jobs: usize,
    shard_k_n: Option<(usize, usize)>,
    plan_only: bool,
) -> PyResult<(String, String)> {
    py.allow_threads(|| -> Result<(String, String), Error> {
        let base = load(path, toml_text, &sets)?;
        let (base_run, plan, kind) = match kind.as_str() {
            "sweep" => {
                let plan = sweep::plan_from_args(&base, &grids, monte_carlo, &vary)?;
                (base.clone(), plan, shard::StudyKind::Sweep)
            }
            "robustness" => {
                let (pinned, plan) = robustness::robustness_plan(&base, samples, percent)?;
                (pinned, plan, shard::StudyKind::Robustness { percent })
            }
            other => return Err(Error::input("exoleg.study", "kind", format!("`{other}`: sweep or robustness"))),
        };
        if plan_only {
            let mut buf = Vec::new();
            shard::write_plan(&plan, &mut buf)?;
            return Ok((String::new(), String::from_utf8_lossy(&buf).into_owned()));
        }
        if let Some((k, n)) = shard_k_n {
            shard::parse_shard(&format!("{k}/{n}"))?;
        }
        let opts = sweep::RunOptions { jobs, progress: false, shard: shard_k_n.unwrap_or((0, 1)), controller: None };
        let done = shard::run_study_into(
            &base_run,
            &base.source_name,
            &plan,
            &kind,
            &opts,
            shard_k_n.is_some(),
            false,
            Path::new(&out),
        )?;
        Ok((done.title, done.aggregate.csv()))
    })
    .map_err(py_err)
}

/// Merge shard folders into `out`. Returns the title line and `aggregate.csv`'s text.
#[pyfunction]
fn merge(py: Python<'_>, shards: Vec<String>, out: String) -> PyResult<(String, String)> {
    py.allow_threads(|| {
        let dirs: Vec<PathBuf> = shards.iter().map(PathBuf::from).collect();
        shard::merge(&dirs, Path::new(&out)).map(|m| (m.title, m.aggregate.csv()))
    })
    .map_err(py_err)
}

/// The paper's eight cases on a base scenario. Returns their results as JSON.
#[pyfunction]
#[pyo3(signature = (path=None, toml_text=None, sets=Vec::new()))]
fn compare_cases(
    py: Python<'_>,
    path: Option<String>,
    toml_text: Option<String>,
    sets: Vec<String>,
) -> PyResult<String> {
    py.allow_threads(|| -> Result<String, Error> {
        let base = load(path, toml_text, &sets)?;
        let results = compare::run_cases(&base, &[])?;
        serde_json::to_string(&results).map_err(|e| Error::input("compare", "results", e.to_string()))
    })
    .map_err(py_err)
}

/// The Python module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ExoError", m.py().get_type_bound::<ExoError>())?;
    m.add("ScenarioError", m.py().get_type_bound::<ScenarioError>())?;
    m.add("DivergedError", m.py().get_type_bound::<DivergedError>())?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(study, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(compare_cases, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
