//! Validation of a deserialised scenario: finiteness, signs, ranges, consistency.

use super::ScenarioFile;
use crate::control::ControllerKind;
use crate::disturbance::{Signal, Term};
use crate::error::{Error, Result};
use crate::human::HumanMode;
use crate::hydraulics::ActuatorMode;
use crate::plant::PlantKind;
use crate::scenario::ReferenceKind;

/// Find the first non-finite float anywhere in the scenario, with its dotted path.
fn first_non_finite(v: &toml::Value, path: &mut Vec<String>) -> Option<(String, f64)> {
    match v {
        toml::Value::Float(f) if !f.is_finite() => Some((path.join("."), *f)),
        toml::Value::Table(t) => t.iter().find_map(|(k, v)| {
            path.push(k.clone());
            let r = first_non_finite(v, path);
            path.pop();
            r
        }),
        toml::Value::Array(a) => a.iter().enumerate().find_map(|(i, v)| {
            path.push(i.to_string());
            let r = first_non_finite(v, path);
            path.pop();
            r
        }),
        _ => None,
    }
}

struct Check<'a> {
    src: &'a str,
}

pub use crate::error::num;

mod leg;
use leg::*;

impl Check<'_> {
    fn positive(&self, key: &str, v: f64) -> Result<()> {
        if v > 0.0 {
            Ok(())
        } else {
            Err(Error::input(self.src, key, format!("must be > 0, got {}", num(v))))
        }
    }
    fn non_negative(&self, key: &str, v: f64) -> Result<()> {
        if v >= 0.0 {
            Ok(())
        } else {
            Err(Error::input(self.src, key, format!("must be >= 0, got {}", num(v))))
        }
    }
    fn range(&self, key: &str, v: f64, lo: f64, hi: f64) -> Result<()> {
        if (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(Error::input(self.src, key, format!("must be in {}..={}, got {}", num(lo), num(hi), num(v))))
        }
    }
    /// `0 < v <= hi`: a limit or a duration that must be positive and has a ceiling (a huge
    /// finite value would overflow what is drawn or timed with it).
    fn positive_up_to(&self, key: &str, v: f64, hi: f64) -> Result<()> {
        if v > 0.0 && v <= hi {
            Ok(())
        } else {
            Err(Error::input(self.src, key, format!("must be in (0, {}], got {}", num(hi), num(v))))
        }
    }
    fn fail(&self, key: &str, msg: impl Into<String>) -> Error {
        Error::input(self.src, key, msg)
    }
}

fn signal(c: &Check, key: &str, s: &Signal) -> Result<()> {
    for (i, t) in s.0.iter().enumerate() {
        match t {
            Term::Random { hold_s, .. } => c.positive(&format!("{key}.{i}.hold_s"), *hold_s)?,
            Term::ExpDecay { rate_per_s, .. } => c.non_negative(&format!("{key}.{i}.rate_per_s"), *rate_per_s)?,
            Term::Sine { frequency_hz, .. } => c.non_negative(&format!("{key}.{i}.frequency_hz"), *frequency_hz)?,
            Term::Constant { .. } | Term::Step { .. } => {}
        }
    }
    Ok(())
}

/// Most fixed steps a run may have (a 27-hour run at 1 ms; its CSV would be ~60 GB).
pub const MAX_STEPS: f64 = 1e8;

/// Validate every value; the error names the source, the dotted key and the problem.
pub(super) fn validate(src: &str, f: &ScenarioFile) -> Result<()> {
    let c = Check { src };
    if let Ok(v) = toml::Value::try_from(f) {
        if let Some((key, x)) = first_non_finite(&v, &mut Vec::new()) {
            return Err(c.fail(&key, format!("must be a finite number, got {x}")));
        }
    }
    sim(&c, f)?;
    hydraulics(&c, f)?;
    reference(&c, f)?;
    controller(&c, f)?;
    sensors_and_actuator(&c, f)?;
    leg_human_metrics(&c, f)?;
    subject(&c, f)?;
    contradictions(&c, f)?;
    if !(1..=1_000_000_000).contains(&f.output.every_steps) {
        return Err(c.fail("output.every_steps", format!("must be 1..=1000000000, got {}", f.output.every_steps)));
    }
    walking(&c, f)
}

