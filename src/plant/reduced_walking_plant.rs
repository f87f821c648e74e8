//! The walking leg on the reduced engine (`leg.engine = "reduced"` on the pelvis carriage, or
//! with the hip fixed or driven over the ground): the planar multibody of
//! [`crate::leg::reduced_walking_model`] as a plant. With the hydraulic actuator the loop
//! integrates its ten states in the same ODE as the hydraulics and the controller
//! ([`CoupledMechanics`]); with a prescribed force or none, the plant integrates them itself
//! (RK4 under the step's force, substepped as the loop would). The body's forces (hip,
//! wearer's knee and ankle, tether, support) are held over a step, as on the Rapier engine;
//! gravity, joint damping, the cylinder force, the compliant contact and the end stops are
//! evaluated at every stage.

use super::{
    CoupledMechanics, CoupledStage, LegSetup, PistonMotion, PistonPredictor, PistonTrack, Plant, PlantInputs,
    StageInputs, CONTACT_MARGIN,
};
use crate::error::{Error, Result};
use crate::human::{BodyForces, BodyState};
use crate::integrator::Integrator;
use crate::leg::geometry::cylinder_kinematics_at;
use crate::leg::planar::P2;
use crate::leg::reduced_walking_model::{
    Anchors, Applied, StartCache, StepStart, WalkerModel, ANKLE, HIP, KNEE, NG, NX, PX, PZ, STATE_NAMES,
};
use crate::record::{ContactRow, LegRow};
use crate::sensors::{FootLoad, LegKinematics};
use std::sync::Arc;

/// Most substeps of the plant's own integration (a prescribed or no actuator force), as the
/// loop allows its own.
const MAX_OWN_SUBSTEPS: usize = 1000;

/// The reduced engine's walking leg.
pub struct WalkerPlant {
    model: Arc<WalkerModel>,
    x: [f64; NX],
    anchors: Vec<Option<f64>>,
    piston: PistonTrack,
    now: StepStart,
    /// What the step's start computed that its first evaluation needs again.
    start_cache: StartCache,
    /// Start of the coming step (s) and its length (s).
    t_step_s: f64,
    dt_s: f64,
    /// The cuff point in the shank's frame (m) and the shank's link.
    cuff: (usize, P2),
    /// The end stops and what they did.
    stops: crate::leg::EndStops,
    /// The stops' dampers on the knee and the ankle over the coming step (N m s/rad).
    stop_c: (f64, f64),
    report: crate::leg::StopReport,
    /// The body's forces over the last step.
    body: BodyForces,
    ground_height_m: Option<f64>,
    lab_knee_moment_nm: f64,
    /// On the carriage (else the hip is fixed at the origin).
    carriage: bool,
    /// The trajectory a driven hip follows (the force reference's hip; None: not driven).
    driven_hip: Option<crate::reference::ForceReference>,
    /// The moment arm dL/dq (m/rad) at the knee now.
    arm_m: f64,
}

