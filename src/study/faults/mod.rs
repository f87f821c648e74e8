//! `exoleg faults`: the simulated-use fault campaign (issue 35). Every failure mode of a
//! matrix ([`matrix`]) at every onset (10 phases of the gait cycle by default) and every
//! severity, each run scored by what would hurt the wearer (`metrics::safety`), next to the
//! unfaulted baseline (run 0). The runs are a plan like a sweep's ([`Plan::Runs`]): jobs,
//! shards and the merge work the same, and the outputs (`faults.csv`, `faults.png`, the FMEA
//! table) follow from `runs.jsonl` ([`report`]).
//!
//! Every run goes to the device's fail-safe state when its controller stops
//! (`controller.on_stop = "failsafe"`: a stop in the field is not the end of the wearer's
//! stride). A walking run ends `observe_strides` strides after the latest its fault can start
//! (the run-in, one stride to the first heel strike, the onset's phase), so every onset is
//! watched as long and no run is longer than the scenario.

pub mod matrix;
pub mod report;

pub use matrix::{parse_matrix, read_matrix, Matrix, Mode, Severity};
pub use report::{write_outputs, CampaignReport};

use super::sweep::{Plan, MAX_RUNS};
use crate::error::{Error, Result};
use crate::scenario::{Resources, Scenario};
use serde::{Deserialize, Serialize};

/// The reading channels the default matrix faults, when the run has them: the force loop's
/// load cell and knee encoder (every controller's), and for a controller of the user's (a
/// plugin, or one passed in from Python) the device's heel sensor and the shank gyroscope's
/// sagittal axis, which the built-in controllers do not read.
pub const DEFAULT_CHANNELS: [&str; 4] = ["force_n", "knee_rad", "heel_force_n", "shank_gyro_y_rad_s"];
/// How many of [`DEFAULT_CHANNELS`] a built-in controller reads.
const BUILT_IN_CHANNELS: usize = 2;
/// The default onsets of a walking run (% of the stride after a heel strike).
pub const DEFAULT_ONSETS_PCT: [f64; 10] = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0];
/// Strides a walking run goes on after its fault's latest onset, by default.
pub const DEFAULT_OBSERVE_STRIDES: f64 = 2.0;

/// A failure mode's labels in the outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModeLabels {
    /// Its target.
    pub target: String,
    /// Its kind.
    pub kind: String,
    /// Its severities' labels.
    pub severities: Vec<String>,
}

impl ModeLabels {
    /// "target kind".
    pub fn name(&self) -> String {
        format!("{} {}", self.target, self.kind)
    }
}

/// How a campaign's runs are laid out: run 0 the baseline, then for each mode, each severity,
/// each onset, one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CampaignLayout {
    /// The failure modes, in run order.
    pub modes: Vec<ModeLabels>,
    /// The onsets: % of the stride after a heel strike, or times (s).
    pub onsets: Vec<f64>,
    /// The onsets are phases (%), not times.
    pub by_phase: bool,
}

impl CampaignLayout {
    /// Runs in the campaign (the baseline included).
    pub fn runs(&self) -> usize {
        1 + self.modes.iter().map(|m| m.severities.len() * self.onsets.len()).sum::<usize>()
    }

    /// Run `i`'s (mode, severity, onset) indices; None for the baseline or beyond the plan.
    pub fn case(&self, i: usize) -> Option<(usize, usize, usize)> {
        let mut rest = i.checked_sub(1)?;
        let n = self.onsets.len().max(1);
        for (m, mode) in self.modes.iter().enumerate() {
            let here = mode.severities.len() * n;
            if rest < here {
                return Some((m, rest / n, rest % n));
            }
            rest -= here;
        }
        None
    }

    /// An onset's label: "30 %" or "2.100 s".
    pub fn onset_label(&self, o: usize) -> String {
        let x = self.onsets.get(o).copied().unwrap_or(f64::NAN);
        if self.by_phase {
            format!("{x} %")
        } else {
            format!("{x:.3} s")
        }
    }

    /// Check a layout read from a file (a shard's `shard.json`) against its plan's runs.
    pub fn check(&self, runs: usize) -> std::result::Result<(), String> {
        let sizes_ok = self.modes.len() <= matrix::MAX_MODES
            && self.onsets.len() <= matrix::MAX_PER_AXIS
            && self.modes.iter().all(|m| m.severities.len() <= matrix::MAX_PER_AXIS);
        if !sizes_ok || self.onsets.iter().any(|x| !x.is_finite()) {
            return Err("a campaign layout beyond its bounds".into());
        }
        if self.runs() != runs {
            return Err(format!("the campaign's layout has {} runs, the plan {runs}", self.runs()));
        }
        Ok(())
    }
}

/// The valve's travel the campaign gives a scenario without one (`actuator.spool_limit_m =
/// 0`), as a multiple of the baseline's largest spool opening: a faulted controller's command
/// can run away, a real spool stops at its travel.
pub const SPOOL_TRAVEL_OVER_BASELINE: f64 = 2.0;

/// The largest |spool position| (m) of a run's rows.
#[derive(Debug, Default)]
struct PeakSpool(f64);

