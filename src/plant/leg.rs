//! The URDF leg in Rapier as a plant of the co-simulation loop.

use super::{PistonMotion, PistonPredictor, PistonTrack, Plant, PlantInputs};
use crate::error::{Error, Result};
use crate::human::{BodyForces, BodyState};
use crate::leg::{
    generalized_inertia_at, knee_forward_acceleration, moment_arm_at, moment_arm_slope_at, CarriageConfig, Leg,
    LegError, LegForces, LegSolverParams, LegSpec, Mount,
};
use crate::record::{ContactRow, LegRow};
use crate::sensors::{FootLoad, LegKinematics};
use rapier3d_f64::glamx::DVec3;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Leg parameters (scenario section `[leg]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LegParams {
    /// URDF file with the `<loop_closure>` and `<hydraulic_actuator>` elements, or
    /// `builtin:exo_leg` (default) / `builtin:exo_leg_small`. A relative path is looked up next
    /// to the scenario file first, then in the working directory.
    pub urdf: String,
    /// Name of the knee joint in the URDF. Default `knee`.
    pub knee_joint: String,
    /// Initial knee flexion (deg), leg at rest. Default: the gait reference's angle at t = 0,
    /// or 30 deg for other references.
    pub initial_knee_deg: Option<f64>,
    /// Rapier solver iterations (TGS substeps) per step. Default 2 (see README, "Leg solver"). 1..=64.
    pub solver_iterations: usize,
    /// SHA-256 of the URDF's content; filled in by every run (see `summary.json`). When set,
    /// a run warns if the file has changed since.
    pub urdf_sha256: Option<String>,
    /// Name of the ankle joint in the URDF (it moves when `ground.enabled`; otherwise it is
    /// locked at 0). Default `ankle`.
    pub ankle_joint: String,
    /// Every link's mass and inertia scaled by this factor (the plant's leg; the controller's
    /// cascade uses `controller.nominal_leg`). Default 1. 0.2..=5.
    pub mass_scale: f64,
    /// `rapier` (default: any URDF, rigid or compliant contact) or `reduced` (planar legs,
    /// integrated with the hydraulics and the controller in one ODE: the closed chain in its
    /// knee coordinate with the thigh fixed or driven, the five-coordinate walking leg with the
    /// compliant sole on the carriage; see README, "Speed").
    pub engine: LegEngine,
}

/// The mechanics engine of the leg.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LegEngine {
    /// Rapier's multibody with the loop-closure joint.
    #[default]
    Rapier,
    /// The reduced-coordinate engine.
    Reduced,
}

impl LegEngine {
    /// The name in scenarios and summaries.
    pub fn as_str(&self) -> &'static str {
        match self {
            LegEngine::Rapier => "rapier",
            LegEngine::Reduced => "reduced",
        }
    }
}

/// `[ground]`: a flat ground, or a treadmill belt, under the foot (leg plant).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GroundParams {
    /// Ground contact on (the URDF's `<collision>` shapes become Rapier colliders and the
    /// ankle moves). Default false.
    pub enabled: bool,
    /// Height of the ground (m, world z; the hip starts at z = 0 when fixed or driven, and
    /// `ground.height_m` + the data's hip height on the carriage). Default: where the sole
    /// touches at the start (carriage) or the lowest sole point over the gait cycle (driven).
    /// Must be below the hip.
    pub height_m: Option<f64>,
    /// Coulomb friction coefficient, sole on ground (-). Default 0.8. 0..=5.
    pub friction: f64,
    /// Belt speed (m/s, the surface moving to -x under a person facing +x). Default: the
    /// speed the data's stance implies (gait on the carriage), else 0. -10..=10.
    pub belt_speed_m_s: Option<f64>,
    /// Natural frequency of Rapier's soft contact constraint (Hz): stiffer contacts penetrate
    /// less (about 0.2 mm under a 75 kg body at 200 Hz; Rapier's regularisation is implicit,
    /// so any value is stable). Default 200. 1..=1000.
    pub contact_frequency_hz: f64,
    /// Damping ratio of the contact constraint (-). Default 1. 0..=20.
    pub contact_damping_ratio: f64,
    /// The sole's contact law: `"compliant"` (default: Hunt-Crossley spheres, a heel strike
    /// spread over milliseconds as a heel pad does) or `"rigid"` (Rapier's contact constraint,
    /// `contact_frequency_hz`: a heel strike within a step). README, "Ground contact".
    pub contact: ContactLaw,
    /// Compliant law: contact modulus E (N/m^2) of `0.4714 E sqrt(R) x^1.5`. Default 1e7 (a
    /// 35 mm heel sphere sinks 9 mm under one 75 kg body weight). 1e4..=1e11.
    pub contact_modulus_pa: f64,
    /// Compliant law: Hunt-Crossley dissipation c (s/m). Default 2 (OpenSim gait models).
    /// 0..=50.
    pub contact_dissipation_s_per_m: f64,
    /// Compliant law: stiffness of each contact point's friction anchor spring (N/m).
    /// Default 1e5 (1.5 mm of stretch at 150 N). 1e3..=1e8.
    pub friction_stiffness_n_per_m: f64,
}

/// `ground.contact`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ContactLaw {
    /// Hunt-Crossley spheres with an anchor-spring friction (explicit forces).
    #[default]
    Compliant,
    /// Rapier's contact constraint on the URDF's collision shapes.
    Rigid,
}

impl Default for GroundParams {
    fn default() -> Self {
        Self {
            enabled: false,
            height_m: None,
            friction: 0.8,
            belt_speed_m_s: None,
            contact_frequency_hz: 200.0,
            contact_damping_ratio: 1.0,
            contact: ContactLaw::Compliant,
            contact_modulus_pa: 1e7,
            contact_dissipation_s_per_m: 2.0,
            friction_stiffness_n_per_m: 1e5,
        }
    }
}

impl Default for LegParams {
    fn default() -> Self {
        Self {
            urdf: "builtin:exo_leg".into(),
            knee_joint: "knee".into(),
            initial_knee_deg: None,
            solver_iterations: LegSolverParams::default().solver_iterations,
            urdf_sha256: None,
            ankle_joint: "ankle".into(),
            mass_scale: 1.0,
            engine: LegEngine::Rapier,
        }
    }
}

/// Check a cuff point against the model before anything is built: the cuff link must be the
/// shank or a link fixed to it, and the point must not lie on the knee axis. Returns the point
/// in the shank frame (m).
pub fn cuff_point_from_model(model: &LegSpec, link_name: &str, xyz: [f64; 3]) -> std::result::Result<[f64; 3], String> {
    let link = model.link_index(link_name).ok_or_else(|| format!("no link `{link_name}` in the URDF"))?;
    let shank = model.knee_joint().child;
    let (mut cur, mut p) = (link, DVec3::from(xyz));
    while cur != shank {
        let j = model.joints().iter().find(|j| j.child == cur && j.kind == crate::leg::JointKind::Fixed).ok_or_else(
            || format!("`{link_name}` is not the shank (`{}`) or a link fixed to it", model.links()[shank].name),
        )?;
        p = crate::leg::joint_origin_pose(j) * p;
        cur = j.parent;
    }
    let axis = DVec3::from(model.knee_joint().axis).normalize();
    if p.cross(axis).length() < 1e-3 {
        return Err(format!("the cuff point {xyz:?} of `{link_name}` lies on the knee axis: it cannot move the knee"));
    }
    Ok(p.into())
}

/// Initial state of the leg: knee angle and rate, and the hip trajectory sample at t = 0 when
/// the hip is driven (`None`: thigh fixed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegStart {
    /// Knee flexion (rad).
    pub knee_rad: f64,
    /// Knee rate (rad/s).
    pub knee_rate_rad_s: f64,
    /// Hip angle, rate, acceleration at t = 0 (rad, rad/s, rad/s^2), when driven.
    pub hip: Option<crate::reference::RefSample>,
}

/// Effective mass at the cylinder, `M(theta) / (dL/dtheta)^2` (kg), tabulated over the knee
/// range (401 points) once per leg model and shared by every run that uses it.
#[derive(Debug, Clone, PartialEq)]
pub struct MassTable {
    lo_rad: f64,
    step_rad: f64,
    kg: Vec<f64>,
}

impl MassTable {
    /// Tabulate the effective mass of a leg model over its knee range.
    pub fn new(model: &LegSpec) -> std::result::Result<Self, LegError> {
        let (lo, hi) = model.knee_range_rad();
        let n = 400;
        let step = (hi - lo) / n as f64;
        let kg = (0..=n)
            .map(|i| {
                let q = lo + i as f64 * step;
                let m = generalized_inertia_at(model, q)?;
                let arm = moment_arm_at(model, q);
                Ok(m / (arm * arm))
            })
            .collect::<std::result::Result<Vec<f64>, LegError>>()?;
        Ok(Self { lo_rad: lo, step_rad: step, kg })
    }

    /// Effective mass (kg) at knee angle `q` (rad): linear interpolation, clamped to the
    /// table's range.
    pub fn at(&self, q: f64) -> f64 {
        let u = ((q - self.lo_rad) / self.step_rad).clamp(0.0, (self.kg.len() - 1) as f64);
        let i = (u.floor() as usize).min(self.kg.len() - 2);
        let f = u - i as f64;
        self.kg[i] * (1.0 - f) + self.kg[i + 1] * f
    }
}

/// Everything needed to build the leg plant of a run, resolved and validated once.
#[derive(Debug, Clone)]
pub struct LegSetup {
    /// The leg model (shared).
    pub model: Arc<LegSpec>,
    /// Its effective-mass table (shared).
    pub mass: Arc<MassTable>,
    /// Initial state.
    pub start: LegStart,
    /// Rapier solver iterations (TGS substeps) per step.
    pub solver_iterations: usize,
    /// The cuff point in the shank's frame (m), resolved from `human.cuff_link` and
    /// `human.cuff_xyz` once.
    pub cuff_point_m: [f64; 3],
    /// The thigh and shank cuffs' lever arms about the knee axis (m): the sagittal distance
    /// from the knee centre to the thigh cuff (`human.thigh_cuff_xyz`) and to the shank cuff.
    pub cuff_lever_m: (f64, f64),
    /// The run starts on its gait trajectory (knee angle and rate from the reference).
    pub start_on_trajectory: bool,
    /// The ground, when contact is on.
    pub ground: Option<crate::leg::GroundConfig>,
    /// The body on the pelvis carriage (`hip.mode = "carriage"`).
    pub body: Option<Arc<crate::human::BodySetup>>,
    /// The reduced-coordinate model when `leg.engine = "reduced"` (the knee-only engine).
    pub reduced: Option<Arc<crate::leg::ReducedModel>>,
    /// The reduced engine's walking leg when `leg.engine = "reduced"` on the carriage.
    pub walker: Option<Arc<crate::leg::WalkerModel>>,
    /// The end stops: the knee's limits, the stroke ends, the moving ankle's limits.
    pub stops: crate::leg::EndStops,
}

/// The Rapier leg of a setup: welded, on a driven hip, or on the carriage, with the ground
/// when contact is on.
fn build_leg(setup: &LegSetup, dt_s: f64, params: LegSolverParams) -> std::result::Result<Leg, LegError> {
    let (model, q0) = (&setup.model, setup.start.knee_rad);
    let ground = setup.ground.as_ref();
    let mount = match (&setup.body, &setup.start.hip) {
        (Some(b), _) => {
            let d = b.targets.at(0.0);
            Mount::Carriage(CarriageConfig {
                pelvis_mass_kg: b.pelvis_mass_kg,
                hip_rad: d.hip.value,
                pelvis_height_m: ground.map_or(0.0, |g| g.height_m) + d.pelvis_height_m + b.hip.initial_clearance_m,
                tether_locked: b.hip.tether_locked,
                hip_locked: b.hip.locked,
                ankle_rad: b.ankle_rad,
            })
        }
        (None, None) => Mount::Fixed,
        // The kinematic hip joint's velocity is its average over a step; the velocity it
        // had over the step before t = 0 is rate - accel*dt/2, so the first step sees the
        // hip acceleration the trajectory has.
        (None, Some(h)) => Mount::Driven { hip_rad: h.value, hip_vel_rad_s: h.rate - 0.5 * h.accel * dt_s },
    };
    let leg = match (mount, ground) {
        (Mount::Fixed, None) => Leg::with_params(model, q0, dt_s, params)?,
        (Mount::Driven { hip_rad, hip_vel_rad_s }, None) => {
            Leg::with_hip(model, q0, hip_rad, hip_vel_rad_s, dt_s, params)?
        }
        (m, g) => Leg::with_config(model, q0, m, dt_s, params, g)?,
    };
    Ok(leg)
}

/// The leg plant: Rapier multibody leg with the hydraulic cylinder in a closed loop.
///
/// Coupling (explicit co-simulation with a force-aware predictor): inside a step the loop
/// integrates the piston as `xc_ddot = a_free + F_cyl(tau)/m_eff`, with `m_eff(theta) =
/// M(theta)/(dL/dtheta)^2` from the URDF's reduced closed-chain inertia and `a_free` the
/// part of the last step's measured piston acceleration not explained by the cylinder force
/// (gravity, velocity terms, human, hip). Rapier then advances under the step's
/// impulse-average cylinder force, and the loop corrects the load force by `-n2` times the
/// stroke the prediction missed, so the oil column's spring acts on the geometric change of
/// cylinder length exactly.
pub struct LegPlant {
    leg: Leg,
    model: Arc<LegSpec>,
    mass: Arc<MassTable>,
    /// The piston (velocity from Rapier's generalized velocity).
    piston: PistonTrack,
    cuff_point: [f64; 3],
    shank_link: usize,
    knee_axis: DVec3,
    max_gap_m: f64,
    /// dt/(2n) for Rapier's n TGS substeps (see [`PistonPredictor::velocity_lead_s`]).
    velocity_lead_s: f64,
    /// What the body on the carriage applied over the last step (the loop computes it).
    body: Option<BodyForces>,
    /// Ground height (m), with contact.
    ground_height_m: Option<f64>,
    /// Moment arm dL/dtheta (m/rad) at the present knee angle.
    arm_m: f64,
    /// The trajectory a driven hip follows (the force reference's hip).
    reference: crate::reference::ForceReference,
    /// The fixed step (s), also in Rapier's integration parameters.
    dt_s: f64,
    /// The end stops and what they did.
    stops: crate::leg::EndStops,
    report: crate::leg::StopReport,
}

/// The scenario key a leg build error belongs to: the start angle (given, or the gait's at
/// t = 0), the step, or the URDF.
fn build_error_key(setup: &LegSetup, e: &LegError) -> &'static str {
    match e {
        LegError::Unreachable { .. } if setup.start_on_trajectory => "reference.gait (the knee angle at t = 0)",
        LegError::Unreachable { .. } => "leg.initial_knee_deg",
        LegError::InvalidArgument(_) => "sim.dt_s",
        _ if setup.ground.is_some() => "leg.urdf (its collision shapes with ground.enabled)",
        _ => "leg.urdf",
    }
}

