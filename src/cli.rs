//! The command line (clap derive) and the dispatch behind it.

use crate::compare;
use crate::error::{Error, Result, EXIT_OK};
use crate::output;
use crate::scenario::{ReferenceKind, Scenario};
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
            let json = serde_json::to_value(&res.summary)
                .map_err(|e| Error::Write { path: out.join("summary.json"), message: e.to_string() })?;
            let title = run_title(&s);
            output::write_run(&out, &res.record, &json, &title)?;
            if !quiet {
                let m = &res.summary;
                println!("scenario            {}", s.source_name);
                println!("controller          {}", s.file.controller.kind.as_str());
                println!("max |F_L - F_d|     {:.4} N", m.max_abs_force_error_n);
                println!(
                    "convergence time    {} (band {:.3} N)",
                    m.force_convergence_time_s.map_or("never".into(), |t| format!("{t:.4} s")),
                    m.force_convergence_band_n
                );
                println!("RMS error           {:.4} N", m.rms_force_error_n);
                println!("max |u|             {:.4e}", m.max_abs_valve_command);
                println!("steps               {} ({:.0} steps/s)", m.steps, m.steps_per_second);
                println!("outputs             {}", out.display());
            }
            Ok(EXIT_OK)
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
