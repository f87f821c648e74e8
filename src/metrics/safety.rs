//! What would hurt the wearer (issue 35), for every leg run: the knee beyond the wearer's range
//! (the data's range plus a margin) and beyond the URDF's limits, and for how long; the knee's
//! peak angular acceleration and jerk (a kick); the cuffs' peak forces against the pain limits;
//! the cylinder's peak force; and for a faulted run the time from the fault's onset to the
//! device's safe state and to the controller's own detection. Each with a verdict against the
//! scenario's `[safety]` limits. Computed online from the rows after the run-in
//! (`metrics.settle_s`).
//!
//! - Acceleration and jerk: differences of the knee rate over windows of at least 1 ms (every
//!   row at 1 ms steps, every 4th at 0.25 ms), so a step's contact impulse does not read as an
//!   infinite kick.
//! - Safe state: the device's knee moment below `safe_moment_nm` in magnitude for at least
//!   `safe_hold_s`; its time is the first instant after the fault's onset from which it holds.
//! - Detection: the controller's stop (`controller.on_stop = "failsafe"`: a stop status or a
//!   command that is not a number; never a crash or an exception), or its logged channel
//!   `fault_detected` reaching 0.5, at or after the onset (the injected fault's).

use crate::error::Result;
use crate::record::{Layout, RecordSink, Row};
use serde::{Deserialize, Serialize};

/// The logged channel a controller reports its own fault detection on (>= 0.5: detected).
pub const DETECTION_LOG_NAME: &str = "fault_detected";

/// `[safety]`: the limits of the safety verdicts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetyLimits {
    /// Margin (deg) around the wearer's knee range in the gait data. Default 5. >= 0.
    pub knee_margin_deg: f64,
    /// Largest knee angular acceleration (rad/s^2). Default: twice the largest in the wearer's
    /// own gait data (walking runs; none otherwise). > 0.
    pub max_knee_accel_rad_s2: Option<f64>,
    /// Largest knee jerk (rad/s^3). Default: none (reported, not judged: a heel strike's
    /// impact differences to tens of thousands of rad/s^3 on any engine, and the data's smooth
    /// cycle gives no scale for it). > 0.
    pub max_knee_jerk_rad_s3: Option<f64>,
    /// The device's knee moment (N m) under which it is in its safe state. Default 5. > 0.
    pub safe_moment_nm: f64,
    /// How long (s) the moment must stay under it. Default 0.1. >= 0.
    pub safe_hold_s: f64,
    /// Largest time (s) from a fault's onset to the safe state; none (default): not judged.
    pub max_time_to_safe_s: Option<f64>,
}

impl Default for SafetyLimits {
    fn default() -> Self {
        Self {
            knee_margin_deg: 5.0,
            max_knee_accel_rad_s2: None,
            max_knee_jerk_rad_s3: None,
            safe_moment_nm: 5.0,
            safe_hold_s: 0.1,
            max_time_to_safe_s: None,
        }
    }
}

/// One safety criterion checked.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafetyVerdict {
    /// Its name.
    pub criterion: String,
    /// The measured value.
    pub value: f64,
    /// The limit.
    pub limit: f64,
    /// value <= limit.
    pub pass: bool,
}

/// What would hurt the wearer (`summary.json` `safety`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafetySummary {
    /// The wearer's knee range, the data's with the margin (deg, [min, max]; None without data).
    pub wearer_knee_range_deg: Option<[f64; 2]>,
    /// Time beyond it (s) and the deepest excursion (deg).
    pub beyond_wearer_range_s: f64,
    /// The deepest excursion beyond the wearer's range (deg).
    pub beyond_wearer_range_deg: f64,
    /// The knee's range after the run-in (deg, [min, max]; None without rows after it).
    pub knee_range_deg: Option<[f64; 2]>,
    /// The URDF's knee limits (deg).
    pub urdf_knee_limits_deg: [f64; 2],
    /// Time beyond them (s).
    pub beyond_urdf_limits_s: f64,
    /// The deepest excursion beyond them (deg).
    pub beyond_urdf_limits_deg: f64,
    /// Peak |knee angular acceleration| (rad/s^2).
    pub peak_knee_accel_rad_s2: f64,
    /// Peak |knee jerk| (rad/s^3).
    pub peak_knee_jerk_rad_s3: f64,
    /// Peak |thigh cuff force| and |shank cuff force| (N).
    pub peak_cuff_n: [f64; 2],
    /// Peak |net cylinder force| (N).
    pub peak_cylinder_force_n: f64,
    /// The first fault's onset (s), if any happened.
    pub fault_onset_s: Option<f64>,
    /// From the onset to the device's safe state (s; None: never, or no fault).
    pub time_to_safe_state_s: Option<f64>,
    /// From the onset to the controller's own detection (s; None: it reported none).
    pub time_to_detection_s: Option<f64>,
    /// When the controller stopped (s) and the device went to its fail-safe state.
    pub controller_stop_s: Option<f64>,
    /// Each criterion.
    pub verdicts: Vec<SafetyVerdict>,
}

