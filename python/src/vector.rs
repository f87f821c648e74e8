//! N runs stepped together (`exoleg._native.VecSimulation`, under `exoleg.gym.ExolegVectorEnv`):
//! one call steps every run, on worker threads with the GIL released, each exactly as
//! `exoleg.Simulation` + `exoleg.gym.ExolegEnv` step one (the same calls into the core, the
//! same observation, reward and failure), with Gymnasium's next-step autoreset.
//!
//! The scenario is resolved once; the runs share its model (`Arc<Model>`), and an episode
//! with another seed gets a copy of it with that seed (as `exoleg.Simulation.reset` does).
//! Stepping allocates nothing in Rust: each run keeps its command, its results and its
//! readings in place, and the numpy arrays are made once the threads are done.

use crate::crew::Crew;
use crate::{load, py_err, ExoError, ScenarioError};
use exoleg::control::{ControlOutput, N_READINGS};
use exoleg::sim::{ControllerSource, Model, Simulation as CoreSimulation};
use exoleg::{Error, Resources};
use numpy::{PyArray1, PyArray2, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::sync::Arc;

/// Most runs one `VecSimulation` holds.
pub const MAX_ENVS: usize = 1024;

/// The reward of a step whose force error is not finite (a failed run): `ExolegEnv`'s.
const FAILED_REWARD: f64 = -1e12;

/// What a step's reward is (`ExolegEnv`'s `reward`).
#[derive(Clone, Copy, PartialEq)]
pub enum Reward {
    /// Minus the squared true force error (N^2).
    ForceError,
    /// Minus the wearer's gross metabolic rate over the last step (W/kg).
    MetabolicRate,
}

impl Reward {
    /// The reward named `name` (`"force_error"` or `"metabolic_rate"`).
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "force_error" => Some(Self::ForceError),
            "metabolic_rate" => Some(Self::MetabolicRate),
            _ => None,
        }
    }

    /// The reward of `sim` now (`FAILED_REWARD` when it is not finite or the run failed).
    fn of(self, sim: Option<&CoreSimulation>) -> f64 {
        let r = match self {
            Self::ForceError => {
                let e = sim.map_or(f64::NAN, |s| s.force_error_n());
                -(e * e)
            }
            Self::MetabolicRate => -sim.and_then(|s| s.gross_metabolic_w_per_kg()).unwrap_or(f64::NAN),
        };
        if r.is_finite() {
            r
        } else {
            FAILED_REWARD
        }
    }
}

/// One run of a [`VecSimulation`] with its episode's state, this call's input and its results.
struct Env {
    /// What its reward is.
    reward_kind: Reward,
    /// The scenario's model (its own seed), shared by every run.
    base: Arc<Model>,
    /// This episode's model (`base`, or a copy with the episode's seed).
    model: Arc<Model>,
    /// The run (None before the first reset and after a failure).
    sim: Option<CoreSimulation>,
    /// The run's logged channels are named (at its first step, as `exoleg.Simulation` does).
    named: bool,
    /// The episode ended (done or failed): the next step resets it and ignores its action.
    ended: bool,
    /// Simulated time (s) of the failure, after one.
    failed_t_s: f64,
    /// Input: this step's valve command.
    action: f64,
    /// Input: what this call does with it.
    work: Work,
    /// The readings of the last sample, as the observation (a non-finite reading is 0).
    obs: [f64; N_READINGS],
    /// Output: the step's reward (0 for a reset).
    reward: f64,
    /// Output: the episode ended at this step.
    terminated: bool,
    /// Output: simulated time (s) after the step (of the failure, after one).
    t_s: f64,
    /// Output: why the episode failed at this step (`info["failure"]`).
    failure: Option<String>,
    /// Output: an error this call raises (not a failure of the episode: a broken input).
    error: Option<Error>,
}

/// What a call does with a run.
#[derive(Clone, Copy)]
enum Work {
    /// Nothing (a reset of other runs).
    Idle,
    /// Start an episode with this seed (a reset, or an autoreset).
    Reset(u64),
    /// Step with its action.
    Step,
}

/// Why a step stopped its run.
enum Stop {
    /// The command is not finite (`ControllerError`'s message).
    Command(String),
    /// The core stopped it.
    Core(Error),
}

/// What ends an episode with `info["failure"]` (`ExolegEnv` catches these classes:
/// `DivergedError`, `ControllerError`); anything else is raised.
fn is_failure(e: &Error) -> bool {
    matches!(e, Error::Diverged { .. } | Error::Stiff { .. } | Error::ControllerStopped { .. })
}

