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

/// What the device does without power (`actuator.failsafe`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Failsafe {
    /// The spring-centred spool closes the valve: the knee is held by the oil (a hydraulic
    /// lock, as tight as the valve's and the cylinder's leakage allow).
    #[default]
    Locked,
    /// A normally open bypass valve connects both chambers to the return line (a single-rod
    /// cylinder needs the tank for its rod's volume; a bypass across the piston alone would
    /// leave the rod area's force at the trapped pressure): the knee is free but for the seal
    /// friction and the valve's flow resistance (`failsafe_bypass_area_m2`).
    Free,
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
    /// What the device does without power (a `power` fault, a controller's stop in a fault
    /// campaign): `locked` (default) or `free`.
    pub failsafe: Failsafe,
    /// The fail-safe bypass valve's orifice area when it opens (`failsafe = "free"`, m^2).
    /// Default 2e-5 (20 mm^2). > 0.
    pub failsafe_bypass_area_m2: f64,
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
            failsafe: Failsafe::Locked,
            failsafe_bypass_area_m2: 2e-5,
        }
    }
}
