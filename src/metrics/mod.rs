//! The metric definitions of MODEL.md section 6, defined once and computed online from the
//! rows of a run ([`SummaryBuilder`] is a [`RecordSink`]), so a run of any length needs
//! constant memory for its figures. Used by the CLI, the studies and the tests.

mod builder;
pub mod muscles;
pub mod safety;
pub mod walking;
pub mod wearer;
pub use builder::*;
pub use safety::{SafetyLimits, SafetyMetrics, SafetySetup, SafetySummary};
pub use walking::{ContactSummary, DatasetComparison, WalkingMetrics};
pub use wearer::{CuffLimits, WearerMetrics, WearerSummary};

use crate::error::Result;
use crate::record::{Layout, RecordSink, Row};
use serde::{Deserialize, Serialize};

/// Most strides with figures of their own in `summary.json` (`strides`); later strides count
/// in the run's figures only.
pub const MAX_STRIDES: usize = 10_000;

/// Tolerance (s) when comparing a row's time with a window boundary.
const T_EPS: f64 = 1e-12;

/// Largest absolute value (0 for an empty slice).
pub fn max_abs(xs: &[f64]) -> f64 {
    xs.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Root mean square (0 for an empty slice).
pub fn rms(xs: &[f64]) -> f64 {
    let mut a = Rms::default();
    xs.iter().for_each(|x| a.add(*x));
    a.value()
}

/// The convergence band of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Band {
    /// A fixed band (N): the scenario's, or 1 % of a sine's amplitude.
    Fixed(f64),
    /// This fraction of the largest |F_d| of the run (gait runs: 1 %).
    FractionOfPeakReference(f64),
}

/// What the metrics need to know about a run besides its rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MetricSettings {
    /// Convergence band.
    pub band: Band,
    /// Settling window excluded from the "after settle" figures (s).
    pub settle_s: f64,
    /// Stride time of a gait reference (s), for per-stride figures.
    pub stride_s: Option<f64>,
    /// The run has a desired force (`reference.force = "computed"`); without one the force
    /// figures are NaN (null in `summary.json`).
    pub force_reference: bool,
}

/// A figure that a run may not have (the force errors of a run without a desired force):
/// NaN in Rust, `null` in JSON.
pub mod nan_null {
    use serde::{Deserialize, Deserializer, Serializer};

    /// NaN as `null`, else the number.
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_nan() {
            s.serialize_none()
        } else {
            s.serialize_f64(*v)
        }
    }

    /// `null` as NaN.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

/// Figures of one stride of a gait run (errors over the whole stride).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    #[serde(with = "nan_null")]
    pub force_rms_error_n: f64,
    /// max |F_L - F_d| (N).
    #[serde(with = "nan_null")]
    pub force_max_abs_error_n: f64,
    /// max |net cylinder force| (N).
    pub peak_cylinder_force_n: f64,
    /// max |cylinder force x piston velocity| (W).
    pub peak_power_w: f64,
}

/// The figures of a run, as written to `summary.json` (plus the scenario and criteria, which
/// the output adds).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// max |F_L - F_d| over the run (N).
    #[serde(with = "nan_null")]
    pub max_abs_force_error_n: f64,
    /// Earliest t after which |F_L - F_d| stays within the band (s); null if never.
    pub force_convergence_time_s: Option<f64>,
    /// The band used for the convergence time (N).
    #[serde(with = "nan_null")]
    pub force_convergence_band_n: f64,
    /// RMS of F_L - F_d over the run (N).
    #[serde(with = "nan_null")]
    pub rms_force_error_n: f64,
    /// Settling window excluded from the figures "after settle" (s).
    pub settle_s: f64,
    /// max |F_L - F_d| after the settling window (N).
    #[serde(with = "nan_null")]
    pub max_abs_force_error_after_settle_n: f64,
    /// RMS of F_L - F_d after the settling window (N).
    #[serde(with = "nan_null")]
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
    /// Most substeps the hydraulic states needed in one step (1 = the fixed step was short
    /// enough everywhere; see the README's stability bounds).
    #[serde(default = "one")]
    pub hydraulic_substeps_max: usize,
    /// Number of steps whose hydraulic states were substepped.
    #[serde(default)]
    pub substepped_steps: usize,
    /// Sampled mode: readings that clipped at a sensor's full scale, by channel (empty when
    /// none did; see `sensors.*.range`).
    #[serde(default)]
    pub sensor_clipped_readings: std::collections::BTreeMap<String, usize>,
    /// Wall-clock time of the simulation loop (s).
    #[serde(default)]
    pub wall_time_s: f64,
    /// steps / wall_time_s.
    #[serde(default)]
    pub steps_per_second: f64,
    /// The leg's mechanics engine (`rapier` or `reduced`; absent on the bench).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub engine: Option<String>,
    /// Time the leg spent at its end stops and the deepest penetration (leg runs): the knee's
    /// URDF limits, the cylinder's stroke ends, the moving ankle's limits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_stops: Option<crate::leg::StopReport>,
    /// Samples a controller flagged with a warning (a C plugin's warning status), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller_warnings: Option<ControllerWarnings>,
    /// When and why the controller stopped under `controller.on_stop = "failsafe"` (the
    /// device went to its fail-safe state and the run went on), if it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller_stop: Option<ControllerStopReport>,
    /// Wall time of the controller's computations, measured (a C plugin's `exoleg_step`
    /// calls, in-process or isolated; a HIL peer's own figure): `samples`, `p50_s`, `p99_s`,
    /// `max_s`, `mean_s` (s). Measured, so it differs from run to run; never in the physics,
    /// and left out of a study's `runs.jsonl` lines.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller_compute: Option<serde_json::Value>,
    /// The link to a controller outside the process: an isolated plugin's round trips, a
    /// hardware-in-the-loop peer's latency, losses, deadlines and pacing (measured; left out of
    /// `runs.jsonl` lines).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller_link: Option<serde_json::Value>,
    /// What the controller's modelled computation did (`controller.compute_delay_s`, ...):
    /// `samples`, `max_time_s`, `max_delay_steps`, `overruns`, `dropped`. Modelled, so the
    /// same for the same run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compute_model: Option<serde_json::Value>,
    /// What would hurt the wearer (leg runs; see [`safety`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub safety: Option<SafetySummary>,
    /// What the wearer got (walking runs; see [`wearer`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wearer: Option<WearerSummary>,
    /// Ground-contact figures (runs with `ground.enabled`), flattened into the summary.
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactSummary>,
}

