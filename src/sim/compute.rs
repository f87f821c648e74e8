//! The firmware's modelled computation on the target (issue 36): a sampled controller's command
//! takes effect `controller.compute_delay_s` (plus a seeded jitter) after its sample instant,
//! rounded up to whole steps; a sample whose modelled time exceeds `controller.compute_budget_s`
//! is applied late, dropped (the last command holds) or stops the controller, as
//! `controller.overrun_policy` says. Modelled times only: the measured ones
//! (`summary.json` `controller_compute`) never enter the physics.

use super::{ControlBlock, Simulation};
use crate::control::{ControlOutput, OverrunPolicy};
use crate::error::{Error, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// The modelled computation of a run (`[controller]` `compute_*`, `overrun_policy`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComputeModel {
    /// Modelled time per sample (s).
    pub delay_s: f64,
    /// Extra time per sample, uniform in [0, jitter] (s).
    pub jitter_s: f64,
    /// The budget (s).
    pub budget_s: f64,
    /// What a sample over its budget does.
    pub policy: OverrunPolicy,
}

impl ComputeModel {
    /// The model of a scenario's controller (None when it models nothing).
    pub fn of(c: &crate::control::ControllerParams) -> Option<Self> {
        let modelled = c.compute_delay_s > 0.0 || c.compute_jitter_s > 0.0 || c.compute_budget_s.is_some();
        (modelled && c.sample_period_s > 0.0).then(|| Self {
            delay_s: c.compute_delay_s,
            jitter_s: c.compute_jitter_s,
            budget_s: c.compute_budget_s.unwrap_or(c.sample_period_s),
            policy: c.overrun_policy,
        })
    }
}

/// What the modelled computation did over a run (`summary.json` `compute_model`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ComputeSummary {
    /// Samples computed.
    pub samples: usize,
    /// The largest modelled time (s).
    pub max_time_s: f64,
    /// The largest delay applied, in steps of `sim.dt_s`.
    pub max_delay_steps: usize,
    /// Samples over the budget.
    pub overruns: usize,
    /// Of them, commands dropped (`hold`).
    pub dropped: usize,
}

/// The modelled computation as the run goes.
#[derive(Debug, Clone)]
pub(crate) struct ComputeRun {
    /// Commands on their way to the valve: (the step they take effect at, the command).
    pending: VecDeque<(usize, ControlOutput)>,
    rng: ChaCha8Rng,
    pub summary: ComputeSummary,
}

impl ComputeRun {
    /// A run seeded from `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            pending: VecDeque::new(),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0xC0_3E_7E),
            summary: Default::default(),
        }
    }
}

/// What [`Simulation::computed`] made of a command.
pub(super) enum Computed {
    /// It takes effect now.
    Now(ControlOutput),
    /// It is on its way (or dropped): the valve keeps what it has.
    Later,
}

impl Simulation {
    /// The command `out` of the sample at step k under the modelled computation: now (no
    /// model, or a modelled time under one step), later, dropped, or a stop.
    pub(super) fn computed(&mut self, out: ControlOutput) -> Result<Computed> {
        let Some(m) = self.sc.compute else { return Ok(Computed::Now(out)) };
        let c = &mut self.compute;
        let time = m.delay_s + if m.jitter_s > 0.0 { m.jitter_s * c.rng.random::<f64>() } else { 0.0 };
        c.summary.samples += 1;
        c.summary.max_time_s = c.summary.max_time_s.max(time);
        if time > m.budget_s {
            c.summary.overruns += 1;
            match m.policy {
                OverrunPolicy::ApplyLate => {}
                OverrunPolicy::Hold => {
                    c.summary.dropped += 1;
                    return Ok(Computed::Later);
                }
                OverrunPolicy::Stop => {
                    let t = self.t_s();
                    let message = format!(
                        "compute budget overrun: the modelled computation takes {time:.6} s, over the budget of {} s",
                        m.budget_s
                    );
                    if self.sc.on_stop == crate::control::OnStop::Failsafe {
                        self.go_failsafe(t, crate::control::ControlStop::stop(message));
                        return Ok(Computed::Now(ControlOutput::default()));
                    }
                    let controller = match &self.control {
                        ControlBlock::Sampled(l) => l.ctrl.as_ref().map_or("external".into(), |c| c.kind().to_string()),
                        ControlBlock::Continuous(_) => String::new(),
                    };
                    return Err(Error::ControllerStopped { time_s: t, controller, message });
                }
            }
        }
        let steps = (time / self.sc.dt_s - 1e-9).ceil().max(0.0) as usize;
        let c = &mut self.compute;
        c.summary.max_delay_steps = c.summary.max_delay_steps.max(steps);
        if steps == 0 {
            return Ok(Computed::Now(out));
        }
        c.pending.push_back((self.k + steps, out));
        Ok(Computed::Later)
    }

    /// At the start of step k: the commands whose computation is done take effect (the
    /// latest of them last).
    pub(super) fn apply_computed(&mut self) {
        while let Some(&(at, out)) = self.compute.pending.front() {
            if at > self.k {
                break;
            }
            self.compute.pending.pop_front();
            if let ControlBlock::Sampled(l) = &mut self.control {
                l.hold.set(out);
            }
            self.held.output = Some(out);
        }
    }

    /// What the modelled computation did (None without one).
    pub fn compute_summary(&self) -> Option<ComputeSummary> {
        self.sc.compute.map(|_| self.compute.summary.clone())
    }
}
