//! What the wearer gets (issue 32): for a walking run, what the device's knee moment did
//! against the wearer's biological knee moment (the gait data's, scaled by the subject's
//! mass), the work and hydraulic energy per stride, the cuff interaction forces against
//! comfort and pain limits, the knee range used, and, for a controller that logs its gait
//! phase (`log_gait_phase_pct`), its heel-strike detection latency and phase error. Computed
//! online from the rows after the run-in (`metrics.settle_s`).
//!
//! - Phase windows (Perry's, on the data's cycle clock, % of the stride): loading response
//!   0-12, mid-stance 12-31, terminal stance 31-50, pre-swing 50-62, swing 62-100.
//! - The device's share of a window: `integral(M_dev sign(M_bio)) / integral(|M_bio|)`, the
//!   part of the biological moment's magnitude the device supplied in its direction (negative
//!   when it opposes it); the wearer's remaining torque `M_bio - M_dev`.
//! - Device work: the cylinder's net force times the piston velocity (= the device's knee
//!   moment times the knee's extension rate), positive and negative parts integrated apart.
//! - Hydraulic energy: the supply pressure times the flow the valve draws from the supply.
//! - True heel strike: the vertical ground reaction rising over [`super::walking::STANCE_CONTACT_N`]
//!   after the foot was off the ground (under [`super::walking::NO_CONTACT_N`]). The
//!   controller's: its logged phase falling by more than 50 points (a wrap), or its first
//!   estimate after NaN (none yet) below 50. Latency: the detection nearest each true heel
//!   strike within half a stride, before (negative: early) or after it. Phase error: the
//!   logged phase against `100 (t - t_HS) / (t_HS,next - t_HS)`, wrapped to +-50 points.

use super::walking::{NO_CONTACT_N, STANCE_CONTACT_N};
use super::Rms;
use crate::error::Result;
use crate::record::{Layout, RecordSink, Row};
use crate::reference::WalkingData;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The phase windows: name and [start, end) in % of the stride.
pub const PHASE_WINDOWS: [(&str, f64, f64); 5] = [
    ("loading_response", 0.0, 12.0),
    ("mid_stance", 12.0, 31.0),
    ("terminal_stance", 31.0, 50.0),
    ("pre_swing", 50.0, 62.0),
    ("swing", 62.0, 100.0),
];

/// The logged channel a controller names its gait-phase estimate (% of the stride, 0..100).
pub const PHASE_LOG_NAME: &str = "gait_phase_pct";

/// Most rows of one stride kept to score a logged phase (a 20 s stride at 1 kHz, twice over).
const MAX_STRIDE_ROWS: usize = 1 << 20;

/// `[cuff_limits]`: the interaction-force limits a cuff is judged against (N, normal force).
/// Defaults from the literature (README, "What the wearer gets"): discomfort from 40 N through
/// a rigid thigh cuff in prolonged repetitive loading (Bessler-Etten et al. 2024, Appl. Ergon.
/// 115:104055: onset at 40 to over 230 N), pain at 220 N (thigh) and 130 N (lower leg), the
/// quasi-static limits of ISO/TS 15066:2016, Annex A.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CuffLimits {
    /// Comfort limit of both cuffs (N). > 0.
    pub comfort_n: f64,
    /// Pain limit of the thigh cuff (N). > 0.
    pub thigh_pain_n: f64,
    /// Pain limit of the shank cuff (N). > 0.
    pub shank_pain_n: f64,
}

impl Default for CuffLimits {
    fn default() -> Self {
        Self { comfort_n: 40.0, thigh_pain_n: 220.0, shank_pain_n: 130.0 }
    }
}

/// The device against the biological moment over one phase window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhaseWindow {
    /// The window's name.
    pub phase: String,
    /// Its start and end (% of the stride).
    pub pct: [f64; 2],
    /// Mean device knee moment (N m, extensor positive).
    pub device_moment_mean_nm: f64,
    /// Mean biological knee moment, the data's (N m).
    pub biological_moment_mean_nm: f64,
    /// The device's share of the biological moment (see the module doc; None when the data's
    /// moment is zero there).
    pub device_share: Option<f64>,
    /// RMS of the wearer's remaining torque `M_bio - M_dev` (N m).
    pub remaining_rms_nm: f64,
}

/// One cuff's interaction force.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CuffFigures {
    /// Peak |force| (N).
    pub peak_n: f64,
    /// RMS force (N).
    pub rms_n: f64,
    /// Fraction of the time over the comfort limit.
    pub over_comfort_fraction: f64,
    /// The comfort and pain limits (N).
    pub limits_n: [f64; 2],
    /// `comfortable`, `uncomfortable` (over the comfort limit at its peak) or `painful` (over
    /// the pain limit).
    pub verdict: String,
}

