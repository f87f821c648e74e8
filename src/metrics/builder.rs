//! The summary built row by row as a run records (a record sink): running RMS, maxima and
//! means, the convergence time, the per-stride figures.

use super::*;

/// Running RMS: the sum of squares in row order, then `sqrt(sum / n)`.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Rms {
    sum_sq: f64,
    n: usize,
}

impl Rms {
    pub(crate) fn add(&mut self, x: f64) {
        self.sum_sq += x * x;
        self.n += 1;
    }
    pub(crate) fn value(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
    /// The RMS, or None before the first value.
    pub(crate) fn value_if_any(&self) -> Option<f64> {
        (self.n > 0).then(|| self.value())
    }
}

/// Running max |x|.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct MaxAbs(f64);

impl MaxAbs {
    fn add(&mut self, x: f64) {
        self.0 = self.0.max(x.abs());
    }
}

/// Running mean (of a 0/1 flag: the fraction of rows set).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Mean {
    sum: f64,
    n: usize,
}

impl Mean {
    fn add(&mut self, x: f64) {
        self.sum += x;
        self.n += 1;
    }
    fn value(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.sum / self.n as f64
        }
    }
}

/// Online convergence time: the time of the row after the last row whose |error| exceeds the
/// band. With a band known only at the end (a fraction of the run's peak reference), it keeps
/// the strict suffix maxima of |error| above the band's current lower bound: the last row
/// beyond the final band is always one of them.
#[derive(Debug, Clone, Default)]
pub(super) struct Convergence {
    /// (|error|, index, time of the next row) of the strict suffix maxima above `floor`.
    stair: Vec<(f64, usize, Option<f64>)>,
    floor: f64,
    first_t: Option<f64>,
    n: usize,
}

impl Convergence {
    fn add(&mut self, t: f64, abs_err: f64, floor: f64) {
        if self.first_t.is_none() {
            self.first_t = Some(t);
        }
        if let Some(last) = self.stair.last_mut() {
            if last.1 + 1 == self.n {
                last.2 = Some(t);
            }
        }
        self.floor = self.floor.max(floor);
        while self.stair.last().is_some_and(|s| s.0 <= abs_err) {
            self.stair.pop();
        }
        let f = self.floor;
        if self.stair.first().is_some_and(|s| s.0 <= f) {
            self.stair.retain(|s| s.0 > f);
        }
        if abs_err > f {
            self.stair.push((abs_err, self.n, None));
        }
        self.n += 1;
    }

    /// Earliest time after which |error| <= band; None if the last row is outside.
    fn time(&self, band: f64) -> Option<f64> {
        match self.stair.iter().rev().find(|s| s.0 > band) {
            None => self.first_t,
            Some(s) => s.2,
        }
    }
}

/// Accumulators of one stride.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StrideAcc {
    knee_rms: Rms,
    knee_max: MaxAbs,
    force_rms: Rms,
    force_max: MaxAbs,
    peak_force: MaxAbs,
    peak_power: MaxAbs,
}

/// Computes a [`Summary`] from rows as they arrive (a [`RecordSink`]).
#[derive(Debug, Clone)]
pub struct SummaryBuilder {
    settings: MetricSettings,
    rows: usize,
    max_err: MaxAbs,
    rms_err: Rms,
    conv: Convergence,
    peak_ref: MaxAbs,
    settled_max_err: MaxAbs,
    settled_rms_err: Rms,
    max_u: MaxAbs,
    peak_load: MaxAbs,
    knee_rms: Rms,
    knee_max: MaxAbs,
    has_knee_error: bool,
    peak_cyl: MaxAbs,
    peak_power: MaxAbs,
    saturated: Mean,
    limited: Mean,
    gap: Option<MaxAbs>,
    knee_range: Option<[f64; 2]>,
    stride: usize,
    strides: Vec<StrideAcc>,
    last_t: f64,
}

impl SummaryBuilder {
    /// A builder for a run with these settings.
    pub fn new(settings: MetricSettings) -> Self {
        Self {
            settings,
            rows: 0,
            max_err: MaxAbs::default(),
            rms_err: Rms::default(),
            conv: Convergence::default(),
            peak_ref: MaxAbs::default(),
            settled_max_err: MaxAbs::default(),
            settled_rms_err: Rms::default(),
            max_u: MaxAbs::default(),
            peak_load: MaxAbs::default(),
            knee_rms: Rms::default(),
            knee_max: MaxAbs::default(),
            has_knee_error: false,
            peak_cyl: MaxAbs::default(),
            peak_power: MaxAbs::default(),
            saturated: Mean::default(),
            limited: Mean::default(),
            gap: None,
            knee_range: None,
            stride: 0,
            strides: Vec::new(),
            last_t: 0.0,
        }
    }

    fn band_floor(&self) -> f64 {
        match self.settings.band {
            Band::Fixed(b) => b,
            Band::FractionOfPeakReference(f) => f * self.peak_ref.0,
        }
    }

    fn add_settled(&mut self, r: &Row) {
        if self.settings.force_reference {
            self.settled_max_err.add(r.force_error_n);
            self.settled_rms_err.add(r.force_error_n);
        }
        if let Some(e) = r.knee_error_deg() {
            self.knee_rms.add(e);
            self.knee_max.add(e);
            self.has_knee_error = true;
        }
        self.peak_cyl.add(r.cylinder_force_n);
        self.peak_power.add(r.cylinder_power_w());
    }

