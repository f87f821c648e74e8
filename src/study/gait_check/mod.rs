//! `exoleg gait-check`: every trial of folders of gait CSVs, each folder with its
//! `subjects.csv` (`reference::subjects`), run with its subject's numbers alone (the built-in
//! leg scaled to the subject, the trial's belt speed and stride time, the data's pelvis tilt),
//! in parallel, and compared with its data: a table (printed, and `gait_check.csv`) and a
//! figure per trial (`figures/FOLDER/TRIAL.png`: knee moment, vertical ground reaction and
//! knee angle over the cycle, simulated against the data), written as one output folder.
//!
//! A trial's bad input (its row, its CSV, a file without a row) is that trial's: the others
//! run and the report lists it. A folder without a readable `subjects.csv` stops the check
//! before anything runs.

use crate::error::{Error, Result};
use crate::metrics::walking::{lowpass, CycleBins, KINETICS_LOWPASS_HZ};
use crate::metrics::{ContactSummary, DatasetComparison};
use crate::record::{Layout, RecordSink, Row};
use crate::reference::{read_subjects, TrialRow};
use crate::scenario::{Resources, Scenario};
use std::path::{Path, PathBuf};

mod report;

/// The base scenario of every trial: `assets/scenarios/treadmill_subject.toml` (dtznn at 1 kHz,
/// no assistance, the compliant sole, the wearer's impedances), the trial's numbers set on it.
pub const BASE_SCENARIO_TOML: &str = include_str!("../../../assets/scenarios/treadmill_subject.toml");
/// The base scenario's name in messages.
pub const BASE_SCENARIO_NAME: &str = "<built-in treadmill_subject.toml>";
/// A peak of the data's knee moment smaller than this (N m) has no timing or size to compare
/// (subject 02's loading response has almost none): its check reads `n/a`.
pub const PEAK_MIN_NM: f64 = 10.0;
/// The columns a trial's CSV needs besides `gait_cycle_pct` and `knee_flexion_deg`
/// (`pelvis_tilt_deg` is optional: without it a constant 10 deg is assumed and said).
pub const TRIAL_COLUMNS: [&str; 6] = [
    "hip_flexion_deg",
    "ankle_dorsiflexion_deg",
    "hip_moment_nm_per_kg",
    "knee_moment_nm_per_kg",
    "ankle_moment_nm_per_kg",
    "grf_vertical_n_per_kg",
];

/// What a trial must meet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Targets {
    /// Stance fraction of the stride, (lowest, highest).
    pub stance: (f64, f64),
    /// Least correlation of the vertical ground reaction with the data's.
    pub min_grf_r: f64,
    /// Least correlation of the stance (0-61 %) knee moment with the data's.
    pub min_knee_moment_r: f64,
    /// The loading-response extensor peak within this many % of the cycle of the data's.
    pub extensor_within_pct: f64,
    /// The mid-stance flexor peak within this fraction of the data's magnitude.
    pub flexor_within: f64,
    /// The two peak checks count toward the verdict (else they are reported only).
    pub require_peaks: bool,
}

impl Default for Targets {
    fn default() -> Self {
        Self {
            stance: (0.45, 0.70),
            min_grf_r: 0.8,
            min_knee_moment_r: 0.7,
            extensor_within_pct: 5.0,
            flexor_within: 0.5,
            require_peaks: false,
        }
    }
}

/// How to run the check.
#[derive(Debug, Clone)]
pub struct CheckOptions {
    /// `leg.engine`: `reduced` or `rapier`.
    pub engine: String,
    /// The step (s); None: 1 ms on the reduced engine, 0.25 ms on Rapier.
    pub dt_s: Option<f64>,
    /// Strides per trial, the first the run-in (>= 2).
    pub strides: usize,
    /// Worker threads (0 = all cores).
    pub jobs: usize,
    /// Progress bar on stderr.
    pub progress: bool,
    /// The targets.
    pub targets: Targets,
    /// The base scenario file (None: [`BASE_SCENARIO_TOML`]).
    pub scenario: Option<PathBuf>,
    /// Overrides applied to every trial's scenario before its own numbers.
    pub sets: Vec<String>,
}