impl WalkerPlant {
    /// The plant of a resolved setup with its walking model (on the carriage, or with the hip
    /// fixed at the origin: held, or driven along `reference`'s hip when the setup's is),
    /// stepped by `dt_s` (s).
    pub fn new(
        setup: &LegSetup,
        model: Arc<WalkerModel>,
        reference: crate::reference::ForceReference,
        dt_s: f64,
    ) -> Result<Self> {
        let ground_height_m = setup.ground.map(|g| g.height_m);
        let mut x = [0.0; NX];
        match (&setup.body, setup.start.hip) {
            (Some(body), _) => {
                let d = body.targets.at(0.0);
                x[PZ] = ground_height_m.unwrap_or(0.0) + d.pelvis_height_m + body.hip.initial_clearance_m;
                x[HIP] = d.hip.value;
                x[ANKLE] = body.ankle_rad;
            }
            (None, Some(h)) => (x[HIP], x[NG + HIP]) = (h.value, h.rate),
            (None, None) => {}
        }
        x[KNEE] = setup.start.knee_rad;
        x[NG + KNEE] = setup.start.knee_rate_rad_s;
        let carriage = setup.body.is_some();
        let driven_hip = (!carriage && setup.start.hip.is_some()).then_some(reference);
        let (l, arm, _) = cylinder_kinematics_at(model.spec(), x[KNEE]);
        let knee = setup.model.knee_joint();
        let cuff = (knee.child, P2::new(setup.cuff_point_m[0], setup.cuff_point_m[2]));
        let mut plant = Self {
            anchors: vec![None; model.spheres().len()],
            x,
            piston: PistonTrack::new(l, arm * x[NG + KNEE], 0.0),
            now: StepStart::default(),
            start_cache: StartCache::default(),
            t_step_s: 0.0,
            dt_s,
            cuff,
            stops: setup.stops,
            stop_c: (0.0, 0.0),
            report: crate::leg::StopReport::default(),
            body: BodyForces::default(),
            ground_height_m,
            lab_knee_moment_nm: 0.0,
            carriage,
            driven_hip,
            arm_m: arm,
            model,
        };
        plant.start_step();
        // The free piston acceleration at rest in the record, as the knee-only engine gives it.
        let (x0, hip_accel_rad_s2) = plant.with_hip(0.0, &plant.x);
        let free = plant.piston_accel(&x0, &Applied { hip_accel_rad_s2, ..Default::default() }, 0.0);
        plant.piston = PistonTrack::new(l, arm * x[NG + KNEE], free);
        Ok(plant)
    }

    /// The start of a step at the state now: the friction anchors, what the ground does, the
    /// knee's compliance, the segments' momenta, and the end stops over the step.
    ///
    /// The stops are spring-dampers evaluated at every stage (`StopRange::spring_damper`; the
    /// Rapier and knee-only engines hold a linearly implicit torque over the step instead),
    /// critically damped with the joint's inertia with the other coordinates held (`M_kk`, as
    /// Rapier's take the chain's M(q)). Near a stop (within 2 steps' travel or 0.01 rad) their
    /// stiffness joins the contact's in the loop's substeps. A held torque computed for the
    /// joint's own inertia was too soft where the foot carries the body: 3.4 deg into the knee's
    /// lower stop under a 650 kg subject at 1 ms.
    fn start_step(&mut self) {
        let m = &self.model;
        self.now = m.step_start_into(&self.x, &mut self.anchors, &mut self.start_cache);
        let (q, qd) = (self.x[KNEE], self.x[NG + KNEE]);
        let k = crate::leg::stops::STOP_STIFFNESS_NM_PER_RAD;
        let zeta = crate::leg::stops::STOP_DAMPING_RATIO;
        let damper = |inertia: f64| 2.0 * zeta * (k * inertia.max(1e-9)).sqrt();
        self.stop_c = (damper(self.now.knee_inertia_kg_m2), damper(self.stops.ankle_inertia_kg_m2));
        let near = |range: &crate::leg::stops::StopRange, q: f64, qd: f64| {
            range.near(q, 0.01) || range.near(q + 2.0 * qd * self.dt_s, 0.0)
        };
        let (mut rate, mut omega) = self.now.stiffness;
        let mut add = |c: f64, compliance: f64| {
            rate += c * compliance;
            omega = (omega * omega + k * compliance).sqrt();
        };
        if near(&self.stops.knee, q, qd) {
            add(self.stop_c.0, self.now.knee_compliance);
        }
        if let (Some(a), false) = (self.stops.ankle, m.locked(ANKLE)) {
            if near(&a, self.x[ANKLE], self.x[NG + ANKLE]) {
                add(self.stop_c.1, self.now.ankle_compliance);
            }
        }
        self.now.stiffness = (rate, omega);
    }

    /// The stops' torques on the knee and the ankle at state `x` (N m).
    fn stop_torques(&self, x: &[f64; NX]) -> (f64, f64) {
        let knee = self.stops.knee.spring_damper(x[KNEE], x[NG + KNEE], self.stop_c.0);
        let ankle = match (self.stops.ankle, self.model.locked(ANKLE)) {
            (Some(a), false) => a.spring_damper(x[ANKLE], x[NG + ANKLE], self.stop_c.1),
            _ => 0.0,
        };
        (knee, ankle)
    }