/// `[subject]`: plausible body, leg length against stature, no contradicting mass.
fn subject(c: &Check, f: &ScenarioFile) -> Result<()> {
    let Some(s) = &f.subject else { return Ok(()) };
    c.range("subject.mass_kg", s.mass_kg, 20.0, 300.0)?;
    c.range("subject.height_m", s.height_m, 1.0, 2.3)?;
    if let Some(l) = s.leg_length_m {
        c.range("subject.leg_length_m", l, 0.35 * s.height_m, 0.65 * s.height_m)?;
    }
    if let Some(m) = f.hip.subject_mass_kg.filter(|m| *m != s.mass_kg) {
        return Err(c.fail(
            "hip.subject_mass_kg",
            format!("{m} kg contradicts subject.mass_kg = {} kg: give the mass once", s.mass_kg),
        ));
    }
    Ok(())
}

/// Keys another key makes meaningless, refused rather than silently ignored: a trial and a
/// gait file; a built-in leg of the other sex than `[subject]`'s template; the ground's height
/// on the carriage (there the ground is at z = 0 and the pelvis at the data's hip height above
/// it: a height would only move the whole world).
fn contradictions(c: &Check, f: &ScenarioFile) -> Result<()> {
    let defaults = ScenarioFile::default();
    if f.reference.gait_file.is_some() && f.reference.gait_trial != defaults.reference.gait_trial {
        return Err(c.fail(
            "reference.gait_trial",
            format!(
                "`{}` contradicts reference.gait_file (the file is the gait): give one of the two",
                f.reference.gait_trial
            ),
        ));
    }
    if let Some(s) = &f.subject {
        let template = crate::leg::subject::template_urdf(&s.body());
        if f.leg.urdf.starts_with("builtin:") && f.leg.urdf != template && f.leg.urdf != defaults.leg.urdf {
            return Err(c.fail(
                "leg.urdf",
                format!(
                    "`{}` contradicts [subject]: it scales the built-in leg of the subject's sex ({template}); leave \
                     leg.urdf out, or give your own URDF (then [subject] sets the mass only)",
                    f.leg.urdf
                ),
            ));
        }
    }
    let carriage = f.hip.mode == Some(crate::human::HipMode::Carriage)
        || (f.hip.mode.is_none() && f.reference.kind == ReferenceKind::Pose);
    if carriage && f.ground.height_m.is_some() {
        return Err(c.fail(
            "ground.height_m",
            "on the carriage the ground is at z = 0 and the pelvis at the data's hip height above it: a height would \
             only move the whole world; leave it out",
        ));
    }
    Ok(())
}

/// `[sim]`: positive step, a whole number of steps, at most [`MAX_STEPS`].
fn sim(c: &Check, f: &ScenarioFile) -> Result<()> {
    c.positive("sim.dt_s", f.sim.dt_s)?;
    c.positive("sim.duration_s", f.sim.duration_s)?;
    let ratio = f.sim.duration_s / f.sim.dt_s;
    if ratio > MAX_STEPS {
        return Err(c.fail(
            "sim.duration_s",
            format!("{ratio:.3e} steps of sim.dt_s, more than the cap of {MAX_STEPS:.0e}: increase sim.dt_s or shorten the run"),
        ));
    }
    if ratio < 1.0 - 1e-9 || (ratio - ratio.round()).abs() > 1e-6 {
        return Err(c.fail(
            "sim.duration_s",
            format!(
                "must be a whole number (>= 1) of steps of sim.dt_s = {}, got {} ({ratio} steps)",
                f.sim.dt_s, f.sim.duration_s
            ),
        ));
    }
    Ok(())
}