/// A controller's own gait-phase estimate against the truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhaseEstimate {
    /// True heel strikes after the run-in.
    pub heel_strikes: usize,
    /// Heel strikes the controller detected (its phase wrapped within half a stride after one).
    pub detected: usize,
    /// Median detection latency (s; negative: early).
    pub median_latency_s: Option<f64>,
    /// Largest |latency| (s).
    pub max_latency_s: Option<f64>,
    /// RMS of the phase error over the complete strides (% of the stride).
    pub phase_rmse_pct: Option<f64>,
}

/// What the wearer got (`summary.json` `wearer`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WearerSummary {
    /// Strides after the run-in (time over the stride time).
    pub strides: f64,
    /// Per phase window.
    pub phases: Vec<PhaseWindow>,
    /// The device's share of the biological moment over the stance (0-62 %).
    pub stance_device_share: Option<f64>,
    /// Peak |remaining torque| over the stride (N m).
    pub remaining_peak_nm: f64,
    /// Positive device work per stride (J).
    pub positive_work_per_stride_j: f64,
    /// Negative device work per stride (J, <= 0).
    pub negative_work_per_stride_j: f64,
    /// Hydraulic energy drawn from the supply per stride (J).
    pub hydraulic_energy_per_stride_j: f64,
    /// Mean hydraulic power (W): for pump and battery sizing.
    pub hydraulic_power_mean_w: f64,
    /// The thigh cuff.
    pub thigh_cuff: CuffFigures,
    /// The shank cuff.
    pub shank_cuff: CuffFigures,
    /// Knee range used (deg, [min, max]).
    pub knee_range_deg: [f64; 2],
    /// The wearer's knee range in the data (deg, [min, max]).
    pub data_knee_range_deg: [f64; 2],
    /// A logged gait phase against the truth (None when the controller logs none).
    pub phase_estimate: Option<PhaseEstimate>,
    /// The cycle means for the plot (not written to `summary.json`).
    #[serde(skip)]
    pub cycle: Option<WearerCycle>,
    /// What the wearer's muscles cost (`wearer.muscles`).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub metabolics: Option<super::muscles::MetabolicsSummary>,
}

/// Means over the cycle (100 bins of 1 %, the data's clock) after the run-in: what
/// `wearer.png` draws.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WearerCycle {
    /// The device's knee moment (N m).
    pub device_moment_nm: Vec<f64>,
    /// The biological knee moment, the data's (N m).
    pub biological_moment_nm: Vec<f64>,
    /// The thigh cuff's force (N).
    pub thigh_cuff_n: Vec<f64>,
    /// The shank cuff's force (N).
    pub shank_cuff_n: Vec<f64>,
    /// The knee angle (deg).
    pub knee_deg: Vec<f64>,
}

/// Running figures of one cuff.
#[derive(Debug, Clone, Copy, Default)]
struct CuffAcc {
    peak: f64,
    rms: Rms,
    over: usize,
}

impl CuffAcc {
    fn add(&mut self, f: f64, comfort: f64) {
        self.peak = self.peak.max(f.abs());
        self.rms.add(f);
        self.over += usize::from(f.abs() > comfort);
    }

    fn finish(&self, rows: usize, comfort: f64, pain: f64) -> CuffFigures {
        let verdict = if self.peak > pain {
            "painful"
        } else if self.peak > comfort {
            "uncomfortable"
        } else {
            "comfortable"
        };
        CuffFigures {
            peak_n: self.peak,
            rms_n: self.rms.value(),
            over_comfort_fraction: if rows > 0 { self.over as f64 / rows as f64 } else { 0.0 },
            limits_n: [comfort, pain],
            verdict: verdict.into(),
        }
    }
}

/// Running sums of one phase window.
#[derive(Debug, Clone, Copy, Default)]
struct WindowAcc {
    n: usize,
    dev: f64,
    bio: f64,
    along: f64,
    bio_abs: f64,
    remaining: Rms,
}

/// Heel strikes and a logged phase against them.
#[derive(Debug, Clone, Default)]
struct PhaseScore {
    /// The foot has been off the ground since the last heel strike.
    off: bool,
    last_hs: Option<f64>,
    /// The true heel strikes and the controller's detections (s; at most
    /// [`super::MAX_STRIDES`] each).
    strikes: Vec<f64>,
    detections: Vec<f64>,
    /// The current stride's (t, logged phase).
    stride: Vec<(f64, f64)>,
    last_phase: Option<f64>,
    errors: Rms,
}

