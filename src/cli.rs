//! The command line (clap derive) and the dispatch behind it.

use crate::error::{Error, Result, EXIT_OK};
use crate::metrics::Summary;
use crate::output;
use crate::scenario::{ResolvedScenario, Resources, Scenario};
use crate::study::{self, compare, robustness, shard, sweep};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

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
        /// Base scenario (TOML): a leg run, without [[faults]].
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

/// The report of a run; `driver`: the controller that drove it when it is not the scenario's
/// own (a HIL peer).
fn print_summary(sc: &ResolvedScenario, m: &Summary, out: &Path, driver: Option<&str>) {
    let f = &sc.file;
    println!("scenario            {}", sc.source_name);
    println!(
        "controller          {}  (plant {:?}, hydraulics {:?})",
        driver.unwrap_or(f.controller.kind.as_str()),
        f.plant.kind,
        f.hydraulics.model
    );
    if let Some(c) = &m.controller_stop {
        println!(
            "controller stop     at t = {:.6} s ({}): {}; the device went to its fail-safe state",
            c.t_s,
            c.cause.as_str(),
            c.message
        );
    }
    if sc.model.desired_force {
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
    } else {
        println!("desired force       none (reference.force = \"none\": the controller decides the assistance)");
    }
    if let (Some(r), Some(x)) = (m.knee_rms_error_deg, m.knee_max_abs_error_deg) {
        println!("knee error          RMS {r:.4} deg, max {x:.4} deg");
    }
    if let Some(w) = &m.wearer {
        print_wearer(w);
    }
    println!("max |u|             {:.4e}", m.max_abs_valve_command);
    println!(
        "saturation          valve {:.2}%, force limit {:.2}%",
        100.0 * m.valve_saturation_fraction,
        100.0 * m.force_limit_fraction
    );
    println!("steps               {} ({:.0} steps/s)", m.steps, m.steps_per_second);
    if m.hydraulic_substeps_max > 1 {
        println!(
            "substeps            the hydraulic states were stiff for sim.dt_s: {} steps substepped, up to {} times",
            m.substepped_steps, m.hydraulic_substeps_max
        );
    }
    println!("outputs             {}", out.display());
}

/// What the wearer got (walking runs).
fn print_wearer(w: &crate::metrics::WearerSummary) {
    let share = |s: Option<f64>| s.map_or("-".into(), |s| format!("{:.0} %", 100.0 * s));
    let phases: Vec<String> = w.phases.iter().map(|p| format!("{} {}", p.phase, share(p.device_share))).collect();
    println!("device share        {} (stance {})", phases.join(", "), share(w.stance_device_share));
    println!(
        "device work         +{:.2} J / {:.2} J per stride; hydraulic energy {:.1} J per stride ({:.0} W mean)",
        w.positive_work_per_stride_j,
        w.negative_work_per_stride_j,
        w.hydraulic_energy_per_stride_j,
        w.hydraulic_power_mean_w
    );
    println!(
        "cuffs               thigh peak {:.0} N RMS {:.0} N ({}), shank peak {:.0} N RMS {:.0} N ({}); limits comfort {:.0} N, pain {:.0} / {:.0} N",
        w.thigh_cuff.peak_n,
        w.thigh_cuff.rms_n,
        w.thigh_cuff.verdict,
        w.shank_cuff.peak_n,
        w.shank_cuff.rms_n,
        w.shank_cuff.verdict,
        w.thigh_cuff.limits_n[0],
        w.thigh_cuff.limits_n[1],
        w.shank_cuff.limits_n[1]
    );
    println!(
        "knee range          {:.1}..{:.1} deg (the wearer's data {:.1}..{:.1} deg)",
        w.knee_range_deg[0], w.knee_range_deg[1], w.data_knee_range_deg[0], w.data_knee_range_deg[1]
    );
    if let Some(m) = &w.metabolics {
        print_metabolics(m);
    }
    if let Some(p) = &w.phase_estimate {
        let ms = |x: Option<f64>| x.map_or("-".into(), |x| format!("{:.1} ms", 1e3 * x));
        println!(
            "gait phase (logged) heel strikes detected {} of {}, median latency {}, phase RMSE {}",
            p.detected,
            p.heel_strikes,
            ms(p.median_latency_s),
            p.phase_rmse_pct.map_or("-".into(), |e| format!("{e:.2} %"))
        );
    }
}