    /// What the plant applies besides gravity, damping and contact: the body's forces `body`,
    /// the stops, the net cylinder force `force_n` (N) on the moment arm `arm` (m/rad) and the
    /// cuff force `cuff_force_n` (N, as [`PlantInputs::cuff_force_n`]).
    /// The stops' torques are those at state `x`.
    fn applied(&self, x: &[f64; NX], arm: f64, body: &BodyForces, force_n: f64, cuff_force_n: f64) -> Applied {
        let (knee_stop, ankle_stop) = self.stop_torques(x);
        let mut q = [0.0; NG];
        q[PX] = body.pelvis_force_n[0];
        q[PZ] = body.pelvis_force_n[1];
        q[HIP] = body.hip_torque_nm;
        q[KNEE] = body.knee_torque_nm + body.device_knee_torque_nm + knee_stop + force_n * arm;
        q[ANKLE] = body.ankle_torque_nm + ankle_stop;
        let point = (cuff_force_n != 0.0).then(|| {
            // Perpendicular to the shank where the cuff moves when the knee flexes; positive w1
            // pushes the knee the way that shortens the cylinder.
            let (link, p) = self.cuff;
            let sign = self.model.spec().knee_joint().axis[1].signum();
            let dir = P2::new(p.z, -p.x).scale(sign / p.norm());
            (link, p, dir.scale(-arm.signum() * cuff_force_n))
        });
        Applied { q, point, hip_accel_rad_s2: 0.0 }
    }

    /// The state's derivative at `t_s` with `applied` into `dx`; returns the knee acceleration.
    fn rates(&self, t_s: f64, x: &[f64; NX], applied: &Applied, dx: &mut [f64]) -> f64 {
        let anchors = Anchors { x_m: &self.anchors, since_s: t_s - self.t_step_s };
        let e = self.model.evaluate_from(x, applied, &anchors, Some(&self.start_cache));
        dx[..NG].copy_from_slice(&x[NG..]);
        dx[NG..NX].copy_from_slice(&e.accel);
        e.accel[KNEE]
    }

    /// Piston acceleration (m/s^2) at state `x` with `applied`, at `t_s`.
    fn piston_accel(&self, x: &[f64; NX], applied: &Applied, t_s: f64) -> f64 {
        let mut dx = [0.0; NX];
        let qdd = self.rates(t_s, x, applied, &mut dx);
        let (_, arm, slope) = cylinder_kinematics_at(self.model.spec(), x[KNEE]);
        arm * qdd + slope * x[NG + KNEE] * x[NG + KNEE]
    }

    /// State `x` with a driven hip where its trajectory has it at `t_s` (rad, rad/s), and the
    /// hip's acceleration there (rad/s^2; 0 unless driven).
    fn with_hip(&self, t_s: f64, x: &[f64; NX]) -> ([f64; NX], f64) {
        let mut s = *x;
        match self.driven_hip.as_ref().and_then(|r| r.hip_at(t_s)) {
            Some(h) => {
                (s[HIP], s[NG + HIP]) = (h.value, h.rate);
                (s, h.accel)
            }
            None => (s, 0.0),
        }
    }

    /// Effective mass at the cylinder now (kg): `1 / (L'^2 (M^-1)_kk)`.
    fn effective_mass_kg(&self) -> f64 {
        let arm = cylinder_kinematics_at(self.model.spec(), self.x[KNEE]).1;
        1.0 / (arm * arm * self.now.knee_compliance)
    }

