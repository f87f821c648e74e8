//! Parameter sweeps (grid or Monte Carlo) and the robustness report, run in parallel.
//!
//! Every run is a scenario with `--set` overrides. Random draws come from a ChaCha stream
//! seeded by (sweep seed, run index), and results are collected in run order, so the output
//! is the same whatever the number of threads. Timing figures (wall time, steps/s) are left
//! out of the per-run lines for the same reason.

use crate::error::{Error, Result};
use crate::metrics::{self, CriterionResult, Summary};
use crate::scenario::Scenario;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::path::Path;

/// A distribution for a Monte-Carlo parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
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
    Ok((key.trim().to_string(), dist))
}

/// Parse `key=v1,v2,...` (values as TOML).
pub fn parse_grid(s: &str) -> Result<(String, Vec<String>)> {
    let (key, vals) = s.split_once('=').ok_or_else(|| Error::input("--grid", s, "expected key=v1,v2,..."))?;
    let vals: Vec<String> = vals.split(',').map(|v| v.trim().to_string()).filter(|v| !v.is_empty()).collect();
    if vals.is_empty() {
        return Err(Error::input("--grid", s, "no values"));
    }
    Ok((key.trim().to_string(), vals))
}

/// The `--set` lists of a full factorial grid, first key varying slowest.
pub fn grid_runs(grids: &[(String, Vec<String>)]) -> Vec<Vec<String>> {
    grids.iter().fold(vec![Vec::new()], |acc, (k, vals)| {
        acc.iter()
            .flat_map(|sets| vals.iter().map(move |v| [sets.clone(), vec![format!("{k}={v}")]].concat()))
            .collect()
    })
}

/// The numeric value of a dotted key in a scenario.
pub fn value_at(s: &Scenario, key: &str) -> Result<f64> {
    let v = toml::Value::try_from(&s.file).map_err(|e| Error::input(&s.source_name, key, e.to_string()))?;
    let mut cur = &v;
    for part in key.split('.') {
        cur = cur
            .get(part)
            .ok_or_else(|| Error::input(&s.source_name, key, "no such key (or it has no value to vary)"))?;
    }
    match cur {
        toml::Value::Float(x) => Ok(*x),
        toml::Value::Integer(i) => Ok(*i as f64),
        _ => Err(Error::input(&s.source_name, key, "not a number")),
    }
}

/// The `--set` lists of `n` Monte-Carlo runs.
pub fn monte_carlo_runs(base: &Scenario, n: usize, vary: &[(String, Dist)], seed: u64) -> Result<Vec<Vec<String>>> {
    let bases: Vec<f64> = vary
        .iter()
        .map(|(k, d)| match d {
            Dist::Pct(_) => value_at(base, k),
            _ => Ok(0.0),
        })
        .collect::<Result<_>>()?;
    Ok((0..n)
        .map(|i| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_0000_0000).clone();
            rng.set_stream(i as u64);
            vary.iter()
                .zip(&bases)
                .map(|((k, d), b)| {
                    let x = match *d {
                        Dist::Uniform(lo, hi) => lo + (hi - lo) * rng.random::<f64>(),
                        Dist::Normal(m, sd) => Normal::new(m, sd).map(|n| n.sample(&mut rng)).unwrap_or(m),
                        Dist::Pct(p) => b * (1.0 + p / 100.0 * (2.0 * rng.random::<f64>() - 1.0)),
                    };
                    format!("{k}={x:?}")
                })
                .collect()
        })
        .collect())
}

/// One run's line of `runs.jsonl`.
#[derive(Debug, Clone, Serialize)]
pub struct RunLine {
    /// Run number, from 0.
    pub index: usize,
    /// The overrides of this run (resolved values).
    pub sets: Vec<String>,
    /// The summary figures (timing removed), or null if the run failed.
    pub summary: Option<serde_json::Value>,
    /// Criteria checks of the scenario, if it has any.
    pub criteria: Vec<CriterionResult>,
    /// All criteria passed (true when there are none) and the run completed.
    pub passed: bool,
    /// Why the run failed (divergence), if it did.
    pub error: Option<String>,
}

