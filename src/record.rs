//! The recorded time series: one [`Row`] per step plus the initial state, handed to a
//! [`RecordSink`] as the run goes (MuJoCo's `mjData` read after each step, not a buffer of the
//! whole run). Sinks: the streaming CSV writer (`output::CsvSink`), the online metrics
//! (`metrics::SummaryBuilder`), the bounded plot copy (`output::PlotBuffer`) and, for tests
//! and the library API, [`MemoryRecord`].

use crate::error::Result;

/// Leg-specific columns of a row (leg plant only).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LegRow {
    /// Knee flexion (deg).
    pub knee_angle_deg: f64,
    /// Knee flexion rate (deg/s).
    pub knee_velocity_deg_s: f64,
    /// Hip flexion (deg), 0 with the thigh fixed.
    pub hip_angle_deg: f64,
    /// Pin-to-pin cylinder length (m).
    pub cylinder_length_m: f64,
    /// Distance between the two loop-closure anchors (m).
    pub loop_closure_gap_m: f64,
    /// Moment arm dL/dq of the cylinder about the knee (m/rad).
    pub moment_arm_m: f64,
}

/// Ground-contact columns of a row (leg plant with `ground.enabled`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactRow {
    /// Vertical ground reaction on the foot (N, up positive).
    pub ground_reaction_vertical_n: f64,
    /// Horizontal ground reaction on the foot (N, +x forward).
    pub ground_reaction_horizontal_n: f64,
    /// Deepest penetration of the sole into the ground (m, >= 0).
    pub contact_penetration_m: f64,
    /// Net knee moment from the ground reaction and the shank and foot dynamics (N m, extensor
    /// positive, gait-lab convention).
    pub knee_moment_nm: f64,
    /// Ankle dorsiflexion (deg).
    pub ankle_angle_deg: f64,
    /// Hip height above the ground (m; the hip's z when not on the carriage).
    pub pelvis_height_m: f64,
    /// The pelvis's fore-aft displacement from its start (m, +x forward; 0 off the carriage).
    pub pelvis_x_m: f64,
    /// The virtual other leg's force on the pelvis (N, up).
    pub support_force_n: f64,
    /// The wearer's knee torque (N m, flexion positive).
    pub wearer_knee_torque_nm: f64,
}

/// What the device does and what its own sensors measure, truth (leg runs; written with a
/// sampled controller, `Layout::device`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DeviceRow {
    /// The thigh's angle (deg): its link frame's forward turn from upright (0 unless the
    /// device's columns are written).
    pub thigh_angle_deg: f64,
    /// The shank's angle (deg), the same way.
    pub shank_angle_deg: f64,
    /// The thigh's angular velocity (deg/s, forward positive).
    pub thigh_rate_deg_s: f64,
    /// The shank's angular velocity (deg/s).
    pub shank_rate_deg_s: f64,
    /// The heel's share of the vertical ground reaction (N) at the heel sensor's position.
    pub heel_force_n: f64,
    /// The forefoot's share (N).
    pub forefoot_force_n: f64,
    /// Normal force the thigh cuff carries (N, positive pressing the thigh forward).
    pub thigh_cuff_force_n: f64,
    /// Normal force the shank cuff carries (N, positive pressing the shank forward).
    pub shank_cuff_force_n: f64,
    /// Chamber A pressure (Pa).
    pub pressure_a_pa: f64,
    /// Chamber B pressure (Pa).
    pub pressure_b_pa: f64,
    /// Load pressure F_L / A_eff (Pa).
    pub load_pressure_pa: f64,
    /// Hydraulic power drawn from the supply, supply pressure times supply flow (W).
    pub hydraulic_power_w: f64,
    /// The device's knee moment (N m, extensor positive as `knee_moment_nm`): minus the net
    /// cylinder force times the moment arm.
    pub device_knee_moment_nm: f64,
}

