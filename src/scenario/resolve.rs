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

    /// The force reference (its cascade on the controller's leg `nominal`), and on the
    /// carriage the walking data it follows.
    fn reference(
        &mut self,
        leg: Option<&crate::scenario::files::LoadedLeg>,
        nominal: Option<&Arc<LegSpec>>,
        mode: HipMode,
    ) -> Result<(ForceReference, Option<Arc<WalkingData>>)> {
        let f = &self.s.file;
        match f.reference.kind {
            ReferenceKind::Sine => Ok((
                ForceReference::Sine(Sine {
                    amplitude: f.reference.amplitude_n,
                    frequency_hz: f.reference.frequency_hz,
                    phase_rad: f.reference.phase_rad,
                    offset: f.reference.offset_n,
                }),
                None,
            )),
            ReferenceKind::Pose => Ok((ForceReference::Pose { knee_rad: f.reference.knee_deg.to_radians() }, None)),
            ReferenceKind::Gait => {
                let (leg, nominal) = leg
                    .zip(nominal)
                    .ok_or_else(|| Error::input(self.src(), "reference.kind", "`gait` needs plant.kind = \"leg\""))?;
                let gait = self.gait()?;
                check_gait_in_leg_range(self.src(), &gait, &leg.model)?;
                let walking = match mode {
                    HipMode::Carriage => Some(self.walking(&gait, &leg.model)?),
                    _ => None,
                };
                let k = self.cascade(gait, nominal, mode, walking.clone())?;
                Ok((ForceReference::Gait(k), walking))
            }
        }
    }

    /// The gait cascade on the controller's leg: the inverse-dynamics fit (cached), blended
    /// with the stance assistance on the carriage, and the friction model.
    fn cascade(
        &mut self,
        gait: GaitReference,
        nominal: &Arc<LegSpec>,
        mode: HipMode,
        walking: Option<Arc<WalkingData>>,
    ) -> Result<Arc<KneeForceReference>> {
        let f = &self.s.file;
        let with_hip = mode != HipMode::Fixed;
        let key = format!(
            "{}|{:?}|{}|{}|{}|{with_hip}|{}",
            self.file.leg.urdf_sha256.clone().unwrap_or_default(),
            (&f.leg.knee_joint, f.controller.nominal_leg.mass_scale.unwrap_or(f.leg.mass_scale)),
            gait.sha256,
            f.reference.harmonics,
            gait.stride_s.to_bits(),
            self.file.controller.nominal_leg.urdf_sha256.clone().unwrap_or_default(),
        );
        let model = nominal.clone();
        let fit = self.res.cascade(key, || KneeForceReference::inverse_dynamics_fit(&gait, &model, with_hip))?;
        let fraction = f.reference.assist_fraction;
        let stance = match walking {
            Some(w) if fraction != 0.0 => {
                let a = KneeForceReference::assist_fit(&gait, &model, &w, fraction)?;
                Some((w, Some(Arc::new(a))))
            }
            Some(w) => Some((w, None)),
            None => None,
        };
        // The cascade's model of the seal friction: the plant's levels with its own smooth sign.
        let fr = FrictionParams {
            smoothing_velocity_m_s: f.reference.friction_smoothing_velocity_m_s,
            ..f.friction.clone()
        };
        Ok(Arc::new(KneeForceReference::new(gait, model, fr, mode == HipMode::Driven, fit, stance)))
    }

    /// The walking data of a gait on the carriage (cached per gait, leg and subject).
    fn walking(&mut self, gait: &GaitReference, model: &Arc<LegSpec>) -> Result<Arc<WalkingData>> {
        let (subject, tilt) = (self.s.file.hip.subject_mass(), self.s.file.hip.pelvic_tilt_deg.map(f64::to_radians));
        let g = &self.s.file.ground;
        let sole = (g.enabled && g.contact == crate::plant::ContactLaw::Compliant).then_some(g.contact_modulus_pa);
        let key = format!(
            "{}|{}|{}|{:?}|{:?}|{:p}",
            gait.sha256,
            gait.stride_s.to_bits(),
            subject.to_bits(),
            tilt.map(f64::to_bits),
            sole.map(f64::to_bits),
            Arc::as_ptr(model)
        );
        let src = self.src().to_string();
        let w = self.res.walking(key, || {
            WalkingData::new(gait.clone(), model, subject, tilt, sole)
                .map_err(|m| Error::input(&src, format!("reference.gait ({})", gait.source), m))
        })?;
        if let Some(v) = self.s.file.ground.belt_speed_m_s.filter(|_| self.s.file.ground.enabled) {
            let sweep = w.belt_speed_m_s;
            let off = v / sweep - 1.0;
            let msg = format!(
                "ground.belt_speed_m_s = {v} m/s and the speed the leg's stance sweeps at this stride time ({sweep:.3} \
                 m/s) differ by {:+.0} %: the belt will {} the stance foot (set the subject's height and the \
                 stride time, or leave the belt speed unset)",
                100.0 * off,
                if off > 0.0 { "drag back" } else { "push forward" }
            );
            if off.abs() > BELT_MISMATCH_WARNING && !self.warnings.contains(&msg) {
                self.warnings.push(msg);
            }
        }
        Ok(w)
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
    if on_trajectory {
        let key = match reference {
            ForceReference::Pose { .. } => "reference.knee_deg",
            _ => "reference.gait (the knee angle at t = 0)",
        };
        model.loop_solution_checked(q0).map_err(|e| Error::input(&s.source_name, key, e.to_string()))?;
    }
    let hip: Option<RefSample> = reference.hip_at(0.0);
    Ok((LegStart { knee_rad: q0, knee_rate_rad_s: qd0, hip }, on_trajectory))
}

