//! Parameter sweeps (grid or Monte Carlo), run in parallel.
//!
//! Every run is the base scenario with `--set` overrides. A [`Plan`] expands its runs lazily
//! (run `i`'s overrides are computed when asked for), so its size costs no memory. Random
//! draws come from a ChaCha stream seeded by (sweep seed, run index), and results are
//! written in run order, so the output is the same whatever the number of threads. Timing
//! figures (wall time, steps/s) are left out of the per-run lines for the same reason.
//! Before anything runs, every run's scenario is resolved and validated (files parsed once).

use crate::error::{Error, Result};
use crate::metrics::{check_criteria, CriterionResult, Metric, Summary};
use crate::scenario::{Resources, Scenario};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Most runs a sweep, grid or robustness report may have (`--monte-carlo`, `--samples`, the
/// product of the `--grid` axes).
pub const MAX_RUNS: usize = 1_000_000;
/// Most worker threads (`--jobs` is clamped to this and to the number of runs).
pub const MAX_JOBS: usize = 256;
/// Runs handed to the workers at a time (results are written in order after each chunk).
const CHUNK: usize = 256;

/// A distribution for a Monte-Carlo parameter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Dist {
    /// Uniform in [lo, hi].
    Uniform(f64, f64),
    /// Normal with mean and standard deviation.
    Normal(f64, f64),
    /// Uniform within +-p % of the base scenario's value.
    Pct(f64),
}

/// Parse `key=uniform(a,b)`, `key=normal(mu,sd)` or `key=pct(p)`.
pub fn parse_vary(s: &str) -> Result<(String, Dist)> {
    let bad = |m: &str| Error::input("--vary", s, m);
    let (key, d) = s.split_once('=').ok_or_else(|| bad("expected key=dist(...), e.g. hydraulics.beta_pa=pct(20)"))?;
    let d = d.trim();
    let (name, args) = d.strip_suffix(')').and_then(|d| d.split_once('(')).ok_or_else(|| bad("expected dist(args)"))?;
    let nums: Vec<f64> = args
        .split(',')
        .map(|a| a.trim().parse::<f64>().map_err(|_| bad(&format!("not a number: {a:?}"))))
        .collect::<Result<_>>()?;
    if nums.iter().any(|x| !x.is_finite()) {
        return Err(bad("arguments must be finite"));
    }
    let dist = match (name.trim(), nums.as_slice()) {
        ("uniform", [a, b]) if a <= b => Dist::Uniform(*a, *b),
        ("normal", [m, sd]) if *sd >= 0.0 => Dist::Normal(*m, *sd),
        ("pct", [p]) if *p >= 0.0 => Dist::Pct(*p),
        _ => return Err(bad("use uniform(lo,hi) with lo <= hi, normal(mean,sd) with sd >= 0, or pct(p) with p >= 0")),
    };
    let key = key.trim();
    if key.is_empty() {
        return Err(bad("empty key"));
    }
    Ok((key.to_string(), dist))
}

/// Parse `key=v1,v2,...` (values as TOML).
pub fn parse_grid(s: &str) -> Result<(String, Vec<String>)> {
    let (key, vals) = s.split_once('=').ok_or_else(|| Error::input("--grid", s, "expected key=v1,v2,..."))?;
    let vals: Vec<String> = vals.split(',').map(|v| v.trim().to_string()).filter(|v| !v.is_empty()).collect();
    if vals.is_empty() || key.trim().is_empty() {
        return Err(Error::input("--grid", s, "expected key=v1,v2,... with at least one value"));
    }
    Ok((key.trim().to_string(), vals))
}

