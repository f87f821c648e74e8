//! The command line (clap derive) and the dispatch behind it.

use crate::compare;
use crate::error::{Error, Result, EXIT_OK};
use crate::metrics;
use crate::output;
use crate::scenario::{ReferenceKind, Scenario};
use crate::sweep;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// exoleg: force control of hydraulic lower-limb exoskeletons, simulated.
#[derive(Debug, Parser)]
#[command(name = "exoleg", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Sub-commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run one scenario headless; writes timeseries.csv, summary.json and force_tracking.png.
    Run {
        /// Scenario file (TOML, or a summary.json to reproduce a run). Default: the embedded
        /// paper Figure 5 case.
        scenario: Option<PathBuf>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Override any scenario key, e.g. `--set controller.gamma=200` (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Print nothing but errors.
        #[arg(long)]
        quiet: bool,
    },
    /// Run many variations of a scenario in parallel: a full grid or a Monte-Carlo sample.
    /// Writes DIR/runs.jsonl (one line per run) and DIR/aggregate.csv (min/median/max).
    Sweep {
        /// Base scenario (TOML).
        scenario: PathBuf,
        /// A grid axis `key=v1,v2,...` (repeatable; the full factorial is run).
        #[arg(long = "grid", value_name = "KEY=V1,V2,..", conflicts_with_all = ["monte_carlo", "vary"])]
        grids: Vec<String>,
        /// Number of Monte-Carlo runs.
        #[arg(long = "monte-carlo", value_name = "N", requires = "vary")]
        monte_carlo: Option<usize>,
        /// A random parameter: `key=uniform(lo,hi)`, `key=normal(mean,sd)` or `key=pct(p)`.
        #[arg(long = "vary", value_name = "KEY=DIST(..)")]
        vary: Vec<String>,
        /// Override any scenario key for all runs (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Worker threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        jobs: usize,
        /// Output directory.
        #[arg(long, default_value = "out/sweep")]
        out: PathBuf,
        /// Also write every run's time series, summary and plots to DIR/run_NNNN.
        #[arg(long)]
        run_outputs: bool,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Robustness report: vary beta, V0, K_q, friction and the human gains by +-PERCENT % (the
    /// controller keeps the nominal model), add the paper's Table 2 disturbances, and check
    /// each run against the scenario's [criteria]. Exit code 4 if any run fails.
    Robustness {
        /// Base scenario (TOML); its [criteria] are the pass/fail limits.
        scenario: PathBuf,
        /// Half-width of the uniform variation, in percent.
        #[arg(long, default_value_t = 20.0)]
        percent: f64,
        /// Number of runs.
        #[arg(long, default_value_t = 64)]
        samples: usize,
        /// Override any scenario key for all runs (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Worker threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        jobs: usize,
        /// Output directory.
        #[arg(long, default_value = "out/robustness")]
        out: PathBuf,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Run the paper's eight cases (Tables 3 and 4) and print ours next to the paper's.
    Compare {
        /// Base scenario (default: the embedded one); the cases override reference and controller.
        scenario: Option<PathBuf>,
        /// Plant kind to run the cases on (`bench`).
        #[arg(long)]
        plant: Option<String>,
        /// Also write the results as JSON to this path.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Override any scenario key for all cases (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
    },
}

fn print_summary(s: &Scenario, m: &crate::metrics::Summary, out: &std::path::Path) {
    println!("scenario            {}", s.source_name);
    println!(
        "controller          {}  (plant {:?}, hydraulics {:?})",
        s.file.controller.kind.as_str(),
        s.file.plant.kind,
        s.file.hydraulics.model
    );
    println!("max |F_L - F_d|     {:.4} N", m.max_abs_force_error_n);
    println!(
        "convergence time    {} (band {:.3} N)",
        m.force_convergence_time_s.map_or("never".into(), |t| format!("{t:.4} s")),
        m.force_convergence_band_n
    );
    println!("RMS error           {:.4} N", m.rms_force_error_n);
    if m.settle_s > 0.0 {
        println!(
            "after {:.3} s        force RMS {:.4} N, max {:.4} N",
            m.settle_s, m.rms_force_error_after_settle_n, m.max_abs_force_error_after_settle_n
        );
    }
    if let (Some(r), Some(x)) = (m.knee_rms_error_deg, m.knee_max_abs_error_deg) {
        println!("knee error          RMS {r:.4} deg, max {x:.4} deg");
    }
    println!("max |u|             {:.4e}", m.max_abs_valve_command);
    println!(
        "saturation          valve {:.2}%, force limit {:.2}%",
        100.0 * m.valve_saturation_fraction,
        100.0 * m.force_limit_fraction
    );
    println!("steps               {} ({:.0} steps/s)", m.steps, m.steps_per_second);
    println!("outputs             {}", out.display());
}

/// Write `runs.jsonl` and `aggregate.csv` of a sweep into `out`.
fn write_sweep(out: &std::path::Path, lines: &[sweep::RunLine]) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::Write { path: out.to_path_buf(), message: e.to_string() })?;
    output::write_atomic(&out.join("runs.jsonl"), sweep::jsonl(lines).as_bytes())?;
    let failed = lines.iter().filter(|l| l.error.is_some()).count();
    output::write_atomic(&out.join("aggregate.csv"), sweep::aggregate_csv(&sweep::aggregate(lines), failed).as_bytes())
}

/// Plot title: scenario, controller, plant and reference.
fn run_title(s: &Scenario) -> String {
    let f = &s.file;
    let reference = match f.reference.kind {
        ReferenceKind::Sine => format!("F_d = {} N sine at {} Hz", f.reference.amplitude_n, f.reference.frequency_hz),
        ReferenceKind::Gait => {
            format!("gait {}", f.reference.gait_file.as_deref().unwrap_or(&f.reference.gait_trial))
        }
    };
    format!("{} | {} | {:?} | {}", s.source_name, f.controller.kind.as_str(), f.plant.kind, reference)
}

/// Execute a parsed command line. Returns the process exit code on success.
pub fn run(cli: Cli) -> Result<i32> {
    match cli.command {
        Command::Run { scenario, out, sets, quiet } => {
            let s = Scenario::load(scenario.as_deref(), &sets)?;
            let res = crate::sim::run(&s)?;
            let checks = metrics::check_criteria(&s.file.criteria, &res.summary);
            let passed = checks.iter().all(|c| c.pass);
            let mut json = serde_json::to_value(&res.summary)
                .map_err(|e| Error::Write { path: out.join("summary.json"), message: e.to_string() })?;
            json["criteria_results"] = serde_json::to_value(&checks).unwrap_or_default();
            json["criteria_passed"] = serde_json::Value::Bool(passed);
            output::write_run(&out, &res.record, &json, &run_title(&s))?;
            if !quiet {
                print_summary(&s, &res.summary, &out);
            }
            for c in &checks {
                let verdict = if c.pass { "pass" } else { "FAIL" };
                println!("criterion {:<30} {verdict}: {:.4} (limit {:.4})", c.name, c.value, c.limit);
            }
            if passed {
                Ok(EXIT_OK)
            } else {
                let failed: Vec<&str> = checks.iter().filter(|c| !c.pass).map(|c| c.name).collect();
                Err(Error::Criteria(format!("{} failed: {}", s.source_name, failed.join(", "))))
            }
        }
        Command::Sweep { scenario, grids, monte_carlo, vary, sets, jobs, out, run_outputs, quiet } => {
            let base = Scenario::load(Some(&scenario), &sets)?;
            if monte_carlo == Some(0) {
                return Err(Error::input("--monte-carlo", "0", "need at least one run"));
            }
            let runs = if let Some(n) = monte_carlo {
                let vary: Vec<(String, sweep::Dist)> =
                    vary.iter().map(|v| sweep::parse_vary(v)).collect::<Result<_>>()?;
                sweep::monte_carlo_runs(&base, n, &vary, base.file.seed)?
            } else if !grids.is_empty() {
                let g: Vec<(String, Vec<String>)> =
                    grids.iter().map(|g| sweep::parse_grid(g)).collect::<Result<_>>()?;
                sweep::grid_runs(&g)
            } else {
                return Err(Error::input(
                    "sweep",
                    "",
                    "give --grid key=v1,v2,... or --monte-carlo N --vary key=dist(...)",
                ));
            };
            let start = std::time::Instant::now();
            let lines =
                sweep::run_all(&base, &runs, jobs, !quiet && runs.len() > 1, run_outputs.then_some(out.as_path()))?;
            let wall = start.elapsed().as_secs_f64();
            write_sweep(&out, &lines)?;
            let failed = lines.iter().filter(|l| l.error.is_some()).count();
            println!("{} runs in {wall:.2} s ({failed} diverged); {}", lines.len(), out.display());
            print!("{}", sweep::aggregate_csv(&sweep::aggregate(&lines), failed));
            Ok(EXIT_OK)
        }
        Command::Robustness { scenario, percent, samples, sets, jobs, out, quiet } => {
            if !(percent.is_finite() && (0.0..100.0).contains(&percent)) {
                return Err(Error::input("--percent", percent.to_string(), "must be in [0, 100)"));
            }
            if samples == 0 {
                return Err(Error::input("--samples", "0", "need at least one run"));
            }
            let base = Scenario::load(Some(&scenario), &sets)?;
            let (pinned, runs) = sweep::robustness_runs(&base, samples, percent)?;
            let lines = sweep::run_all(&pinned, &runs, jobs, !quiet && runs.len() > 1, None)?;
            write_sweep(&out, &lines)?;
            let c = &base.file.criteria;
            let get = |l: &sweep::RunLine, k: &str| l.summary.as_ref().and_then(|s| s.get(k)).and_then(|x| x.as_f64());
            let col = |k: &str| lines.iter().filter_map(|l| get(l, k)).collect::<Vec<f64>>();
            let mut panels = vec![
                ("max |F_L - F_d| after settling (N)", col("max_abs_force_error_after_settle_n"), c.max_force_error_n),
                ("RMS force error after settling (N)", col("rms_force_error_after_settle_n"), c.rms_force_error_n),
            ];
            if base.file.reference.kind == ReferenceKind::Gait {
                panels.push(("knee RMS error (deg)", col("knee_rms_error_deg"), c.knee_rms_error_deg));
                panels.push(("knee max |error| (deg)", col("knee_max_abs_error_deg"), c.knee_max_error_deg));
            }
            let title =
                format!("{}: +-{percent}% parameters, Table 2 disturbances, {} runs", base.source_name, lines.len());
            output::histograms_png(&out.join("robustness.png"), &title, &panels)?;
            let passed = lines.iter().filter(|l| l.passed).count();
            let diverged = lines.iter().filter(|l| l.error.is_some()).count();
            println!("{title}");
            print!("{}", sweep::aggregate_csv(&sweep::aggregate(&lines), diverged));
            let has_criteria = lines.iter().any(|l| !l.criteria.is_empty());
            println!(
                "{passed}/{} runs pass{} ({diverged} diverged); report in {}",
                lines.len(),
                if has_criteria {
                    " the scenario's criteria"
                } else {
                    " (the scenario sets no [criteria]: only divergence fails)"
                },
                out.display()
            );
            if passed == lines.len() {
                Ok(EXIT_OK)
            } else {
                Err(Error::Criteria(format!("{} of {} robustness runs failed", lines.len() - passed, lines.len())))
            }
        }
        Command::Compare { scenario, plant, json, sets } => {
            let mut all = Vec::new();
            if let Some(p) = plant {
                all.push(format!("plant.kind={p}"));
            }
            all.extend(sets);
            let base = Scenario::load(scenario.as_deref(), &all)?;
            let results = compare::run_cases(&base, &[])?;
            println!("Paper cases on plant `{:?}` ({}):", base.file.plant.kind, base.source_name);
            print!("{}", compare::table(&results));
            if let Some(p) = json {
                let bytes = serde_json::to_vec_pretty(&results)
                    .map_err(|e| Error::Write { path: p.clone(), message: e.to_string() })?;
                output::write_atomic(&p, &bytes)?;
            }
            Ok(EXIT_OK)
        }
    }
}