/// A sampled controller's stop under `controller.on_stop = "failsafe"` (`summary.json`
/// `controller_stop`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerStopReport {
    /// When (s).
    pub t_s: f64,
    /// `stop` (on purpose: a stop status), `command` (not a number) or `crash` (a signal, an
    /// exit, a hang, a broken link, an exception: the run does not pass).
    pub cause: crate::faults::StopCause,
    /// What the controller, or exoleg about it, said.
    pub message: String,
}

impl Summary {
    /// Why the run's controller crashed, if it did (under `controller.on_stop = "failsafe"`
    /// the run goes on, and does not pass).
    pub fn controller_crash(&self) -> Option<String> {
        let s = self.controller_stop.as_ref().filter(|s| s.cause == crate::faults::StopCause::Crash)?;
        Some(format!("the controller crashed at t = {:.6} s: {}", s.t_s, s.message))
    }

    /// The run's verdict: every criterion passed and its controller did not crash.
    pub fn passes(&self, criteria: &[CriterionResult]) -> bool {
        criteria.iter().all(|c| c.pass) && self.controller_crash().is_none()
    }
}

/// The warnings a sampled controller gave during a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerWarnings {
    /// Samples with a warning status.
    pub samples: usize,
    /// The last warning's message.
    pub last: String,
}

impl Summary {
    /// Check figures read back from a file (a shard's `runs.jsonl`): every number finite, every
    /// maximum, RMS, peak and time non-negative, every fraction within [0, 1]. The error names
    /// the figure.
    pub fn check_plausible(&self) -> std::result::Result<(), String> {
        let non_negative = [
            ("max_abs_force_error_n", self.max_abs_force_error_n),
            ("force_convergence_band_n", self.force_convergence_band_n),
            ("rms_force_error_n", self.rms_force_error_n),
            ("settle_s", self.settle_s),
            ("max_abs_force_error_after_settle_n", self.max_abs_force_error_after_settle_n),
            ("rms_force_error_after_settle_n", self.rms_force_error_after_settle_n),
            ("max_abs_valve_command", self.max_abs_valve_command),
            ("peak_load_force_n", self.peak_load_force_n),
            ("knee_rms_error_deg", self.knee_rms_error_deg.unwrap_or(0.0)),
            ("knee_max_abs_error_deg", self.knee_max_abs_error_deg.unwrap_or(0.0)),
            ("peak_cylinder_force_n", self.peak_cylinder_force_n),
            ("peak_power_w", self.peak_power_w),
            ("force_convergence_time_s", self.force_convergence_time_s.unwrap_or(0.0)),
            ("loop_closure_max_gap_m", self.loop_closure_max_gap_m.unwrap_or(0.0)),
            ("controller_stop.t_s", self.controller_stop.as_ref().map_or(0.0, |c| c.t_s)),
        ];
        for (name, v) in non_negative {
            // NaN: a figure the run does not have (no desired force).
            if !(v.is_nan() || (v.is_finite() && v >= 0.0)) {
                return Err(format!("{name} = {v}: a maximum, RMS, peak or time is finite and >= 0"));
            }
        }
        for (name, v) in [
            ("valve_saturation_fraction", self.valve_saturation_fraction),
            ("force_limit_fraction", self.force_limit_fraction),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(format!("{name} = {v}: a fraction is within [0, 1]"));
            }
        }
        if let Some([a, b]) = self.knee_range_deg {
            if !(a.is_finite() && b.is_finite() && a <= b) {
                return Err(format!("knee_range_deg = [{a}, {b}]"));
            }
        }
        Ok(())
    }
}

