//! The cylinder as one block of the loop: the linear force ODE (paper Eq. 1) or the two-chamber
//! plant, with its hard stops (spool travel, supply-pressure force bounds or chamber-pressure
//! limits), the stroke correction the co-simulation applies after the mechanics moved, and its
//! limit test. The loop never branches on the model kind: it asks the cylinder.

use super::{Coefficients, ForceChannelInput, ForceChannelState, HydraulicModel, HydraulicParams, TwoChamber};

/// The hydraulic states the loop integrates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HydraulicState {
    /// Load force F_L (N).
    pub force_n: f64,
    /// Spool position x_v (m).
    pub spool_m: f64,
    /// Integrated force-acceleration disturbance r (N/s), see [`super`].
    pub accel_dist_n_per_s: f64,
    /// Mean chamber pressure (Pa), two-chamber model only (0 for the linear one).
    pub mean_pressure_pa: f64,
}

impl HydraulicState {
    /// The force-channel view of the state (F_L, x_v, r).
    pub fn channel(&self) -> ForceChannelState {
        ForceChannelState { force_n: self.force_n, spool_m: self.spool_m, accel_dist_n_per_s: self.accel_dist_n_per_s }
    }
}

/// Piston position (m) and velocity (m/s) as the cylinder sees them at one stage.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PistonKinematics {
    /// Position from the start (m).
    pub position_m: f64,
    /// Velocity (m/s).
    pub velocity_m_s: f64,
}

/// The force rates of one stage ([`Cylinder::rates`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceRates {
    /// dF_L/dt of the model (N/s), past a force bound too.
    pub raw_n_per_s: f64,
    /// What the load cell sees (N/s): 0 where a supply-pressure bound holds F_L.
    pub load_cell_n_per_s: f64,
    /// Mean chamber pressure rate (Pa/s; two-chamber model, else 0).
    pub mean_pressure_pa_s: f64,
}

/// What faults do to the valve and the cylinder over a step (`crate::faults`: the loop sets it
/// from the faults active at the step's start).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValveFaults {
    /// The spool is stuck where it is (its rate 0).
    pub spool_stuck: bool,
    /// The spool's time constant times this (1: normal).
    pub spool_tau_factor: f64,
    /// A bypass across the piston: `k` of `Q = k sign(dp) sqrt(|dp|)` (m^3/(s Pa^0.5), `C_d A
    /// sqrt(2/rho)`), 0: none.
    pub bypass_k: f64,
    /// A vent of both chambers to the return line (the fail-safe bypass valve of a `free`
    /// failsafe): `k` of each chamber's orifice, as `bypass_k`; 0: none. The two-chamber model
    /// drains each chamber toward the return pressure; the linear model, which has no mean
    /// pressure, relaxes its load pressure `F_L / A_eff` through the orifice.
    pub vent_k: f64,
    /// The valve is sealed at its null: a spool held at centre by a fault, or spring-centred
    /// without power, seals its ports with its overlap, so the working valve's flow-pressure
    /// coefficient K_c (the `2 K_c` of n3) is gone and only the opening's flow and the
    /// cylinder's own leakage (`2 C_in + C_ex`) remain.
    pub sealed: bool,
    /// The supply pressure's fraction left (1: normal).
    pub supply_factor: f64,
    /// No power: the valve's command is 0.
    pub power_off: bool,
}

impl ValveFaults {
    /// No fault.
    pub const NONE: ValveFaults = ValveFaults {
        spool_stuck: false,
        spool_tau_factor: 1.0,
        bypass_k: 0.0,
        vent_k: 0.0,
        sealed: false,
        supply_factor: 1.0,
        power_off: false,
    };

    /// Whether nothing is faulty.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }
}

impl Default for ValveFaults {
    fn default() -> Self {
        Self::NONE
    }
}

/// Pressure difference (Pa) below which the bypass orifice's flow is laminar-like (a
/// regularisation of `sqrt(|dp|)`, whose slope is infinite at 0): `Q = k dp / (dp^2 +
/// dp_t^2)^(1/4)`, within 0.003 % of the orifice equation above 1 MPa.
pub const BYPASS_TRANSITION_PA: f64 = 1e4;

