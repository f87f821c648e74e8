//! How the actuator drives the mechanics, and its physical limits.

use serde::{Deserialize, Serialize};

/// What drives the prismatic actuator joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActuatorMode {
    /// The hydraulic force channel, closed by the force controller (the normal case).
    Hydraulic,
    /// A prescribed force, no hydraulics (mechanics checks, required-force curves). Leg only.
    Force,
    /// No actuator force at all (passive leg). Leg only.
    Free,
}

/// Where the prescribed force of `mode = "force"` comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ForceSource {
    /// `actuator.force_n`.
    Constant,
    /// The force reference F_d(t).
    Reference,
}

/// Actuator parameters (scenario section `[actuator]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ActuatorParams {
    /// `hydraulic` (default), `force` or `free`.
    pub mode: ActuatorMode,
    /// Prescribed force (N), positive lengthening, for `mode = "force"`. Default 0.
    pub force_n: f64,
    /// `constant` (default: `force_n`) or `reference` (F_d(t)) for `mode = "force"`.
    pub force_source: ForceSource,
    /// Valve command saturation |u| <= limit; 0 = no limit. Default 0. >= 0.
    pub valve_command_limit: f64,
    /// Spool travel limit |x_v| <= limit (m); 0 = no limit. Default 0. >= 0.
    pub spool_limit_m: f64,
    /// Clamp the load force to what the supply pressure can give, [-p_s*A2, p_s*A1]. Default true.
    pub pressure_limit: bool,
}

impl Default for ActuatorParams {
    fn default() -> Self {
        Self {
            mode: ActuatorMode::Hydraulic,
            force_n: 0.0,
            force_source: ForceSource::Constant,
            valve_command_limit: 0.0,
            spool_limit_m: 0.0,
            pressure_limit: true,
        }
    }
}
