//! What the wearer's muscles cost (issue 39): the muscle analysis's samples after the run-in
//! (`metrics.settle_s`) summed as exoskeleton studies report them.
//!
//! - Gross metabolic rate (W/kg): this leg's muscles' mean rate, twice (both legs, assumed
//!   symmetric), over the subject's mass, plus the basal 1.2 W/kg (Umberger et al. 2003); net:
//!   without the basal rate. J per stride: the gross rate times the mass and the stride.
//! - Effort: the mean over the samples of this leg's summed squared activations.
//! - Peak reserve: the largest |reserve| at each joint over the largest |moment| the wearer
//!   applies there, in % (the field's guideline: under 5 %).
//! - Activations against normative EMG: each muscle's mean activation inside the phases where
//!   Perry (1992) has it on (the windows of its on/off bars as tabulated in
//!   `get_emgTimingFromPerry.m`; % of the stride from heel strike on the data's clock) and
//!   outside them; a muscle agrees when it is more active inside.

use super::Rms;
use crate::error::Result;
use crate::muscles::analysis::{MuscleSetup, PER_MUSCLE};
use crate::record::{Layout, RecordSink, Row};
use crate::reference::WalkingData;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Perry (1992)'s on-windows (% of the stride) per muscle name of the 9-muscle models
/// (Rajagopal's muscles by the group they belong to).
pub const EMG_ON_WINDOWS: [(&str, &[(f64, f64)]); 9] = [
    ("glut_max", &[(0.0, 24.0), (94.0, 100.0)]),
    ("iliopsoas", &[(60.0, 72.0)]),
    ("hamstrings", &[(0.0, 5.0), (80.0, 100.0)]),
    ("rect_fem", &[(55.0, 66.0)]),
    ("vasti", &[(0.0, 18.0), (90.0, 100.0)]),
    ("bifemsh", &[(62.0, 81.0)]),
    ("gastroc", &[(6.0, 48.0)]),
    ("soleus", &[(3.0, 52.0)]),
    ("tib_ant", &[(0.0, 9.0), (54.0, 100.0)]),
];

/// Whether `pct` falls in `windows`.
pub fn in_windows(pct: f64, windows: &[(f64, f64)]) -> bool {
    windows.iter().any(|(a, b)| pct >= *a && pct < *b)
}

/// One muscle's activation against its normative on-windows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EmgCheck {
    /// The muscle.
    pub muscle: String,
    /// Perry (1992)'s on-windows (% of the stride).
    pub on_windows_pct: Vec<[f64; 2]>,
    /// Mean activation inside them.
    pub on_mean: f64,
    /// Mean activation outside them.
    pub off_mean: f64,
    /// Where in the stride the activation peaks (% of the stride, cycle means).
    pub peak_pct: f64,
    /// More active inside the windows than outside.
    pub agrees: bool,
}

/// `summary.json` `wearer.metabolics`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetabolicsSummary {
    /// The source model of the muscles, and where the table came from.
    pub muscle_model: String,
    /// The table's origin (`builtin:...` or its path).
    pub muscle_table: String,
    /// The length scale applied to the source model.
    pub scale: f64,
    /// The metabolic model.
    pub metabolic_model: String,
    /// What static optimisation minimised.
    pub muscle_cost: String,
    /// Gross metabolic rate of a person walking with this leg's muscles on both legs (W/kg).
    pub gross_w_per_kg: f64,
    /// The same without the basal rate (W/kg).
    pub net_w_per_kg: f64,
    /// The basal rate added (W/kg).
    pub basal_w_per_kg: f64,
    /// Gross metabolic energy per stride (J, both legs and the basal rate).
    pub gross_j_per_stride: Option<f64>,
    /// Each of this leg's muscles' mean metabolic rate (W).
    pub per_muscle_w: BTreeMap<String, f64>,
    /// Each muscle's mean activation.
    pub per_muscle_activation: BTreeMap<String, f64>,
    /// Mean over the samples of this leg's summed squared activations.
    pub effort: f64,
    /// Largest |reserve| at hip, knee and ankle (N m).
    pub peak_reserve_nm: [f64; 3],
    /// It over the largest |moment| the wearer applies there (%).
    pub peak_reserve_pct: [f64; 3],
    /// RMS reserve at hip, knee and ankle (N m).
    pub rms_reserve_nm: [f64; 3],
    /// Samples whose angles left a muscle's table (its length extrapolated).
    pub samples_outside_tables: usize,
    /// Samples the figures average (after the run-in).
    pub samples: usize,
    /// Activations against normative EMG.
    pub emg: Vec<EmgCheck>,
    /// The same scenario without the device's help (`exoleg run --baseline`): its gross rate
    /// (W/kg).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline_gross_w_per_kg: Option<f64>,
    /// The change against it (%; negative: a saving).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub change_pct: Option<f64>,
    /// The baseline's effort.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline_effort: Option<f64>,
    /// The effort's change against it (%).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub effort_change_pct: Option<f64>,
    /// Cycle means for the plot (not written to `summary.json`).
    #[serde(skip)]
    pub cycle: Option<MuscleCycle>,
}