impl LegPlant {
    /// Build the plant from a resolved setup, stepped by `dt_s` (s); `reference` drives the
    /// hip when the setup's hip is driven. `source_name` names the scenario in errors.
    pub fn new(
        setup: &LegSetup,
        reference: crate::reference::ForceReference,
        dt_s: f64,
        source_name: &str,
    ) -> Result<Self> {
        let params = LegSolverParams { solver_iterations: setup.solver_iterations, ..Default::default() };
        let model = setup.model.clone();
        let (q0, qd0, hip) = (setup.start.knee_rad, setup.start.knee_rate_rad_s, setup.start.hip);
        let bad = |e: LegError| Error::input(source_name, build_error_key(setup, &e), e.to_string());
        let mut leg = build_leg(setup, dt_s, params).map_err(bad)?;
        if qd0 != 0.0 {
            leg.set_knee_velocity(qd0).map_err(bad)?;
        }
        let length0_m = leg.cylinder_length_m();
        let knee = model.knee_joint();
        let knee_axis = DVec3::from(knee.axis).normalize();
        let shank_link = knee.child;
        let cuff_point = setup.cuff_point_m;
        let mass = setup.mass.clone();
        // xc_ddot = dL/dq * q_ddot + d(dL/dq)/dq * q_dot^2, with no cylinder force.
        let arm = moment_arm_at(&model, q0);
        let darm = moment_arm_slope_at(&model, q0);
        let h = hip.map_or((0.0, 0.0, 0.0), |h| (h.value, h.rate, h.accel));
        let free_accel_m_s2 = arm * knee_forward_acceleration(&model, h, q0, qd0, 0.0).map_err(bad)? + darm * qd0 * qd0;
        Ok(Self {
            leg,
            model,
            mass,
            piston: PistonTrack::new(length0_m, arm * qd0, free_accel_m_s2),
            cuff_point,
            shank_link,
            knee_axis,
            max_gap_m: 0.0,
            velocity_lead_s: dt_s / (2.0 * setup.solver_iterations as f64),
            body: setup.body.as_ref().map(|_| BodyForces::default()),
            ground_height_m: setup.ground.map(|g| g.height_m),
            arm_m: arm,
            reference,
            dt_s,
            stops: setup.stops,
            report: crate::leg::StopReport::default(),
        })
    }

