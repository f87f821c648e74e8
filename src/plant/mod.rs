//! Plants: the mechanics that move the piston, behind one interface.
//!
//! The force channel ([`crate::hydraulics`]) is integrated by the co-simulation loop; a
//! plant supplies the piston motion it needs and takes the resulting cylinder force.

mod bench;
mod leg;
mod reduced_knee_plant;
mod reduced_walking_plant;
pub use bench::*;
pub use leg::*;
pub use reduced_knee_plant::ReducedLegPlant;
pub use reduced_walking_plant::WalkerPlant;

use crate::error::Result;
use crate::record::{ContactRow, LegRow};
use serde::{Deserialize, Serialize};

/// Which plant a scenario runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantKind {
    /// The cylinder on a force-loading test bench with prescribed piston motion.
    Bench,
    /// The URDF leg in Rapier, driven through the cylinder in its closed loop.
    Leg,
}

/// The plant of a run, resolved.
#[derive(Debug, Clone)]
pub enum PlantSetup {
    /// Cylinder on the force-loading bench.
    Bench(BenchParams),
    /// The URDF leg.
    Leg(Box<LegSetup>),
}

/// Piston (cylinder length) motion at one instant. Positive = cylinder lengthening.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PistonMotion {
    /// Piston position x_c (m), relative to its position at t = 0.
    pub position_m: f64,
    /// Piston velocity xc_dot (m/s).
    pub velocity_m_s: f64,
    /// Piston acceleration xc_ddot (m/s^2).
    pub accel_m_s2: f64,
}

/// A local model of the piston for one step, for plants whose piston motion responds to the
/// cylinder force (the leg): `xc_ddot(tau) = free_accel + cylinder_force(tau) / effective_mass`,
/// starting from `position_m`, `velocity_m_s`. The loop integrates it together with the
/// force ODE, so the hydraulics and the controller see a piston that reacts to the force
/// inside the step; the plant then takes the step's impulse-average force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PistonPredictor {
    /// Piston position at the step start (m).
    pub position_m: f64,
    /// Piston velocity at the step start (m/s).
    pub velocity_m_s: f64,
    /// Acceleration with zero cylinder force (gravity, velocity terms, human, hip) (m/s^2).
    pub free_accel_m_s2: f64,
    /// Effective mass of the mechanics reflected to the cylinder axis (kg).
    pub effective_mass_kg: f64,
    /// Lead (s) of the position update of the plant's integrator: a scheme that advances
    /// velocity then position in `n` substeps of `dt/n` moves `v0*dt + a*dt^2*(n+1)/(2n)`,
    /// i.e. as if the velocity were `v + a*dt/(2n)`. The predictor's piston velocity includes
    /// this lead so its stroke matches the plant's to second order.
    pub velocity_lead_s: f64,
    /// Part of the acceleration that is not integrated with that lead (m/s^2): for a piston
    /// driven through a joint, `d(dL/dq)/dq * qdot^2`, the curvature of the stroke in the
    /// joint coordinate the plant integrates.
    pub lead_exempt_accel_m_s2: f64,
}

/// The piston as a mechanical plant tracks it from step to step: its stroke, its velocity and
/// the acceleration measured over the last step, split into the part the cylinder force
/// explains and the free rest, which the next step's [`PistonPredictor`] extrapolates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PistonTrack {
    /// Cylinder length at the start of the run (m).
    length0_m: f64,
    /// Cylinder length now (m).
    length_m: f64,
    /// Piston velocity at the end of the last step (m/s).
    velocity_m_s: f64,
    /// Measured piston acceleration over the last step (m/s^2).
    accel_m_s2: f64,
    /// The part of it with no cylinder force (m/s^2).
    free_accel_m_s2: f64,
    /// Change of the free acceleration over the last step (m/s^2), for linear extrapolation.
    free_accel_trend_m_s2: f64,
}

