//! The leg on the reduced-coordinate engine (`leg.engine = "reduced"`): the knee in its own
//! coordinate (see [`crate::leg::ReducedModel`]). With the hydraulic actuator the loop integrates
//! the knee in the same ODE as the hydraulics and the controller ([`CoupledMechanics`]: at every
//! integrator stage the force ODE sees the exact piston motion and the knee the force of that
//! stage); with a prescribed force or none, the plant integrates the knee itself (RK4 under the
//! step's force).

use super::{
    CoupledMechanics, CoupledStage, LegSetup, PistonMotion, PistonPredictor, PistonTrack, Plant, PlantInputs,
    StageInputs,
};
use crate::error::{Error, Result};
use crate::integrator::Integrator;
use crate::leg::{moment_arm_slope_at, ReducedModel};
use crate::record::LegRow;
use crate::reference::{ForceReference, RefSample};
use crate::sensors::{LegKinematics, SegmentState};
use std::sync::Arc;

/// The reduced-coordinate leg plant.
pub struct ReducedLegPlant {
    model: Arc<ReducedModel>,
    reference: ForceReference,
    q: f64,
    qd: f64,
    piston: PistonTrack,
    /// Distance of the cuff point from the knee axis (m).
    cuff_radius_m: f64,
    driven_hip: bool,
    hip_rad: f64,
    /// Time of the state (s): the start of the coming step.
    t_s: f64,
    dt_s: f64,
    /// The end stops, their torque held over the coming step (N m, from the state at its
    /// start, as on the Rapier engine), and what they did.
    stops: crate::leg::EndStops,
    stop_nm: f64,
    report: crate::leg::StopReport,
}

impl ReducedLegPlant {
    /// Build the plant from a resolved setup and its reduced model, stepped by `dt_s` (s);
    /// `reference` drives the hip when the setup's hip is driven.
    pub fn new(setup: &LegSetup, model: Arc<ReducedModel>, reference: ForceReference, dt_s: f64) -> Result<Self> {
        let (q, qd) = (setup.start.knee_rad, setup.start.knee_rate_rad_s);
        let (l, arm) = model.cylinder(q);
        let cuff = setup.cuff_point_m;
        let driven_hip = setup.start.hip.is_some();
        let hip = setup.start.hip.unwrap_or_default();
        let qdd = model.acceleration(q, qd, (hip.value, hip.rate, hip.accel), 0.0);
        let free = arm * qdd + moment_arm_slope_at(model.model(), q) * qd * qd;
        Ok(Self {
            reference,
            q,
            qd,
            piston: PistonTrack::new(l, arm * qd, free),
            cuff_radius_m: (cuff[0] * cuff[0] + cuff[2] * cuff[2]).sqrt(),
            driven_hip,
            hip_rad: hip.value,
            t_s: 0.0,
            dt_s,
            stops: setup.stops,
            stop_nm: 0.0,
            report: crate::leg::StopReport::default(),
            model,
        }
        .with_stop_torque())
    }

    /// The end stops' torque over the coming step from the knee state now.
    fn with_stop_torque(mut self) -> Self {
        let arm = self.model.cylinder(self.q).1;
        let inertia = self.model.effective_mass_kg(self.q) * arm * arm;
        self.stop_nm = self.stops.knee.torque(self.q, self.qd, inertia, self.dt_s, 0.5);
        self
    }

    fn hip_at(&self, t_s: f64) -> (f64, f64, f64) {
        if !self.driven_hip {
            return (0.0, 0.0, 0.0);
        }
        let h: RefSample = self.reference.hip_at(t_s).unwrap_or_default();
        (h.value, h.rate, h.accel)
    }

    /// Knee acceleration (rad/s^2) at `t_s`, knee state, net cylinder force (N) and cuff
    /// torque (N m, flexion positive) with the moment arm `arm_m` (m/rad) at `q`.
    fn knee_accel(&self, t_s: f64, q: f64, qd: f64, force_n: f64, arm_m: f64, cuff_tau_nm: f64) -> f64 {
        self.model.acceleration(q, qd, self.hip_at(t_s), force_n * arm_m + cuff_tau_nm + self.stop_nm)
    }

    /// Cuff torque about the knee (N m) for the cuff force `cuff_force_n` (N; positive w1
    /// pushes the knee the way that shortens the cylinder) with the moment arm `arm_m`.
    fn cuff_torque(&self, cuff_force_n: f64, arm_m: f64) -> f64 {
        -arm_m.signum() * cuff_force_n * self.cuff_radius_m
    }

    /// RK4 over one step under a constant cylinder force (used when the loop does not
    /// integrate the knee itself: a force or free actuator). Returns the knee at the end.
    fn rk4(&self, t_s: f64, h: f64, force: f64, cuff_force_n: f64) -> (f64, f64) {
        let m = &self.model;
        let cuff_tau = self.cuff_torque(cuff_force_n, m.cylinder(self.q).1);
        let f = |t: f64, x: &[f64; 2]| [x[1], self.knee_accel(t, x[0], x[1], force, m.cylinder(x[0]).1, cuff_tau)];
        let [q, qd] = Integrator::Rk4.step(t_s, h, &[self.q, self.qd], f);
        (q, qd)
    }
}

/// Names of the knee-only engine's mechanical state.
const KNEE_STATE: [&str; 2] = ["knee_angle_rad", "knee_rate_rad_s"];