    /// The Rapier leg.
    pub fn leg(&self) -> &Leg {
        &self.leg
    }

    /// The leg model.
    pub fn model(&self) -> &LegSpec {
        &self.model
    }

    /// Largest loop-closure gap seen so far (m).
    pub fn max_loop_gap_m(&self) -> f64 {
        self.max_gap_m
    }

    /// The end stops' torques on the knee and the ankle (N m) over the coming step, from the
    /// state now (the knee's inertia M(q) = m_eff(q) (dL/dq)^2 with `m_eff_kg` at `q`).
    fn stop_torques(&self, q: f64, m_eff_kg: f64) -> (f64, f64) {
        let dt = self.dt_s;
        let inertia = m_eff_kg * self.arm_m * self.arm_m;
        // Rapier's substeps move velocity then position: q' = q + qd dt + a dt^2 (n + 1) / (2 n).
        let gain = 0.5 + self.velocity_lead_s / dt;
        let knee = self.stops.knee.torque(q, self.leg.knee_velocity_rad_s(), inertia, dt, gain);
        let ankle = self.stops.ankle.map_or(0.0, |a| {
            let (qa, qda) = (self.leg.ankle_angle_rad(), self.leg.ankle_velocity_rad_s());
            a.torque(qa, qda, self.stops.ankle_inertia_kg_m2, dt, gain)
        });
        (knee, ankle)
    }