/// What the wearer's muscles cost (`wearer.muscles`).
fn print_metabolics(m: &crate::metrics::muscles::MetabolicsSummary) {
    let change = match (m.baseline_gross_w_per_kg, m.change_pct) {
        (Some(b), Some(c)) => format!("; without the device's help {b:.2} W/kg: {c:+.1} %"),
        _ => String::new(),
    };
    println!(
        "metabolic rate      gross {:.2} W/kg, net {:.2} W/kg ({}, {} muscles, {}){change}",
        m.gross_w_per_kg, m.net_w_per_kg, m.metabolic_model, m.muscle_model, m.muscle_cost
    );
    let mut top: Vec<(&String, &f64)> = m.per_muscle_w.iter().collect();
    top.sort_by(|a, b| b.1.total_cmp(a.1));
    let top: Vec<String> = top.iter().take(4).map(|(n, w)| format!("{n} {w:.0} W")).collect();
    let effort_change = m.effort_change_pct.map_or(String::new(), |c| format!(" ({c:+.1} %)"));
    println!(
        "muscles             effort {:.3}{effort_change}; {}; peak reserves hip {:.1} %, knee {:.1} %, ankle {:.1} % of the moments",
        m.effort,
        top.join(", "),
        m.peak_reserve_pct[0],
        m.peak_reserve_pct[1],
        m.peak_reserve_pct[2]
    );
    let off: Vec<&str> = m.emg.iter().filter(|e| !e.agrees).map(|e| e.muscle.as_str()).collect();
    println!(
        "activations vs EMG  {} of {} muscles on in Perry's (1992) phases{}",
        m.emg.len() - off.len(),
        m.emg.len(),
        if off.is_empty() { String::new() } else { format!(" (not: {})", off.join(", ")) }
    );
}

/// The warnings of a study's base scenario, once (a file changed since a recorded run, ...);
/// its errors surface when the study's runs are resolved.
fn warn_base(base: &Scenario) {
    if let Ok(r) = base.resolve(&Resources::new()) {
        warn(&r.warnings);
    }
}

fn warn(warnings: &[String]) {
    for w in warnings {
        eprintln!("warning: {}", output::text::terminal(w));
    }
}

/// `exoleg muscles`: the scenario's muscles (scaled to its leg, or the source model's own
/// size) at a pose, as a table or JSON.
fn cmd_muscles(scenario: Option<PathBuf>, pose: &str, generic: bool, json: bool, sets: Vec<String>) -> Result<i32> {
    let parts: Vec<&str> = pose.split(',').map(str::trim).collect();
    let angles: Vec<f64> = parts.iter().filter_map(|p| p.parse::<f64>().ok()).filter(|v| v.is_finite()).collect();
    if parts.len() != 3 || angles.len() != 3 || angles.iter().any(|a| a.abs() > 360.0) {
        return Err(Error::input("--pose", "", "give three angles in degrees, HIP,KNEE,ANKLE (each -360..=360)"));
    }
    let loaded = Scenario::load(scenario.as_deref(), &sets)?;
    let res = Resources::new();
    let set = match &loaded.file.wearer.muscles_file {
        None => crate::muscles::MuscleSet::builtin()?,
        Some(f) => res.muscle_set(&loaded.source_name, f, loaded.base_dir.as_deref())?.0,
    };
    let set = if generic {
        (*set).clone()
    } else {
        let sc = loaded.resolve(&res)?;
        let leg = sc.model.leg().ok_or_else(|| {
            Error::input(
                &sc.source_name,
                "plant.kind",
                "the muscles scale to the leg: plant.kind = \"leg\" (or --generic)",
            )
        })?;
        let (thigh, shank) = leg.model.thigh_shank_lengths_m();
        set.scaled(set.scale_for(thigh, shank))
    };
    let q = [angles[0].to_radians(), angles[1].to_radians(), angles[2].to_radians()];
    let muscles = set.at_pose(q);
    if json {
        let v = serde_json::json!({
            "model": set.model, "table": set.source, "citation": set.citation, "credits": set.credits,
            "scale": set.scale, "source": set.info, "pose_deg": {"hip": angles[0], "knee": angles[1], "ankle": angles[2]},
            "muscles": muscles,
        });
        println!("{}", serde_json::to_string_pretty(&v).map_err(|e| Error::Usage(e.to_string()))?);
        return Ok(EXIT_OK);
    }
    print_muscles(&set, &angles, &muscles);
    Ok(EXIT_OK)
}

