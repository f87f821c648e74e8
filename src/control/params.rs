//! The model the controller assumes: its hydraulics (`[controller.nominal]`) and its leg
//! (`[controller.nominal_leg]`).

use crate::hydraulics::HydraulicParams;
use serde::{Deserialize, Serialize};

/// `[controller.nominal]`: the hydraulic parameters the controller assumes. Each key that
/// is absent takes the plant's value from `[hydraulics]` (a perfect model).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NominalParams {
    /// Assumed bulk modulus (Pa).
    pub beta_pa: Option<f64>,
    /// Assumed volume V0 (m^3).
    pub v0_m3: Option<f64>,
    /// Assumed flow gain K_q (m^2/s).
    pub k_q: Option<f64>,
    /// Assumed flow-pressure coefficient K_c (m^3/(s Pa)).
    pub k_c: Option<f64>,
    /// Assumed leakage 2*C_in + C_ex (m^3/(s Pa)).
    pub leakage: Option<f64>,
    /// Assumed spool time constant (s).
    pub tau_s: Option<f64>,
    /// Assumed valve gain.
    pub k_s: Option<f64>,
    /// Assumed area A1 (m^2).
    pub a1_m2: Option<f64>,
    /// Assumed area A2 (m^2).
    pub a2_m2: Option<f64>,
}

impl NominalParams {
    /// The controller's parameter set: the plant's, with the given assumptions replacing it.
    pub fn apply(&self, plant: &HydraulicParams) -> HydraulicParams {
        let mut p = plant.clone();
        let pick = |o: Option<f64>, v: &mut f64| {
            if let Some(x) = o {
                *v = x
            }
        };
        pick(self.beta_pa, &mut p.beta_pa);
        pick(self.v0_m3, &mut p.v0_m3);
        pick(self.k_q, &mut p.k_q);
        pick(self.k_c, &mut p.k_c);
        pick(self.leakage, &mut p.leakage);
        pick(self.tau_s, &mut p.tau_s);
        pick(self.k_s, &mut p.k_s);
        pick(self.a1_m2, &mut p.a1_m2);
        pick(self.a2_m2, &mut p.a2_m2);
        p
    }
}

/// `[controller.nominal_leg]`: the leg model the controller believes in. Defaults: the
/// plant's (`leg.urdf`, `leg.mass_scale`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NominalLeg {
    /// URDF of the controller's leg (same lookup as `leg.urdf`). Default: the plant's.
    pub urdf: Option<String>,
    /// Mass scale of the controller's leg. Default: the plant's `leg.mass_scale`. 0.2..=5.
    pub mass_scale: Option<f64>,
    /// SHA-256 of the controller's URDF; filled in by every run that names one.
    pub urdf_sha256: Option<String>,
}
