//! The plugin as a controller of the loop: the readings in the ABI's layout, its command back,
//! and the instance's life (create, step, destroy).

use super::*;

/// Raw counts as the ABI carries them: a validity bit per channel and the counts (0 where
/// invalid).
pub(super) fn counts_of<const N: usize>(c: &[Option<i64>; N]) -> (u32, [i64; N]) {
    let mut valid = 0u32;
    let mut counts = [0i64; N];
    for (i, n) in c.iter().enumerate() {
        if let Some(n) = n {
            valid |= 1 << i;
            counts[i] = *n;
        }
    }
    (valid, counts)
}

impl Default for ExolegReadings {
    fn default() -> Self {
        Self {
            size: std::mem::size_of::<Self>() as u32,
            counts_valid: 0,
            t_s: 0.0,
            period_s: 0.0,
            force_n: 0.0,
            force_rate_n_per_s: 0.0,
            spool_m: 0.0,
            piston_m: 0.0,
            piston_velocity_m_s: 0.0,
            piston_accel_m_s2: 0.0,
            knee_rad: 0.0,
            knee_rate_rad_s: 0.0,
            ref_force_n: 0.0,
            ref_force_rate_n_per_s: 0.0,
            ref_force_accel_n_per_s2: 0.0,
            next_ref_force_n: 0.0,
            next_ref_force_rate_n_per_s: 0.0,
            next_ref_force_accel_n_per_s2: 0.0,
            valve_command_limit: 0.0,
            counts: [0; 5],
            hip_rad: 0.0,
            hip_rate_rad_s: 0.0,
            thigh_accel_m_s2: [0.0; 3],
            thigh_gyro_rad_s: [0.0; 3],
            shank_accel_m_s2: [0.0; 3],
            shank_gyro_rad_s: [0.0; 3],
            heel_force_n: 0.0,
            forefoot_force_n: 0.0,
            foot_contact: 0.0,
            thigh_cuff_force_n: 0.0,
            shank_cuff_force_n: 0.0,
            pressure_a_pa: 0.0,
            pressure_b_pa: 0.0,
            supply_pressure_pa: 0.0,
            load_pressure_pa: 0.0,
            device_counts_valid: 0,
            reserved1: 0,
            device_counts: [0; 21],
        }
    }
}

/// The ABI's readings of a sample.
pub fn readings_of(s: &SampleInput) -> ExolegReadings {
    let (y, d) = (&s.y, &s.device);
    let (valid, counts) = counts_of(&s.counts.0);
    let (device_counts_valid, device_counts) = counts_of(&s.device_counts.0);
    ExolegReadings {
        size: std::mem::size_of::<ExolegReadings>() as u32,
        counts_valid: valid,
        t_s: s.t_s,
        period_s: s.period_s,
        force_n: y.force_n,
        force_rate_n_per_s: y.force_rate_n_per_s,
        spool_m: y.spool_m,
        piston_m: y.piston_m,
        piston_velocity_m_s: y.piston_velocity_m_s,
        piston_accel_m_s2: y.piston_accel_m_s2,
        knee_rad: y.knee_rad,
        knee_rate_rad_s: y.knee_rate_rad_s,
        ref_force_n: s.r.value,
        ref_force_rate_n_per_s: s.r.rate,
        ref_force_accel_n_per_s2: s.r.accel,
        next_ref_force_n: s.r_next.value,
        next_ref_force_rate_n_per_s: s.r_next.rate,
        next_ref_force_accel_n_per_s2: s.r_next.accel,
        valve_command_limit: s.valve_limit.0,
        counts,
        hip_rad: d.hip_rad,
        hip_rate_rad_s: d.hip_rate_rad_s,
        thigh_accel_m_s2: d.thigh_accel_m_s2,
        thigh_gyro_rad_s: d.thigh_gyro_rad_s,
        shank_accel_m_s2: d.shank_accel_m_s2,
        shank_gyro_rad_s: d.shank_gyro_rad_s,
        heel_force_n: d.heel_force_n,
        forefoot_force_n: d.forefoot_force_n,
        foot_contact: d.foot_contact,
        thigh_cuff_force_n: d.thigh_cuff_force_n,
        shank_cuff_force_n: d.shank_cuff_force_n,
        pressure_a_pa: d.pressure_a_pa,
        pressure_b_pa: d.pressure_b_pa,
        supply_pressure_pa: d.supply_pressure_pa,
        load_pressure_pa: d.load_pressure_pa,
        device_counts_valid,
        reserved1: 0,
        device_counts,
    }
}

/// One plugin instance: a [`DiscreteController`].
pub struct PluginController {
    pub(super) setup: Arc<PluginSetup>,
    pub(super) handle: *mut c_void,
    pub(super) readings: ExolegReadings,
    pub(super) command: ExolegCommand,
    pub(super) reset: bool,
    pub(super) status: StatusCount,
    /// Wall time of each `exoleg_step` call (s): measured, reported, never in the physics.
    pub(super) compute_s: Vec<f64>,
}

// SAFETY: the ABI requires instances without global state, used by one thread at a time;
// the controller is owned by one run, which moves between threads only between calls.
unsafe impl Send for PluginController {}

/// The output of a plugin's command (a non-finite valve command stops the run).
pub(crate) fn output_of(name: &str, c: &ExolegCommand, status: i32) -> Result<ControlOutput, ControlStop> {
    let u = c.valve_command;
    if !u.is_finite() {
        return Err(ControlStop::command(format!("plugin {name} returned the valve command {u} (status {status})")));
    }
    Ok(ControlOutput {
        valve_command: u,
        disturbance_estimate_n_per_s2: c.disturbance_estimate_n_per_s2,
        ..Default::default()
    })
}

impl DiscreteController for PluginController {
    fn kind(&self) -> &str {
        "plugin"
    }

    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        self.command = ExolegCommand::default();
        let lib = &self.setup.lib;
        if !self.reset {
            self.reset = true;
            let st = lib.reset_raw(self.handle);
            let m = message_text(&self.command.message);
            self.status.take("exoleg_reset", st, || m)?;
        }
        self.readings = readings_of(s);
        let t0 = std::time::Instant::now();
        let st = lib.step_raw(self.handle, &self.readings, &mut self.command);
        self.compute_s.push(t0.elapsed().as_secs_f64());
        let cmd = &self.command;
        self.status.take("exoleg_step", st, || message_text(&cmd.message))?;
        output_of(&self.status.name, &self.command, st)
    }

    fn log_names(&self) -> Vec<String> {
        self.setup.log.clone()
    }

    fn log_values(&self, out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(self.command.log) {
            *o = v;
        }
    }

    fn warnings(&self) -> (usize, Option<String>) {
        (self.status.warnings, self.status.last_warning.clone())
    }

    fn compute_times_s(&self) -> &[f64] {
        &self.compute_s
    }
}

impl Drop for PluginController {
    fn drop(&mut self) {
        // The instance was created by this library and is destroyed once.
        self.setup.lib.destroy_raw(self.handle);
    }
}