    /// World force vector of magnitude `flexion_force_n` at the cuff, perpendicular to the
    /// shank in the sagittal plane, pointing where the cuff moves when the knee flexes.
    fn cuff_force_world(&self, flexion_force_n: f64) -> [f64; 3] {
        let pose = self.leg.link_pose(self.shank_link);
        let axis = pose.rotation * self.knee_axis;
        let r = pose.rotation * DVec3::from(self.cuff_point);
        let dir = axis.cross(r).normalize_or_zero();
        (dir * flexion_force_n).into()
    }
}

impl Plant for LegPlant {
    fn piston_at(&self, _t_s: f64) -> PistonMotion {
        self.piston.motion()
    }

    fn piston_predictor(&self) -> Option<PistonPredictor> {
        let (q, qd) = (self.leg.knee_angle_rad(), self.leg.knee_velocity_rad_s());
        let exempt = moment_arm_slope_at(&self.model, q) * qd * qd;
        Some(self.piston.predictor(self.mass.at(q), self.velocity_lead_s, exempt))
    }

    fn knee_rad(&self) -> f64 {
        self.leg.knee_angle_rad()
    }

    fn stop_report(&self) -> Option<crate::leg::StopReport> {
        Some(self.report)
    }

    fn body_state(&self) -> Option<BodyState> {
        self.body?;
        let leg = &self.leg;
        let (p, v) = leg.pelvis_state();
        Some(BodyState {
            hip: (leg.hip_angle_rad(), leg.hip_velocity_rad_s()),
            knee: (leg.knee_angle_rad(), leg.knee_velocity_rad_s()),
            ankle: (leg.ankle_angle_rad(), leg.ankle_velocity_rad_s()),
            pelvis: [p[0], p[1] - self.ground_height_m.unwrap_or(0.0)],
            pelvis_rate: v,
        })
    }