/// `[hydraulics]`, `[friction]`.
fn hydraulics(c: &Check, f: &ScenarioFile) -> Result<()> {
    let h = &f.hydraulics;
    for (k, v) in [
        ("hydraulics.beta_pa", h.beta_pa),
        ("hydraulics.v0_m3", h.v0_m3),
        ("hydraulics.a1_m2", h.a1_m2),
        ("hydraulics.a2_m2", h.a2_m2),
        ("hydraulics.k_q", h.k_q),
        ("hydraulics.tau_s", h.tau_s),
        ("hydraulics.k_s", h.k_s),
        ("hydraulics.supply_pressure_pa", h.supply_pressure_pa),
    ] {
        c.positive(k, v)?;
    }
    c.non_negative("hydraulics.k_c", h.k_c)?;
    c.non_negative("hydraulics.leakage", h.leakage)?;
    c.non_negative("hydraulics.return_pressure_pa", h.return_pressure_pa)?;
    if h.return_pressure_pa >= h.supply_pressure_pa {
        return Err(c.fail("hydraulics.return_pressure_pa", "must be below hydraulics.supply_pressure_pa"));
    }
    let fr = &f.friction;
    c.non_negative("friction.coulomb_n", fr.coulomb_n)?;
    c.non_negative("friction.viscous_n_s_per_m", fr.viscous_n_s_per_m)?;
    c.positive("friction.stribeck_velocity_m_s", fr.stribeck_velocity_m_s)?;
    c.positive("friction.smoothing_velocity_m_s", fr.smoothing_velocity_m_s)?;
    if fr.static_n < fr.coulomb_n {
        return Err(c.fail(
            "friction.static_n",
            format!("must be >= friction.coulomb_n ({}), got {}", fr.coulomb_n, fr.static_n),
        ));
    }
    Ok(())
}

/// `[bench]`, `[reference]`.
fn reference(c: &Check, f: &ScenarioFile) -> Result<()> {
    c.non_negative("bench.amplitude_m", f.bench.amplitude_m)?;
    c.positive("bench.frequency_hz", f.bench.frequency_hz)?;
    let rf = &f.reference;
    c.non_negative("reference.amplitude_n", rf.amplitude_n)?;
    c.non_negative("reference.frequency_hz", rf.frequency_hz)?;
    if rf.kind == ReferenceKind::Gait {
        if f.plant.kind != PlantKind::Leg {
            return Err(c.fail("reference.kind", "`gait` drives a knee: it needs plant.kind = \"leg\""));
        }
        if rf.stride_s.is_some() && rf.cadence_steps_per_min.is_some() {
            return Err(c.fail("reference.cadence_steps_per_min", "give reference.stride_s or the cadence, not both"));
        }
    }
    // A human stride takes 0.5-2 s walking, 0.6 s sprinting; these bounds leave room for any
    // gait a leg may be asked to do and refuse what no stride is.
    if let Some(v) = rf.stride_s {
        c.range("reference.stride_s", v, 0.2, 20.0)?;
    }
    if let Some(v) = rf.cadence_steps_per_min {
        c.range("reference.cadence_steps_per_min", v, 6.0, 600.0)?;
    }
    if !(1..=40).contains(&rf.harmonics) {
        return Err(c.fail("reference.harmonics", format!("must be 1..=40, got {}", rf.harmonics)));
    }
    c.positive("reference.friction_smoothing_velocity_m_s", rf.friction_smoothing_velocity_m_s)?;
    c.non_negative("reference.knee_kp_nm_per_rad", rf.knee_kp_nm_per_rad)?;
    c.non_negative("reference.knee_kd_nm_s_per_rad", rf.knee_kd_nm_s_per_rad)?;
    c.non_negative("reference.knee_ki_nm_per_rad_s", rf.knee_ki_nm_per_rad_s)?;
    c.range("reference.assist_fraction", rf.assist_fraction, 0.0, 1.0)?;
    c.range("reference.hip_deg", rf.hip_deg, -60.0, 120.0)?;
    c.range("reference.knee_deg", rf.knee_deg, -20.0, 160.0)?;
    if rf.kind == ReferenceKind::Pose && f.plant.kind != PlantKind::Leg {
        return Err(c.fail("reference.kind", "`pose` holds a knee: it needs plant.kind = \"leg\""));
    }
    no_desired_force(c, f)
}

