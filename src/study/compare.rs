//! The paper's eight simulation cases (Tables 3 and 4) and their published numbers.

use crate::error::{Error, Result};
use crate::metrics::Band;
use crate::record::NullSink;
use crate::scenario::{Resources, Scenario};
use serde::Serialize;

/// One of the paper's cases with its published figures.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PaperCase {
    /// Reference frequency (Hz): 2 or 10.
    pub frequency_hz: f64,
    /// gamma (ZNN) = k (ERL-SMC).
    pub gain: f64,
    /// `arbfnn_fdo_znn` or `erl_smc`.
    pub controller: &'static str,
    /// The paper's maximum tracking error (N).
    pub paper_max_error_n: f64,
    /// The paper's convergence time (s).
    pub paper_convergence_s: f64,
}

/// Tables 3 and 4 of the paper.
pub const PAPER_CASES: [PaperCase; 8] = [
    PaperCase {
        frequency_hz: 2.0,
        gain: 100.0,
        controller: "arbfnn_fdo_znn",
        paper_max_error_n: 9.24,
        paper_convergence_s: 0.113,
    },
    PaperCase {
        frequency_hz: 2.0,
        gain: 100.0,
        controller: "erl_smc",
        paper_max_error_n: 11.41,
        paper_convergence_s: 0.403,
    },
    PaperCase {
        frequency_hz: 2.0,
        gain: 200.0,
        controller: "arbfnn_fdo_znn",
        paper_max_error_n: 4.62,
        paper_convergence_s: 0.047,
    },
    PaperCase {
        frequency_hz: 2.0,
        gain: 200.0,
        controller: "erl_smc",
        paper_max_error_n: 7.58,
        paper_convergence_s: 0.385,
    },
    PaperCase {
        frequency_hz: 10.0,
        gain: 200.0,
        controller: "arbfnn_fdo_znn",
        paper_max_error_n: 23.14,
        paper_convergence_s: 0.054,
    },
    PaperCase {
        frequency_hz: 10.0,
        gain: 200.0,
        controller: "erl_smc",
        paper_max_error_n: 47.45,
        paper_convergence_s: 0.436,
    },
    PaperCase {
        frequency_hz: 10.0,
        gain: 300.0,
        controller: "arbfnn_fdo_znn",
        paper_max_error_n: 15.4,
        paper_convergence_s: 0.037,
    },
    PaperCase {
        frequency_hz: 10.0,
        gain: 300.0,
        controller: "erl_smc",
        paper_max_error_n: 33.58,
        paper_convergence_s: 0.389,
    },
];

/// Our result for one case next to the paper's.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    /// The case.
    pub case: PaperCase,
    /// Our maximum tracking error (N); null if the run diverged.
    pub max_abs_force_error_n: Option<f64>,
    /// (ours - paper)/paper, in percent; null if the run diverged.
    pub max_error_diff_pct: Option<f64>,
    /// Our convergence time (s), null if it never entered the band or diverged.
    pub force_convergence_time_s: Option<f64>,
    /// Band used (N).
    pub force_convergence_band_n: f64,
    /// Our RMS error (N); null if the run diverged.
    pub rms_force_error_n: Option<f64>,
    /// Why the case has no figures (the divergence message), if it has none.
    pub failure: Option<String>,
}

/// Largest `--json` report exoleg recognises as its own (bytes).
const MAX_REPORT_BYTES: u64 = 16 << 20;

/// True when `f` holds a report `exoleg compare --json` wrote (the paper's cases, or the
/// firmware table): a JSON array of objects with exactly the fields exoleg writes.
pub fn is_report_json(f: &mut std::fs::File, len: u64) -> bool {
    const CASES: [&str; 7] = [
        "case",
        "failure",
        "force_convergence_band_n",
        "force_convergence_time_s",
        "max_abs_force_error_n",
        "max_error_diff_pct",
        "rms_force_error_n",
    ];
    const FIRMWARE: [&str; 2] = ["case", "cells"];
    if len > MAX_REPORT_BYTES {
        return false;
    }
    let bytes = crate::fsio::head(f, MAX_REPORT_BYTES as usize);
    let Ok(serde_json::Value::Array(items)) = serde_json::from_slice::<serde_json::Value>(&bytes) else {
        return false;
    };
    fn keys(v: &serde_json::Value) -> Option<Vec<&str>> {
        v.as_object().map(|o| {
            let mut k: Vec<&str> = o.keys().map(String::as_str).collect();
            k.sort_unstable();
            k
        })
    }
    let first = items.first().and_then(keys);
    let ok = |k: &Vec<&str>| k.as_slice() == CASES || k.as_slice() == FIRMWARE;
    first.as_ref().is_some_and(ok) && items.iter().all(|v| keys(v) == first)
}

