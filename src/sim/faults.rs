//! Faults in the loop (`crate::faults`): when each is active (its clock, a heel strike from the
//! gait events setting an event's onset), what the valve and the cylinder get over a step
//! (their `ValveFaults`, from the faults active at the step's start), the controller's timing
//! faults, and a controller's stop taken to the device's fail-safe state
//! (`controller.on_stop = "failsafe"`).

use super::{ControlBlock, Simulation};
use crate::control::{ControlOutput, ControlStop};
use crate::faults::{ActuatorFaultKind as A, ControllerFaultKind as C, FaultClock, FaultKind};
use crate::hydraulics::{Failsafe, ValveFaults};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// Discharge coefficient and oil density (kg/m^3) of the fail-safe's bypass valve.
const BYPASS_CD: f64 = 0.61;
const OIL_DENSITY_KG_M3: f64 = 870.0;

/// A run's faults as they happen.
#[derive(Debug, Clone)]
pub(crate) struct FaultRun {
    pub clock: FaultClock,
    /// Heel strikes the gait events had counted at the last step.
    heel_strikes: usize,
    /// Per fault: its onset's one-time action is done (a stuck spool put at its value).
    started: Vec<bool>,
    /// The controller stopped (time, why); the device is in its fail-safe state since.
    pub stopped: Option<(f64, ControlStop)>,
    /// Overrun: the commands on their way to the valve, oldest first.
    late: VecDeque<ControlOutput>,
    /// Lost samples' draws.
    rng: ChaCha8Rng,
    /// This sample is skipped or lost: the controller is not called, the last command holds.
    pub skip: bool,
}

impl FaultRun {
    /// The faults of a run of `faults` seeded from `seed`.
    pub fn new(faults: &[crate::faults::Fault], seed: u64) -> Self {
        Self {
            clock: FaultClock::new(faults),
            heel_strikes: 0,
            started: vec![false; faults.len()],
            stopped: None,
            late: VecDeque::new(),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0xC04E_0011),
            skip: false,
        }
    }
}

/// `C_d A sqrt(2 / rho)` of an orifice (m^3/(s Pa^0.5)).
fn orifice_k(area_m2: f64, cd: f64, density_kg_m3: f64) -> f64 {
    cd * area_m2 * (2.0 / density_kg_m3).sqrt()
}

impl Simulation {
    /// Fault `i`'s onset (s) when it is active at `t` (s).
    pub(crate) fn fault_active(&self, i: usize, t: f64) -> Option<f64> {
        let f = &self.faults;
        f.clock.active(&self.sc.faults, i, t).then(|| f.clock.onset(i)).flatten()
    }

    /// Whether any of the run's `[[faults]]` is active at `t` (s): the row's `fault_active`.
    /// The device's fail-safe state after its controller stopped is not a fault (its onset
    /// is the injected fault's, never the stop's; `summary.json` `controller_stop` says when
    /// and why the controller stopped).
    pub(crate) fn any_fault_active(&self, t: f64) -> bool {
        (0..self.sc.faults.len()).any(|i| self.fault_active(i, t).is_some())
    }