/// The bypass flow (m^3/s, from A to B) at a pressure difference `dp` (Pa, p_A - p_B).
pub fn bypass_flow_m3_s(k: f64, dp: f64) -> f64 {
    k * dp / (dp * dp + BYPASS_TRANSITION_PA * BYPASS_TRANSITION_PA).sqrt().sqrt()
}

/// The pressure difference (Pa) at which [`bypass_flow_m3_s`] passes `q` (m^3/s): its inverse,
/// `dp^2 = (q^4 + sqrt(q^8 + 4 k^4 q^4 dp_t^2)) / (2 k^4)`.
pub fn bypass_pressure_pa(k: f64, q: f64) -> f64 {
    if k <= 0.0 || q == 0.0 {
        return 0.0;
    }
    let (k4, q4) = (k.powi(4), q.powi(4));
    let y = (q4 + (q4 * q4 + 4.0 * k4 * q4 * BYPASS_TRANSITION_PA * BYPASS_TRANSITION_PA).sqrt()) / (2.0 * k4);
    y.sqrt().copysign(q)
}

/// The free failsafe's vent in the linear model relaxes the load force to its quasi-static
/// value with at least this time constant (s) when the vent itself is faster: an open bypass
/// relaxes the load pressure in microseconds (a stiff state that would take hundreds of
/// substeps per millisecond step), and the knee moves on the scale of tens of milliseconds, so
/// the force is the damper force the vent's flow sets, 0.5 ms late at most.
pub const VENT_RELAX_S: f64 = 5e-4;

/// Which plant integrates the force channel.
#[derive(Debug, Clone, PartialEq)]
enum Chambers {
    /// dF_L/dt from the linear ODE; F_L clamped to the force bounds.
    Linear,
    /// Two chambers; the pressures hold themselves in [p_r, p_s].
    Two(TwoChamber),
}

/// The valve-controlled cylinder: coefficients, model and hard stops.
#[derive(Debug, Clone, PartialEq)]
pub struct Cylinder {
    /// The plant's force-ODE coefficients n1..n4, tau, k_s.
    pub coeffs: Coefficients,
    chambers: Chambers,
    /// Load-force bounds (N): [-p_s*A2, p_s*A1], or infinite without `actuator.pressure_limit`.
    pub force_bounds_n: (f64, f64),
    /// Spool travel limit (m), 0 = none.
    pub spool_limit_m: f64,
    /// Piston areas A1 (cap side) and A2 (rod side) (m^2).
    pub areas_m2: (f64, f64),
    /// Supply and return pressures (Pa).
    pub supply_return_pa: (f64, f64),
    /// Valve flow gain K_q (m^2/s).
    pub k_q: f64,
    /// The valve's part of n3, `beta 2 K_c / V0` (1/s): its flow-pressure coefficient at the
    /// working null, which a sealed valve ([`ValveFaults::sealed`]) does not have.
    pub n3_valve_per_s: f64,
}

impl Cylinder {
    /// The cylinder of a scenario. `pressure_limit`: clamp F_L to what the supply gives
    /// (linear model); `spool_limit_m`: spool travel stop, 0 = none.
    pub fn new(h: &HydraulicParams, pressure_limit: bool, spool_limit_m: f64) -> Self {
        let force_bounds_n = if pressure_limit {
            (-h.max_pull_force_n(), h.max_push_force_n())
        } else {
            (f64::NEG_INFINITY, f64::INFINITY)
        };
        let chambers = match h.model {
            HydraulicModel::Linear => Chambers::Linear,
            HydraulicModel::TwoChamber => Chambers::Two(TwoChamber::new(h)),
        };
        Self {
            coeffs: h.coefficients(),
            chambers,
            force_bounds_n,
            spool_limit_m,
            areas_m2: (h.a1_m2, h.a2_m2),
            supply_return_pa: (h.supply_pressure_pa, h.return_pressure_pa),
            k_q: h.k_q,
            n3_valve_per_s: h.beta_pa * 2.0 * h.k_c / h.v0_m3,
        }
    }