    fn knee_rate_rad_s(&self) -> f64 {
        self.leg.knee_velocity_rad_s()
    }

    fn advance(&mut self, t_s: f64, inputs: &PlantInputs<'_>) -> Result<f64> {
        let _timed = crate::profile::scope(crate::profile::Stage::Plant);
        let dt_s = self.dt_s;
        let q = self.leg.knee_angle_rad();
        // Interaction: positive w1 resists a lengthening surplus of the actuator, so it pushes
        // the knee the way that shortens the cylinder.
        let cuff = if inputs.cuff_force_n != 0.0 {
            let flex = -self.arm_m.signum() * inputs.cuff_force_n;
            Some((self.cuff_point, self.cuff_force_world(flex)))
        } else {
            None
        };
        let m_eff = self.mass.at(q);
        if let Some(h) = self.reference.hip_at(t_s + dt_s).map(|h| h.value) {
            self.leg.set_hip_target(h).map_err(|e| Error::Diverged {
                time_s: t_s,
                state: format!("hip_angle_rad ({e})"),
                value: h,
            })?;
        }
        let body = inputs.body.unwrap_or_default();
        if let Some(last) = self.body.as_mut() {
            *last = body;
        }
        let (knee_stop, ankle_stop) = self.stop_torques(q, m_eff);
        self.leg.step_with(&LegForces {
            actuator_force_n: inputs.cylinder_force_n,
            shank_force: cuff,
            hip_torque_nm: body.hip_torque_nm,
            knee_torque_nm: body.knee_torque_nm + body.device_knee_torque_nm + knee_stop,
            ankle_torque_nm: body.ankle_torque_nm + ankle_stop,
            pelvis_force_n: body.pelvis_force_n,
        });
        let ankle = self.stops.ankle.map(|_| self.leg.ankle_angle_rad());
        self.report.add(&self.stops, self.leg.knee_angle_rad(), ankle, dt_s);
        let dl = self.leg.cylinder_length_change_m();
        let q1 = self.leg.knee_angle_rad();
        self.arm_m = moment_arm_at(&self.model, q1);
        let v = self.arm_m * self.leg.knee_velocity_rad_s();
        self.piston.record(self.piston.length_m() + dl, v, inputs.cylinder_force_n, m_eff, dt_s);
        self.max_gap_m = self.max_gap_m.max(self.leg.loop_gap_m());
        if !q1.is_finite() || !self.piston.length_m().is_finite() || !v.is_finite() {
            return Err(Error::Diverged { time_s: t_s + dt_s, state: "knee_angle_rad".into(), value: q1 });
        }
        Ok(dl)
    }