/// `reference.force = "none"`: what needs a desired force is refused, naming it.
fn no_desired_force(c: &Check, f: &ScenarioFile) -> Result<()> {
    if f.reference.force != crate::scenario::DesiredForce::None {
        return Ok(());
    }
    let why = "needs the desired force, and reference.force = \"none\" has none";
    if f.reference.kind == ReferenceKind::Sine {
        return Err(c.fail("reference.force", "a sine reference is a desired force: \"none\" needs reference.kind = \"gait\" or \"pose\" (the wearer's motion)"));
    }
    if f.human.mode != HumanMode::Off {
        return Err(c.fail(
            "human.mode",
            format!("w1 = k_p (F_L - F_d) + k_d (dF_L/dt - dF_d/dt) {why}: set human.mode = \"off\""),
        ));
    }
    if f.reference.assist_fraction > 0.0 {
        return Err(c.fail(
            "reference.assist_fraction",
            format!("exoleg's stance assistance {why}: the controller decides the assistance"),
        ));
    }
    if f.actuator.force_source == crate::hydraulics::ForceSource::Reference && f.actuator.mode == ActuatorMode::Force {
        return Err(c.fail("actuator.force_source", format!("`reference` {why}")));
    }
    if f.criteria.max_force_error_n.is_some() || f.criteria.rms_force_error_n.is_some() {
        return Err(c.fail("criteria", format!("a force-error criterion {why}")));
    }
    if f.controller.sample_period_s == 0.0 && f.controller.kind.needs_reference() {
        return Err(c.fail("controller.kind", format!("`{}` (continuous) {why}: a controller that decides the assistance runs sampled (a plugin, open_loop, or yours with controller.sample_period_s > 0)", f.controller.kind.as_str())));
    }
    Ok(())
}

/// `[controller]`.
/// `controller.compute_*`: finite, non-negative, for a sampled controller only.
fn compute_model(c: &Check, f: &ScenarioFile) -> Result<()> {
    let ct = &f.controller;
    c.non_negative("controller.compute_delay_s", ct.compute_delay_s)?;
    c.non_negative("controller.compute_jitter_s", ct.compute_jitter_s)?;
    if let Some(b) = ct.compute_budget_s {
        c.positive("controller.compute_budget_s", b)?;
    }
    let modelled = ct.compute_delay_s > 0.0 || ct.compute_jitter_s > 0.0 || ct.compute_budget_s.is_some();
    if modelled && ct.sample_period_s == 0.0 {
        return Err(c.fail(
            "controller.compute_delay_s",
            "a modelled computation needs a sampled controller (controller.sample_period_s > 0)".to_string(),
        ));
    }
    if ct.overrun_policy != crate::control::OverrunPolicy::ApplyLate
        && (ct.sample_period_s == 0.0 || ct.compute_delay_s + ct.compute_jitter_s == 0.0)
    {
        return Err(c.fail(
            "controller.overrun_policy",
            "acts on a sample whose modelled computation overruns its budget: it needs a sampled controller \
             (controller.sample_period_s > 0) and a modelled time (controller.compute_delay_s or compute_jitter_s > 0)",
        ));
    }
    if ct.compute_delay_s + ct.compute_jitter_s > f.sim.duration_s {
        return Err(c.fail("controller.compute_delay_s", "with compute_jitter_s longer than the run".to_string()));
    }
    Ok(())
}