impl Default for CheckOptions {
    fn default() -> Self {
        Self {
            engine: "reduced".into(),
            dt_s: None,
            strides: 6,
            jobs: 0,
            progress: false,
            targets: Targets::default(),
            scenario: None,
            sets: Vec::new(),
        }
    }
}

impl CheckOptions {
    /// The step (s) the trials run at.
    pub fn step_s(&self) -> f64 {
        self.dt_s.unwrap_or(if self.engine == "rapier" { 0.00025 } else { 0.001 })
    }

    fn check(&self) -> Result<()> {
        if self.engine != "reduced" && self.engine != "rapier" {
            return Err(Error::input("gait-check", "--engine", format!("{:?}: give reduced or rapier", self.engine)));
        }
        let dt = self.step_s();
        if !(dt.is_finite() && (1e-6..=0.01).contains(&dt)) {
            return Err(Error::input("gait-check", "--dt", format!("{dt} s: give 1e-6..=0.01 s")));
        }
        if !(2..=100).contains(&self.strides) {
            return Err(Error::input("gait-check", "--strides", format!("{}: give 2..=100", self.strides)));
        }
        self.targets.check()
    }
}

impl Targets {
    /// Every target a trial could meet: finite, within its range, the stance's lowest below
    /// its highest (an impossible target is bad input, exit 2, not every trial missing it).
    pub fn check(&self) -> Result<()> {
        let t = self;
        for (flag, v, lo, hi) in [
            ("--min-stance", t.stance.0, 0.0, 1.0),
            ("--max-stance", t.stance.1, 0.0, 1.0),
            ("--min-grf-r", t.min_grf_r, -1.0, 1.0),
            ("--min-knee-moment-r", t.min_knee_moment_r, -1.0, 1.0),
            ("--extensor-within-pct", t.extensor_within_pct, 0.0, 100.0),
            ("--flexor-within", t.flexor_within, 0.0, 100.0),
        ] {
            if !(lo..=hi).contains(&v) {
                return Err(Error::input("gait-check", flag, format!("{v}: give {lo}..={hi}")));
            }
        }
        if t.stance.0 >= t.stance.1 {
            let msg = format!("{} is not below --max-stance {}: no stance meets both", t.stance.0, t.stance.1);
            return Err(Error::input("gait-check", "--min-stance", msg));
        }
        Ok(())
    }
}

/// One trial found in a folder.
#[derive(Debug)]
struct Trial {
    /// The folder's label in the report (its name).
    folder: String,
    /// The trial's name (its CSV's stem, or `subjects.csv row N` for an unreadable row).
    name: String,
    /// Its CSV.
    path: PathBuf,
    /// Its row, or why there is none.
    row: Result<TrialRow>,
}

/// The simulated and the data's curves of a trial over the cycle (at 0.5, 1.5, ... %).
#[derive(Debug, Clone, Default)]
pub struct Curves {
    /// Knee moment (N m, extensor +; both low-passed at 10 Hz as the comparison), sim / data.
    pub knee_moment_nm: [Vec<f64>; 2],
    /// Vertical ground reaction (N; low-passed at 10 Hz), sim / data.
    pub grf_n: [Vec<f64>; 2],
    /// Knee flexion (deg), sim / data.
    pub knee_deg: [Vec<f64>; 2],
    /// The data's stance, heel strike and toe-off (% of the cycle).
    pub stance_pct: (f64, f64),
}

/// What a trial that ran gave.
#[derive(Debug, Clone)]
pub struct Figures {
    /// The run's contact figures (stance, knee RMS, not-walking flags).
    pub contact: ContactSummary,
    /// Its comparison with the data.
    pub dataset: DatasetComparison,
    /// The curves of its figure.
    pub curves: Curves,
    /// What the wearer's muscles cost (`--set wearer.muscles=true`).
    pub metabolics: Option<crate::metrics::muscles::MetabolicsSummary>,
}