/// The numeric value of a dotted key in a scenario, and whether it is an integer.
pub fn value_at(s: &Scenario, key: &str) -> Result<(f64, bool)> {
    let v = toml::Value::try_from(&s.file).map_err(|e| Error::input(&s.source_name, key, e.to_string()))?;
    let mut cur = &v;
    for part in key.split('.') {
        // An array of tables (`[[faults]]`) is indexed by number (`faults.0.onset_s`).
        let next = match (cur, part.parse::<usize>()) {
            (toml::Value::Array(a), Ok(i)) => a.get(i),
            _ => cur.get(part),
        };
        cur = next.ok_or_else(|| Error::input(&s.source_name, key, "no such key (or it has no value to vary)"))?;
    }
    match cur {
        toml::Value::Float(x) => Ok((*x, false)),
        toml::Value::Integer(i) => Ok((*i as f64, true)),
        _ => Err(Error::input(&s.source_name, key, "not a number")),
    }
}

/// One randomly varied parameter of a Monte-Carlo plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Varied {
    /// Dotted key.
    pub key: String,
    /// Distribution.
    pub dist: Dist,
    /// The base scenario's value.
    pub base: f64,
    /// The key holds an integer: draws are rounded.
    pub integer: bool,
    /// Keys that scale with this one (same ratio to their base value), to keep the model's
    /// relations (static friction moves with Coulomb friction): (key, base value).
    pub followers: Vec<(String, f64)>,
}

/// The runs of a sweep, expanded lazily.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Plan {
    /// Full factorial, first axis varying slowest.
    Grid(Vec<(String, Vec<String>)>),
    /// Runs listed one by one, each with its overrides (a fault campaign's).
    Runs(Vec<Vec<String>>),
    /// `n` random draws.
    MonteCarlo {
        /// Number of runs.
        n: usize,
        /// The parameters.
        vary: Vec<Varied>,
        /// Sweep seed.
        seed: u64,
    },
}

fn fmt_value(x: f64, integer: bool) -> String {
    if integer {
        format!("{}", x.round() as i64)
    } else {
        format!("{x:?}")
    }
}

impl Plan {
    /// A grid plan; a key given twice, or more than [`MAX_RUNS`] runs, is an error.
    pub fn grid(axes: Vec<(String, Vec<String>)>) -> Result<Plan> {
        for (i, (k, _)) in axes.iter().enumerate() {
            if axes[..i].iter().any(|(k2, _)| k2 == k) {
                return Err(Error::input("--grid", k.as_str(), "given twice: put all its values in one --grid"));
            }
        }
        let n = axes.iter().try_fold(1usize, |a, (_, v)| a.checked_mul(v.len()));
        match n {
            Some(n) if n <= MAX_RUNS => Ok(Plan::Grid(axes)),
            _ => Err(Error::input("--grid", "", format!("the grid has more than {MAX_RUNS} runs (the cap)"))),
        }
    }

    /// A Monte-Carlo plan of `n` runs varying `vary` around `base`.
    pub fn monte_carlo(base: &Scenario, n: usize, vary: &[(String, Dist)], seed: u64) -> Result<Plan> {
        if n == 0 || n > MAX_RUNS {
            return Err(Error::input("--monte-carlo", n.to_string(), format!("must be 1..={MAX_RUNS} runs")));
        }
        let mut out: Vec<Varied> = Vec::new();
        for (key, dist) in vary {
            if out.iter().any(|v| &v.key == key) {
                return Err(Error::input("--vary", key.as_str(), "given twice"));
            }
            let (base, integer) = value_at(base, key)?;
            out.push(Varied { key: key.clone(), dist: *dist, base, integer, followers: Vec::new() });
        }
        Ok(Plan::MonteCarlo { n, vary: out, seed })
    }

    /// Number of runs.
    pub fn len(&self) -> usize {
        match self {
            Plan::Grid(axes) => axes.iter().try_fold(1usize, |a, (_, v)| a.checked_mul(v.len())).unwrap_or(usize::MAX),
            Plan::Runs(runs) => runs.len(),
            Plan::MonteCarlo { n, .. } => *n,
        }
    }