impl Env {
    fn new(base: Arc<Model>, reward_kind: Reward) -> Self {
        Self {
            reward_kind,
            model: base.clone(),
            base,
            sim: None,
            named: false,
            ended: true,
            failed_t_s: 0.0,
            action: 0.0,
            work: Work::Idle,
            obs: [0.0; N_READINGS],
            reward: 0.0,
            terminated: false,
            t_s: 0.0,
            failure: None,
            error: None,
        }
    }

    /// Keep the readings of a sample as the observation (`ExolegEnv`: `nan_to_num` to 0).
    fn observe(&mut self, values: &[f64; N_READINGS]) {
        for (o, v) in self.obs.iter_mut().zip(values) {
            *o = if v.is_finite() { *v } else { 0.0 };
        }
    }

    /// This call's work.
    fn run(&mut self) {
        self.failure = None;
        self.error = None;
        match std::mem::replace(&mut self.work, Work::Idle) {
            Work::Reset(seed) => self.reset(seed),
            Work::Step if self.ended => {
                self.error = Some(Error::Usage("its episode ended: the step that resets it needs its seed".into()))
            }
            Work::Step => self.step(),
            Work::Idle => {}
        }
    }

    /// Start an episode with `seed` (`exoleg.Simulation.reset(seed)`): the first readings.
    fn reset(&mut self, seed: u64) {
        (self.sim, self.named, self.ended, self.reward, self.terminated) = (None, false, true, 0.0, false);
        if seed != self.model.seed {
            self.model = if seed == self.base.seed {
                self.base.clone()
            } else {
                Arc::new(Model { seed, ..(*self.base).clone() })
            };
        }
        let started = CoreSimulation::build(self.model.clone(), ControllerSource::External).and_then(|mut sim| {
            let s = sim.sample()?;
            Ok((sim, s.reading_values()))
        });
        match started {
            Ok((sim, values)) => {
                self.observe(&values);
                self.t_s = sim.t_s();
                self.sim = Some(sim);
                self.ended = false;
            }
            Err(e) => self.error = Some(e),
        }
    }

    /// Hold the action for one sample period (`exoleg.Simulation.step(command)`), then the
    /// observation, reward and end as `ExolegEnv.step` makes them.
    fn step(&mut self) {
        let Some(sim) = self.sim.as_mut() else { return };
        let u = self.action;
        let stepped = if u.is_finite() {
            Self::hold_and_read(sim, &mut self.named, u).map_err(Stop::Core)
        } else {
            Err(Stop::Command(format!(
                "step(): the valve command is {u}: the run stops here (finish() writes nothing; reset() starts again)"
            )))
        };
        match stepped {
            Ok(Some(values)) => self.observe(&values),
            Ok(None) => {}
            Err(stop) => {
                self.failed_t_s = sim.t_s();
                self.sim = None;
                match stop {
                    Stop::Command(m) => self.failure = Some(m),
                    Stop::Core(e) if is_failure(&e) => self.failure = Some(e.to_string()),
                    Stop::Core(e) => self.error = Some(e),
                }
            }
        }
        self.reward = self.reward_kind.of(self.sim.as_ref());
        self.t_s = self.sim.as_ref().map_or(self.failed_t_s, |s| s.t_s());
        self.terminated = self.sim.as_ref().is_none_or(|s| s.done());
        self.ended = self.terminated;
    }

    /// The core of a step: hold `u` to the next sample instant and read it (None at the end of
    /// the run: the last readings stay).
    fn hold_and_read(sim: &mut CoreSimulation, named: &mut bool, u: f64) -> Result<Option<[f64; N_READINGS]>, Error> {
        if !*named {
            sim.set_log_names(Vec::new())?;
            *named = true;
        }
        if sim.done() {
            return Err(Error::Usage("the run is done: reset it".into()));
        }
        sim.set_log(&[]);
        sim.hold(ControlOutput::command(u))?;
        sim.advance(&mut exoleg::record::NullSink)?;
        while !sim.done() && !sim.is_sample_step() {
            sim.advance(&mut exoleg::record::NullSink)?;
        }
        if sim.done() {
            return Ok(None);
        }
        Ok(Some(sim.sample()?.reading_values()))
    }
}

/// N runs of one scenario stepped together on worker threads (`exoleg.gym.ExolegVectorEnv`
/// wraps it). `reset(seeds, mask)` starts episodes; `step(actions, seeds)` steps every run
/// whose episode goes on and resets, with `seeds`, those whose episode ended at the last step
/// (their action is ignored: Gymnasium's next-step autoreset). Each run is exactly an
/// `exoleg.Simulation` stepped by `exoleg.gym.ExolegEnv`.
#[pyclass(module = "exoleg._native")]
pub struct VecSimulation {
    /// The runs, split across the threads (the calling thread's chunk first).
    crew: Crew<Env>,
    /// Number of runs.
    n: usize,
    /// The scenario's model.
    base: Arc<Model>,
}