impl Figures {
    /// The extensor peak within the targets' timing of the data's (None: the data's peak is
    /// under [`PEAK_MIN_NM`]).
    pub fn extensor_timing_ok(&self, t: &Targets) -> Option<bool> {
        let d = &self.dataset;
        (d.data_extensor_peak_nm >= PEAK_MIN_NM)
            .then(|| (d.extensor_peak_pct - d.data_extensor_peak_pct).abs() <= t.extensor_within_pct + 1e-9)
    }

    /// The flexor peak within the targets' fraction of the data's magnitude (None: the data's
    /// peak is under [`PEAK_MIN_NM`]).
    pub fn flexor_size_ok(&self, t: &Targets) -> Option<bool> {
        let d = &self.dataset;
        (d.data_flexor_peak_nm <= -PEAK_MIN_NM)
            .then(|| (d.flexor_peak_nm / d.data_flexor_peak_nm - 1.0).abs() <= t.flexor_within + 1e-9)
    }

    /// Why the trial misses the targets (empty: it meets them).
    pub fn misses(&self, t: &Targets) -> Vec<String> {
        let (c, d) = (&self.contact, &self.dataset);
        let mut why = Vec::new();
        if !(t.stance.0..=t.stance.1).contains(&c.stance_fraction) {
            why.push(format!("stance {:.3} outside {}..{}", c.stance_fraction, t.stance.0, t.stance.1));
        }
        // A NaN correlation (a flat curve) misses the target too.
        if d.grf_correlation.is_nan() || d.grf_correlation < t.min_grf_r {
            why.push(format!("GRF r {:.3} < {}", d.grf_correlation, t.min_grf_r));
        }
        if d.knee_moment_stance_correlation.is_nan() || d.knee_moment_stance_correlation < t.min_knee_moment_r {
            why.push(format!("knee moment r {:.3} < {}", d.knee_moment_stance_correlation, t.min_knee_moment_r));
        }
        match &c.not_walking {
            Some(flags) if !flags.is_empty() => why.push(format!("not walking: {}", flags.join("; "))),
            Some(_) => {}
            None => why.push("not walking: not evaluated (no row after the run-in)".into()),
        }
        if t.require_peaks && self.extensor_timing_ok(t) == Some(false) {
            why.push("extensor peak timing".into());
        }
        if t.require_peaks && self.flexor_size_ok(t) == Some(false) {
            why.push("flexor peak size".into());
        }
        why
    }
}

/// How a trial ended.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// It ran; its figures.
    Ran(Box<Figures>),
    /// Its input is bad (its row, its CSV, its scenario): the message names file, row, column.
    BadInput(String),
    /// The simulation failed (diverged, too stiff, a panic): the message says when and why.
    Failed(String),
}

/// One trial of the report.
#[derive(Debug, Clone)]
pub struct TrialResult {
    /// The folder's label.
    pub folder: String,
    /// The trial's name.
    pub name: String,
    /// Its row, when it was readable.
    pub row: Option<TrialRow>,
    /// How it ended.
    pub outcome: Outcome,
}

impl TrialResult {
    /// It ran and meets the targets.
    pub fn meets(&self, t: &Targets) -> bool {
        matches!(&self.outcome, Outcome::Ran(f) if f.misses(t).is_empty())
    }
}