fn summary_value(s: &Summary) -> serde_json::Value {
    let mut v = serde_json::to_value(s).unwrap_or_default();
    if let Some(o) = v.as_object_mut() {
        o.remove("wall_time_s");
        o.remove("steps_per_second");
        o.remove("scenario");
    }
    v
}

/// Run all `runs` on top of `base` with `jobs` threads (0 = all cores). `progress`: show a
/// progress bar on stderr. `run_dir`: also write each run's outputs to `run_dir/run_NNNN`.
pub fn run_all(
    base: &Scenario,
    runs: &[Vec<String>],
    jobs: usize,
    progress: bool,
    run_dir: Option<&Path>,
) -> Result<Vec<RunLine>> {
    use rayon::prelude::*;
    // Validate every run's scenario first, so bad input fails before anything runs.
    let scenarios: Vec<Scenario> = runs.iter().map(|sets| base.with_sets(sets)).collect::<Result<_>>()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| Error::input("--jobs", jobs.to_string(), e.to_string()))?;
    let bar = if progress {
        let b = indicatif::ProgressBar::new(runs.len() as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} runs  {elapsed_precise} (eta {eta})")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    let lines = pool.install(|| {
        scenarios
            .par_iter()
            .enumerate()
            .map(|(i, s)| {
                let line = match crate::sim::run(s) {
                    Ok(out) => {
                        let criteria = metrics::check_criteria(&s.file.criteria, &out.summary);
                        if let Some(dir) = run_dir {
                            let json = serde_json::to_value(&out.summary).unwrap_or_default();
                            crate::output::write_run(
                                &dir.join(format!("run_{i:04}")),
                                &out.record,
                                &json,
                                &s.source_name,
                            )?;
                        }
                        RunLine {
                            index: i,
                            sets: runs[i].clone(),
                            summary: Some(summary_value(&out.summary)),
                            passed: criteria.iter().all(|c| c.pass),
                            criteria,
                            error: None,
                        }
                    }
                    Err(e @ Error::Diverged { .. }) => RunLine {
                        index: i,
                        sets: runs[i].clone(),
                        summary: None,
                        criteria: Vec::new(),
                        passed: false,
                        error: Some(e.to_string()),
                    },
                    Err(e) => return Err(e),
                };
                bar.inc(1);
                Ok(line)
            })
            .collect::<Result<Vec<_>>>()
    })?;
    bar.finish_and_clear();
    Ok(lines)
}

/// The metrics aggregated over a sweep.
pub const AGGREGATED: [&str; 8] = [
    "max_abs_force_error_n",
    "rms_force_error_n",
    "max_abs_force_error_after_settle_n",
    "rms_force_error_after_settle_n",
    "knee_rms_error_deg",
    "knee_max_abs_error_deg",
    "valve_saturation_fraction",
    "peak_cylinder_force_n",
];

/// (metric, n, min, median, max) over the runs that completed.
pub fn aggregate(lines: &[RunLine]) -> Vec<(String, usize, f64, f64, f64)> {
    AGGREGATED
        .iter()
        .filter_map(|m| {
            let mut v: Vec<f64> = lines
                .iter()
                .filter_map(|l| l.summary.as_ref().and_then(|s| s.get(*m)).and_then(|x| x.as_f64()))
                .collect();
            if v.is_empty() {
                return None;
            }
            v.sort_by(|a, b| a.total_cmp(b));
            let n = v.len();
            let med = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
            Some((m.to_string(), n, v[0], med, v[n - 1]))
        })
        .collect()
}

/// `runs.jsonl` text.
pub fn jsonl(lines: &[RunLine]) -> String {
    lines.iter().map(|l| serde_json::to_string(l).unwrap_or_default() + "\n").collect()
}