/// New numpy arrays of one step: observations (N, n), times (N,, s), rewards (N,, N^2),
/// terminated (N,).
type Arrays<'py> =
    (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<bool>>);

impl VecSimulation {
    /// Run every run's work (`Env::run`), the GIL released, the runs split across the
    /// threads; then raise the first error.
    fn run_all(&mut self, py: Python<'_>) -> PyResult<()> {
        let crew = &self.crew;
        py.allow_threads(|| crew.run()).map_err(|m| ExoError::new_err(format!("internal error (a panic): {m}")))?;
        let mut first = None;
        self.crew.for_each(|i, e| {
            if let (None, Some(err)) = (&first, e.error.take()) {
                first = Some((i, err));
            }
        });
        match first {
            Some((i, e)) => {
                let e = py_err(e);
                Err(PyErr::from_type_bound(e.get_type_bound(py), format!("env {i}: {}", e.value_bound(py))))
            }
            None => Ok(()),
        }
    }

    /// Give each run its work: a reset with its seed in `seeds` (one a run) where `reset(i)`,
    /// else `otherwise`.
    fn set_work(
        &mut self,
        seeds: &PyReadonlyArray1<'_, u64>,
        reset: impl Fn(usize, &Env) -> bool,
        otherwise: Work,
    ) -> PyResult<()> {
        let s = seeds.as_array();
        if s.len() != self.n {
            return Err(PyValueError::new_err(format!("seeds: expected {} of them, got {}", self.n, s.len())));
        }
        self.crew.for_each(|i, e| e.work = if reset(i, e) { Work::Reset(s[i]) } else { otherwise });
        Ok(())
    }

    /// The runs' results as new numpy arrays, and `each(i, run)` called on every run.
    fn arrays<'py>(&self, py: Python<'py>, mut each: impl FnMut(usize, &mut Env)) -> PyResult<Arrays<'py>> {
        let obs = PyArray2::<f64>::zeros_bound(py, [self.n, N_READINGS], false);
        let t_s = PyArray1::<f64>::zeros_bound(py, self.n, false);
        let rewards = PyArray1::<f64>::zeros_bound(py, self.n, false);
        let terminated = PyArray1::<bool>::zeros_bound(py, self.n, false);
        // SAFETY: the arrays were just made, contiguous, and nothing else refers to them yet:
        // these are the only views of their data (no borrow tracking, which allocates).
        let (o, t, r, d) =
            unsafe { (obs.as_slice_mut()?, t_s.as_slice_mut()?, rewards.as_slice_mut()?, terminated.as_slice_mut()?) };
        self.crew.for_each(|i, e| {
            o[i * N_READINGS..(i + 1) * N_READINGS].copy_from_slice(&e.obs);
            (t[i], r[i], d[i]) = (e.t_s, e.reward, e.terminated);
            each(i, e);
        });
        Ok((obs, t_s, rewards, terminated))
    }
}

/// What `VecSimulation.reset` returns: observations (N, n), simulated times (N,, s).
type ResetOut<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// What `VecSimulation.step` returns: observations (N, n), rewards (N,), terminated (N,),
/// simulated times (N,, s), failures [(i, message)], and how many episodes ended.
type StepOut<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<f64>>,
    Vec<(usize, String)>,
    usize,
);

