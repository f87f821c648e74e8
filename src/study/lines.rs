//! A study's run lines as exoleg writes them (`runs.jsonl` of a study, a shard or a journal):
//! what kind of study they belong to, how one line is read with a cap, and how it is checked
//! against the plan. The shard merge ([`super::shard`]) and the journal
//! ([`super::journal`]) both read lines through here.

use super::sweep::{Plan, RunLine};
use serde::{Deserialize, Serialize};
use std::io::BufRead;

/// Longest line of a shard's `runs.jsonl` the merge reads (bytes).
pub const MAX_LINE_BYTES: usize = 8 << 20;

/// What kind of study a plan belongs to (what the merge writes besides the runs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StudyKind {
    /// `exoleg sweep`: `runs.jsonl` and `aggregate.csv`.
    Sweep,
    /// `exoleg robustness`: also `robustness.png`, judged by the scenario's criteria.
    Robustness {
        /// Half-width of the variation (%).
        percent: f64,
    },
    /// `exoleg faults`: also `faults.csv`, `faults.png`, `fmea.csv` and `fmea.md`.
    Faults {
        /// The runs' layout (modes, severities, onsets).
        layout: super::faults::CampaignLayout,
    },
}

/// The next line of `r` (without its newline), at most [`MAX_LINE_BYTES`]; None at the end.
pub fn bounded_line(r: &mut impl BufRead, buf: &mut Vec<u8>) -> std::io::Result<Option<()>> {
    buf.clear();
    let n = std::io::Read::take(&mut *r, MAX_LINE_BYTES as u64 + 1).read_until(b'\n', buf)?;
    if n == 0 {
        return Ok(None);
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
    } else if buf.len() > MAX_LINE_BYTES {
        return Err(std::io::Error::other(format!("a line longer than {MAX_LINE_BYTES} bytes")));
    }
    Ok(Some(()))
}

/// Check one line of a shard against the plan: run `i`, its overrides, its fields exactly as
/// exoleg writes them, plausible figures.
pub fn check_line(text: &[u8], i: usize, plan: &Plan) -> std::result::Result<RunLine, String> {
    let text = std::str::from_utf8(text).map_err(|_| "not UTF-8".to_string())?;
    let line: RunLine = serde_json::from_str(text).map_err(|e| format!("not a run line: {e}"))?;
    if line.index != i {
        return Err(format!("found run {} in its place", line.index));
    }
    if line.sets != plan.sets(i) {
        return Err(format!("its overrides {:?} are not the plan's {:?}", line.sets, plan.sets(i)));
    }
    let canonical = serde_json::to_string(&line).map_err(|e| e.to_string())?;
    if canonical != text {
        return Err("not as exoleg writes it (fields added, changed or reordered)".into());
    }
    if let Some(s) = &line.summary {
        s.check_plausible()?;
    }
    let passed = line.error.is_none() && line.summary.as_ref().is_some_and(|s| s.passes(&line.criteria));
    if line.passed != passed || line.summary.is_none() != line.error.is_some() {
        return Err("its verdict does not follow from its figures and criteria".into());
    }
    Ok(line)
}