    /// Check a plan read from a file (a shard's `shard.json`): at most [`MAX_RUNS`] runs, no
    /// empty grid axis, finite distributions.
    pub fn check(&self) -> std::result::Result<(), String> {
        if self.len() > MAX_RUNS {
            return Err(format!("more than {MAX_RUNS} runs"));
        }
        match self {
            Plan::Grid(axes) if axes.iter().any(|(_, v)| v.is_empty()) => Err("an empty grid axis".into()),
            Plan::MonteCarlo { vary, .. } => {
                let finite = |d: &Dist| match d {
                    Dist::Uniform(a, b) | Dist::Normal(a, b) => a.is_finite() && b.is_finite(),
                    Dist::Pct(p) => p.is_finite(),
                };
                let ok = vary
                    .iter()
                    .all(|v| finite(&v.dist) && v.base.is_finite() && v.followers.iter().all(|f| f.1.is_finite()));
                if ok {
                    Ok(())
                } else {
                    Err("a distribution or base value is not finite".into())
                }
            }
            Plan::Grid(_) | Plan::Runs(_) => Ok(()),
        }
    }

    /// True when the plan has no runs.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `--set` overrides of run `i`.
    pub fn sets(&self, i: usize) -> Vec<String> {
        match self {
            Plan::Grid(axes) => {
                let mut rest = i;
                let mut out = vec![String::new(); axes.len()];
                for (j, (k, vals)) in axes.iter().enumerate().rev() {
                    out[j] = format!("{k}={}", vals[rest % vals.len()]);
                    rest /= vals.len();
                }
                out
            }
            Plan::Runs(runs) => runs.get(i).cloned().unwrap_or_default(),
            Plan::MonteCarlo { vary, seed, .. } => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_0000_0000);
                rng.set_stream(i as u64);
                let mut out = Vec::new();
                for v in vary {
                    let x = match v.dist {
                        Dist::Uniform(lo, hi) => lo + (hi - lo) * rng.random::<f64>(),
                        Dist::Normal(m, sd) => Normal::new(m, sd).map(|n| n.sample(&mut rng)).unwrap_or(m),
                        Dist::Pct(p) => v.base * (1.0 + p / 100.0 * (2.0 * rng.random::<f64>() - 1.0)),
                    };
                    out.push(format!("{}={}", v.key, fmt_value(x, v.integer)));
                    for (fk, fb) in &v.followers {
                        let ratio = if v.base != 0.0 { x / v.base } else { 1.0 };
                        out.push(format!("{fk}={:?}", fb * ratio));
                    }
                }
                out
            }
        }
    }
}

/// The plan of `exoleg sweep`: a Monte-Carlo sample (`monte_carlo` runs of the `vary`
/// distributions, seeded by the scenario's seed) or the full grid of `grids`.
pub fn plan_from_args(base: &Scenario, grids: &[String], monte_carlo: Option<usize>, vary: &[String]) -> Result<Plan> {
    if let Some(n) = monte_carlo {
        let vary: Vec<(String, Dist)> = vary.iter().map(|v| parse_vary(v)).collect::<Result<_>>()?;
        Plan::monte_carlo(base, n, &vary, base.file.seed)
    } else if !grids.is_empty() {
        Plan::grid(grids.iter().map(|g| parse_grid(g)).collect::<Result<_>>()?)
    } else {
        Err(Error::input("sweep", "", "give --grid key=v1,v2,... or --monte-carlo N --vary key=dist(...)"))
    }
}

/// One run's line of `runs.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunLine {
    /// Run number, from 0 (the global index in a sharded sweep).
    pub index: usize,
    /// The overrides of this run (resolved values).
    pub sets: Vec<String>,
    /// The summary figures (timing left out), or null if the run failed.
    #[serde(serialize_with = "summary_without_timing")]
    pub summary: Option<Summary>,
    /// Criteria checks of the scenario, if it has any.
    pub criteria: Vec<CriterionResult>,
    /// All criteria passed (true when there are none), the run completed and its controller
    /// did not crash.
    pub passed: bool,
    /// Why the run failed (divergence), if it did.
    pub error: Option<String>,
}