impl CoupledMechanics for ReducedLegPlant {
    fn state_names(&self) -> &'static [&'static str] {
        &KNEE_STATE
    }

    fn state(&self, x: &mut [f64]) {
        x[0] = self.q;
        x[1] = self.qd;
    }

    fn stage(&self, t_s: f64, x: &[f64], inputs: &StageInputs, dx: &mut [f64]) -> CoupledStage {
        let _timed = crate::profile::scope(crate::profile::Stage::Plant);
        let (q, qd) = (x[0], x[1]);
        let (l, arm, arm_slope) = self.model.cylinder_kinematics(q);
        let v = arm * qd;
        let cuff = self.cuff_torque(inputs.cuff_force_n, arm);
        let qdd = self.knee_accel(t_s, q, qd, (inputs.net_force_n)(v), arm, cuff);
        // xc_ddot = L'(q) q'' + L''(q) q'^2.
        let accel_m_s2 = arm * qdd + arm_slope * qd * qd;
        dx[0] = qd;
        dx[1] = qdd;
        CoupledStage {
            piston: PistonMotion { position_m: self.piston.position_at(l), velocity_m_s: v, accel_m_s2 },
            knee: (q, qd),
        }
    }
}

impl Plant for ReducedLegPlant {
    fn piston_at(&self, _t_s: f64) -> PistonMotion {
        self.piston.motion()
    }

    fn piston_predictor(&self) -> Option<PistonPredictor> {
        // No substep lead (the knee is integrated with the hydraulics, or by RK4).
        Some(self.piston.predictor(self.model.effective_mass_kg(self.q), 0.0, 0.0))
    }

    fn coupled(&self) -> Option<&dyn CoupledMechanics> {
        Some(self)
    }

    fn knee_rad(&self) -> f64 {
        self.q
    }

    fn stop_report(&self) -> Option<crate::leg::StopReport> {
        Some(self.report)
    }

    fn knee_rate_rad_s(&self) -> f64 {
        self.qd
    }

    fn advance(&mut self, t_s: f64, inputs: &PlantInputs<'_>) -> Result<f64> {
        let _timed = crate::profile::scope(crate::profile::Stage::Plant);
        let dt_s = self.dt_s;
        let force = inputs.cylinder_force_n;
        let q0 = self.q;
        (self.q, self.qd) = match inputs.mech_end {
            Some(end) => (end[0], end[1]),
            None => self.rk4(t_s, dt_s, force, inputs.cuff_force_n),
        };
        let m = &self.model;
        let (l1, arm1) = m.cylinder(self.q);
        let v = arm1 * self.qd;
        let dl = l1 - self.piston.length_m();
        self.piston.record(l1, v, force, m.effective_mass_kg(q0), dt_s);
        self.hip_rad = self.hip_at(t_s + dt_s).0;
        self.t_s = t_s + dt_s;
        self.report.add(&self.stops, self.q, None, dt_s);
        let arm = m.cylinder(self.q).1;
        // Integrated exactly (or by RK4) over the step: q' = q + qd dt + a dt^2 / 2.
        self.stop_nm = self.stops.knee.torque(self.q, self.qd, m.effective_mass_kg(self.q) * arm * arm, dt_s, 0.5);
        if !(self.q.is_finite() && self.qd.is_finite() && self.piston.length_m().is_finite()) {
            return Err(Error::Diverged { time_s: t_s + dt_s, state: "knee_angle_rad".into(), value: self.q });
        }
        Ok(dl)
    }

    fn leg_kinematics(&self) -> Option<LegKinematics> {
        let spec = self.model.model();
        let (h, hd, _) = self.hip_at(self.t_s);
        let poses = crate::leg::link_poses_full_at(spec, h, self.q, 0.0)?;
        let knee = spec.knee_joint();
        let foot = spec.ankle_joint().map_or(knee.child, |a| a.child);
        let w_thigh = -hd;
        let w_shank = w_thigh + knee.axis[1].signum() * self.qd;
        let state = |p: &crate::leg::planar::Pose2, v: [f64; 2], w: f64| SegmentState {
            origin_m: [p.t.x, p.t.z],
            cos_sin: (p.a.cos(), p.a.sin()),
            velocity_m_s: v,
            omega_rad_s: w,
        };
        // The hip sits still at the origin; the knee centre turns with the thigh, the foot
        // (its ankle locked in the air) with the shank.
        let (k, f) = (poses[knee.child].t, poses[foot].t);
        let v_knee = [w_thigh * k.z, -w_thigh * k.x];
        let v_foot = [v_knee[0] + w_shank * (f.z - k.z), v_knee[1] - w_shank * (f.x - k.x)];
        Some(LegKinematics {
            hip: (h, hd),
            thigh: state(&poses[knee.parent], [0.0, 0.0], w_thigh),
            shank: state(&poses[knee.child], v_knee, w_shank),
            foot: state(&poses[foot], v_foot, w_shank),
        })
    }

    fn leg_row(&self) -> Option<LegRow> {
        Some(LegRow {
            knee_angle_deg: self.q.to_degrees(),
            knee_velocity_deg_s: self.qd.to_degrees(),
            hip_angle_deg: self.hip_rad.to_degrees(),
            cylinder_length_m: self.piston.length_m(),
            loop_closure_gap_m: 0.0,
            moment_arm_m: self.model.cylinder(self.q).1,
        })
    }
}
