//! Resolve once (ripgrep's low-args to high-args): a validated [`Scenario`] becomes a
//! [`ResolvedScenario`] holding everything a run needs, with shared models, and every input
//! error surfaces here, before anything runs.

use super::files::{InputText, Resources};
use super::{ReferenceKind, Scenario, ScenarioFile};
use crate::control::{ControllerKind, DtZnn, DtZnnSettings, KneePd, NominalModel, SensorModel, ValveLimit};
use crate::error::{Error, Result};
use crate::hydraulics::{Cylinder, FrictionParams};
use crate::leg::LegSpec;
use crate::metrics::{Band, MetricSettings};
use crate::plant::{LegSetup, LegStart, PlantKind, PlantSetup};
use crate::reference::{ForceReference, GaitReference, KneeForceReference, RefSample, Sine, BUILTIN_TRIALS};
use crate::sim::Model;
use std::sync::Arc;

/// A file a run read, as recorded in `summary.json`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct InputRecord {
    /// The scenario key that names it.
    pub key: &'static str,
    /// `builtin:...` / the trial name, or the absolute path.
    pub origin: String,
    /// SHA-256 of its content (hex).
    pub sha256: String,
}

/// A resolved scenario: the model a run needs, and where it came from.
#[derive(Debug, Clone)]
pub struct ResolvedScenario {
    /// Where the scenario came from (for messages).
    pub source_name: String,
    /// The scenario as run: files named by absolute path with their content hashes, so
    /// `exoleg run summary.json` reproduces the run from any directory.
    pub file: ScenarioFile,
    /// The immutable model the loop runs (shared by the runs that use it).
    pub model: Arc<Model>,
    /// Input files read.
    pub inputs: Vec<InputRecord>,
    /// Things the user should know that do not stop the run (printed on stderr).
    pub warnings: Vec<String>,
}

/// Compare a recorded hash with the file's; a change is a warning, not an error.
fn check_hash(key: &str, input: &InputText, recorded: &Option<String>, warnings: &mut Vec<String>) {
    if let Some(r) = recorded {
        if *r != input.sha256 {
            warnings.push(format!(
                "{key}: {} changed since the recorded run (sha256 {} recorded, {} now): the results may differ",
                input.origin,
                &r[..r.len().min(12)],
                &input.sha256[..12]
            ));
        }
    }
}

struct Ctx<'a> {
    s: &'a Scenario,
    res: &'a Resources,
    file: ScenarioFile,
    inputs: Vec<InputRecord>,
    warnings: Vec<String>,
}

