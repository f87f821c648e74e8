//! A fault campaign's matrix: the failure modes (a target and a kind), each with its
//! severities (a label and the fault's parameters), and the onsets. The default matrix for a
//! scenario, or one read from a TOML file (`exoleg faults --matrix FILE`; `--print-matrix`
//! writes the default as a starting point):
//!
//! ```toml
//! onsets_pct = [0.0, 10.0, 20.0]   # walking: % of the stride after a heel strike
//! # onsets_s = [1.5, 2.0]          # or times (s)
//! [[mode]]
//! target = "force_n"
//! kind = "bias"
//! [[mode.severity]]
//! label = "2 % FS"
//! bias = 100.0
//! ```
//!
//! A severity's keys are a `[[faults]]` entry's (`crate::faults::FaultSpec`) besides the
//! target, the kind and the onset, which the campaign sets.

use crate::error::{Error, Result};
use crate::sensors::{CHANNELS, DEVICE_CHANNELS};
use serde::{Deserialize, Serialize};

/// Most failure modes a matrix may have.
pub const MAX_MODES: usize = 1000;
/// Most severities a failure mode, and onsets a matrix, may have.
pub const MAX_PER_AXIS: usize = 100;
/// Largest matrix file read (bytes).
pub const MAX_MATRIX_BYTES: u64 = 1 << 20;

/// One severity of a failure mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Severity {
    /// Its label in the outputs ("10 % FS").
    pub label: String,
    /// The fault's parameters (keys of a `[[faults]]` entry).
    #[serde(flatten)]
    pub keys: toml::Table,
}

/// A failure mode: what fails, how, and how badly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mode {
    /// A reading channel (`force_n`, ...), `valve`, `leakage`, `supply`, `power`, `controller`.
    pub target: String,
    /// The fault's kind.
    pub kind: String,
    /// Its severities, mildest first.
    #[serde(rename = "severity")]
    pub severities: Vec<Severity>,
}

impl Mode {
    /// "target kind".
    pub fn name(&self) -> String {
        format!("{} {}", self.target, self.kind)
    }
}

/// The campaign's matrix.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Matrix {
    /// Onsets at this % of the stride after a heel strike (walking runs). 0..100.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onsets_pct: Option<Vec<f64>>,
    /// Onsets at these times (s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onsets_s: Option<Vec<f64>>,
    /// The failure modes.
    #[serde(rename = "mode", default)]
    pub modes: Vec<Mode>,
}

/// The keys a severity may not set (the campaign sets them).
const CAMPAIGN_KEYS: [&str; 6] = ["target", "kind", "onset_s", "onset_event", "onset_phase_pct", "onset_after_s"];

impl Matrix {
    /// Check the matrix's shape (`name`: its file, for messages): onsets of one kind, within
    /// bounds, sizes capped, labels given, no severity setting what the campaign sets.
    pub fn check(&self, name: &str) -> Result<()> {
        let bad = |key: String, m: String| Err(Error::input(name, key, m));
        match (&self.onsets_pct, &self.onsets_s) {
            (Some(_), Some(_)) => return bad("onsets_pct".into(), "give onsets_pct or onsets_s, not both".into()),
            (Some(v), None) | (None, Some(v)) if v.is_empty() || v.len() > MAX_PER_AXIS => {
                return bad("onsets".into(), format!("1..={MAX_PER_AXIS} onsets, got {}", v.len()))
            }
            _ => {}
        }
        if let Some(v) = &self.onsets_pct {
            if let Some(x) = v.iter().find(|x| !(0.0..100.0).contains(*x)) {
                return bad("onsets_pct".into(), format!("{x}: a phase is in [0, 100) %"));
            }
        }
        if let Some(v) = &self.onsets_s {
            if let Some(x) = v.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                return bad("onsets_s".into(), format!("{x}: a time is >= 0 s"));
            }
        }
        if self.modes.len() > MAX_MODES {
            return bad("mode".into(), format!("at most {MAX_MODES} modes, got {}", self.modes.len()));
        }
        for (i, m) in self.modes.iter().enumerate() {
            if m.severities.is_empty() || m.severities.len() > MAX_PER_AXIS {
                return bad(format!("mode.{i}.severity"), format!("1..={MAX_PER_AXIS} severities"));
            }
            for (j, s) in m.severities.iter().enumerate() {
                if let Some(k) = CAMPAIGN_KEYS.iter().find(|k| s.keys.contains_key(**k)) {
                    return bad(format!("mode.{i}.severity.{j}.{k}"), "the campaign sets it".into());
                }
                if s.label.trim().is_empty() || s.label.len() > 80 {
                    return bad(format!("mode.{i}.severity.{j}.label"), "1..=80 characters".into());
                }
            }
            if m.target.len() > 80 || m.kind.len() > 80 {
                return bad(format!("mode.{i}.target"), "a target or kind of at most 80 characters".into());
            }
        }
        Ok(())
    }

    /// The matrix as TOML (`--print-matrix`).
    pub fn to_toml(&self) -> Result<String> {
        toml::to_string(self).map_err(|e| Error::input("--print-matrix", "matrix", e.to_string()))
    }
}

/// Parse and check a matrix file's text (`name` for messages): the fuzz target's entry point.
pub fn parse_matrix(name: &str, text: &str) -> Result<Matrix> {
    let m: Matrix = toml::from_str(text).map_err(|e| {
        let msg = e.message().lines().next().unwrap_or_default().to_string();
        Error::input(name, "matrix", msg)
    })?;
    m.check(name)?;
    Ok(m)
}