    /// The chamber pressures (Pa) at a state: the two-chamber model's; for the linear model
    /// (whose state is the load force alone) the pressures that give F_L about the valve's
    /// operating point, whose mean pressure is `(p_s + p_r) / 2`:
    /// `p_A = (F_L + A2 (p_s + p_r)) / (A1 + A2)`, `p_B = (A1 (p_s + p_r) - F_L) / (A1 + A2)`,
    /// so that `A1 p_A - A2 p_B = F_L`.
    pub fn pressures_pa(&self, h: &HydraulicState) -> (f64, f64) {
        match &self.chambers {
            Chambers::Two(tc) => tc.pressures(h.force_n, h.mean_pressure_pa),
            Chambers::Linear => {
                let (a1, a2) = self.areas_m2;
                let sum = self.supply_return_pa.0 + self.supply_return_pa.1;
                ((h.force_n + a2 * sum) / (a1 + a2), (a1 * sum - h.force_n) / (a1 + a2))
            }
        }
    }

    /// The load pressure `F_L / A_eff` (Pa) with `A_eff = (A1 + A2) / 2`, the area of the
    /// paper's symmetric-cylinder linearisation (n2 = beta (A1 + A2)^2 / (2 V0)).
    pub fn load_pressure_pa(&self, h: &HydraulicState) -> f64 {
        h.force_n / (0.5 * (self.areas_m2.0 + self.areas_m2.1))
    }

    /// Flow drawn from the supply (m^3/s, >= 0): the two-chamber orifice flow from the supply,
    /// or the linear valve's `K_q |x_v|` (the load flow of the paper's valve, which a
    /// critically centred four-way valve draws from the supply).
    pub fn supply_flow_m3_s(&self, h: &HydraulicState) -> f64 {
        match &self.chambers {
            Chambers::Two(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                tc.supply_flow_m3_s(h.spool_m, p1, p2)
            }
            Chambers::Linear => self.k_q * h.spool_m.abs(),
        }
    }

    /// True for the two-chamber plant.
    pub fn is_two_chamber(&self) -> bool {
        matches!(self.chambers, Chambers::Two(_))
    }

    /// The state at t = 0 with F_L = 0: zero (linear), or the two-chamber equilibrium
    /// (pressures and the balancing spool opening).
    pub fn initial_state(&self) -> HydraulicState {
        match &self.chambers {
            Chambers::Linear => HydraulicState::default(),
            Chambers::Two(tc) => {
                let (p1, p2, xv) = tc.operating_point();
                let (force_n, mean_pressure_pa) = tc.force_and_mean(p1, p2);
                HydraulicState { force_n, spool_m: xv, accel_dist_n_per_s: 0.0, mean_pressure_pa }
            }
        }
    }

    /// Start on a trajectory: F_L = F_d(0) (within the bounds) and the spool opening that
    /// gives dF_L/dt = dF_d/dt(0) with the piston moving at `piston_velocity_m_s`.
    pub fn start_on_trajectory(
        &self,
        h: &mut HydraulicState,
        force_n: f64,
        rate_n_per_s: f64,
        piston_velocity_m_s: f64,
    ) {
        let c = &self.coeffs;
        let (lo, hi) = self.force_bounds_n;
        h.force_n = force_n.clamp(lo, hi);
        h.spool_m = (rate_n_per_s + c.n2 * piston_velocity_m_s + c.n3 * h.force_n - c.n4) / c.n1;
    }

    /// The cylinder at one integrator stage, before the valve command is known: the force rates
    /// the load cell and the controller see. `inp` carries the piston velocity and the
    /// disturbances; its `valve_command` is not used. Then [`Self::derivatives`] with the
    /// command.
    #[inline]
    pub fn rates(&self, h: &HydraulicState, piston: &PistonKinematics, inp: &ForceChannelInput) -> ForceRates {
        let (raw, mean) = self.force_rate(h, piston, inp);
        ForceRates { raw_n_per_s: raw, load_cell_n_per_s: self.rate_at_bound(h, raw), mean_pressure_pa_s: mean }
    }