fn print_muscles(set: &crate::muscles::MuscleSet, angles: &[f64], muscles: &[crate::muscles::MusclePose]) {
    let size =
        if set.scale == 1.0 { "its own size".to_string() } else { format!("scaled x{:.4} to the leg", set.scale) };
    println!("model      {} ({}), {size}", set.model, set.source);
    println!(
        "pose       hip {} deg, knee {} deg, ankle {} deg (hip flexion +, knee flexion +, ankle dorsiflexion +; r = -dL/dq)",
        angles[0], angles[1], angles[2]
    );
    println!(
        "{:<11} {:>8} {:>8} {:>8} {:>6} {:>5} {:>8} {:>8} {:>8} {:>8}  source muscles",
        "muscle", "F_max N", "l_opt m", "l_slk m", "pen deg", "slow", "L m", "r_hip mm", "r_knee", "r_ankle"
    );
    for m in muscles {
        let r = m.moment_arm_m.map(|x| 1e3 * x);
        println!(
            "{:<11} {:>8.1} {:>8.4} {:>8.4} {:>6.1} {:>5.2} {:>8.4} {:>8.2} {:>8.2} {:>8.2}  {}{}",
            m.name,
            m.max_isometric_force_n,
            m.optimal_fiber_length_m,
            m.tendon_slack_length_m,
            m.pennation_at_optimal_rad.to_degrees(),
            m.slow_twitch_fraction,
            m.length_m,
            r[0],
            r[1],
            r[2],
            m.source_names.join(" "),
            if m.inside_table { "" } else { " (outside its table: extrapolated)" }
        );
    }
}

/// `exoleg run`'s switches.
struct RunFlags {
    quiet: bool,
    animate: bool,
    baseline: bool,
}

/// `exoleg run`.
fn cmd_run(scenario: Option<PathBuf>, out: PathBuf, sets: Vec<String>, flags: RunFlags) -> Result<i32> {
    let RunFlags { quiet, animate, baseline } = flags;
    let loaded = Scenario::load(scenario.as_deref(), &sets)?;
    loaded.own_controller()?;
    let res = Resources::new();
    let sc = loaded.resolve(&res)?;
    warn(&sc.warnings);
    if animate && sc.model.leg().is_none() {
        return Err(Error::input(&sc.source_name, "--animate", "the animation draws the leg: plant.kind = \"leg\""));
    }
    let base = if baseline { Some(study::baseline_metabolics(&loaded, &res)?) } else { None };
    let report = study::RunBuilder::new(&sc).animate(animate).baseline(base).write_to(&out)?;
    if !out.join("summary.json").is_file() {
        return Err(Error::Write { path: out.clone(), message: "the run's summary.json is not there".into() });
    }
    if !quiet {
        print_summary(&sc, &report.summary, &out, None);
    }
    warn_controller_stop(&report.summary);
    if let Some(s) = report.summary.end_stops.filter(|s| !s.is_clear()) {
        eprintln!(
            "warning: the leg ran into its end stops: knee at its lower limit {:.3} s, upper limit {:.3} s, \
             cylinder stroke ends {:.3} s, ankle limits {:.3} s; deepest {:.3} deg (summary.json: end_stops)",
            s.knee_lower_s, s.knee_upper_s, s.stroke_end_s, s.ankle_s, s.max_penetration_deg
        );
    }
    if let Some(why) = report.summary.contact.as_ref().and_then(|c| c.not_walking.as_ref()).filter(|v| !v.is_empty()) {
        eprintln!(
            "warning: this run is not walking: {} (summary.json: not_walking; criteria.max_not_walking_flags = 0 \
             fails such a run)",
            why.join("; ")
        );
    }
    for (channel, n) in &report.summary.sensor_clipped_readings {
        eprintln!("warning: sensors.{channel}: {n} readings clipped at the full scale; raise sensors.{channel}.range");
    }
    for c in &report.criteria {
        let verdict = if c.pass { "pass" } else { "FAIL" };
        println!("criterion {:<30} {verdict}: {:.4} (limit {:.4})", c.name, c.value, c.limit);
    }
    verdict(&sc, &report)
}

