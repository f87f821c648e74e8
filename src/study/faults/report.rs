//! A fault campaign's outputs, from its `runs.jsonl` (written by the campaign or by the merge
//! of its shards): `faults.csv` (one row per run with every safety outcome), `faults.png` (the
//! heat map: failure mode x onset, coloured by the worst margin to a safety limit over the
//! severities), `fmea.csv` and `fmea.md` (per failure mode: the worst onset and outcome,
//! detection, time to the safe state). When the runs have the wearer's muscles (`wearer.model
//! = "muscles"` or `wearer.muscles = true`), `faults.csv`'s `gross_w_per_kg` and
//! `metabolic_change_pct` (against the baseline) are filled and `faults_metabolic.png` maps
//! the metabolic change as `faults.png` maps the margins.
//!
//! A run's use of a limit: value / limit; for the knee's ranges (the wearer's, the URDF's)
//! 1 + e / margin, e the knee's excursion beyond the range (deg; negative inside it) and the
//! margin `safety.knee_margin_deg`, so 0 at the data's own range and 1 at its edge. Its margin
//! is 100 % x (1 - the largest use). A hazard: a criterion broken (or a run that failed). A
//! fault-induced hazard: one the baseline does not break, or breaks by at least 10 points of
//! the limit less.

use super::CampaignLayout;
use crate::error::{Error, Result};
use crate::metrics::{ControllerStopReport, SafetySummary};
use crate::study::sweep::RunLine;
use std::io::BufRead;
use std::path::Path;

/// Points of a limit (use) by which a fault must worsen a criterion the baseline already breaks
/// for it to count as fault-induced.
pub const WORSE_BY: f64 = 0.1;

/// What a campaign found.
#[derive(Debug, Clone, Default)]
pub struct CampaignReport {
    /// The report's title line.
    pub title: String,
    /// Runs (the baseline included).
    pub runs: usize,
    /// Runs that break a safety criterion or failed (the baseline included).
    pub hazard_runs: usize,
    /// Faulted runs with a fault-induced hazard.
    pub fault_induced_runs: usize,
    /// The criteria the baseline breaks.
    pub baseline_broken: Vec<String>,
    /// The FMEA table (Markdown).
    pub fmea: String,
}

/// One run's outcome.
#[derive(Debug, Clone, Default)]
struct Outcome {
    /// Its worst margin (%); None: the run failed.
    margin_pct: Option<f64>,
    /// The criterion with the worst margin (or the failure).
    worst: String,
    /// Each criterion's use of its limit.
    uses: Vec<(String, f64, bool)>,
    broken: Vec<String>,
    induced: Vec<String>,
    safety: Option<SafetySummary>,
    error: Option<String>,
    /// The controller crashed (`error` says how): its figures are the failsafe's.
    crashed: bool,
    /// The wearer's gross metabolic rate (W/kg), when the run has the wearer's muscles.
    gross_w_per_kg: Option<f64>,
}

impl Outcome {
    /// A hazard the fault caused: a failed run or a crashed controller (unless the baseline's
    /// crashed too), or a criterion it broke beyond the baseline.
    fn fault_induced(&self, baseline: Option<&Outcome>) -> bool {
        let both_crashed = self.crashed && baseline.is_some_and(|b| b.crashed);
        (self.error.is_some() && !both_crashed) || !self.induced.is_empty()
    }
}

/// Each verdict's use of its limit (see the module doc), with its pass.
fn uses(s: &SafetySummary, margin_deg: f64) -> Vec<(String, f64, bool)> {
    let range_use = |range: Option<[f64; 2]>| {
        let (Some([lo, hi]), Some([qmin, qmax])) = (range, s.knee_range_deg) else { return 0.0 };
        let e = (lo - qmin).max(qmax - hi);
        if margin_deg > 0.0 {
            (1.0 + e / margin_deg).max(0.0)
        } else if e > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    };
    s.verdicts
        .iter()
        .map(|v| {
            let u = match v.criterion.as_str() {
                "beyond_wearer_range_s" => range_use(s.wearer_knee_range_deg),
                "beyond_urdf_limits_s" => range_use(Some(s.urdf_knee_limits_deg)),
                _ if v.limit > 0.0 => v.value / v.limit,
                _ => f64::from(u8::from(!v.pass)) * f64::INFINITY,
            };
            // A broken verdict uses more than its limit, whatever the rounding.
            let u = if v.pass { u } else { u.max(1.0 + 1e-9) };
            (v.criterion.clone(), if u.is_nan() { f64::INFINITY } else { u }, v.pass)
        })
        .collect()
}