/// One recorded instant. Units in the field names; see the README's output section.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Row {
    /// Time (s).
    pub t_s: f64,
    /// Desired force F_d (N).
    pub ref_force_n: f64,
    /// dF_d/dt (N/s).
    pub ref_force_rate_n_per_s: f64,
    /// Load force F_L (N).
    pub load_force_n: f64,
    /// Tracking error F_L - F_d (N).
    pub force_error_n: f64,
    /// True dF_L/dt (N/s).
    pub force_rate_n_per_s: f64,
    /// Valve command u as applied (after the valve limit; the held value in sampled mode).
    pub valve_command: f64,
    /// The valve command was clipped.
    pub valve_saturated: bool,
    /// Spool position x_v (m).
    pub spool_m: f64,
    /// F_L is at the supply-pressure limit.
    pub force_limited: bool,
    /// Piston position x_c (m).
    pub piston_m: f64,
    /// Piston velocity (m/s).
    pub piston_velocity_m_s: f64,
    /// Friction force (N), with the sign of the piston velocity.
    pub friction_force_n: f64,
    /// Net force applied along the cylinder (N): F_L - F_f, or the prescribed force.
    pub cylinder_force_n: f64,
    /// Human interaction force w1 (N in cuff mode, N/s^2 in paper mode).
    pub interaction_force: f64,
    /// Controller's disturbance estimate g_hat + D_hat (N/s^2).
    pub disturbance_estimate_n_per_s2: f64,
    /// The RBF network's part of it, g_hat (N/s^2).
    pub rbf_output_n_per_s2: f64,
    /// True lumped disturbance on dx2/dt relative to the controller's nominal model (N/s^2;
    /// NaN for the two-chamber plant).
    pub lumped_disturbance_n_per_s2: f64,
    /// Desired knee flexion (deg), gait runs only.
    pub ref_knee_deg: Option<f64>,
    /// Leg columns, leg plant only.
    pub leg: Option<LegRow>,
    /// Contact columns, with ground contact only.
    pub contact: Option<ContactRow>,
    /// What the device does and its sensors measure (leg runs).
    pub device: Option<DeviceRow>,
    /// One of the run's `[[faults]]` is active (the column of runs with `[[faults]]` or
    /// `controller.on_stop = "failsafe"`; a controller's stop is `summary.json` `controller_stop`).
    pub fault_active: bool,
    /// The controller's logged channels (the first `layout.log.len()` are used).
    pub log: [f64; MAX_LOGGED],
    /// The wearer's muscle analysis of this instant (`wearer.muscles`; the values of
    /// `muscles::analysis::Sample`, per muscle then the totals).
    pub muscles: Option<std::sync::Arc<[f64]>>,
}

/// Most channels a controller may log ([`Row::log`]).
pub const MAX_LOGGED: usize = 16;

/// Longest name of a logged channel (characters).
pub const MAX_LOG_NAME: usize = 64;

/// Check the names of a controller's logged channels (columns `log_<name>` of the CSV and
/// Parquet files, keys in Python): at most [`MAX_LOGGED`], each 1 to [`MAX_LOG_NAME`]
/// characters of ASCII letters, digits, `_`, `.` and `-` (no comma, quote, space, newline or
/// control character that would break a CSV header or a Parquet schema), no two alike. The
/// message names the offending name.
pub fn check_log_names(names: &[String]) -> Result<(), String> {
    if names.len() > MAX_LOGGED {
        return Err(format!("{} channels, at most {MAX_LOGGED}", names.len()));
    }
    for (i, n) in names.iter().enumerate() {
        let shown: String = n.chars().take(80).flat_map(char::escape_default).collect();
        let ok = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '-');
        if n.is_empty() {
            return Err(format!("channel {i} has an empty name"));
        }
        if n.chars().count() > MAX_LOG_NAME || !n.chars().all(ok) {
            return Err(format!(
                "channel name \"{shown}\": use 1 to {MAX_LOG_NAME} ASCII letters, digits, `_`, `.` or `-`"
            ));
        }
        if names[..i].contains(n) {
            return Err(format!("channel name \"{shown}\" is given twice: each channel needs its own name"));
        }
    }
    Ok(())
}

/// Which optional column groups a run records (fixed for the whole run).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Layout {
    /// `ref_knee_angle_deg` (gait runs).
    pub knee_reference: bool,
    /// The leg columns.
    pub leg: bool,
    /// The contact columns.
    pub contact: bool,
    /// The device's columns.
    pub device: bool,
    /// The `fault_active` column.
    pub faults: bool,
    /// The controller's logged channels (columns `log_<name>`).
    pub log: Vec<String>,
    /// The muscle analysis's columns (`output.muscles`), last.
    pub muscles: Vec<String>,
}

/// Names of the always-present columns, with units in their suffixes, in output order.
pub const BASE_COLUMNS: [&str; 18] = [
    "t_s",
    "ref_force_n",
    "ref_force_rate_n_per_s",
    "load_force_n",
    "force_error_n",
    "force_rate_n_per_s",
    "valve_command",
    "valve_saturated",
    "spool_m",
    "force_limited",
    "piston_m",
    "piston_velocity_m_s",
    "friction_force_n",
    "cylinder_force_n",
    "interaction_force",
    "disturbance_estimate_n_per_s2",
    "rbf_output_n_per_s2",
    "lumped_disturbance_n_per_s2",
];