/// A belt speed further than this (relative) from the leg's stance sweep gets a warning.
pub const BELT_MISMATCH_WARNING: f64 = 0.10;

/// The leg plant's setup: start, cuff, and with contact the ground and the body.
fn leg_setup(
    s: &Scenario,
    l: &crate::scenario::files::LoadedLeg,
    reference: &ForceReference,
    mode: HipMode,
    walking: Option<Arc<WalkingData>>,
) -> Result<LegSetup> {
    let f = &s.file;
    let (start, start_on_trajectory) = leg_start(s, &l.model, reference)?;
    if f.ground.enabled {
        if let Some(c) =
            l.model.collisions().iter().find(|c| matches!(c.shape, crate::leg::CollisionShape::Mesh { .. }))
        {
            let link = &l.model.links()[c.link].name;
            return Err(Error::input(
                &s.source_name,
                format!("leg.urdf (link '{link}' <collision>)"),
                "a mesh: ground contact needs boxes, cylinders, spheres or capsules",
            ));
        }
    }
    let cuff_point_m = crate::plant::cuff_point_from_model(&l.model, &f.human.cuff_link, f.human.cuff_xyz)
        .map_err(|m| Error::input(&s.source_name, "human.cuff_link", m))?;
    let (ground, body) = body_setup(s, &l.model, mode, walking, &start, reference)?;
    let knee = l.model.knee_joint().origin_xyz;
    let thigh_cuff = f.human.thigh_cuff_xyz.unwrap_or([knee[0], 0.0, 0.6 * knee[2]]);
    let cuff_lever_m =
        ((thigh_cuff[0] - knee[0]).hypot(thigh_cuff[2] - knee[2]), cuff_point_m[0].hypot(cuff_point_m[2]));
    if cuff_lever_m.0 < 1e-3 {
        return Err(Error::input(
            &s.source_name,
            "human.thigh_cuff_xyz",
            "lies on the knee axis: it carries no moment",
        ));
    }
    Ok(LegSetup {
        model: l.model.clone(),
        mass: l.mass.clone(),
        start,
        solver_iterations: f.leg.solver_iterations,
        cuff_point_m,
        cuff_lever_m,
        start_on_trajectory,
        ground,
        body,
        reduced: None,
        walker: None,
        stops: crate::leg::EndStops::of(&l.model),
    })
}