impl crate::record::RecordSink for PeakSpool {
    fn start(&mut self, _: &crate::record::Layout) -> Result<()> {
        Ok(())
    }
    fn row(&mut self, r: &crate::record::Row) -> Result<()> {
        self.0 = self.0.max(r.spool_m.abs());
        Ok(())
    }
}

/// `base` with a valve travel: its own, or [`SPOOL_TRAVEL_OVER_BASELINE`] times the largest
/// spool opening of its unfaulted run (with `controller`, or the scenario's), and a note
/// saying so.
fn with_spool_travel(
    base: Scenario,
    controller: Option<&super::sweep::ControllerFactory>,
    res: &Resources,
) -> Result<(Scenario, Option<String>)> {
    if base.file.actuator.spool_limit_m > 0.0 {
        return Ok((base, None));
    }
    let sc = base.resolve(res)?;
    let source = match controller {
        Some(f) => crate::sim::ControllerSource::Discrete(f(&sc)?),
        None => crate::sim::ControllerSource::Model,
    };
    let sim = crate::sim::Simulation::build(sc.model.clone(), source)?;
    let mut peak = PeakSpool::default();
    crate::session::run_cancellable(sim, &mut peak, None)
        .map_err(|e| Error::input(&base.source_name, "campaign baseline", format!("the unfaulted run failed: {e}")))?;
    if !(peak.0 > 0.0 && peak.0.is_finite()) {
        return Err(Error::input(
            &base.source_name,
            "actuator.spool_limit_m",
            "the unfaulted run never opens the valve: set the valve's travel",
        ));
    }
    let travel = matrix::sig3(SPOOL_TRAVEL_OVER_BASELINE * peak.0);
    let note = format!(
        "actuator.spool_limit_m is 0 (no travel stop): the campaign gives the spool a travel of {travel} m, {SPOOL_TRAVEL_OVER_BASELINE}x the unfaulted run's largest opening ({:.4e} m); set your valve's to override",
        peak.0
    );
    Ok((base.with_sets(&[format!("actuator.spool_limit_m={travel:?}")])?, Some(note)))
}

/// A campaign ready to run.
#[derive(Debug, Clone)]
pub struct Campaign {
    /// What the user should know (printed): the valve travel the campaign chose.
    pub notes: Vec<String>,
    /// The scenario its runs start from (the base with `controller.on_stop = "failsafe"`).
    pub base: Scenario,
    /// Its runs.
    pub plan: Plan,
    /// How they are laid out.
    pub layout: CampaignLayout,
    /// The matrix run.
    pub matrix: Matrix,
}

/// What the campaign needs to know about the base scenario.
struct BaseFacts {
    walking: bool,
    /// The controller is the user's (reads the device's channels).
    users: bool,
    sampled: bool,
    stride_s: Option<f64>,
    settle_s: f64,
    duration_s: f64,
}

fn base_facts(base: &Scenario, external: bool, res: &Resources) -> Result<BaseFacts> {
    let sc = base.resolve(res)?;
    let m = &sc.model;
    if m.leg().is_none() {
        return Err(Error::input(
            &base.source_name,
            "plant.kind",
            "a fault campaign scores what would hurt the wearer: it needs a leg (plant.kind = \"leg\")",
        ));
    }
    if !sc.file.faults.is_empty() {
        return Err(Error::input(
            &base.source_name,
            "faults",
            "the campaign places its own faults: remove [[faults]] from the scenario (or run it with `exoleg run`)",
        ));
    }
    Ok(BaseFacts {
        walking: m.walking(),
        users: external || sc.file.controller.kind == crate::control::ControllerKind::Plugin,
        sampled: m.sample_every.is_some(),
        stride_s: m.reference.stride_s(),
        settle_s: sc.file.metrics.settle_s,
        duration_s: sc.file.sim.duration_s,
    })
}

/// The default matrix of a run: the sensor modes on each of [`DEFAULT_CHANNELS`] it has and
/// the controller's timing modes (a sampled controller), the valve, leakage, supply and power
/// modes; onsets at [`DEFAULT_ONSETS_PCT`] of the stride (walking), or spread over one stride
/// (or the first half of the run after the run-in) otherwise.
fn default_matrix(base: &Scenario, f: &BaseFacts) -> Matrix {
    let mut modes = Vec::new();
    if f.sampled {
        let n = if f.users { DEFAULT_CHANNELS.len() } else { BUILT_IN_CHANNELS };
        for ch in &DEFAULT_CHANNELS[..n] {
            if let (true, Some(fs)) =
                (crate::scenario::reading_available(&base.file.sensors, true, ch), matrix::full_scale(ch))
            {
                modes.extend(matrix::sensor_modes(ch, fs));
            }
        }
    }
    modes.extend(matrix::actuator_modes());
    if f.sampled {
        modes.extend(matrix::controller_modes());
    }
    if f.walking {
        return Matrix { onsets_pct: Some(DEFAULT_ONSETS_PCT.to_vec()), onsets_s: None, modes };
    }
    let span = f.stride_s.filter(|s| f.settle_s + s < f.duration_s).unwrap_or(0.5 * (f.duration_s - f.settle_s));
    let onsets = (0..10).map(|k| f.settle_s + span * k as f64 / 10.0).map(|t| (t * 1e4).round() / 1e4).collect();
    Matrix { onsets_pct: None, onsets_s: Some(onsets), modes }
}