    /// dF_L/dt (N/s) and the mean-pressure rate (Pa/s) at a state. `inp` carries the piston
    /// velocity and the force-rate disturbance; `u` is not needed.
    fn force_rate(&self, h: &HydraulicState, piston: &PistonKinematics, inp: &ForceChannelInput) -> (f64, f64) {
        match &self.chambers {
            Chambers::Linear => (self.coeffs.force_rate(&h.channel(), inp), 0.0),
            Chambers::Two(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                let extra = inp.force_rate_dist_n_per_s + h.accel_dist_n_per_s;
                let (d1, d2) = tc.pressure_rates(p1, p2, h.spool_m, piston.position_m, piston.velocity_m_s, extra);
                let (df, _) = tc.force_and_mean(d1, d2);
                (df, 0.5 * (d1 + d2))
            }
        }
    }

    /// The load cell's rate: held at a supply-pressure bound (linear model) F_L does not move,
    /// so a rate pushing past the bound reads 0.
    fn rate_at_bound(&self, h: &HydraulicState, rate_n_per_s: f64) -> f64 {
        let (lo, hi) = self.force_bounds_n;
        let out = (h.force_n >= hi && rate_n_per_s > 0.0) || (h.force_n <= lo && rate_n_per_s < 0.0);
        if matches!(self.chambers, Chambers::Linear) && out {
            0.0
        } else {
            rate_n_per_s
        }
    }

    /// Time derivative of the hydraulic state, with the hard stops applied: the spool does not
    /// move past its travel limit, F_L not past its bounds (linear model). `rates` come from
    /// [`Self::rates`] at the same state.
    pub fn derivatives(&self, h: &HydraulicState, inp: &ForceChannelInput, rates: &ForceRates) -> HydraulicState {
        let dh = self.coeffs.derivatives(&h.channel(), inp);
        let mut d = HydraulicState {
            force_n: rates.load_cell_n_per_s,
            spool_m: dh.spool_m,
            accel_dist_n_per_s: dh.accel_dist_n_per_s,
            mean_pressure_pa: rates.mean_pressure_pa_s,
        };
        let sl = self.spool_limit_m;
        if sl > 0.0 && h.spool_m.abs() >= sl && d.spool_m * h.spool_m > 0.0 {
            d.spool_m = 0.0;
        }
        if matches!(self.chambers, Chambers::Linear) {
            let (lo, hi) = self.force_bounds_n;
            if (h.force_n >= hi && d.force_n > 0.0) || (h.force_n <= lo && d.force_n < 0.0) {
                d.force_n = 0.0;
            }
        }
        d
    }

    /// The two-chamber model with the supply a fault leaves (None for the linear model).
    fn chambers_with(&self, f: &ValveFaults) -> Option<TwoChamber> {
        match &self.chambers {
            Chambers::Two(tc) if f.supply_factor != 1.0 => Some(tc.with_supply(tc.p_s * f.supply_factor)),
            Chambers::Two(tc) => Some(tc.clone()),
            Chambers::Linear => None,
        }
    }

    /// The force bounds with the supply a fault leaves (N).
    fn bounds_with(&self, f: &ValveFaults) -> (f64, f64) {
        let (lo, hi) = self.force_bounds_n;
        (lo * f.supply_factor, hi * f.supply_factor)
    }