impl SafetySummary {
    /// Whether every verdict passes.
    pub fn passed(&self) -> bool {
        self.verdicts.iter().all(|v| v.pass)
    }
}

/// What the safety figures need besides the rows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetySetup {
    /// The limits.
    pub limits: SafetyLimits,
    /// The run-in (s).
    pub settle_s: f64,
    /// The URDF's knee limits (rad).
    pub urdf_knee_rad: (f64, f64),
    /// The wearer's knee range in the data (rad) and their largest knee acceleration (rad/s^2),
    /// for walking runs.
    pub data: Option<((f64, f64), f64)>,
    /// The pain limits of the thigh and shank cuffs (N).
    pub cuff_pain_n: [f64; 2],
}

/// Accumulates [`SafetySummary`] row by row.
#[derive(Debug, Clone)]
pub struct SafetyMetrics {
    setup: SafetySetup,
    detect_log: Option<usize>,
    last_t: Option<f64>,
    /// Rows per difference window and the rates kept (t, rate, accel) for the differences.
    window: Option<usize>,
    rows_seen: usize,
    prev_rate: Option<(f64, f64)>,
    prev_accel: Option<(f64, f64)>,
    beyond: [(f64, f64); 2],
    peaks: [f64; 5],
    knee_range_deg: [f64; 2],
    onset: Option<f64>,
    safe_since: Option<f64>,
    safe_at: Option<f64>,
    detected: Option<f64>,
}

impl SafetyMetrics {
    /// Figures for a run with `setup`.
    pub fn new(setup: SafetySetup) -> Self {
        Self {
            setup,
            detect_log: None,
            last_t: None,
            window: None,
            rows_seen: 0,
            prev_rate: None,
            prev_accel: None,
            beyond: [(0.0, 0.0); 2],
            peaks: [0.0; 5],
            knee_range_deg: [f64::INFINITY, f64::NEG_INFINITY],
            onset: None,
            safe_since: None,
            safe_at: None,
            detected: None,
        }
    }

    /// The wearer's knee range with the margin (deg).
    fn wearer_range_deg(&self) -> Option<[f64; 2]> {
        let m = self.setup.limits.knee_margin_deg;
        self.setup.data.map(|((lo, hi), _)| [lo.to_degrees() - m, hi.to_degrees() + m])
    }

    /// The knee's acceleration and jerk from its rate (rad/s) at `t` (s), every `window` rows.
    fn kick(&mut self, t: f64, rate: f64) {
        if let Some((t0, r0)) = self.prev_rate {
            let a = (rate - r0) / (t - t0);
            self.peaks[0] = self.peaks[0].max(a.abs());
            if let Some((ta, a0)) = self.prev_accel {
                self.peaks[1] = self.peaks[1].max(((a - a0) / (0.5 * (t - ta))).abs());
            }
            self.prev_accel = Some((0.5 * (t + t0), a));
        }
        self.prev_rate = Some((t, rate));
    }

    /// The fault's onset, the safe state and the detection at row `r`.
    fn faults(&mut self, r: &Row) {
        if r.fault_active && self.onset.is_none() {
            self.onset = Some(r.t_s);
        }
        let Some(t0) = self.onset else { return };
        if let (Some(k), None) = (self.detect_log, self.detected) {
            if r.log[k] >= 0.5 {
                self.detected = Some(r.t_s);
            }
        }
        if self.safe_at.is_some() {
            return;
        }
        let m = r.device.map_or(0.0, |d| d.device_knee_moment_nm.abs());
        if m < self.setup.limits.safe_moment_nm {
            let since = *self.safe_since.get_or_insert(r.t_s);
            if r.t_s - since >= self.setup.limits.safe_hold_s - 1e-12 {
                self.safe_at = Some(since.max(t0));
            }
        } else {
            self.safe_since = None;
        }
    }

