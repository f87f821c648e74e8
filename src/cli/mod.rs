//! The command line (clap derive) and the dispatch behind it: the arguments here, each
//! command in its own file beside this one.

use crate::error::{Error, Result, EXIT_OK};
use crate::metrics::Summary;
use crate::output;
use crate::scenario::{ResolvedScenario, Resources, Scenario};
use crate::study::{self, compare, robustness, shard, sweep};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

mod campaign;
mod fmu;
mod gait_check;
mod hil;
mod muscles;
mod paper;
mod report;
mod run;
mod sweeps;
mod urdf;

use campaign::*;
use fmu::*;
use gait_check::*;
use hil::*;
use muscles::*;
use paper::*;
use report::*;
use run::*;
use sweeps::*;
use urdf::*;

/// exoleg: force control of hydraulic lower-limb exoskeletons, simulated.
#[derive(Debug, Parser)]
#[command(name = "exoleg", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Options of every study that runs many runs in parallel.
#[derive(Debug, Clone, clap::Args)]
pub struct ParallelArgs {
    /// Override any scenario key for all runs (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub sets: Vec<String>,
    /// Worker threads (0 = all cores; clamped to the runs and to 256).
    #[arg(long, default_value_t = 0)]
    pub jobs: usize,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Options shared by `sweep` and `robustness`.
#[derive(Debug, Clone, clap::Args)]
pub struct SweepArgs {
    /// Overrides, workers, progress.
    #[command(flatten)]
    pub parallel: ParallelArgs,
    /// Run only shard K of N (0-based: the runs whose index % N == K; e.g.
    /// `--shard $SLURM_ARRAY_TASK_ID/N`): writes DIR/runs.jsonl and DIR/shard.json for
    /// `exoleg merge`.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// Print the expanded runs as JSON lines (index, overrides) and exit without running.
    #[arg(long)]
    pub plan: bool,
    /// Keep the runs an interrupted study of the same plan into the same DIR finished (kept in
    /// DIR's journal, `.DIR.exoleg-partial`) and make only the missing ones; a journal of
    /// another plan is refused. Without it, a new study starts.
    #[arg(long)]
    pub resume: bool,
}

/// Options of `gait-check`.
#[derive(Debug, Clone, clap::Args)]
pub struct GaitCheckArgs {
    /// `reduced` (the default: about 16x faster) or `rapier`.
    #[arg(long, default_value = "reduced")]
    pub engine: String,
    /// Step (s). Default: 0.001 on the reduced engine, 0.00025 on Rapier.
    #[arg(long = "dt", value_name = "S")]
    pub dt_s: Option<f64>,
    /// Strides per trial, the first of them the run-in.
    #[arg(long, default_value_t = 6)]
    pub strides: usize,
    /// The base scenario (default: the built-in treadmill_subject.toml).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Overrides for every trial, workers, progress.
    #[command(flatten)]
    pub parallel: ParallelArgs,
    /// Target: the least stance fraction of the stride.
    #[arg(long, default_value_t = 0.45)]
    pub min_stance: f64,
    /// Target: the largest stance fraction of the stride.
    #[arg(long, default_value_t = 0.70)]
    pub max_stance: f64,
    /// Target: the least correlation of the vertical ground reaction with the data's.
    #[arg(long, default_value_t = 0.8)]
    pub min_grf_r: f64,
    /// Target: the least correlation of the stance knee moment with the data's.
    #[arg(long, default_value_t = 0.7)]
    pub min_knee_moment_r: f64,
    /// Peak check: the extensor peak within this many % of the cycle of the data's.
    #[arg(long, default_value_t = 5.0)]
    pub extensor_within_pct: f64,
    /// Peak check: the flexor peak within this fraction of the data's magnitude.
    #[arg(long, default_value_t = 0.5)]
    pub flexor_within: f64,
    /// Count the peak checks in the verdict (else they are reported only).
    #[arg(long)]
    pub require_peaks: bool,
}

/// Sub-commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run one scenario headless; writes timeseries.csv, summary.json and force_tracking.png.
    Run {
        /// Scenario file (TOML, or a summary.json to reproduce a run). Default: the embedded
        /// paper Figure 5 case.
        scenario: Option<PathBuf>,
        /// Output directory (replaced as a whole when the run completes).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Override any scenario key, e.g. `--set controller.gamma=200` (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Print nothing but errors.
        #[arg(long)]
        quiet: bool,
        /// Also write leg_motion.gif: the leg in motion (leg plant only).
        #[arg(long)]
        animate: bool,
        /// Also run the scenario without the device's help (the cylinder disconnected; an
        /// ideal device gives no moment) and report the metabolic rate's change against it
        /// (needs wearer.muscles = true).
        #[arg(long)]
        baseline: bool,
    },
    /// Run many variations of a scenario in parallel: a full grid or a Monte-Carlo sample.
    /// Writes DIR/runs.jsonl (one line per run) and DIR/aggregate.csv (min/median/max).
    Sweep {
        /// Base scenario (TOML).
        scenario: PathBuf,
        /// A grid axis `key=v1,v2,...` (repeatable; the full factorial is run, at most 10^6 runs).
        #[arg(long = "grid", value_name = "KEY=V1,V2,..", conflicts_with_all = ["monte_carlo", "vary"])]
        grids: Vec<String>,
        /// Number of Monte-Carlo runs (1..=10^6).
        #[arg(long = "monte-carlo", value_name = "N", requires = "vary")]
        monte_carlo: Option<usize>,
        /// A random parameter: `key=uniform(lo,hi)`, `key=normal(mean,sd)` or `key=pct(p)`.
        #[arg(long = "vary", value_name = "KEY=DIST(..)")]
        vary: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "out/sweep")]
        out: PathBuf,
        /// Also write every run's time series, summary and plots to DIR/run_NNNN.
        #[arg(long)]
        run_outputs: bool,
        /// Shared options.
        #[command(flatten)]
        common: SweepArgs,
    },
    /// Robustness report: vary beta, V0, K_q, friction and the human gains by +-PERCENT % (the
    /// controller keeps the nominal model), add the paper's Table 2 disturbances, and check
    /// each run against the scenario's criteria table. Exit code 4 if any run fails.
    Robustness {
        /// Base scenario (TOML); its criteria table holds the pass/fail limits.
        scenario: PathBuf,
        /// Half-width of the uniform variation, in percent.
        #[arg(long, default_value_t = 20.0)]
        percent: f64,
        /// Number of runs (1..=10^6).
        #[arg(long, default_value_t = 64)]
        samples: usize,
        /// Output directory.
        #[arg(long, default_value = "out/robustness")]
        out: PathBuf,
        /// Shared options.
        #[command(flatten)]
        common: SweepArgs,
    },
    /// Fault campaign: every failure mode of the matrix (sensor, valve, leakage, supply, power
    /// and controller faults; by default the ones that apply to the scenario) at 10 onsets
    /// across the gait cycle and 2 severities, each run scored by what would hurt the wearer
    /// (`[safety]`) next to the unfaulted baseline. Writes runs.jsonl, faults.csv, faults.png
    /// (the heat map), fmea.csv and fmea.md; prints the FMEA table. Exit code 4 if any run
    /// breaks a safety criterion.
    Faults {
        /// Base scenario (TOML): a leg run, without `[[faults]]`.
        scenario: PathBuf,
        /// The campaign's failure modes, severities and onsets (TOML; see --print-matrix).
        #[arg(long, value_name = "FILE")]
        matrix: Option<PathBuf>,
        /// Print the matrix the campaign would run (TOML, a starting point for --matrix) and exit.
        #[arg(long)]
        print_matrix: bool,
        /// Strides a walking run goes on after the latest its fault can start (0: the
        /// scenario's duration).
        #[arg(long, default_value_t = study::faults::DEFAULT_OBSERVE_STRIDES)]
        observe_strides: f64,
        /// Output directory.
        #[arg(long, default_value = "out/faults")]
        out: PathBuf,
        /// Shared options.
        #[command(flatten)]
        common: SweepArgs,
    },
    /// Merge the shard folders of a sharded sweep or robustness report into what the
    /// unsharded run writes (runs.jsonl, aggregate.csv, plots). Every shard exactly once.
    Merge {
        /// The shard folders (each with shard.json and runs.jsonl).
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Output directory.
        #[arg(long, default_value = "out/merged")]
        out: PathBuf,
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
        /// The firmware table instead: every controller at 1 kHz with 16-bit sensors and one
        /// sample of delay, on the paper's bench cases and the shipped gait scenarios.
        #[arg(long, conflicts_with_all = ["scenario", "plant"])]
        firmware: bool,
    },
    /// Write the built-in leg scaled to a subject as a URDF (what `[subject]` runs), to look
    /// at or to edit and use as `leg.urdf`.
    Urdf {
        /// Body mass (kg).
        #[arg(long)]
        mass_kg: f64,
        /// Stature (m).
        #[arg(long)]
        height_m: f64,
        /// Hip joint centre to floor (m), if measured.
        #[arg(long)]
        leg_length_m: Option<f64>,
        /// `male` or `female`.
        #[arg(long, default_value = "male")]
        sex: String,
        /// The URDF file to write (`-`: standard output).
        #[arg(long, default_value = "-")]
        out: PathBuf,
    },
    /// The wearer's muscles at a pose: each muscle's parameters, its muscle-tendon length and
    /// its moment arms about the hip, knee and ankle (hip flexion +, knee flexion +, ankle
    /// dorsiflexion +; r = -dL/dq, so a knee flexor's knee arm is positive), the source model
    /// and its muscles' names. Scaled to the scenario's leg unless --generic.
    Muscles {
        /// Scenario whose leg and `wearer.muscles_file` to use. Default: the embedded default
        /// scenario's leg and the built-in muscles.
        scenario: Option<PathBuf>,
        /// The pose: hip flexion, knee flexion, ankle dorsiflexion (deg).
        #[arg(long, value_name = "HIP_DEG,KNEE_DEG,ANKLE_DEG", allow_hyphen_values = true)]
        pose: String,
        /// The source model's own size (no scaling to the leg).
        #[arg(long)]
        generic: bool,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Override any scenario key (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
    },
    /// Run every trial of folders of gait CSVs, each folder with its subjects.csv, with each
    /// subject's numbers alone, in parallel; compare each with its data. Writes
    /// OUT/gait_check.csv and OUT/figures/FOLDER/TRIAL.png. Exit 0 if every trial meets the
    /// targets, 4 if not, 2 if a folder or a trial is bad input (the other trials still run).
    GaitCheck {
        /// Folders of gait CSVs, each with its subjects.csv (README, "Walking for anyone").
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output directory.
        #[arg(long, default_value = "out/gait-check")]
        out: PathBuf,
        /// The engine and how to run.
        #[command(flatten)]
        run: GaitCheckArgs,
    },
    /// Package a scenario's plant as an FMI 2.0 co-simulation FMU for Simulink, OpenModelica,
    /// FMPy or any FMI master: everything but the controller (the master reads the sensor
    /// readings and sets the valve command at every sample instant).
    Fmu {
        /// Scenario file (TOML). Default: the embedded paper Figure 5 case. Its controller is
        /// dropped; its sensors, reference, human, disturbances and leg are packaged.
        scenario: Option<PathBuf>,
        /// Override any scenario key (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// The FMU file to write.
        #[arg(long, default_value = "exoleg.fmu")]
        out: PathBuf,
        /// The FMU's shared library (built by `cargo build --release -p exoleg-fmu`). Default:
        /// next to this executable.
        #[arg(long, value_name = "PATH")]
        library: Option<PathBuf>,
    },
    /// Hardware in the loop: run a scenario's plant against a controller peer over UDP (a board,
    /// another process or machine, `examples/hil/hil_client.c`, `python -m exoleg.hil`)
    /// speaking the protocol of the README's "The controller out of process". Writes what
    /// `run` writes; summary.json's controller_link has the link's figures.
    Hil {
        /// Scenario file (TOML; controller.sample_period_s > 0). Its controller.plugin.params
        /// and .log go to the peer. Default: the embedded paper Figure 5 case.
        scenario: Option<PathBuf>,
        /// ADDR:PORT to listen on (port 0: any free port; the address is printed on stderr).
        #[arg(long, default_value = "127.0.0.1:9300")]
        listen: String,
        /// `lockstep` (the plant waits for every command: bit-identical to the in-process
        /// plugin) or `realtime` (paced at wall-clock time; a late command is missed).
        #[arg(long, value_enum, default_value = "lockstep")]
        mode: crate::hil::Mode,
        /// Output directory (replaced as a whole when the run completes).
        #[arg(long, default_value = "out/hil")]
        out: PathBuf,
        /// Override any scenario key (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Print nothing but errors.
        #[arg(long)]
        quiet: bool,
        /// How long to wait for the peer's HELLO (s).
        #[arg(long, default_value_t = 60.0)]
        wait_s: f64,
        /// The stall watchdog: the run ends when no valid command comes for this long (s).
        #[arg(long, default_value_t = 10.0)]
        stall_timeout_s: f64,
        /// Lockstep: send the readings again after this long without an answer (s).
        #[arg(long, default_value_t = 0.1)]
        resend_s: f64,
        /// Realtime: the valve command of a sample whose command missed its deadline (`hold`
        /// the last, or `zero`).
        #[arg(long, value_enum, default_value = "hold")]
        on_miss: crate::hil::OnMiss,
        /// Only this address (an IP: any port; or ADDR:PORT) may be the peer (repeatable). The
        /// protocol is unauthenticated: without it, whoever says HELLO first drives the valve.
        #[arg(long, value_name = "ADDR")]
        allow_from: Vec<String>,
    },
    /// (Internal) serve an isolated plugin to the run that started this process
    /// (`controller.plugin.isolate`).
    #[command(name = "plugin-host", hide = true)]
    PluginHost {
        /// The socket the run gave.
        #[arg(long)]
        fd: i32,
        /// The plugin library.
        #[arg(long)]
        library: PathBuf,
        /// The plugin's address space (MiB; `controller.plugin.memory_mb`).
        #[arg(long)]
        memory_mb: Option<u64>,
    },
}