fn controller(c: &Check, f: &ScenarioFile) -> Result<()> {
    compute_model(c, f)?;
    let ct = &f.controller;
    c.positive("controller.gamma", ct.gamma)?;
    c.positive("controller.k", ct.k)?;
    c.positive("controller.delta", ct.delta)?;
    c.non_negative("controller.zeta", ct.zeta)?;
    c.non_negative("controller.sample_period_s", ct.sample_period_s)?;
    if ct.sample_period_s > 0.0 {
        let ratio = ct.sample_period_s / f.sim.dt_s;
        if ratio < 1.0 - 1e-9 || (ratio - ratio.round()).abs() > 1e-6 {
            return Err(c.fail(
                "controller.sample_period_s",
                format!(
                    "must be 0 (continuous) or a whole multiple of sim.dt_s = {}, got {}",
                    f.sim.dt_s, ct.sample_period_s
                ),
            ));
        }
        if ct.sample_period_s > f.sim.duration_s {
            return Err(c.fail(
                "controller.sample_period_s",
                format!(
                    "{} s is longer than the run (sim.duration_s = {} s): the controller would see one sample only",
                    num(ct.sample_period_s),
                    num(f.sim.duration_s)
                ),
            ));
        }
    }
    if ct.kind.sampled_only() && ct.sample_period_s == 0.0 {
        return Err(c.fail(
            "controller.kind",
            format!(
                "`{}` is a discrete-time (firmware) controller: set controller.sample_period_s > 0",
                ct.kind.as_str()
            ),
        ));
    }
    if ct.kind == ControllerKind::Plugin {
        // The same check `exoleg hil` makes of what it sends its peer.
        ct.plugin.check().map_err(|(k, m)| c.fail(&k, m))?;
    }
    c.non_negative("controller.resonator_hz", ct.resonator_hz)?;
    if ct.resonator_hz > 0.0 && ct.sample_period_s > 0.0 && ct.resonator_hz >= 0.5 / ct.sample_period_s {
        return Err(c.fail(
            "controller.resonator_hz",
            format!(
                "{} Hz is at or above the Nyquist frequency of controller.sample_period_s = {} s ({} Hz): a sampled model cannot hold it",
                num(ct.resonator_hz),
                num(ct.sample_period_s),
                num(0.5 / ct.sample_period_s)
            ),
        ));
    }
    if ct.delay_samples.is_some_and(|d| d > 100_000) {
        return Err(c.fail("controller.delay_samples", "at most 100000 samples"));
    }
    for (i, v) in ct.observer.process_noise.iter().enumerate() {
        c.non_negative(&format!("controller.observer.process_noise.{i}"), *v)?;
    }
    c.positive("controller.rbf.width", ct.rbf.width)?;
    c.positive("controller.rbf.eta", ct.rbf.eta)?;
    c.positive("controller.observer.gain", ct.observer.gain)?;
    if !(ct.observer.exponent > 0.0 && ct.observer.exponent < 1.0) {
        return Err(c.fail("controller.observer.exponent", format!("must be in (0, 1), got {}", ct.observer.exponent)));
    }
    let n = &ct.nominal;
    for (k, v) in [
        ("controller.nominal.beta_pa", n.beta_pa),
        ("controller.nominal.v0_m3", n.v0_m3),
        ("controller.nominal.k_q", n.k_q),
        ("controller.nominal.tau_s", n.tau_s),
        ("controller.nominal.k_s", n.k_s),
        ("controller.nominal.a1_m2", n.a1_m2),
        ("controller.nominal.a2_m2", n.a2_m2),
    ] {
        if let Some(v) = v {
            c.positive(k, v)?;
        }
    }
    for (k, v) in [("controller.nominal.k_c", n.k_c), ("controller.nominal.leakage", n.leakage)] {
        if let Some(v) = v {
            c.non_negative(k, v)?;
        }
    }
    Ok(())
}

/// One `[sensors.<channel>]` table: noise, range and bits; `saturates`: its range clamps
/// without quantisation (the device's sensors), else it needs bits to mean anything.
fn channel_params(
    c: &Check,
    f: &ScenarioFile,
    key: &str,
    ch: &crate::sensors::ChannelParams,
    saturates: bool,
) -> Result<()> {
    if let Some(n) = ch.noise_std {
        c.non_negative(&format!("{key}.noise_std"), n)?;
    }
    if let Some(r) = ch.range {
        c.positive(&format!("{key}.range"), r)?;
    }
    bits(c, &format!("{key}.bits"), ch.bits)?;
    if !saturates && ch.range.is_some() && ch.bits.is_none() && !f.sensors.preset.quantises() {
        return Err(c.fail(
            &format!("{key}.range"),
            format!("has no effect without quantisation: set {key}.bits or a quantising sensors.preset (\"adc16\", \"adc32\", \"device\")"),
        ));
    }
    Ok(())
}

fn bits(c: &Check, key: &str, b: Option<u32>) -> Result<()> {
    if b.is_some_and(|b| b == 0 || b > 52) {
        return Err(c.fail(
            key,
            "must be 1..=52 (leave it out for the preset's; sensors.preset = \"ideal\" quantises nothing)",
        ));
    }
    Ok(())
}