impl MetabolicsSummary {
    /// Set the baseline's figures and the changes against them.
    pub fn against(&mut self, baseline: &MetabolicsSummary) {
        self.baseline_gross_w_per_kg = Some(baseline.gross_w_per_kg);
        self.change_pct = Some(100.0 * (self.gross_w_per_kg / baseline.gross_w_per_kg - 1.0));
        self.baseline_effort = Some(baseline.effort);
        self.effort_change_pct = Some(100.0 * (self.effort / baseline.effort - 1.0));
    }
}

/// Per muscle, its mean activation in 100 bins of 1 % of the stride (the data's clock).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MuscleCycle {
    /// The muscles' names.
    pub names: Vec<String>,
    /// Per muscle, 100 means.
    pub activation: Vec<Vec<f64>>,
}

/// The running sums.
#[derive(Debug)]
pub struct MuscleMetrics {
    settle_s: f64,
    setup: Arc<MuscleSetup>,
    data: Arc<WalkingData>,
    origin: String,
    samples: usize,
    outside: usize,
    total_w: f64,
    effort: f64,
    per_muscle_w: Vec<f64>,
    per_muscle_a: Vec<f64>,
    peak_reserve: [f64; 3],
    peak_moment: [f64; 3],
    rms_reserve: [Rms; 3],
    bins: Vec<[f64; 100]>,
    bin_counts: [usize; 100],
}

impl MuscleMetrics {
    /// Figures after `settle_s` (s) on the data's clock of `data`.
    pub fn new(settle_s: f64, setup: Arc<MuscleSetup>, data: Arc<WalkingData>) -> Self {
        let n = setup.set.muscles.len();
        let origin = setup.set.source.clone();
        Self {
            settle_s,
            setup,
            data,
            origin,
            samples: 0,
            outside: 0,
            total_w: 0.0,
            effort: 0.0,
            per_muscle_w: vec![0.0; n],
            per_muscle_a: vec![0.0; n],
            peak_reserve: [0.0; 3],
            peak_moment: [0.0; 3],
            rms_reserve: [Rms::default(); 3],
            bins: vec![[0.0; 100]; n],
            bin_counts: [0; 100],
        }
    }