    /// The start of a step at `t` (s): a new heel strike sets the event onsets waiting for it,
    /// and the valve and cylinder get the faults active now.
    pub(super) fn update_faults(&mut self, t: f64) {
        let n = self.held.events.map_or(0, |e| e.heel_strikes());
        if n > self.faults.heel_strikes {
            self.faults.heel_strikes = n;
            let stride = self.sc.reference.stride_s().unwrap_or(1.0);
            self.faults.clock.heel_strike(&self.sc.faults, t, stride);
        }
        let mut v = ValveFaults::NONE;
        let act = &self.sc.actuator;
        let bypass = orifice_k(act.failsafe_bypass_area_m2, BYPASS_CD, OIL_DENSITY_KG_M3);
        for (i, f) in self.sc.faults.iter().enumerate() {
            let (Some(t0), FaultKind::Actuator(k)) = (self.fault_active(i, t), f.kind) else { continue };
            match k {
                A::SpoolStuck(at) => {
                    v.spool_stuck = true;
                    v.sealed = at == Some(0.0);
                    if let (Some(x), false) = (at, self.faults.started[i]) {
                        self.state.hyd.spool_m = x;
                    }
                }
                A::SpoolSlow(factor) => v.spool_tau_factor = factor,
                A::Leakage { area_m2, cd, density_kg_m3 } => v.bypass_k += orifice_k(area_m2, cd, density_kg_m3),
                A::SupplyLoss { residual, tau_s } => {
                    let left = if tau_s > 0.0 { (-(t - t0) / tau_s).exp() } else { 0.0 };
                    v.supply_factor = residual + (1.0 - residual) * left;
                }
                A::PowerLoss => {
                    v.power_off = true;
                    v.sealed = true;
                    if act.failsafe == Failsafe::Free {
                        v.vent_k = bypass;
                    }
                }
            }
            self.faults.started[i] = true;
        }
        if self.faults.stopped.is_some() {
            v.power_off = true;
            v.sealed = true;
            if act.failsafe == Failsafe::Free {
                v.vent_k = bypass;
            }
        }
        self.held.valve = v;
    }

    /// At a sample instant `t` (s): whether the controller's sample is skipped or lost.
    pub(super) fn sample_controller_faults(&mut self, t: f64) {
        let mut skip = self.faults.stopped.is_some();
        for (i, f) in self.sc.faults.iter().enumerate() {
            if self.fault_active(i, t).is_none() {
                continue;
            }
            match f.kind {
                FaultKind::Controller(C::Skip) => skip = true,
                FaultKind::Controller(C::Lost(p)) => {
                    let u: f64 = rand::Rng::random(&mut self.faults.rng);
                    skip |= u < p;
                }
                _ => {}
            }
        }
        self.faults.skip = skip;
    }

    /// The output the valve gets at this sample for the controller's `out`: the last one when
    /// the sample is skipped; with an overrun of `n` samples active, the one computed `n`
    /// samples ago (the last one until there is one).
    pub(super) fn timed_output(&mut self, out: ControlOutput) -> ControlOutput {
        let ControlBlock::Sampled(l) = &self.control else { return out };
        let previous = l.hold.value();
        if self.faults.skip {
            return previous;
        }
        let t = self.t_s();
        let overrun = self.sc.faults.iter().enumerate().find_map(|(i, f)| match f.kind {
            FaultKind::Controller(C::Overrun(n)) if self.fault_active(i, t).is_some() => Some(n),
            _ => None,
        });
        let Some(n) = overrun else {
            self.faults.late.clear();
            return out;
        };
        self.faults.late.push_back(out);
        if self.faults.late.len() > n {
            self.faults.late.pop_front().unwrap_or(previous)
        } else {
            previous
        }
    }

    /// The controller stopped at `t` (s) for `why` under `controller.on_stop = "failsafe"`:
    /// the device goes to its fail-safe state for the rest of the run (the first stop is kept,
    /// its cause and message).
    pub(super) fn go_failsafe(&mut self, t: f64, why: ControlStop) {
        if self.faults.stopped.is_none() {
            self.faults.stopped = Some((t, why));
        }
        self.update_faults(t);
    }

    /// When the controller stopped (s) and why, under `controller.on_stop = "failsafe"`.
    pub fn controller_stop(&self) -> Option<(f64, &ControlStop)> {
        self.faults.stopped.as_ref().map(|(t, m)| (*t, m))
    }

    /// Each fault's onset (s), once it happened (None: a gait event that never came).
    pub fn fault_onsets(&self) -> Vec<Option<f64>> {
        (0..self.sc.faults.len()).map(|i| self.faults.clock.onset(i)).collect()
    }
}