fn one() -> usize {
    1
}

/// A figure of a [`Summary`] by name, for aggregation over a sweep (typed: a renamed field is
/// a compile error, not a column that silently disappears).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metric {
    /// [`Summary::max_abs_force_error_n`].
    MaxAbsForceError,
    /// [`Summary::rms_force_error_n`].
    RmsForceError,
    /// [`Summary::max_abs_force_error_after_settle_n`].
    MaxAbsForceErrorAfterSettle,
    /// [`Summary::rms_force_error_after_settle_n`].
    RmsForceErrorAfterSettle,
    /// [`Summary::knee_rms_error_deg`].
    KneeRmsError,
    /// [`Summary::knee_max_abs_error_deg`].
    KneeMaxAbsError,
    /// [`Summary::valve_saturation_fraction`].
    ValveSaturationFraction,
    /// [`Summary::peak_cylinder_force_n`].
    PeakCylinderForce,
    /// The wearer's gross metabolic rate (W/kg, `wearer.metabolics.gross_w_per_kg`).
    MetabolicGross,
    /// The wearer's muscle effort (`wearer.metabolics.effort`).
    MuscleEffort,
}

impl Metric {
    /// The metrics aggregated over a sweep, in `aggregate.csv` order.
    pub const AGGREGATED: [Metric; 10] = [
        Metric::MaxAbsForceError,
        Metric::RmsForceError,
        Metric::MaxAbsForceErrorAfterSettle,
        Metric::RmsForceErrorAfterSettle,
        Metric::KneeRmsError,
        Metric::KneeMaxAbsError,
        Metric::ValveSaturationFraction,
        Metric::PeakCylinderForce,
        Metric::MetabolicGross,
        Metric::MuscleEffort,
    ];

    /// The `summary.json` key.
    pub fn name(&self) -> &'static str {
        match self {
            Metric::MaxAbsForceError => "max_abs_force_error_n",
            Metric::RmsForceError => "rms_force_error_n",
            Metric::MaxAbsForceErrorAfterSettle => "max_abs_force_error_after_settle_n",
            Metric::RmsForceErrorAfterSettle => "rms_force_error_after_settle_n",
            Metric::KneeRmsError => "knee_rms_error_deg",
            Metric::KneeMaxAbsError => "knee_max_abs_error_deg",
            Metric::ValveSaturationFraction => "valve_saturation_fraction",
            Metric::PeakCylinderForce => "peak_cylinder_force_n",
            Metric::MetabolicGross => "metabolic_gross_w_per_kg",
            Metric::MuscleEffort => "muscle_effort",
        }
    }

    /// The value in a summary (None when the run has no such figure).
    pub fn value(&self, s: &Summary) -> Option<f64> {
        self.raw(s).filter(|v| !v.is_nan())
    }

    fn raw(&self, s: &Summary) -> Option<f64> {
        match self {
            Metric::MaxAbsForceError => Some(s.max_abs_force_error_n),
            Metric::RmsForceError => Some(s.rms_force_error_n),
            Metric::MaxAbsForceErrorAfterSettle => Some(s.max_abs_force_error_after_settle_n),
            Metric::RmsForceErrorAfterSettle => Some(s.rms_force_error_after_settle_n),
            Metric::KneeRmsError => s.knee_rms_error_deg,
            Metric::KneeMaxAbsError => s.knee_max_abs_error_deg,
            Metric::ValveSaturationFraction => Some(s.valve_saturation_fraction),
            Metric::PeakCylinderForce => Some(s.peak_cylinder_force_n),
            Metric::MetabolicGross => s.wearer.as_ref()?.metabolics.as_ref().map(|m| m.gross_w_per_kg),
            Metric::MuscleEffort => s.wearer.as_ref()?.metabolics.as_ref().map(|m| m.effort),
        }
    }
}