/// A controller's stop under `controller.on_stop = "failsafe"` said on stderr (whatever
/// `--quiet` says: the run went on without its controller).
fn warn_controller_stop(m: &Summary) {
    if let Some(c) = m.controller_stop.as_ref().filter(|c| c.cause != crate::control::StopCause::Crash) {
        eprintln!(
            "warning: the controller stopped at t = {:.6} s ({}): {}; the device went to its fail-safe state \
             (controller.on_stop = \"failsafe\"; summary.json: controller_stop)",
            c.t_s,
            c.cause.as_str(),
            c.message
        );
    }
}

/// A run's exit: 0 if it passes, else exit 4 naming the failed criteria and a crashed
/// controller.
fn verdict(sc: &ResolvedScenario, report: &study::RunReport) -> Result<i32> {
    if report.passed() {
        return Ok(EXIT_OK);
    }
    let mut failed: Vec<String> = report.criteria.iter().filter(|c| !c.pass).map(|c| c.name.clone()).collect();
    if let Some(crash) = report.summary.controller_crash() {
        failed.push(format!(
            "{crash} (controller.on_stop = \"failsafe\": the device went to its fail-safe state and the run went on)"
        ));
    }
    Err(Error::Criteria(format!("{} failed: {}", sc.source_name, failed.join(", "))))
}

/// `exoleg hil`: the scenario's plant against a controller peer over UDP. Everything is
/// checked before the port opens (the flags, the scenario, what goes to the peer, `--out`).
fn cmd_hil(
    scenario: Option<PathBuf>,
    sets: Vec<String>,
    opts: crate::hil::HilOptions,
    out: PathBuf,
    quiet: bool,
) -> Result<i32> {
    opts.check().map_err(|(flag, e)| Error::input(flag, "", e))?;
    let sc = Scenario::load(scenario.as_deref(), &sets)?.resolve(&Resources::new())?;
    warn(&sc.warnings);
    let m = &sc.model;
    if m.sample_every.is_none() {
        let why = "a controller peer runs sampled: set controller.sample_period_s > 0";
        return Err(Error::input(&sc.source_name, "controller.sample_period_s", why));
    }
    // The same check of what the peer gets as a plugin's, on every route.
    let plugin = &sc.file.controller.plugin;
    plugin.check().map_err(|(k, e)| Error::input(&sc.source_name, k, e))?;
    let c = &m.nominal.c;
    let params = plugin.numbers().map_err(|(k, e)| Error::input(&sc.source_name, k, e))?;
    let setup = crate::control::plugin::InstanceSetup {
        sample_period_s: m.sample_period_s,
        valve_command_limit: m.valve_limit.0,
        nominal: [c.n1, c.n2, c.n3, c.tau_s, c.k_s],
        seed: m.seed,
        params: params.into_iter().map(|(n, v)| (n.to_string_lossy().into_owned(), v)).collect(),
    };
    let dir = crate::output::OutputDir::prepare_with_inputs(&out, "--out", &sc.input_paths())?;
    let link = crate::hil::HilController::bind(&opts).map_err(|e| Error::input("--listen", "", e))?;
    let at = link.local_addr();
    let shown = at.map_or(opts.listen.clone(), |a| a.to_string());
    eprintln!("exoleg hil: waiting for a controller peer on {shown} ({:?})", opts.mode);
    if at.is_some_and(|a| !a.ip().is_loopback()) && opts.allow_from.is_empty() {
        eprintln!(
            "warning: --listen {shown} is reachable beyond this machine and the protocol is unauthenticated: \
             whoever says HELLO first drives the valve (give --allow-from ADDR, or listen on 127.0.0.1)"
        );
    }
    let stopped = |message| Error::ControllerStopped { time_s: 0.0, controller: "hil".into(), message };
    let ctrl = crate::hil::HilController::on_link(link, &setup, plugin.log.clone(), opts).map_err(stopped)?;
    let driver = ctrl.peer_name();
    eprintln!("exoleg hil: {driver} drives this run");
    let report = study::RunBuilder::new(&sc).controller(Box::new(ctrl)).write_into(dir)?;
    if !quiet {
        print_summary(&sc, &report.summary, &out, Some(&driver));
        if let Some(l) = &report.summary.controller_link {
            println!("link                {l}");
        }
    }
    warn_controller_stop(&report.summary);
    verdict(&sc, &report)
}