    fn leg_kinematics(&self) -> Option<LegKinematics> {
        let knee = self.model.knee_joint();
        let foot = self.model.ankle_joint().map_or(knee.child, |a| a.child);
        let leg = &self.leg;
        Some(LegKinematics {
            hip: (leg.hip_angle_rad(), leg.hip_velocity_rad_s()),
            thigh: leg.link_planar_state(knee.parent),
            shank: leg.link_planar_state(knee.child),
            foot: leg.link_planar_state(foot),
        })
    }

    fn foot_load(&self) -> Option<FootLoad> {
        self.ground_height_m?;
        let c = self.leg.contact();
        let knee = self.model.knee_joint();
        let foot = self.model.ankle_joint().map_or(knee.child, |a| a.child);
        let cop_x_m = c.cop_m.map_or(0.0, |p| self.leg.link_planar_state(foot).to_local(p)[0]);
        Some(FootLoad { vertical_n: c.vertical_n, cop_x_m })
    }

    fn contact_row(&self) -> Option<ContactRow> {
        self.ground_height_m?;
        let c = self.leg.contact();
        let body = self.body.unwrap_or_default();
        let (p, _) = self.leg.pelvis_state();
        Some(ContactRow {
            ground_reaction_vertical_n: c.vertical_n,
            ground_reaction_horizontal_n: c.horizontal_n,
            contact_penetration_m: c.penetration_m,
            knee_moment_nm: self.leg.lab_knee_moment_nm(),
            ankle_angle_deg: self.leg.ankle_angle_rad().to_degrees(),
            pelvis_height_m: p[1] - self.ground_height_m.unwrap_or(0.0),
            pelvis_x_m: p[0],
            support_force_n: body.pelvis_force_n[1],
            wearer_knee_torque_nm: body.knee_torque_nm,
        })
    }

    fn leg_row(&self) -> Option<LegRow> {
        let q = self.leg.knee_angle_rad();
        Some(LegRow {
            knee_angle_deg: q.to_degrees(),
            knee_velocity_deg_s: self.leg.knee_velocity_rad_s().to_degrees(),
            hip_angle_deg: if self.leg.has_hip() { self.leg.hip_angle_rad().to_degrees() } else { 0.0 },
            cylinder_length_m: self.piston.length_m(),
            loop_closure_gap_m: self.leg.loop_gap_m(),
            moment_arm_m: self.arm_m,
        })
    }
}