fn summary_without_timing<S: serde::Serializer>(s: &Option<Summary>, ser: S) -> std::result::Result<S::Ok, S::Error> {
    let mut v = serde_json::to_value(s).map_err(serde::ser::Error::custom)?;
    if let Some(o) = v.as_object_mut() {
        o.remove("wall_time_s");
        o.remove("steps_per_second");
        o.remove("controller_compute");
        o.remove("controller_link");
    }
    v.serialize(ser)
}

/// Makes the controller of each run of a study from the run's resolved scenario (the caller's
/// controller in a sweep: one instance per run).
pub type ControllerFactory =
    dyn Fn(&crate::scenario::ResolvedScenario) -> Result<Box<dyn crate::control::DiscreteController>> + Send + Sync;

/// How to run a plan.
#[derive(Clone, Default)]
pub struct RunOptions {
    /// Worker threads (0 = all cores); clamped to [`MAX_JOBS`] and the number of runs.
    pub jobs: usize,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// Only the runs with index % of.1 == of.0 (a shard); (0, 1) = all.
    pub shard: (usize, usize),
    /// The caller's controller for every run (None: each run's `controller.kind`).
    pub controller: Option<std::sync::Arc<ControllerFactory>>,
    /// Set by the caller to stop the study (its runs check it as they go).
    pub cancel: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// Keep the finished runs of an interrupted study of the same plan into the same folder
    /// and make only the missing ones (`--resume`).
    pub resume: bool,
}

/// The number of worker threads for `runs` runs.
pub fn clamp_jobs(jobs: usize, runs: usize) -> usize {
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let j = if jobs == 0 { all } else { jobs };
    j.clamp(1, MAX_JOBS).min(runs.max(1))
}

/// Indices of the runs a shard owns, in order.
fn shard_indices(n: usize, shard: (usize, usize)) -> impl Iterator<Item = usize> + Clone {
    let (k, of) = (shard.0, shard.1.max(1));
    (k..n).step_by(of)
}

/// Resolve every run of the plan (in parallel, files parsed once): bad input fails here,
/// before anything runs.
pub fn validate_plan(base: &Scenario, plan: &Plan, res: &Resources, opts: &RunOptions) -> Result<()> {
    use rayon::prelude::*;
    let idx: Vec<usize> = shard_indices(plan.len(), opts.shard).collect();
    let pool = pool(opts.jobs, idx.len())?;
    pool.install(|| {
        idx.par_chunks(CHUNK).try_for_each(|chunk| {
            chunk.iter().try_for_each(|&i| {
                base.with_sets(&plan.sets(i)).and_then(|s| s.resolve(res)).map(|_| ()).map_err(|e| e.in_run(i))
            })
        })
    })
}

/// A thread pool of [`clamp_jobs`] workers.
pub(crate) fn pool(jobs: usize, runs: usize) -> Result<rayon::ThreadPool> {
    let n = clamp_jobs(jobs, runs);
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| Error::input("--jobs", n.to_string(), e.to_string()))
}

/// Run one resolved run (its outputs into `run_dir/run_NNNN` when asked).
fn simulate(
    sc: &crate::scenario::ResolvedScenario,
    i: usize,
    opts: &RunOptions,
    run_dir: Option<&Path>,
) -> Result<Summary> {
    let source = match &opts.controller {
        Some(f) => crate::sim::ControllerSource::Discrete(f(sc)?),
        None => crate::sim::ControllerSource::Model,
    };
    match run_dir {
        Some(dir) => {
            let d = dir.join(format!("run_{i:04}"));
            std::fs::create_dir_all(&d).map_err(|e| Error::Write { path: d.clone(), message: e.to_string() })?;
            super::run_into_with(sc, source, &d, &sc.source_name, None).map(|r| r.summary)
        }
        None => {
            let sim = crate::sim::Simulation::build(sc.model.clone(), source)?;
            crate::session::run_cancellable(sim, &mut crate::record::NullSink, opts.cancel.clone()).map(|r| r.0)
        }
    }
}