/// `exoleg sweep`.
fn cmd_sweep(
    scenario: PathBuf,
    grids: Vec<String>,
    monte_carlo: Option<usize>,
    vary: Vec<String>,
    out: PathBuf,
    run_outputs: bool,
    common: SweepArgs,
) -> Result<i32> {
    let base = Scenario::load(Some(&scenario), &common.parallel.sets)?;
    base.own_controller()?;
    warn_base(&base);
    let plan = sweep::plan_from_args(&base, &grids, monte_carlo, &vary)?;
    run_study(&base, &base.source_name, &plan, shard::StudyKind::Sweep, out, run_outputs, &common)
}

/// Run a study's plan (or print it, or run one shard of it) into `out`.
fn run_study(
    base: &Scenario,
    source_name: &str,
    plan: &sweep::Plan,
    study: shard::StudyKind,
    out: PathBuf,
    run_outputs: bool,
    common: &SweepArgs,
) -> Result<i32> {
    if common.plan {
        let stdout = std::io::stdout();
        shard::write_plan(plan, &mut stdout.lock())?;
        return Ok(EXIT_OK);
    }
    let sh = common.shard.as_deref().map(shard::parse_shard).transpose()?;
    let opts = sweep::RunOptions {
        jobs: common.parallel.jobs,
        progress: !common.parallel.quiet,
        shard: sh.unwrap_or((0, 1)),
        controller: None,
        cancel: None,
        resume: common.resume,
    };
    let start = std::time::Instant::now();
    let done = shard::run_study_into(base, source_name, plan, &study, &opts, sh.is_some(), run_outputs, &out)?;
    let (title, agg) = (done.title, done.aggregate);
    let wall = start.elapsed().as_secs_f64();
    println!("{title}; {wall:.2} s; {}", out.display());
    match (&study, done.faults) {
        (shard::StudyKind::Faults { .. }, Some(r)) => faults_verdict(&r, &out),
        (shard::StudyKind::Robustness { .. }, _) if common.shard.is_none() => {
            print!("{}", agg.csv());
            robustness_verdict(&base.file, &agg, &out)
        }
        _ => {
            print!("{}", agg.csv());
            Ok(EXIT_OK)
        }
    }
}

/// A fault campaign's verdict: its FMEA table; exit 4 if any run breaks a safety criterion.
fn faults_verdict(r: &study::faults::CampaignReport, out: &Path) -> Result<i32> {
    print!("{}", r.fmea);
    println!(
        "{} of {} runs break a safety criterion ({} faulted runs with a fault-induced hazard); report in {}",
        r.hazard_runs,
        r.runs,
        r.fault_induced_runs,
        out.display()
    );
    if r.hazard_runs == 0 {
        Ok(EXIT_OK)
    } else {
        let base = if r.baseline_broken.is_empty() {
            String::new()
        } else {
            format!(" (the baseline itself breaks {})", r.baseline_broken.join(", "))
        };
        Err(Error::Criteria(format!("{} of {} campaign runs break a safety criterion{base}", r.hazard_runs, r.runs)))
    }
}

/// `exoleg faults`.
fn cmd_faults(
    scenario: PathBuf,
    matrix: Option<PathBuf>,
    print_matrix: bool,
    observe_strides: f64,
    out: PathBuf,
    common: SweepArgs,
) -> Result<i32> {
    let base = Scenario::load(Some(&scenario), &common.parallel.sets)?;
    base.own_controller()?;
    warn_base(&base);
    let matrix = matrix.as_deref().map(study::faults::read_matrix).transpose()?;
    let res = crate::scenario::Resources::new();
    let c = study::faults::campaign(&base, matrix, observe_strides, None, &res)?;
    for n in &c.notes {
        eprintln!("note: {n}");
    }
    if print_matrix {
        print!("{}", c.matrix.to_toml()?);
        return Ok(EXIT_OK);
    }
    let study = shard::StudyKind::Faults { layout: c.layout };
    run_study(&c.base, &base.source_name, &c.plan, study, out, false, &common)
}