/// A run whose controller crashed (a signal, an exception) under the campaign's failsafe: a
/// hazard like a failed run, whatever its figures (they are the failsafe's, kept in
/// `faults.csv`); its reason is the row's `error`.
fn crashed(line: &RunLine, safety: Option<SafetySummary>) -> Option<Outcome> {
    let why = line.summary.as_ref()?.controller_crash()?;
    Some(Outcome { worst: "controller crashed".into(), error: Some(why), crashed: true, safety, ..Default::default() })
}

fn outcome(line: &RunLine, margin_deg: f64, baseline: Option<&Outcome>) -> Outcome {
    let gross_w_per_kg =
        line.summary.as_ref().and_then(|s| s.wearer.as_ref()?.metabolics.as_ref()).map(|m| m.gross_w_per_kg);
    Outcome { gross_w_per_kg, ..safety_outcome(line, margin_deg, baseline) }
}

/// [`outcome`]'s safety verdicts.
fn safety_outcome(line: &RunLine, margin_deg: f64, baseline: Option<&Outcome>) -> Outcome {
    let Some(s) = line.summary.as_ref().and_then(|s| s.safety.clone()) else {
        if let Some(o) = crashed(line, None) {
            return o;
        }
        let error = line.error.clone().unwrap_or_else(|| "no safety figures (not a leg run)".into());
        return Outcome { worst: "failed".into(), error: Some(error), ..Default::default() };
    };
    if let Some(o) = crashed(line, Some(s.clone())) {
        return o;
    }
    let uses = uses(&s, margin_deg);
    let worst = uses.iter().max_by(|a, b| a.1.total_cmp(&b.1));
    let margin_pct = Some(worst.map_or(100.0, |w| 100.0 * (1.0 - w.1)));
    let broken: Vec<String> = uses.iter().filter(|u| !u.2).map(|u| u.0.clone()).collect();
    let induced = uses
        .iter()
        .filter(|u| !u.2)
        .filter(|u| match baseline.and_then(|b| b.uses.iter().find(|x| x.0 == u.0)) {
            Some(b) => b.2 || u.1 > b.1 + WORSE_BY,
            None => baseline.is_some(),
        })
        .map(|u| u.0.clone())
        .collect();
    Outcome {
        margin_pct,
        worst: worst.map_or(String::new(), |w| w.0.clone()),
        uses,
        broken,
        induced,
        safety: Some(s),
        error: None,
        crashed: false,
        gross_w_per_kg: None,
    }
}

impl Outcome {
    /// The change of the wearer's gross metabolic rate from `baseline`'s (%; negative a
    /// saving), when both have it.
    fn metabolic_change_pct(&self, baseline: Option<&Outcome>) -> Option<f64> {
        let (g, b) = (self.gross_w_per_kg?, baseline?.gross_w_per_kg?);
        (b > 0.0).then(|| 100.0 * (g - b) / b)
    }
}

fn werr(path: &Path) -> impl Fn(String) -> Error + '_ {
    move |m| Error::Write { path: path.to_path_buf(), message: m }
}

fn opt(x: Option<f64>) -> String {
    x.map_or(String::new(), |x| format!("{x}"))
}