    /// [`Self::rates`] under the faults `f` (the same arithmetic without any): the supply's
    /// fraction scales the linear valve's flow gain by its square root and the force bounds by
    /// itself (the two-chamber model's orifices see the lower supply pressure), and the bypass
    /// takes its flow out of chamber A into B.
    pub fn rates_with(
        &self,
        h: &HydraulicState,
        piston: &PistonKinematics,
        inp: &ForceChannelInput,
        f: &ValveFaults,
    ) -> ForceRates {
        if f.bypass_k == 0.0 && f.vent_k == 0.0 && !f.sealed && f.supply_factor == 1.0 {
            return self.rates(h, piston, inp);
        }
        let (pa, pb) = self.pressures_pa(h);
        let q = bypass_flow_m3_s(f.bypass_k, pa - pb);
        let sum = self.areas_m2.0 + self.areas_m2.1;
        let (raw, mean) = match self.chambers_with(f) {
            None => {
                let c = &self.coeffs;
                let x = h.channel();
                let rest =
                    c.n1 * f.supply_factor.sqrt() * x.spool_m - c.n2 * inp.piston_velocity_m_s - c.n3 * x.force_n
                        + c.n4
                        + inp.force_rate_dist_n_per_s
                        + x.accel_dist_n_per_s
                        - c.n2 * 2.0 / sum * q
                        + if f.sealed { self.n3_valve_per_s * x.force_n } else { 0.0 };
                let r = if self.vent_rate_per_s(f.vent_k) * VENT_RELAX_S > 1.0 {
                    // Quasi-static: the vent passes what the rest would change the force by.
                    let f_qs = bypass_pressure_pa(f.vent_k, rest * sum / (2.0 * c.n2)) * sum / 2.0;
                    (f_qs - x.force_n) / VENT_RELAX_S
                } else {
                    rest - c.n2 * 2.0 / sum * bypass_flow_m3_s(f.vent_k, self.load_pressure_pa(h))
                };
                (r, 0.0)
            }
            Some(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                let extra = inp.force_rate_dist_n_per_s + h.accel_dist_n_per_s;
                let (mut d1, mut d2) =
                    tc.pressure_rates(p1, p2, h.spool_m, piston.position_m, piston.velocity_m_s, extra);
                let (l1, l2) = tc.transfer_rates(piston.position_m, q);
                let vent = |p: f64| bypass_flow_m3_s(f.vent_k, p - tc.p_r);
                let (v1, v2) = tc.drain_rates(piston.position_m, vent(p1), vent(p2));
                let (s1, s2) = if f.sealed { tc.null_leak_rates(p1, p2, piston.position_m) } else { (0.0, 0.0) };
                (d1, d2) = (d1 + l1 + v1 - s1, d2 + l2 + v2 - s2);
                let (df, _) = tc.force_and_mean(d1, d2);
                (df, 0.5 * (d1 + d2))
            }
        };
        let (lo, hi) = self.bounds_with(f);
        let out = (h.force_n >= hi && raw > 0.0) || (h.force_n <= lo && raw < 0.0);
        let load_cell = if self.chambers_with(f).is_none() && out { 0.0 } else { raw };
        ForceRates { raw_n_per_s: raw, load_cell_n_per_s: load_cell, mean_pressure_pa_s: mean }
    }

    /// [`Self::derivatives`] under the faults `f`: a stuck spool does not move, a slow one
    /// moves with its time constant times the factor, the force bounds follow the supply.
    pub fn derivatives_with(
        &self,
        h: &HydraulicState,
        inp: &ForceChannelInput,
        rates: &ForceRates,
        f: &ValveFaults,
    ) -> HydraulicState {
        let mut d = self.derivatives(h, inp, rates);
        if f.is_none() {
            return d;
        }
        if f.spool_stuck {
            d.spool_m = 0.0;
        } else if f.spool_tau_factor != 1.0 {
            d.spool_m = (self.coeffs.k_s * inp.valve_command - h.spool_m) / (self.coeffs.tau_s * f.spool_tau_factor)
                + inp.spool_dist_m_per_s;
        }
        if matches!(self.chambers, Chambers::Linear) {
            let (lo, hi) = self.bounds_with(f);
            if (h.force_n >= hi && d.force_n > 0.0) || (h.force_n <= lo && d.force_n < 0.0) {
                d.force_n = 0.0;
            }
        }
        d
    }