/// The robustness report's verdict: exit 4 unless every run passes.
fn robustness_verdict(base: &crate::scenario::ScenarioFile, agg: &sweep::Aggregate, out: &Path) -> Result<i32> {
    let verdict = if base.criteria.any() {
        " the scenario's criteria"
    } else {
        " (the scenario sets no [criteria]: only divergence fails)"
    };
    println!("{}/{} runs pass{verdict} ({} failed); report in {}", agg.passed, agg.runs, agg.failed, out.display());
    if agg.passed == agg.runs {
        Ok(EXIT_OK)
    } else {
        Err(Error::Criteria(format!("{} of {} robustness runs failed", agg.runs - agg.passed, agg.runs)))
    }
}

/// `exoleg robustness`.
fn cmd_robustness(scenario: PathBuf, percent: f64, samples: usize, out: PathBuf, common: SweepArgs) -> Result<i32> {
    let base = Scenario::load(Some(&scenario), &common.parallel.sets)?;
    base.own_controller()?;
    warn_base(&base);
    let (pinned, plan) = robustness::robustness_plan(&base, samples, percent)?;
    run_study(&pinned, &base.source_name, &plan, shard::StudyKind::Robustness { percent }, out, false, &common)
}

/// `exoleg merge`.
fn cmd_merge(shards: Vec<PathBuf>, out: PathBuf) -> Result<i32> {
    let m = shard::merge(&shards, &out)?;
    println!("{}; {} shards merged into {}", m.title, shards.len(), out.display());
    print!("{}", m.aggregate.csv());
    match (&m.meta.study, &m.faults) {
        (shard::StudyKind::Faults { .. }, Some(r)) => faults_verdict(r, &out),
        (shard::StudyKind::Robustness { .. }, _) => robustness_verdict(&m.meta.scenario, &m.aggregate, &out),
        _ => Ok(EXIT_OK),
    }
}

/// `exoleg compare`.
fn cmd_compare(
    scenario: Option<PathBuf>,
    plant: Option<String>,
    json: Option<PathBuf>,
    sets: Vec<String>,
) -> Result<i32> {
    let mut all = Vec::new();
    if let Some(p) = plant {
        all.push(format!("plant.kind={p}"));
    }
    all.extend(sets);
    let base = Scenario::load(scenario.as_deref(), &all)?;
    let mut inputs = crate::fsio::own_executable();
    inputs.extend(base.resolve(&Resources::new()).map(|r| r.input_paths()).unwrap_or_default());
    inputs.extend(scenario);
    if let Some(p) = &json {
        crate::fsio::check_out(p, &compare::json_rule(&inputs))?;
    }
    let results = compare::run_cases(&base, &[])?;
    println!("Paper cases on plant `{:?}` ({}):", base.file.plant.kind, base.source_name);
    print!("{}", compare::table(&results));
    if let Some(p) = json {
        write_report(&p, &results, &inputs)?;
    }
    Ok(EXIT_OK)
}

/// Write a `--json` report (pretty JSON) under [`compare::json_rule`].
fn write_report(path: &Path, value: &impl serde::Serialize, inputs: &[PathBuf]) -> Result<()> {
    let bytes = serde_json::to_vec_pretty(value)
        .map_err(|e| Error::Write { path: path.to_path_buf(), message: e.to_string() })?;
    crate::fsio::write_bytes(path, &compare::json_rule(inputs), &bytes).map(|_| ())
}

/// `exoleg compare --firmware`.
fn cmd_firmware(json: Option<PathBuf>, sets: Vec<String>) -> Result<i32> {
    let inputs = crate::fsio::own_executable();
    if let Some(p) = &json {
        crate::fsio::check_out(p, &compare::json_rule(&inputs))?;
    }
    let rows = crate::study::firmware::run_table(&sets)?;
    println!(
        "Firmware conditions (1 kHz, zero-order hold, adc16, one sample of delay; bench cases at 0.1 ms steps).\n\
         Each cell: max |F_L - F_d| / max after settling / RMS after settling (N), and the knee RMS / max (deg) for gait:"
    );
    print!("{}", crate::study::firmware::table(&rows));
    if let Some(p) = json {
        write_report(&p, &rows, &inputs)?;
    }
    Ok(EXIT_OK)
}