/// The device's own sensors: IMUs, foot, hip, cuffs, pressures.
fn device_sensors(c: &Check, f: &ScenarioFile) -> Result<()> {
    let s = &f.sensors;
    for (key, ch) in [
        ("sensors.hip", &s.hip),
        ("sensors.thigh_cuff", &s.thigh_cuff),
        ("sensors.shank_cuff", &s.shank_cuff),
        ("sensors.pressure_a", &s.pressure_a),
        ("sensors.pressure_b", &s.pressure_b),
        ("sensors.supply_pressure", &s.supply_pressure),
        ("sensors.load_pressure", &s.load_pressure),
    ] {
        channel_params(c, f, key, ch, true)?;
    }
    for (name, imu) in [("sensors.thigh_imu", &s.thigh_imu), ("sensors.shank_imu", &s.shank_imu)] {
        for (kind, a) in [("accel", &imu.accel), ("gyro", &imu.gyro)] {
            let key = format!("{name}.{kind}");
            for (k, v) in [("noise_density", a.noise_density), ("bias_random_walk", a.bias_random_walk)] {
                if let Some(v) = v {
                    c.non_negative(&format!("{key}.{k}"), v)?;
                }
            }
            for (i, e) in a.scale_error.unwrap_or_default().iter().enumerate() {
                c.range(&format!("{key}.scale_error.{i}"), *e, -0.5, 0.5)?;
            }
            if let Some(r) = a.range {
                c.positive(&format!("{key}.range"), r)?;
            }
            bits(c, &format!("{key}.bits"), a.bits)?;
        }
        if let Some(r) = imu.rate_hz {
            c.positive(&format!("{name}.rate_hz"), r)?;
        }
    }
    let foot = &s.foot;
    for (k, v) in [("threshold_n", foot.threshold_n), ("noise_std", foot.noise_std)] {
        if let Some(v) = v {
            c.non_negative(&format!("sensors.foot.{k}"), v)?;
        }
    }
    if let Some(r) = foot.range {
        c.positive("sensors.foot.range", r)?;
    }
    if let Some(r) = foot.rate_hz {
        c.positive("sensors.foot.rate_hz", r)?;
    }
    bits(c, "sensors.foot.bits", foot.bits)
}

/// `[sensors]`, `[actuator]`, `[disturbance]`.
fn sensors_and_actuator(c: &Check, f: &ScenarioFile) -> Result<()> {
    c.non_negative("sensors.derivative_cutoff_hz", f.sensors.derivative_cutoff_hz)?;
    for info in crate::sensors::CHANNELS {
        let key = format!("sensors.{}", info.name);
        channel_params(c, f, &key, f.sensors.channel(info.id), false)?;
    }
    device_sensors(c, f)?;
    for (key, ch) in
        [("sensors.force", &f.sensors.force), ("sensors.piston", &f.sensors.piston), ("sensors.knee", &f.sensors.knee)]
    {
        if !ch.enabled {
            return Err(
                c.fail(&format!("{key}.enabled"), "only the spool and piston-velocity sensors may be switched off")
            );
        }
    }
    if !f.sensors.spool.enabled && !f.controller.kind.sampled_only() {
        return Err(c.fail(
            "sensors.spool.enabled",
            format!(
                "`{}` reads the spool position; only `dtznn` (and a plugin) work without a sensor",
                f.controller.kind.as_str()
            ),
        ));
    }
    if f.sensors.delay_samples > 100_000 {
        return Err(c.fail("sensors.delay_samples", format!("at most 100000 samples, got {}", f.sensors.delay_samples)));
    }
    if f.sensors.has_effects() && f.controller.sample_period_s == 0.0 {
        return Err(c.fail(
            "sensors",
            "noise, quantisation, delay and filtering act on sampled signals: set controller.sample_period_s > 0",
        ));
    }
    c.non_negative("actuator.valve_command_limit", f.actuator.valve_command_limit)?;
    c.positive("actuator.failsafe_bypass_area_m2", f.actuator.failsafe_bypass_area_m2)?;
    c.non_negative("actuator.spool_limit_m", f.actuator.spool_limit_m)?;
    if f.actuator.mode != ActuatorMode::Hydraulic && f.plant.kind == PlantKind::Bench {
        return Err(c.fail("actuator.mode", "`force` and `free` drive a leg; the bench has no mechanics to drive"));
    }
    signal(c, "disturbance.force_rate", &f.disturbance.force_rate)?;
    signal(c, "disturbance.force_accel", &f.disturbance.force_accel)?;
    signal(c, "disturbance.spool", &f.disturbance.spool)
}
