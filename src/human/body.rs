//! The wearer's body in loaded walking (issue 12): the hip on a spring-damper about the data's
//! angle plus a share of the data's hip moment, the pelvis on a horizontal tether (to a
//! fore-aft target) and a "virtual other leg" that supports it, and the wearer's knee and
//! ankle as impedances about the data's angles plus optional shares of the data's moments.
//!
//! ```text
//! hip torque (flexion +)    = K_h (h_d - h) + C_h (h_d' - h') + s_h * M_hip,data
//! knee torque (flexion +)   = K_k (k_d - k) + C_k (k_d' - k') - s_k * M_knee,data   (data: extensor +)
//! ankle torque (dorsi +)    = K_a (a_d - a) + C_a (a_d' - a') - s_a * M_ankle,data  (data: plantarflexor +)
//! tether force (x)          = K_t (x_d - x) + C_t (x_d' - x')
//! support force (z, up)     = max(0, F_other + s_o * [ K_s (z_d - z) + C_s (z_d' - z') ])
//!   F_other = the data's other-foot ground reaction (`data`, the default when walking)
//!           | s_o * m_subject (g + z_d'')                          (`weight`, and a pose)
//! ```
//! `s_o` is the other leg's share of the support (from the gait events, `human::events`: 1 in
//! this leg's swing, 0 in its single support, the data's `grf_other / (grf_this + grf_other)`
//! between; `hip.other_leg_share` when set), `z_d` the hip height the data's angles imply on
//! this leg (see `reference::WalkingData`), `x_d` the pelvis's fore-aft target: over the
//! supporting foot as the data's angles move it, plus any belt-sweep difference
//! (`WalkingData::pelvis_x_at`). The other leg is a force on the pelvis, not a body; like a
//! leg it pushes and never pulls (without the clamp its damper pulled the pelvis down onto the
//! landing foot with up to 1.4 kN and doubled the heel-strike peak of a light subject).
//!
//! The other leg is virtual, so its ground reaction is the data's on the data's clock (its
//! events are the data's); the spring and damper, scaled by the share the events give, only
//! hold the hip near the height this leg reaches. `weight` moves the body along `z_d` instead
//! (`m_subject (g + z_d'')`); `z_d` is geometry (this leg's reach at the data's angles, with
//! kinks where the supporting foot changes), and its second derivative is not the body's: up
//! to 2.5 body weights just before heel strike, a landing 0-5 % of the stride late and half the
//! loading-response extensor moment on held-out subjects (README, "Walking for anyone").

use crate::reference::WalkingSample;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// How the thigh is held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HipMode {
    /// Welded at the origin (bench tests of the knee).
    Fixed,
    /// A kinematic hip joint that follows the trial's hip angle exactly (hanging leg).
    Driven,
    /// A pelvis free in x and z on a carriage, a dynamic hip hinge (loaded walking, standing).
    Carriage,
}

impl HipMode {
    /// The name in scenario files.
    pub fn as_str(&self) -> &'static str {
        match self {
            HipMode::Fixed => "fixed",
            HipMode::Driven => "driven",
            HipMode::Carriage => "carriage",
        }
    }
}