/// `exoleg urdf`: the subject goes through the scenario's own checks.
fn cmd_urdf(mass_kg: f64, height_m: f64, leg_length_m: Option<f64>, sex: String, out: PathBuf) -> Result<i32> {
    let sex_toml = toml::Value::String(sex).to_string();
    let mut sets = vec![format!("subject={{mass_kg={mass_kg:?}, height_m={height_m:?}, sex={sex_toml}}}")];
    if let Some(l) = leg_length_m {
        sets.push(format!("subject.leg_length_m={l:?}"));
    }
    let sc = Scenario::load(None, &sets)?;
    let subject = sc.file.subject.as_ref().ok_or_else(|| Error::Usage("no subject".into()))?;
    let text = crate::leg::subject::scaled_urdf(&subject.body());
    crate::leg::LegSpec::from_urdf_with(&text, &crate::leg::LegOptions::default())
        .map_err(|e| Error::input("exoleg urdf", "--height-m", format!("the scaled leg does not build: {e}")))?;
    if out.as_os_str() == "-" {
        print!("{text}");
    } else {
        let inputs = crate::fsio::own_executable();
        let rule = crate::fsio::OutFile {
            flag: "--out",
            what: "a URDF exoleg urdf wrote",
            inputs: &inputs,
            ours: crate::leg::subject::is_scaled_urdf,
        };
        crate::fsio::write_bytes(&out, &rule, text.as_bytes())?;
        eprintln!("wrote {}", out.display());
    }
    Ok(EXIT_OK)
}

/// `exoleg gait-check`: the table printed, the bad trials listed on stderr; exit 2 if any
/// input was bad, else 4 if a trial misses the targets.
fn cmd_gait_check(dirs: Vec<PathBuf>, out: PathBuf, a: GaitCheckArgs) -> Result<i32> {
    use crate::study::gait_check::{CheckOptions, Targets};
    let targets = Targets {
        stance: (a.min_stance, a.max_stance),
        min_grf_r: a.min_grf_r,
        min_knee_moment_r: a.min_knee_moment_r,
        extensor_within_pct: a.extensor_within_pct,
        flexor_within: a.flexor_within,
        require_peaks: a.require_peaks,
    };
    let opts = CheckOptions {
        engine: a.engine,
        dt_s: a.dt_s,
        strides: a.strides,
        jobs: a.parallel.jobs,
        progress: !a.parallel.quiet,
        targets,
        scenario: a.scenario,
        sets: a.parallel.sets,
    };
    let report = crate::study::gait_check::gait_check(&dirs, &out, &opts)?;
    print!("{}", report.table());
    println!("outputs             {}", out.display());
    let bad = report.bad_input();
    for t in &bad {
        if let crate::study::gait_check::Outcome::BadInput(m) = &t.outcome {
            eprintln!("bad input: {}", output::text::terminal(m));
        }
    }
    let (meet, n) = report.count_meeting(report.trials.iter());
    if !bad.is_empty() {
        let msg =
            format!("{} of {n} trials are bad input (listed above); the others ran: {}", bad.len(), out.display());
        return Err(Error::input("gait-check", "", msg));
    }
    if meet < n {
        return Err(Error::Criteria(format!("{} of {n} trials miss the targets (table above)", n - meet)));
    }
    Ok(EXIT_OK)
}

/// `exoleg fmu`.
fn cmd_fmu(scenario: Option<PathBuf>, sets: Vec<String>, out: PathBuf, library: Option<PathBuf>) -> Result<i32> {
    let resolved = Scenario::load(scenario.as_deref(), &sets)?.resolve(&Resources::new())?;
    for w in &resolved.warnings {
        eprintln!("warning: {w}");
    }
    let library = library.or_else(crate::fmu::default_library).ok_or_else(|| {
        Error::Usage("cannot locate the FMU library next to this executable: pass --library PATH".into())
    })?;
    let mut inputs = crate::fsio::own_executable();
    inputs.extend(scenario);
    let r = crate::fmu::package(&resolved, &library, &out, &inputs)?;
    println!("wrote {} ({} bytes) from {}", out.display(), r.bytes, resolved.source_name);
    println!("GUID                {}", r.guid);
    println!(
        "outputs             {} (17 readings of the latest sample, the rest true_* time-series columns)",
        r.outputs
    );
    println!("input               valve_command (latched at the sample instants)");
    println!("parameters          {} (set before fmi2ExitInitializationMode)", r.parameters);
    println!("files in resources  {}", r.files);
    println!("communication step  {} s (the sample period: one reading and one command per step)", r.sample_period_s);
    Ok(EXIT_OK)
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