impl PhaseScore {
    /// One row; heel strikes count from `settled` on (detections before it still pair with
    /// the first one).
    fn row(&mut self, t: f64, vertical_n: f64, phase: Option<f64>, settled: bool) {
        if vertical_n < NO_CONTACT_N {
            self.off = true;
        }
        if self.off && vertical_n > STANCE_CONTACT_N {
            self.off = false;
            if let Some(t0) = self.last_hs {
                let len = t - t0;
                for (ti, p) in &self.stride {
                    let truth = 100.0 * (ti - t0) / len;
                    self.errors.add((p - truth + 50.0).rem_euclid(100.0) - 50.0);
                }
            }
            self.stride.clear();
            self.last_hs = Some(t).filter(|_| settled);
            if settled && self.strikes.len() < super::MAX_STRIDES {
                self.strikes.push(t);
            }
        }
        let Some(p) = phase else { return };
        if self.last_hs.is_some() && self.stride.len() < MAX_STRIDE_ROWS && !p.is_nan() {
            self.stride.push((t, p));
        }
        // A detection: the phase wraps (falls by more than 50 points), or a first estimate
        // (after NaN: none yet) starts in the stride's first half.
        if let Some(prev) = self.last_phase {
            let wrap = prev - p > 50.0 || (prev.is_nan() && p < 50.0);
            if wrap && self.detections.len() < super::MAX_STRIDES {
                self.detections.push(t);
            }
        }
        self.last_phase = Some(p);
    }

    /// Each true heel strike paired with the nearest detection within half a stride
    /// (`stride_s`, s) of it, before or after.
    fn finish(&self, stride_s: f64) -> PhaseEstimate {
        let mut l: Vec<f64> = self
            .strikes
            .iter()
            .filter_map(|hs| {
                let d = self.detections.iter().map(|d| d - hs).filter(|x| x.abs() <= 0.5 * stride_s);
                d.min_by(|a, b| a.abs().total_cmp(&b.abs()))
            })
            .collect();
        l.sort_by(f64::total_cmp);
        PhaseEstimate {
            heel_strikes: self.strikes.len(),
            detected: l.len(),
            median_latency_s: (!l.is_empty()).then(|| l[l.len() / 2]),
            max_latency_s: l.iter().map(|x| x.abs()).reduce(f64::max),
            phase_rmse_pct: self.errors.value_if_any(),
        }
    }
}

/// Accumulates [`WearerSummary`] row by row (a [`RecordSink`]).
#[derive(Debug, Clone)]
pub struct WearerMetrics {
    settle_s: f64,
    data: Arc<WalkingData>,
    limits: CuffLimits,
    windows: [WindowAcc; 5],
    remaining_peak: f64,
    work: [f64; 2],
    hydraulic_j: f64,
    cuffs: [CuffAcc; 2],
    rows: usize,
    knee: [f64; 2],
    span: Option<(f64, f64)>,
    last_t: Option<f64>,
    phase_log: Option<usize>,
    phase: PhaseScore,
    /// Per 1 % bin: count and sums of the device and biological moments, the cuffs, the knee.
    bins: Vec<(usize, [f64; 5])>,
}

impl WearerMetrics {
    /// Figures after `settle_s` (s) against the walking `data`, the cuffs judged by `limits`.
    pub fn new(settle_s: f64, data: Arc<WalkingData>, limits: CuffLimits) -> Self {
        Self {
            settle_s,
            data,
            limits,
            windows: [WindowAcc::default(); 5],
            remaining_peak: 0.0,
            work: [0.0; 2],
            hydraulic_j: 0.0,
            cuffs: [CuffAcc::default(); 2],
            rows: 0,
            knee: [f64::INFINITY, f64::NEG_INFINITY],
            span: None,
            last_t: None,
            phase_log: None,
            phase: PhaseScore::default(),
            bins: vec![(0, [0.0; 5]); 100],
        }
    }

    /// The cycle means (None while a bin is empty).
    fn cycle(&self) -> Option<WearerCycle> {
        if self.bins.iter().any(|b| b.0 == 0) {
            return None;
        }
        let col = |k: usize| self.bins.iter().map(|(n, s)| s[k] / *n as f64).collect();
        Some(WearerCycle {
            device_moment_nm: col(0),
            biological_moment_nm: col(1),
            thigh_cuff_n: col(2),
            shank_cuff_n: col(3),
            knee_deg: col(4),
        })
    }