/// Run one planned run. A run that fails for any reason (divergence, a controller that stops
/// it, an error writing its own outputs, even a panic) is a failed line with its message; the
/// others go on. Only bad input (caught before anything runs) stops a sweep.
fn run_one(
    base: &Scenario,
    plan: &Plan,
    i: usize,
    res: &Resources,
    opts: &RunOptions,
    run_dir: Option<&Path>,
) -> Result<RunLine> {
    if opts.cancel.as_ref().is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed)) {
        return Err(Error::Interrupted);
    }
    let sets = plan.sets(i);
    let sc = base.with_sets(&sets)?.resolve(res)?;
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| simulate(&sc, i, opts, run_dir)))
        .unwrap_or_else(|p| Err(Error::Usage(format!("internal error (a panic): {}", panic_message(&p)))));
    // A run stopped because the study is being stopped is no finished run: it has no line.
    if opts.cancel.as_ref().is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed)) && result.is_err() {
        return Err(Error::Interrupted);
    }
    Ok(match result {
        Err(Error::Interrupted) => return Err(Error::Interrupted),
        Ok(summary) => {
            let criteria = check_criteria(&sc.file.criteria, &summary);
            RunLine { index: i, sets, passed: summary.passes(&criteria), criteria, summary: Some(summary), error: None }
        }
        Err(e) => {
            RunLine { index: i, sets, summary: None, criteria: Vec::new(), passed: false, error: Some(e.to_string()) }
        }
    })
}

/// The text of a caught panic.
pub fn panic_message(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into())
}

/// Aggregated figures of a sweep, gathered line by line.
#[derive(Debug, Clone, Default)]
pub struct Aggregate {
    values: Vec<Vec<f64>>,
    /// Runs that failed (diverged, stopped by their controller, or any other run error).
    pub failed: usize,
    /// Runs that passed their criteria.
    pub passed: usize,
    /// Runs seen.
    pub runs: usize,
}

impl Aggregate {
    /// Take one line into account.
    pub fn add(&mut self, l: &RunLine) {
        if self.values.is_empty() {
            self.values = vec![Vec::new(); Metric::AGGREGATED.len()];
        }
        self.runs += 1;
        self.failed += usize::from(l.error.is_some());
        self.passed += usize::from(l.passed);
        if let Some(s) = &l.summary {
            for (v, m) in self.values.iter_mut().zip(Metric::AGGREGATED) {
                if let Some(x) = m.value(s) {
                    v.push(x);
                }
            }
        }
    }

    /// The values of one metric over the completed runs.
    pub fn values(&self, m: Metric) -> &[f64] {
        let i = Metric::AGGREGATED.iter().position(|x| *x == m).unwrap_or(0);
        self.values.get(i).map_or(&[], |v| v.as_slice())
    }

    /// `aggregate.csv` text: min/median/max per metric over the completed runs.
    pub fn csv(&self) -> String {
        let mut s = String::from("metric,runs,min,median,max\n");
        for (i, m) in Metric::AGGREGATED.iter().enumerate() {
            let Some(v) = self.values.get(i).filter(|v| !v.is_empty()) else { continue };
            let mut v = v.clone();
            v.sort_by(|a, b| a.total_cmp(b));
            let n = v.len();
            let med = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
            s.push_str(&format!("{},{n},{},{med},{}\n", m.name(), v[0], v[n - 1]));
        }
        s.push_str(&format!("failed_runs,{},,,\n", self.failed));
        s
    }
}