/// On SIGINT, SIGTERM or SIGHUP (Ctrl-C, `kill`, Slurm and Kubernetes stopping a job):
/// remove the temporary output folders being written, then exit with 128 + the signal (as a
/// shell reports it). Nothing half-written is left, as when a run fails.
pub fn remove_outputs_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else { return };
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            output::remove_active();
            exit(128 + sig);
        }
    });
}

/// `p` made absolute against the working directory now (nothing else changed: `out/.` stays
/// `/abs/out/.`), so that nothing run later (a plugin that changes the working directory)
/// moves what a command reads or writes.
fn absolute(p: PathBuf) -> PathBuf {
    if p.is_absolute() || p.as_os_str().is_empty() {
        return p;
    }
    std::env::current_dir().map(|d| d.join(&p)).unwrap_or(p)
}

/// Every path of a command line made absolute before anything is loaded ([`absolute`]).
fn absolute_paths(c: Command) -> Command {
    let opt = |p: Option<PathBuf>| p.map(absolute);
    match c {
        Command::Run { scenario, out, sets, quiet, animate, baseline } => {
            Command::Run { scenario: opt(scenario), out: absolute(out), sets, quiet, animate, baseline }
        }
        Command::Sweep { scenario, grids, monte_carlo, vary, out, run_outputs, common } => Command::Sweep {
            scenario: absolute(scenario),
            grids,
            monte_carlo,
            vary,
            out: absolute(out),
            run_outputs,
            common,
        },
        Command::Robustness { scenario, percent, samples, out, common } => {
            Command::Robustness { scenario: absolute(scenario), percent, samples, out: absolute(out), common }
        }
        Command::Merge { shards, out } => {
            Command::Merge { shards: shards.into_iter().map(absolute).collect(), out: absolute(out) }
        }
        Command::Compare { scenario, plant, json, sets, firmware } => {
            Command::Compare { scenario: opt(scenario), plant, json: opt(json), sets, firmware }
        }
        Command::Muscles { scenario, pose, generic, json, sets } => {
            Command::Muscles { scenario: opt(scenario), pose, generic, json, sets }
        }
        Command::Urdf { mass_kg, height_m, leg_length_m, sex, out } => {
            let out = if out.as_os_str() == "-" { out } else { absolute(out) };
            Command::Urdf { mass_kg, height_m, leg_length_m, sex, out }
        }
        Command::Fmu { scenario, sets, out, library } => {
            Command::Fmu { scenario: opt(scenario), sets, out: absolute(out), library: opt(library) }
        }
        Command::Faults { scenario, matrix, print_matrix, observe_strides, out, common } => Command::Faults {
            scenario: absolute(scenario),
            matrix: opt(matrix),
            print_matrix,
            observe_strides,
            out: absolute(out),
            common,
        },
        Command::GaitCheck { dirs, out, mut run } => {
            run.scenario = opt(run.scenario);
            Command::GaitCheck { dirs: dirs.into_iter().map(absolute).collect(), out: absolute(out), run }
        }
        Command::Hil {
            scenario,
            listen,
            mode,
            out,
            sets,
            quiet,
            wait_s,
            stall_timeout_s,
            resend_s,
            on_miss,
            allow_from,
        } => Command::Hil {
            scenario: opt(scenario),
            listen,
            mode,
            out: absolute(out),
            sets,
            quiet,
            wait_s,
            stall_timeout_s,
            resend_s,
            on_miss,
            allow_from,
        },
        c @ Command::PluginHost { .. } => c,
    }
}

