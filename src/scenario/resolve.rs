//! Resolve once (ripgrep's low-args to high-args): a validated [`Scenario`] becomes a
//! [`ResolvedScenario`] holding everything a run needs, with shared models, and every input
//! error surfaces here, before anything runs.

use super::files::{InputText, Resources};
use super::{ReferenceKind, Scenario, ScenarioFile};
use crate::control::{ControllerKind, ControllerSetup, KneePd, NominalModel, SetupContext, ValveLimit};
use crate::error::{Error, Result};
use crate::human::HipMode;
use crate::human::{BodySetup, BodyTargets};
use crate::hydraulics::{Cylinder, FrictionParams};
use crate::leg::LegSpec;
use crate::leg::{foot_points_at, GroundConfig, LegOptions};
use crate::metrics::{Band, MetricSettings};
use crate::plant::{LegSetup, LegStart, PlantKind, PlantSetup};
use crate::reference::{
    ForceReference, GaitReference, KneeForceReference, RefSample, Sine, WalkingData, WalkingSample, BUILTIN_TRIALS,
};
use crate::sim::Model;
use std::sync::Arc;

mod body;
mod gait;
mod wearer;
use body::*;

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
    /// The scenario file, when it came from one.
    pub path: Option<std::path::PathBuf>,
}

impl ResolvedScenario {
    /// Every file this run reads (the scenario file and the files it names): an output folder
    /// must not hold any of them.
    pub fn input_paths(&self) -> Vec<std::path::PathBuf> {
        let files = self.inputs.iter().map(|i| std::path::PathBuf::from(&i.origin)).filter(|p| p.is_absolute());
        self.path.iter().cloned().chain(files).collect()
    }
}