/// Run the plan (or this shard of it) with `opts`, leaving out the runs `skip` names (a
/// resumed study's finished runs); each run's line goes to `on_line` as soon as the run ends
/// (from the worker thread that ran it, so in the order the runs finish). `run_dir`: also
/// write every run's outputs to `run_dir/run_NNNN`. Returns the number of runs made.
pub fn run_plan(
    base: &Scenario,
    plan: &Plan,
    res: &Resources,
    opts: &RunOptions,
    run_dir: Option<&Path>,
    skip: &(dyn Fn(usize) -> bool + Sync),
    on_line: &(dyn Fn(&RunLine) -> Result<()> + Sync),
) -> Result<usize> {
    use rayon::prelude::*;
    let idx: Vec<usize> = shard_indices(plan.len(), opts.shard).filter(|&i| !skip(i)).collect();
    let pool = pool(opts.jobs, idx.len())?;
    let bar = progress_bar(opts.progress && idx.len() > 1, idx.len());
    for chunk in idx.chunks(CHUNK) {
        if opts.cancel.as_ref().is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed)) {
            return Err(Error::Interrupted);
        }
        pool.install(|| {
            chunk.par_iter().try_for_each(|&i| {
                let l = run_one(base, plan, i, res, opts, run_dir)?;
                on_line(&l)?;
                bar.inc(1);
                Ok(())
            })
        })?;
    }
    bar.finish_and_clear();
    Ok(idx.len())
}

/// A progress bar over `n` runs on stderr (hidden unless `show`).
pub(crate) fn progress_bar(show: bool, n: usize) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new(n as u64);
    b.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} runs  {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsing_and_grids() {
        assert_eq!(parse_vary("a.b=pct(20)").unwrap(), ("a.b".into(), Dist::Pct(20.0)));
        assert_eq!(parse_vary("a=uniform(1, 2)").unwrap().1, Dist::Uniform(1.0, 2.0));
        assert!(parse_vary("a=uniform(2,1)").is_err());
        assert!(parse_vary("a=gauss(1)").is_err());
        let g = Plan::grid(vec![
            ("x".into(), vec!["1".into(), "2".into()]),
            ("y".into(), vec!["3".into(), "4".into(), "5".into()]),
        ])
        .unwrap();
        assert_eq!(g.len(), 6);
        assert_eq!(g.sets(0), vec!["x=1".to_string(), "y=3".to_string()]);
        assert_eq!(g.sets(5), vec!["x=2".to_string(), "y=5".to_string()]);
        let twice = Plan::grid(vec![("x".into(), vec!["1".into()]), ("x".into(), vec!["2".into()])]);
        assert!(twice.unwrap_err().to_string().contains("given twice"));
        let big: Vec<(String, Vec<String>)> = (0..7).map(|i| (format!("k{i}"), vec!["1".to_string(); 10])).collect();
        assert!(Plan::grid(big).unwrap_err().to_string().contains("1000000"));
    }

    #[test]
    fn monte_carlo_draws_are_per_run_and_within_range() {
        let s = Scenario::load(None, &[]).unwrap();
        let vary = [("hydraulics.beta_pa".to_string(), Dist::Pct(20.0))];
        let runs = Plan::monte_carlo(&s, 50, &vary, 7).unwrap();
        let again = Plan::monte_carlo(&s, 50, &vary, 7).unwrap();
        assert_eq!(
            (0..50).map(|i| runs.sets(i)).collect::<Vec<_>>(),
            (0..50).map(|i| again.sets(i)).collect::<Vec<_>>()
        );
        let vals: Vec<f64> = (0..50).map(|i| runs.sets(i)[0].split('=').nth(1).unwrap().parse().unwrap()).collect();
        assert!(vals.iter().all(|v| (v / 1.517e9 - 1.0).abs() <= 0.2 + 1e-12));
        assert!(vals.iter().any(|v| *v > 1.6e9) && vals.iter().any(|v| *v < 1.4e9));
        // Integer keys get integer draws.
        let int = Plan::monte_carlo(&s, 20, &[("leg.solver_iterations".into(), Dist::Pct(60.0))], 1).unwrap();
        for i in 0..20 {
            let v = int.sets(i)[0].split('=').nth(1).unwrap().to_string();
            assert!(v.parse::<i64>().is_ok(), "{v}");
        }
        assert!(Plan::monte_carlo(&s, MAX_RUNS + 1, &vary, 1).is_err());
    }
}