#[pymethods]
impl VecSimulation {
    /// `num_envs` runs (1..=1024) of the scenario on `threads` threads, the calling one
    /// included (0: one per core; at most one per run). Every run starts an episode with the
    /// scenario's own seed (as `exoleg.Simulation` does).
    #[new]
    #[allow(clippy::too_many_arguments)] // Python keywords
    #[pyo3(signature = (num_envs, threads=0, path=None, toml_text=None, scenario_json=None, overrides_json=None, reward="force_error"))]
    fn new(
        py: Python<'_>,
        num_envs: usize,
        threads: usize,
        path: Option<String>,
        toml_text: Option<String>,
        scenario_json: Option<String>,
        overrides_json: Option<String>,
        reward: &str,
    ) -> PyResult<Self> {
        if !(1..=MAX_ENVS).contains(&num_envs) {
            return Err(ScenarioError::new_err(format!("num_envs: {num_envs} is out of range (1..={MAX_ENVS})")));
        }
        let reward_kind = Reward::parse(reward).ok_or_else(|| {
            pyo3::exceptions::PyValueError::new_err(format!(
                "reward: {reward:?} is not a reward: \"force_error\" or \"metabolic_rate\""
            ))
        })?;
        let sc = py
            .allow_threads(|| load(path, toml_text, scenario_json, overrides_json)?.resolve(&Resources::new()))
            .map_err(py_err)?;
        if sc.model.sample_every.is_none() {
            return Err(ScenarioError::new_err(format!(
                "{}: controller.sample_period_s: a loop you own runs sampled: set it > 0 (e.g. 0.001)",
                sc.source_name
            )));
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = if threads == 0 { cores } else { threads };
        if reward_kind == Reward::MetabolicRate && sc.model.muscles.is_none() {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "reward: \"metabolic_rate\" needs the wearer's muscles: {} has none (set wearer.model = \"muscles\" or wearer.muscles = true)",
                sc.source_name
            )));
        }
        let base = sc.model.clone();
        let envs = (0..num_envs)
            .map(|_| Env { work: Work::Reset(base.seed), ..Env::new(base.clone(), reward_kind) })
            .collect();
        let crew =
            Crew::new(envs, threads, Env::run).map_err(|e| ExoError::new_err(format!("the worker threads: {e}")))?;
        let mut v = Self { crew, n: num_envs, base };
        crate::guard(|| v.run_all(py))?;
        Ok(v)
    }

    /// Number of runs.
    #[getter]
    fn num_envs(&self) -> usize {
        self.n
    }

    /// Threads stepping them, the calling one included.
    #[getter]
    fn threads(&self) -> usize {
        self.crew.threads()
    }

    /// What the controller is told (sample period, valve limit, nominal model), as JSON.
    #[getter]
    fn info_json(&self) -> String {
        crate::stepwise::info_json(&self.base).to_string()
    }

    /// The runs whose episode ended (the next step resets them).
    fn ended(&self) -> Vec<usize> {
        let mut out = Vec::new();
        self.crew.for_each(|i, e| {
            if e.ended {
                out.push(i)
            }
        });
        out
    }

    /// Start a new episode of every run (of those where `mask` is true) with its seed in
    /// `seeds` (uint64, one a run); returns the observations of every run (N, n) and their
    /// simulated times (N,, s).
    #[pyo3(signature = (seeds, mask=None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seeds: PyReadonlyArray1<'py, u64>,
        mask: Option<PyReadonlyArray1<'py, bool>>,
    ) -> PyResult<ResetOut<'py>> {
        let mask = mask.map(|m| m.as_array().to_vec());
        if mask.as_ref().is_some_and(|m| m.len() != self.n) {
            return Err(PyValueError::new_err(format!("mask: expected {} flags", self.n)));
        }
        self.set_work(&seeds, |i, _| mask.as_ref().is_none_or(|m| m[i]), Work::Idle)?;
        crate::guard(|| self.run_all(py))?;
        let (obs, t_s, _, _) = self.arrays(py, |_, _| {})?;
        Ok((obs, t_s))
    }

    /// Hold each run's action (`actions`: float64, shape (N, 1) or (N,), the valve commands)
    /// for one sample period, and reset with its seed in `seeds` (uint64, one a run; needed
    /// when an episode ended at the last step) each run whose episode ended. Returns the
    /// observations (N, n), rewards (N,, N^2), terminated (N,), simulated times (N,, s), the
    /// failures of this step [(i, message)] and how many episodes ended.
    #[pyo3(signature = (actions, seeds=None))]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: &Bound<'py, PyArrayDyn<f64>>,
        seeds: Option<PyReadonlyArray1<'py, u64>>,
    ) -> PyResult<StepOut<'py>> {
        let n = self.n;
        let shape = actions.shape();
        if !(shape == [n] || shape == [n, 1]) {
            return Err(PyValueError::new_err(format!(
                "actions: expected one valve command per environment (shape ({n}, 1) or ({n},)), got shape {shape:?}"
            )));
        }
        // SAFETY: read at once with the GIL held and no Python code running: nothing writes
        // to the array meanwhile (a view without borrow tracking, which allocates).
        let a = unsafe { actions.as_array() };
        let mut next = a.iter();
        self.crew.for_each(|_, e| e.action = next.next().copied().unwrap_or(f64::NAN));
        match &seeds {
            Some(s) => self.set_work(s, |_, e| e.ended, Work::Step)?,
            None => self.crew.for_each(|_, e| e.work = Work::Step),
        }
        crate::guard(|| self.run_all(py))?;
        let (mut failures, mut ended) = (Vec::new(), 0);
        let (obs, t_s, rewards, terminated) = self.arrays(py, |i, e| {
            ended += usize::from(e.terminated);
            if let Some(f) = e.failure.take() {
                failures.push((i, f));
            }
        })?;
        Ok((obs, rewards, terminated, t_s, failures, ended))
    }
}