/// Names of the leg columns.
pub const LEG_COLUMNS: [&str; 6] = [
    "knee_angle_deg",
    "knee_velocity_deg_s",
    "hip_angle_deg",
    "cylinder_length_m",
    "loop_closure_gap_m",
    "moment_arm_m",
];

/// Names of the device's columns.
pub const DEVICE_COLUMNS: [&str; 13] = [
    "thigh_angle_deg",
    "shank_angle_deg",
    "thigh_rate_deg_s",
    "shank_rate_deg_s",
    "heel_force_n",
    "forefoot_force_n",
    "thigh_cuff_force_n",
    "shank_cuff_force_n",
    "pressure_a_pa",
    "pressure_b_pa",
    "load_pressure_pa",
    "hydraulic_power_w",
    "device_knee_moment_nm",
];

/// Names of the contact columns.
pub const CONTACT_COLUMNS: [&str; 9] = [
    "ground_reaction_vertical_n",
    "ground_reaction_horizontal_n",
    "contact_penetration_m",
    "knee_moment_nm",
    "ankle_angle_deg",
    "pelvis_height_m",
    "pelvis_x_m",
    "support_force_n",
    "wearer_knee_torque_nm",
];

impl Layout {
    /// Values per row ([`Row::values_into`] appends this many).
    pub fn width(&self) -> usize {
        BASE_COLUMNS.len()
            + usize::from(self.knee_reference)
            + if self.leg { LEG_COLUMNS.len() } else { 0 }
            + if self.contact { CONTACT_COLUMNS.len() } else { 0 }
            + if self.device { DEVICE_COLUMNS.len() } else { 0 }
            + usize::from(self.faults)
            + self.log.len().min(MAX_LOGGED)
            + self.muscles.len()
    }

    /// Column names in output order.
    pub fn names(&self) -> Vec<String> {
        let mut n: Vec<String> = BASE_COLUMNS.iter().map(|c| c.to_string()).collect();
        if self.knee_reference {
            n.push("ref_knee_angle_deg".into());
        }
        if self.leg {
            n.extend(LEG_COLUMNS.iter().map(|c| c.to_string()));
        }
        if self.contact {
            n.extend(CONTACT_COLUMNS.iter().map(|c| c.to_string()));
        }
        if self.device {
            n.extend(DEVICE_COLUMNS.iter().map(|c| c.to_string()));
        }
        if self.faults {
            n.push("fault_active".into());
        }
        n.extend(self.log.iter().map(|l| format!("log_{l}")));
        n.extend(self.muscles.iter().cloned());
        n
    }
}

fn flag(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

impl Row {
    /// Append the row's values in the order of `layout.names()` to `out`.
    pub fn values_into(&self, layout: &Layout, out: &mut Vec<f64>) {
        out.extend_from_slice(&[
            self.t_s,
            self.ref_force_n,
            self.ref_force_rate_n_per_s,
            self.load_force_n,
            self.force_error_n,
            self.force_rate_n_per_s,
            self.valve_command,
            flag(self.valve_saturated),
            self.spool_m,
            flag(self.force_limited),
            self.piston_m,
            self.piston_velocity_m_s,
            self.friction_force_n,
            self.cylinder_force_n,
            self.interaction_force,
            self.disturbance_estimate_n_per_s2,
            self.rbf_output_n_per_s2,
            self.lumped_disturbance_n_per_s2,
        ]);
        if layout.knee_reference {
            out.push(self.ref_knee_deg.unwrap_or(f64::NAN));
        }
        if layout.leg {
            let l = self.leg.unwrap_or_default();
            out.extend_from_slice(&[
                l.knee_angle_deg,
                l.knee_velocity_deg_s,
                l.hip_angle_deg,
                l.cylinder_length_m,
                l.loop_closure_gap_m,
                l.moment_arm_m,
            ]);
        }
        if layout.contact {
            let c = self.contact.unwrap_or_default();
            out.extend_from_slice(&[
                c.ground_reaction_vertical_n,
                c.ground_reaction_horizontal_n,
                c.contact_penetration_m,
                c.knee_moment_nm,
                c.ankle_angle_deg,
                c.pelvis_height_m,
                c.pelvis_x_m,
                c.support_force_n,
                c.wearer_knee_torque_nm,
            ]);
        }
        if layout.device {
            let d = self.device.unwrap_or_default();
            out.extend_from_slice(&[
                d.thigh_angle_deg,
                d.shank_angle_deg,
                d.thigh_rate_deg_s,
                d.shank_rate_deg_s,
                d.heel_force_n,
                d.forefoot_force_n,
                d.thigh_cuff_force_n,
                d.shank_cuff_force_n,
                d.pressure_a_pa,
                d.pressure_b_pa,
                d.load_pressure_pa,
                d.hydraulic_power_w,
                d.device_knee_moment_nm,
            ]);
        }
        if layout.faults {
            out.push(flag(self.fault_active));
        }
        out.extend_from_slice(&self.log[..layout.log.len().min(MAX_LOGGED)]);
        if !layout.muscles.is_empty() {
            match &self.muscles {
                Some(m) if m.len() == layout.muscles.len() => out.extend_from_slice(m),
                _ => out.extend(std::iter::repeat_n(f64::NAN, layout.muscles.len())),
            }
        }
    }

    /// Knee error actual - desired (deg), when the row has both.
    pub fn knee_error_deg(&self) -> Option<f64> {
        Some(self.leg?.knee_angle_deg - self.ref_knee_deg?)
    }

    /// Cylinder power, net cylinder force times piston velocity (W).
    pub fn cylinder_power_w(&self) -> f64 {
        self.cylinder_force_n * self.piston_velocity_m_s
    }
}

/// Where the rows of a run go.
pub trait RecordSink {
    /// Called once before the first row with the run's column layout.
    fn start(&mut self, layout: &Layout) -> Result<()>;
    /// One row, in time order.
    fn row(&mut self, row: &Row) -> Result<()>;
}

impl<T: RecordSink + ?Sized> RecordSink for &mut T {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        (**self).start(layout)
    }
    fn row(&mut self, row: &Row) -> Result<()> {
        (**self).row(row)
    }
}

