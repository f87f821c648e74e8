//! Plants: the mechanics that move the piston, behind one interface.
//!
//! The force channel ([`crate::hydraulics`]) is integrated by the co-simulation loop; a
//! plant supplies the piston motion it needs and takes the resulting cylinder force.

mod bench;
pub use bench::*;

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

/// A plant as the co-simulation loop sees it.
pub trait Plant: Send {
    /// Piston motion at time `t_s` inside the step that is about to be taken.
    fn piston_at(&self, t_s: f64) -> PistonMotion;
    /// Advance the mechanics from `t_s` to `t_s + dt_s` under the net cylinder force
    /// `cylinder_force_n` (N, load force minus friction, positive lengthening).
    fn advance(&mut self, t_s: f64, dt_s: f64, cylinder_force_n: f64);
}