/// `[criteria]`: pass/fail limits checked after a run (absent = not checked). A run whose
/// criteria fail still writes its outputs and exits with code 4.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Criteria {
    /// Limit on max |F_L - F_d| after the settling window (N).
    pub max_force_error_n: Option<f64>,
    /// Limit on the RMS force error after the settling window (N).
    pub rms_force_error_n: Option<f64>,
    /// Limit on the knee RMS error after the settling window (deg).
    pub knee_rms_error_deg: Option<f64>,
    /// Limit on max |knee error| after the settling window (deg).
    pub knee_max_error_deg: Option<f64>,
    /// Limit on the fraction of samples with the valve command saturated.
    pub max_valve_saturation_fraction: Option<f64>,
    /// Limit on the fraction of samples at the supply-pressure force limit.
    pub max_force_limit_fraction: Option<f64>,
    /// Limit on the number of reasons a loaded-walking run is not walking
    /// (`not_walking` in `summary.json`): 0 fails any run that is not walking. NaN (a
    /// failure) for a run that is not loaded walking.
    pub max_not_walking_flags: Option<f64>,
}

impl Criteria {
    /// The limits with their keys, in order.
    pub fn limits(&self) -> [(&'static str, Option<f64>); 7] {
        [
            ("max_force_error_n", self.max_force_error_n),
            ("rms_force_error_n", self.rms_force_error_n),
            ("knee_rms_error_deg", self.knee_rms_error_deg),
            ("knee_max_error_deg", self.knee_max_error_deg),
            ("max_valve_saturation_fraction", self.max_valve_saturation_fraction),
            ("max_force_limit_fraction", self.max_force_limit_fraction),
            ("max_not_walking_flags", self.max_not_walking_flags),
        ]
    }

    /// True when at least one limit is set.
    pub fn any(&self) -> bool {
        self.limits().iter().any(|(_, l)| l.is_some())
    }
}

/// One checked criterion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CriterionResult {
    /// The `criteria.*` key.
    pub name: String,
    /// The limit.
    pub limit: f64,
    /// The measured value (NaN if the run has no such figure).
    pub value: f64,
    /// value <= limit.
    pub pass: bool,
}

/// Check a summary against the scenario's criteria (only those that are set).
pub fn check_criteria(c: &Criteria, s: &Summary) -> Vec<CriterionResult> {
    let nan = f64::NAN;
    let values = [
        s.max_abs_force_error_after_settle_n,
        s.rms_force_error_after_settle_n,
        s.knee_rms_error_deg.unwrap_or(nan),
        s.knee_max_abs_error_deg.unwrap_or(nan),
        s.valve_saturation_fraction,
        s.force_limit_fraction,
        s.contact.as_ref().and_then(|c| c.not_walking.as_ref()).map_or(nan, |v| v.len() as f64),
    ];
    c.limits()
        .into_iter()
        .zip(values)
        .filter_map(|((name, limit), value)| {
            limit.map(|limit| CriterionResult { name: name.to_string(), limit, value, pass: value <= limit })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t: f64, e: f64, r: f64) -> Row {
        Row { t_s: t, force_error_n: e, ref_force_n: r, ..Default::default() }
    }

    fn conv(band: Band, errs: &[f64], refs: &[f64]) -> Option<f64> {
        let mut b = SummaryBuilder::new(MetricSettings { band, settle_s: 0.0, stride_s: None, force_reference: true });
        b.start(&Layout::default()).unwrap();
        for (i, (e, r)) in errs.iter().zip(refs).enumerate() {
            b.row(&row(0.1 * i as f64, *e, *r)).unwrap();
        }
        b.finish(0.0).force_convergence_time_s
    }

    #[test]
    fn convergence_time_definition() {
        let z = [0.0; 5];
        assert_eq!(conv(Band::Fixed(1.0), &[5.0, 3.0, 0.5, 2.5, 0.1], &z), Some(0.4));
        assert_eq!(conv(Band::Fixed(1.0), &[0.0, 0.1, 0.5, 0.5, 0.1], &z), Some(0.0));
        assert_eq!(conv(Band::Fixed(1.0), &[0.0, 0.1, 0.5, 0.5, 3.0], &z), None);
        assert!((rms(&[3.0, -4.0]) - (12.5f64).sqrt()).abs() < 1e-15);
    }

    /// With the band a fraction of the peak reference, known only at the end, the online
    /// answer equals the one computed from the whole series.
    #[test]
    fn convergence_with_a_band_known_only_at_the_end() {
        let errs = [9.0, 7.0, 8.0, 3.0, 4.0, 2.5, 1.0, 2.6, 0.5, 0.4];
        let refs = [10.0, 50.0, 100.0, 150.0, 100.0, 0.0, -50.0, -260.0, 0.0, 10.0];
        // band = 1 % of 260 = 2.6: the last error above it is 3.0 at index 4 (4.0), next t = 0.5
        assert_eq!(conv(Band::FractionOfPeakReference(0.01), &errs, &refs), Some(0.5));
        let refs_small = refs.map(|r| r / 2.6); // band 1.0: last violation at index 7 -> t 0.8
        assert_eq!(conv(Band::FractionOfPeakReference(0.01), &errs, &refs_small), Some(0.8));
    }
}