    /// The figures (None before any row after the run-in).
    pub fn finish(&self) -> Option<WearerSummary> {
        let (t0, t1) = self.span?;
        let strides = (t1 - t0) / self.data.gait.stride_s;
        let per = |x: f64| if strides > 0.0 { x / strides } else { 0.0 };
        let share = |along: f64, abs: f64| (abs > 0.0).then(|| along / abs);
        let phases = PHASE_WINDOWS
            .iter()
            .zip(&self.windows)
            .map(|((name, a, b), w)| {
                let mean = |x: f64| if w.n > 0 { x / w.n as f64 } else { 0.0 };
                PhaseWindow {
                    phase: name.to_string(),
                    pct: [*a, *b],
                    device_moment_mean_nm: mean(w.dev),
                    biological_moment_mean_nm: mean(w.bio),
                    device_share: share(w.along, w.bio_abs),
                    remaining_rms_nm: w.remaining.value(),
                }
            })
            .collect();
        let stance = &self.windows[..4];
        let l = &self.limits;
        let gait = &self.data.gait;
        let knee_data = (0..200).map(|i| gait.knee_at(i as f64 * gait.stride_s / 200.0).value.to_degrees());
        let data_knee = knee_data.fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], q| [lo.min(q), hi.max(q)]);
        Some(WearerSummary {
            strides,
            phases,
            stance_device_share: share(stance.iter().map(|w| w.along).sum(), stance.iter().map(|w| w.bio_abs).sum()),
            remaining_peak_nm: self.remaining_peak,
            positive_work_per_stride_j: per(self.work[0]),
            negative_work_per_stride_j: per(self.work[1]),
            hydraulic_energy_per_stride_j: per(self.hydraulic_j),
            hydraulic_power_mean_w: if t1 > t0 { self.hydraulic_j / (t1 - t0) } else { 0.0 },
            thigh_cuff: self.cuffs[0].finish(self.rows, l.comfort_n, l.thigh_pain_n),
            shank_cuff: self.cuffs[1].finish(self.rows, l.comfort_n, l.shank_pain_n),
            knee_range_deg: self.knee,
            data_knee_range_deg: data_knee,
            phase_estimate: self.phase_log.map(|_| self.phase.finish(self.data.gait.stride_s)),
            cycle: self.cycle(),
            metabolics: None,
        })
    }
}

impl RecordSink for WearerMetrics {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.phase_log = layout.log.iter().position(|n| n == PHASE_LOG_NAME);
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        let (Some(d), Some(leg)) = (r.device, r.leg) else { return Ok(()) };
        let dt = self.last_t.map_or(0.0, |t| r.t_s - t);
        self.last_t = Some(r.t_s);
        let vertical = r.contact.map_or(0.0, |c| c.ground_reaction_vertical_n);
        let logged = self.phase_log.map(|k| r.log[k]);
        let settled = r.t_s >= self.settle_s - 1e-9;
        self.phase.row(r.t_s, vertical, logged, settled);
        if !settled {
            return Ok(());
        }
        self.span = Some((self.span.map_or(r.t_s, |s| s.0), r.t_s));
        self.rows += 1;
        let pct = self.data.pct_at(r.t_s);
        let (dev, bio) = (d.device_knee_moment_nm, self.data.knee_moment_at_pct(pct));
        let i = PHASE_WINDOWS.iter().position(|(_, a, b)| pct >= *a && pct < *b).unwrap_or(4);
        let w = &mut self.windows[i];
        w.n += 1;
        w.dev += dev;
        w.bio += bio;
        w.along += dev * bio.signum();
        w.bio_abs += bio.abs();
        w.remaining.add(bio - dev);
        self.remaining_peak = self.remaining_peak.max((bio - dev).abs());
        let p = r.cylinder_power_w();
        self.work[usize::from(p < 0.0)] += p * dt;
        self.hydraulic_j += d.hydraulic_power_w * dt;
        self.cuffs[0].add(d.thigh_cuff_force_n, self.limits.comfort_n);
        self.cuffs[1].add(d.shank_cuff_force_n, self.limits.comfort_n);
        self.knee = [self.knee[0].min(leg.knee_angle_deg), self.knee[1].max(leg.knee_angle_deg)];
        let b = &mut self.bins[(pct as usize).min(99)];
        b.0 += 1;
        for (acc, v) in b.1.iter_mut().zip([dev, bio, d.thigh_cuff_force_n, d.shank_cuff_force_n, leg.knee_angle_deg]) {
            *acc += v;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A phase estimate that wraps 20 ms after each true heel strike and ramps at the true
    /// rate reads a 20 ms latency and a phase error of 20 ms over the stride.
    #[test]
    fn a_late_phase_estimate_scores_its_latency() {
        let (stride, dt, late) = (1.0, 0.001, 0.02);
        let mut s = PhaseScore::default();
        for k in 0..5000 {
            let t = k as f64 * dt;
            let in_stride = t.rem_euclid(stride);
            let vertical = if in_stride < 0.6 { 700.0 } else { 0.0 };
            let est = 100.0 * ((t - late).rem_euclid(stride)) / stride;
            s.row(t, vertical, Some(est), true);
        }
        let e = s.finish(stride);
        // The run starts in stance: the first heel strike it counts is the second stride's.
        assert_eq!(e.heel_strikes, 4);
        assert!((e.median_latency_s.unwrap() - late).abs() < 1.5 * dt, "{e:?}");
        assert!((e.phase_rmse_pct.unwrap() - 100.0 * late / stride).abs() < 0.2, "{e:?}");
    }
}