/// `[hip]`: the thigh's mount and, on the carriage, the body it carries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HipParams {
    /// `fixed`, `driven` or `carriage`. Default: `driven` for gait references, else `fixed`.
    pub mode: Option<HipMode>,
    /// The subject's mass (kg): scales the data's moments and ground reaction. Default
    /// `subject.mass_kg`, else 75 (the built-in URDFs' male subject). 2..=650.
    pub subject_mass_kg: Option<f64>,
    /// Mass the pelvis carries (kg): the trunk, arms, head and the other leg. Default: the
    /// subject's mass minus this leg's (URDF links other than the cylinder). > 0.
    pub body_mass_kg: Option<f64>,
    /// Anterior pelvic tilt (deg), constant: the data's hip flexion is measured from the
    /// pelvis, which leans forward in walking; the carriage's pelvis stays upright, so the
    /// thigh follows the hip flexion minus the tilt. Default: the gait data's own
    /// `pelvis_tilt_deg` column over the cycle when it has one (every shipped trial does),
    /// else 10 (typical in adult walking); `summary.json` (`walking_assumptions`) says which.
    /// Setting it overrides the data's column. -30..=45.
    pub pelvic_tilt_deg: Option<f64>,
    /// Hip spring about the data's angle (N m/rad). Default 500 (about 7 N m/rad per kg of a
    /// 75 kg subject): compliant. A stiffly held hip fixes the pelvis's path over the foot, so
    /// the foot is dragged against the belt and the stance knee moment loses its shape (on
    /// `gait_treadmill.toml`, 3000 N m/rad with 100 N m s/rad: correlation with the data
    /// -0.43 instead of 0.79). >= 0.
    pub stiffness_nm_per_rad: f64,
    /// Hip damper (N m s/rad). Default 30 (100 already drags the foot: correlation 0.40). >= 0.
    pub damping_nm_s_per_rad: f64,
    /// Share of the data's hip moment applied across the hip (0..=1). Default 1.
    pub moment_share: f64,
    /// The hip is locked at its initial angle (static tests). Default false.
    pub locked: bool,
    /// Horizontal tether of the pelvis to its fore-aft target (N/m): its start, moving back and
    /// forth when the belt and the leg's stance sweep differ (`BodySetup::pelvis_drift_m_s`).
    /// Default 1000 (0.65 Hz with 60 kg). A weaker tether lets the compliant hip yield to a
    /// belt faster than the leg sweeps instead of the pelvis following the foot: at 200 N/m
    /// and 300 N s/m, 8 of the 18 shipped treadmill trials with the belt 10-20 % off the sweep
    /// lost the stance knee moment (its terminal-stance flexor peak shrinks with the
    /// mismatch); at 1000 / 1000 none. >= 0.
    pub tether_stiffness_n_per_m: f64,
    /// Tether damper (N s/m). Default 1000 (about 2 times critical with 60 kg). >= 0.
    pub tether_damping_n_s_per_m: f64,
    /// The pelvis cannot move horizontally (static tests). Default false.
    pub tether_locked: bool,
    /// The virtual other leg's spring toward the data's hip height (N/m), scaled by its
    /// share. Default 20000 (stiffer springs force the data's height on a leg whose geometry
    /// differs from the subject's, and the stance ground reaction loses its shape). >= 0.
    pub support_stiffness_n_per_m: f64,
    /// The virtual other leg's damper (N s/m), scaled by its share. Default 3000 (1.4 times
    /// critical with 60 kg on the default spring, 1.6 with 45 kg). More damping slows the
    /// spring's slow pole (`K/C`: 0.3 s at 6000) so far that a pelvis that sank in one stance
    /// is not back at the data's height by the next heel strike, and a light subject's pelvis
    /// sank stride after stride into a dragged leg. >= 0.
    pub support_damping_n_s_per_m: f64,
    /// What the virtual other leg carries besides its spring: `data` (the other foot's ground
    /// reaction in the data, on the data's clock: the body's vertical dynamics as the data
    /// measured them) or `weight` (its share of the subject's weight and of the force that
    /// moves the body along the hip height the data's angles imply). Default: `data` when
    /// walking along gait data, `weight` for a pose (the same force there). The hip height
    /// the angles imply has kinks where the supporting foot changes and dips in double support
    /// (on the model's toeless foot the terminal-stance reach is short): its second
    /// derivative reached 10-27 m/s^2, and `weight` pushed up to 2.5 body weights just before
    /// heel strike, delaying the landing (README, "Walking for anyone").
    pub support_force: Option<SupportForce>,
    /// A constant share of the support for the other leg (0..=1) instead of the data's phase
    /// (standing: 0.5 on two legs). Default: the data's; 0.5 for the pose reference.
    pub other_leg_share: Option<f64>,
    /// Height of the sole above the ground at the start (m). Default 0.002. 0..=0.5.
    pub initial_clearance_m: f64,
}