/// The trials of the folders, in folder order, each folder's in its table's order, then the
/// CSVs without a row (sorted). A folder without a readable `subjects.csv` is an error.
fn discover(dirs: &[PathBuf]) -> Result<Vec<Trial>> {
    let mut trials = Vec::new();
    let mut labels: Vec<String> = Vec::new();
    for dir in dirs {
        let mut label = dir.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().to_string());
        if labels.contains(&label) {
            label = format!("{label}_{}", labels.len() + 1);
        }
        labels.push(label.clone());
        let table = dir.join("subjects.csv");
        let name = table.display().to_string();
        let text = crate::scenario::read_capped(&table, crate::scenario::MAX_INPUT_FILE_BYTES)?;
        let rows = read_subjects(&name, &text)?;
        let mut csvs = folder_csvs(dir)?;
        for r in rows {
            // A row claims the file it names, read or not: its problem is that trial's.
            let claimed = csvs.iter().position(|c| *c == r.file).map(|i| csvs.remove(i));
            let path = dir.join(&r.file);
            let row = match (r.row, claimed) {
                (Err(e), _) => Err(e),
                (Ok(row), Some(_)) => Ok(row),
                (Ok(row), None) => {
                    let known = trials.iter().any(|t: &Trial| t.path == path);
                    let why = if known {
                        format!("{} has a row already", row.file)
                    } else {
                        format!("no file {} in {}", row.file, dir.display())
                    };
                    Err(Error::input(&name, format!("row {}, file", row.line), why))
                }
            };
            let trial_name = match r.file.strip_suffix(".csv") {
                Some(stem) if !stem.is_empty() && !stem.contains(['/', '\\']) => stem.to_string(),
                _ => format!("subjects.csv row {}", r.line),
            };
            trials.push(Trial { folder: label.clone(), name: trial_name, path, row });
        }
        for c in csvs {
            let path = dir.join(&c);
            let e = Error::input(path.display().to_string(), "subjects.csv", format!("no row for {c} in {name}"));
            trials.push(Trial {
                folder: label.clone(),
                name: c.trim_end_matches(".csv").to_string(),
                path,
                row: Err(e),
            });
        }
    }
    Ok(trials)
}

/// The names in `dir` ending in `.csv` other than `subjects.csv`, sorted: whatever is there (a
/// link, a FIFO, a device: the trial's reader says what it is and why it is refused, never
/// "no file").
fn folder_csvs(dir: &Path) -> Result<Vec<String>> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::Read { path: dir.to_path_buf(), message: e.to_string() })?;
    let mut out: Vec<String> = rd
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.ends_with(".csv") && n != "subjects.csv")
        .collect();
    out.sort();
    Ok(out)
}

/// The scenario overrides of a trial: its data, timing, belt, subject, engine and step.
fn trial_sets(row: &TrialRow, path: &Path, opts: &CheckOptions) -> Vec<String> {
    let dt = opts.step_s();
    let duration = (opts.strides as f64 * row.stride_s / dt).round() * dt;
    let file = toml::Value::String(path.display().to_string()).to_string();
    let sex = if row.sex == crate::leg::subject::Sex::Male { "male" } else { "female" };
    let mut sets = vec![
        format!("reference.gait_file={file}"),
        format!("reference.stride_s={:?}", row.stride_s),
        format!("ground.belt_speed_m_s={:?}", row.speed_m_s),
        format!("leg.engine=\"{}\"", opts.engine),
        format!("sim.dt_s={dt:?}"),
        format!("sim.duration_s={duration:?}"),
        format!("metrics.settle_s={:?}", row.stride_s),
        format!("subject={{mass_kg={:?}, height_m={:?}, sex=\"{sex}\"}}", row.mass_kg, row.height_m),
    ];
    if let Some(l) = row.leg_length_m {
        sets.push(format!("subject.leg_length_m={l:?}"));
    }
    sets
}

/// Read and check a trial's CSV: the gait reader's checks (rows, numbers, the cycle) and the
/// columns a comparison needs.
fn check_trial_csv(path: &Path) -> Result<()> {
    let name = path.display().to_string();
    let text = crate::scenario::read_capped(path, crate::scenario::MAX_INPUT_FILE_BYTES)?;
    let cycle = crate::reference::GaitCycle::parse(&name, &text, 12)?;
    let has = |c: &str| match c {
        "hip_flexion_deg" => cycle.hip.is_some(),
        "ankle_dorsiflexion_deg" => cycle.ankle.is_some(),
        _ => cycle.kinetic(c).is_some(),
    };
    match TRIAL_COLUMNS.iter().find(|c| !has(c)) {
        Some(c) => Err(Error::input(&name, *c, "missing column (gait-check compares the run with it)")),
        None => Ok(()),
    }
}