/// One fault entry as an inline TOML table (a run's `faults=[...]` override).
fn fault_entry(mode: &Mode, sev: &Severity, onset: (bool, f64)) -> String {
    let mut t = toml::Table::new();
    t.insert("target".into(), mode.target.clone().into());
    t.insert("kind".into(), mode.kind.clone().into());
    if onset.0 {
        t.insert("onset_event".into(), "heel_strike".into());
        t.insert("onset_phase_pct".into(), onset.1.into());
    } else {
        t.insert("onset_s".into(), onset.1.into());
    }
    for (k, v) in &sev.keys {
        t.insert(k.clone(), v.clone());
    }
    format!("faults=[{}]", toml::Value::Table(t))
}

/// The run length (s) for an onset: the base's, or (walking, by phase) `observe` strides
/// after the latest the fault can start, rounded up to the millisecond.
fn run_length(f: &BaseFacts, by_phase: bool, onset: f64, observe: f64) -> Option<f64> {
    let stride = f.stride_s?;
    if !(by_phase && observe > 0.0) {
        return None;
    }
    let d = f.settle_s + (1.0 + onset / 100.0 + observe) * stride;
    let d = (d * 1e3).ceil() / 1e3;
    (d < f.duration_s).then_some(d)
}

/// The campaign of `base` with `matrix` (None: the default for the scenario), walking runs
/// watched `observe_strides` strides after the latest onset (0: the scenario's duration);
/// `controller`: the runs' controller when it is the caller's (it may read the device's
/// channels). A scenario without a valve travel gets one ([`SPOOL_TRAVEL_OVER_BASELINE`]).
/// Every mode and severity is resolved once before anything runs: a bad one is an error
/// naming it.
pub fn campaign(
    base: &Scenario,
    matrix: Option<Matrix>,
    observe_strides: f64,
    controller: Option<&super::sweep::ControllerFactory>,
    res: &Resources,
) -> Result<Campaign> {
    if !(observe_strides.is_finite() && (0.0..=1000.0).contains(&observe_strides)) {
        return Err(Error::input("--observe-strides", observe_strides.to_string(), "must be in 0..=1000 strides"));
    }
    let base = base.with_sets(&["controller.on_stop=\"failsafe\"".to_string()])?;
    let facts = base_facts(&base, controller.is_some(), res)?;
    let (base, note) = with_spool_travel(base, controller, res)?;
    let from_file = matrix.is_some();
    let matrix = match matrix {
        Some(m) => m,
        None => default_matrix(&base, &facts),
    };
    let name = if from_file { "--matrix" } else { "the default matrix" };
    matrix.check(name)?;
    let (by_phase, onsets) = match (&matrix.onsets_pct, &matrix.onsets_s) {
        (Some(p), None) if facts.walking => (true, p.clone()),
        (Some(_), None) => {
            return Err(Error::input(name, "onsets_pct", "phases need a walking run (gait events): give onsets_s"))
        }
        (None, Some(s)) => (false, s.clone()),
        _ => return Err(Error::input(name, "onsets", "give onsets_pct (walking) or onsets_s")),
    };
    if matrix.modes.is_empty() {
        return Err(Error::input(
            &base.source_name,
            "faults",
            format!("no fault of {name} applies to this scenario (a continuous controller has no readings to fault; a matrix needs [[mode]] entries)"),
        ));
    }
    let mut runs = vec![vec!["faults=[]".to_string()]];
    for (i, mode) in matrix.modes.iter().enumerate() {
        for (j, sev) in mode.severities.iter().enumerate() {
            for (k, &o) in onsets.iter().enumerate() {
                let mut sets = vec![fault_entry(mode, sev, (by_phase, o))];
                if let Some(d) = run_length(&facts, by_phase, o, observe_strides) {
                    sets.push(format!("sim.duration_s={d:?}"));
                }
                if k == 0 {
                    // Each mode and severity resolved once: a bad one named before anything runs.
                    base.with_sets(&sets).and_then(|s| s.resolve(res)).map_err(|e| {
                        Error::input(
                            name,
                            format!("mode.{i}.severity.{j}"),
                            format!("`{}` `{}`: {e}", mode.name(), sev.label),
                        )
                    })?;
                }
                runs.push(sets);
                if runs.len() > MAX_RUNS {
                    return Err(Error::input(name, "mode", format!("more than {MAX_RUNS} runs (the cap)")));
                }
            }
        }
    }
    let layout = CampaignLayout {
        modes: matrix
            .modes
            .iter()
            .map(|m| ModeLabels {
                target: m.target.clone(),
                kind: m.kind.clone(),
                severities: m.severities.iter().map(|s| s.label.clone()).collect(),
            })
            .collect(),
        onsets,
        by_phase,
    };
    Ok(Campaign { notes: note.into_iter().collect(), base, plan: Plan::Runs(runs), layout, matrix })
}