/// Read a matrix file.
pub fn read_matrix(path: &std::path::Path) -> Result<Matrix> {
    let text = crate::scenario::read_capped(path, MAX_MATRIX_BYTES)?;
    parse_matrix(&path.display().to_string(), &text)
}

/// Three significant digits (a default severity's value, for readable files and labels).
pub(crate) fn sig3(x: f64) -> f64 {
    format!("{x:.2e}").parse().unwrap_or(x)
}

fn sev(label: impl Into<String>, keys: &[(&str, toml::Value)]) -> Severity {
    Severity { label: label.into(), keys: keys.iter().map(|(k, v)| (k.to_string(), v.clone())).collect() }
}

fn f(x: f64) -> toml::Value {
    toml::Value::Float(x)
}

fn int(n: i64) -> toml::Value {
    toml::Value::Integer(n)
}

/// A reading channel's default full scale (its unit).
pub fn full_scale(reading: &str) -> Option<f64> {
    CHANNELS
        .iter()
        .find(|c| c.reading == reading)
        .map(|c| c.default_range)
        .or_else(|| DEVICE_CHANNELS.iter().find(|c| c.reading == reading).map(|c| c.default_range))
}

/// The nine sensor failure modes of a channel of full scale `fs`, two severities each
/// (README, "Faults and safety").
pub fn sensor_modes(reading: &str, fs: f64) -> Vec<Mode> {
    let pct = |p: f64| sig3(p / 100.0 * fs);
    let mode = |kind: &str, s: Vec<Severity>| Mode { target: reading.into(), kind: kind.into(), severities: s };
    vec![
        mode(
            "dropout",
            vec![
                sev("20 ms, NaN", &[("mode", "nan".into()), ("duration_s", f(0.02))]),
                sev("permanent, NaN", &[("mode", "nan".into())]),
            ],
        ),
        mode("stuck", vec![sev("frozen", &[]), sev("at 10 % FS", &[("value", f(pct(10.0)))])]),
        mode("bias", vec![sev("2 % FS", &[("bias", f(pct(2.0)))]), sev("10 % FS", &[("bias", f(pct(10.0)))])]),
        mode("drift", vec![sev("1 % FS/s", &[("rate", f(pct(1.0)))]), sev("5 % FS/s", &[("rate", f(pct(5.0)))])]),
        mode("gain", vec![sev("x1.1", &[("gain", f(1.1))]), sev("x1.5", &[("gain", f(1.5))])]),
        mode("noise", vec![sev("0.5 % FS", &[("sd", f(pct(0.5)))]), sev("2 % FS", &[("sd", f(pct(2.0)))])]),
        mode(
            "spikes",
            vec![
                sev("10 % FS, 1 %", &[("amplitude", f(pct(10.0))), ("probability", f(0.01))]),
                sev("50 % FS, 5 %", &[("amplitude", f(pct(50.0))), ("probability", f(0.05))]),
            ],
        ),
        mode(
            "saturation",
            vec![sev("at 10 % FS", &[("level", f(pct(10.0)))]), sev("at 3 % FS", &[("level", f(pct(3.0)))])],
        ),
        mode("delay", vec![sev("2 samples", &[("samples", int(2))]), sev("10 samples", &[("samples", int(10))])]),
    ]
}

/// The valve, leakage, supply and power failure modes, two severities each.
pub fn actuator_modes() -> Vec<Mode> {
    let mode =
        |target: &str, kind: &str, s: Vec<Severity>| Mode { target: target.into(), kind: kind.into(), severities: s };
    vec![
        mode("valve", "stuck", vec![sev("at centre", &[("value", f(0.0))]), sev("where it is", &[])]),
        mode(
            "valve",
            "slow",
            vec![sev("tau x5", &[("tau_factor", f(5.0))]), sev("tau x20", &[("tau_factor", f(20.0))])],
        ),
        mode(
            "leakage",
            "orifice",
            vec![sev("0.2 mm2", &[("area_m2", f(2e-7))]), sev("1 mm2", &[("area_m2", f(1e-6))])],
        ),
        mode(
            "supply",
            "loss",
            vec![
                sev("to 50 %, tau 0.2 s", &[("residual", f(0.5)), ("tau_s", f(0.2))]),
                sev("to 0, sudden", &[("residual", f(0.0))]),
            ],
        ),
        mode("power", "loss", vec![sev("0.1 s", &[("duration_s", f(0.1))]), sev("permanent", &[])]),
    ]
}

/// The controller's timing failure modes, two severities each.
pub fn controller_modes() -> Vec<Mode> {
    let mode = |kind: &str, s: Vec<Severity>| Mode { target: "controller".into(), kind: kind.into(), severities: s };
    vec![
        mode("overrun", vec![sev("1 sample", &[("samples", int(1))]), sev("5 samples", &[("samples", int(5))])]),
        mode("skip", vec![sev("50 ms", &[("duration_s", f(0.05))]), sev("permanent", &[])]),
        mode(
            "lost",
            vec![
                sev("10 % of samples", &[("probability", f(0.1))]),
                sev("50 % of samples", &[("probability", f(0.5))]),
            ],
        ),
    ]
}