/// Bins a run's rows after the run-in: ground reaction, knee moment, knee angle and the data's.
struct CycleSink {
    settle_s: f64,
    stride_s: f64,
    bins: CycleBins<4>,
}

impl RecordSink for CycleSink {
    fn start(&mut self, _layout: &Layout) -> Result<()> {
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        if let (Some(c), Some(l), Some(q)) = (r.contact, r.leg, r.ref_knee_deg) {
            if r.t_s >= self.settle_s - 1e-9 {
                let v = [c.ground_reaction_vertical_n, c.knee_moment_nm, l.knee_angle_deg, q];
                self.bins.add(r.t_s, self.stride_s, v);
            }
        }
        Ok(())
    }
}

/// The curves of a run (`bins`) against its data (`sc`'s walking data).
fn curves(sc: &crate::scenario::ResolvedScenario, bins: &CycleBins<4>, stride_s: f64) -> Option<Curves> {
    let body = sc.model.leg()?.body.as_ref()?;
    let crate::human::BodyTargets::Walking(w) = &body.targets else { return None };
    let keep = (KINETICS_LOWPASS_HZ * stride_s).floor() as usize;
    let data = |f: &dyn Fn(f64) -> f64| lowpass(&(0..100).map(|i| f(i as f64 + 0.5)).collect::<Vec<_>>(), keep);
    Some(Curves {
        knee_moment_nm: [lowpass(&bins.mean(1)?, keep), data(&|p| w.knee_moment_at_pct(p))],
        grf_n: [lowpass(&bins.mean(0)?, keep), data(&|p| w.grf_at_pct(p))],
        knee_deg: [bins.mean(2)?, bins.mean(3)?],
        stance_pct: w.stance_pct,
    })
}

/// Run one trial (its scenario from `base`, its own numbers on top).
fn run_trial(t: &Trial, base: &Scenario, opts: &CheckOptions, res: &Resources) -> TrialResult {
    let result =
        |row: Option<TrialRow>, outcome| TrialResult { folder: t.folder.clone(), name: t.name.clone(), row, outcome };
    let row = match &t.row {
        Ok(r) => r.clone(),
        Err(e) => return result(None, Outcome::BadInput(e.to_string())),
    };
    if let Err(e) = check_trial_csv(&t.path) {
        return result(Some(row), Outcome::BadInput(e.to_string()));
    }
    // The scenario's errors name its keys: say which trial they are about.
    let sc = match base.with_sets(&trial_sets(&row, &t.path, opts)).and_then(|s| s.resolve(res)) {
        Ok(sc) => sc,
        Err(e) => return result(Some(row), Outcome::BadInput(format!("{}: {e}", t.path.display()))),
    };
    let mut sink = CycleSink { settle_s: row.stride_s, stride_s: row.stride_s, bins: CycleBins::default() };
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| crate::session::run(&sc.model, &mut sink)))
        .unwrap_or_else(|p| {
            Err(Error::Usage(format!("internal error (a panic): {}", super::sweep::panic_message(&p))))
        });
    let outcome = match run {
        Err(e) => Outcome::Failed(e.to_string()),
        Ok(summary) => match (summary.contact, curves(&sc, &sink.bins, row.stride_s)) {
            (Some(contact), Some(curves)) => match contact.dataset.clone() {
                Some(dataset) => {
                    let metabolics = summary.wearer.and_then(|w| w.metabolics);
                    Outcome::Ran(Box::new(Figures { contact, dataset, curves, metabolics }))
                }
                None => Outcome::Failed("no stride to compare with the data".into()),
            },
            _ => Outcome::Failed("the run has no ground contact to compare with the data".into()),
        },
    };
    result(Some(row), outcome)
}

/// The check's result.
#[derive(Debug, Clone)]
pub struct Report {
    /// Every trial, in folder and table order.
    pub trials: Vec<TrialResult>,
    /// The targets.
    pub targets: Targets,
    /// The engine and step the trials ran at.
    pub engine: (String, f64),
    /// Wall time of the runs (s).
    pub wall_s: f64,
}