    fn add_stride(&mut self, r: &Row) {
        let (Some(stride_s), Some(ke)) = (self.settings.stride_s, r.knee_error_deg()) else { return };
        // Jump to about the row's stride, then settle the boundary exactly (two steps at most),
        // so a run of any length with any stride costs no loop over the strides it skips.
        let k = ((r.t_s + T_EPS) / stride_s).floor();
        if k > self.stride as f64 + 1.0 {
            self.stride = (k.min(MAX_STRIDES as f64) as usize).saturating_sub(1);
        }
        while self.stride < MAX_STRIDES && r.t_s >= (self.stride + 1) as f64 * stride_s - T_EPS {
            self.stride += 1;
        }
        if self.stride >= MAX_STRIDES {
            return;
        }
        if self.strides.len() <= self.stride {
            self.strides.resize(self.stride + 1, StrideAcc::default());
        }
        let a = &mut self.strides[self.stride];
        a.knee_rms.add(ke);
        a.knee_max.add(ke);
        a.force_rms.add(r.force_error_n);
        a.force_max.add(r.force_error_n);
        a.peak_force.add(r.cylinder_force_n);
        a.peak_power.add(r.cylinder_power_w());
    }

    /// The summary of the rows so far. `wall_time_s`: the loop's wall-clock time.
    pub fn finish(&self, wall_time_s: f64) -> Summary {
        let band = match self.settings.band {
            Band::Fixed(b) => b,
            Band::FractionOfPeakReference(f) => f * self.peak_ref.0,
        };
        let steps = self.rows.saturating_sub(1);
        let knee = self.has_knee_error;
        // Without a desired force there is no force error.
        let f = |v: f64| if self.settings.force_reference { v } else { f64::NAN };
        Summary {
            max_abs_force_error_n: f(self.max_err.0),
            force_convergence_time_s: self.conv.time(band).filter(|_| self.settings.force_reference),
            force_convergence_band_n: f(band),
            rms_force_error_n: f(self.rms_err.value()),
            settle_s: self.settings.settle_s,
            max_abs_force_error_after_settle_n: f(self.settled_max_err.0),
            rms_force_error_after_settle_n: f(self.settled_rms_err.value()),
            max_abs_valve_command: self.max_u.0,
            peak_load_force_n: self.peak_load.0,
            knee_rms_error_deg: knee.then(|| self.knee_rms.value()),
            knee_max_abs_error_deg: knee.then_some(self.knee_max.0),
            peak_cylinder_force_n: self.peak_cyl.0,
            peak_power_w: self.peak_power.0,
            strides: self.stride_figures(),
            valve_saturation_fraction: self.saturated.value(),
            force_limit_fraction: self.limited.value(),
            loop_closure_max_gap_m: self.gap.map(|g| g.0),
            knee_range_deg: self.knee_range,
            steps,
            hydraulic_substeps_max: 1,
            substepped_steps: 0,
            sensor_clipped_readings: Default::default(),
            wall_time_s,
            steps_per_second: if wall_time_s > 0.0 { steps as f64 / wall_time_s } else { f64::INFINITY },
            contact: None,
            wearer: None,
            safety: None,
            controller_warnings: None,
            controller_stop: None,
            controller_compute: None,
            compute_model: None,
            controller_link: None,
            end_stops: None,
            engine: None,
        }
    }

    /// The complete strides (a partial last stride is left out).
    fn stride_figures(&self) -> Vec<StrideFigures> {
        let Some(stride) = self.settings.stride_s else { return Vec::new() };
        let n = (((self.last_t + 1e-9) / stride).floor() as usize).min(MAX_STRIDES);
        self.strides
            .iter()
            .take(n)
            .enumerate()
            .map(|(i, a)| StrideFigures {
                index: i,
                t_start_s: i as f64 * stride,
                knee_rms_error_deg: a.knee_rms.value(),
                knee_max_abs_error_deg: a.knee_max.0,
                force_rms_error_n: if self.settings.force_reference { a.force_rms.value() } else { f64::NAN },
                force_max_abs_error_n: if self.settings.force_reference { a.force_max.0 } else { f64::NAN },
                peak_cylinder_force_n: a.peak_force.0,
                peak_power_w: a.peak_power.0,
            })
            .collect()
    }
}

impl RecordSink for SummaryBuilder {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        if layout.leg {
            self.gap = Some(MaxAbs::default());
        }
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        if self.settings.force_reference {
            self.peak_ref.add(r.ref_force_n);
            self.conv.add(r.t_s, r.force_error_n.abs(), self.band_floor());
            self.max_err.add(r.force_error_n);
            self.rms_err.add(r.force_error_n);
        }
        self.max_u.add(r.valve_command);
        self.peak_load.add(r.load_force_n);
        self.saturated.add(if r.valve_saturated { 1.0 } else { 0.0 });
        self.limited.add(if r.force_limited { 1.0 } else { 0.0 });
        if r.t_s >= self.settings.settle_s - T_EPS {
            self.add_settled(r);
        }
        self.add_stride(r);
        if let (Some(g), Some(l)) = (self.gap.as_mut(), r.leg) {
            g.add(l.loop_closure_gap_m);
            let q = l.knee_angle_deg;
            let [lo, hi] = self.knee_range.get_or_insert([f64::INFINITY, f64::NEG_INFINITY]);
            *lo = lo.min(q);
            *hi = hi.max(q);
        }
        self.last_t = r.t_s;
        self.rows += 1;
        Ok(())
    }
}