/// faults.csv's row of run `i` (`stop`: its controller's stop, if any).
fn csv_row(
    layout: &CampaignLayout,
    i: usize,
    o: &Outcome,
    stop: Option<&ControllerStopReport>,
    baseline: Option<&Outcome>,
) -> Vec<String> {
    let (mode, sev, onset) = match layout.case(i) {
        Some((m, s, k)) => {
            let l = &layout.modes[m];
            (l.name(), l.severities[s].clone(), format!("{}", layout.onsets[k]))
        }
        None => ("baseline".into(), String::new(), String::new()),
    };
    let (target, kind) = match layout.case(i) {
        Some((m, ..)) => (layout.modes[m].target.clone(), layout.modes[m].kind.clone()),
        None => (String::new(), String::new()),
    };
    let status = match (&o.error, o.broken.is_empty()) {
        (Some(_), _) if o.crashed => "crashed",
        (Some(_), _) => "failed",
        (None, true) => "ok",
        (None, false) => "hazard",
    };
    let s = o.safety.as_ref();
    let f = |g: &dyn Fn(&SafetySummary) -> f64| s.map_or(String::new(), |s| format!("{}", g(s)));
    let fo = |g: &dyn Fn(&SafetySummary) -> Option<f64>| opt(s.and_then(g));
    vec![
        i.to_string(),
        mode,
        target,
        kind,
        sev,
        onset,
        fo(&|s| s.fault_onset_s),
        status.into(),
        opt(o.margin_pct),
        o.worst.clone(),
        o.broken.join(";"),
        o.induced.join(";"),
        f(&|s| s.beyond_wearer_range_s),
        f(&|s| s.beyond_wearer_range_deg),
        f(&|s| s.beyond_urdf_limits_s),
        f(&|s| s.beyond_urdf_limits_deg),
        fo(&|s| s.knee_range_deg.map(|r| r[0])),
        fo(&|s| s.knee_range_deg.map(|r| r[1])),
        f(&|s| s.peak_knee_accel_rad_s2),
        f(&|s| s.peak_knee_jerk_rad_s3),
        f(&|s| s.peak_cuff_n[0]),
        f(&|s| s.peak_cuff_n[1]),
        f(&|s| s.peak_cylinder_force_n),
        fo(&|s| s.time_to_detection_s),
        fo(&|s| s.time_to_safe_state_s),
        fo(&|s| s.controller_stop_s),
        stop.map_or(String::new(), |c| format!("{}: {}", c.cause.as_str(), c.message)),
        o.error.clone().unwrap_or_default(),
        opt(o.gross_w_per_kg),
        opt(o.metabolic_change_pct(baseline)),
    ]
}

const CSV_HEADER: [&str; 30] = [
    "index",
    "mode",
    "target",
    "kind",
    "severity",
    "onset",
    "fault_onset_s",
    "status",
    "worst_margin_pct",
    "worst_criterion",
    "broken",
    "fault_induced",
    "beyond_wearer_range_s",
    "beyond_wearer_range_deg",
    "beyond_urdf_limits_s",
    "beyond_urdf_limits_deg",
    "knee_min_deg",
    "knee_max_deg",
    "peak_knee_accel_rad_s2",
    "peak_knee_jerk_rad_s3",
    "peak_thigh_cuff_n",
    "peak_shank_cuff_n",
    "peak_cylinder_force_n",
    "time_to_detection_s",
    "time_to_safe_state_s",
    "controller_stop_s",
    "controller_stop",
    "error",
    "gross_w_per_kg",
    "metabolic_change_pct",
];

/// Per failure mode, gathered over its runs.
#[derive(Debug, Clone, Default)]
struct ModeTally {
    runs: usize,
    induced: usize,
    /// (margin, severity, onset, outcome text) of the worst run.
    worst: Option<(f64, usize, usize, String)>,
    detections: Vec<f64>,
    safe: Vec<f64>,
    /// Per onset: the worst margin over the severities (None: a failed run) and a
    /// fault-induced hazard.
    cells: Vec<(Option<Option<f64>>, bool)>,
    /// Per onset: the metabolic change (%) of largest size over the severities.
    metabolic: Vec<Option<f64>>,
}

impl ModeTally {
    fn add(&mut self, sev: usize, onset: usize, o: &Outcome, baseline: Option<&Outcome>) {
        self.runs += 1;
        let induced = o.fault_induced(baseline);
        self.induced += usize::from(induced);
        let m = o.margin_pct.unwrap_or(f64::NEG_INFINITY);
        if self.worst.as_ref().is_none_or(|w| m < w.0) {
            let text = match (&o.error, o.uses.iter().max_by(|a, b| a.1.total_cmp(&b.1))) {
                (Some(e), _) if o.crashed => short(e, 72),
                (Some(e), _) => format!("failed: {}", short(e, 72)),
                (None, Some(u)) => format!("{} at {:.0} % of its limit", u.0, 100.0 * u.1),
                (None, None) => "no criterion".into(),
            };
            self.worst = Some((m, sev, onset, text));
        }
        if let Some(s) = &o.safety {
            self.detections.extend(s.time_to_detection_s);
            self.safe.extend(s.time_to_safe_state_s);
        }
        let cell = &mut self.cells[onset];
        cell.0 = Some(match (cell.0, o.margin_pct) {
            (Some(None), _) | (_, None) => None,
            (Some(Some(a)), Some(b)) => Some(a.min(b)),
            (None, b) => b,
        });
        cell.1 |= induced;
        if let Some(c) = o.metabolic_change_pct(baseline) {
            let m = &mut self.metabolic[onset];
            if m.is_none_or(|m| c.abs() > m.abs()) {
                *m = Some(c);
            }
        }
    }
}