/// The targets of a pose on the carriage: the angles held, the foot flat (ankle = knee -
/// hip), the hip as high as the sole reaches, the other leg's share of the subject's weight.
fn pose_targets(s: &Scenario, model: &LegSpec) -> Result<WalkingSample> {
    let f = &s.file;
    let (h, k) = (f.reference.hip_deg.to_radians(), f.reference.knee_deg.to_radians());
    let fp = foot_points_at(model, h, k, k - h).ok_or_else(|| {
        Error::input(&s.source_name, "reference.knee_deg", "the leg cannot take this pose (loop or soles)")
    })?;
    let share = f.hip.other_leg_share.unwrap_or(0.5);
    let weight = f.hip.subject_mass() * crate::leg::model::GRAVITY_M_S2;
    let at = |v: f64| RefSample { value: v, ..Default::default() };
    Ok(WalkingSample {
        hip: at(h),
        knee: at(k),
        ankle: at(k - h),
        grf_this_n: (1.0 - share) * weight,
        grf_other_n: share * weight,
        other_share: share,
        pelvis_height_m: -fp.lowest.z,
        stance_weight: 1.0,
        ..Default::default()
    })
}

/// With ground contact: the ground (height, belt) and, on the carriage, the body.
fn body_setup(
    s: &Scenario,
    model: &LegSpec,
    mode: HipMode,
    walking: Option<Arc<WalkingData>>,
    start: &LegStart,
    reference: &ForceReference,
) -> Result<(Option<GroundConfig>, Option<Arc<BodySetup>>)> {
    let f = &s.file;
    let g = &f.ground;
    if !g.enabled {
        return Ok((None, None));
    }
    let targets = match (mode, walking) {
        (HipMode::Carriage, Some(w)) => Some(BodyTargets::Walking(w)),
        (HipMode::Carriage, None) => Some(BodyTargets::Pose(pose_targets(s, model)?)),
        _ => None,
    };
    let height_m = match (g.height_m, &targets) {
        (Some(h), _) => h,
        (None, Some(_)) => 0.0,
        (None, None) => lowest_sole_z(s, model, start, reference)?,
    };
    let belt_speed_m_s = g.belt_speed_m_s.unwrap_or(match &targets {
        Some(BodyTargets::Walking(w)) => w.belt_speed_m_s,
        _ => 0.0,
    });
    let ground = GroundConfig {
        height_m,
        friction: g.friction,
        belt_speed_m_s,
        contact_frequency_hz: g.contact_frequency_hz,
        contact_damping_ratio: g.contact_damping_ratio,
        compliant: (g.contact == crate::plant::ContactLaw::Compliant).then_some(crate::leg::CompliantContact {
            modulus_pa: g.contact_modulus_pa,
            dissipation_s_per_m: g.contact_dissipation_s_per_m,
            friction_stiffness_n_per_m: g.friction_stiffness_n_per_m,
        }),
    };
    let Some(targets) = targets else { return Ok((Some(ground), None)) };
    let pelvis_mass_kg = f.hip.body_mass_kg.unwrap_or(f.hip.subject_mass() - model.leg_mass_kg());
    if pelvis_mass_kg <= 0.0 {
        return Err(Error::input(
            &s.source_name,
            "hip.body_mass_kg",
            format!(
                "the subject ({} kg) minus this leg ({:.2} kg) leaves {pelvis_mass_kg:.2} kg for the body: must be > 0",
                f.hip.subject_mass(),
                model.leg_mass_kg()
            ),
        ));
    }
    let ankle_rad = targets.at(0.0).ankle.value;
    let pelvis_drift_m_s = match &targets {
        BodyTargets::Walking(w) => belt_speed_m_s - w.belt_speed_m_s,
        BodyTargets::Pose(_) => 0.0,
    };
    let mut hip = f.hip.clone();
    hip.support_force.get_or_insert(match &targets {
        BodyTargets::Walking(_) => crate::human::SupportForce::Data,
        BodyTargets::Pose(_) => crate::human::SupportForce::Weight,
    });
    let body = BodySetup { hip, wearer: f.wearer.clone(), targets, pelvis_mass_kg, ankle_rad, pelvis_drift_m_s };
    Ok((Some(ground), Some(Arc::new(body))))
}

