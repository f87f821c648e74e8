//! The metric definitions of MODEL.md section 6, defined once and used by the CLI, the
//! comparison, sweeps and tests.

use crate::scenario::{CriteriaSection, ReferenceKind, Scenario, ScenarioFile};
use crate::sim::Record;
use serde::Serialize;

/// Largest absolute value (0 for an empty slice).
pub fn max_abs(xs: &[f64]) -> f64 {
    xs.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Root mean square (0 for an empty slice).
pub fn rms(xs: &[f64]) -> f64 {
    if xs.is_empty() {
        return 0.0;
    }
    (xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64).sqrt()
}

/// Convergence time: the earliest recorded time after which `|e| <= band` for the rest of
/// the run. `None` if the last sample is outside the band (never converged).
pub fn convergence_time(t_s: &[f64], e: &[f64], band: f64) -> Option<f64> {
    match e.iter().rposition(|x| x.abs() > band) {
        None => t_s.first().copied(),
        Some(i) if i + 1 < t_s.len() => Some(t_s[i + 1]),
        Some(_) => None,
    }
}

/// Index of the first sample at or after `settle_s`.
pub fn settle_index(t_s: &[f64], settle_s: f64) -> usize {
    t_s.partition_point(|&t| t < settle_s - 1e-12)
}

/// Arithmetic mean (0 for an empty slice); of a 0/1 flag column, the fraction of time set.
pub fn mean(xs: &[f64]) -> f64 {
    if xs.is_empty() {
        return 0.0;
    }
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// Figures of one stride of a gait run (errors over the whole stride).
#[derive(Debug, Clone, Serialize)]
pub struct StrideFigures {
    /// Stride number, from 0.
    pub index: usize,
    /// Start time of the stride (s).
    pub t_start_s: f64,
    /// RMS of knee angle - desired (deg).
    pub knee_rms_error_deg: f64,
    /// max |knee angle - desired| (deg).
    pub knee_max_abs_error_deg: f64,
    /// RMS of F_L - F_d (N).
    pub force_rms_error_n: f64,
    /// max |F_L - F_d| (N).
    pub force_max_abs_error_n: f64,
    /// max |net cylinder force| (N).
    pub peak_cylinder_force_n: f64,
    /// max |cylinder force x piston velocity| (W).
    pub peak_power_w: f64,
}

/// Knee error series (deg) from a record with a knee reference.
pub fn knee_error_deg(r: &Record) -> Option<Vec<f64>> {
    let q = r.extra_column("knee_angle_deg")?;
    if r.ref_knee_deg.len() != q.len() {
        return None;
    }
    Some(q.iter().zip(&r.ref_knee_deg).map(|(a, d)| a - d).collect())
}

/// Mechanical power of the cylinder (W) at each row.
pub fn cylinder_power_w(r: &Record) -> Vec<f64> {
    r.cylinder_force_n.iter().zip(&r.piston_velocity_m_s).map(|(f, v)| f * v).collect()
}

fn strides(r: &Record, knee_err: &[f64]) -> Vec<StrideFigures> {
    let Some(stride) = r.stride_s else { return Vec::new() };
    let power = cylinder_power_w(r);
    let t_end = r.t_s.last().copied().unwrap_or(0.0);
    let n = ((t_end + 1e-9) / stride).floor() as usize;
    (0..n)
        .map(|i| {
            let (a, b) = (settle_index(&r.t_s, i as f64 * stride), settle_index(&r.t_s, (i + 1) as f64 * stride));
            StrideFigures {
                index: i,
                t_start_s: i as f64 * stride,
                knee_rms_error_deg: rms(&knee_err[a..b]),
                knee_max_abs_error_deg: max_abs(&knee_err[a..b]),
                force_rms_error_n: rms(&r.force_error_n[a..b]),
                force_max_abs_error_n: max_abs(&r.force_error_n[a..b]),
                peak_cylinder_force_n: max_abs(&r.cylinder_force_n[a..b]),
                peak_power_w: max_abs(&power[a..b]),
            }
        })
        .collect()
}

/// The summary written to `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// max |F_L - F_d| over the run (N).
    pub max_abs_force_error_n: f64,
    /// Earliest t after which |F_L - F_d| stays within the band (s); null if never.
    pub force_convergence_time_s: Option<f64>,
    /// The band used for the convergence time (N).
    pub force_convergence_band_n: f64,
    /// RMS of F_L - F_d over the run (N).
    pub rms_force_error_n: f64,
    /// Settling window excluded from the two figures below (s).
    pub settle_s: f64,
    /// max |F_L - F_d| after the settling window (N).
    pub max_abs_force_error_after_settle_n: f64,
    /// RMS of F_L - F_d after the settling window (N).
    pub rms_force_error_after_settle_n: f64,
    /// max |u| (valve command).
    pub max_abs_valve_command: f64,
    /// max |F_L| (N).
    pub peak_load_force_n: f64,
    /// RMS of knee angle - desired after the settling window (deg); null without a knee reference.
    pub knee_rms_error_deg: Option<f64>,
    /// max |knee angle - desired| after the settling window (deg); null without a knee reference.
    pub knee_max_abs_error_deg: Option<f64>,
    /// max |net cylinder force| after the settling window (N).
    pub peak_cylinder_force_n: f64,
    /// max |cylinder force x piston velocity| after the settling window (W).
    pub peak_power_w: f64,
    /// Per-stride figures of a gait run (empty otherwise).
    pub strides: Vec<StrideFigures>,
    /// Fraction of samples with the valve command clipped by `actuator.valve_command_limit`.
    pub valve_saturation_fraction: f64,
    /// Fraction of samples with F_L at the supply-pressure limit.
    pub force_limit_fraction: f64,
    /// Largest loop-closure gap of the leg over the run (m); null on the bench.
    pub loop_closure_max_gap_m: Option<f64>,
    /// Knee angle range over the run (deg), [min, max]; null on the bench.
    pub knee_range_deg: Option<[f64; 2]>,
    /// Number of fixed steps.
    pub steps: usize,
    /// Wall-clock time of the simulation loop (s).
    pub wall_time_s: f64,
    /// steps / wall_time_s.
    pub steps_per_second: f64,
    /// The resolved scenario: feed it back (`exoleg run summary.json`) to reproduce the run.
    pub scenario: ScenarioFile,
}

/// Compute the summary of a finished run.
pub fn summarise(s: &Scenario, r: &Record, wall_time_s: f64) -> Summary {
    // 1% of the reference amplitude: the sine's, or for a gait run (whose desired force is not
    // a sine) 1% of the largest |F_d| of the run, unless the scenario sets the band.
    let band = match (s.file.metrics.convergence_band_n, s.file.reference.kind) {
        (None, ReferenceKind::Gait) => 0.01 * max_abs(&r.ref_force_n),
        _ => s.convergence_band_n(),
    };
    let settle = s.file.metrics.settle_s;
    let i0 = settle_index(&r.t_s, settle);
    let steps = r.t_s.len().saturating_sub(1);
    let knee_err = knee_error_deg(r);
    Summary {
        max_abs_force_error_n: max_abs(&r.force_error_n),
        force_convergence_time_s: convergence_time(&r.t_s, &r.force_error_n, band),
        force_convergence_band_n: band,
        rms_force_error_n: rms(&r.force_error_n),
        settle_s: settle,
        max_abs_force_error_after_settle_n: max_abs(&r.force_error_n[i0..]),
        rms_force_error_after_settle_n: rms(&r.force_error_n[i0..]),
        max_abs_valve_command: max_abs(&r.valve_command),
        peak_load_force_n: max_abs(&r.load_force_n),
        knee_rms_error_deg: knee_err.as_ref().map(|e| rms(&e[i0..])),
        knee_max_abs_error_deg: knee_err.as_ref().map(|e| max_abs(&e[i0..])),
        peak_cylinder_force_n: max_abs(&r.cylinder_force_n[i0..]),
        peak_power_w: max_abs(&cylinder_power_w(r)[i0..]),
        strides: knee_err.as_ref().map_or(Vec::new(), |e| strides(r, e)),
        valve_saturation_fraction: mean(&r.valve_saturated),
        force_limit_fraction: mean(&r.force_limited),
        loop_closure_max_gap_m: r.extra_column("loop_closure_gap_m").map(max_abs),
        knee_range_deg: r.extra_column("knee_angle_deg").map(|q| {
            [q.iter().copied().fold(f64::INFINITY, f64::min), q.iter().copied().fold(f64::NEG_INFINITY, f64::max)]
        }),
        steps,
        wall_time_s,
        steps_per_second: if wall_time_s > 0.0 { steps as f64 / wall_time_s } else { f64::INFINITY },
        scenario: s.file.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn convergence_time_definition() {
        let t = [0.0, 0.1, 0.2, 0.3, 0.4];
        assert_eq!(convergence_time(&t, &[5.0, 3.0, 0.5, 2.5, 0.1], 1.0), Some(0.4));
        assert_eq!(convergence_time(&t, &[0.0, 0.1, 0.5, 0.5, 0.1], 1.0), Some(0.0));
        assert_eq!(convergence_time(&t, &[0.0, 0.1, 0.5, 0.5, 3.0], 1.0), None);
        assert!((rms(&[3.0, -4.0]) - (12.5f64).sqrt()).abs() < 1e-15);
        assert_eq!(settle_index(&t, 0.2), 2);
    }
}

/// One checked criterion.
#[derive(Debug, Clone, Serialize)]
pub struct CriterionResult {
    /// The `criteria.*` key.
    pub name: &'static str,
    /// The limit.
    pub limit: f64,
    /// The measured value (NaN if the run has no such figure).
    pub value: f64,
    /// value <= limit.
    pub pass: bool,
}

/// Check a summary against the scenario's criteria (only those that are set).
pub fn check_criteria(c: &CriteriaSection, s: &Summary) -> Vec<CriterionResult> {
    let nan = f64::NAN;
    [
        ("max_force_error_n", c.max_force_error_n, s.max_abs_force_error_after_settle_n),
        ("rms_force_error_n", c.rms_force_error_n, s.rms_force_error_after_settle_n),
        ("knee_rms_error_deg", c.knee_rms_error_deg, s.knee_rms_error_deg.unwrap_or(nan)),
        ("knee_max_error_deg", c.knee_max_error_deg, s.knee_max_abs_error_deg.unwrap_or(nan)),
        ("max_valve_saturation_fraction", c.max_valve_saturation_fraction, s.valve_saturation_fraction),
        ("max_force_limit_fraction", c.max_force_limit_fraction, s.force_limit_fraction),
    ]
    .into_iter()
    .filter_map(|(name, limit, value)| limit.map(|limit| CriterionResult { name, limit, value, pass: value <= limit }))
    .collect()
}