    /// [`Self::end_step`] under the faults `f` (the force bounds of the supply left).
    pub fn end_step_with(&self, h: &mut HydraulicState, missed: Option<(f64, f64)>, f: &ValveFaults) {
        if f.supply_factor == 1.0 {
            return self.end_step(h, missed);
        }
        if let Some((xc_m, dx_m)) = missed {
            self.apply_stroke(h, xc_m, dx_m);
        }
        let sl = self.spool_limit_m;
        if sl > 0.0 {
            h.spool_m = h.spool_m.clamp(-sl, sl);
        }
        match self.chambers_with(f) {
            None => {
                let (lo, hi) = self.bounds_with(f);
                h.force_n = h.force_n.clamp(lo, hi);
            }
            Some(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                let (p1, p2) = tc.clamp(p1, p2);
                (h.force_n, h.mean_pressure_pa) = tc.force_and_mean(p1, p2);
            }
        }
    }

    /// [`Self::local_stiffness`] with a bypass's flow (its slope at the pressure difference
    /// now: at most `k / sqrt(dp_t)`) and a slow spool.
    pub fn local_stiffness_with(&self, h: &HydraulicState, piston_position_m: f64, f: &ValveFaults) -> (f64, f64) {
        let (mut rate, k) = self.local_stiffness(h, piston_position_m);
        let vent = match self.chambers {
            // The linear model's vent relaxes no faster than VENT_RELAX_S.
            Chambers::Linear => self.vent_rate_per_s(f.vent_k).min(1.0 / VENT_RELAX_S),
            Chambers::Two(_) => self.vent_rate_per_s(f.vent_k),
        };
        rate = rate.max(self.vent_rate_per_s(f.bypass_k)).max(vent);
        (rate, k)
    }

    /// The decay rate (1/s) of the load force through an orifice `k` across the load pressure
    /// at its steepest (`k / sqrt(dp_t)`): `n2 (2 / (A1 + A2))^2 k / sqrt(dp_t)` (d(dp)/dF is
    /// 2 / (A1 + A2) for the linear model's pressures; the two-chamber chambers' pressures move
    /// with their own volumes, of the same order).
    fn vent_rate_per_s(&self, k: f64) -> f64 {
        let sum = self.areas_m2.0 + self.areas_m2.1;
        self.coeffs.n2 * (2.0 / sum).powi(2) * k / BYPASS_TRANSITION_PA.sqrt()
    }

    /// Whether the cylinder is at its force limit (linear: a bound; two chambers: a pressure
    /// at p_r or p_s).
    pub fn at_limit(&self, h: &HydraulicState) -> bool {
        match &self.chambers {
            Chambers::Linear => {
                let (lo, hi) = self.force_bounds_n;
                h.force_n <= lo || h.force_n >= hi
            }
            Chambers::Two(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                p1 <= tc.p_r || p1 >= tc.p_s || p2 <= tc.p_r || p2 >= tc.p_s
            }
        }
    }

    /// The part of the true dx2/dt that is not the lumped disturbance's business: the linear
    /// model's analytic `n1*dx_v/dt - n2*xc_ddot - n3*x2 + d(d_F)/dt + D_acc`; None for the
    /// two-chamber model (no closed form).
    pub fn force_accel(
        &self,
        spool_rate_m_s: f64,
        piston_accel_m_s2: f64,
        force_rate_n_per_s: f64,
        force_rate_dist_rate: f64,
        accel_dist_n_per_s2: f64,
    ) -> Option<f64> {
        let c = &self.coeffs;
        match self.chambers {
            Chambers::Linear => Some(
                c.n1 * spool_rate_m_s - c.n2 * piston_accel_m_s2 - c.n3 * force_rate_n_per_s
                    + force_rate_dist_rate
                    + accel_dist_n_per_s2,
            ),
            Chambers::Two(_) => None,
        }
    }