    /// The gait lab's knee moment over the step from `before`: the shank and foot segments'
    /// Newton-Euler balance with the ground reaction averaged over the step (as the Rapier
    /// engine's `Leg::lab_knee_moment_nm`, whose contact force is constant over a step).
    fn lab_knee_moment(&self, before: &StepStart) -> f64 {
        let dt = self.dt_s;
        let now = &self.now;
        let (p0, p1) = (before.momentum, now.momentum);
        let (a, b) = (&before.contact, &now.contact);
        let grf = [0.5 * (a.horizontal_n + b.horizontal_n), 0.5 * (a.vertical_n + b.vertical_n)];
        let grf_moment = 0.5 * (a.moment_origin_y_nm + b.moment_origin_y_nm);
        let g = crate::leg::model::GRAVITY_M_S2;
        // Force the thigh side applies at the knee: R = dP/dt - m g - GRF.
        let r = [(p1[0] - p0[0]) / dt - grf[0], (p1[1] - p0[1]) / dt + g * now.segment_mass_kg - grf[1]];
        let kc = now.knee_centre;
        // Moment about the origin (about +y): M_k + (K x R).y + weight + ground = dH/dt.
        let k_cross_r = kc.z * r[0] - kc.x * r[1];
        let mk = (now.angular_momentum - before.angular_momentum) / dt - k_cross_r - now.weight_moment - grf_moment;
        // Flexion is a rotation about +y: an extensor moment is -y.
        -mk
    }
}

impl CoupledMechanics for WalkerPlant {
    fn state_names(&self) -> &'static [&'static str] {
        &STATE_NAMES
    }

    fn state(&self, x: &mut [f64]) {
        x.copy_from_slice(&self.x);
    }

    fn stiffness(&self) -> (f64, f64) {
        self.now.stiffness
    }

    fn stage(&self, t_s: f64, x: &[f64], inputs: &StageInputs, dx: &mut [f64]) -> CoupledStage {
        let _timed = crate::profile::scope(crate::profile::Stage::Plant);
        let mut s = [0.0; NX];
        s.copy_from_slice(&x[..NX]);
        let (s, hip_accel_rad_s2) = self.with_hip(t_s, &s);
        let (k, kd) = (s[KNEE], s[NG + KNEE]);
        let (l, arm, slope) = cylinder_kinematics_at(self.model.spec(), k);
        let v = arm * kd;
        let body = inputs.body.unwrap_or_default();
        let applied =
            Applied { hip_accel_rad_s2, ..self.applied(&s, arm, &body, (inputs.net_force_n)(v), inputs.cuff_force_n) };
        let qdd = self.rates(t_s, &s, &applied, dx);
        CoupledStage {
            piston: PistonMotion {
                position_m: self.piston.position_at(l),
                velocity_m_s: v,
                accel_m_s2: arm * qdd + slope * kd * kd,
            },
            knee: (k, kd),
        }
    }
}

impl Plant for WalkerPlant {
    fn piston_at(&self, _t_s: f64) -> PistonMotion {
        self.piston.motion()
    }

    fn piston_predictor(&self) -> Option<PistonPredictor> {
        Some(self.piston.predictor(self.effective_mass_kg(), 0.0, 0.0))
    }

    fn coupled(&self) -> Option<&dyn CoupledMechanics> {
        Some(self)
    }

    fn knee_rad(&self) -> f64 {
        self.x[KNEE]
    }

    fn knee_rate_rad_s(&self) -> f64 {
        self.x[NG + KNEE]
    }

    fn stop_report(&self) -> Option<crate::leg::StopReport> {
        Some(self.report)
    }

    fn body_state(&self) -> Option<BodyState> {
        if !self.carriage {
            return None;
        }
        let (x, v) = (&self.x[..NG], &self.x[NG..]);
        Some(BodyState {
            hip: (x[HIP], v[HIP]),
            knee: (x[KNEE], v[KNEE]),
            ankle: (x[ANKLE], v[ANKLE]),
            pelvis: [x[PX], x[PZ] - self.ground_height_m.unwrap_or(0.0)],
            pelvis_rate: [v[PX], v[PZ]],
        })
    }