/// Default ground height without the carriage: the lowest sole point (ankle at 0) at the
/// start, or over the gait cycle when the hip is driven along it.
fn lowest_sole_z(s: &Scenario, model: &LegSpec, start: &LegStart, reference: &ForceReference) -> Result<f64> {
    let none = || Error::input(&s.source_name, "ground.enabled", "the URDF has no collision shapes to stand on");
    let z = |h: f64, k: f64| foot_points_at(model, h, k, 0.0).map(|p| p.lowest.z);
    let z0 = z(start.hip.map_or(0.0, |h| h.value), start.knee_rad).ok_or_else(none)?;
    let Some(stride) = reference.stride_s().filter(|_| start.hip.is_some()) else { return Ok(z0) };
    // Driven along a gait: the lowest the sole reaches over the cycle (200 samples).
    let mut lowest = z0;
    for i in 0..200 {
        let t = stride * i as f64 / 200.0;
        if let (Some(h), Some(k)) = (reference.hip_at(t), reference.knee_at(t)) {
            lowest = lowest.min(z(h.value, k.value).unwrap_or(lowest));
        }
    }
    Ok(lowest)
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

impl Scenario {
    /// The muscle wearer of `wearer.model = "muscles"` on the analysis's muscles, its gains
    /// scaled by the subject's mass, its gait learned in [`Self::learning_scenario`].
    fn muscle_wearer_setup(
        &self,
        res: &Resources,
        muscles: Option<&Arc<crate::muscles::analysis::MuscleSetup>>,
        stride_s: Option<f64>,
    ) -> Result<Arc<crate::human::MuscleWearerSetup>> {
        let w = &self.file.wearer;
        let (Some(muscles), Some(stride_s)) = (muscles, stride_s) else {
            return Err(Error::input(
                &self.source_name,
                "wearer.model",
                "\"muscles\" needs the leg's muscles and a gait",
            ));
        };
        let learning = self.learning_scenario(stride_s).resolve(res)?;
        let feedforward = crate::sim::learn::learn_gait(learning.model).map_err(|e| {
            Error::input(&self.source_name, "wearer.model", format!("the muscle wearer could not learn the gait: {e}"))
        })?;
        let m = self.file.hip.subject_mass();
        let per_kg = |g: [f64; 3]| g.map(|k| k * m);
        Ok(Arc::new(crate::human::MuscleWearerSetup {
            muscles: muscles.clone(),
            delay_s: w.neural_delay_s.per_joint(),
            adapted: w.adapted,
            stiffness_nm_per_rad: [per_kg(w.stance_stiffness_nm_per_rad_kg), per_kg(w.swing_stiffness_nm_per_rad_kg)],
            damping_nm_s_per_rad: [per_kg(w.stance_damping_nm_s_per_rad_kg), per_kg(w.swing_damping_nm_s_per_rad_kg)],
            feedforward: Arc::new(feedforward),
        }))
    }

    /// The run the muscle wearer learns its gait in (its internal model): this walk with the
    /// impedance wearer, the cylinder disconnected and no faults, for
    /// [`crate::sim::learn::LEARNING_STRIDES`] strides, recording nothing.
    fn learning_scenario(&self, stride_s: f64) -> Scenario {
        let mut l = self.clone();
        let f = &mut l.file;
        // The cylinder free: no command reaches the knee, so the controller is a zero valve
        // command (open loop), which needs no desired force (`reference.force = "none"`
        // scenarios learn too).
        f.actuator.mode = crate::hydraulics::ActuatorMode::Free;
        f.controller = crate::control::ControllerParams {
            kind: crate::control::ControllerKind::OpenLoop,
            open_loop_command: 0.0,
            ..Default::default()
        };
        f.faults.clear();
        f.wearer = crate::human::WearerParams {
            knee_stiffness_nm_per_rad: f.wearer.knee_stiffness_nm_per_rad,
            knee_damping_nm_s_per_rad: f.wearer.knee_damping_nm_s_per_rad,
            knee_moment_share: f.wearer.knee_moment_share,
            ankle_stiffness_nm_per_rad: f.wearer.ankle_stiffness_nm_per_rad,
            ankle_damping_nm_s_per_rad: f.wearer.ankle_damping_nm_s_per_rad,
            ankle_moment_share: f.wearer.ankle_moment_share,
            ..Default::default()
        };
        f.output.muscles = false;
        f.sim.duration_s = stride_s * crate::sim::learn::LEARNING_STRIDES as f64;
        l
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