/// Compare a recorded hash with the file's; a change is a warning, not an error.
fn check_hash(key: &str, input: &InputText, recorded: &Option<String>, warnings: &mut Vec<String>) {
    if let Some(r) = recorded {
        if *r != input.sha256 {
            warnings.push(format!(
                "{key}: {} changed since the recorded run (sha256 {} recorded, {} now): the results may differ",
                input.origin,
                r.chars().take(12).collect::<String>(),
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

    /// The wearer's muscles (`wearer.muscles`): the table (embedded, or the file's, recorded by
    /// its absolute path) scaled to the leg's thigh and shank, and the analysis's settings.
    fn muscles(
        &mut self,
        leg: Option<&crate::leg::LegSpec>,
    ) -> Result<Option<Arc<crate::muscles::analysis::MuscleSetup>>> {
        let w = self.file.wearer.clone();
        let wanted = w.muscles || w.model == crate::human::WearerModel::Muscles;
        let (true, Some(leg)) = (wanted, leg) else { return Ok(None) };
        let set = match &w.muscles_file {
            None => crate::muscles::MuscleSet::builtin()?,
            Some(f) => {
                let (set, text) = self.res.muscle_set(self.src(), f, self.s.base_dir.as_deref())?;
                self.file.wearer.muscles_file = Some(text.origin.clone());
                self.inputs.push(InputRecord { key: "wearer.muscles_file", origin: text.origin, sha256: text.sha256 });
                set
            }
        };
        let (thigh, shank) = leg.thigh_shank_lengths_m();
        let scaled = Arc::new(set.scaled(set.scale_for(thigh, shank)));
        Ok(Some(Arc::new(crate::muscles::analysis::MuscleSetup::new(
            scaled,
            w.muscle_cost,
            w.metabolic_model,
            w.reserve_optimal_moment_nm,
            self.file.hip.subject_mass(),
        ))))
    }

    /// The plant's leg: `leg.urdf` with its knee and ankle joints, the ankle free with ground
    /// contact, its mass scale.
    fn leg_model(&mut self) -> Result<Arc<crate::scenario::files::LoadedLeg>> {
        let leg = &self.s.file.leg;
        let options = LegOptions {
            knee_joint: leg.knee_joint.clone(),
            ankle_joint: leg.ankle_joint.clone(),
            ankle_free: self.s.file.ground.enabled,
            mass_scale: leg.mass_scale,
        };
        let (loaded, text) = self.load_leg("leg.urdf", &leg.urdf, &leg.urdf_sha256, &options)?;
        if !text.origin.starts_with("builtin:") {
            self.file.leg.urdf = text.origin.clone();
        }
        self.file.leg.urdf_sha256 = Some(text.sha256);
        Ok(loaded)
    }

    /// Load and record a URDF named by `key`.
    fn load_leg(
        &mut self,
        key: &'static str,
        urdf: &str,
        recorded: &Option<String>,
        options: &LegOptions,
    ) -> Result<(Arc<crate::scenario::files::LoadedLeg>, InputText)> {
        let mut text = self.res.urdf_text(self.src(), key, urdf, self.s.base_dir.as_deref())?;
        if let Some(subject) = &self.s.file.subject {
            if text.origin.starts_with("builtin:") {
                let scaled = crate::leg::subject::scaled_urdf(&subject.body());
                text = InputText {
                    origin: format!("{} scaled to [subject]", text.origin),
                    sha256: crate::scenario::files::sha256_hex(scaled.as_bytes()),
                    text: Arc::from(scaled.as_str()),
                };
            } else {
                let msg = format!(
                    "{key} is your own URDF: it is used as given ([subject] sets the subject's mass only; it scales \
                     the built-in legs)"
                );
                if !self.warnings.contains(&msg) {
                    self.warnings.push(msg);
                }
            }
        }
        check_hash(key, &text, recorded, &mut self.warnings);
        let loaded = self.res.leg(&text, options).map_err(|e| {
            Error::input(self.src(), key, format!("{}: {e}", text.origin.trim_start_matches("builtin:")))
        })?;
        self.inputs.push(InputRecord { key, origin: text.origin.clone(), sha256: text.sha256.clone() });
        Ok((loaded, text))
    }

    /// The controller's leg (`controller.nominal_leg`): the plant's unless it names another
    /// URDF or mass scale. Its ankle is locked (the cascade's inverse dynamics is the hanging
    /// leg's).
    fn nominal_leg(&mut self, plant: &Arc<crate::scenario::files::LoadedLeg>) -> Result<Arc<LegSpec>> {
        let f = &self.s.file;
        let n = &f.controller.nominal_leg;
        if n.urdf.is_none() && n.mass_scale.is_none_or(|m| m == f.leg.mass_scale) {
            return Ok(plant.model.clone());
        }
        let options = LegOptions {
            knee_joint: f.leg.knee_joint.clone(),
            ankle_joint: f.leg.ankle_joint.clone(),
            ankle_free: false,
            mass_scale: n.mass_scale.unwrap_or(f.leg.mass_scale),
        };
        let urdf = n.urdf.clone().unwrap_or_else(|| f.leg.urdf.clone());
        let (loaded, text) = self.load_leg("controller.nominal_leg.urdf", &urdf, &n.urdf_sha256, &options)?;
        if n.urdf.is_some() {
            if !text.origin.starts_with("builtin:") {
                self.file.controller.nominal_leg.urdf = Some(text.origin.clone());
            }
            self.file.controller.nominal_leg.urdf_sha256 = Some(text.sha256);
        }
        Ok(loaded.model.clone())
    }

    /// `hip.mode`, or its default: `reference.drive_hip` (deprecated, with a warning), the
    /// carriage for a pose, driven for a gait, else fixed.
    fn hip_mode(&mut self) -> HipMode {
        let f = &self.s.file;
        if let Some(d) = f.reference.drive_hip {
            self.warnings.push(format!(
                "reference.drive_hip is deprecated: use hip.mode = \"{}\"",
                if d { "driven" } else { "fixed" }
            ));
            self.file.reference.drive_hip = None;
        }
        let mode = match (f.hip.mode, f.reference.drive_hip, f.reference.kind) {
            (Some(m), _, _) => m,
            (None, Some(true), _) => HipMode::Driven,
            (None, Some(false), _) => HipMode::Fixed,
            (None, None, ReferenceKind::Pose) => HipMode::Carriage,
            (None, None, ReferenceKind::Gait) => HipMode::Driven,
            (None, None, ReferenceKind::Sine) => HipMode::Fixed,
        };
        self.file.hip.mode = Some(mode);
        mode
    }
}

impl Ctx<'_> {
    /// The controller's setup: its kind's tagged value (dtznn designed, a plugin loaded).
    fn controller(&mut self, nominal: NominalModel) -> Result<ControllerSetup> {
        let f = &self.s.file;
        let p = &f.controller;
        let plugin = match (p.kind, &p.plugin.library) {
            (ControllerKind::Plugin, None) => {
                return Err(Error::input(
                    self.src(),
                    "controller.plugin.library",
                    "`plugin` needs the shared library's path",
                ))
            }
            (ControllerKind::Plugin, Some(lib)) => {
                let (l, sha) = self.res.plugin(self.src(), lib, self.s.base_dir.as_deref())?;
                check_hash(
                    "controller.plugin.library",
                    &InputText { origin: l.path.display().to_string(), text: Arc::from(""), sha256: sha.clone() },
                    &p.plugin.library_sha256,
                    &mut self.warnings,
                );
                self.inputs.push(InputRecord {
                    key: "controller.plugin.library",
                    origin: l.path.display().to_string(),
                    sha256: sha.clone(),
                });
                self.file.controller.plugin.library = Some(l.path.display().to_string());
                self.file.controller.plugin.library_sha256 = Some(sha);
                Some(l)
            }
            _ => None,
        };
        let cx = SetupContext {
            nominal,
            sensors: &f.sensors,
            limit: ValveLimit(f.actuator.valve_command_limit),
            plugin,
            seed: f.seed,
        };
        ControllerSetup::resolve(p, cx).map_err(|(key, m)| Error::input(self.src(), key, m))
    }
}

impl Scenario {
    /// The reduced engine's model of the leg `l` into `setup`: the walking leg on the carriage or
    /// over the ground, else the knee-only closed chain (tabulated once per leg in `res`).
    fn reduced_engine(
        &self,
        res: &Resources,
        l: &crate::scenario::files::LoadedLeg,
        setup: &mut LegSetup,
    ) -> Result<()> {
        use crate::leg::reduced_walking_model::WalkerMount;
        let mount = match (&setup.body, &setup.ground) {
            (Some(b), _) => WalkerMount::Carriage {
                pelvis_mass_kg: b.pelvis_mass_kg,
                hip_locked: b.hip.locked,
                tether_locked: b.hip.tether_locked,
            },
            (None, Some(_)) => WalkerMount::FixedHip,
            (None, None) => {
                let bad = |e: crate::leg::LegError| Error::input(&self.source_name, "leg.engine", e.to_string());
                setup.reduced = Some(res.reduced(&l.model).map_err(bad)?);
                return Ok(());
            }
        };
        let w = crate::leg::WalkerModel::new(&l.model, mount, setup.ground.as_ref())
            // What it refuses is in the leg's file (a mesh sole, a joint it cannot move) or the
            // contact law (validated before).
            .map_err(|e| Error::input(&self.source_name, "leg.urdf (with leg.engine = \"reduced\")", e.to_string()))?;
        setup.walker = Some(Arc::new(w));
        Ok(())
    }

    /// The device's sensors of a sampled run (`sampled`), with the leg's mounting defaults.
    fn device_setup(
        &self,
        leg: Option<&crate::scenario::files::LoadedLeg>,
        sampled: bool,
    ) -> Result<Option<crate::sensors::DeviceSetup>> {
        let f = &self.file;
        let defaults = match leg {
            Some(l) => l.model.device_defaults(),
            None => crate::sensors::DeviceDefaults { imu_xyz_m: [[0.0; 3]; 2], foot_x_m: (-0.03, 0.15) },
        };
        if !sampled {
            return Ok(None);
        }
        f.sensors
            .device_setup(f.controller.sample_period_s, &defaults)
            .map(Some)
            .map_err(|(key, m)| Error::input(&self.source_name, key, m))
    }

    /// The scenario's `[[faults]]` resolved for the run of `plant` (a leg run when `leg`).
    fn faults(&self, plant: &PlantSetup, leg: bool) -> Result<Vec<crate::faults::Fault>> {
        let f = &self.file;
        let fcx = crate::scenario::FaultContext {
            duration_s: f.sim.duration_s,
            settle_s: f.metrics.settle_s,
            sample_period_s: f.controller.sample_period_s,
            dt_s: f.sim.dt_s,
            walking: crate::sim::is_walking(plant),
            leg,
            sensors: &f.sensors,
        };
        crate::scenario::resolve_faults(&f.faults, &fcx).map_err(|(k, m)| Error::input(&self.source_name, k, m))
    }

    /// The scenario resolved in its normal form when it is not in it: the subject's mass moved
    /// into `hip.subject_mass_kg` (recorded as written), an ideal device's cylinder
    /// disconnected. None: it is.
    fn resolve_normalised(&self, res: &Resources) -> Option<Result<ResolvedScenario>> {
        if let Some(m) =
            self.file.subject.as_ref().map(|s| s.mass_kg).filter(|_| self.file.hip.subject_mass_kg.is_none())
        {
            // The subject's mass is the hip's (kinetics, carried weight), in one place.
            let mut with_mass = self.clone();
            with_mass.file.hip.subject_mass_kg = Some(m);
            return Some(with_mass.resolve(res).map(|mut resolved| {
                // Recorded as written: the mass once, in [subject] (a sweep of subject.mass_kg
                // on a reproduced run is not a contradiction).
                resolved.file.hip.subject_mass_kg = None;
                resolved
            }));
        }
        if self.file.controller.kind == ControllerKind::IdealMoment
            && self.file.actuator.mode != crate::hydraulics::ActuatorMode::Free
        {
            // The ideal device's cylinder is disconnected (recorded so).
            let mut free = self.clone();
            free.file.actuator.mode = crate::hydraulics::ActuatorMode::Free;
            return Some(free.resolve(res));
        }
        None
    }

    /// Resolve this validated scenario with shared inputs from `res`. Every input error
    /// (files, leg, gait, cuff) is reported here.
    pub fn resolve(&self, res: &Resources) -> Result<ResolvedScenario> {
        if let Some(r) = self.resolve_normalised(res) {
            return r;
        }
        let f = &self.file;
        let mut cx = Ctx { s: self, res, file: f.clone(), inputs: Vec::new(), warnings: Vec::new() };
        let leg = match f.plant.kind {
            PlantKind::Leg => Some(cx.leg_model()?),
            PlantKind::Bench => None,
        };
        let mode = cx.hip_mode();
        let nominal = match &leg {
            Some(l) => Some(cx.nominal_leg(l)?),
            None => None,
        };
        let (reference, walking) = cx.reference(leg.as_deref(), nominal.as_ref(), mode)?;
        let plant = match &leg {
            None => PlantSetup::Bench(f.bench.clone()),
            Some(l) => {
                let mut setup = leg_setup(self, l, &reference, mode, walking)?;
                if f.leg.engine == crate::plant::LegEngine::Reduced {
                    self.reduced_engine(res, l, &mut setup)?;
                }
                PlantSetup::Leg(Box::new(setup))
            }
        };
        let desired_force = f.reference.force == crate::scenario::DesiredForce::Computed;
        let knee_pd = knee_pd(f, &reference, nominal.as_ref(), desired_force);
        let band = match (f.metrics.convergence_band_n, f.reference.kind) {
            (None, ReferenceKind::Gait | ReferenceKind::Pose) => Band::FractionOfPeakReference(0.01),
            (Some(b), _) => Band::Fixed(b),
            (None, ReferenceKind::Sine) => Band::Fixed(0.01 * f.reference.amplitude_n),
        };
        let nominal = NominalModel { c: f.controller.nominal.apply(&f.hydraulics).coefficients() };
        let dt_s = f.sim.dt_s;
        let sample_every =
            (f.controller.sample_period_s > 0.0).then(|| (f.controller.sample_period_s / dt_s).round() as usize);
        let device = self.device_setup(leg.as_deref(), sample_every.is_some())?;
        let faults = self.faults(&plant, leg.is_some())?;
        let mut model = Model {
            faults,
            on_stop: f.controller.on_stop,
            compute: crate::sim::ComputeModel::of(&f.controller),
            device_columns: leg.is_some() && device.is_some(),
            device,
            source_name: self.source_name.clone(),
            steps: (f.sim.duration_s / dt_s).round() as usize,
            dt_s,
            integrator: f.sim.integrator,
            substep_controller: f.sim.substep_controller,
            seed: f.seed,
            sample_every,
            sample_period_s: f.controller.sample_period_s,
            plant,
            metrics: MetricSettings {
                band,
                settle_s: f.metrics.settle_s,
                stride_s: reference.stride_s(),
                force_reference: desired_force,
            },
            reference,
            knee_pd,
            desired_force,
            cylinder: Cylinder::new(&f.hydraulics, f.actuator.pressure_limit, f.actuator.spool_limit_m),
            controller: cx.controller(nominal)?,
            nominal,
            friction: f.friction.clone(),
            actuator: f.actuator.clone(),
            valve_limit: ValveLimit(f.actuator.valve_command_limit),
            human: f.human.clone(),
            disturbance: f.disturbance.clone(),
            sensors: f.sensors.clone(),
            cuff_limits: f.cuff_limits,
            safety: f.safety,
            muscle_wearer: None,
            muscles: cx.muscles(leg.as_deref().map(|l| &*l.model))?,
            muscle_columns: f.output.muscles,
            ideal: (f.controller.kind == ControllerKind::IdealMoment)
                .then(|| (f.controller.ideal, f.hip.subject_mass())),
        };
        if f.wearer.model == crate::human::WearerModel::Muscles {
            model.muscle_wearer =
                Some(self.muscle_wearer_setup(res, model.muscles.as_ref(), model.reference.stride_s())?);
        }
        Ok(ResolvedScenario {
            source_name: self.source_name.clone(),
            model: Arc::new(model),
            file: cx.file,
            inputs: cx.inputs,
            warnings: cx.warnings,
            path: self.path.clone(),
        })
    }
}

/// The cascade's outer knee loop of a gait or pose run with a desired force (None otherwise).
fn knee_pd(
    f: &ScenarioFile,
    reference: &ForceReference,
    nominal: Option<&Arc<crate::leg::LegSpec>>,
    desired_force: bool,
) -> Option<KneePd> {
    match (reference, nominal) {
        _ if !desired_force => None,
        (ForceReference::Gait(_) | ForceReference::Pose { .. }, Some(model)) => Some(KneePd {
            kp_nm_per_rad: f.reference.knee_kp_nm_per_rad,
            kd_nm_s_per_rad: f.reference.knee_kd_nm_s_per_rad,
            ki_nm_per_rad_s: f.reference.knee_ki_nm_per_rad_s,
            model: model.clone(),
        }),
        _ => None,
    }
}