fn median(v: &[f64]) -> Option<f64> {
    let mut v = v.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    (n > 0).then(|| if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) })
}

/// The FMEA rows (header first).
fn fmea_rows(layout: &CampaignLayout, tallies: &[ModeTally]) -> Vec<Vec<String>> {
    let mut rows = vec![[
        "failure mode",
        "runs",
        "fault-induced hazards",
        "worst onset",
        "worst severity",
        "worst outcome",
        "worst margin %",
        "detected",
        "median detection s",
        "safe state reached",
        "longest time to safe s",
    ]
    .map(String::from)
    .to_vec()];
    for (l, t) in layout.modes.iter().zip(tallies) {
        let (margin, sev, onset, text) = t.worst.clone().unwrap_or((f64::NAN, 0, 0, String::new()));
        let ms = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.3}"));
        rows.push(vec![
            l.name(),
            t.runs.to_string(),
            t.induced.to_string(),
            layout.onset_label(onset),
            l.severities.get(sev).cloned().unwrap_or_default(),
            text,
            if margin.is_finite() { format!("{margin:.0}") } else { "failed".into() },
            format!("{}/{}", t.detections.len(), t.runs),
            ms(median(&t.detections)),
            format!("{}/{}", t.safe.len(), t.runs),
            ms(t.safe.iter().copied().reduce(f64::max)),
        ]);
    }
    rows
}

fn markdown(rows: &[Vec<String>]) -> String {
    let mut s = String::new();
    for (i, r) in rows.iter().enumerate() {
        let cells: Vec<String> = r.iter().map(|c| crate::output::text::markdown(c)).collect();
        s.push_str(&format!("| {} |\n", cells.join(" | ")));
        if i == 0 {
            s.push_str(&format!("|{}\n", "---|".repeat(r.len())));
        }
    }
    s
}

/// A CSV of `rows`, every text cell by exoleg's one rule ([`crate::output::text::cell`]).
fn write_csv(path: &Path, rows: impl Iterator<Item = Vec<String>>) -> Result<()> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        let cells = r.iter().map(|c| crate::output::text::cell(c));
        w.write_record(cells).map_err(|e| werr(path)(e.to_string()))?;
    }
    let bytes = w.into_inner().map_err(|e| werr(path)(e.to_string()))?;
    crate::output::write_atomic(path, &bytes)
}

