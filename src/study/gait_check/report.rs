//! The gait check's table: `gait_check.csv` (one line per trial) and the printed report
//! (grouped by folder and age group, with the pass counts).

use super::{Figures, Outcome, Report, TrialResult};
use crate::output::text::terminal;
use crate::reference::StrideSource;
use std::fmt::Write;

/// The columns of `gait_check.csv`, in order.
pub const CSV_COLUMNS: [&str; 32] = [
    "folder",
    "trial",
    "subject",
    "age_group",
    "stride_s",
    "stride_from",
    "outcome",
    "stance",
    "grf_r",
    "grf_peak_ratio",
    "knee_moment_r",
    "extensor_nm",
    "data_extensor_nm",
    "extensor_pct",
    "data_extensor_pct",
    "flexor_nm",
    "data_flexor_nm",
    "flexor_pct",
    "data_flexor_pct",
    "knee_rms_stance_deg",
    "knee_rms_swing_deg",
    "meets_targets",
    "extensor_timing_ok",
    "flexor_size_ok",
    "not_walking",
    "misses",
    "message",
    "gross_w_per_kg",
    "net_w_per_kg",
    "peak_reserve_hip_pct",
    "peak_reserve_knee_pct",
    "peak_reserve_ankle_pct",
];

/// The muscle analysis's columns, last (empty without `wearer.muscles`).
const METABOLIC_COLUMNS: usize = 5;

/// A text field: exoleg's one rule for text cells ([`crate::output::text`]: no formula, no
/// control character), quoted when it holds a comma or a quote.
fn field(s: &str) -> String {
    crate::output::text::csv_field(s)
}

fn check(v: Option<bool>) -> &'static str {
    match v {
        Some(true) => "yes",
        Some(false) => "no",
        None => "n/a",
    }
}

fn stride_from(s: StrideSource) -> &'static str {
    match s {
        StrideSource::Given => "stride_s",
        StrideSource::Cadence => "cadence",
        StrideSource::Estimated => "estimated",
    }
}

