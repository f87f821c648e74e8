//! Valve-controlled cylinder: the paper's force channel (MODEL.md section 1, paper Eq. 1).
//!
//! State: load force `F_L` (N), spool position `x_v` (m) and the integrated
//! force-acceleration disturbance `r` (N/s). Input: valve command `u`, piston velocity
//! `xc_dot` (m/s) from the mechanics, and the injected disturbances.
//!
//! ```text
//! dF_L/dt = n1*x_v - n2*xc_dot - n3*F_L + n4 + d_F(t) + r
//! dx_v/dt = (k_s*u - x_v)/tau + d_v(t)
//! dr/dt   = D_acc(t, x)          (disturbance on dx2/dt = d^2 F_L/dt^2, paper Eq. 5)
//! ```
//!
//! `r` is how a disturbance that the paper adds to `dx2/dt` (Eq. 5: `g1 + w1`) enters a
//! model whose state is `F_L` rather than `dF_L/dt`: differentiating the first line gives
//! exactly the paper's `dx2/dt = n1*dx3/dt - n2*xc_ddot - n3*x2 + D_acc`.

mod actuator;
mod cylinder;
mod friction;
mod two_chamber;
pub use actuator::*;
pub use cylinder::*;
pub use friction::*;
pub use two_chamber::*;

use serde::{Deserialize, Serialize};

/// Which hydraulic plant model integrates the force channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HydraulicModel {
    /// The paper's linear force ODE (Eq. 1).
    Linear,
    /// Two chambers with orifice flow and pressure limits (see [`TwoChamber`]).
    TwoChamber,
}

/// Physical parameters of the valve and cylinder (paper Table 1 plus our documented defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HydraulicParams {
    /// `linear` (default, the paper's) or `two_chamber`.
    pub model: HydraulicModel,
    /// Return (tank) pressure (Pa), two-chamber model. Default 0. >= 0, < supply.
    pub return_pressure_pa: f64,
    /// Oil bulk modulus beta (Pa). Default 1.517e9 (paper Table 1). Must be > 0.
    pub beta_pa: f64,
    /// Chamber plus hose volume V0 (m^3). Default 1.0e-4 (our assumption; the paper gives none). > 0.
    pub v0_m3: f64,
    /// Piston area of the cap side A1 (m^2). Default 3.25e-4. > 0.
    pub a1_m2: f64,
    /// Piston area of the rod side A2 (m^2). Default 2.1e-4. > 0.
    pub a2_m2: f64,
    /// Valve flow gain K_q (m^2/s: flow per metre of spool travel). Default 18.2e-3. > 0.
    pub k_q: f64,
    /// Valve flow-pressure coefficient K_c (m^3/(s Pa)). Default 2.0e-11. >= 0.
    pub k_c: f64,
    /// Leakage coefficient 2*C_in + C_ex (m^3/(s Pa)). Default 3e-14. >= 0.
    pub leakage: f64,
    /// Spool time constant tau (s). Default 0.0035. > 0.
    pub tau_s: f64,
    /// Valve DC gain k_s (m of spool per unit command). Default 1.54. > 0.
    pub k_s: f64,
    /// Constant offset n4 in dF_L/dt (N/s). Default 0 (our assumption).
    pub n4_n_per_s: f64,
    /// Supply pressure p_s (Pa). Default 8e6. > 0. Bounds the force: |F_L| <= p_s*A1.
    pub supply_pressure_pa: f64,
}

impl Default for HydraulicParams {
    fn default() -> Self {
        Self {
            model: HydraulicModel::Linear,
            return_pressure_pa: 0.0,
            beta_pa: 1.517e9,
            v0_m3: 1.0e-4,
            a1_m2: 3.25e-4,
            a2_m2: 2.1e-4,
            k_q: 18.2e-3,
            k_c: 2.0e-11,
            leakage: 3e-14,
            tau_s: 0.0035,
            k_s: 1.54,
            n4_n_per_s: 0.0,
            supply_pressure_pa: 8e6,
        }
    }
}

