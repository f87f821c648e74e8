//! Plants: the mechanics that move the piston, behind one interface.
//!
//! The force channel ([`crate::hydraulics`]) is integrated by the co-simulation loop; a
//! plant supplies the piston motion it needs and takes the resulting cylinder force.

mod bench;
pub use bench::*;

use crate::error::Result;
use serde::{Deserialize, Serialize};

/// Which plant a scenario runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantKind {
    /// The cylinder on a force-loading test bench with prescribed piston motion.
    Bench,
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

/// What the loop applies to the plant over one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantInputs {
    /// Net force along the cylinder axis (N), positive lengthening: load force minus friction
    /// (or the prescribed force in `actuator.mode = "force"`).
    pub cylinder_force_n: f64,
    /// Human interaction force at the cuff (N), perpendicular to the shank, positive in the
    /// direction of knee flexion (`human.mode = "cuff"`; ignored by the bench).
    pub cuff_force_n: f64,
}

/// A plant as the co-simulation loop sees it.
pub trait Plant: Send {
    /// Piston motion at time `t_s` inside the step that is about to be taken.
    fn piston_at(&self, t_s: f64) -> PistonMotion;
    /// Knee angle (rad), 0 for plants without a knee.
    fn knee_rad(&self) -> f64 {
        0.0
    }
    /// Advance the mechanics from `t_s` to `t_s + dt_s`. Returns the piston displacement over
    /// the step that the force ODE did not see (m): the actual change of cylinder length minus
    /// the change implied by [`Plant::piston_at`] during the step. The loop adds `-n2` times it
    /// to the load force, so the oil spring sees the geometric stroke exactly.
    fn advance(&mut self, t_s: f64, dt_s: f64, inputs: &PlantInputs) -> Result<f64>;
    /// Names (with units) of plant-specific recorded columns.
    fn extra_names(&self) -> Vec<&'static str> {
        Vec::new()
    }
    /// Values of the plant-specific columns now, appended to `out`.
    fn extra_values(&self, _out: &mut Vec<f64>) {}
}
