//! The muscle wearer's internal model (`wearer.model = "muscles"`): the gait a run of the
//! impedance wearer walks, and the moments it took, learned per % of the cycle before the run.

use super::{Model, Simulation};
use crate::error::{Error, Result};
use crate::human::muscle_wearer::Feedforward;
use std::sync::Arc;

/// Strides the learning run walks; the first is its run-in and is not learned.
pub const LEARNING_STRIDES: usize = 3;

/// Learn the gait of `model` (a walking run on the carriage with the impedance wearer): its
/// hip, knee and ankle moments, the angles and rates they made and the device's knee moment
/// it walked with, over every stride after the first. Errors when the model does not walk gait data.
pub fn learn_gait(model: Arc<Model>) -> Result<Feedforward> {
    let data = match model.leg().and_then(|l| l.body.as_ref()).map(|b| &b.targets) {
        Some(crate::human::BodyTargets::Walking(w)) => w.clone(),
        _ => return Err(Error::Usage("the muscle wearer learns a walking run on the carriage".into())),
    };
    let from_s = data.gait.stride_s;
    let mut sim = Simulation::new(model)?;
    let mut samples = Vec::with_capacity(sim.sc.steps);
    let started = std::time::Instant::now();
    while !sim.done() {
        let t = sim.t_s();
        let state = sim.plant.body_state();
        let cylinder_nm = sim.device_knee_torque_nm(t);
        sim.step(&mut crate::record::NullSink)?;
        if let (Some(s), Some(f)) = (state, sim.held.body) {
            if t >= from_s {
                let moments = [f.hip_torque_nm, f.knee_torque_nm, f.ankle_torque_nm];
                let angles = [s.hip.0, s.knee.0, s.ankle.0];
                let rates = [s.hip.1, s.knee.1, s.ankle.1];
                // What the wearer feels of the device, as the run gives it (the free
                // cylinder's friction and the fluid's damping at the knee).
                let device = cylinder_nm + f.device_knee_torque_nm;
                samples.push((data.pct_at(t), [moments, angles, rates], device));
            }
        }
    }
    // (A `stage-timing` build's table counts this loop's steps with the run's.)
    crate::profile::count_loop(sim.steps_taken() as u64, started.elapsed().as_nanos() as u64);
    Feedforward::learn(&samples).ok_or_else(|| {
        Error::Usage(format!(
            "the muscle wearer's learning run left a % of the cycle unvisited (stride {} s, step {} s)",
            data.gait.stride_s, sim.sc.dt_s
        ))
    })
}