impl PistonTrack {
    /// At rest in the record: length (m), velocity (m/s) and the free acceleration (m/s^2).
    pub fn new(length_m: f64, velocity_m_s: f64, free_accel_m_s2: f64) -> Self {
        Self {
            length0_m: length_m,
            length_m,
            velocity_m_s,
            accel_m_s2: free_accel_m_s2,
            free_accel_m_s2,
            free_accel_trend_m_s2: 0.0,
        }
    }

    /// Cylinder length now (m).
    pub fn length_m(&self) -> f64 {
        self.length_m
    }

    /// Piston position (m, from the start length) at cylinder length `length_m` (m).
    pub fn position_at(&self, length_m: f64) -> f64 {
        length_m - self.length0_m
    }

    /// The piston's motion now.
    pub fn motion(&self) -> PistonMotion {
        PistonMotion {
            position_m: self.position_at(self.length_m),
            velocity_m_s: self.velocity_m_s,
            accel_m_s2: self.accel_m_s2,
        }
    }

    /// The predictor for the next step with the effective mass (kg) there, the plant
    /// integrator's velocity lead (s) and the acceleration exempt from it (m/s^2).
    pub fn predictor(
        &self,
        effective_mass_kg: f64,
        velocity_lead_s: f64,
        lead_exempt_accel_m_s2: f64,
    ) -> PistonPredictor {
        PistonPredictor {
            position_m: self.position_at(self.length_m),
            velocity_m_s: self.velocity_m_s,
            // The free acceleration measured over the last step is centred half a step back;
            // extrapolate it linearly to the middle of the coming step.
            free_accel_m_s2: self.free_accel_m_s2 + self.free_accel_trend_m_s2,
            effective_mass_kg,
            velocity_lead_s,
            lead_exempt_accel_m_s2,
        }
    }

    /// After a step of `dt_s` (s) under the net cylinder force `force_n` (N) with the effective
    /// mass `effective_mass_kg` (kg) at its start: the new length (m) and velocity (m/s).
    pub fn record(&mut self, length_m: f64, velocity_m_s: f64, force_n: f64, effective_mass_kg: f64, dt_s: f64) {
        self.accel_m_s2 = (velocity_m_s - self.velocity_m_s) / dt_s;
        let free = self.accel_m_s2 - force_n / effective_mass_kg;
        self.free_accel_trend_m_s2 = free - self.free_accel_m_s2;
        self.free_accel_m_s2 = free;
        self.velocity_m_s = velocity_m_s;
        self.length_m = length_m;
    }
}

/// What the loop applies to the plant over one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantInputs<'a> {
    /// Net force along the cylinder axis (N), positive lengthening: load force minus friction
    /// (or the prescribed force in `actuator.mode = "force"`).
    pub cylinder_force_n: f64,
    /// Human interaction force at the cuff (N), perpendicular to the shank, positive in the
    /// direction of knee flexion (`human.mode = "cuff"`; ignored by the bench).
    pub cuff_force_n: f64,
    /// The body's forces on the carriage over the step (from [`Plant::body_state`]).
    pub body: Option<crate::human::BodyForces>,
    /// With [`CoupledMechanics`]: the mechanical state the loop integrated to the end of the
    /// step together with the hydraulics (in the order of [`CoupledMechanics::state_names`]);
    /// the plant takes it as it is.
    pub mech_end: Option<&'a [f64]>,
}

/// Fraction of an integrator's stability limit the mechanics' stiffness
/// ([`CoupledMechanics::stiffness`]: the reduced walking leg's contact and end stops) may use
/// in a substep: its fastest modes are critically or heavily damped (the sole's damper, the
/// stops), and their integration stays damped up to near the limit (ode3 at 0.8 of it:
/// amplification -0.33 per step), so they substep only where they must.
pub const CONTACT_MARGIN: f64 = 0.8;

/// What a [`CoupledMechanics`] stage is given besides the time and the mechanical state.
pub struct StageInputs<'a> {
    /// The net cylinder force (N, positive lengthening) at a piston velocity (m/s).
    pub net_force_n: &'a dyn Fn(f64) -> f64,
    /// As [`PlantInputs::cuff_force_n`] (N), held over the step.
    pub cuff_force_n: f64,
    /// As [`PlantInputs::body`], held over the step.
    pub body: Option<crate::human::BodyForces>,
}