/// Run every trial of `dirs` into the output folder `out` (the table and the figures, written
/// as one folder: a temporary folder renamed into place).
pub fn gait_check(dirs: &[PathBuf], out: &Path, opts: &CheckOptions) -> Result<Report> {
    use rayon::prelude::*;
    opts.check()?;
    if let Some(d) = dirs.iter().find(|d| crate::output::within(out, d)) {
        let msg = format!("is inside the gait folder {}: give a folder outside it", d.display());
        return Err(Error::input("--out", out.display().to_string(), msg));
    }
    let trials = discover(dirs)?;
    let base = match &opts.scenario {
        Some(p) => Scenario::load(Some(p), &opts.sets)?,
        None => Scenario::from_toml_str(BASE_SCENARIO_NAME, BASE_SCENARIO_TOML, &opts.sets)?,
    };
    let dir = crate::output::OutputDir::prepare_with_inputs(out, "--out", dirs)?;
    let res = Resources::new();
    let pool = super::sweep::pool(opts.jobs, trials.len())?;
    let bar = super::sweep::progress_bar(opts.progress && trials.len() > 1, trials.len());
    let start = std::time::Instant::now();
    let results: Vec<TrialResult> = pool.install(|| {
        trials
            .par_iter()
            .map(|t| {
                let r = run_trial(t, &base, opts, &res);
                bar.inc(1);
                r
            })
            .collect()
    });
    bar.finish_and_clear();
    let report =
        Report { trials: results, targets: opts.targets, engine: (opts.engine.clone(), opts.step_s()), wall_s: 0.0 };
    pool.install(|| report.trials.par_iter().try_for_each(|t| write_figure(t, &report.targets, dir.path())))?;
    crate::output::write_atomic(&dir.path().join("gait_check.csv"), report.csv().as_bytes())?;
    dir.commit()?;
    Ok(Report { wall_s: start.elapsed().as_secs_f64(), ..report })
}

/// The figure of a trial that ran: `figures/FOLDER/TRIAL.png`.
fn write_figure(t: &TrialResult, targets: &Targets, root: &Path) -> Result<()> {
    use crate::output::{Panel, Series};
    use plotters::style::{BLACK, BLUE};
    let Outcome::Ran(f) = &t.outcome else { return Ok(()) };
    let folder = root.join("figures").join(&t.folder);
    std::fs::create_dir_all(&folder).map_err(|e| Error::Write { path: folder.clone(), message: e.to_string() })?;
    let pct: Vec<f64> = (0..100).map(|i| i as f64 + 0.5).collect();
    let pts = |v: &[f64]| -> Vec<(f64, f64)> { pct.iter().copied().zip(v.iter().copied()).collect() };
    let pair =
        |v: &[Vec<f64>; 2]| -> Vec<Series> { vec![("data", pts(&v[1]), BLACK), ("simulated", pts(&v[0]), BLUE)] };
    let c = &f.curves;
    let panels = [
        Panel { y_label: "knee moment (N m, extensor +)", series: pair(&c.knee_moment_nm) },
        Panel { y_label: "vertical ground reaction (N)", series: pair(&c.grf_n) },
        Panel { y_label: "knee flexion (deg)", series: pair(&c.knee_deg) },
    ];
    let (hs, to) = c.stance_pct;
    let shade = if hs < to { vec![(hs, to)] } else { vec![(0.0, to), (hs, 100.0)] };
    let misses = f.misses(targets);
    let verdict =
        if misses.is_empty() { "meets the targets".to_string() } else { format!("misses: {}", misses.join(", ")) };
    let title = format!(
        "{}/{}: stance {:.3}, GRF r {:.3}, knee moment r {:.3}; {verdict}",
        t.folder,
        t.name,
        f.contact.stance_fraction,
        f.dataset.grf_correlation,
        f.dataset.knee_moment_stance_correlation
    );
    let path = folder.join(format!("{}.png", t.name));
    crate::output::panels_png(
        &path,
        &title,
        "% of the gait cycle (the data's stance shaded)",
        (0.0, 100.0),
        &panels,
        &shade,
    )
}