/// The rule for `compare --json`: a new file, or a report exoleg wrote that is none of `inputs`.
pub fn json_rule(inputs: &[std::path::PathBuf]) -> crate::fsio::OutFile<'_> {
    crate::fsio::OutFile { flag: "--json", what: "a report exoleg compare --json wrote", inputs, ours: is_report_json }
}

/// The `--set` overrides that turn `base` into one paper case.
pub fn case_sets(c: &PaperCase) -> Vec<String> {
    vec![
        "reference.kind=\"sine\"".into(),
        "reference.amplitude_n=200.0".into(),
        format!("reference.frequency_hz={:?}", c.frequency_hz),
        format!("controller.kind=\"{}\"", c.controller),
        format!("controller.gamma={:?}", c.gain),
        format!("controller.k={:?}", c.gain),
    ]
}

/// Run the eight cases on top of `base` (which fixes plant, disturbances, solver...).
pub fn run_cases(base: &Scenario, extra_sets: &[String]) -> Result<Vec<CaseResult>> {
    use rayon::prelude::*;
    let res = Resources::new();
    let resolved: Vec<_> = PAPER_CASES
        .iter()
        .map(|c| {
            let mut sets = case_sets(c);
            sets.extend_from_slice(extra_sets);
            Ok(base.with_sets(&sets)?.resolve(&res)?.model)
        })
        .collect::<Result<_>>()?;
    PAPER_CASES
        .par_iter()
        .zip(resolved.par_iter())
        .map(|(c, sc)| {
            let band = match sc.metrics.band {
                Band::Fixed(b) => b,
                // The cases are 200 N sines: a band relative to the peak reference is relative to 200 N.
                Band::FractionOfPeakReference(f) => f * 200.0,
            };
            Ok(match crate::session::run(sc, &mut NullSink) {
                Ok(m) => CaseResult {
                    case: *c,
                    max_abs_force_error_n: Some(m.max_abs_force_error_n),
                    max_error_diff_pct: Some(
                        100.0 * (m.max_abs_force_error_n - c.paper_max_error_n) / c.paper_max_error_n,
                    ),
                    force_convergence_time_s: m.force_convergence_time_s,
                    force_convergence_band_n: band,
                    rms_force_error_n: Some(m.rms_force_error_n),
                    failure: None,
                },
                Err(e @ Error::Diverged { .. }) => CaseResult {
                    case: *c,
                    max_abs_force_error_n: None,
                    max_error_diff_pct: None,
                    force_convergence_time_s: None,
                    force_convergence_band_n: band,
                    rms_force_error_n: None,
                    failure: Some(e.to_string()),
                },
                Err(e) => return Err(e),
            })
        })
        .collect()
}

/// Render the comparison as a text table.
pub fn table(results: &[CaseResult]) -> String {
    let mut s = String::new();
    s.push_str(
        "case               controller       max err (N)  paper (N)   diff %   conv (s)  paper conv (s)  band (N)\n",
    );
    for r in results {
        let c = &r.case;
        s.push_str(&format!("{:>4} Hz, gain {:<4} {:<16} ", c.frequency_hz, c.gain, c.controller));
        match (r.max_abs_force_error_n, r.max_error_diff_pct) {
            (Some(m), Some(d)) => s.push_str(&format!(
                "{:>11.3}  {:>9.2}  {:>+7.2}   {:>8}  {:>14.3}  {:>8.2}\n",
                m,
                c.paper_max_error_n,
                d,
                r.force_convergence_time_s.map_or("never".to_string(), |t| format!("{t:.3}")),
                c.paper_convergence_s,
                r.force_convergence_band_n
            )),
            _ => s.push_str(&format!("{}\n", r.failure.as_deref().unwrap_or("no result"))),
        }
    }
    s
}