impl Ctx<'_> {
    fn src(&self) -> &str {
        &self.s.source_name
    }

    /// Load the leg model named by `leg.urdf`.
    fn leg_model(&mut self) -> Result<Arc<crate::scenario::files::LoadedLeg>> {
        let leg = &self.s.file.leg;
        let text = self.res.urdf_text(self.src(), &leg.urdf, self.s.base_dir.as_deref())?;
        check_hash("leg.urdf", &text, &leg.urdf_sha256, &mut self.warnings);
        let loaded = self.res.leg(&text, &leg.knee_joint).map_err(|e| {
            Error::input(self.src(), "leg.urdf", format!("{}: {e}", text.origin.trim_start_matches("builtin:")))
        })?;
        if !text.origin.starts_with("builtin:") {
            self.file.leg.urdf = text.origin.clone();
        }
        self.file.leg.urdf_sha256 = Some(text.sha256.clone());
        self.inputs.push(InputRecord { key: "leg.urdf", origin: text.origin, sha256: text.sha256 });
        Ok(loaded)
    }

    /// The gait trajectory named by `reference.gait_trial` / `reference.gait_file`.
    fn gait(&mut self) -> Result<GaitReference> {
        let rf = &self.s.file.reference;
        let (text, default_stride) = match &rf.gait_file {
            Some(f) => (self.res.gait_text(self.src(), f, self.s.base_dir.as_deref())?, None),
            None => match Resources::builtin_gait_text(&rf.gait_trial) {
                Some((t, stride)) => (t, Some(stride)),
                None => {
                    let names: Vec<&str> = BUILTIN_TRIALS.iter().map(|t| t.0).collect();
                    return Err(Error::input(
                        self.src(),
                        "reference.gait_trial",
                        format!("unknown trial `{}` (built-in: {})", rf.gait_trial, names.join(", ")),
                    ));
                }
            },
        };
        check_hash("reference.gait", &text, &rf.gait_sha256, &mut self.warnings);
        let cycle = self.res.gait(&text, &text.origin, rf.harmonics)?;
        let stride_s = match (rf.stride_s, rf.cadence_steps_per_min, default_stride) {
            (Some(s), _, _) => s,
            (None, Some(c), _) => 120.0 / c,
            (None, None, Some(s)) => s,
            (None, None, None) => {
                return Err(Error::input(
                    self.src(),
                    "reference.stride_s",
                    "a gait_file gives no timing: set reference.stride_s or reference.cadence_steps_per_min",
                ))
            }
        };
        if rf.gait_file.is_some() {
            self.file.reference.gait_file = Some(text.origin.clone());
        }
        self.file.reference.gait_sha256 = Some(text.sha256.clone());
        self.inputs.push(InputRecord {
            key: "reference.gait",
            origin: text.origin.clone(),
            sha256: text.sha256.clone(),
        });
        Ok(GaitReference { cycle: (*cycle).clone(), stride_s, source: text.origin, sha256: text.sha256 })
    }

    /// The force reference; for gait runs also the leg it drives.
    fn reference(&mut self, leg: Option<&crate::scenario::files::LoadedLeg>) -> Result<ForceReference> {
        let s = self.s;
        let f = &s.file;
        match f.reference.kind {
            ReferenceKind::Sine => Ok(ForceReference::Sine(Sine {
                amplitude: f.reference.amplitude_n,
                frequency_hz: f.reference.frequency_hz,
                phase_rad: f.reference.phase_rad,
                offset: f.reference.offset_n,
            })),
            ReferenceKind::Gait => {
                let leg =
                    leg.ok_or_else(|| Error::input(self.src(), "reference.kind", "`gait` needs plant.kind = \"leg\""))?;
                let gait = self.gait()?;
                check_gait_in_leg_range(self.src(), &gait, &leg.model)?;
                let drive_hip = f.reference.drive_hip;
                let key = (
                    self.file.leg.urdf_sha256.clone().unwrap_or_default(),
                    f.leg.knee_joint.clone(),
                    gait.sha256.clone(),
                    f.reference.harmonics,
                    gait.stride_s.to_bits(),
                    drive_hip,
                );
                let model = leg.model.clone();
                let fit =
                    self.res.cascade(key, || KneeForceReference::inverse_dynamics_fit(&gait, &model, drive_hip))?;
                // The cascade's model of the seal friction: the plant's levels with its own smooth sign.
                let fr = FrictionParams {
                    smoothing_velocity_m_s: f.reference.friction_smoothing_velocity_m_s,
                    ..f.friction.clone()
                };
                let k = Arc::new(KneeForceReference::new(gait, model, fr, drive_hip, fit));
                Ok(ForceReference::Gait(k))
            }
        }
    }
}

/// Refuse a gait whose knee leaves what the leg can do: the cylinder loop must close at every
/// angle of the trajectory, and the angles must lie within 20 deg of the URDF's knee range.
fn check_gait_in_leg_range(src: &str, gait: &GaitReference, model: &LegSpec) -> Result<()> {
    let (lo, hi) = model.knee_range_rad();
    let margin = 20f64.to_radians();
    for i in 0..1000 {
        let pct = i as f64 / 10.0;
        let q = gait.knee_at(pct / 100.0 * gait.stride_s).value;
        let outside = q < lo - margin || q > hi + margin;
        let unreachable = model.loop_solution_checked(q).err();
        if outside || unreachable.is_some() {
            let why = match unreachable {
                Some(e) if !outside => format!("the cylinder cannot reach it ({e})"),
                _ => format!(
                    "more than 20 deg outside the leg's knee range [{:.1}, {:.1}] deg",
                    lo.to_degrees(),
                    hi.to_degrees()
                ),
            };
            return Err(Error::input(
                src,
                format!("reference.gait ({}): knee_flexion_deg", gait.source),
                format!("the fitted knee angle reaches {:.2} deg at {pct:.1} % of the cycle: {why}", q.to_degrees()),
            ));
        }
    }
    Ok(())
}

/// Initial knee state: at rest at `leg.initial_knee_deg`; else on the gait trajectory;
/// else at rest at 30 deg. Returns the start and whether it is on the trajectory.
fn leg_start(s: &Scenario, model: &LegSpec, reference: &ForceReference) -> Result<(LegStart, bool)> {
    let f = &s.file;
    let on_trajectory = f.leg.initial_knee_deg.is_none() && reference.knee_at(0.0).is_some();
    let (q0, qd0) = match (f.leg.initial_knee_deg, reference.knee_at(0.0)) {
        (Some(d), _) => (d.to_radians(), 0.0),
        (None, Some(k)) => (k.value, k.rate),
        (None, None) => (30f64.to_radians(), 0.0),
    };
    let (lo, hi) = model.knee_range_rad();
    if f.leg.initial_knee_deg.is_some() {
        let outside = (lo - q0).max(q0 - hi).max(0.0);
        if outside > 20f64.to_radians() {
            return Err(Error::input(
                &s.source_name,
                "leg.initial_knee_deg",
                format!(
                    "{:.2} deg is outside the URDF knee range [{:.1}, {:.1}] deg by more than 20 deg",
                    q0.to_degrees(),
                    lo.to_degrees(),
                    hi.to_degrees()
                ),
            ));
        }
        model
            .loop_solution_checked(q0)
            .map_err(|e| Error::input(&s.source_name, "leg.initial_knee_deg", e.to_string()))?;
    }
    let hip: Option<RefSample> = reference.hip_at(0.0);
    Ok((LegStart { knee_rad: q0, knee_rate_rad_s: qd0, hip }, on_trajectory))
}