/// Read the campaign's `runs.jsonl` in `dir` and write `faults.csv`, `faults.png`, `fmea.csv`
/// and `fmea.md` beside it.
pub fn write_outputs(
    dir: &Path,
    layout: &CampaignLayout,
    base: &crate::scenario::ScenarioFile,
    source: &str,
) -> Result<CampaignReport> {
    let path = dir.join("runs.jsonl");
    let file = std::fs::File::open(&path).map_err(|e| werr(&path)(e.to_string()))?;
    let margin_deg = base.safety.knee_margin_deg;
    let tally = ModeTally {
        cells: vec![(None, false); layout.onsets.len()],
        metabolic: vec![None; layout.onsets.len()],
        ..Default::default()
    };
    let mut tallies = vec![tally; layout.modes.len()];
    let mut baseline: Option<Outcome> = None;
    let mut rep = CampaignReport::default();
    let mut rows = vec![CSV_HEADER.iter().map(|h| h.to_string()).collect::<Vec<_>>()];
    if layout.by_phase {
        rows[0][5] = "onset_phase_pct".into();
    } else {
        rows[0][5] = "onset_s".into();
    }
    for text in std::io::BufReader::new(file).lines() {
        let text = text.map_err(|e| werr(&path)(e.to_string()))?;
        let line: RunLine = serde_json::from_str(&text).map_err(|e| werr(&path)(e.to_string()))?;
        let o = outcome(&line, margin_deg, baseline.as_ref());
        rep.runs += 1;
        rep.hazard_runs += usize::from(o.error.is_some() || !o.broken.is_empty());
        let stop = line.summary.as_ref().and_then(|s| s.controller_stop.as_ref());
        rows.push(csv_row(layout, line.index, &o, stop, baseline.as_ref()));
        match layout.case(line.index) {
            None => {
                rep.baseline_broken = match (&o.error, o.crashed) {
                    (Some(_), true) => vec!["controller crashed".into()],
                    (Some(_), false) => vec!["failed".into()],
                    (None, _) => o.broken.clone(),
                };
                baseline = Some(o);
            }
            Some((m, s, k)) => {
                rep.fault_induced_runs += usize::from(o.fault_induced(baseline.as_ref()));
                tallies[m].add(s, k, &o, baseline.as_ref());
            }
        }
    }
    write_csv(&dir.join("faults.csv"), rows.into_iter())?;
    let fmea = fmea_rows(layout, &tallies);
    write_csv(&dir.join("fmea.csv"), fmea.clone().into_iter())?;
    rep.fmea = markdown(&fmea);
    let base_text = match &baseline {
        Some(b) if b.crashed => {
            format!("the baseline's own controller crashed ({})", short(b.error.as_deref().unwrap_or(""), 60))
        }
        Some(b) if b.error.is_some() => "the baseline failed".to_string(),
        Some(b) if b.broken.is_empty() => {
            format!("the baseline breaks none (worst margin {:.0} %)", b.margin_pct.unwrap_or(0.0))
        }
        Some(b) => format!("the baseline breaks {}", b.broken.join(", ")),
        None => "no baseline".into(),
    };
    rep.title = format!(
        "{}: {} faulted runs, {} with a fault-induced hazard; {base_text}",
        crate::output::text::title_name(source),
        rep.runs.saturating_sub(1),
        rep.fault_induced_runs
    );
    let heading = crate::output::text::terminal(&rep.title);
    crate::output::write_atomic(&dir.join("fmea.md"), format!("# {heading}\n\n{}", rep.fmea).as_bytes())?;
    let names: Vec<String> = layout.modes.iter().map(|m| m.name()).collect();
    let cols: Vec<String> = (0..layout.onsets.len()).map(|o| layout.onset_label(o)).collect();
    let cells: Vec<Vec<Option<f64>>> =
        tallies.iter().map(|t| t.cells.iter().map(|c| c.0.flatten()).collect()).collect();
    let marks: Vec<Vec<bool>> = tallies.iter().map(|t| t.cells.iter().map(|c| c.1).collect()).collect();
    let onset_what = if layout.by_phase { "onset: % of the stride after a heel strike" } else { "onset (s)" };
    let legend = format!("worst margin to a safety limit over the severities (% of the limit left; < 0 broken); ! a fault-induced hazard; {onset_what}");
    crate::output::heatmap_png(&dir.join("faults.png"), &rep.title, &names, &cols, &cells, &marks, &legend)?;
    if baseline.as_ref().is_some_and(|b| b.gross_w_per_kg.is_some()) {
        let cells: Vec<Vec<Option<f64>>> = tallies.iter().map(|t| t.metabolic.clone()).collect();
        let legend = format!("the wearer's gross metabolic rate against the baseline's (%; the change of largest size over the severities; blue a saving, red a cost); ! a fault-induced hazard; {onset_what}");
        let scale = crate::output::HeatScale::Change { span_pct: 20.0 };
        let path = dir.join("faults_metabolic.png");
        crate::output::heatmap_png_scaled(&path, &rep.title, &names, &cols, &cells, &marks, &legend, scale)?;
    }
    Ok(rep)
}

/// `text` in at most about `n` characters, cut at a word with " ..." when longer.
fn short(text: &str, n: usize) -> String {
    if text.chars().count() <= n {
        return text.to_string();
    }
    let head: String = text.chars().take(n).collect();
    let cut = head.rfind(' ').unwrap_or(head.len());
    format!("{} ...", head[..cut].trim_end_matches([':', ',']))
}