/// `aggregate.csv` text.
pub fn aggregate_csv(agg: &[(String, usize, f64, f64, f64)], failed: usize) -> String {
    let mut s = String::from("metric,runs,min,median,max\n");
    for (m, n, lo, med, hi) in agg {
        s.push_str(&format!("{m},{n},{lo},{med},{hi}\n"));
    }
    s.push_str(&format!("diverged_runs,{failed},,,\n"));
    s
}

/// The parameters the robustness report varies, with the keys of the controller's nominal
/// model they must be pinned to (so the plant varies and the controller does not).
pub const ROBUSTNESS_KEYS: [(&str, Option<&str>); 7] = [
    ("hydraulics.beta_pa", Some("controller.nominal.beta_pa")),
    ("hydraulics.v0_m3", Some("controller.nominal.v0_m3")),
    ("hydraulics.k_q", Some("controller.nominal.k_q")),
    ("friction.viscous_n_s_per_m", None),
    ("friction.coulomb_n", None),
    ("human.k_p", None),
    ("human.k_d", None),
];

/// The paper's Table 2 disturbance forms (constant, random, sine, exponential decay, each of
/// unit amplitude) on dx2/dt, plus its state-dependent g = 0.05 x1 + 1e-3 x2.
pub const TABLE2_DISTURBANCES: [&str; 3] = [
    "disturbance.force_accel=[{kind=\"constant\",value=1.0},{kind=\"random\",amplitude=1.0},{kind=\"sine\"},{kind=\"exp_decay\"}]",
    "disturbance.state_gain_force=0.05",
    "disturbance.state_gain_force_rate=1e-3",
];

/// The robustness runs: every parameter of [`ROBUSTNESS_KEYS`] uniform within +-`percent` %,
/// the controller's nominal model pinned to the base values, the Table 2 disturbances on.
pub fn robustness_runs(base: &Scenario, n: usize, percent: f64) -> Result<(Scenario, Vec<Vec<String>>)> {
    let mut pinned: Vec<String> = TABLE2_DISTURBANCES.iter().map(|s| s.to_string()).collect();
    for (k, nominal) in ROBUSTNESS_KEYS {
        if let Some(nk) = nominal {
            pinned.push(format!("{nk}={:?}", value_at(base, k)?));
        }
    }
    let base = base.with_sets(&pinned)?;
    let vary: Vec<(String, Dist)> = ROBUSTNESS_KEYS.iter().map(|(k, _)| (k.to_string(), Dist::Pct(percent))).collect();
    let runs = monte_carlo_runs(&base, n, &vary, base.file.seed)?;
    Ok((base, runs))
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
        let g = grid_runs(&[
            ("x".into(), vec!["1".into(), "2".into()]),
            ("y".into(), vec!["3".into(), "4".into(), "5".into()]),
        ]);
        assert_eq!(g.len(), 6);
        assert_eq!(g[0], vec!["x=1".to_string(), "y=3".to_string()]);
        assert_eq!(g[5], vec!["x=2".to_string(), "y=5".to_string()]);
    }

    #[test]
    fn monte_carlo_draws_are_per_run_and_within_range() {
        let s = Scenario::load(None, &[]).unwrap();
        let runs = monte_carlo_runs(&s, 50, &[("hydraulics.beta_pa".into(), Dist::Pct(20.0))], 7).unwrap();
        let again = monte_carlo_runs(&s, 50, &[("hydraulics.beta_pa".into(), Dist::Pct(20.0))], 7).unwrap();
        assert_eq!(runs, again);
        let vals: Vec<f64> = runs.iter().map(|r| r[0].split('=').nth(1).unwrap().parse().unwrap()).collect();
        assert!(vals.iter().all(|v| (v / 1.517e9 - 1.0).abs() <= 0.2 + 1e-12));
        assert!(vals.iter().any(|v| *v > 1.6e9) && vals.iter().any(|v| *v < 1.4e9));
    }
}