    /// Local stiffness at a state: the fastest decay rate of the force channel (1/s: n3 for the
    /// linear model, the chamber-pressure rate for the two-chamber one, the spool's 1/tau) and
    /// the oil column's stiffness against the piston (N/m: n2, or the two-chamber value at the
    /// current volumes). The loop substeps the hydraulic states when a step is too long for them.
    pub fn local_stiffness(&self, h: &HydraulicState, piston_position_m: f64) -> (f64, f64) {
        let spool = 1.0 / self.coeffs.tau_s;
        match &self.chambers {
            Chambers::Linear => (self.coeffs.n3.max(spool), self.coeffs.n2),
            Chambers::Two(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                let (rate, k) = tc.local_stiffness(p1, p2, h.spool_m, piston_position_m);
                (rate.max(spool), k)
            }
        }
    }

    /// The end of a step: the stroke the force ODE did not see (`missed`: the piston position
    /// `xc_m` (m) after the step and the missed stroke (m)) acts on the oil spring, then the
    /// states that sit against hard stops are held there.
    pub fn end_step(&self, h: &mut HydraulicState, missed: Option<(f64, f64)>) {
        if let Some((xc_m, dx_m)) = missed {
            self.apply_stroke(h, xc_m, dx_m);
        }
        self.clamp(h);
    }

    /// Hold the states that sit against hard stops after a step.
    fn clamp(&self, h: &mut HydraulicState) {
        let sl = self.spool_limit_m;
        if sl > 0.0 {
            h.spool_m = h.spool_m.clamp(-sl, sl);
        }
        match &self.chambers {
            Chambers::Linear => h.force_n = h.force_n.clamp(self.force_bounds_n.0, self.force_bounds_n.1),
            Chambers::Two(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                let (p1, p2) = tc.clamp(p1, p2);
                (h.force_n, h.mean_pressure_pa) = tc.force_and_mean(p1, p2);
            }
        }
    }

    /// Apply a piston stroke `dx_m` at position `xc_m` that the force ODE did not see: the oil
    /// spring acts on the geometric change of cylinder length.
    fn apply_stroke(&self, h: &mut HydraulicState, xc_m: f64, dx_m: f64) {
        match &self.chambers {
            Chambers::Linear => h.force_n -= self.coeffs.n2 * dx_m,
            Chambers::Two(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, h.mean_pressure_pa);
                let (d1, d2) = tc.pressure_change_for_stroke(xc_m, dx_m);
                (h.force_n, h.mean_pressure_pa) = tc.force_and_mean(p1 + d1, p2 + d2);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Held at a supply-pressure bound, the load force does not move: the load cell's rate reads
    /// 0 when it would push past the bound, and the state derivative is 0 too; a rate back into
    /// the range is kept.
    #[test]
    fn load_cell_rate_is_held_at_the_pressure_bound() {
        let h = HydraulicParams::default();
        let c = Cylinder::new(&h, true, 0.0);
        let (lo, hi) = c.force_bounds_n;
        assert_eq!((lo, hi), (-h.max_pull_force_n(), h.max_push_force_n()));
        let at_hi = HydraulicState { force_n: hi, ..Default::default() };
        assert_eq!(c.rate_at_bound(&at_hi, 500.0), 0.0);
        assert_eq!(c.rate_at_bound(&at_hi, -500.0), -500.0);
        let at_lo = HydraulicState { force_n: lo, ..Default::default() };
        assert_eq!(c.rate_at_bound(&at_lo, -500.0), 0.0);
        let rates = ForceRates { raw_n_per_s: 500.0, load_cell_n_per_s: 500.0, mean_pressure_pa_s: 0.0 };
        assert_eq!(c.derivatives(&at_hi, &ForceChannelInput::default(), &rates).force_n, 0.0);
        assert!(c.at_limit(&at_hi) && c.at_limit(&at_lo));
        // Without the pressure limit nothing is held.
        let free = Cylinder::new(&h, false, 0.0);
        assert_eq!(free.rate_at_bound(&at_hi, 500.0), 500.0);
        // The two-chamber model holds its pressures itself: its rate is never overridden.
        let tc = Cylinder::new(&HydraulicParams { model: HydraulicModel::TwoChamber, ..h }, true, 0.0);
        assert_eq!(tc.rate_at_bound(&at_hi, 500.0), 500.0);
    }
}