/// The subject's mass when neither `hip.subject_mass_kg` nor `subject.mass_kg` gives it (kg).
pub const DEFAULT_SUBJECT_MASS_KG: f64 = 75.0;

impl HipParams {
    /// The subject's mass (kg): `subject_mass_kg` (the scenario fills it from `[subject]` at
    /// resolve), else [`DEFAULT_SUBJECT_MASS_KG`].
    pub fn subject_mass(&self) -> f64 {
        self.subject_mass_kg.unwrap_or(DEFAULT_SUBJECT_MASS_KG)
    }
}

impl Default for HipParams {
    fn default() -> Self {
        Self {
            mode: None,
            subject_mass_kg: None,
            body_mass_kg: None,
            pelvic_tilt_deg: None,
            stiffness_nm_per_rad: 500.0,
            damping_nm_s_per_rad: 30.0,
            moment_share: 1.0,
            locked: false,
            tether_stiffness_n_per_m: 1000.0,
            tether_damping_n_s_per_m: 1000.0,
            tether_locked: false,
            support_stiffness_n_per_m: 20000.0,
            support_damping_n_s_per_m: 3000.0,
            other_leg_share: None,
            support_force: None,
            initial_clearance_m: 0.002,
        }
    }
}

/// The force the virtual other leg carries (see [`HipParams::support_force`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SupportForce {
    /// Its share of the subject's weight and vertical motion, `m_subject (g + z_d'')`.
    Weight,
    /// The other foot's data ground reaction.
    Data,
}