/// Design `dtznn` once from the controller's nominal model and what it knows of its sensors.
fn design_dtznn(s: &Scenario, nominal: NominalModel) -> Result<Option<DtZnn>> {
    let f = &s.file;
    if f.controller.kind != ControllerKind::Dtznn {
        return Ok(None);
    }
    let sensors =
        SensorModel { force_sd_n: f.sensors.reading_sd(0).unwrap_or(0.0), spool_sd_m: f.sensors.reading_sd(1) };
    let settings = DtZnnSettings {
        gamma: f.controller.gamma,
        period_s: f.controller.sample_period_s,
        delay_samples: f.controller.delay_samples.unwrap_or(f.sensors.delay_samples),
        process_noise: f.controller.observer.process_noise,
        resonator_hz: f.controller.resonator_hz,
        estimator: f.controller.observer.kind,
        sensors,
        limit: ValveLimit(f.actuator.valve_command_limit),
    };
    DtZnn::new(nominal, settings)
        .map(Some)
        .map_err(|m| Error::input(&s.source_name, "controller", format!("dtznn design: {m}")))
}

impl Scenario {
    /// Resolve this validated scenario with shared inputs from `res`. Every input error
    /// (files, leg, gait, cuff) is reported here.
    pub fn resolve(&self, res: &Resources) -> Result<ResolvedScenario> {
        let f = &self.file;
        let mut cx = Ctx { s: self, res, file: f.clone(), inputs: Vec::new(), warnings: Vec::new() };
        let leg = match f.plant.kind {
            PlantKind::Leg => Some(cx.leg_model()?),
            PlantKind::Bench => None,
        };
        let reference = cx.reference(leg.as_deref())?;
        let plant = match &leg {
            None => PlantSetup::Bench(f.bench.clone()),
            Some(l) => {
                let (start, start_on_trajectory) = leg_start(self, &l.model, &reference)?;
                crate::plant::cuff_point_from_model(&l.model, &f.human.cuff_link, f.human.cuff_xyz)
                    .map_err(|m| Error::input(&self.source_name, "human.cuff_link", m))?;
                PlantSetup::Leg(Box::new(LegSetup {
                    model: l.model.clone(),
                    mass: l.mass.clone(),
                    start,
                    solver_iterations: f.leg.solver_iterations,
                    cuff: (f.human.cuff_link.clone(), f.human.cuff_xyz),
                    start_on_trajectory,
                }))
            }
        };
        let knee_pd = match (&reference, &leg) {
            (ForceReference::Gait(_), Some(_)) => Some(KneePd {
                kp_nm_per_rad: f.reference.knee_kp_nm_per_rad,
                kd_nm_s_per_rad: f.reference.knee_kd_nm_s_per_rad,
            }),
            _ => None,
        };
        let band = match (f.metrics.convergence_band_n, f.reference.kind) {
            (None, ReferenceKind::Gait) => Band::FractionOfPeakReference(0.01),
            (Some(b), _) => Band::Fixed(b),
            (None, ReferenceKind::Sine) => Band::Fixed(0.01 * f.reference.amplitude_n),
        };
        let nominal = NominalModel { c: f.controller.nominal.apply(&f.hydraulics).coefficients() };
        let dt_s = f.sim.dt_s;
        let sample_every =
            (f.controller.sample_period_s > 0.0).then(|| (f.controller.sample_period_s / dt_s).round() as usize);
        let model = Model {
            source_name: self.source_name.clone(),
            steps: (f.sim.duration_s / dt_s).round() as usize,
            dt_s,
            integrator: f.sim.integrator,
            seed: f.seed,
            sample_every,
            plant,
            metrics: MetricSettings { band, settle_s: f.metrics.settle_s, stride_s: reference.stride_s() },
            reference,
            knee_pd,
            cylinder: Cylinder::new(&f.hydraulics, f.actuator.pressure_limit, f.actuator.spool_limit_m),
            controller: f.controller.clone(),
            nominal,
            dtznn: design_dtznn(self, nominal)?,
            friction: f.friction.clone(),
            actuator: f.actuator.clone(),
            human: f.human.clone(),
            disturbance: f.disturbance.clone(),
            sensors: f.sensors.clone(),
        };
        Ok(ResolvedScenario {
            source_name: self.source_name.clone(),
            model: Arc::new(model),
            file: cx.file,
            inputs: cx.inputs,
            warnings: cx.warnings,
        })
    }
}