impl Report {
    /// The trials that ran and meet the targets, of those in `which`.
    pub fn count_meeting<'a>(&self, which: impl Iterator<Item = &'a TrialResult>) -> (usize, usize) {
        which.fold((0, 0), |(m, n), t| (m + usize::from(t.meets(&self.targets)), n + 1))
    }

    /// The trials with bad input.
    pub fn bad_input(&self) -> Vec<&TrialResult> {
        self.trials.iter().filter(|t| matches!(t.outcome, Outcome::BadInput(_))).collect()
    }

    /// The ran trials whose extensor timing and flexor size both hold (a check whose data peak
    /// is too small to compare counts as holding), and those that ran.
    pub fn peaks_holding(&self) -> (usize, usize) {
        let t = &self.targets;
        self.trials.iter().filter_map(|r| if let Outcome::Ran(f) = &r.outcome { Some(f) } else { None }).fold(
            (0, 0),
            |(ok, n), f| {
                let holds = f.extensor_timing_ok(t) != Some(false) && f.flexor_size_ok(t) != Some(false);
                (ok + usize::from(holds), n + 1)
            },
        )
    }

    /// `gait_check.csv`.
    pub fn csv(&self) -> String {
        let mut s = CSV_COLUMNS.join(",");
        s.push('\n');
        for t in &self.trials {
            let row = t.row.as_ref();
            let mut cells = vec![
                field(&t.folder),
                field(&t.name),
                field(row.map_or("", |r| r.subject.as_str())),
                field(row.map_or("", |r| r.group.as_str())),
                row.map_or(String::new(), |r| format!("{}", r.stride_s)),
                row.map_or("", |r| stride_from(r.stride_from)).to_string(),
            ];
            match &t.outcome {
                Outcome::Ran(f) => {
                    cells.push("ran".into());
                    cells.extend(self.figure_cells(f));
                    cells.push(String::new());
                    match &f.metabolics {
                        Some(m) => cells.extend(
                            [m.gross_w_per_kg, m.net_w_per_kg]
                                .into_iter()
                                .chain(m.peak_reserve_pct)
                                .map(|v| format!("{v}")),
                        ),
                        None => cells.extend(std::iter::repeat_n(String::new(), METABOLIC_COLUMNS)),
                    }
                }
                Outcome::BadInput(m) | Outcome::Failed(m) => {
                    let what = if matches!(t.outcome, Outcome::BadInput(_)) { "bad_input" } else { "failed" };
                    cells.push(what.into());
                    cells.extend(std::iter::repeat_n(String::new(), CSV_COLUMNS.len() - 8 - METABOLIC_COLUMNS));
                    cells.push(field(m));
                    cells.extend(std::iter::repeat_n(String::new(), METABOLIC_COLUMNS));
                }
            }
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        s
    }

    /// The cells from `stance` to `misses` of a trial that ran.
    fn figure_cells(&self, f: &Figures) -> Vec<String> {
        let (c, d, t) = (&f.contact, &f.dataset, &self.targets);
        let num = |v: f64| format!("{v}");
        let opt = |v: Option<f64>| v.map_or(String::new(), num);
        vec![
            num(c.stance_fraction),
            num(d.grf_correlation),
            num(d.grf_peak_ratio),
            num(d.knee_moment_stance_correlation),
            num(d.extensor_peak_nm),
            num(d.data_extensor_peak_nm),
            num(d.extensor_peak_pct),
            num(d.data_extensor_peak_pct),
            num(d.flexor_peak_nm),
            num(d.data_flexor_peak_nm),
            num(d.flexor_peak_pct),
            num(d.data_flexor_peak_pct),
            opt(c.knee_rms_error_stance_deg),
            opt(c.knee_rms_error_swing_deg),
            check(Some(f.misses(t).is_empty())).into(),
            check(f.extensor_timing_ok(t)).into(),
            check(f.flexor_size_ok(t)).into(),
            field(&c.not_walking.as_ref().map_or_else(|| "not evaluated".to_string(), |f| f.join("; "))),
            field(&f.misses(t).join("; ")),
        ]
    }

    /// One printed line of a trial.
    fn line(&self, t: &TrialResult) -> String {
        let est = if t.row.as_ref().is_some_and(|r| r.stride_from == StrideSource::Estimated) { "*" } else { " " };
        let stride = t.row.as_ref().map_or(String::new(), |r| format!("{:.3}{est}", r.stride_s));
        let head = format!("{:<24} {:>7}", terminal(&t.name), stride);
        let f = match &t.outcome {
            Outcome::Ran(f) => f,
            Outcome::BadInput(m) => return format!("{head}  BAD INPUT: {}", terminal(m)),
            Outcome::Failed(m) => return format!("{head}  FAILED: {}", terminal(m)),
        };
        let (c, d, tg) = (&f.contact, &f.dataset, &self.targets);
        let misses = f.misses(tg);
        format!(
            "{head}  {:.3}  {:.3} {:4.2}  {:6.3}  {:6.1}/{:6.1} @{:4.1}/{:4.1} {:<3}  {:6.1}/{:6.1} @{:4.1}/{:4.1} {:<3}  {:4.2}  {}",
            c.stance_fraction,
            d.grf_correlation,
            d.grf_peak_ratio,
            d.knee_moment_stance_correlation,
            d.extensor_peak_nm,
            d.data_extensor_peak_nm,
            d.extensor_peak_pct,
            d.data_extensor_peak_pct,
            check(f.extensor_timing_ok(tg)),
            d.flexor_peak_nm,
            d.data_flexor_peak_nm,
            d.flexor_peak_pct,
            d.data_flexor_peak_pct,
            check(f.flexor_size_ok(tg)),
            c.knee_rms_error_stance_deg.unwrap_or(f64::NAN),
            if misses.is_empty() { "meets".to_string() } else { format!("MISSES: {}", misses.join("; ")) }
        ) + &f.metabolics.as_ref().map_or(String::new(), |m| {
            let r = m.peak_reserve_pct;
            format!("  {:.2} W/kg gross, reserves {:.1}/{:.1}/{:.1} %", m.gross_w_per_kg, r[0], r[1], r[2])
        })
    }

    /// The printed report: per folder and age group, every trial's line and the group's count.
    pub fn table(&self) -> String {
        let t = &self.targets;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Targets: stance {}..{}, GRF r >= {}, stance knee-moment r >= {}, no not-walking flag{}; engine {} at {} s.",
            t.stance.0,
            t.stance.1,
            t.min_grf_r,
            t.min_knee_moment_r,
            if t.require_peaks { ", the peak checks" } else { "" },
            self.engine.0,
            self.engine.1
        );
        let _ = writeln!(
            s,
            "Peaks (N m, % of the cycle; sim/data): extensor in 5-25 % (timing within {} %), flexor in 25-61 % (size within {:.0} %); n/a: the data's peak is under {} N m. * stride estimated.",
            t.extensor_within_pct,
            100.0 * t.flexor_within,
            super::PEAK_MIN_NM
        );
        let _ = writeln!(
            s,
            "{:<24} {:>7}  stance GRF_r peak  knee_r  extensor (sim/data @%)       ok   flexor (sim/data @%)         ok   knee_rms_stance  verdict",
            "trial", "stride"
        );
        let mut folders: Vec<&str> = Vec::new();
        for r in &self.trials {
            if !folders.contains(&r.folder.as_str()) {
                folders.push(&r.folder);
            }
        }
        for folder in folders {
            let mut groups: Vec<&str> = Vec::new();
            for r in self.trials.iter().filter(|r| r.folder == folder) {
                let g = r.row.as_ref().map_or("", |r| r.group.as_str());
                if !groups.contains(&g) {
                    groups.push(g);
                }
            }
            for g in groups {
                let of = || {
                    self.trials
                        .iter()
                        .filter(move |r| r.folder == folder && r.row.as_ref().map_or("", |r| r.group.as_str()) == g)
                };
                let label = if g.is_empty() { String::new() } else { format!(", {}", terminal(g)) };
                let _ = writeln!(s, "-- {}{label}", terminal(folder));
                for r in of() {
                    let _ = writeln!(s, "{}", self.line(r));
                }
                let (m, n) = self.count_meeting(of());
                let _ = writeln!(s, "   {m} of {n} meet the targets");
            }
        }
        let (m, n) = self.count_meeting(self.trials.iter());
        let (p, ran) = self.peaks_holding();
        let _ = writeln!(
            s,
            "All: {m} of {n} trials meet the targets; extensor timing and flexor size hold on {p} of the {ran} that ran; {} bad input; {:.1} s",
            self.bad_input().len(),
            self.wall_s
        );
        if let Some(line) = self.metabolics_line() {
            let _ = writeln!(s, "{line}");
        }
        s
    }

    /// The muscle analysis over the trials that ran with it: the gross rate's mean and range,
    /// the largest peak reserve.
    fn metabolics_line(&self) -> Option<String> {
        let ms: Vec<&crate::metrics::muscles::MetabolicsSummary> = self
            .trials
            .iter()
            .filter_map(|t| match &t.outcome {
                Outcome::Ran(f) => f.metabolics.as_ref(),
                _ => None,
            })
            .collect();
        let first = ms.first()?;
        let g: Vec<f64> = ms.iter().map(|m| m.gross_w_per_kg).collect();
        let mean = g.iter().sum::<f64>() / g.len() as f64;
        let (lo, hi) = g.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        let worst = ms.iter().flat_map(|m| m.peak_reserve_pct).fold(0.0, f64::max);
        Some(format!(
            "Metabolic rate ({}, {} muscles, {}): gross {mean:.2} W/kg on average over {} trials ({lo:.2}..{hi:.2}), net {:.2}; the largest peak reserve {worst:.1} % of a joint's moment",
            first.metabolic_model,
            first.muscle_model,
            first.muscle_cost,
            g.len(),
            mean - first.basal_w_per_kg
        ))
    }
}