/// `[wearer]`: the wearer's own knee and ankle, as impedances about the data's angles.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WearerParams {
    /// Knee stiffness about the data's angle (N m/rad). Default 1000. >= 0.
    pub knee_stiffness_nm_per_rad: f64,
    /// Knee damping (N m s/rad). Default 20. >= 0.
    pub knee_damping_nm_s_per_rad: f64,
    /// Share of the data's knee moment the wearer produces (0..=1). Default 0: the stance
    /// knee moment then comes from the impedance and the exoskeleton only.
    pub knee_moment_share: f64,
    /// Ankle stiffness (N m/rad). Default 300. >= 0.
    pub ankle_stiffness_nm_per_rad: f64,
    /// Ankle damping (N m s/rad). Default 5. >= 0.
    pub ankle_damping_nm_s_per_rad: f64,
    /// Share of the data's ankle moment the wearer produces (0..=1). Default 1 (push-off).
    pub ankle_moment_share: f64,
    /// Analyse the wearer's muscles (issue 39; walking runs on the carriage): each sample,
    /// static optimisation of the hip, knee and ankle moments the wearer applies among the
    /// leg's muscles, and their metabolic rate (`summary.json` `wearer.metabolics`). It
    /// changes no dynamics. Default false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub muscles: bool,
    /// A muscle table made by `scripts/opensim-muscles` from an OpenSim model (a path,
    /// relative to the scenario's folder). Default: the embedded 2D_gait (`assets/muscles/2d_gait.toml`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub muscles_file: Option<String>,
    /// What static optimisation minimises: `"activation_squared"` (default) or `"metabolic"`
    /// (the muscles' metabolic rate, a local minimum).
    #[serde(skip_serializing_if = "is_default")]
    pub muscle_cost: crate::muscles::analysis::MuscleCost,
    /// The metabolic model: `"umberger2010"` (default, Umberger et al. 2003/2010 as published)
    /// or `"bhargava2004"`.
    #[serde(skip_serializing_if = "is_default")]
    pub metabolic_model: crate::muscles::metabolics::MetabolicModel,
    /// The joint reserves' optimal moment (N m): a reserve costs `(R / this)^2`, as much as a
    /// muscle at full activation per this many N m. Default 1 (OpenSim's reserve actuators).
    /// 0.01..=1000.
    #[serde(skip_serializing_if = "is_one")]
    pub reserve_optimal_moment_nm: f64,
    /// Who makes the wearer's knee, ankle and hip moments (issue 40): `"impedance"` (default:
    /// the spring-dampers about the data above) or `"muscles"` (the leg's muscles, driven by a
    /// nervous system with a neural delay through activation dynamics; `human::muscle_wearer`).
    #[serde(skip_serializing_if = "is_default")]
    pub model: WearerModel,
    /// The muscle wearer is used to the device: it asks its muscles for the gait's moments less
    /// the device's moment it feels (true, default); false: a new wearer who does not discount
    /// it.
    #[serde(skip_serializing_if = "is_true")]
    pub adapted: bool,
    /// The muscle wearer's neural delays (s): its feedback at the hip, the knee and the ankle
    /// sees the joints' deviation (and the knee the device's moment) this long ago. A number
    /// (every joint) or `[hip, knee, ankle]`. Default [0.005, 0.010, 0.020]: the neural
    /// transmission delays of Geyer and Herr's (2010) reflex walking model; the stretch
    /// reflexes measured in walking people start later (soleus 42 ms, Sinkjaer et al. 1996),
    /// and with those this wearer does not hold the gait (README, "A wearer as strong and as
    /// slow as a person"). Static optimisation knows each muscle its group's delay late: a
    /// muscle spanning the hip the hip's (the hamstrings and rectus femoris too), else one
    /// spanning the ankle the ankle's (the gastrocnemius), else the knee's. Each 0..=0.3.
    #[serde(skip_serializing_if = "is_default")]
    pub neural_delay_s: NeuralDelay,
    /// The muscle wearer's feedback stiffness in stance about the gait it learned, hip, knee
    /// and ankle (N m/rad per kg of the subject). Default [0.7, 2.0, 3.0]: the joint
    /// stiffness of walking people in stance (knee quasi-stiffness in weight acceptance, a
    /// few N m/rad/kg, Shamaei et al. 2013; ankle 1.1-5.4 N m/rad/kg over stance, Lee and
    /// Rouse, the default 3.0 near the middle: 2 to 4 keep 19-21 of v3's 21 trials; hip as
    /// in swing). Blended with the swing gains by the data's stance weight.
    /// Each 0..=50.
    #[serde(skip_serializing_if = "is_default_stance_stiffness")]
    pub stance_stiffness_nm_per_rad_kg: [f64; 3],
    /// Its feedback stiffness in swing (N m/rad/kg). Default [0.7, 0.3, 0.32]. van der
    /// Kooij et al. (2022) measured hip 34-66, knee 0-3.5 and ankle 2.5-24 N m/rad in swing
    /// at 0.5 m/s; the hip's is taken as measured; the ankle's is their upper value (24 N m/rad
    /// for a 75 kg person); the knee's, 22 N m/rad at 75 kg, is above their slow-walking range
    /// because a swing knee left nearly free by a wearer that sees it 10 ms late does not hold
    /// the gait (at 0.05 N m/rad/kg, 14 of v3's 21 trials walk with the cylinder free, 20 with
    /// the device; at 0.3, 21 and 20). Each 0..=50.
    #[serde(skip_serializing_if = "is_default_swing_stiffness")]
    pub swing_stiffness_nm_per_rad_kg: [f64; 3],
    /// Its feedback damping in stance (N m s/rad/kg). Default [0.045, 0.03, 0.03] (ankle
    /// 0.016-0.08 N m s/rad/kg, Lee and Rouse; the knee taken alike). Each 0..=5.
    #[serde(skip_serializing_if = "is_default_stance_damping")]
    pub stance_damping_nm_s_per_rad_kg: [f64; 3],
    /// Its feedback damping in swing (N m s/rad/kg). Default [0.045, 0.0015, 0.015] (hip
    /// 1.9-4.6, knee 0.02-0.14, ankle 0.2-2.4 N m s/rad, van der Kooij et al. 2022). Each
    /// 0..=5.
    #[serde(skip_serializing_if = "is_default_swing_damping")]
    pub swing_damping_nm_s_per_rad_kg: [f64; 3],
}

/// Who makes the wearer's joint moments (`wearer.model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum WearerModel {
    /// Spring-dampers about the data's angles plus shares of the data's moments.
    #[default]
    Impedance,
    /// The leg's muscles under a delayed nervous system.
    Muscles,
}

