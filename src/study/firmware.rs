//! The firmware table (`exoleg compare --firmware`): every controller run as 1 kHz firmware
//! (zero-order hold, 16-bit sensors, one sample of delay) on the paper's four bench cases and
//! the two shipped gait scenarios, next to the paper's continuous design.

use crate::error::{Error, Result};
use crate::metrics::Summary;
use crate::record::NullSink;
use crate::scenario::{Resources, Scenario};
use serde::Serialize;

/// The cases: (name, shipped scenario file text).
const CASES: [(&str, &str); 6] = [
    ("2 Hz, gamma 100", include_str!("../../assets/scenarios/paper_2hz_gamma100.toml")),
    ("2 Hz, gamma 200", include_str!("../../assets/scenarios/paper_2hz_gamma200.toml")),
    ("10 Hz, gamma 200", include_str!("../../assets/scenarios/paper_10hz_gamma200.toml")),
    ("10 Hz, gamma 300", include_str!("../../assets/scenarios/paper_10hz_gamma300.toml")),
    ("gait, comfortable", include_str!("../../assets/scenarios/gait_walk.toml")),
    ("gait, fast", include_str!("../../assets/scenarios/gait_walk_fast.toml")),
];

/// The columns: (label, controller kind, sampled).
pub const COLUMNS: [(&str, &str, bool); 5] = [
    ("ARBFNN-FDO-ZNN continuous", "arbfnn_fdo_znn", false),
    ("ARBFNN-FDO-ZNN 1 kHz", "arbfnn_fdo_znn", true),
    ("ZNN 1 kHz", "znn", true),
    ("dtznn 1 kHz", "dtznn", true),
    ("ERL-SMC 1 kHz", "erl_smc", true),
];

/// The firmware conditions: 1 kHz, adc16, one sample of delay (bench cases at 0.1 ms steps,
/// the gait scenarios at their own 0.25 ms).
pub const FIRMWARE_SETS: [&str; 3] =
    ["controller.sample_period_s=0.001", "sensors.preset=\"adc16\"", "sensors.delay_samples=1"];

/// One cell: the figures of a run, or why it has none.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// Column label.
    pub controller: &'static str,
    /// max |F_L - F_d| over the run (N).
    pub max_error_n: Option<f64>,
    /// max |F_L - F_d| after the settling window (N).
    pub max_error_after_settle_n: Option<f64>,
    /// RMS of F_L - F_d after the settling window (N).
    pub rms_error_after_settle_n: Option<f64>,
    /// Knee RMS and max error after the settling window (deg), gait cases.
    pub knee_rms_max_deg: Option<[f64; 2]>,
    /// The divergence message, if the run did not finish.
    pub failure: Option<String>,
}

/// One row: a case and its cells.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Case label.
    pub case: &'static str,
    /// The cells, in [`COLUMNS`] order.
    pub cells: Vec<Cell>,
}

fn cell(label: &'static str, r: Result<Summary>) -> Result<Cell> {
    Ok(match r {
        Ok(s) => Cell {
            controller: label,
            max_error_n: Some(s.max_abs_force_error_n),
            max_error_after_settle_n: Some(s.max_abs_force_error_after_settle_n),
            rms_error_after_settle_n: Some(s.rms_force_error_after_settle_n),
            knee_rms_max_deg: s.knee_rms_error_deg.zip(s.knee_max_abs_error_deg).map(|(a, b)| [a, b]),
            failure: None,
        },
        Err(e @ (Error::Diverged { .. } | Error::Stiff { .. })) => Cell {
            controller: label,
            max_error_n: None,
            max_error_after_settle_n: None,
            rms_error_after_settle_n: None,
            knee_rms_max_deg: None,
            failure: Some(e.to_string()),
        },
        Err(e) => return Err(e),
    })
}

/// Run the table (in parallel); `extra` overrides apply to every run.
pub fn run_table(extra: &[String]) -> Result<Vec<Row>> {
    use rayon::prelude::*;
    let res = Resources::new();
    let jobs: Vec<(usize, usize)> = (0..CASES.len()).flat_map(|i| (0..COLUMNS.len()).map(move |j| (i, j))).collect();
    let models = jobs
        .iter()
        .map(|&(i, j)| {
            let (name, text) = CASES[i];
            let (_, kind, sampled) = COLUMNS[j];
            let mut sets = vec![format!("controller.kind=\"{kind}\"")];
            if i < 4 {
                sets.extend(["sim.dt_s=0.0001".to_string(), "metrics.settle_s=0.5".to_string()]);
            }
            if sampled {
                sets.extend(FIRMWARE_SETS.iter().map(|s| s.to_string()));
            }
            sets.extend_from_slice(extra);
            Ok(Scenario::from_toml_str(name, text, &sets)?.resolve(&res)?.model)
        })
        .collect::<Result<Vec<_>>>()?;
    let cells: Vec<Cell> = models
        .par_iter()
        .zip(jobs.par_iter())
        .map(|(m, &(_, j))| cell(COLUMNS[j].0, crate::session::run(m, &mut NullSink)))
        .collect::<Result<_>>()?;
    Ok(CASES
        .iter()
        .enumerate()
        .map(|(i, (name, _))| Row { case: name, cells: cells[i * COLUMNS.len()..(i + 1) * COLUMNS.len()].to_vec() })
        .collect())
}

/// The table as text: per cell "max / max after settle / RMS after settle" in N, and the knee
/// RMS / max in deg for the gait cases; "unstable (t)" for runs that diverged.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!("{:<20}", "case");
    for (label, _, _) in COLUMNS {
        s.push_str(&format!(" | {label:<28}"));
    }
    s.push('\n');
    for r in rows {
        s.push_str(&format!("{:<20}", r.case));
        for c in &r.cells {
            let text = match (c.max_error_n, c.max_error_after_settle_n, c.rms_error_after_settle_n, &c.failure) {
                (Some(m), Some(a), Some(rms), _) => {
                    let knee = c.knee_rms_max_deg.map_or(String::new(), |[kr, km]| format!(", {kr:.3}/{km:.3} deg"));
                    format!("{m:.2}/{a:.3}/{rms:.3} N{knee}")
                }
                (_, _, _, Some(f)) => match f.split("t = ").nth(1).and_then(|x| x.split(' ').next()) {
                    Some(t) => format!("unstable ({t} s)"),
                    None => "unstable".into(),
                },
                _ => "-".into(),
            };
            s.push_str(&format!(" | {text:<28}"));
        }
        s.push('\n');
    }
    s
}