    /// The figures (None before any sample after the run-in).
    pub fn finish(&self) -> Option<MetabolicsSummary> {
        if self.samples == 0 {
            return None;
        }
        let k = 1.0 / self.samples as f64;
        let mass = self.setup.body_mass_kg;
        let basal = crate::muscles::metabolics::BASAL_W_PER_KG;
        let net = crate::muscles::metabolics::net_w_per_kg(self.total_w * k, mass);
        let names: Vec<String> = self.setup.names().map(str::to_string).collect();
        let cycle = self.cycle(&names);
        Some(MetabolicsSummary {
            muscle_model: self.setup.set.model.clone(),
            muscle_table: self.origin.clone(),
            scale: self.setup.set.scale,
            metabolic_model: self.setup.model.as_str().into(),
            muscle_cost: self.setup.cost.as_str().into(),
            gross_w_per_kg: net + basal,
            net_w_per_kg: net,
            basal_w_per_kg: basal,
            gross_j_per_stride: Some((net + basal) * mass * self.data.gait.stride_s),
            per_muscle_w: names.iter().cloned().zip(self.per_muscle_w.iter().map(|w| w * k)).collect(),
            per_muscle_activation: names.iter().cloned().zip(self.per_muscle_a.iter().map(|a| a * k)).collect(),
            effort: self.effort * k,
            peak_reserve_nm: self.peak_reserve,
            peak_reserve_pct: [0, 1, 2].map(|j| 100.0 * self.peak_reserve[j] / self.peak_moment[j].max(1e-9)),
            rms_reserve_nm: [0, 1, 2].map(|j| self.rms_reserve[j].value()),
            samples_outside_tables: self.outside,
            samples: self.samples,
            emg: emg_checks(&cycle),
            baseline_gross_w_per_kg: None,
            change_pct: None,
            baseline_effort: None,
            effort_change_pct: None,
            cycle: Some(cycle),
        })
    }

    fn cycle(&self, names: &[String]) -> MuscleCycle {
        let activation = self
            .bins
            .iter()
            .map(|b| {
                b.iter().zip(&self.bin_counts).map(|(s, &c)| if c > 0 { s / c as f64 } else { f64::NAN }).collect()
            })
            .collect();
        MuscleCycle { names: names.to_vec(), activation }
    }
}

/// Each muscle with normative windows against them (cycle means).
pub fn emg_checks(cycle: &MuscleCycle) -> Vec<EmgCheck> {
    let mut out = Vec::new();
    for (name, act) in cycle.names.iter().zip(&cycle.activation) {
        let Some((_, windows)) = EMG_ON_WINDOWS.iter().find(|(n, _)| n == name) else { continue };
        let (mut on, mut off) = ((0.0, 0usize), (0.0, 0usize));
        let mut peak = (f64::NEG_INFINITY, 0.0);
        for (i, a) in act.iter().enumerate().filter(|(_, a)| a.is_finite()) {
            let pct = i as f64 + 0.5;
            let slot = if in_windows(pct, windows) { &mut on } else { &mut off };
            (slot.0, slot.1) = (slot.0 + a, slot.1 + 1);
            if *a > peak.0 {
                peak = (*a, pct);
            }
        }
        let (on_mean, off_mean) = (on.0 / on.1.max(1) as f64, off.0 / off.1.max(1) as f64);
        out.push(EmgCheck {
            muscle: name.clone(),
            on_windows_pct: windows.iter().map(|(a, b)| [*a, *b]).collect(),
            on_mean,
            off_mean,
            peak_pct: peak.1,
            agrees: on_mean > off_mean,
        });
    }
    out
}

impl RecordSink for MuscleMetrics {
    fn start(&mut self, _layout: &Layout) -> Result<()> {
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        let Some(v) = &r.muscles else { return Ok(()) };
        if r.t_s < self.settle_s - 1e-9 {
            return Ok(());
        }
        let n = self.per_muscle_w.len();
        let w = PER_MUSCLE.len();
        let totals = &v[n * w..];
        if !totals[0].is_finite() {
            return Ok(());
        }
        self.samples += 1;
        self.total_w += totals[0];
        self.effort += totals[1];
        let bin = (self.data.pct_at(r.t_s) as usize).min(99);
        self.bin_counts[bin] += 1;
        for i in 0..n {
            let (a, rate) = (v[i * w], v[i * w + 5]);
            self.per_muscle_a[i] += a;
            self.per_muscle_w[i] += rate;
            self.bins[i][bin] += a;
        }
        for j in 0..3 {
            self.peak_reserve[j] = self.peak_reserve[j].max(totals[2 + j].abs());
            self.peak_moment[j] = self.peak_moment[j].max(totals[5 + j].abs());
            self.rms_reserve[j].add(totals[2 + j]);
        }
        self.outside += usize::from(totals[9] > 0.0);
        Ok(())
    }
}