    fn advance(&mut self, t_s: f64, inputs: &PlantInputs<'_>) -> Result<f64> {
        let _timed = crate::profile::scope(crate::profile::Stage::Plant);
        let dt_s = self.dt_s;
        let force = inputs.cylinder_force_n;
        let m_eff = self.effective_mass_kg();
        self.body = inputs.body.unwrap_or_default();
        self.x = match inputs.mech_end {
            Some(end) => std::array::from_fn(|i| end[i]),
            None => {
                let body = self.body;
                let f = |t: f64, x: &[f64; NX]| {
                    let mut dx = [0.0; NX];
                    let (x, hip_accel_rad_s2) = self.with_hip(t, x);
                    let arm = cylinder_kinematics_at(self.model.spec(), x[KNEE]).1;
                    let applied =
                        Applied { hip_accel_rad_s2, ..self.applied(&x, arm, &body, force, inputs.cuff_force_n) };
                    self.rates(t, &x, &applied, &mut dx);
                    dx
                };
                // Substepped as the loop substeps the coupled path (the contact and the stops).
                let (lim_re, lim_im) = Integrator::Rk4.stability_limits();
                let (rate, omega) = self.now.stiffness;
                let need = (rate * dt_s / (CONTACT_MARGIN * lim_re)).max(omega * dt_s / (CONTACT_MARGIN * lim_im));
                let n = need.ceil().clamp(1.0, MAX_OWN_SUBSTEPS as f64) as usize;
                let h = dt_s / n as f64;
                (0..n).fold(self.x, |x, i| Integrator::Rk4.step(t_s + i as f64 * h, h, &x, f))
            }
        };
        // A driven hip is where its trajectory is.
        self.x = self.with_hip(t_s + dt_s, &self.x).0;
        // The friction anchors are points of the belt.
        let belt = self.model.belt_speed_m_s();
        self.anchors.iter_mut().flatten().for_each(|a| *a -= belt * dt_s);
        self.t_step_s = t_s + dt_s;
        let before = self.now;
        self.start_step();
        if self.ground_height_m.is_some() {
            self.lab_knee_moment_nm = self.lab_knee_moment(&before);
        }
        let (l1, arm1, _) = cylinder_kinematics_at(self.model.spec(), self.x[KNEE]);
        self.arm_m = arm1;
        let dl = l1 - self.piston.length_m();
        self.piston.record(l1, arm1 * self.x[NG + KNEE], force, m_eff, dt_s);
        let ankle = self.stops.ankle.filter(|_| !self.model.locked(ANKLE)).map(|_| self.x[ANKLE]);
        self.report.add(&self.stops, self.x[KNEE], ankle, dt_s);
        if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
            return Err(Error::Diverged { time_s: t_s + dt_s, state: STATE_NAMES[i].into(), value: self.x[i] });
        }
        Ok(dl)
    }

    fn leg_row(&self) -> Option<LegRow> {
        let (k, kd) = (self.x[KNEE], self.x[NG + KNEE]);
        Some(LegRow {
            knee_angle_deg: k.to_degrees(),
            knee_velocity_deg_s: kd.to_degrees(),
            hip_angle_deg: self.x[HIP].to_degrees(),
            cylinder_length_m: self.piston.length_m(),
            loop_closure_gap_m: 0.0,
            moment_arm_m: self.arm_m,
        })
    }

    fn leg_kinematics(&self) -> Option<LegKinematics> {
        let [thigh, shank, foot] = self.now.links;
        Some(LegKinematics { hip: (self.x[HIP], self.x[NG + HIP]), thigh, shank, foot })
    }

    fn foot_load(&self) -> Option<FootLoad> {
        self.ground_height_m?;
        let c = &self.now.contact;
        let cop_x_m = c.cop_m.map_or(0.0, |p| self.now.links[2].to_local(p)[0]);
        Some(FootLoad { vertical_n: c.vertical_n, cop_x_m })
    }

    fn contact_row(&self) -> Option<ContactRow> {
        let ground = self.ground_height_m?;
        let c = &self.now.contact;
        Some(ContactRow {
            ground_reaction_vertical_n: c.vertical_n,
            ground_reaction_horizontal_n: c.horizontal_n,
            contact_penetration_m: c.penetration_m,
            knee_moment_nm: self.lab_knee_moment_nm,
            ankle_angle_deg: self.x[ANKLE].to_degrees(),
            pelvis_height_m: self.x[PZ] - ground,
            pelvis_x_m: self.x[PX],
            support_force_n: self.body.pelvis_force_n[1],
            wearer_knee_torque_nm: self.body.knee_torque_nm,
        })
    }
}