/// Default `wearer.neural_delay_s` (hip, knee, ankle; s).
pub const DEFAULT_NEURAL_DELAY_S: [f64; 3] = [0.005, 0.010, 0.020];

/// `wearer.neural_delay_s`: one delay for every joint or one per joint (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum NeuralDelay {
    /// The same delay at the hip, the knee and the ankle.
    All(f64),
    /// Hip, knee, ankle.
    PerJoint([f64; 3]),
}

impl Default for NeuralDelay {
    fn default() -> Self {
        Self::PerJoint(DEFAULT_NEURAL_DELAY_S)
    }
}

impl NeuralDelay {
    /// Hip, knee and ankle delays (s).
    pub fn per_joint(&self) -> [f64; 3] {
        match *self {
            Self::All(d) => [d; 3],
            Self::PerJoint(d) => d,
        }
    }
}
/// Default `wearer.stance_stiffness_nm_per_rad_kg` (hip, knee, ankle).
pub const DEFAULT_STANCE_STIFFNESS: [f64; 3] = [0.7, 2.0, 3.0];
/// Default `wearer.swing_stiffness_nm_per_rad_kg` (hip, knee, ankle).
pub const DEFAULT_SWING_STIFFNESS: [f64; 3] = [0.7, 0.3, 0.32];
/// Default `wearer.stance_damping_nm_s_per_rad_kg` (hip, knee, ankle).
pub const DEFAULT_STANCE_DAMPING: [f64; 3] = [0.045, 0.03, 0.03];
/// Default `wearer.swing_damping_nm_s_per_rad_kg` (hip, knee, ankle).
pub const DEFAULT_SWING_DAMPING: [f64; 3] = [0.045, 0.0015, 0.015];

fn is_true(v: &bool) -> bool {
    *v
}

fn is_default_stance_stiffness(v: &[f64; 3]) -> bool {
    *v == DEFAULT_STANCE_STIFFNESS
}

fn is_default_swing_stiffness(v: &[f64; 3]) -> bool {
    *v == DEFAULT_SWING_STIFFNESS
}

fn is_default_stance_damping(v: &[f64; 3]) -> bool {
    *v == DEFAULT_STANCE_DAMPING
}

fn is_default_swing_damping(v: &[f64; 3]) -> bool {
    *v == DEFAULT_SWING_DAMPING
}

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

impl Default for WearerParams {
    fn default() -> Self {
        Self {
            knee_stiffness_nm_per_rad: 1000.0,
            knee_damping_nm_s_per_rad: 20.0,
            knee_moment_share: 0.0,
            ankle_stiffness_nm_per_rad: 300.0,
            ankle_damping_nm_s_per_rad: 5.0,
            ankle_moment_share: 1.0,
            muscles: false,
            muscles_file: None,
            muscle_cost: Default::default(),
            metabolic_model: Default::default(),
            reserve_optimal_moment_nm: 1.0,
            model: WearerModel::Impedance,
            adapted: true,
            neural_delay_s: NeuralDelay::default(),
            stance_stiffness_nm_per_rad_kg: DEFAULT_STANCE_STIFFNESS,
            swing_stiffness_nm_per_rad_kg: DEFAULT_SWING_STIFFNESS,
            stance_damping_nm_s_per_rad_kg: DEFAULT_STANCE_DAMPING,
            swing_damping_nm_s_per_rad_kg: DEFAULT_SWING_DAMPING,
        }
    }
}

/// The state of the body the force laws read (rad, rad/s, m, m/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyState {
    /// Hip flexion and rate.
    pub hip: (f64, f64),
    /// Knee flexion and rate.
    pub knee: (f64, f64),
    /// Ankle dorsiflexion and rate.
    pub ankle: (f64, f64),
    /// Pelvis displacement from its start (x) and height above the ground (z), m.
    pub pelvis: [f64; 2],
    /// Pelvis velocity (x, z), m/s.
    pub pelvis_rate: [f64; 2],
}