    /// The figures, with the controller's stop (its time, s, and cause) if it stopped: a
    /// crash is never a detection.
    pub fn finish(&self, controller_stop: Option<(f64, crate::faults::StopCause)>) -> SafetySummary {
        let controller_stop_s = controller_stop.map(|(t, _)| t);
        let detecting_stop = controller_stop.filter(|(_, c)| c.detects()).map(|(t, _)| t);
        let l = &self.setup.limits;
        let urdf = [self.setup.urdf_knee_rad.0.to_degrees(), self.setup.urdf_knee_rad.1.to_degrees()];
        let accel_limit = l.max_knee_accel_rad_s2.or(self.setup.data.map(|(_, a)| 2.0 * a));
        let jerk_limit = l.max_knee_jerk_rad_s3;
        let onset = self.onset;
        let detected = match (self.detected, detecting_stop.filter(|s| onset.is_some_and(|o| *s >= o))) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let time_to_safe = onset.and(self.safe_at).zip(onset).map(|(s, o)| s - o);
        let mut v = Vec::new();
        let mut check = |name: &str, value: f64, limit: Option<f64>| {
            if let Some(limit) = limit {
                v.push(SafetyVerdict { criterion: name.into(), value, limit, pass: value <= limit });
            }
        };
        check("beyond_wearer_range_s", self.beyond[0].0, self.wearer_range_deg().map(|_| 0.0));
        check("beyond_urdf_limits_s", self.beyond[1].0, Some(0.0));
        check("knee_accel_rad_s2", self.peaks[0], accel_limit);
        check("knee_jerk_rad_s3", self.peaks[1], jerk_limit);
        check("thigh_cuff_pain_n", self.peaks[2], Some(self.setup.cuff_pain_n[0]));
        check("shank_cuff_pain_n", self.peaks[3], Some(self.setup.cuff_pain_n[1]));
        if onset.is_some() {
            check("time_to_safe_state_s", time_to_safe.unwrap_or(f64::INFINITY), l.max_time_to_safe_s);
        }
        SafetySummary {
            wearer_knee_range_deg: self.wearer_range_deg(),
            beyond_wearer_range_s: self.beyond[0].0,
            beyond_wearer_range_deg: self.beyond[0].1,
            knee_range_deg: (self.knee_range_deg[0] <= self.knee_range_deg[1]).then_some(self.knee_range_deg),
            urdf_knee_limits_deg: urdf,
            beyond_urdf_limits_s: self.beyond[1].0,
            beyond_urdf_limits_deg: self.beyond[1].1,
            peak_knee_accel_rad_s2: self.peaks[0],
            peak_knee_jerk_rad_s3: self.peaks[1],
            peak_cuff_n: [self.peaks[2], self.peaks[3]],
            peak_cylinder_force_n: self.peaks[4],
            fault_onset_s: onset,
            time_to_safe_state_s: time_to_safe,
            time_to_detection_s: detected.zip(onset).map(|(d, o)| d - o),
            controller_stop_s,
            verdicts: v,
        }
    }
}

impl RecordSink for SafetyMetrics {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.detect_log = layout.log.iter().position(|n| n == DETECTION_LOG_NAME);
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        let dt = self.last_t.map(|t| r.t_s - t);
        self.last_t = Some(r.t_s);
        self.faults(r);
        let Some(leg) = r.leg else { return Ok(()) };
        if r.t_s < self.setup.settle_s - 1e-9 {
            return Ok(());
        }
        let window = *self.window.get_or_insert_with(|| dt.map_or(1, |d| ((1e-3 / d).round() as usize).max(1)));
        if self.rows_seen.is_multiple_of(window) {
            self.kick(r.t_s, leg.knee_velocity_deg_s.to_radians());
        }
        self.rows_seen += 1;
        let q = leg.knee_angle_deg;
        self.knee_range_deg = [self.knee_range_deg[0].min(q), self.knee_range_deg[1].max(q)];
        let dt = dt.unwrap_or(0.0);
        let urdf = [self.setup.urdf_knee_rad.0.to_degrees(), self.setup.urdf_knee_rad.1.to_degrees()];
        for (i, range) in [self.wearer_range_deg(), Some(urdf)].into_iter().enumerate() {
            if let Some([lo, hi]) = range {
                let out = (lo - q).max(q - hi);
                if out > 0.0 {
                    self.beyond[i].0 += dt;
                    self.beyond[i].1 = self.beyond[i].1.max(out);
                }
            }
        }
        if let Some(d) = r.device {
            self.peaks[2] = self.peaks[2].max(d.thigh_cuff_force_n.abs());
            self.peaks[3] = self.peaks[3].max(d.shank_cuff_force_n.abs());
        }
        self.peaks[4] = self.peaks[4].max(r.cylinder_force_n.abs());
        Ok(())
    }
}