/// Passes the first row and every `n`-th after it to `inner` (`output.every_steps`: the
/// recorded time series thinned; the metrics, fed separately, still see every step).
#[derive(Debug)]
pub struct EveryNth<S> {
    inner: S,
    n: usize,
    seen: usize,
}

impl<S> EveryNth<S> {
    /// Keep rows 0, n, 2n, ... (`n` >= 1; 0 is taken as 1).
    pub fn new(inner: S, n: usize) -> Self {
        Self { inner, n: n.max(1), seen: 0 }
    }
    /// The sink inside.
    pub fn into_inner(self) -> S {
        self.inner
    }
    /// The sink inside.
    pub fn inner(&self) -> &S {
        &self.inner
    }
}

impl<S: RecordSink> RecordSink for EveryNth<S> {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.inner.start(layout)
    }
    fn row(&mut self, row: &Row) -> Result<()> {
        let keep = self.seen.is_multiple_of(self.n);
        self.seen += 1;
        if keep {
            self.inner.row(row)
        } else {
            Ok(())
        }
    }
}

/// Several sinks fed with the same rows, in order.
pub struct Tee<'a>(pub Vec<&'a mut dyn RecordSink>);

impl RecordSink for Tee<'_> {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.0.iter_mut().try_for_each(|s| s.start(layout))
    }
    fn row(&mut self, row: &Row) -> Result<()> {
        self.0.iter_mut().try_for_each(|s| s.row(row))
    }
}

/// The whole time series in memory (tests, the library API, Python). Memory grows with the
/// run (about 0.3 KB per row); the CLI streams instead.
#[derive(Debug, Clone, Default)]
pub struct MemoryRecord {
    /// The column layout of the run.
    pub layout: Layout,
    /// Every row, in time order.
    pub rows: Vec<Row>,
}

impl MemoryRecord {
    /// One series, e.g. `record.series(|r| r.load_force_n)`.
    pub fn series(&self, f: impl Fn(&Row) -> f64) -> Vec<f64> {
        self.rows.iter().map(f).collect()
    }

    /// The columns by name, in output order (what `timeseries.csv` holds).
    pub fn columns(&self) -> Vec<(String, Vec<f64>)> {
        let names = self.layout.names();
        let mut cols: Vec<Vec<f64>> = names.iter().map(|_| Vec::with_capacity(self.rows.len())).collect();
        let mut buf = Vec::with_capacity(names.len());
        for r in &self.rows {
            buf.clear();
            r.values_into(&self.layout, &mut buf);
            for (c, v) in cols.iter_mut().zip(&buf) {
                c.push(*v);
            }
        }
        names.into_iter().zip(cols).collect()
    }
}

impl RecordSink for MemoryRecord {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.layout = layout.clone();
        Ok(())
    }
    fn row(&mut self, row: &Row) -> Result<()> {
        self.rows.push(row.clone());
        Ok(())
    }
}

/// A sink that drops every row (runs that only need the summary).
#[derive(Debug, Clone, Copy, Default)]
pub struct NullSink;

impl RecordSink for NullSink {
    fn start(&mut self, _layout: &Layout) -> Result<()> {
        Ok(())
    }
    fn row(&mut self, _row: &Row) -> Result<()> {
        Ok(())
    }
}
