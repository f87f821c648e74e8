//! Test-bench plant: the cylinder on a force-loading rig, piston motion prescribed.

use super::{PistonMotion, Plant, PlantInputs};
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// How the bench moves the piston.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BenchMotion {
    /// Piston held still (x_c = 0): the paper's force-loading case.
    Still,
    /// x_c = amplitude*sin(2*pi*f*t): exercises the n2*xc_dot path of the force ODE.
    Sine,
}

/// Bench parameters (scenario section `[bench]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BenchParams {
    /// Prescribed motion. Default `still`.
    pub motion: BenchMotion,
    /// Amplitude of the sine motion (m). Default 1e-4. >= 0.
    pub amplitude_m: f64,
    /// Frequency of the sine motion (Hz). Default 1. > 0.
    pub frequency_hz: f64,
}

impl Default for BenchParams {
    fn default() -> Self {
        Self { motion: BenchMotion::Still, amplitude_m: 1e-4, frequency_hz: 1.0 }
    }
}

/// The bench plant. The rig is infinitely stiff: the cylinder force does not move it.
pub struct Bench {
    p: BenchParams,
    dt_s: f64,
}

impl Bench {
    /// A bench with the given prescribed motion, stepped by `dt_s` (s).
    pub fn new(p: BenchParams, dt_s: f64) -> Self {
        Self { p, dt_s }
    }
}

impl Plant for Bench {
    fn piston_at(&self, t_s: f64) -> PistonMotion {
        match self.p.motion {
            BenchMotion::Still => PistonMotion::default(),
            BenchMotion::Sine => {
                let w = std::f64::consts::TAU * self.p.frequency_hz;
                let (s, c) = (w * t_s).sin_cos();
                let a = self.p.amplitude_m;
                PistonMotion { position_m: a * s, velocity_m_s: a * w * c, accel_m_s2: -a * w * w * s }
            }
        }
    }

    fn advance(&mut self, t_s: f64, _inputs: &PlantInputs<'_>) -> Result<f64> {
        Ok(self.piston_at(t_s + self.dt_s).position_m - self.piston_at(t_s).position_m)
    }
}