/// Mechanics the loop can evaluate at any instant of a step (the reduced engine). The loop
/// then integrates the mechanical state in the same ODE as the hydraulics and the controller
/// (monolithic coupling: the force ODE sees the exact piston motion at every stage, and the
/// mechanics see the force as it changes within the step), instead of predicting the piston
/// and handing the plant the step's average force.
pub trait CoupledMechanics {
    /// Names of the mechanical state's entries (SI units in the names); its length is the
    /// state's.
    fn state_names(&self) -> &'static [&'static str];
    /// The mechanical state now, into `x` (as long as [`Self::state_names`]).
    fn state(&self, x: &mut [f64]);
    /// The piston and the knee at time `t_s` and mechanical state `x`, with the state's time
    /// derivative written to `dx`.
    fn stage(&self, t_s: f64, x: &[f64], inputs: &StageInputs, dx: &mut [f64]) -> CoupledStage;
    /// How stiff the mechanics are over the coming step: the fastest decay rate (1/s) and
    /// oscillation (rad/s) of their forces (contact springs and dampers), which the loop's
    /// substeps must resolve as they do the hydraulics'. Default none.
    fn stiffness(&self) -> (f64, f64) {
        (0.0, 0.0)
    }
}

/// One evaluation of [`CoupledMechanics`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoupledStage {
    /// The piston: position from its length at the start of the run (m), velocity (m/s),
    /// acceleration (m/s^2).
    pub piston: PistonMotion,
    /// Knee angle (rad) and rate (rad/s) at the stage.
    pub knee: (f64, f64),
}

/// A plant as the co-simulation loop sees it.
pub trait Plant: Send {
    /// Piston motion at time `t_s`: prescribed (bench) or the state at the step start (leg).
    fn piston_at(&self, t_s: f64) -> PistonMotion;
    /// The local piston model for the next step, for plants whose piston responds to force.
    /// `None` (default): the motion is prescribed by [`Plant::piston_at`].
    fn piston_predictor(&self) -> Option<PistonPredictor> {
        None
    }
    /// The mechanics as the loop can integrate them with the hydraulics, for plants that can
    /// (see [`CoupledMechanics`]). Default `None`: the loop predicts the piston.
    fn coupled(&self) -> Option<&dyn CoupledMechanics> {
        None
    }
    /// Knee angle (rad), 0 for plants without a knee.
    fn knee_rad(&self) -> f64 {
        0.0
    }
    /// Knee angular rate (rad/s), 0 for plants without a knee.
    fn knee_rate_rad_s(&self) -> f64 {
        0.0
    }
    /// Advance the mechanics over one step (its length was fixed when the plant was built) from
    /// `t_s` under a force constant over the step. Returns the change of cylinder length over
    /// the step (m), measured geometrically.
    fn advance(&mut self, t_s: f64, inputs: &PlantInputs<'_>) -> Result<f64>;
    /// What the end stops did so far (None for plants without a leg).
    fn stop_report(&self) -> Option<crate::leg::StopReport> {
        None
    }
    /// The state the body on the carriage reads (None without the carriage).
    fn body_state(&self) -> Option<crate::human::BodyState> {
        None
    }
    /// The leg's segments now, for the device's sensors (None for plants without a leg).
    fn leg_kinematics(&self) -> Option<crate::sensors::LegKinematics> {
        None
    }
    /// The ground's vertical reaction on the foot and where it acts along the foot (from the
    /// same contact as [`Self::contact_row`]; None without ground contact).
    fn foot_load(&self) -> Option<crate::sensors::FootLoad> {
        None
    }
    /// The leg columns of the record now (None for plants without a leg).
    fn leg_row(&self) -> Option<LegRow> {
        None
    }
    /// The contact columns of the record now: what the ground and the body did over the last
    /// step (None without ground contact).
    fn contact_row(&self) -> Option<ContactRow> {
        None
    }
}