/// End the process with `code` (exoleg's own exit: the plugin exit guard stands aside).
pub fn exit(code: i32) -> ! {
    crate::control::plugin::exit_guard::exit(code)
}

/// Execute a parsed command line. Returns the process exit code on success. While it runs,
/// an `exit()` from anything but exoleg (a plugin) ends the process with exit 3, never 0.
pub fn run(cli: Cli) -> Result<i32> {
    if let Command::PluginHost { fd, library, memory_mb } = &cli.command {
        // A child of a run: its exit status (a plugin's exit() included) is the run's to read.
        return Ok(crate::control::isolate::child::serve(*fd, library, *memory_mb));
    }
    let _armed = crate::control::plugin::exit_guard::arm();
    match absolute_paths(cli.command) {
        Command::Run { scenario, out, sets, quiet, animate, baseline } => {
            cmd_run(scenario, out, sets, RunFlags { quiet, animate, baseline })
        }
        Command::Muscles { scenario, pose, generic, json, sets } => cmd_muscles(scenario, &pose, generic, json, sets),
        Command::Sweep { scenario, grids, monte_carlo, vary, out, run_outputs, common } => {
            cmd_sweep(scenario, grids, monte_carlo, vary, out, run_outputs, common)
        }
        Command::Robustness { scenario, percent, samples, out, common } => {
            cmd_robustness(scenario, percent, samples, out, common)
        }
        Command::Faults { scenario, matrix, print_matrix, observe_strides, out, common } => {
            cmd_faults(scenario, matrix, print_matrix, observe_strides, out, common)
        }
        Command::Merge { shards, out } => cmd_merge(shards, out),
        Command::Compare { firmware: true, json, sets, .. } => cmd_firmware(json, sets),
        Command::Compare { scenario, plant, json, sets, .. } => cmd_compare(scenario, plant, json, sets),
        Command::Fmu { scenario, sets, out, library } => cmd_fmu(scenario, sets, out, library),
        Command::GaitCheck { dirs, out, run } => cmd_gait_check(dirs, out, run),
        Command::Urdf { mass_kg, height_m, leg_length_m, sex, out } => {
            cmd_urdf(mass_kg, height_m, leg_length_m, sex, out)
        }
        Command::Hil {
            scenario,
            listen,
            mode,
            out,
            sets,
            quiet,
            wait_s,
            stall_timeout_s,
            resend_s,
            on_miss,
            allow_from,
        } => {
            let allow_from = allow_from
                .iter()
                .map(|a| crate::hil::link::Allowed::parse(a))
                .collect::<std::result::Result<Vec<_>, String>>()
                .map_err(|e| Error::input("--allow-from", "", e))?;
            let opts = crate::hil::HilOptions { listen, mode, wait_s, stall_timeout_s, resend_s, on_miss, allow_from };
            cmd_hil(scenario, sets, opts, out, quiet)
        }
        Command::PluginHost { .. } => Ok(EXIT_OK),
    }
}