/// What the body applies over one step (N m, N).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyForces {
    /// Across the hip (flexion +).
    pub hip_torque_nm: f64,
    /// The wearer's knee (flexion +).
    pub knee_torque_nm: f64,
    /// The wearer's ankle (dorsiflexion +).
    pub ankle_torque_nm: f64,
    /// Tether (x) and support (z) on the pelvis.
    pub pelvis_force_n: [f64; 2],
    /// An ideal device's torque at the knee (flexion +; `controller.kind = "ideal_moment"`):
    /// not the wearer's, applied beside it.
    pub device_knee_torque_nm: f64,
}

/// The body's force laws at data sample `d` and state `s` (see the module's table).
pub fn body_forces(hip: &HipParams, wearer: &WearerParams, d: &WalkingSample, s: &BodyState) -> BodyForces {
    let imp = |k: f64, c: f64, target: &crate::reference::RefSample, (q, qd): (f64, f64)| {
        k * (target.value - q) + c * (target.rate - qd)
    };
    let share = hip.other_leg_share.unwrap_or(d.other_share);
    let base = match hip.support_force.unwrap_or(SupportForce::Data) {
        SupportForce::Weight => share * hip.subject_mass() * (crate::leg::model::GRAVITY_M_S2 + d.pelvis_accel_m_s2),
        SupportForce::Data => d.grf_other_n,
    };
    let support = base
        + share
            * (hip.support_stiffness_n_per_m * (d.pelvis_height_m - s.pelvis[1])
                + hip.support_damping_n_s_per_m * (d.pelvis_rate_m_s - s.pelvis_rate[1]));
    let tether = hip.tether_stiffness_n_per_m * (d.pelvis_x_m - s.pelvis[0])
        + hip.tether_damping_n_s_per_m * (d.pelvis_x_rate_m_s - s.pelvis_rate[0]);
    BodyForces {
        hip_torque_nm: imp(hip.stiffness_nm_per_rad, hip.damping_nm_s_per_rad, &d.hip, s.hip)
            + hip.moment_share * d.hip_moment_nm,
        knee_torque_nm: imp(wearer.knee_stiffness_nm_per_rad, wearer.knee_damping_nm_s_per_rad, &d.knee, s.knee)
            - wearer.knee_moment_share * d.knee_moment_nm,
        ankle_torque_nm: imp(wearer.ankle_stiffness_nm_per_rad, wearer.ankle_damping_nm_s_per_rad, &d.ankle, s.ankle)
            - wearer.ankle_moment_share * d.ankle_moment_nm,
        pelvis_force_n: [tether, support.max(0.0)],
        device_knee_torque_nm: 0.0,
    }
}

/// What the body does on the carriage: the data it follows.
#[derive(Debug, Clone)]
pub enum BodyTargets {
    /// Loaded walking along a gait cycle.
    Walking(Arc<crate::reference::WalkingData>),
    /// A constant pose (standing).
    Pose(crate::reference::WalkingSample),
}

impl BodyTargets {
    /// The targets at `t_s`.
    pub fn at(&self, t_s: f64) -> crate::reference::WalkingSample {
        match self {
            BodyTargets::Walking(w) => w.at(t_s),
            BodyTargets::Pose(p) => *p,
        }
    }
}

/// The body on the pelvis carriage, resolved.
#[derive(Debug, Clone)]
pub struct BodySetup {
    /// `[hip]` settings.
    pub hip: HipParams,
    /// `[wearer]` settings.
    pub wearer: WearerParams,
    /// What the body follows.
    pub targets: BodyTargets,
    /// Mass the pelvis carries (kg).
    pub pelvis_mass_kg: f64,
    /// How much faster the belt runs than the leg's stance sweeps at the data's angles (m/s;
    /// 0 at the default belt speed): the pelvis's fore-aft target carries the difference
    /// (`WalkingData::pelvis_x_at`).
    pub pelvis_drift_m_s: f64,
    /// Initial ankle dorsiflexion (rad).
    pub ankle_rad: f64,
}