/// The lumped coefficients n1..n4 of the force ODE.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Coefficients {
    /// n1 = beta*(A1+A2)*K_q/V0 (N/(m s)): force rate per metre of spool opening.
    pub n1: f64,
    /// n2 = beta*(A1+A2)^2/(2*V0) (N/m): oil-column stiffness seen by the piston.
    pub n2: f64,
    /// n3 = beta*(2*K_c + leakage)/V0 (1/s): force decay rate through leakage and valve.
    pub n3: f64,
    /// n4 (N/s): constant offset.
    pub n4: f64,
    /// Spool time constant tau (s).
    pub tau_s: f64,
    /// Valve gain k_s.
    pub k_s: f64,
}

impl HydraulicParams {
    /// The force-ODE coefficients n1..n4 computed from the physical parameters.
    pub fn coefficients(&self) -> Coefficients {
        let a = self.a1_m2 + self.a2_m2;
        Coefficients {
            n1: self.beta_pa * a * self.k_q / self.v0_m3,
            n2: self.beta_pa * a * a / (2.0 * self.v0_m3),
            n3: self.beta_pa * (2.0 * self.k_c + self.leakage) / self.v0_m3,
            n4: self.n4_n_per_s,
            tau_s: self.tau_s,
            k_s: self.k_s,
        }
    }

    /// Largest force the supply pressure can push with, p_s*A1 (N).
    pub fn max_push_force_n(&self) -> f64 {
        self.supply_pressure_pa * self.a1_m2
    }

    /// Largest force the supply pressure can pull with, p_s*A2 (N).
    pub fn max_pull_force_n(&self) -> f64 {
        self.supply_pressure_pa * self.a2_m2
    }
}

/// State of the force channel.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceChannelState {
    /// Load force F_L (N), positive when it lengthens the cylinder.
    pub force_n: f64,
    /// Spool position x_v (m).
    pub spool_m: f64,
    /// Integrated force-acceleration disturbance r (N/s).
    pub accel_dist_n_per_s: f64,
}

/// Inputs to the force channel at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceChannelInput {
    /// Valve command u (dimensionless command; k_s*u is the commanded spool position in m).
    pub valve_command: f64,
    /// Piston velocity xc_dot (m/s), positive when the cylinder lengthens.
    pub piston_velocity_m_s: f64,
    /// Disturbance d_F on dF_L/dt (N/s).
    pub force_rate_dist_n_per_s: f64,
    /// Disturbance D_acc on dx2/dt = d^2F_L/dt^2 (N/s^2).
    pub force_accel_dist_n_per_s2: f64,
    /// Disturbance d_v on dx_v/dt (m/s).
    pub spool_dist_m_per_s: f64,
}

impl Coefficients {
    /// dF_L/dt (N/s) at the given state and input: the first line of the force ODE.
    pub fn force_rate(&self, x: &ForceChannelState, inp: &ForceChannelInput) -> f64 {
        self.n1 * x.spool_m - self.n2 * inp.piston_velocity_m_s - self.n3 * x.force_n
            + self.n4
            + inp.force_rate_dist_n_per_s
            + x.accel_dist_n_per_s
    }

    /// dx_v/dt (m/s) at the given state and input.
    pub fn spool_rate(&self, x: &ForceChannelState, inp: &ForceChannelInput) -> f64 {
        (self.k_s * inp.valve_command - x.spool_m) / self.tau_s + inp.spool_dist_m_per_s
    }

    /// Time derivative of the whole force-channel state. Pure.
    pub fn derivatives(&self, x: &ForceChannelState, inp: &ForceChannelInput) -> ForceChannelState {
        ForceChannelState {
            force_n: self.force_rate(x, inp),
            spool_m: self.spool_rate(x, inp),
            accel_dist_n_per_s: inp.force_accel_dist_n_per_s2,
        }
    }
}
